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
//! checker. Speed: a candidate that does not clear is usually refuted by a witness, a
//! sample tet that was inside the other body and whose moved interior point still is (one
//! exact ray, [`mapped_tet_inside`]); the others get the full check, which decides as
//! [`interferes`] does for the bodies placed, without placing them: the trees are walked
//! with their boxes, tets and normals mapped as they are read (the walk stops at the first
//! interfering pair, as a failing candidate's usually does), and containment is tested
//! in frames where the tree tested against is the prepared one, at most scaled, and the
//! tested tets are mapped as they are read. A placement writes a whole tree, every vertex
//! and every normal out for every candidate; this reads the few the other body comes near.
//! A clear verdict always comes from the full check.

use super::inclusion::Inclusion;
use super::labels::{any_inside, Label, Touch};
use super::{
    faces_apart, facing, gcd64, interferes, mapped_tet_inside, normal_in_i32, one_instant, sides,
    straddles, strictly_one_side, tet_of, CommonLattice, PairResult, Placement, Prepared,
    TetInside, TetSource, NO_NORMAL, SPLIT_DEPTH,
};
use chronotope_kernel::bvh::{Bvh, Node, TraverseWorkspace};
use chronotope_kernel::intersect::{classify_if, TetPairRelation};
use chronotope_kernel::{Aabb4, LatticePoint};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};

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

/// Sample tets whose rays one task casts (about 60 tasks for the most samples).
const SAMPLES_PER_TASK: usize = 64;

/// The sample points of `a` inside `b` (see [`samples`]) with their exits along `dir`, in
/// sample order; `None` as soon as one exit lies farther than `bound` (`f64` bits of a
/// positive distance): then `dir` is not the shortest way out. The rays are cast on all
/// cores, a task of [`SAMPLES_PER_TASK`] at a time.
fn exits_within(
    a: &Prepared,
    samples: &[u32],
    b: &Prepared,
    dir: &V4,
    bound: &AtomicU64,
) -> Option<Vec<Exit>> {
    let tasks: Option<Vec<Vec<Exit>>> = samples
        .par_chunks(SAMPLES_PER_TASK)
        .map_init(
            || (TraverseWorkspace::new(), Vec::new()),
            |(ws, hits), task| {
                let mut out = Vec::new();
                for &t in task {
                    let point = centroid(&tet_of(&a.mesh, t));
                    let xs = ray_crossings(&point, dir, b, ws, hits);
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
            },
        )
        .collect();
    tasks.map(|t| t.concat())
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

/// The exact check of one body's candidate moves against the others, as a search places
/// them, without placing them: the moved body is [`Seen`] through the move, the others
/// through one scaling set at the start (1; the time scaling's refinement Q; a rotation's
/// lattice refinement n about its point).
struct Verifier<'a> {
    moved: Seen<'a>,
    others: Vec<Seen<'a>>,
    /// The others' scaling x → n·(x − centre): n and the centre.
    scale: (i64, LatticePoint),
    /// The stamp of the latest walk (see [`walk_seen`]).
    stamp: u32,
    /// The moved body placed in full, for a move whose frame does not fit (made when
    /// first needed, see [`other_inside`]).
    placed: Option<Placement<'a>>,
}

impl<'a> Verifier<'a> {
    /// Checks of moves of `a` against `others` scaled by `n` about `centre`
    /// (x → n·(x − centre) on every axis); `None` if a scaled coordinate would leave
    /// ±2^30, where a scaled copy could not be placed.
    fn new(a: &'a Prepared, others: &[&'a Prepared], n: i64, centre: LatticePoint) -> Option<Self> {
        let map = AxisMap {
            mul: [n; 4],
            add: centre.map(|c| i64::from(c).saturating_mul(-n)),
        };
        // Bodies taken as they are need no room (as the checks of placed bodies take them).
        let others = others
            .iter()
            .map(|b| {
                let mut seen = Seen::new(b);
                (map == AxisMap::IDENTITY || seen.place(map)).then_some(seen)
            })
            .collect::<Option<Vec<_>>>()?;
        Some(Self {
            moved: Seen::new(a),
            others,
            scale: (n, centre),
            stamp: 0,
            placed: None,
        })
    }

    /// The inclusion tests of the other body `k` as it is seen (`None` if its scaling
    /// does not fit).
    fn inclusion_of(&self, k: usize) -> Option<Inclusion<'a>> {
        let b = self.others[k].body;
        let inc = Inclusion::with_normals(&b.mesh, &b.bvh, &b.normals);
        match self.scale {
            (1, [0, 0, 0, 0]) => Some(inc),
            (n, centre) => inc.scaled(n, centre),
        }
    }

    /// Whether the move `map` of the body clears every other body, exactly. Before the
    /// full check, up to [`WITNESSES`] of `likely` (sample tets with the body they were
    /// inside, most likely still inside first) are tested with [`mapped_tet_inside`]: one
    /// inside proves the move fails at the cost of a ray, with neither a walk nor labels.
    /// A clear verdict always comes from the full check ([`Verifier::interferes`]).
    fn verified_clear(&mut self, likely: &[(u32, usize)], map: AxisMap) -> bool {
        let a = self.moved.body;
        let mut tests: Vec<Option<Inclusion>> = (0..self.others.len())
            .map(|k| self.inclusion_of(k))
            .collect();
        if likely.iter().take(WITNESSES).any(|&(t, i)| {
            tests[i]
                .as_mut()
                .is_some_and(|inc| mapped_tet_inside(a, t, map.mul, map.add, inc))
        }) {
            return false;
        }
        self.moved.place(map) && (0..self.others.len()).all(|k| !self.interferes(k))
    }

    /// Whether the moved body interferes with other body `k`, exactly as [`interferes`]
    /// decides it for the two bodies placed: a tet pair that interferes
    /// ([`walk_seen`]), else a part of one inside the other, decided from the tets that
    /// meet the other body as labelling decides it ([`any_inside`]). The moved body's
    /// parts are tested in the placed coordinates; the other's in a frame where the moved
    /// body is only scaled ([`other_inside`]).
    fn interferes(&mut self, k: usize) -> bool {
        self.stamp = match self.stamp.checked_add(1) {
            Some(s) => s,
            None => {
                // After 2^32 walks: clear every stamp and count again.
                for seen in std::iter::once(&mut self.moved).chain(&mut self.others) {
                    seen.marks.iter_mut().for_each(|m| *m.get_mut() = 0);
                }
                1
            }
        };
        let stamp = self.stamp;
        self.moved.prepare_marks();
        self.others[k].prepare_marks();
        if walk_seen(&self.moved, &self.others[k], stamp) {
            return true;
        }
        self.moved.touches(stamp);
        self.others[k].touches(stamp);
        let Some(inc) = self.inclusion_of(k) else {
            return true;
        };
        let Self {
            moved,
            others,
            placed,
            ..
        } = self;
        let (a, b) = (&*moved, &others[k]);
        let (a_inside, b_inside) = rayon::join(
            || {
                any_inside(
                    &a.body.adjacency,
                    &a.touch,
                    a.body.components(),
                    &mut seen_inside(a.body, a.map, inc),
                )
            },
            || other_inside(a, b, placed),
        );
        a_inside || b_inside
    }
}

