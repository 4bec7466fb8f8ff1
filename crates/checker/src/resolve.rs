//! Resolve suggestions (the interference paper's §4:
//! docs/methods/interference.md#resolution): move one body in space-time, or stretch its
//! time axis, so that it clears every other body; every suggestion is verified by checking
//! the moved body again, exactly, against every other body.
//!
//! - **Translation** (seed §4.2): direction u = −∇V/|∇V| where V is the overlap
//!   hypervolume; by Reynolds transport ∇_v vol((A+v) ∩ B) = ∫_{∂A ∩ B} n̂ dS, i.e. the sum of
//!   N_τ/6 over A's INSIDE tets (half weight for INTERFERENCE tets, whose inside part is not
//!   measured), no finite differences
//!   (docs/methods/interference.md#gradient-of-the-overlap). The gradient is taken in the
//!   metric space (x, y, z, c·t). If it vanishes (a symmetric setup), the axis direction
//!   with the shortest exit is used. Distance d: the largest distance, over interior points
//!   of A's INSIDE and INTERFERENCE tets that lie inside the other body, from the point
//!   along u to where its ray leaves that body. The vector is snapped to the lattice
//!   (rounded up in length) and verified; if a body still interferes it is lengthened by
//!   10 % at a time (at most [`GROWTH_STEPS`] times) and the final verdict is reported as
//!   it is.
//! - **Time scaling** (seed §4.3, eqs. 1-2): t_s = t0 + s (t − t0). The same distance along
//!   the time axis gives t_A (the point) and t_B (where it leaves); t0 is whichever of A's
//!   t_min / t_max lies farther from [t_A, t_B]; s = (t_B − t0)/(t_A − t0). s is made a
//!   fraction p/64 (rounded away from 1) and verified exactly on a lattice refined 64 times;
//!   if it does not clear, s moves away from 1 by 10 % at a time until it does, and then
//!   p is bisected between the last failing and the first clearing scale.
//!
//! Ray distances are measurements in floating point; every verdict comes from the exact
//! checker. Speed: each search places one copy of the body again and again
//! ([`Placement`]: no allocation after the first), and a candidate that does not clear is
//! usually refuted by a witness, a sample tet that was inside the other body and whose
//! moved interior point still is (one exact ray, [`mapped_tet_inside`]); a clear verdict
//! always comes from the full check.

use super::inclusion::Inclusion;
use super::labels::Label;
use super::{
    interferes, mapped_tet_inside, tet_of, CommonLattice, PairResult, Placement, Prepared,
};
use chronotope_kernel::bvh::TraverseWorkspace;
use chronotope_kernel::LatticePoint;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// How many times a suggestion that does not clear is lengthened by 10 %.
pub const GROWTH_STEPS: usize = 8;

/// Interior points sampled per pair for ray distances.
const MAX_SAMPLES: usize = 4000;

/// Metres per checker lattice unit along each axis of the metric space (time: c × seconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metric {
    /// Per axis x, y, z, t.
    pub sigma: [f64; 4],
}

impl Metric {
    /// The metric of a lattice with time scale `c` (m/s), using the mean frame period.
    pub fn new(lat: &CommonLattice, c: f64) -> Self {
        let per = lat.per_step() as f64;
        let n = lat.stamps_ns.len().max(2);
        let span = (lat.stamps_ns[n - 1] - lat.stamps_ns[0]) as f64 * 1e-9;
        let period = span / (n - 1) as f64;
        let h = lat.resolution / per;
        Self {
            sigma: [h, h, h, c * period / per],
        }
    }
}

/// A suggested translation.
#[derive(Debug, Clone, PartialEq)]
pub struct Translation {
    /// In checker lattice units.
    pub lattice: [i64; 4],
    /// Metric length (m): sqrt(dx² + dy² + dz² + (c·dt)²).
    pub distance_m: f64,
    /// The moved body was checked against every other body and nothing interferes.
    pub verified_clear: bool,
    /// How the direction was found (`gradient` or `axis fallback`).
    pub direction: &'static str,
}

/// A suggested time scaling t_s = t0 + s (t − t0).
#[derive(Debug, Clone, PartialEq)]
pub struct TimeScaling {
    /// Fixed time, in checker lattice units.
    pub t0: i64,
    /// Scale s.
    pub scale: f64,
    /// The scaled body was checked against every other body and nothing interferes.
    pub verified_clear: bool,
}

