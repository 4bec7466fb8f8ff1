//! `chronotope bench carve` and `chronotope bench carve --accuracy`: the carving model's
//! per-pose update time, and its error against the exact swept solid.
//!
//! Speed: a knife stroke across a block at 1 kHz; each pose's update (sweep, surface update,
//! force) is timed on its own and the median, p99 and maximum printed, for several grid
//! sizes, a ~1M-surfel plate and several tool sizes. Accuracy: strokes of a box knife across
//! a block, cut with moves of 1, 10 and 40 spacings per frame, with and without rotation,
//! against the exact result; the force's coefficient of variation in a steady cut.

use std::collections::HashMap;
use std::time::Instant;

use super::CliError;
use crate::carving::exact::{box_signed_distance, BoxSweep, SweptSolid};
use crate::carving::{
    ForceModel, ForceParams, ForceRenderer, Quat, Tool, ToolPose, Vec3, Workpiece,
};
use crate::mesh::stats::percentile;

fn err(e: impl std::fmt::Display) -> CliError {
    CliError::Usage(e.to_string())
}

/// The knife with its blade face towards +x (tool z → world x, tool x → world -z): it
/// planes material moving along x.
fn facing_x() -> Quat {
    Quat::from_axis_angle([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2)
}

struct Timing {
    median_us: f64,
    p99_us: f64,
    max_us: f64,
    removed_per_pose: f64,
    surfels: usize,
}

/// A knife planing the block at 1 kHz, `step` m per pose: passes along x over the middle
/// 80% of the block, alternating direction, each half a blade width further along y, and
/// `depth` deeper once y is done; every pose cuts fresh material. Each pose timed.
fn time_stroke(work: &mut Workpiece, tool: &Tool, step: f64, depth: f64, poses: usize) -> Timing {
    let (lo, hi) = work.block_bounds();
    let half_len = tool
        .vertices()
        .iter()
        .map(|v| v[0].abs())
        .fold(0.0, f64::max);
    let half_width = tool
        .vertices()
        .iter()
        .map(|v| v[1].abs())
        .fold(0.0, f64::max);
    let (x0, x1) = (lo[0] + 0.1 * (hi[0] - lo[0]), lo[0] + 0.9 * (hi[0] - lo[0]));
    let (y0, y1) = (lo[1] + 0.1 * (hi[1] - lo[1]), lo[1] + 0.9 * (hi[1] - lo[1]));
    let mut z = hi[2] + half_len - depth;
    let mut y = y0;
    let mut dir = 1.0;
    let mut force = ForceRenderer::new(ForceParams::default());
    let rot = facing_x();
    let mut prev = ToolPose {
        position: [x0, y, z],
        rotation: rot,
    };
    let mut times = Vec::with_capacity(poses);
    let mut removed = 0u64;
    for _ in 0..poses {
        let mut p = prev.position;
        p[0] += dir * step;
        if p[0] > x1 || p[0] < x0 {
            // Next pass: sideways by half a blade width (or down a layer), then back.
            dir = -dir;
            p[0] = p[0].clamp(x0, x1);
            y += half_width.max(step);
            if y > y1 {
                y = y0;
                z -= depth / 2.0;
            }
            p[1] = y;
            p[2] = z;
        }
        let next = ToolPose {
            position: p,
            rotation: rot,
        };
        let t0 = Instant::now();
        let cut = work.carve(tool, &prev, &next).unwrap_or_default();
        let motion = [0, 1, 2].map(|a| next.position[a] - prev.position[a]);
        let f = force.step(&cut, work.spacing(), motion, 1e-3);
        times.push(t0.elapsed().as_secs_f64() * 1e6);
        std::hint::black_box(f);
        removed += cut.removed;
        prev = next;
    }
    times.sort_by(f64::total_cmp);
    Timing {
        median_us: percentile(&times, 0.5),
        p99_us: percentile(&times, 0.99),
        max_us: times.last().copied().unwrap_or(0.0),
        removed_per_pose: removed as f64 / poses as f64,
        surfels: work.surfels().len(),
    }
}

/// Time to build one display frame as the node does (copies of the occupancy bits and of
/// the surfel cloud's bytes, both kept up to date by the cuts), ms.
fn frame_build_ms(work: &Workpiece) -> f64 {
    let t0 = Instant::now();
    let bits = work.occupancy_bits().to_vec();
    let data = work.surfel_bytes().to_vec();
    std::hint::black_box((bits, data));
    t0.elapsed().as_secs_f64() * 1e3
}

/// `chronotope bench carve`.
///
/// # Errors
/// A workpiece or tool the model refuses.
pub fn bench_carve(poses: usize) -> Result<(), CliError> {
    let h = 1e-3;
    println!("Knife planing passes along x at 1 kHz (0.5 spacing per pose: 0.5 m/s at 1 mm), blade 4 spacings deep,");
    println!("each pass half a blade width further along y; {poses} poses per row; spacing 1 mm.");
    println!("Per-pose update = sweep + surface update + force.");
    println!();
    println!("| workpiece | points | surfels | knife (spacings) | removed/pose | median µs | p99 µs | max µs | frame build ms |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let row = |name: &str, dims: [usize; 3], knife: [f64; 3]| -> Result<(), CliError> {
        let hi = dims.map(|d| d as f64 * h);
        let mut work = Workpiece::block([0.0; 3], hi, h).map_err(err)?;
        let tool = Tool::knife(knife[0] * h, knife[1] * h, knife[2] * h, h).map_err(err)?;
        let t = time_stroke(&mut work, &tool, 0.5 * h, 4.0 * h, poses);
        println!(
            "| {name} | {} | {} | {}x{}x{} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            dims.iter().product::<usize>(),
            t.surfels,
            knife[0],
            knife[1],
            knife[2],
            t.removed_per_pose,
            t.median_us,
            t.p99_us,
            t.max_us,
            frame_build_ms(&work)
        );
        Ok(())
    };
    for n in [64usize, 128, 256] {
        row(&format!("block {n}^3"), [n, n, n], [20.0, 10.0, 2.0])?;
    }
    row(
        "plate 720x720x32 (~1.1M surfels)",
        [720, 720, 32],
        [20.0, 10.0, 2.0],
    )?;
    for l in [10.0, 40.0, 80.0] {
        row("block 256^3", [256, 256, 256], [l, l / 2.0, 2.0])?;
    }
    Ok(())
}

/// One accuracy case's result.
struct Accuracy {
    volume_err: f64,
    rms: f64,
    max: f64,
    hole_frac: f64,
    holes: usize,
    boundary_samples: usize,
    ms: f64,
}

/// The knife as a box: half-extents along its (tool) axes.
fn knife_half(tool: &Tool) -> Vec3 {
    let mut e = [0.0f64; 3];
    for v in tool.vertices() {
        for a in 0..3 {
            e[a] = e[a].max(v[a].abs());
        }
    }
    e
}

fn accuracy_case(h: f64, per_frame: f64, rotate: bool) -> Result<Accuracy, CliError> {
    // Block 60 x 40 x 20 mm; knife 8 mm (deep, along -z) x 6 mm (y) x 2 mm (x); a 40 mm
    // stroke from (10, 12) to (50, 28) mm with the blade 4 mm into the top.
    let lo = [0.0, 0.0, 0.0];
    let hi = [0.06, 0.04, 0.02];
    let mut work = Workpiece::block(lo, hi, h).map_err(err)?;
    let tool = Tool::knife(0.008, 0.006, 0.002, h).map_err(err)?;
    let start = [0.010, 0.012, 0.020];
    let end = [0.050, 0.028, 0.020];
    let turn = if rotate { 60f64.to_radians() } else { 0.0 };
    let pose = |t: f64| ToolPose {
        position: [0, 1, 2].map(|a| start[a] + (end[a] - start[a]) * t),
        rotation: {
            let q = Quat::from_axis_angle([0.0, 0.0, 1.0], turn * t);
            q.mul(&facing_x())
        },
    };
    let length = ((end[0] - start[0]).powi(2) + (end[1] - start[1]).powi(2)).sqrt();
    let frames = ((length / (per_frame * h)).ceil() as usize).max(1);
    let v0 = work.material_volume();
    // The stroke cut three times on fresh blocks; the fastest time kept.
    let mut ms = f64::INFINITY;
    for rep in 0..3 {
        if rep > 0 {
            work = Workpiece::block(lo, hi, h).map_err(err)?;
        }
        let t0 = Instant::now();
        let mut prev = pose(0.0);
        work.carve(&tool, &prev, &prev).map_err(err)?;
        for k in 1..=frames {
            let next = pose(k as f64 / frames as f64);
            work.carve(&tool, &prev, &next).map_err(err)?;
            prev = next;
        }
        ms = ms.min(t0.elapsed().as_secs_f64() * 1e3);
    }
    let removed = v0 - work.material_volume();
    // The exact solid: one sweep for a translation, 400 fine sweeps for the rotating move.
    let half = knife_half(&tool);
    let pieces = if rotate { 400 } else { 1 };
    let mut solid = SweptSolid::default();
    for j in 0..pieces {
        let (a, b) = (j as f64 / pieces as f64, (j + 1) as f64 / pieces as f64);
        let (pa, pb) = (pose(a), pose(b));
        solid.pieces.push(BoxSweep {
            c0: pa.position,
            rotation: pose((a + b) / 2.0).rotation,
            half,
            d: [0, 1, 2].map(|i| pb.position[i] - pa.position[i]),
        });
    }
    // Reference volume and true cut surface from a fine lattice (spacing href) over the
    // solid's bounding box within the block.
    let href = 0.0001;
    let r = half.iter().map(|e| e * e).sum::<f64>().sqrt();
    let bmin = [0, 1, 2].map(|a| (start[a].min(end[a]) - r).max(lo[a]));
    let bmax = [0, 1, 2].map(|a| (start[a].max(end[a]) + r).min(hi[a]));
    let n = [0, 1, 2].map(|a| ((bmax[a] - bmin[a]) / href).ceil() as usize);
    let at = |i: usize, j: usize, k: usize| {
        [
            bmin[0] + (i as f64 + 0.5) * href,
            bmin[1] + (j as f64 + 0.5) * href,
            bmin[2] + (k as f64 + 0.5) * href,
        ]
    };
    let mut inside = vec![false; n[0] * n[1] * n[2]];
    for piece in &solid.pieces {
        // The piece's own bounding box on the fine lattice.
        let mut pmin = [f64::INFINITY; 3];
        let mut pmax = [f64::NEG_INFINITY; 3];
        for c in [piece.c0, [0, 1, 2].map(|a| piece.c0[a] + piece.d[a])] {
            for a in 0..3 {
                pmin[a] = pmin[a].min(c[a] - r);
                pmax[a] = pmax[a].max(c[a] + r);
            }
        }
        let rng = |a: usize| {
            let l = ((pmin[a] - bmin[a]) / href).floor().max(0.0) as usize;
            let u = (((pmax[a] - bmin[a]) / href).ceil().max(0.0) as usize).min(n[a]);
            l..u
        };
        for k in rng(2) {
            for j in rng(1) {
                for i in rng(0) {
                    let idx = i + n[0] * (j + n[1] * k);
                    if !inside[idx] && piece.contains(at(i, j, k)) {
                        inside[idx] = true;
                    }
                }
            }
        }
    }
    let exact_removed = inside.iter().filter(|&&b| b).count() as f64 * href.powi(3);
    // Surfel distance to the true surface: the cut surfels (not on the untouched block faces).
    let (mut sum2, mut max, mut count) = (0.0f64, 0.0f64, 0usize);
    for s in work.surfels() {
        let p = s.position.map(f64::from);
        if box_signed_distance(lo, hi, p).abs() < 1e-9 {
            continue;
        }
        let d = solid.carved_block_distance(lo, hi, p).abs();
        sum2 += d * d;
        max = max.max(d);
        count += 1;
    }
    // Holes: true-surface samples (fine lattice points inside the solid with a neighbour
    // outside it, away from the block's faces) farther than a surfel radius from every surfel.
    let mut hash: HashMap<[i64; 3], Vec<Vec3>> = HashMap::new();
    let cell = |p: Vec3| p.map(|v| (v / h).floor() as i64);
    for s in work.surfels() {
        let p = s.position.map(f64::from);
        hash.entry(cell(p)).or_default().push(p);
    }
    let radius = work.surfel_radius();
    let (mut samples, mut holes) = (0usize, 0usize);
    for k in 1..n[2].saturating_sub(1) {
        for j in 1..n[1].saturating_sub(1) {
            for i in 1..n[0].saturating_sub(1) {
                let idx = i + n[0] * (j + n[1] * k);
                if !inside[idx] {
                    continue;
                }
                let edge = [1, n[0], n[0] * n[1]]
                    .iter()
                    .any(|&s| !inside[idx - s] || !inside[idx + s]);
                let p = at(i, j, k);
                if !edge || box_signed_distance(lo, hi, p) > -h {
                    continue;
                }
                samples += 1;
                let c = cell(p);
                let mut near = false;
                'search: for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            if let Some(v) = hash.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                                if v.iter().any(|q| {
                                    (0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>()
                                        <= (radius + href).powi(2)
                                }) {
                                    near = true;
                                    break 'search;
                                }
                            }
                        }
                    }
                }
                if !near {
                    holes += 1;
                }
            }
        }
    }
    Ok(Accuracy {
        volume_err: (removed - exact_removed) / exact_removed,
        rms: if count > 0 {
            (sum2 / count as f64).sqrt()
        } else {
            0.0
        },
        max,
        hole_frac: holes as f64 / samples.max(1) as f64,
        holes,
        boundary_samples: samples,
        ms,
    })
}