/// The gradient of the overlap hypervolume with respect to translating `a`, in the
/// lattice's units (sum of outward N_τ/6 over the tets of `a` inside the others).
fn overlap_gradient(a: &Prepared, results: &[&PairResult]) -> V4 {
    let mut g = [0.0; 4];
    for r in results {
        // The normals on all cores, summed in tet order (the same sum, bit for bit).
        let terms: Vec<(f64, V4)> = r
            .labels_a
            .labels
            .par_iter()
            .enumerate()
            .filter_map(|(i, l)| {
                let w = match l {
                    Label::Inside => 1.0 / 6.0,
                    Label::Interference => 0.5 / 6.0,
                    Label::Outside => return None,
                };
                Some((w, normal(&tet_of(&a.mesh, i as u32))))
            })
            .collect();
        for (w, n) in terms {
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
/// body of `hits` along it; the directions one after the other in the order given, each
/// one's rays on all cores ([`exits_within`]).
///
/// A direction is dropped (`None`) as soon as one of its exits lies farther
/// than the farthest exit of a direction already done: it cannot be the shortest. The
/// shortest is never dropped (its exits are all within every done direction's farthest),
/// so [`shortest`] picks what it picks from all exits in full. Done in turn, every
/// direction after the first is held to the best of those before it (the gradient comes
/// first, and is mostly the best or near it), so most are dropped after a few rays.
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
        .iter()
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
    let mut verifier = Verifier::new(a, others, 1, [0; 4]);
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
        let ok = verifier.as_mut().is_some_and(|c| {
            c.verified_clear(
                &witnesses,
                AxisMap {
                    mul: [1; 4],
                    add: v,
                },
            )
        });
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
    let map = AxisMap {
        mul: [1; 4],
        add: best_t.lattice,
    };
    best_t.verified_clear = clear_when_placed(a, others, map, 1, "translation");
    Some(best_t)
}

/// The suggestion a user acts on, checked once more on another path: the body moved by
/// `map` and the others refined `scale` times placed in full (copies), and checked as
/// [`interferes`] checks any two bodies. The search's verdicts come from the check of the
/// bodies as they are read ([`Verifier`]), which answers as this one does (tests); should
/// the two ever disagree, the suggestion is not said to be clear, and the disagreement is
/// logged as the bug it is.
fn clear_when_placed(
    a: &Prepared,
    others: &[&Prepared],
    map: AxisMap,
    scale: i64,
    what: &str,
) -> bool {
    let moved = a.mapped(map.mul, map.add);
    // The others as the search saw them: as they are, or refined `scale` times.
    let refined: Option<Vec<Prepared>> = match scale {
        1 => Some(Vec::new()),
        n => others.iter().map(|b| b.mapped([n; 4], [0; 4])).collect(),
    };
    let placed: Option<Vec<&Prepared>> = refined.as_ref().map(|r| match scale {
        1 => others.to_vec(),
        _ => r.iter().collect(),
    });
    let (Some(moved), Some(placed)) = (moved, placed) else {
        tracing::warn!(
            body = %a.id,
            "the {what} found clear does not fit the lattice when the bodies are placed, so it \
             cannot be checked again; it is not suggested as clear"
        );
        return false;
    };
    let clear = placed.iter().all(|b| !interferes(&moved, b));
    if !clear {
        tracing::error!(
            body = %a.id,
            "the {what} found clear is not clear when placed (a bug: please report it); it is \
             not suggested as clear"
        );
    }
    clear
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
    // s = p/Q with Q = 64, rounded away from 1; the others are seen refined Q times.
    const Q: i64 = 64;
    let mut verifier = Verifier::new(a, others, Q, [0; 4]);
    let mut try_p = |p: i64| {
        let witnesses: Vec<(u32, usize)> = likely
            .iter()
            .take_while(|w| w.0 > p as f64 / Q as f64)
            .map(|w| (w.1, w.2))
            .collect();
        // Times become Q·t0 + p·(t − t0) on the lattice refined Q times: t_s = t0 + s (t − t0).
        let map = AxisMap {
            mul: [Q, Q, Q, p],
            add: [0, 0, 0, Q * t0 - p * t0],
        };
        verifier
            .as_mut()
            .is_some_and(|c| c.verified_clear(&witnesses, map))
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
    let map = AxisMap {
        mul: [Q, Q, Q, clear],
        add: [0, 0, 0, Q * t0 - clear * t0],
    };
    Some(TimeScaling {
        t0,
        scale: clear as f64 / Q as f64,
        verified_clear: clear_when_placed(a, others, map, Q, "time scaling"),
    })
}

/// Coordinates the exact predicates see stay strictly within ±2^30 (their far points must
/// fit `i32`), as [`Placement::place`] keeps them.
const COORDINATE_LIMIT: i64 = 1 << 30;

/// An increasing map x_k → mul_k·x_k + add_k on each axis (every `mul_k > 0`): a
/// translation (every `mul_k` 1), or a time scaling on the lattice refined Q times (Q on
/// space, p on time), or a refinement alone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct AxisMap {
    mul: [i64; 4],
    add: [i64; 4],
}

impl AxisMap {
    const IDENTITY: Self = Self::scaling(1);

    /// x → n·x on every axis.
    const fn scaling(n: i64) -> Self {
        Self {
            mul: [n; 4],
            add: [0; 4],
        }
    }

    /// Whether it maps every point of the box with these extremes (per axis, smallest and
    /// largest) strictly within ±2^30: an increasing map takes its extremes there.
    fn keeps_within(&self, bounds: &[[i32; 2]; 4]) -> bool {
        (0..4).all(|k| {
            self.mul[k] > 0
                && bounds[k].iter().all(|&c| {
                    i64::from(c)
                        .checked_mul(self.mul[k])
                        .and_then(|v| v.checked_add(self.add[k]))
                        .is_some_and(|v| v.abs() < COORDINATE_LIMIT)
                })
        })
    }

    /// `p` mapped; the caller knows that it fits ([`AxisMap::keeps_within`]).
    #[inline]
    fn point(&self, p: &LatticePoint) -> LatticePoint {
        [0, 1, 2, 3].map(|k| (i64::from(p[k]) * self.mul[k] + self.add[k]) as i32)
    }

    /// The box of the image of `b`, a box within the extremes the map keeps within ±2^30
    /// (every box of a body's tree lies within its vertices' extremes).
    #[inline]
    fn image(&self, b: &Aabb4) -> Aabb4 {
        if b.is_empty() {
            return Aabb4::EMPTY;
        }
        Aabb4::new(self.point(&b.min), self.point(&b.max))
    }

    /// The weights of a tet's normal under the map, as [`Placement::place`] maps normals
    /// (the cofactor rule, N'_k = N_k · Π_{j≠k} mul_j, divided by the weights' gcd);
    /// `None` where they are all 1 (the normals are the source's).
    fn normal_weights(&self) -> Option<[i128; 4]> {
        let weight = [0, 1, 2, 3].map(|k| {
            (0..4)
                .filter(|&j| j != k)
                .map(|j| i128::from(self.mul[j]))
                .product::<i128>()
        });
        let g = weight
            .iter()
            .fold(0u128, |g, &w| super::gcd(g, w.unsigned_abs()))
            .max(1) as i128;
        let weight = weight.map(|w| w / g);
        (weight != [1; 4]).then_some(weight)
    }
}

/// A prepared body as a candidate move places it, without placing it: seen through an
/// [`AxisMap`], its tree's boxes, its tets and their normals mapped as a walk reads them.
/// A [`Placement`] writes the whole tree, every vertex and every normal out for every
/// move; a walk reads the few the other body comes near.
struct Seen<'a> {
    body: &'a Prepared,
    /// The smallest and largest coordinate of its vertices on each axis (`None` without
    /// vertices).
    bounds: Option<[[i32; 2]; 4]>,
    map: AxisMap,
    /// The map is the identity.
    identity: bool,
    /// The normals' weights under the map (see [`AxisMap::normal_weights`]).
    weights: Option<[i128; 4]>,
    /// Per tet, the stamp of the latest walk that found it meeting the other body.
    marks: Vec<AtomicU32>,
    /// Per tet, how it meets the other body after the latest walk, as containment needs
    /// it (clear or not).
    touch: Vec<Touch>,
}

impl<'a> Seen<'a> {
    /// `body` as it is.
    fn new(body: &'a Prepared) -> Self {
        let bounds = body.mesh.vertices.split_first().map(|(first, rest)| {
            let mut b = first.map(|c| [c, c]);
            for p in rest {
                for k in 0..4 {
                    b[k][0] = b[k][0].min(p[k]);
                    b[k][1] = b[k][1].max(p[k]);
                }
            }
            b
        });
        Self {
            body,
            bounds,
            map: AxisMap::IDENTITY,
            identity: true,
            weights: None,
            marks: Vec::new(),
            touch: Vec::new(),
        }
    }

    /// Sees the body through `map`; `false`, with the body unusable until the next
    /// placement, if a coordinate would leave ±2^30 (where [`Placement::place`] refuses).
    fn place(&mut self, map: AxisMap) -> bool {
        if !self.bounds.is_none_or(|b| map.keeps_within(&b)) {
            return false;
        }
        self.map = map;
        self.identity = map == AxisMap::IDENTITY;
        self.weights = map.normal_weights();
        true
    }

    /// Tet `i` as seen.
    #[inline]
    fn tet(&self, i: u32) -> [LatticePoint; 4] {
        let t = tet_of(&self.body.mesh, i);
        if self.identity {
            t
        } else {
            t.map(|p| self.map.point(&p))
        }
    }

    /// Tet `i` with its vertices and normal as seen.
    #[inline]
    fn seen_tet(&self, i: u32) -> SeenTet {
        (i, self.tet(i), self.normal(i))
    }

    /// The normal of tet `i` as seen: the one a placed copy would hold.
    #[inline]
    fn normal(&self, i: u32) -> [i32; 4] {
        let n = self.body.normals[i as usize];
        match &self.weights {
            Some(w) if n != NO_NORMAL => {
                normal_in_i32([0, 1, 2, 3].map(|k| i128::from(n[k]) * w[k]))
            }
            _ => n,
        }
    }

    /// A box of the body's tree as seen.
    #[inline]
    fn image(&self, b: &Aabb4) -> Aabb4 {
        if self.identity {
            *b
        } else {
            self.map.image(b)
        }
    }

    /// Makes room for a stamp per tet (once).
    fn prepare_marks(&mut self) {
        let n = self.body.mesh.tets.len();
        if self.marks.len() != n {
            self.marks = (0..n).map(|_| AtomicU32::new(0)).collect();
        }
    }

    /// The touches of the walk with `stamp`: a tet it marked meets the other body.
    fn touches(&mut self, stamp: u32) {
        self.touch.clear();
        self.touch.extend(self.marks.iter_mut().map(|m| {
            if *m.get_mut() == stamp {
                Touch::Contact
            } else {
                Touch::Clear
            }
        }));
    }
}

/// How two tets meet, as far as the check of a move needs it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Meet {
    /// Disjoint (or, where touching does not matter, at most touching).
    Apart,
    /// The closed tets meet without interfering.
    Touch,
    /// Their relative interiors cross, or they overlap in one hyperplane facing the same
    /// way.
    Interferes,
}