type V4 = [f64; 4];

use chronotope_kernel::float::{det4, tet_normal as normal};

fn centroid(t: &[LatticePoint; 4]) -> V4 {
    [0, 1, 2, 3].map(|k| t.iter().map(|p| f64::from(p[k])).sum::<f64>() / 4.0)
}

/// Parameters λ > 0 (sorted) where the ray p + λ·dir crosses tets of `b`.
fn ray_crossings(
    p: &V4,
    dir: &V4,
    b: &Prepared,
    ws: &mut TraverseWorkspace,
    hits: &mut Vec<u32>,
) -> Vec<f64> {
    let bb = b.bvh.aabb();
    let diag: f64 = (0..4)
        .map(|k| f64::from(bb.max[k]) - f64::from(bb.min[k]))
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt();
    let reach: f64 = (0..4)
        .map(|k| {
            (p[k] - f64::from(bb.min[k]))
                .abs()
                .max((p[k] - f64::from(bb.max[k])).abs())
        })
        .sum::<f64>()
        + diag;
    let len = dir.iter().map(|x| x * x).sum::<f64>().sqrt();
    if len == 0.0 {
        return Vec::new();
    }
    let k = reach / len * 1.5 + 2.0;
    let start = p.map(|x| x.floor() as i64);
    let end = [0, 1, 2, 3].map(|i| (p[i] + dir[i] * k).round() as i64);
    // The integer segment is within a unit of the real ray: widen the query by querying
    // from the floor point; tets just off the ray are rejected by the exact-ish test below.
    hits.clear();
    b.bvh.segment_candidates(start, end, ws, |i| hits.push(i));
    let mut out = Vec::new();
    for &i in hits.iter() {
        let t = tet_of(&b.mesh, i);
        let n = normal(&t);
        let nd: f64 = (0..4).map(|k| n[k] * dir[k]).sum();
        if nd == 0.0 {
            continue;
        }
        let a0 = t[0].map(f64::from);
        let lam = (0..4).map(|k| n[k] * (a0[k] - p[k])).sum::<f64>() / nd;
        if lam <= 0.0 {
            continue;
        }
        let x: V4 = [0, 1, 2, 3].map(|k| p[k] + lam * dir[k]);
        if inside_tet(&t, &n, &x) {
            out.push(lam);
        }
    }
    out.sort_by(f64::total_cmp);
    out.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * b.abs().max(1.0));
    out
}

/// Whether x (on the tet's hyperplane) lies in the closed tet.
fn inside_tet(t: &[LatticePoint; 4], n: &V4, x: &V4) -> bool {
    let f = |q: &LatticePoint| q.map(f64::from);
    (0..4).all(|i| {
        let others: [usize; 3] = match i {
            0 => [1, 2, 3],
            1 => [0, 2, 3],
            2 => [0, 1, 3],
            _ => [0, 1, 2],
        };
        let face: [V4; 3] = others.map(|j| f(&t[j]));
        let sub = |a: &V4, b: &V4| [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]];
        let g = |y: &V4| {
            det4(
                &sub(&face[1], &face[0]),
                &sub(&face[2], &face[0]),
                n,
                &sub(y, &face[0]),
            )
        };
        let s = g(&f(&t[i]));
        s * g(x) >= -1e-9 * s.abs()
    })
}

/// A sample point of `a` (the centroid of one of its tets) that lies inside another body
/// (odd crossing count along a ray), and how far along the ray it first leaves that body.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Exit {
    /// The tet of `a`.
    tet: u32,
    /// Its centroid (checker coordinates).
    point: V4,
    /// Distance to the exit, in units of the ray's direction.
    distance: f64,
}

/// The sample tets of `a` for ray distances: up to [`MAX_SAMPLES`] of its INSIDE and
/// INTERFERENCE tets against one other body (every k-th, in order).
fn samples(r: &PairResult) -> Vec<u32> {
    let cand: Vec<u32> = r
        .labels_a
        .labels
        .iter()
        .enumerate()
        .filter(|(_, l)| **l != Label::Outside)
        .map(|(i, _)| i as u32)
        .collect();
    let step = (cand.len() / MAX_SAMPLES).max(1);
    cand.into_iter().step_by(step).collect()
}

