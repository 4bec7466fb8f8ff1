//! `chronotope bench check`: the checker's speed at the seed's sphere scale, next to what a
//! user would do instead (a 3D triangle-mesh intersection test with parry3d at every frame),
//! and what each of the two misses.
//!
//! Two spheres of `four-spheres` (A moving +z, B moving −y; they overlap for
//! t ∈ 0.5 ± 1/√13 s) are meshed first, outside the clock. Then, timed:
//! - *detection plus labels*: the common lattice, both bodies' trees and adjacency (on two
//!   cores), the tree-vs-tree traversal with the exact tet-pair predicate, and every tet
//!   labelled;
//! - *resolution*: the translation suggestion and the time scaling, each verified exactly;
//!   then the rotation about the vertical axis through A's centroid at first contact, alone
//!   (the node runs the three at once);
//! - *per-frame 3D*: each body's surface at every frame time (the t-slice of its 4D mesh,
//!   which is that frame's marching-cubes surface), a parry3d `TriMesh` per body and frame,
//!   and `intersection_test` between them.
//!
//! Detection and resolution run `reps` times each and their medians are printed;
//! detection also without the per-body preparation, which every pair and every
//! resolution of a body reuses, and streamed as the checker node does it: the two bodies'
//! slabs arrive in turn, each is prepared and walked against the other body's slabs as it
//! comes (timed per slab, outside the clock), and the clock covers what is left after the
//! last slab (trees' tops, placement, labels).
//!
//! A sweep over frame counts then shows what each misses on all three of A's pairs.

use super::BenchError;
use crate::checker::prep::BodyPrep;
use crate::checker::resolve::{suggest_time_scaling, suggest_translation, Metric};
use crate::checker::rotate::{suggest_rotation, RotationSpec};
use crate::checker::{
    check_pair, check_pair_walked, CommonLattice, PairResult, Prepared, StreamWalk,
};
use crate::mesh::glue::{BodyAssembler, BodyMesh};
use crate::mesh::slice::{slice_mesh, PlaneValue, TriMesh as SliceMesh};
use crate::mesh::MesherOptions;
use crate::msg::VoxelEncoding;
use crate::msg::VoxelGrid;
use crate::scene::{build_scene, Rasterizer, SceneName, SceneOptions, FOUR_SPHERES};
use parry3d::math::{Pose, Vector};
use parry3d::query::intersection_test;
use parry3d::shape::TriMesh as ParryMesh;
use rayon::prelude::*;
use std::time::Instant;

/// Meshes bodies `which` of four-spheres at `grid` voxels and `frames` frames.
fn spheres(
    grid: u32,
    frames: u32,
    encoding: VoxelEncoding,
    which: &[usize],
) -> Result<Vec<(String, BodyMesh)>, BenchError> {
    let o = SceneOptions::for_scene(SceneName::FourSpheres)
        .grid(grid)
        .frames(frames)
        .encoding(encoding.into());
    let scene = build_scene(SceneName::FourSpheres, &o)?;
    let topics = scene.topics();
    let out: Vec<Result<(String, BodyMesh), BenchError>> = which
        .par_iter()
        .map(|&b| -> Result<(String, BodyMesh), BenchError> {
            let mut raster = Rasterizer::new();
            let mut grid = VoxelGrid::default();
            let mut asm = BodyAssembler::new(MesherOptions::default())?;
            for k in 0..scene.frame_count() {
                scene.write_frame(b, k, &mut raster, &mut grid)?;
                asm.push(&grid.frame_ref())?;
            }
            Ok((topics[b].clone(), asm.finish()))
        })
        .collect();
    out.into_iter().collect()
}

/// Detection plus labels, timed: returns the prepared bodies, the pair result and the
/// seconds spent preparing (lattice, trees, adjacency).
fn detect(
    bodies: &[(String, BodyMesh)],
) -> Result<(CommonLattice, Vec<Prepared>, f64, Vec<PairResult>), BenchError> {
    let t0 = Instant::now();
    let named: Vec<(&str, &BodyMesh)> = bodies.iter().map(|(id, b)| (id.as_str(), b)).collect();
    let lat = CommonLattice::of(&named)?;
    let prepared: Vec<Prepared> = named
        .par_iter()
        .map(|&(id, b)| lat.prepare(id, b))
        .collect::<Result<_, _>>()?;
    let prepare_s = t0.elapsed().as_secs_f64();
    let results = (1..prepared.len())
        .map(|j| check_pair(&prepared[0], &prepared[j]))
        .collect();
    Ok((lat, prepared, prepare_s, results))
}

