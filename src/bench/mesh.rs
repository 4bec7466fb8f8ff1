//! `chronotope bench mesh` and `bench accuracy`: meshing throughput on a synthetic scene held
//! in memory, the frames played through a launch config's nodes, and the checker's error
//! against run time on four-spheres.
//!
//! Frames are generated before the clock starts, so the figure is the mesher alone (decode,
//! march, and the streaming validation timed separately); `chronotope mesh BAG --stats`
//! measures the end-to-end run from a bag.

use super::BenchError;
use crate::checker::oracle::{shortest_translation, MovingSphere};
use crate::checker::resolve::{suggest_translation, Metric};
use crate::checker::{bounds, check_pair, CommonLattice, PairResult, Prepared};
use crate::mesh::glue::{BodyAssembler, BodyMesh};
use crate::mesh::stats::{percentile, StatsAccumulator};
use crate::mesh::{CapSide, Mesher, MesherOptions};
use crate::msg::{VoxelEncoding, VoxelGrid};
use crate::node::launch::{LaunchConfig, LaunchError};
use crate::node::Node;
use crate::scene::{build_scene, Rasterizer, SceneName, SceneOptions, FOUR_SPHERES};
use std::time::Instant;

/// Builds the nodes of a launch config over the given body topics (the command line's
/// replay does it; passed in so that benchmarks do not depend on the command line).
pub type BuildNodes<'a> =
    &'a dyn Fn(&LaunchConfig, &[String]) -> Result<Vec<Box<dyn Node>>, LaunchError>;

fn sphere(i: usize) -> MovingSphere {
    let p = &FOUR_SPHERES;
    MovingSphere {
        c0: p.centres_at_t0[i],
        v: p.velocities[i],
        r: p.radius,
        t: p.t_span,
    }
}