/// The sample points of `a` inside `b` (see [`samples`]) with their exits along `dir`, in
/// sample order; `None` as soon as one exit lies farther than `bound` (`f64` bits of a
/// positive distance): then `dir` is not the shortest way out.
fn exits_within(
    a: &Prepared,
    samples: &[u32],
    b: &Prepared,
    dir: &V4,
    bound: &AtomicU64,
) -> Option<Vec<Exit>> {
    let mut ws = TraverseWorkspace::new();
    let mut hits = Vec::new();
    let mut out = Vec::new();
    for &t in samples {
        let point = centroid(&tet_of(&a.mesh, t));
        let xs = ray_crossings(&point, dir, b, &mut ws, &mut hits);
        if xs.len() % 2 == 1 {
            if xs[0] > f64::from_bits(bound.load(Ordering::Relaxed)) {
                return None;
            }
            out.push(Exit {
                tet: t,
                point,
                distance: xs[0],
            });
        }
    }
    Some(out)
}

/// The sample points of `a` inside `b` with their exits along `dir`, in sample order.
fn exits(a: &Prepared, r: &PairResult, b: &Prepared, dir: &V4) -> Vec<Exit> {
    let unbounded = AtomicU64::new(f64::INFINITY.to_bits());
    exits_within(a, &samples(r), b, dir, &unbounded).unwrap_or_default()
}

/// The farthest exit (the first one among equals).
fn farthest(exits: &[Exit]) -> Option<Exit> {
    exits
        .iter()
        .copied()
        .fold(None, |best: Option<Exit>, e| match best {
            Some(b) if e.distance <= b.distance => Some(b),
            _ => Some(e),
        })
}

/// How many sample tets are tried as witnesses before a candidate move is verified in full.
const WITNESSES: usize = 8;

/// Whether a candidate move of `a` (x_k → mul_k·x_k + add_k) clears every body of
/// `others`, exactly. Before the full check ([`clears`]), up to [`WITNESSES`] of `likely`
/// (sample tets with the body they were inside, most likely still inside first) are tested
/// with [`mapped_tet_inside`]: one inside proves the move fails at the cost of a ray, with
/// neither a walk nor labels. A clear verdict always comes from the full check.
fn verified_clear(
    placement: &mut Placement,
    others: &[&Prepared],
    likely: &[(u32, usize)],
    mul: [i64; 4],
    add: [i64; 4],
) -> bool {
    let a = placement.source();
    let mut tests: Vec<Inclusion> = others
        .iter()
        .map(|b| Inclusion::with_normals(&b.mesh, &b.bvh, &b.normals))
        .collect();
    if likely
        .iter()
        .take(WITNESSES)
        .any(|&(t, i)| mapped_tet_inside(a, t, mul, add, &mut tests[i]))
    {
        return false;
    }
    placement
        .place(mul, add)
        .is_some_and(|moved| clears(moved, others))
}

/// The gradient of the overlap hypervolume with respect to translating `a`, in the
/// lattice's units (sum of outward N_τ/6 over the tets of `a` inside the others).
fn overlap_gradient(a: &Prepared, results: &[&PairResult]) -> V4 {
    let mut g = [0.0; 4];
    for r in results {
        for (i, l) in r.labels_a.labels.iter().enumerate() {
            let w = match l {
                Label::Inside => 1.0 / 6.0,
                Label::Interference => 0.5 / 6.0,
                Label::Outside => continue,
            };
            let n = normal(&tet_of(&a.mesh, i as u32));
            for k in 0..4 {
                g[k] += w * n[k];
            }
        }
    }
    g
}

/// Indices of the pairs that interfere, or `None` if nothing does.
fn interfering(results: &[&PairResult]) -> Option<Vec<usize>> {
    let hits: Vec<usize> = (0..results.len())
        .filter(|&i| results[i].interfering())
        .collect();
    (!hits.is_empty()).then_some(hits)
}

/// True if `a` interferes with none of `others`.
pub fn clears(a: &Prepared, others: &[&Prepared]) -> bool {
    others.iter().all(|b| !interferes(a, b))
}