/// Detection plus labels with the two bodies' pieces arriving in turn (A's slab k, B's
/// slab k, ...), each prepared and walked against the other body's pieces as it comes, as
/// the checker node does. Returns the seconds each piece took (preparation and walk), and
/// from the last piece to the labels: in total, for the lattice, trees' tops and
/// placement, and the pair result.
fn detect_streamed(
    bodies: &[(String, BodyMesh)],
) -> Result<(Vec<f64>, f64, f64, PairResult), BenchError> {
    let mut preps = [BodyPrep::new(), BodyPrep::new()];
    let mut walk = StreamWalk::new();
    let mut per_piece = Vec::new();
    let most = bodies
        .iter()
        .map(|(_, b)| b.pieces.len())
        .max()
        .unwrap_or(0);
    for k in 0..most {
        for (p, (_, b)) in preps.iter_mut().zip(bodies) {
            if k >= b.pieces.len() {
                continue;
            }
            let end = b.pieces.get(k + 1).copied().unwrap_or(b.mesh.tets.len());
            let t = Instant::now();
            p.add_up_to(&b.mesh, end)
                .map_err(|e| BenchError::Usage(e.to_string()))?;
            per_piece.push(t.elapsed().as_secs_f64());
        }
        let t = Instant::now();
        walk.advance(&preps[0], &preps[1]);
        // The walk is charged to the piece that completed the pair of slabs.
        if let Some(last) = per_piece.last_mut() {
            *last += t.elapsed().as_secs_f64();
        }
    }
    let t0 = Instant::now();
    let named: Vec<(&str, &BodyMesh)> = bodies.iter().map(|(id, b)| (id.as_str(), b)).collect();
    let lat = CommonLattice::of(&named)?;
    let prepared: Vec<Prepared> = named
        .par_iter()
        .zip(preps)
        .map(|(&(id, b), p)| lat.place_prep(id, b, p))
        .collect::<Result<_, _>>()?;
    let place_s = t0.elapsed().as_secs_f64();
    let r = if named.iter().all(|(_, b)| lat.places_as_is(b)) {
        check_pair_walked(&prepared[0], &prepared[1], walk)
    } else {
        check_pair(&prepared[0], &prepared[1])
    };
    Ok((per_piece, t0.elapsed().as_secs_f64(), place_s, r))
}

/// One body's surface at frame `k` (lattice units; the first and last frames are sliced
/// 1/1024 of a frame inside, off the caps).
fn frame_slice(b: &BodyMesh, k: usize) -> SliceMesh {
    let s = i64::from(b.geometry.map_or(1, |g| g.scale));
    let last = b.stamps_ns.len().saturating_sub(1);
    let nudge = match k {
        0 => 1,
        k if k == last => -1,
        _ => 0,
    };
    slice_mesh(
        &[&b.mesh],
        3,
        PlaneValue {
            num: k as i64 * s * 1024 + nudge,
            den: 1024,
        },
    )
}

/// A slice as a parry3d mesh in metres.
fn to_parry(b: &BodyMesh, tri: SliceMesh) -> Option<ParryMesh> {
    let g = b.geometry?;
    if tri.triangles.is_empty() {
        return None;
    }
    let (c, h) = (g.voxel0_centre(), g.step_m());
    let vertices: Vec<Vector> = tri
        .vertices
        .iter()
        .map(|v| {
            Vector::new(
                (c[0] + v[0] * h) as f32,
                (c[1] + v[1] * h) as f32,
                (c[2] + v[2] * h) as f32,
            )
        })
        .collect();
    ParryMesh::new(vertices, tri.triangles).ok()
}