/// Coefficient of variation of the rendered force over a steady cut at 1 kHz (after 0.2 s),
/// and its mean (N).
fn force_cv(h: f64, model: ForceModel, filtered: bool) -> Result<(f64, f64), CliError> {
    let mut work = Workpiece::block([0.0; 3], [0.08, 0.02, 0.02], h).map_err(err)?;
    let tool = Tool::knife(0.008, 0.006, 0.002, h).map_err(err)?;
    let mut params = ForceParams {
        model,
        ..ForceParams::default()
    };
    if !filtered {
        params.cutoff_hz = 0.0;
        params.coupling_stiffness = 0.0;
        params.max_force = f64::INFINITY;
    }
    let mut force = ForceRenderer::new(params);
    let speed = 0.05; // m/s
    let dt = 1e-3;
    let rot = facing_x();
    let z = 0.02 + 0.004 - 0.003; // 3 mm deep
    let mut prev = ToolPose {
        position: [0.005, 0.01, z],
        rotation: rot,
    };
    let mut mags = Vec::new();
    for k in 1..=1000 {
        let next = ToolPose {
            position: [prev.position[0] + speed * dt, 0.01, z],
            rotation: rot,
        };
        let cut = work.carve(&tool, &prev, &next).map_err(err)?;
        let f = force.step(&cut, h, [speed * dt, 0.0, 0.0], dt);
        if k > 200 {
            mags.push((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt());
        }
        prev = next;
    }
    let mean = mags.iter().sum::<f64>() / mags.len() as f64;
    let var = mags.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / mags.len() as f64;
    Ok((var.sqrt() / mean.max(1e-300), mean))
}

/// `chronotope bench carve --accuracy`: prints the tables and writes them to `out` (Markdown).
///
/// # Errors
/// A workpiece the model refuses, or `out` cannot be written.
pub fn bench_carve_accuracy(
    spacings_mm: &[f64],
    out: Option<&std::path::Path>,
) -> Result<(), CliError> {
    let mut md = String::new();
    md.push_str("# Carving accuracy (`chronotope bench carve --accuracy --out docs/carving-accuracy.md`)\n\n");
    md.push_str(
        "Block 60 x 40 x 20 mm; knife 8 x 6 x 2 mm (a box), 4 mm into the top, a 40 mm stroke\n",
    );
    md.push_str(
        "from (10, 12) to (50, 28) mm (diagonal to the grid), cut with moves of 1, 10 and 40\n",
    );
    md.push_str(
        "spacings per frame; with rotation, the knife also turns 60° about z over the stroke.\n",
    );
    md.push_str(
        "Exact result: block minus the exact swept solid (one exact translation sweep; for the\n",
    );
    md.push_str(
        "rotating stroke, the union of 400 exact translation sweeps, within 0.02 mm of the\n",
    );
    md.push_str(
        "rotating sweep). Removed volume of the exact result by counting a 0.1 mm lattice;\n",
    );
    md.push_str(
        "surfel distance = |max(d_block, -d_sweep)| of the cut surfels (the block's untouched\n",
    );
    md.push_str(
        "faces left out); holes = true-surface samples (0.1 mm lattice points in the sweep next\n",
    );
    md.push_str(
        "to one outside it, one spacing away from the block's faces) with no surfel within a\n",
    );
    md.push_str(
        "surfel radius (√3/2 spacing). Time = carving the whole stroke (fastest of three).\n\n",
    );
    md.push_str("| spacing mm | spacings/frame | rotation | frames | volume err | surfel RMS mm | surfel max mm | holes (samples) | time ms |\n");
    md.push_str("|---|---|---|---|---|---|---|---|---|\n");
    print!("{md}");
    for &s in spacings_mm {
        let h = s * 1e-3;
        for per in [1.0, 10.0, 40.0] {
            for rotate in [false, true] {
                let a = accuracy_case(h, per, rotate)?;
                let frames = ((0.04f64.hypot(0.016) / (per * h)).ceil() as usize).max(1);
                let line = format!(
                    "| {s} | {per} | {} | {frames} | {:+.2}% | {:.3} | {:.3} | {:.2}% ({} of {}) | {:.1} |\n",
                    if rotate { "60°" } else { "no" },
                    a.volume_err * 100.0,
                    a.rms * 1e3,
                    a.max * 1e3,
                    a.hole_frac * 100.0,
                    a.holes,
                    a.boundary_samples,
                    a.ms
                );
                print!("{line}");
                md.push_str(&line);
            }
        }
    }
    let mut f = String::new();
    f.push_str(
        "\nForce in a steady cut: knife 3 mm deep moving along x at 50 mm/s, poses at 1 kHz,\n",
    );
    f.push_str(
        "0.8 s after the first 0.2 s. CV = standard deviation / mean of |F|. Filtered = the\n",
    );
    f.push_str("default 30 Hz low-pass and virtual coupling (2000 N/m, 8 N·s/m, 0.02 kg).\n\n");
    f.push_str("| spacing mm | force | mean N | CV |\n|---|---|---|---|\n");
    for &s in spacings_mm {
        let h = s * 1e-3;
        for (name, model, filtered) in [
            ("eq. 8 (count), raw", ForceModel::Count, false),
            ("cross-section (volume), raw", ForceModel::Volume, false),
            ("cross-section (volume), filtered", ForceModel::Volume, true),
            ("layer ahead (section), raw", ForceModel::Section, false),
            ("layer ahead (section), filtered", ForceModel::Section, true),
        ] {
            let (cv, mean) = force_cv(h, model, filtered)?;
            f.push_str(&format!("| {s} | {name} | {mean:.3} | {cv:.2} |\n"));
        }
    }
    print!("{f}");
    md.push_str(&f);
    if let Some(path) = out {
        std::fs::write(path, md).map_err(|source| CliError::Io {
            path: path.to_owned(),
            source,
        })?;
    }
    Ok(())
}