/// The checker's error against run time on four-spheres at each grid and encoding: intervals,
/// first contacts, overlap hypervolumes and translations against the exact answers; with
/// `svg`, a log-log plot of the errors against the run time.
///
/// # Errors
/// Bad scene options, a check that fails, or a plot that cannot be written.
pub fn bench_accuracy(
    grids: &[u32],
    encodings: &[VoxelEncoding],
    svg: Option<&std::path::Path>,
) -> Result<(), BenchError> {
    let mut points: Vec<(String, f64, f64)> = Vec::new();
    let c = 1.0;
    let exact_single = shortest_translation(&sphere(0), &[sphere(1)], c);
    let exact_multi = shortest_translation(&sphere(0), &[sphere(1), sphere(2), sphere(3)], c);
    println!(
        "exact shortest translation of A (metric c = 1 m/s): against B {:.5} m along {:?};",
        exact_single.0,
        exact_single.1.map(|x| (x * 1000.0).round() / 1000.0)
    );
    println!(
        "  against B, C and D at once {:.5} m along {:?}",
        exact_multi.0,
        exact_multi.1.map(|x| (x * 1000.0).round() / 1000.0)
    );
    println!();
    println!("| grid | encoding | tets/body | mesh s | check s | resolve s | first contact err / bound (s) | interval end err / bound (s) | overlap err / bound | translate A vs B: got / exact | A vs B,C,D: got / exact | translation bound (m) | verified | errors within bound |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for &n in grids {
        for &e in encodings {
            let o = SceneOptions::for_scene(SceneName::FourSpheres)
                .grid(n)
                .frames(n + 1)
                .encoding(e.into());
            let scene = build_scene(SceneName::FourSpheres, &o)?;
            let t0 = Instant::now();
            let mut bodies = Vec::new();
            let mut raster = Rasterizer::new();
            let mut grid = VoxelGrid::default();
            for b in 0..4 {
                let mut asm = BodyAssembler::new(MesherOptions::default())?.keep_frames(true);
                for k in 0..scene.frame_count() {
                    scene.write_frame(b, k, &mut raster, &mut grid)?;
                    asm.push(&grid.frame_ref())?;
                }
                bodies.push(asm.finish());
            }
            let t_mesh = t0.elapsed().as_secs_f64();
            let topics = scene.topics();
            let named: Vec<(&str, &BodyMesh)> = topics
                .iter()
                .map(|t| t.as_str())
                .zip(bodies.iter())
                .collect();
            let lat = CommonLattice::of(&named)?;
            let t1 = Instant::now();
            let prepared: Vec<Prepared> = named
                .iter()
                .map(|(id, b)| lat.prepare(id, b))
                .collect::<Result<_, _>>()?;
            let results: Vec<PairResult> = (1..4)
                .map(|j| check_pair(&prepared[0], &prepared[j]))
                .collect();
            let t_check = t1.elapsed().as_secs_f64();
            let origin = lat.stamps_ns[0];
            let (mut err_first, mut err_ends, mut err_hv) = (0.0f64, 0.0f64, 0.0f64);
            let (mut b_first, mut b_ends, mut b_hv) = (0.0f64, 0.0f64, 0.0f64);
            // Errors checked against their bounds (a missing bound counts as a miss).
            let (mut within, mut checked) = (0, 0);
            let mut tally = |err: f64, bound: Option<f64>| {
                checked += 1;
                if bound.is_some_and(|b| err <= b) {
                    within += 1;
                }
            };
            for (j, r) in results.iter().enumerate() {
                let (x0, x1) = FOUR_SPHERES
                    .overlap_interval(0, j + 1)
                    .expect("A meets B, C and D");
                let (Some(&(s, e)), Some(&(vs, _)), Some(&(_, ve))) = (
                    r.intervals.first(),
                    r.interval_speeds.first(),
                    r.interval_speeds.last(),
                ) else {
                    tally(f64::INFINITY, None);
                    continue;
                };
                let e = r.intervals.last().map_or(e, |iv| iv.1);
                let (first, last) = (lat.time_s(s, origin), lat.time_s(e, origin));
                let bs = bounds::contact_time_bound(lat.period_s(s), vs);
                let be = bounds::contact_time_bound(lat.period_s(e), ve);
                tally((first - x0).abs(), bs);
                tally((last - x1).abs(), be);
                err_first = err_first.max((first - x0).abs());
                err_ends = err_ends.max((first - x0).abs()).max((last - x1).abs());
                b_first = b_first.max(bs.unwrap_or(f64::INFINITY));
                b_ends = b_ends
                    .max(bs.unwrap_or(f64::INFINITY))
                    .max(be.unwrap_or(f64::INFINITY));
                let (hv, hv_bound) = overlap_hypervolume_of(&bodies[0], &bodies[j + 1]);
                let exact = FOUR_SPHERES.overlap_hypervolume(0, j + 1);
                tally((hv - exact).abs(), Some(hv_bound));
                err_hv = err_hv.max((hv - exact).abs() / exact);
                b_hv = b_hv.max(hv_bound / exact);
            }
            let m = Metric::new(&lat, c);
            let t2 = Instant::now();
            let single = suggest_translation(&prepared[0], &[&prepared[1]], &[&results[0]], &m);
            let others: Vec<&Prepared> = prepared[1..].iter().collect();
            let rs: Vec<&PairResult> = results.iter().collect();
            let multi = suggest_translation(&prepared[0], &others, &rs, &m);
            let t_resolve = t2.elapsed().as_secs_f64();
            let d = |t: &Option<crate::checker::resolve::Translation>| {
                t.as_ref().map_or(f64::NAN, |t| t.distance_m)
            };
            let run = t_mesh + t_check + t_resolve;
            points.push((format!("first contact ({e:?})"), run, err_first));
            points.push((format!("overlap rel. ({e:?})"), run, err_hv));
            points.push((
                format!("translation rel. ({e:?})"),
                run,
                (d(&multi) / exact_multi.0 - 1.0).abs(),
            ));
            let ok = |t: &Option<crate::checker::resolve::Translation>| {
                t.as_ref().is_some_and(|t| t.verified_clear)
            };
            let period = 1.0 / f64::from(n);
            let snap = m.sigma.iter().map(|s| s * s).sum::<f64>().sqrt();
            let b_tr = bounds::translation_bound(lat.resolution, period, c, snap);
            tally((d(&single) - exact_single.0).abs(), Some(b_tr));
            tally((d(&multi) - exact_multi.0).abs(), Some(b_tr));
            println!(
                "| {n} | {:?} | {} | {t_mesh:.2} | {t_check:.2} | {t_resolve:.2} | {err_first:.4} / {b_first:.4} | {err_ends:.4} / {b_ends:.4} | {:.2} % / {:.1} % | {:.4} / {:.4} ({:+.0} %) | {:.4} / {:.4} ({:+.0} %) | {b_tr:.4} | {} / {} | {within} / {checked} |",
                e,
                bodies[0].mesh.tets.len(),
                100.0 * err_hv,
                100.0 * b_hv,
                d(&single),
                exact_single.0,
                100.0 * (d(&single) / exact_single.0 - 1.0),
                d(&multi),
                exact_multi.0,
                100.0 * (d(&multi) / exact_multi.0 - 1.0),
                ok(&single),
                ok(&multi),
            );
        }
    }
    if let Some(path) = svg {
        crate::fsio::write_atomic(path, error_plot(&points).as_bytes()).map_err(|source| {
            BenchError::Io {
                path: path.to_path_buf(),
                source,
            }
        })?;
    }
    Ok(())
}