/// Per direction (unit vectors in the metric space), the exits of `a`'s samples from each
/// body of `hits` along it, on all cores (independent ray casts).
///
/// A direction is dropped (`None`) as soon as one of its exits lies farther
/// than the farthest exit of a direction already done: it cannot be the shortest. The
/// shortest is never dropped (its exits are all within every done direction's farthest),
/// so [`shortest`] picks what it picks from all exits in full, whatever the order the
/// directions finish in.
fn direction_exits(
    a: &Prepared,
    others: &[&Prepared],
    results: &[&PairResult],
    hits: &[usize],
    directions: &[(V4, &'static str)],
    m: &Metric,
) -> Vec<Option<Vec<(usize, Vec<Exit>)>>> {
    let sampled: Vec<(usize, Vec<u32>)> = hits.iter().map(|&i| (i, samples(results[i]))).collect();
    let bound = AtomicU64::new(f64::INFINITY.to_bits());
    directions
        .par_iter()
        .map(|(u, _)| {
            // Move λ along dir_lattice = u/σ: the metric displacement is λ·u, |u| = 1.
            let dir: V4 = [0, 1, 2, 3].map(|k| u[k] / m.sigma[k]);
            let per_pair: Option<Vec<(usize, Vec<Exit>)>> = sampled
                .iter()
                .map(|(i, s)| Some((*i, exits_within(a, s, others[*i], &dir, &bound)?)))
                .collect();
            let d = farthest_of(per_pair.iter().flatten());
            if d > 0.0 {
                // Positive floats order as their bits.
                bound.fetch_min(d.to_bits(), Ordering::Relaxed);
            }
            per_pair
        })
        .collect()
}

/// The farthest exit distance over the pairs' exits (0 if none).
fn farthest_of<'a>(per_pair: impl Iterator<Item = &'a (usize, Vec<Exit>)>) -> f64 {
    per_pair
        .filter_map(|(_, e)| farthest(e))
        .fold(0.0f64, |d, e| d.max(e.distance))
}

/// The direction whose farthest exit is the shortest (the first among equals), with that
/// distance; directions without exits or dropped are skipped.
fn shortest(per_direction: &[Option<Vec<(usize, Vec<Exit>)>>]) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (n, per_pair) in per_direction.iter().enumerate() {
        let Some(per_pair) = per_pair else {
            continue;
        };
        let d = farthest_of(per_pair.iter());
        if d > 0.0 && best.is_none_or(|(bd, _)| d < bd) {
            best = Some((d, n));
        }
    }
    best
}