/// Per-frame 3D checks of body 0 against each other body: for every pair the frames whose
/// surfaces intersect, plus (slice s, build s, test s).
fn per_frame(bodies: &[(String, BodyMesh)]) -> (Vec<Vec<bool>>, [f64; 3]) {
    let frames = bodies[0].1.stamps_ns.len();
    let mut hits = vec![vec![false; frames]; bodies.len() - 1];
    let (mut slice_s, mut build_s, mut test_s) = (0.0, 0.0, 0.0);
    let id = Pose::IDENTITY;
    for k in 0..frames {
        let t0 = Instant::now();
        let sliced: Vec<SliceMesh> = bodies.iter().map(|(_, b)| frame_slice(b, k)).collect();
        slice_s += t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let meshes: Vec<Option<ParryMesh>> = bodies
            .iter()
            .zip(sliced)
            .map(|((_, b), tri)| to_parry(b, tri))
            .collect();
        build_s += t1.elapsed().as_secs_f64();
        let t2 = Instant::now();
        if let Some(a) = &meshes[0] {
            for (j, m) in meshes[1..].iter().enumerate() {
                if let Some(m) = m {
                    hits[j][k] = intersection_test(&id, a, &id, m).is_ok_and(|r| r.intersecting);
                }
            }
        }
        test_s += t2.elapsed().as_secs_f64();
    }
    (hits, [slice_s, build_s, test_s])
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the benchmark.
///
/// # Errors
/// Bad scene options, or a body that cannot be checked.
pub fn bench_check(
    grid: u32,
    encoding: VoxelEncoding,
    reps: usize,
    sweep: &[u32],
) -> Result<(), BenchError> {
    let frames = grid + 1;
    let t0 = Instant::now();
    let bodies = spheres(grid, frames, encoding, &[0, 1])?;
    println!(
        "four-spheres A vs B, {grid}^3 voxels x {frames} frames, {encoding:?}: {} + {} tets ({} + {} vertices), meshed in {:.2} s (not counted below)",
        bodies[0].1.mesh.tets.len(),
        bodies[1].1.mesh.tets.len(),
        bodies[0].1.mesh.vertices.len(),
        bodies[1].1.mesh.vertices.len(),
        t0.elapsed().as_secs_f64()
    );
    let (x0, x1) = FOUR_SPHERES.overlap_interval(0, 1).expect("A meets B");
    let mut run = None;
    let (mut prep, mut det, mut lab, mut tot, mut checked) =
        (vec![], vec![], vec![], vec![], vec![]);
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let (lat, prepared, prepare_s, results) = detect(&bodies)?;
        tot.push(t.elapsed().as_secs_f64());
        prep.push(prepare_s);
        det.push(results[0].timing.detect_s);
        lab.push(results[0].timing.label_s);
        checked.push(results[0].timing.detect_s + results[0].timing.label_s);
        run = Some((lat, prepared, results));
    }
    // The same detection with each body prepared and walked slab by slab as its stream
    // arrives (as the checker node does), outside the clock: what is left after the last
    // slab, and what each slab costs while the stream runs.
    let (mut end, mut place, mut pieces, mut s_lab) = (vec![], vec![], vec![], vec![]);
    let mut streamed = None;
    for _ in 0..reps.max(1) {
        let (per_piece, e, pl, r) = detect_streamed(&bodies)?;
        end.push(e);
        place.push(pl);
        s_lab.push(r.timing.label_s);
        pieces = per_piece;
        streamed = Some(r);
    }
    let (lat, prepared, results) = run.expect("one run");
    let r = &results[0];
    let origin = lat.stamps_ns[0];
    let first = r
        .first_contact()
        .map_or(f64::NAN, |t| lat.time_s(t, origin));
    let last = r
        .intervals
        .last()
        .map_or(f64::NAN, |iv| lat.time_s(iv.1, origin));
    let (ca, cb) = r.counts();
    println!(
        "detection + labels: median {:.3} s over {} runs, {:.3} s without the per-body preparation (prepare: lattice, trees, adjacency {:.3} s; traversal + exact predicate {:.3} s; labels {:.3} s)",
        median(&mut tot),
        tot.len(),
        median(&mut checked),
        median(&mut prep),
        median(&mut det),
        median(&mut lab),
    );
    let s = streamed.expect("one run");
    let total_pieces: f64 = pieces.iter().sum();
    let max_piece = pieces.iter().copied().fold(0.0, f64::max);
    println!(
        "  prepared and walked slab by slab as the streams arrive (the checker node): {:.3} s after the last slab (lattice, trees' tops, placement {:.3} s; labels {:.3} s); while streaming {:.1} ms per slab and body on average, at most {:.1} ms, {:.2} s in all over {} pieces (one core); same result: {}",
        median(&mut end),
        median(&mut place),
        median(&mut s_lab),
        total_pieces / pieces.len().max(1) as f64 * 1e3,
        max_piece * 1e3,
        total_pieces,
        pieces.len(),
        s.intervals == r.intervals
            && s.counts() == r.counts()
            && s.candidate_pairs == r.candidate_pairs
            && s.interfering_pairs == r.interfering_pairs,
    );
    println!(
        "  {} candidate tet pairs, {} interfering; A: {} interference / {} inside / {} outside; B: {} / {} / {}",
        r.candidate_pairs, r.interfering_pairs, ca.interference, ca.inside, ca.outside, cb.interference, cb.inside, cb.outside
    );
    println!(
        "  interval [{first:.4}, {last:.4}] s, exact [{x0:.4}, {x1:.4}] s: first contact error {:+.4} s, frame period {:.4} s",
        first - x0,
        1.0 / f64::from(grid)
    );
    let m = Metric::new(&lat, 1.0);
    let (mut tr_s, mut ts_s, mut both_s) = (vec![], vec![], vec![]);
    let (mut tr, mut ts) = (None, None);
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        tr = suggest_translation(&prepared[0], &[&prepared[1]], &[r], &m);
        let t_tr = t.elapsed().as_secs_f64();
        let t = Instant::now();
        ts = suggest_time_scaling(&prepared[0], &[&prepared[1]], &[r]);
        let t_ts = t.elapsed().as_secs_f64();
        tr_s.push(t_tr);
        ts_s.push(t_ts);
        both_s.push(t_tr + t_ts);
    }
    println!(
        "resolution: median {:.3} s over {} runs (translation {:.3} s: {}; time scaling {:.3} s: {})",
        median(&mut both_s),
        both_s.len(),
        median(&mut tr_s),
        tr.as_ref().map_or("none".into(), |t| format!(
            "{:.4} m, verified clear {}",
            t.distance_m, t.verified_clear
        )),
        median(&mut ts_s),
        ts.as_ref().map_or("none".into(), |t| format!(
            "s = {:.4}, verified clear {}",
            t.scale, t.verified_clear
        )),
    );
    let mut rot_s = Vec::new();
    let mut rot = None;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        rot = suggest_rotation(
            &prepared[0],
            &[&prepared[1]],
            &[r],
            &lat,
            &RotationSpec::default(),
        );
        rot_s.push(t.elapsed().as_secs_f64());
    }
    println!(
        "  rotation about the vertical axis through A's centroid at first contact: median {:.3} s ({})",
        median(&mut rot_s),
        rot.as_ref().map_or("none".into(), |x| format!(
            "{:+.2}°, verified clear {}, {} angles tried, {} checked in full",
            x.angle_rad.to_degrees(),
            x.verified_clear,
            x.tried.0,
            x.tried.1
        )),
    );
    let (hits, [slice_s, build_s, test_s]) = per_frame(&bodies);
    let period = 1.0 / f64::from(grid);
    let first_frame = hits[0].iter().position(|&h| h).map(|k| k as f64 * period);
    println!(
        "per-frame 3D (parry3d TriMesh intersection_test at each of {frames} frames): tests {test_s:.3} s, TriMesh builds {build_s:.3} s, surfaces (t-slices) {slice_s:.3} s"
    );
    println!(
        "  {} of {frames} frames in contact; first contact {} (exact {x0:.4} s; at best one frame period late)",
        hits[0].iter().filter(|&&h| h).count(),
        first_frame.map_or("never".into(), |t| format!("{t:.4} s, error {:+.4} s", t - x0)),
    );
    if !sweep.is_empty() {
        misses(grid.min(64), encoding, sweep)?;
    }
    Ok(())
}