/// A log-log SVG of (series, run time s, error) points, one polyline per series.
fn error_plot(points: &[(String, f64, f64)]) -> String {
    // Errors below 1e-4 (e.g. an exact hit) are drawn at 1e-4.
    let floored: Vec<(String, f64, f64)> = points
        .iter()
        .filter(|p| p.1 > 0.0 && p.2.is_finite())
        .map(|p| (p.0.clone(), p.1, p.2.max(1e-4)))
        .collect();
    let pts: Vec<&(String, f64, f64)> = floored.iter().collect();
    let (w, h, m, legend) = (900.0, 440.0, 60.0, 200.0);
    let lx = |v: f64| v.log10();
    let (x0, x1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
        (a.0.min(lx(p.1)), a.1.max(lx(p.1)))
    });
    let (y0, y1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
        (a.0.min(lx(p.2)), a.1.max(lx(p.2)))
    });
    let (x0, x1, y0, y1) = (
        x0.floor(),
        x1.ceil().max(x0.floor() + 1.0),
        y0.floor(),
        y1.ceil().max(y0.floor() + 1.0),
    );
    let sx = |v: f64| m + (lx(v) - x0) / (x1 - x0) * (w - legend - 2.0 * m);
    let sy = |v: f64| h - m - (lx(v) - y0) / (y1 - y0) * (h - 2.0 * m);
    let mut out = format!("<svg xmlns='http://www.w3.org/2000/svg' width='{w}' height='{h}' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n");
    out += &format!("<line x1='{m}' y1='{}' x2='{}' y2='{}' stroke='black'/><line x1='{m}' y1='{m}' x2='{m}' y2='{}' stroke='black'/>\n", h - m, w - legend - m, h - m, h - m);
    for e in (x0 as i32)..=(x1 as i32) {
        let x = m + (f64::from(e) - x0) / (x1 - x0) * (w - legend - 2.0 * m);
        out += &format!(
            "<text x='{x}' y='{}' text-anchor='middle'>1e{e} s</text>\n",
            h - m + 18.0
        );
    }
    for e in (y0 as i32)..=(y1 as i32) {
        let y = h - m - (f64::from(e) - y0) / (y1 - y0) * (h - 2.0 * m);
        out += &format!(
            "<text x='{}' y='{y}' text-anchor='end'>1e{e}</text>\n",
            m - 6.0
        );
    }
    out += &format!("<text x='{}' y='20' text-anchor='middle'>four-spheres: error against run time (mesh + check + resolve), one point per grid; errors below 1e-4 drawn at 1e-4</text>\n", (w - legend) / 2.0);
    let colours = [
        "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
    ];
    let mut series: Vec<&str> = pts.iter().map(|p| p.0.as_str()).collect();
    series.sort_unstable();
    series.dedup();
    for (i, name) in series.iter().enumerate() {
        let c = colours[i % colours.len()];
        let line: Vec<String> = pts
            .iter()
            .filter(|p| p.0 == *name)
            .map(|p| format!("{:.1},{:.1}", sx(p.1), sy(p.2)))
            .collect();
        out += &format!(
            "<polyline fill='none' stroke='{c}' stroke-width='2' points='{}'/>\n",
            line.join(" ")
        );
        for xy in &line {
            let (x, y) = xy.split_once(',').unwrap_or(("0", "0"));
            out += &format!("<circle cx='{x}' cy='{y}' r='3' fill='{c}'/>\n");
        }
        out += &format!(
            "<text x='{}' y='{}' fill='{c}'>{name}</text>\n",
            w - m - 170.0,
            m + 16.0 * i as f64
        );
    }
    out + "</svg>\n"
}