/// How tets `ta` and `tb` (normals `na` and `nb`, as [`Prepared::normals`]) meet, exactly
/// (the checker's walk, `walk::visit`, also takes a pair whose boxes meet in one plane
/// only as touching untested; here every pair is decided): a pair meeting in one
/// instant only touches, and only where its faces there meet; one with a tet strictly on
/// one side of the other's hyperplane is apart; a pair facing each other in one hyperplane
/// never interferes; unless `touching_matters`, a pair that can at most touch is apart;
/// the rest is the exact relation ([`classify_if`]).
pub(crate) fn meet(
    ta: &[LatticePoint; 4],
    na: &[i32; 4],
    tb: &[LatticePoint; 4],
    nb: &[i32; 4],
    touching_matters: bool,
) -> Meet {
    if let Some(instant) = one_instant(ta, tb) {
        if !touching_matters || faces_apart(ta, tb, instant) {
            return Meet::Apart;
        }
    }
    let sides_of_b = sides(na, ta, tb);
    if sides_of_b.is_some_and(|s| strictly_one_side(&s)) {
        return Meet::Apart;
    }
    if sides_of_b == Some([0; 4]) && facing(na, nb) {
        let touch = touching_matters && classify_if(ta, tb, true) != TetPairRelation::Disjoint;
        return if touch { Meet::Touch } else { Meet::Apart };
    }
    let sides_of_a = sides(nb, tb, ta);
    if sides_of_a.is_some_and(|s| strictly_one_side(&s)) {
        return Meet::Apart;
    }
    if let (false, Some(sb), Some(sa)) = (touching_matters, sides_of_b, sides_of_a) {
        if sb != [0; 4] && !(straddles(&sb) && straddles(&sa)) {
            return Meet::Apart;
        }
    }
    match classify_if(ta, tb, touching_matters) {
        TetPairRelation::Crossing
        | TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            same_orientation: true,
        } => Meet::Interferes,
        TetPairRelation::Disjoint => Meet::Apart,
        TetPairRelation::Coplanar { .. } | TetPairRelation::Touching => Meet::Touch,
    }
}