/// What each method finds on A's three pairs as frames get sparse.
fn misses(grid: u32, encoding: VoxelEncoding, sweep: &[u32]) -> Result<(), BenchError> {
    println!();
    println!("what each misses: A against B, C, D at {grid}^3 voxels, frames spread over 1 s ({encoding:?})");
    println!();
    println!("| frames | pair | exact interval (s) | 4D: found / first contact err (s) | 4D: slabs where a body vanishes | per-frame: found / first contact err (s) |");
    println!("|---|---|---|---|---|---|");
    for &f in sweep {
        let bodies = spheres(grid, f, encoding, &[0, 1, 2, 3])?;
        let vanishing: u64 = bodies.iter().map(|(_, b)| b.stats.vanishing_slabs).sum();
        let (lat, _, _, results) = detect(&bodies)?;
        let (hits, _) = per_frame(&bodies);
        let origin = lat.stamps_ns[0];
        let period = 1.0 / f64::from(f - 1);
        for (j, r) in results.iter().enumerate() {
            let (x0, x1) = FOUR_SPHERES
                .overlap_interval(0, j + 1)
                .expect("A meets all");
            let four_d = r.first_contact().map_or("missed".to_string(), |t| {
                format!("yes / {:+.4}", lat.time_s(t, origin) - x0)
            });
            let frame = hits[j]
                .iter()
                .position(|&h| h)
                .map_or("missed".to_string(), |k| {
                    format!("yes / {:+.4}", k as f64 * period - x0)
                });
            println!(
                "| {f} | A–{} | [{x0:.3}, {x1:.3}] | {four_d} | {vanishing} | {frame} |",
                ["B", "C", "D"][j]
            );
        }
    }
    Ok(())
}