/// Overlap hypervolume of two bodies from their intersected occupancy, and its bound (see
/// `check`).
fn overlap_hypervolume_of(a: &BodyMesh, b: &BodyMesh) -> (f64, f64) {
    crate::checker::pipeline::overlap_hypervolume(a, b, MesherOptions::default())
        .unwrap_or((f64::NAN, f64::NAN))
}

/// Meshes a scene held in memory body by body and prints the time per body and per slab
/// (`validate`: also the streaming validation of every slab).
///
/// # Errors
/// Bad scene options or a frame the mesher refuses.
pub fn bench_mesh(name: SceneName, o: &SceneOptions, validate: bool) -> Result<(), BenchError> {
    let scene = build_scene(name, o)?;
    println!(
        "scene {name}: {}^3 voxels x {} frames, {:?}, {} bodies",
        o.grid,
        o.frames,
        o.encoding,
        scene.topics().len()
    );
    let mut raster = Rasterizer::new();
    let mut all_slab_ms = Vec::new();
    let (mut tets, mut lateral_vertices, mut total_s, mut validate_s) =
        (0u64, 0u64, 0.0f64, 0.0f64);
    for (b, topic) in scene.topics().iter().enumerate() {
        let frames: Vec<VoxelGrid> = (0..scene.frame_count())
            .map(|k| {
                let mut g = VoxelGrid::default();
                scene.write_frame(b, k, &mut raster, &mut g).map(|_| g)
            })
            .collect::<Result<_, _>>()?;
        let mut m = Mesher::new(MesherOptions::default())?;
        let mut acc = StatsAccumulator::new();
        let mut first_cap = None;
        let mut slab_ms = Vec::new();
        let start = Instant::now();
        let mut body_tets = 0u64;
        for f in &frames {
            let t0 = Instant::now();
            let slab = m.push(&f.frame_ref())?;
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            if let Some(slab) = slab {
                slab_ms.push(ms);
                body_tets += slab.mesh.tets.len() as u64;
                lateral_vertices += slab.mesh.vertices.len() as u64;
                if validate {
                    let v0 = Instant::now();
                    if first_cap.is_none() {
                        first_cap = m.first_frame().and_then(|k| m.cap(k, CapSide::Low));
                    }
                    acc.add_slab(&slab, first_cap.as_ref());
                    validate_s += v0.elapsed().as_secs_f64();
                }
            }
        }
        let body_s = start.elapsed().as_secs_f64();
        total_s += body_s;
        tets += body_tets;
        println!(
            "  {topic:<24} lateral tets {body_tets:>10}  {body_s:>7.3} s  slab p50 {:>6.2} ms  p99 {:>6.2} ms",
            percentile(&slab_ms, 0.5),
            percentile(&slab_ms, 0.99)
        );
        all_slab_ms.extend(slab_ms);
    }
    println!(
        "total {:.3} s on {} thread(s) ({} lateral tets, {} lateral vertices before welding frames); slab p50 {:.2} ms, p99 {:.2} ms{}",
        total_s,
        rayon::current_num_threads(),
        tets,
        lateral_vertices,
        percentile(&all_slab_ms, 0.5),
        percentile(&all_slab_ms, 0.99),
        if validate { format!("; streaming validation {validate_s:.3} s") } else { String::new() }
    );
    println!(
        "peak RSS {:.1} MB (frames held in memory for the benchmark)",
        super::peak_rss_mb()
    );
    Ok(())
}