/// Pushes the child pairs of node pair `(i, j)` (not both leaves) whose boxes, as seen,
/// overlap: both nodes split when both are internal, as the checker's walk does.
#[inline]
fn expand_seen(a: &Seen, b: &Seen, i: u32, j: u32, mut push: impl FnMut(u32, u32)) {
    let (ta, tb) = (a.body.bvh.nodes(), b.body.bvh.nodes());
    let (na, nb) = (&ta[i as usize], &tb[j as usize]);
    let children = |n: &Node, at: u32| {
        if n.is_leaf() {
            [Some(at), None]
        } else {
            [Some(n.first), Some(n.first + 1)]
        }
    };
    for c in children(na, i).into_iter().flatten() {
        let box_a = a.image(&ta[c as usize].aabb);
        if !box_a.overlaps(&b.image(&nb.aabb)) {
            continue;
        }
        for d in children(nb, j).into_iter().flatten() {
            if box_a.overlaps(&b.image(&tb[d as usize].aabb)) {
                push(c, d);
            }
        }
    }
}

/// Whether some tet of `a` and some tet of `b`, both as seen, interfere, exactly as the
/// checker's walk finds it for the two placed ([`meet`] on every pair whose boxes
/// overlap): the trees are walked against each other on all cores, their boxes mapped as
/// they are reached (an increasing map keeps every containment, so the pairs met are the
/// placed trees' pairs). Where none interferes, every tet that meets the other body ends
/// with `stamp` in its mark: the walk's contact tets, all that containment needs of them
/// ([`any_inside`] asks only which tets are clear). A pair whose tets are both marked
/// already is tested only for interference.
fn walk_seen(a: &Seen, b: &Seen, stamp: u32) -> bool {
    let (ta, tb) = (&a.body.bvh, &b.body.bvh);
    let (Some(ra), Some(rb)) = (ta.nodes().first(), tb.nodes().first()) else {
        return false;
    };
    if !a.image(&ra.aabb).overlaps(&b.image(&rb.aabb)) {
        return false;
    }
    // Node pairs a few levels down, whose sub-walks are disjoint: the workers' shares.
    let mut tops = vec![(0u32, 0u32)];
    for _ in 0..SPLIT_DEPTH {
        let level = tops.len();
        let mut expanded = false;
        for k in 0..level {
            let (i, j) = tops[k];
            if ta.nodes()[i as usize].is_leaf() && tb.nodes()[j as usize].is_leaf() {
                tops.push((i, j));
            } else {
                expanded = true;
                expand_seen(a, b, i, j, |x, y| tops.push((x, y)));
            }
        }
        tops.drain(..level);
        if !expanded {
            break;
        }
    }
    let found = AtomicBool::new(false);
    tops.par_iter().for_each_init(Vec::new, |stack, &top| {
        if !found.load(Ordering::Relaxed) && walk_under(a, b, top, stamp, stack, &found) {
            found.store(true, Ordering::Relaxed);
        }
    });
    found.into_inner()
}