/// Suggests a translation of `a` that clears every body of `others` (`results[i]` is the
/// check of `a` against `others[i]`).
pub fn suggest_translation(
    a: &Prepared,
    others: &[&Prepared],
    results: &[&PairResult],
    m: &Metric,
) -> Option<Translation> {
    let hits = interfering(results)?;
    let g = overlap_gradient(a, results);
    // Gradient in metric coordinates y = σ x: covariant, so g_y,k ∝ g_k / σ_k.
    let gy: V4 = [0, 1, 2, 3].map(|k| g[k] / m.sigma[k]);
    let norm = gy.iter().map(|x| x * x).sum::<f64>().sqrt();
    let scale: f64 = g.iter().map(|x| x.abs()).sum::<f64>().max(1.0);
    let mut directions: Vec<(V4, &'static str)> = Vec::new();
    let axes = |how: &'static str, out: &mut Vec<(V4, &'static str)>| {
        for k in 0..4 {
            for s in [1.0, -1.0] {
                let mut u = [0.0; 4];
                u[k] = s;
                out.push((u, how));
            }
        }
    };
    if norm > 1e-9 * scale / m.sigma.iter().cloned().fold(f64::INFINITY, f64::min) {
        // The seed's direction first, then a local search around it and the axes: the
        // gradient is not the shortest way out when the body hits several others.
        let ug = gy.map(|x| -x / norm);
        directions.push((ug, "gradient"));
        for k in 0..4 {
            for s in [0.35, -0.35] {
                let mut u = ug;
                u[k] += s;
                let n = u.iter().map(|x| x * x).sum::<f64>().sqrt();
                directions.push((u.map(|x| x / n), "search"));
            }
        }
        axes("search", &mut directions);
    } else {
        axes("axis fallback", &mut directions);
    }
    let per_direction = direction_exits(a, others, results, &hits, &directions, m);
    let best = shortest(&per_direction);
    let (d, n) = best?;
    let (u, how) = directions[n];
    // Witnesses for a move of length `len`: the samples whose exit lies beyond `len`,
    // farthest first (they stay inside longest).
    let mut likely: Vec<(f64, u32, usize)> = per_direction[n]
        .iter()
        .flatten()
        .flat_map(|(i, e)| e.iter().map(move |e| (e.distance, e.tet, *i)))
        .collect();
    likely.sort_by(|x, y| y.0.total_cmp(&x.0));
    let mut placement = Placement::new(a);
    // Place the body at metric length `len` along u (snapped to the lattice, each component
    // rounded away from zero) and verify exactly.
    let mut place = |len: f64| {
        let v: [i64; 4] = [0, 1, 2, 3].map(|k| {
            let x = len * u[k] / m.sigma[k];
            (x.abs().ceil() * x.signum()) as i64
        });
        let witnesses: Vec<(u32, usize)> = likely
            .iter()
            .take_while(|w| w.0 > len)
            .map(|w| (w.1, w.2))
            .collect();
        let ok = verified_clear(&mut placement, others, &witnesses, [1; 4], v);
        let dist = (0..4)
            .map(|k| (v[k] as f64 * m.sigma[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        Translation {
            lattice: v,
            distance_m: dist,
            verified_clear: ok,
            direction: how,
        }
    };
    // Grow until it clears ...
    let (mut lo, mut hi, mut best_t) = (None, d, place(d));
    let mut steps = 0;
    while !best_t.verified_clear && steps < GROWTH_STEPS {
        lo = Some(hi);
        hi *= 1.1;
        best_t = place(hi);
        steps += 1;
    }
    if !best_t.verified_clear {
        return Some(best_t);
    }
    // ... probe shorter if the first try already cleared ...
    let mut probes = 0;
    while lo.is_none() && probes < 3 {
        let l = hi / 1.15;
        let t = place(l);
        if t.verified_clear {
            hi = l;
            best_t = t;
        } else {
            lo = Some(l);
        }
        probes += 1;
    }
    // ... and bisect between the last length that failed and the first that cleared.
    if let Some(mut lo) = lo {
        for _ in 0..4 {
            let mid = 0.5 * (lo + hi);
            let t = place(mid);
            if t.verified_clear {
                hi = mid;
                best_t = t;
            } else {
                lo = mid;
            }
        }
    }
    Some(best_t)
}

/// Suggests a time scaling of `a` about t0 that clears every body of `others`.
pub fn suggest_time_scaling(
    a: &Prepared,
    others: &[&Prepared],
    results: &[&PairResult],
) -> Option<TimeScaling> {
    let hits = interfering(results)?;
    let g = overlap_gradient(a, results);
    let sign = if g[3] > 0.0 { -1.0 } else { 1.0 };
    let dir = [0.0, 0.0, 0.0, sign];
    let per_pair: Vec<(usize, Vec<Exit>)> = hits
        .iter()
        .map(|&i| (i, exits(a, results[i], others[i], &dir)))
        .collect();
    let mut far: Option<(f64, V4)> = None;
    for e in per_pair.iter().filter_map(|(_, e)| farthest(e)) {
        if far.is_none_or(|(d, _)| e.distance > d) {
            far = Some((e.distance, e.point));
        }
    }
    let (d, p) = far?;
    let (ta, tb) = (p[3], p[3] + sign * d);
    let tmin = a.mesh.vertices.iter().map(|v| i64::from(v[3])).min()?;
    let tmax = a.mesh.vertices.iter().map(|v| i64::from(v[3])).max()?;
    let (lo, hi) = (ta.min(tb), ta.max(tb));
    let dist = |x: f64| {
        if x < lo {
            lo - x
        } else if x > hi {
            x - hi
        } else {
            0.0
        }
    };
    let t0 = if dist(tmax as f64) >= dist(tmin as f64) {
        tmax
    } else {
        tmin
    };
    if (ta - t0 as f64).abs() < 1e-9 {
        return None;
    }
    let mut s = (tb - t0 as f64) / (ta - t0 as f64);
    if !(s.is_finite() && s > 0.0) {
        return None;
    }
    // Witnesses for a scale s: the samples that eqs. (1)-(2) would clear only with a
    // scale above s (the ray's exit reached at that scale), largest first.
    let mut likely: Vec<(f64, u32, usize)> = per_pair
        .iter()
        .flat_map(|(i, e)| {
            e.iter().map(move |e| {
                let (ta, tb) = (e.point[3], e.point[3] + sign * e.distance);
                ((tb - t0 as f64) / (ta - t0 as f64), e.tet, *i)
            })
        })
        .collect();
    likely.sort_by(|x, y| y.0.total_cmp(&x.0));
    // s = p/Q with Q = 64, rounded away from 1; the others are refined once.
    const Q: i64 = 64;
    let refined_others: Option<Vec<Prepared>> =
        others.iter().map(|b| b.mapped([Q; 4], [0; 4])).collect();
    let refined_refs: Option<Vec<&Prepared>> = refined_others.as_ref().map(|r| r.iter().collect());
    let mut placement = Placement::new(a);
    let mut try_p = |p: i64| {
        let witnesses: Vec<(u32, usize)> = likely
            .iter()
            .take_while(|w| w.0 > p as f64 / Q as f64)
            .map(|w| (w.1, w.2))
            .collect();
        // Times become Q·t0 + p·(t − t0) on the lattice refined Q times: t_s = t0 + s (t − t0).
        refined_refs.as_ref().is_some_and(|others| {
            verified_clear(
                &mut placement,
                others,
                &witnesses,
                [Q, Q, Q, p],
                [0, 0, 0, Q * t0 - p * t0],
            )
        })
    };
    let snap = |s: f64| {
        if s >= 1.0 {
            (s * Q as f64).ceil()
        } else {
            (s * Q as f64).floor()
        }
        .max(1.0) as i64
    };
    // Grow away from 1 by 10 % until it clears ...
    let (mut failed, mut cleared) = (None, None);
    for _ in 0..=GROWTH_STEPS {
        let p = snap(s);
        if try_p(p) {
            cleared = Some(p);
            break;
        }
        failed = Some(p);
        s = if s >= 1.0 { s * 1.1 } else { s / 1.1 };
    }
    let Some(mut clear) = cleared else {
        return failed.map(|p| TimeScaling {
            t0,
            scale: p as f64 / Q as f64,
            verified_clear: false,
        });
    };
    // ... then bisect the steps p between the last scale that failed and the first that
    // cleared, for the clearing scale closest to 1 (the least retiming) found that way.
    if let Some(mut fail) = failed {
        while (clear - fail).abs() > 1 {
            let mid = (clear + fail) / 2;
            if try_p(mid) {
                clear = mid;
            } else {
                fail = mid;
            }
        }
    }
    Some(TimeScaling {
        t0,
        scale: clear as f64 / Q as f64,
        verified_clear: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{check_pair, CommonLattice};
    use chronotope_mesh::glue::BodyMesh;

    const SIZE: [u32; 3] = [14, 11, 10];

    /// A box of voxels `lo..=hi` moved by `dx` voxels along x per frame, over `frames`.
    fn moving_box(lo: [usize; 3], hi: [usize; 3], dx: usize, frames: usize) -> BodyMesh {
        let stamps: Vec<i64> = (0..frames as i64).map(|k| k * 100_000_000).collect();
        chronotope_mesh::glue::test_body(SIZE, [0.0; 3], &stamps, |k, p| {
            let q = [p[0].wrapping_sub(dx * k), p[1], p[2]];
            (0..3).all(|c| (lo[c]..=hi[c]).contains(&q[c]))
        })
    }

    /// The direction search with its pruning picks the direction, distance and exits that
    /// every direction's exits in full give, and the pruning drops directions.
    #[test]
    fn pruned_direction_search_picks_what_the_full_one_picks() {
        let mut dropped = 0;
        let scenes = [
            (([1, 2, 2], [4, 7, 6], 1), ([4, 1, 1], [8, 8, 8], 0)),
            (([2, 3, 1], [5, 6, 4], 2), ([6, 2, 2], [9, 9, 7], 0)),
            (([1, 1, 3], [3, 9, 8], 1), ([3, 4, 1], [10, 6, 5], 1)),
        ];
        for ((alo, ahi, adx), (blo, bhi, bdx)) in scenes {
            let a = moving_box(alo, ahi, adx, 4);
            let b = moving_box(blo, bhi, bdx, 4);
            let lat = CommonLattice::of(&[("a", &a), ("b", &b)]).expect("one lattice");
            let (pa, pb) = (
                lat.prepare("a", &a).expect("a"),
                lat.prepare("b", &b).expect("b"),
            );
            let r = check_pair(&pa, &pb);
            assert!(r.interfering());
            let m = Metric::new(&lat, 0.1);
            let mut directions: Vec<(V4, &'static str)> = Vec::new();
            for k in 0..4 {
                for s in [1.0, -1.0] {
                    let mut u = [0.0; 4];
                    u[k] = s;
                    directions.push((u, "axis"));
                    let mut w = [0.3, -0.2, 0.1, 0.25];
                    w[k] += s;
                    let n = w.iter().map(|x| x * x).sum::<f64>().sqrt();
                    directions.push((w.map(|x| x / n), "search"));
                }
            }
            // Every direction's exits in full, as the search ran before its pruning.
            let full: Vec<Option<Vec<(usize, Vec<Exit>)>>> = directions
                .iter()
                .map(|(u, _)| {
                    let dir: V4 = [0, 1, 2, 3].map(|k| u[k] / m.sigma[k]);
                    Some(vec![(0, exits(&pa, &r, &pb, &dir))])
                })
                .collect();
            let pruned = direction_exits(&pa, &[&pb], &[&r], &[0], &directions, &m);
            let best = shortest(&full).expect("a way out");
            assert_eq!(shortest(&pruned), Some(best));
            assert_eq!(pruned[best.1], full[best.1]);
            dropped += pruned.iter().filter(|p| p.is_none()).count();
        }
        assert!(dropped > 0, "the pruning dropped no direction");
    }

    /// A move's containment, decided from the contact tets and each component's tries
    /// ([`interferes`]), is what labelling every tet of both bodies says, on moves that
    /// nest, touch from inside and outside, cross and miss.
    #[test]
    fn containment_from_contact_tets_answers_as_labelling_does() {
        use crate::labels::{Label, Touch};
        use crate::walk::{label_against, walk};
        let by_labels = |a: &Prepared, b: &Prepared| {
            let all = walk(a, b, true);
            if all.interfering_pairs > 0 {
                return (true, true, false);
            }
            let touched = all
                .hit_a
                .iter()
                .chain(&all.hit_b)
                .any(|t| *t != Touch::Clear);
            let inside = label_against(a, b, &all.hit_a)
                .labels
                .contains(&Label::Inside)
                || label_against(b, a, &all.hit_b)
                    .labels
                    .contains(&Label::Inside);
            (inside, false, touched)
        };
        // (moving body, static body, frames of each): nested (the moved body's frames
        // within the other's), side by side, crossing.
        let scenes = [
            (
                ([4, 4, 3], [6, 6, 5], 0),
                ([1, 1, 1], [12, 9, 8], 0),
                (2, 4),
            ),
            (([1, 2, 2], [4, 7, 6], 0), ([6, 1, 1], [9, 8, 8], 0), (3, 3)),
            (([1, 2, 2], [4, 7, 6], 1), ([6, 3, 1], [9, 6, 8], 0), (3, 3)),
            // Moving inside the other until, at its last frame, its face reaches the
            // other's wall: they touch along a ridge, from inside.
            (
                ([6, 4, 3], [8, 6, 5], 1),
                ([1, 1, 1], [12, 9, 8], 0),
                (3, 5),
            ),
        ];
        let (mut nested, mut touching, mut inside_touching) = (0, 0, 0);
        for ((alo, ahi, adx), (blo, bhi, bdx), (fa, fb)) in scenes {
            let a = moving_box(alo, ahi, adx, fa);
            let b = moving_box(blo, bhi, bdx, fb);
            let lat = CommonLattice::of(&[("a", &a), ("b", &b)]).expect("one lattice");
            let (pa, pb) = (
                lat.prepare("a", &a).expect("a"),
                lat.prepare("b", &b).expect("b"),
            );
            let mut placement = Placement::new(&pa);
            for dx in (-40..=40).step_by(4) {
                for dy in (-24..=24).step_by(8) {
                    for dt in [-8, 0, 8] {
                        let moved = placement.place([1; 4], [dx, dy, 0, dt]).expect("fits");
                        let (inside, crossing, touched) = by_labels(moved, &pb);
                        assert_eq!(interferes(moved, &pb), inside, "move {:?}", [dx, dy, 0, dt]);
                        if !crossing {
                            nested += usize::from(inside && !touched);
                            touching += usize::from(touched);
                            inside_touching += usize::from(inside && touched);
                        }
                    }
                }
            }
        }
        assert!(
            nested > 0 && touching > 0 && inside_touching > 0,
            "nested {nested}, touching {touching}, inside and touching {inside_touching}"
        );
    }
}