/// Plays the scene's frames in time order (every body's frame k, then k + 1, ...) through
/// the nodes of launch config `path`, in one process, timing each frame's handling by all
/// the nodes (what the frame costs the process: meshing, checking, markers), by body.
pub fn bench_nodes(
    name: SceneName,
    o: &SceneOptions,
    path: &std::path::Path,
    build: BuildNodes<'_>,
) -> Result<(), BenchError> {
    use crate::node::bus::Bus;
    use crate::node::launch::LaunchConfig;
    use crate::node::{Message, Payload};
    use std::sync::Arc;

    let text = std::fs::read_to_string(path).map_err(|source| BenchError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let config = LaunchConfig::parse(&text, &path.display().to_string())
        .map_err(|e| BenchError::Usage(e.to_string()))?;
    let scene = build_scene(name, o)?;
    let topics = scene.topics();
    let nodes = build(&config, &topics).map_err(|e| BenchError::Usage(e.to_string()))?;
    let mut bus = Bus::new(nodes);
    let mut raster = Rasterizer::new();
    // Frames are made before the clock starts, one time step at a time.
    let mut per_body: Vec<Vec<f64>> = vec![Vec::new(); topics.len()];
    let mut published = 0u64;
    let start = Instant::now();
    let mut made_s = 0.0;
    for k in 0..scene.frame_count() {
        let t = Instant::now();
        let mut step = Vec::with_capacity(topics.len());
        for (b, topic) in topics.iter().enumerate() {
            let mut g = VoxelGrid::default();
            scene.write_frame(b, k, &mut raster, &mut g)?;
            let stamp = g.header.stamp.as_nanos();
            step.push(Message::new(topic, stamp, Payload::VoxelGrid(Arc::new(g))));
        }
        made_s += t.elapsed().as_secs_f64();
        for (b, m) in step.into_iter().enumerate() {
            let t = Instant::now();
            bus.deliver(m, &mut |_| published += 1);
            per_body[b].push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let t = Instant::now();
    bus.finish(&mut |_| published += 1);
    let finish_s = t.elapsed().as_secs_f64();
    let total_s = start.elapsed().as_secs_f64() - made_s;
    println!(
        "nodes of {} on {} thread(s), frames in time order ({} messages published):",
        path.display(),
        rayon::current_num_threads(),
        published
    );
    for (topic, ms) in topics.iter().zip(&per_body) {
        println!(
            "  {topic:<24} per frame p50 {:>7.2} ms  p99 {:>7.2} ms  max {:>7.2} ms",
            percentile(ms, 0.5),
            percentile(ms, 0.99),
            ms.iter().copied().fold(0.0, f64::max)
        );
    }
    let steps: Vec<f64> = (0..scene.frame_count())
        .map(|k| per_body.iter().map(|v| v[k as usize]).sum())
        .collect();
    println!(
        "  all bodies' frames of one time step: p50 {:.2} ms, p99 {:.2} ms; end of run (closing caps, last periods, resolutions) {:.3} s; in all {:.3} s",
        percentile(&steps, 0.5),
        percentile(&steps, 0.99),
        finish_s,
        total_s
    );
    for (node, s) in bus.busy_s() {
        println!("  node {node:<20} {s:>8.3} s in its handlers");
    }
    Ok(())
}