/// One share of [`walk_seen`]: the pairs below node pair `top`; `true` at the first that
/// interferes, `false` at the end or once `found` says another share found one.
fn walk_under(
    a: &Seen,
    b: &Seen,
    top: (u32, u32),
    stamp: u32,
    stack: &mut Vec<(u32, u32)>,
    found: &AtomicBool,
) -> bool {
    let (ta, tb) = (&a.body.bvh, &b.body.bvh);
    stack.clear();
    stack.push(top);
    while let Some((i, j)) = stack.pop() {
        let (na, nb) = (&ta.nodes()[i as usize], &tb.nodes()[j as usize]);
        if !(na.is_leaf() && nb.is_leaf()) {
            expand_seen(a, b, i, j, |x, y| stack.push((x, y)));
            continue;
        }
        if found.load(Ordering::Relaxed) {
            return false;
        }
        if leaves_interfere(a, b, na, nb, stamp) {
            return true;
        }
    }
    false
}

/// A tet as a walk reads it: its index, its vertices and its normal as seen.
type SeenTet = (u32, [LatticePoint; 4], [i32; 4]);

/// The tet pairs of two leaves whose boxes, as seen, overlap ([`pair_seen`]): `true` at
/// the first that interferes. Each tet is mapped once for the leaf pair, however many of
/// the other leaf's tets it meets.
fn leaves_interfere(a: &Seen, b: &Seen, na: &Node, nb: &Node, stamp: u32) -> bool {
    let (ta, tb) = (&a.body.bvh, &b.body.bvh);
    let box_nb = b.image(&nb.aabb);
    let slots_b = nb.slots();
    // The other leaf's boxes and tets, mapped when first needed (a leaf holds at most
    // Bvh::LEAF_SIZE items; a larger one, which no build makes, is read without a cache).
    let cached = slots_b.len() <= Bvh::LEAF_SIZE;
    let mut boxes_b = [Aabb4::EMPTY; Bvh::LEAF_SIZE];
    if cached {
        for (k, sb) in slots_b.clone().enumerate() {
            boxes_b[k] = b.image(&tb.leaf_boxes()[sb]);
        }
    }
    let mut tets_b: [Option<SeenTet>; Bvh::LEAF_SIZE] = [None; Bvh::LEAF_SIZE];
    for sa in na.slots() {
        let box_a = a.image(&ta.leaf_boxes()[sa]);
        if !box_a.overlaps(&box_nb) {
            continue;
        }
        let mut tet_a: Option<SeenTet> = None;
        for (k, sb) in slots_b.clone().enumerate() {
            let box_b = if cached {
                boxes_b[k]
            } else {
                b.image(&tb.leaf_boxes()[sb])
            };
            if !box_a.overlaps(&box_b) {
                continue;
            }
            let x = *tet_a.get_or_insert_with(|| a.seen_tet(ta.order()[sa]));
            let y = if cached {
                *tets_b[k].get_or_insert_with(|| b.seen_tet(tb.order()[sb]))
            } else {
                b.seen_tet(tb.order()[sb])
            };
            if pair_seen(a, b, &x, &y, stamp) {
                return true;
            }
        }
    }
    false
}

