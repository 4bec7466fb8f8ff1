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

use super::BenchError;
use crate::carving::exact::{box_signed_distance, BoxSweep, SweptSolid};
use crate::carving::{
    ForceModel, ForceParams, ForceRenderer, Quat, Tool, ToolPose, Vec3, Workpiece,
};
use crate::mesh::stats::percentile;

fn err(e: impl std::fmt::Display) -> BenchError {
    BenchError::Usage(e.to_string())
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
pub fn bench_carve(poses: usize) -> Result<(), BenchError> {
    let h = 1e-3;
    println!("Knife planing passes along x at 1 kHz (0.5 spacing per pose: 0.5 m/s at 1 mm), blade 4 spacings deep,");
    println!("each pass half a blade width further along y; {poses} poses per row; spacing 1 mm.");
    println!("Per-pose update = sweep + surface update + force.");
    println!();
    println!("| workpiece | points | surfels | knife (spacings) | removed/pose | median µs | p99 µs | max µs | frame build ms |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let row = |name: &str, dims: [usize; 3], knife: [f64; 3]| -> Result<(), BenchError> {
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

fn accuracy_case(h: f64, per_frame: f64, rotate: bool) -> Result<Accuracy, BenchError> {
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

/// How the `section` force reads the layer ahead in [`force_cv`].
#[derive(Clone, Copy, PartialEq)]
enum Ahead {
    /// As the model does ([`crate::carving::Workpiece::section_ahead`], sub-voxel weights).
    SubVoxel,
    /// The material points within one spacing ahead, counted whole (the estimate before
    /// the sub-voxel one; [`crate::carving::Workpiece::material_ahead`]).
    Count,
}

/// A steady cut's force statistics.
struct ForceStats {
    /// Coefficient of variation of |F|.
    cv: f64,
    /// Mean |F| (N).
    mean: f64,
    /// Median time of one pose's update (carve + force), µs.
    pose_us: f64,
}

/// The rendered force over a steady cut at 1 kHz (after 0.2 s): the knife 3 mm deep, facing
/// its motion, moving at 50 mm/s at `angle_deg` to the grid's x axis in the x-y plane.
fn force_cv(
    h: f64,
    model: ForceModel,
    filtered: bool,
    angle_deg: f64,
    ahead: Ahead,
) -> Result<ForceStats, BenchError> {
    let speed = 0.05; // m/s
    let dt = 1e-3;
    let poses = 1000;
    let (sin, cos) = angle_deg.to_radians().sin_cos();
    let start = [0.005, 0.01, 0.0];
    let travel = speed * dt * poses as f64;
    // The block holds the stroke with 10 mm to spare past its end and beside it.
    let hi = [
        (start[0] + travel * cos + 0.01).max(0.02),
        (start[1] + travel * sin + 0.01).max(0.02),
        0.02,
    ];
    let mut work = Workpiece::block([0.0, 0.0, 0.01], hi, h).map_err(err)?;
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
    let rot = Quat::from_axis_angle([0.0, 0.0, 1.0], angle_deg.to_radians()).mul(&facing_x());
    let z = 0.02 + 0.004 - 0.003; // 3 mm deep
    let step = [speed * dt * cos, speed * dt * sin, 0.0];
    let mut prev = ToolPose {
        position: [start[0], start[1], z],
        rotation: rot,
    };
    let mut mags = Vec::with_capacity(poses);
    let mut times = Vec::with_capacity(poses);
    for k in 1..=poses {
        let next = ToolPose {
            position: [0, 1, 2].map(|a| prev.position[a] + step[a]),
            rotation: rot,
        };
        let t0 = Instant::now();
        let mut cut = work.carve(&tool, &prev, &next).map_err(err)?;
        if ahead == Ahead::Count {
            cut.ahead_area = cut.ahead as f64 * h * h;
        }
        let f = force.step(&cut, h, step, dt);
        times.push(t0.elapsed().as_secs_f64() * 1e6);
        if k > 200 {
            mags.push((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt());
        }
        prev = next;
    }
    let mean = mags.iter().sum::<f64>() / mags.len() as f64;
    let var = mags.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / mags.len() as f64;
    times.sort_by(f64::total_cmp);
    Ok(ForceStats {
        cv: var.sqrt() / mean.max(1e-300),
        mean,
        pose_us: percentile(&times, 0.5),
    })
}

/// Median time (µs) of reading the layer ahead by counting points and with sub-voxel
/// weights, on a steady diagonal cut at `angle_deg`, spacing `h`.
fn ahead_cost_us(h: f64, angle_deg: f64) -> Result<(f64, f64), BenchError> {
    let (sin, cos) = angle_deg.to_radians().sin_cos();
    let mut work = Workpiece::block([0.0, 0.0, 0.01], [0.04, 0.04, 0.02], h).map_err(err)?;
    let tool = Tool::knife(0.008, 0.006, 0.002, h).map_err(err)?;
    let rot = Quat::from_axis_angle([0.0, 0.0, 1.0], angle_deg.to_radians()).mul(&facing_x());
    let step = [5e-5 * cos, 5e-5 * sin, 0.0];
    let mut prev = ToolPose {
        position: [0.005, 0.01, 0.021],
        rotation: rot,
    };
    let (mut count, mut sub) = (Vec::new(), Vec::new());
    for _ in 0..400 {
        let next = ToolPose {
            position: [0, 1, 2].map(|a| prev.position[a] + step[a]),
            rotation: rot,
        };
        work.carve(&tool, &prev, &next).map_err(err)?;
        let t0 = Instant::now();
        std::hint::black_box(work.material_ahead(&tool, &next, step));
        let t1 = Instant::now();
        std::hint::black_box(work.section_ahead(&tool, &next, step));
        let t2 = Instant::now();
        count.push((t1 - t0).as_secs_f64() * 1e6);
        sub.push((t2 - t1).as_secs_f64() * 1e6);
        prev = next;
    }
    count.sort_by(f64::total_cmp);
    sub.sort_by(f64::total_cmp);
    Ok((percentile(&count, 0.5), percentile(&sub, 0.5)))
}

/// One chisel-edge case's result: the edge drawn by the eq. 6 surfels alone and by the
/// eq. 7 polygon strip, against the true edges of the groove.
struct EdgeAccuracy {
    surfels: usize,
    polygons: usize,
    unmatched: usize,
    strip_ends: usize,
    /// Edge surfel centres' distance to the true edge: RMS and max (m).
    centre_rms: f64,
    centre_max: f64,
    /// True-edge samples' distance to the nearest edge surfel centre: mean and max (m).
    gap_mean_before: f64,
    gap_max_before: f64,
    /// ... to the polygon strip (the segments `P1 P2`): mean and max (m).
    gap_mean_after: f64,
    gap_max_after: f64,
    /// Time to build the polygons (ms).
    build_ms: f64,
    /// Median and p99 time of one pose's carve (µs), eq. 6 and its band included.
    pose_us: (f64, f64),
}

fn point_segment(p: Vec3, a: Vec3, b: Vec3) -> f64 {
    let ab = [0, 1, 2].map(|k| b[k] - a[k]);
    let ap = [0, 1, 2].map(|k| p[k] - a[k]);
    let l2 = ab.iter().map(|v| v * v).sum::<f64>();
    let t = if l2 > 0.0 {
        ((0..3).map(|k| ab[k] * ap[k]).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3)
        .map(|k| (ap[k] - t * ab[k]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// A chisel (3 mm wide, 1.5 mm high: sides at 45°; 1 mm thick) stroke 20 mm long at
/// `angle_deg` to the grid's x axis, apex 1 mm below the top of a 40 x 30 x 10 mm block, in
/// moves of half a spacing; its two groove edges on the top face against the edge surfels
/// and the eq. 7 strip.
fn edge_case(h: f64, angle_deg: f64) -> Result<EdgeAccuracy, BenchError> {
    use crate::carving::edge::EDGE_POLYGON_WIDTH_SPACINGS;
    let lo = [0.0, 0.0, 0.0];
    let hi = [0.04, 0.03, 0.01];
    let mut work = Workpiece::block(lo, hi, h).map_err(err)?;
    let (width, height) = (0.003, 0.0015);
    let tool = Tool::chisel(width, height, 0.001, h).map_err(err)?;
    let rot = Quat::from_axis_angle([0.0, 0.0, 1.0], angle_deg.to_radians());
    let (sin, cos) = angle_deg.to_radians().sin_cos();
    let start = [0.01, 0.008, hi[2] - 0.001];
    let length = 0.02;
    let moves = (length / (h / 2.0)).ceil() as usize;
    let at = |t: f64| ToolPose {
        position: [start[0] + t * cos, start[1] + t * sin, start[2]],
        rotation: rot,
    };
    let mut prev = at(0.0);
    work.carve(&tool, &prev, &prev).map_err(err)?;
    let mut times = Vec::with_capacity(moves);
    for k in 1..=moves {
        let next = at(length * k as f64 / moves as f64);
        let t0 = Instant::now();
        work.carve(&tool, &prev, &next).map_err(err)?;
        times.push(t0.elapsed().as_secs_f64() * 1e6);
        prev = next;
    }
    times.sort_by(f64::total_cmp);
    let t0 = Instant::now();
    let mut polys = Vec::new();
    let report = work
        .edge_polygons(EDGE_POLYGON_WIDTH_SPACINGS * h, &mut polys)
        .map_err(err)?;
    let build_ms = t0.elapsed().as_secs_f64() * 1e3;
    // The true edges: the sides' planes (through the apex line, containing the motion) on
    // the top face, at tool-frame y = ±(width/2) z/height with z the apex's depth.
    let depth = hi[2] - start[2];
    let side = width / 2.0 * depth / height;
    let edge = |s: f64, t: f64| -> Vec3 {
        let q = rot.rotate([t, s * side, depth]);
        [start[0] + q[0], start[1] + q[1], start[2] + q[2]]
    };
    // Along the edge, stay two spacings inside the stroke's ends.
    let (t_lo, t_hi) = (2.0 * h, length - 2.0 * h);
    let red: Vec<Vec3> = work
        .surfels()
        .iter()
        .filter(|s| s.colour == 0xd02020)
        .map(|s| s.position.map(f64::from))
        .collect();
    let line_distance = |p: Vec3| -> Option<f64> {
        [-1.0, 1.0]
            .iter()
            .filter_map(|&s| {
                let a = edge(s, 0.0);
                let u = [cos, sin, 0.0];
                let t = (0..3).map(|k| (p[k] - a[k]) * u[k]).sum::<f64>();
                (t >= t_lo && t <= t_hi).then(|| point_segment(p, edge(s, t_lo), edge(s, t_hi)))
            })
            .reduce(f64::min)
    };
    let (mut sum2, mut cmax, mut n) = (0.0f64, 0.0f64, 0usize);
    for &p in &red {
        if let Some(d) = line_distance(p) {
            sum2 += d * d;
            cmax = cmax.max(d);
            n += 1;
        }
    }
    let segs: Vec<(Vec3, Vec3)> = polys
        .iter()
        .map(|p| (p.vertices[0].map(f64::from), p.vertices[1].map(f64::from)))
        .collect();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    let samples = ((t_hi - t_lo) / (h / 20.0)).ceil() as usize;
    for s in [-1.0, 1.0] {
        for k in 0..=samples {
            let q = edge(s, t_lo + (t_hi - t_lo) * k as f64 / samples as f64);
            let b = red
                .iter()
                .map(|&p| (0..3).map(|a| (p[a] - q[a]).powi(2)).sum::<f64>().sqrt())
                .fold(f64::INFINITY, f64::min);
            let a = segs
                .iter()
                .map(|&(p1, p2)| point_segment(q, p1, p2))
                .fold(f64::INFINITY, f64::min);
            before.push(b);
            after.push(a);
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let max = |v: &[f64]| v.iter().copied().fold(0.0f64, f64::max);
    Ok(EdgeAccuracy {
        surfels: report.edge_surfels,
        polygons: report.polygons,
        unmatched: report.unmatched,
        strip_ends: report.strip_ends,
        centre_rms: (sum2 / n.max(1) as f64).sqrt(),
        centre_max: cmax,
        gap_mean_before: mean(&before),
        gap_max_before: max(&before),
        gap_mean_after: mean(&after),
        gap_max_after: max(&after),
        build_ms,
        pose_us: (percentile(&times, 0.5), percentile(&times, 0.99)),
    })
}

/// Agreement of a tool-surfel classification with the exact one.
#[derive(Default)]
struct Agreement {
    /// Tool surfels compared (those not on the exact surface).
    total: usize,
    /// Same material / air answer.
    material: usize,
    /// Of those farther than half a spacing from the exact surface: count and agreeing.
    clear: usize,
    clear_material: usize,
    /// Same class of three (OUTSIDE, BOUND within d_s, INSIDE).
    class: usize,
    /// Time (µs per tool surfel).
    us: f64,
}

/// The seed's eqs. 3-5 against the grid's classification of the tool surfels of one knife
/// move (8 x 6 x 2 mm, crossing a 6 mm wide, 3 mm deep slot cut before it, or the plain
/// block), against the exact workpiece.
fn eq3_case(h: f64, slot: bool) -> Result<(usize, Agreement, Agreement), BenchError> {
    use crate::carving::toolsurfel::{sweep_surfels, ToolClass};
    let lo = [0.0, 0.0, 0.0];
    let hi = [0.04, 0.03, 0.02];
    let mut work = Workpiece::block(lo, hi, h).map_err(err)?;
    let tool = Tool::knife(0.008, 0.006, 0.002, h).map_err(err)?;
    let z = hi[2] + 0.004 - 0.003;
    let mut solid = SweptSolid::default();
    if slot {
        let a = ToolPose {
            position: [0.005, 0.015, z],
            rotation: facing_x(),
        };
        let b = ToolPose {
            position: [0.035, 0.015, z],
            rotation: facing_x(),
        };
        work.carve(&tool, &a, &a).map_err(err)?;
        work.carve(&tool, &a, &b).map_err(err)?;
        solid.pieces.push(BoxSweep {
            c0: a.position,
            rotation: a.rotation,
            half: knife_half(&tool),
            d: [0.03, 0.0, 0.0],
        });
    }
    // The second move: across the slot along y, 1 mm deeper, turned to face y.
    let rot = Quat::from_axis_angle([0.0, 0.0, 1.0], std::f64::consts::FRAC_PI_2).mul(&facing_x());
    let from = ToolPose {
        position: [0.02, 0.004, z - 0.001],
        rotation: rot,
    };
    let to = ToolPose {
        position: [0.02, 0.026, z - 0.001],
        rotation: rot,
    };
    let surfels = sweep_surfels(&tool, &from, &to, h).map_err(err)?;
    let d_s = h;
    let exact = |x: Vec3| {
        let sd = solid.carved_block_distance(lo, hi, x);
        let class = if sd >= 0.0 {
            ToolClass::Outside
        } else if sd > -d_s {
            ToolClass::Bound
        } else {
            ToolClass::Inside
        };
        (sd, class)
    };
    let score = |f: &dyn Fn(Vec3) -> ToolClass| {
        let mut a = Agreement::default();
        let t0 = Instant::now();
        let got: Vec<ToolClass> = surfels.iter().map(|s| f(s.position)).collect();
        a.us = t0.elapsed().as_secs_f64() * 1e6 / surfels.len().max(1) as f64;
        for (s, g) in surfels.iter().zip(got) {
            let (sd, want) = exact(s.position);
            if sd.abs() < 1e-9 {
                continue;
            }
            let same = (g == ToolClass::Outside) == (want == ToolClass::Outside);
            a.total += 1;
            a.material += usize::from(same);
            a.class += usize::from(g == want);
            if sd.abs() > h {
                a.clear += 1;
                a.clear_material += usize::from(same);
            }
        }
        a
    };
    let eq3 = score(&|x| work.classify_eq3(x, d_s));
    let grid = score(&|x| work.classify_grid(x, d_s));
    Ok((surfels.len(), eq3, grid))
}

/// `chronotope bench carve --accuracy`: prints the tables and writes them to `out` (Markdown).
///
/// # Errors
/// A workpiece the model refuses, or `out` cannot be written.
pub fn bench_carve_accuracy(
    spacings_mm: &[f64],
    out: Option<&std::path::Path>,
) -> Result<(), BenchError> {
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
        "\nForce in a steady cut: knife 8 x 6 x 2 mm, 3 mm deep, facing its motion, moving at\n",
    );
    f.push_str(
        "50 mm/s at 0°, 30° or 45° to the grid's x axis (in the x-y plane), poses at 1 kHz;\n",
    );
    f.push_str(
        "statistics over 0.8 s after the first 0.2 s. CV = standard deviation / mean of |F|.\n",
    );
    f.push_str("Filtered = the default 30 Hz low-pass and virtual coupling (2000 N/m, 8 N·s/m,\n");
    f.push_str(
        "0.02 kg). `section`, count = the layer ahead read by counting the points within one\n",
    );
    f.push_str(
        "spacing ahead (the estimate before); `section`, sub-voxel = the model's estimate\n",
    );
    f.push_str(
        "(row chords through a window half a spacing ahead). Pose µs = median of one pose's\n",
    );
    f.push_str("update (carve + force).\n\n");
    f.push_str(
        "| spacing mm | angle | force | mean N | CV | pose µs |\n|---|---|---|---|---|---|\n",
    );
    print!("{f}");
    for &s in spacings_mm {
        let h = s * 1e-3;
        for angle in [0.0, 30.0, 45.0] {
            for (name, model, filtered, ahead) in [
                (
                    "eq. 8 (count), raw",
                    ForceModel::Count,
                    false,
                    Ahead::SubVoxel,
                ),
                (
                    "cross-section (volume), raw",
                    ForceModel::Volume,
                    false,
                    Ahead::SubVoxel,
                ),
                (
                    "cross-section (volume), filtered",
                    ForceModel::Volume,
                    true,
                    Ahead::SubVoxel,
                ),
                (
                    "layer ahead (section), count, raw",
                    ForceModel::Section,
                    false,
                    Ahead::Count,
                ),
                (
                    "layer ahead (section), count, filtered",
                    ForceModel::Section,
                    true,
                    Ahead::Count,
                ),
                (
                    "layer ahead (section), sub-voxel, raw",
                    ForceModel::Section,
                    false,
                    Ahead::SubVoxel,
                ),
                (
                    "layer ahead (section), sub-voxel, filtered",
                    ForceModel::Section,
                    true,
                    Ahead::SubVoxel,
                ),
            ] {
                let r = force_cv(h, model, filtered, angle, ahead)?;
                let line = format!(
                    "| {s} | {angle}° | {name} | {:.3} | {:.3} | {:.1} |\n",
                    r.mean, r.cv, r.pose_us
                );
                print!("{line}");
                f.push_str(&line);
            }
        }
    }
    let mut c = String::from(
        "\nCost of reading the layer ahead (median µs per pose, steady cut as above):\n\n\
         | spacing mm | angle | count | sub-voxel |\n|---|---|---|---|\n",
    );
    for &s in spacings_mm {
        for angle in [0.0, 30.0, 45.0] {
            let (count, sub) = ahead_cost_us(s * 1e-3, angle)?;
            c.push_str(&format!("| {s} | {angle}° | {count:.1} | {sub:.1} |\n"));
        }
    }
    f.push_str(&c);
    print!("{c}");
    md.push_str(&f);
    let mut e = String::new();
    e.push_str(
        "\nChisel edges (seed eqs. 6-7): a chisel 3 mm wide, 1.5 mm high (sides at 45°), 1 mm\n",
    );
    e.push_str(
        "thick, apex 1 mm below the top of a 40 x 30 x 10 mm block, a 20 mm stroke at 0°, 30°\n",
    );
    e.push_str(
        "or 45° to the grid's x axis in moves of half a spacing. The true edges: the lines where\n",
    );
    e.push_str(
        "the groove's sides meet the top (2 mm apart), two spacings inside the stroke's ends.\n",
    );
    e.push_str(
        "Centre = distance of the eq. 6 edge surfels' centres to the true edge. Gap = distance\n",
    );
    e.push_str("from a true-edge sample (every 1/20 spacing) to the nearest edge surfel centre\n");
    e.push_str(
        "(before: the edge drawn by discs alone, each also overhanging the edge by its radius,\n",
    );
    e.push_str(
        "√3/2 spacing) or to the eq. 7 strip's edge side P1 P2 (after; polygons half a spacing\n",
    );
    e.push_str(
        "wide on each side). Build = time to build the polygons from the surfels (display rate);\n",
    );
    e.push_str(
        "pose µs = median / p99 of one move's carve (sweep, exposure, eq. 6 and its band).\n\n",
    );
    e.push_str("| spacing mm | angle | edge surfels | polygons (unmatched, strip ends) | centre RMS / max mm | gap before mean / max mm | gap after mean / max mm | build ms | pose µs |\n");
    e.push_str("|---|---|---|---|---|---|---|---|---|\n");
    print!("{e}");
    for &s in spacings_mm {
        for angle in [0.0, 30.0, 45.0] {
            let a = edge_case(s * 1e-3, angle)?;
            let line = format!(
                "| {s} | {angle}° | {} | {} ({}, {}) | {:.4} / {:.4} | {:.3} / {:.3} | {:.4} / {:.4} | {:.2} | {:.1} / {:.1} |\n",
                a.surfels,
                a.polygons,
                a.unmatched,
                a.strip_ends,
                a.centre_rms * 1e3,
                a.centre_max * 1e3,
                a.gap_mean_before * 1e3,
                a.gap_max_before * 1e3,
                a.gap_mean_after * 1e3,
                a.gap_max_after * 1e3,
                a.build_ms,
                a.pose_us.0,
                a.pose_us.1
            );
            print!("{line}");
            e.push_str(&line);
        }
    }
    md.push_str(&e);
    let mut t = String::new();
    t.push_str(
        "\nTool surfels (seed eqs. 3-5) against the grid: the surfels of one knife move (8 x 6 x\n",
    );
    t.push_str(
        "2 mm, 22 mm along y, 4 mm deep) on a 40 x 30 x 20 mm block, plain or with a 6 mm wide,\n",
    );
    t.push_str(
        "3 mm deep slot cut along x before it; each classified by eqs. 3-5 as written (against\n",
    );
    t.push_str(
        "every surfel of the workpiece) and by the grid (the nearest point's flag; BOUND if a\n",
    );
    t.push_str("surfel within two points is closer than d_s = one spacing), against the exact\n");
    t.push_str(
        "workpiece (block minus the slot's exact sweep). Material = same material / air answer;\n",
    );
    t.push_str(
        "clear = the same for tool surfels farther than a spacing from the exact surface (wrong of n);\n",
    );
    t.push_str("class = same of OUTSIDE / BOUND / INSIDE. µs per tool surfel.\n\n");
    t.push_str(
        "| spacing mm | workpiece | tool surfels | method | material | clear | class | µs |\n",
    );
    t.push_str("|---|---|---|---|---|---|---|---|\n");
    print!("{t}");
    for &s in spacings_mm {
        for slot in [false, true] {
            let (n, eq3, grid) = eq3_case(s * 1e-3, slot)?;
            for (name, a) in [("eqs. 3-5", eq3), ("grid", grid)] {
                let pct = |k: usize, of: usize| 100.0 * k as f64 / of.max(1) as f64;
                let line = format!(
                    "| {s} | {} | {n} | {name} | {:.2}% | {:.2}% ({} of {}) | {:.2}% | {:.3} |\n",
                    if slot { "slot" } else { "block" },
                    pct(a.material, a.total),
                    pct(a.clear_material, a.clear),
                    a.clear - a.clear_material,
                    a.clear,
                    pct(a.class, a.total),
                    a.us
                );
                print!("{line}");
                t.push_str(&line);
            }
        }
    }
    md.push_str(&t);
    if let Some(path) = out {
        crate::fsio::write_atomic(path, md.as_bytes()).map_err(|source| BenchError::Io {
            path: path.to_owned(),
            source,
        })?;
    }
    Ok(())
}