/// Tet `x` of `a` against tet `y` of `b`, as seen: `true` if they interfere, else both
/// marked with `stamp` if they meet (touching matters only while one is not marked yet).
#[inline]
fn pair_seen(a: &Seen, b: &Seen, x: &SeenTet, y: &SeenTet, stamp: u32) -> bool {
    let (mark_a, mark_b) = (&a.marks[x.0 as usize], &b.marks[y.0 as usize]);
    let touching_matters =
        mark_a.load(Ordering::Relaxed) != stamp || mark_b.load(Ordering::Relaxed) != stamp;
    match meet(&x.1, &x.2, &y.1, &y.2, touching_matters) {
        Meet::Interferes => true,
        Meet::Touch => {
            mark_a.store(stamp, Ordering::Relaxed);
            mark_b.store(stamp, Ordering::Relaxed);
            false
        }
        Meet::Apart => false,
    }
}

/// One body's tets seen through an axis map into some frame: inclusion tests of them against
/// a body in that frame are what the checker's labelling asks of a placed body
/// ([`TetInside`]), for a body that is not placed.
#[derive(Clone, Copy)]
struct SeenTets<'a> {
    body: &'a Prepared,
    /// Into the frame (its far points and coordinates within ±2^30, checked).
    map: AxisMap,
}

impl TetSource for SeenTets<'_> {
    #[inline]
    fn tet(&self, t: u32) -> [LatticePoint; 4] {
        tet_of(&self.body.mesh, t).map(|p| self.map.point(&p))
    }
}

/// Inclusion tests of `body`'s tets, seen through `map`, against `inc`.
type SeenInside<'a> = TetInside<'a, SeenTets<'a>>;

/// The tests of `body`'s tets seen through `map` against `inc`.
fn seen_inside<'a>(body: &'a Prepared, map: AxisMap, inc: Inclusion<'a>) -> SeenInside<'a> {
    TetInside {
        mesh: SeenTets { body, map },
        inc,
    }
}

/// The frame in which the body moved by `a` is only scaled, x → n·x, with the map that
/// takes a body seen through `b` there: the increasing axis map φ_k(y) =
/// (n/a.mul_k)·(y − a.add_k) with the least n that makes φ∘b integer, n = lcm_k of
/// a.mul_k / gcd(a.mul_k, b.mul_k, b.add_k − a.add_k). A translation by v gives n = 1
/// and b − v; a time scaling p/Q against the others refined Q times gives n = p/gcd(p, Q).
/// `None` if a number overflows.
fn frame_of(a: &AxisMap, b: &AxisMap) -> Option<(i64, AxisMap)> {
    let mut n: i64 = 1;
    for k in 0..4 {
        let d = b.add[k].checked_sub(a.add[k])?;
        let g = gcd64(
            a.mul[k].unsigned_abs(),
            gcd64(b.mul[k].unsigned_abs(), d.unsigned_abs()),
        );
        let need = a.mul[k] / i64::try_from(g.max(1)).ok()?;
        let common = i64::try_from(gcd64(n.unsigned_abs(), need.unsigned_abs())).ok()?;
        n = (n / common).checked_mul(need)?;
    }
    let mut map = AxisMap::IDENTITY;
    for k in 0..4 {
        // Exact: a.mul_k divides n·b.mul_k and n·(b.add_k − a.add_k).
        map.mul[k] = n.checked_mul(b.mul[k])? / a.mul[k];
        map.add[k] = n.checked_mul(b.add[k].checked_sub(a.add[k])?)? / a.mul[k];
    }
    Some((n, map))
}

/// Whether a part of `b` lies inside `a`, both as seen, as [`any_inside`] decides it for
/// the two placed (from `b`'s tets that the latest walk found meeting `a`). Decided in
/// the frame where `a` is only scaled ([`frame_of`]): there `a`'s tree and normals serve
/// as they are ([`Inclusion::scaled`]), and `b`'s tets are mapped as they are tested.
///
/// Exact: an increasing axis map keeps every incidence and orientation, so every point,
/// segment and sign tested is the image of the one tested for the placed bodies, and
/// every decided answer is theirs. Under a translation (or no move, as for a rotated
/// body placed) the frame is the placed one moved by a lattice vector, far points
/// included: every test is the same test. Under a time scaling the far points are not
/// the images of the placed body's (they are offset from the box in lattice units of
/// each frame), so a point that no far point decides in one frame (it would have to lie
/// on the other boundary's degenerate alignments towards all six) may be decided in the
/// other; both are exact wherever they decide. If the frame does not fit ±2^30, `a` is
/// placed in full (`placed`) and tested as it is.
fn other_inside<'a>(a: &Seen<'a>, b: &Seen<'_>, placed: &mut Option<Placement<'a>>) -> bool {
    let body = a.body;
    let frame = frame_of(&a.map, &b.map).and_then(|(n, map)| {
        if !b.bounds.is_none_or(|bounds| map.keeps_within(&bounds)) {
            return None;
        }
        let inc = Inclusion::with_normals(&body.mesh, &body.bvh, &body.normals);
        let inc = if n == 1 {
            Some(inc)
        } else {
            inc.scaled(n, [0; 4])
        }?;
        Some(seen_inside(b.body, map, inc))
    });
    match frame {
        Some(mut test) => any_inside(&b.body.adjacency, &b.touch, b.body.components(), &mut test),
        None => other_inside_placed(a, b, placed),
    }
}

/// [`other_inside`] with `a` placed in full (`placed`), in the frame `b` is seen in.
fn other_inside_placed<'a>(a: &Seen<'a>, b: &Seen<'_>, placed: &mut Option<Placement<'a>>) -> bool {
    let placement = placed.get_or_insert_with(|| Placement::new(a.body));
    let Some(moved) = placement.place(a.map.mul, a.map.add) else {
        // Where a placed copy cannot be made, the move is not clear.
        return true;
    };
    let inc = Inclusion::with_normals(&moved.mesh, &moved.bvh, &moved.normals);
    any_inside(
        &b.body.adjacency,
        &b.touch,
        b.body.components(),
        &mut seen_inside(b.body, b.map, inc),
    )
}

/// Whether `a`, as it is, clears every body of `others` scaled by `n` about `centre`
/// (x → n·(x − centre) on every axis), exactly as [`clears`] decides it for the others
/// placed so, without placing them (see [`Verifier::interferes`]); `None` if a scaled
/// coordinate would leave ±2^30.
pub(crate) fn clears_scaled(
    a: &Prepared,
    others: &[&Prepared],
    n: i64,
    centre: LatticePoint,
) -> Option<bool> {
    let mut check = Verifier::new(a, others, n, centre)?;
    Some((0..others.len()).all(|k| !check.interferes(k)))
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

    /// A move checked without placing the bodies ([`Verifier::interferes`]: the trees
    /// walked as seen, containment of the other body in the frame where the moved one is
    /// only scaled, or against the moved body placed) says what the check of the placed
    /// bodies says ([`interferes`]), for translations and time scalings on the lattice
    /// refined Q times that nest, touch, cross and miss.
    #[test]
    fn moves_checked_unplaced_answer_as_placed_bodies_do() {
        let scenes = [
            (
                ([4, 4, 3], [6, 6, 5], 0),
                ([1, 1, 1], [12, 9, 8], 0),
                (2, 4),
            ),
            (([1, 2, 2], [4, 7, 6], 0), ([6, 1, 1], [9, 8, 8], 0), (3, 3)),
            (([1, 2, 2], [4, 7, 6], 1), ([6, 3, 1], [9, 6, 8], 0), (3, 3)),
            (
                ([6, 4, 3], [8, 6, 5], 1),
                ([1, 1, 1], [12, 9, 8], 0),
                (3, 5),
            ),
            // The other body inside the moved one at many moves (its frames within the
            // moved body's).
            (
                ([1, 1, 1], [12, 9, 8], 0),
                ([5, 4, 3], [7, 6, 5], 0),
                (5, 3),
            ),
        ];
        let (mut interfering, mut clear, mut contained) = (0, 0, 0);
        for ((alo, ahi, adx), (blo, bhi, bdx), (fa, fb)) in scenes {
            let a = moving_box(alo, ahi, adx, fa);
            let b = moving_box(blo, bhi, bdx, fb);
            let lat = CommonLattice::of(&[("a", &a), ("b", &b)]).expect("one lattice");
            let (pa, pb) = (
                lat.prepare("a", &a).expect("a"),
                lat.prepare("b", &b).expect("b"),
            );
            let t: Vec<i64> = pa.mesh.vertices.iter().map(|v| i64::from(v[3])).collect();
            let (tmin, tmax) = (t.iter().min().copied(), t.iter().max().copied());
            let mut moves: Vec<(i64, AxisMap)> = Vec::new();
            for dx in (-40..=40).step_by(8) {
                for dy in (-24..=24).step_by(12) {
                    for dt in [-8, 0, 5] {
                        let add = [dx, dy, 0, dt];
                        moves.push((1, AxisMap { mul: [1; 4], add }));
                    }
                }
            }
            const Q: i64 = 64;
            for t0 in [tmin, tmax].into_iter().flatten() {
                for p in (16..=176).step_by(12) {
                    let map = AxisMap {
                        mul: [Q, Q, Q, p],
                        add: [0, 0, 0, Q * t0 - p * t0],
                    };
                    moves.push((Q, map));
                }
            }
            for (scale, map) in moves {
                let placed_a = pa.mapped(map.mul, map.add).expect("fits");
                let placed_b = pb.mapped([scale; 4], [0; 4]).expect("fits");
                let want = interferes(&placed_a, &placed_b);
                let mut check = Verifier::new(&pa, &[&pb], scale, [0; 4]).expect("fits");
                assert!(check.moved.place(map));
                assert_eq!(check.interferes(0), want, "move {map:?}");
                // The other body's containment against the moved body placed in full.
                let walked = walk_seen(&check.moved, &check.others[0], check.stamp);
                if !walked {
                    let (a, b) = (&check.moved, &check.others[0]);
                    let mut placed = None;
                    let inside_b = other_inside_placed(a, b, &mut placed);
                    assert_eq!(other_inside(a, b, &mut None), inside_b, "move {map:?}");
                    contained += usize::from(inside_b);
                }
                if want {
                    interfering += 1;
                } else {
                    clear += 1;
                }
            }
        }
        assert!(
            interfering > 50 && clear > 50 && contained > 20,
            "interfering {interfering}, clear {clear}, other body inside {contained}"
        );
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
