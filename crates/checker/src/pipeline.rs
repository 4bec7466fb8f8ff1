//! The whole check of a set of bodies: every planned pair checked, overlaps measured,
//! resolutions suggested and verified, and the [`Report`] assembled. Shared by `chronotope
//! check` and the rolling checker's resolution step; knows nothing of ROS.

use super::bounds;
use super::prep::BodyPrep;
use super::report::{
    BodyReport, LostSpan, PairLabels, PairReport, Report, Resolution, Timings, UncheckedPair,
    UnsureSpanReport, Verdict,
};
use super::resolve::{suggest_time_scaling, suggest_translation, Metric, TimeScaling, Translation};
use super::rotate::{suggest_rotation, Rotation, RotationSpec};
use super::{
    check_pair, check_pair_walked, CheckError, CommonLattice, PairResult, Prepared, StreamWalk,
};
use chronotope_mesh::glue::{BodyAssembler, BodyMesh};
use chronotope_mesh::stream::LossKind;
use chronotope_mesh::unsure::UnsureLog;
use chronotope_mesh::MesherOptions;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// What to check.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckPlan {
    /// The pairs to check (body ids); `None`: every pair of bodies.
    pub pairs: Option<Vec<(String, String)>>,
    /// Bodies to suggest resolutions for, each against the bodies it is paired with.
    pub movable: Vec<String>,
    /// c (m/s) of the 4D metric; `None`: one voxel per frame period.
    pub time_scale: Option<f64>,
    /// Each body's `header.frame_id`, where known: bodies in different frames are not
    /// checked against each other (the pair is reported as unchecked).
    pub frame_ids: BTreeMap<String, String>,
    /// The axis, point and largest angle of the rotation suggested for a movable body.
    pub rotation: RotationSpec,
}

impl CheckPlan {
    /// Whether the plan checks bodies `a` and `b` against each other.
    pub fn pairs_with(&self, a: &str, b: &str) -> bool {
        a != b
            && self.pairs.as_ref().is_none_or(|p| {
                p.iter()
                    .any(|(x, y)| (x == a && y == b) || (x == b && y == a))
            })
    }

    /// Every pair, resolutions for the body whose id sorts first (the contract's default:
    /// docs/formats.md#command-line).
    pub fn all_pairs_first_movable(ids: &[&str], time_scale: Option<f64>) -> Self {
        let mut sorted: Vec<&str> = ids.to_vec();
        sorted.sort_unstable();
        Self {
            pairs: None,
            movable: sorted.first().map(|s| s.to_string()).into_iter().collect(),
            time_scale,
            frame_ids: BTreeMap::new(),
            rotation: RotationSpec::default(),
        }
    }
}

/// The report and what it was computed from (for publishing labels and markers).
#[derive(Debug)]
pub struct CheckOutcome {
    /// The report (timings: `check` and `resolve` filled in).
    pub report: Report,
    /// The common lattice of the checked bodies, if any was checked.
    pub lattice: Option<CommonLattice>,
    /// Ids of the checked bodies, sorted.
    pub ids: Vec<String>,
    /// Their prepared meshes, in the order of `ids`.
    pub prepared: Vec<Prepared>,
    /// Each checked pair `(i, j)` (indices into `ids`, `i < j`) and its result.
    pub results: Vec<(usize, usize, PairResult)>,
}

/// Checks the planned pairs of `bodies` (bodies with fewer than two frames have no 4D mesh
/// and are left out, with a problem noted), measures the overlaps and suggests resolutions for
/// the movable bodies.
///
/// # Errors
/// The checked bodies are not on one lattice (or their coordinates overflow it).
pub fn check_bodies(
    bodies: &BTreeMap<String, BodyMesh>,
    plan: &CheckPlan,
    opts: MesherOptions,
) -> Result<CheckOutcome, CheckError> {
    check_streamed(bodies, BTreeMap::new(), BTreeMap::new(), plan, opts)
}

/// [`check_bodies`] with some bodies already prepared piece by piece as their streams
/// arrived (`preps`, by body id; see [`checker::prep`](crate::prep)), and some
/// pairs already walked as they arrived (`walks`, by the pair's ids in sorted order; used
/// when both bodies are on the common lattice as prepared): for those only the trees'
/// tops and the labels are left to do.
///
/// # Errors
/// As [`check_bodies`].
pub fn check_streamed(
    bodies: &BTreeMap<String, BodyMesh>,
    mut preps: BTreeMap<String, BodyPrep>,
    mut walks: BTreeMap<(String, String), StreamWalk>,
    plan: &CheckPlan,
    opts: MesherOptions,
) -> Result<CheckOutcome, CheckError> {
    let start = Instant::now();
    let mut problems = unmeshed_bodies(bodies);
    let mut pair_ids = planned_pairs(bodies, plan, &mut problems);
    let unchecked = drop_incomparable(bodies, plan, &mut pair_ids, &mut problems);
    // Bodies that can all be compared are checked together; otherwise each group of
    // pairs that can is checked on its own lattice.
    if !pair_ids.is_empty() && CommonLattice::of(&pair_bodies(bodies, &pair_ids)).is_err() {
        let groups = Groups {
            bodies,
            pair_ids: &pair_ids,
            plan,
            opts,
        };
        return groups.check(preps, walks, problems, unchecked);
    }
    let mut ids: Vec<String> = pair_ids
        .iter()
        .flat_map(|(a, b)| [a.clone(), b.clone()])
        .collect();
    ids.sort();
    ids.dedup();
    let mut report = report_of_bodies(bodies, plan, problems, unchecked);
    if ids.is_empty() {
        report.timings_ms.check = start.elapsed().as_secs_f64() * 1e3;
        return Ok(CheckOutcome {
            report,
            lattice: None,
            ids,
            prepared: Vec::new(),
            results: Vec::new(),
        });
    }
    let named: Vec<(&str, &BodyMesh)> = ids.iter().map(|k| (k.as_str(), &bodies[k])).collect();
    let lat = CommonLattice::of(&named)?;
    let span = (lat.stamps_ns[lat.stamps_ns.len() - 1] - lat.stamps_ns[0]) as f64 * 1e-9;
    let period = span / (lat.stamps_ns.len() - 1) as f64;
    let c = plan.time_scale.unwrap_or(lat.resolution / period);
    report.time_scale_m_per_s = c;
    let index = |id: &str| ids.binary_search_by(|x| x.as_str().cmp(id)).ok();
    let jobs: Vec<(usize, usize)> = pair_ids
        .iter()
        .filter_map(|(a, b)| Some((index(a)?, index(b)?)))
        .collect();
    let time_origin_ns = report.time_origin_ns;
    let checked = CheckedPairs {
        named: &named,
        ids: &ids,
        lat: &lat,
        time_origin_ns,
        opts,
    };
    let (prepared, pairs, results) = checked.check(&jobs, &mut preps, &mut walks)?;
    report.pairs = pairs;
    let t_check = start.elapsed();
    let results: Vec<(usize, usize, PairResult)> = jobs
        .iter()
        .zip(results)
        .map(|(&(i, j), r)| (i, j, r))
        .collect();
    for m in &plan.movable {
        let Some(im) = index(m) else {
            let why = format!("movable body {m}: in no checked pair; no resolution");
            tracing::warn!("{why}");
            report.problems.push(why);
            continue;
        };
        report.resolutions.extend(resolve_movable(
            im,
            &prepared,
            &results,
            &lat,
            c,
            &plan.rotation,
            time_origin_ns,
        ));
    }
    report.timings_ms.check = t_check.as_secs_f64() * 1e3;
    report.timings_ms.resolve = (start.elapsed() - t_check).as_secs_f64() * 1e3;
    report.note_unsure_resolutions();
    Ok(CheckOutcome {
        report,
        lattice: Some(lat),
        ids,
        prepared,
        results,
    })
}

/// The problems of the bodies that have no 4D mesh (fewer than two frames accepted): they
/// are not checked.
fn unmeshed_bodies(bodies: &BTreeMap<String, BodyMesh>) -> Vec<String> {
    let mut problems = Vec::new();
    for (id, b) in bodies {
        if b.stamps_ns.len() < 2 {
            let why = match b.losses.spans.iter().find(|s| s.kind == LossKind::Refused) {
                Some(first) => format!(
                    "{id}: {} frame(s) accepted and {} refused (the first refused at {:.3} s: {}): \
                     a body needs two accepted frames for a 4D mesh; not checked",
                    b.stamps_ns.len(),
                    b.losses.refused_frames,
                    first.from_ns as f64 * 1e-9,
                    first.reason
                ),
                None => format!(
                    "{id}: {} frame(s): a body needs two for a 4D mesh; not checked",
                    b.stamps_ns.len()
                ),
            };
            tracing::warn!("{why}");
            problems.push(why);
        }
    }
    problems
}

/// The pairs the plan asks for whose bodies both have a 4D mesh, each as its ids in sorted
/// order, sorted, once each. A pair the plan names that cannot be checked (a body paired with
/// itself, or without a mesh) is a problem.
fn planned_pairs(
    bodies: &BTreeMap<String, BodyMesh>,
    plan: &CheckPlan,
    problems: &mut Vec<String>,
) -> Vec<(String, String)> {
    let meshed = |id: &str| bodies.get(id).is_some_and(|b| b.stamps_ns.len() >= 2);
    let wanted: Vec<(String, String)> = match &plan.pairs {
        Some(p) => p.clone(),
        None => {
            let ids: Vec<&String> = bodies.keys().collect();
            (0..ids.len())
                .flat_map(|i| (i + 1..ids.len()).map(move |j| (i, j)))
                .map(|(i, j)| (ids[i].clone(), ids[j].clone()))
                .collect()
        }
    };
    let mut pair_ids = Vec::new();
    for (a, b) in wanted {
        let missing: Vec<&String> = [&a, &b].into_iter().filter(|x| !meshed(x)).collect();
        if missing.is_empty() && a != b {
            pair_ids.push(if a < b { (a, b) } else { (b, a) });
        } else if plan.pairs.is_some() {
            let why = if a == b {
                format!("pair {a} x {b}: a body is not paired with itself; skipped")
            } else {
                format!("pair {a} x {b}: no 4D mesh of {}; not checked", missing[0])
            };
            tracing::warn!("{why}");
            problems.push(why);
        }
    }
    pair_ids.sort();
    pair_ids.dedup();
    pair_ids
}

/// Takes out of `pair_ids` the pairs whose bodies cannot be compared (in different frames,
/// or not on one lattice) and returns them as unchecked pairs, each a problem too: such a
/// pair costs only itself.
fn drop_incomparable(
    bodies: &BTreeMap<String, BodyMesh>,
    plan: &CheckPlan,
    pair_ids: &mut Vec<(String, String)>,
    problems: &mut Vec<String>,
) -> Vec<UncheckedPair> {
    let mut unchecked = Vec::new();
    pair_ids.retain(|(a, b)| {
        let frames = match (plan.frame_ids.get(a), plan.frame_ids.get(b)) {
            (Some(fa), Some(fb)) if fa != fb => Some(format!(
                "{a} is in frame {fa:?} and {b} in frame {fb:?}: bodies in different frames \
                 are not compared (publish them in one frame)"
            )),
            _ => None,
        };
        let why = frames.or_else(|| {
            CommonLattice::of(&[(a.as_str(), &bodies[a]), (b.as_str(), &bodies[b])])
                .err()
                .map(|e| e.to_string())
        });
        match why {
            Some(reason) => {
                let why = format!("pair {a} x {b}: not checked: {reason}");
                tracing::warn!("{why}");
                problems.push(why);
                unchecked.push(UncheckedPair {
                    a: a.clone(),
                    b: b.clone(),
                    reason,
                });
                false
            }
            None => true,
        }
    });
    unchecked
}

/// Pairs whose bodies are not all on one lattice, checked group by group, each group on its
/// own lattice ([`lattice_groups`]).
struct Groups<'a> {
    bodies: &'a BTreeMap<String, BodyMesh>,
    pair_ids: &'a [(String, String)],
    plan: &'a CheckPlan,
    opts: MesherOptions,
}

impl Groups<'_> {
    /// Checks each group as a plan of its own (with the preparations and walks of its
    /// bodies and pairs) and merges the outcomes: pairs sorted, the problems found before
    /// (`problems`, `unchecked`) first, once each. The outcome keeps the first group's
    /// lattice and bodies.
    fn check(
        &self,
        mut preps: BTreeMap<String, BodyPrep>,
        mut walks: BTreeMap<(String, String), StreamWalk>,
        problems: Vec<String>,
        mut unchecked: Vec<UncheckedPair>,
    ) -> Result<CheckOutcome, CheckError> {
        let plan = self.plan;
        let mut merged: Option<CheckOutcome> = None;
        for group in lattice_groups(self.bodies, self.pair_ids) {
            let sub = CheckPlan {
                pairs: Some(group.clone()),
                movable: plan
                    .movable
                    .iter()
                    .filter(|m| group.iter().any(|(a, b)| a == *m || b == *m))
                    .cloned()
                    .collect(),
                time_scale: plan.time_scale,
                frame_ids: BTreeMap::new(),
                rotation: plan.rotation,
            };
            let mut sub_preps = BTreeMap::new();
            let mut sub_walks = BTreeMap::new();
            for (a, b) in &group {
                for id in [a, b] {
                    if let Some(p) = preps.remove(id) {
                        sub_preps.insert(id.clone(), p);
                    }
                }
                if let Some(w) = walks.remove(&(a.clone(), b.clone())) {
                    sub_walks.insert((a.clone(), b.clone()), w);
                }
            }
            let o = check_streamed(self.bodies, sub_preps, sub_walks, &sub, self.opts)?;
            merged = Some(match merged {
                None => o,
                Some(mut m) => {
                    m.report.pairs.extend(o.report.pairs);
                    m.report.resolutions.extend(o.report.resolutions);
                    m.report.unchecked_pairs.extend(o.report.unchecked_pairs);
                    for p in o.report.problems {
                        if !m.report.problems.contains(&p) {
                            m.report.problems.push(p);
                        }
                    }
                    m.report.timings_ms.check += o.report.timings_ms.check;
                    m.report.timings_ms.resolve += o.report.timings_ms.resolve;
                    // One lattice per group: the outcome keeps the first group's.
                    m
                }
            });
        }
        let mut m = merged.expect("at least one group");
        m.report
            .pairs
            .sort_by(|x, y| (&x.a, &x.b).cmp(&(&y.a, &y.b)));
        for p in problems.into_iter().rev() {
            if !m.report.problems.contains(&p) {
                m.report.problems.insert(0, p);
            }
        }
        unchecked.extend(m.report.unchecked_pairs);
        unchecked.sort_by(|x, y| (&x.a, &x.b).cmp(&(&y.a, &y.b)));
        m.report.unchecked_pairs = unchecked;
        Ok(m)
    }
}

/// The report before any pair is checked: every body's figures, the problems and the pairs
/// not checked so far. Its time origin is the earliest first frame of any body.
fn report_of_bodies(
    bodies: &BTreeMap<String, BodyMesh>,
    plan: &CheckPlan,
    problems: Vec<String>,
    unchecked: Vec<UncheckedPair>,
) -> Report {
    let time_origin_ns = bodies
        .values()
        .filter_map(|b| b.stamps_ns.first().copied())
        .min()
        .unwrap_or(0);
    Report {
        schema: "chronotope.report/1",
        time_origin_ns,
        time_scale_m_per_s: plan.time_scale.unwrap_or(0.0),
        bodies: bodies
            .iter()
            .map(|(id, b)| BodyReport {
                id: id.clone(),
                frames: b.stats.frames,
                tets: b.mesh.tets.len() as u64,
                vertices: b.mesh.vertices.len() as u64,
                closed: b.stats.closed.is_closed(),
                hypervolume_m3s: b.stats.hypervolume_m3s,
                skipped_frames: b.skipped,
                vanishing_slabs: b.stats.vanishing_slabs,
                filled_frames: b.losses.filled_frames,
                lost_spans: LostSpan::of(&b.losses, time_origin_ns),
            })
            .collect(),
        pairs: Vec::new(),
        resolutions: Vec::new(),
        timings_ms: Timings::default(),
        problems,
        unchecked_pairs: unchecked,
    }
}

/// The bodies to check on one lattice, to be placed there and checked pair by pair.
struct CheckedPairs<'a> {
    /// The bodies by id, sorted.
    named: &'a [(&'a str, &'a BodyMesh)],
    /// Their ids, in the same order.
    ids: &'a [String],
    /// Their common lattice.
    lat: &'a CommonLattice,
    /// The report's time origin.
    time_origin_ns: i64,
    opts: MesherOptions,
}

impl CheckedPairs<'_> {
    /// Prepares the bodies (those prepared as they streamed, in `preps`, are placed), then
    /// checks each pair of `jobs` (indices into the bodies; walked as it streamed if `walks`
    /// holds it and both bodies lie on the lattice as they were prepared), measures the
    /// overlap of those that interfere and writes each pair's report (its verdict unsure
    /// over the spans where either body was not observed well enough). Bodies are prepared,
    /// and pairs checked, on all cores: they are independent. Gives the prepared bodies,
    /// and per job its report and result.
    fn check(
        &self,
        jobs: &[(usize, usize)],
        preps: &mut BTreeMap<String, BodyPrep>,
        walks: &mut BTreeMap<(String, String), StreamWalk>,
    ) -> Result<(Vec<Prepared>, Vec<PairReport>, Vec<PairResult>), CheckError> {
        let Self {
            named,
            ids,
            lat,
            time_origin_ns,
            opts,
        } = *self;
        let streamed: Vec<Option<BodyPrep>> =
            named.iter().map(|(id, _)| preps.remove(*id)).collect();
        let prepared: Vec<Prepared> = named
            .par_iter()
            .zip(streamed)
            .map(|(&(id, b), p)| match p {
                Some(p) => lat.place_prep(id, b, p),
                None => lat.prepare(id, b),
            })
            .collect::<Result<_, _>>()?;
        let as_is: Vec<bool> = named.iter().map(|(_, b)| lat.places_as_is(b)).collect();
        let walked: Vec<Option<StreamWalk>> = jobs
            .iter()
            .map(|&(i, j)| {
                let w = walks.remove(&(ids[i].clone(), ids[j].clone()));
                w.filter(|_| as_is[i] && as_is[j])
            })
            .collect();
        let checked: Vec<(PairResult, _)> = jobs
            .par_iter()
            .zip(walked)
            .map(|(&(i, j), w)| {
                let r = match w {
                    Some(w) => check_pair_walked(&prepared[i], &prepared[j], w),
                    None => check_pair(&prepared[i], &prepared[j]),
                };
                let hv = if r.interfering() {
                    overlap_hypervolume(named[i].1, named[j].1, opts)
                } else {
                    Some((0.0, 0.0))
                };
                (r, hv)
            })
            .collect();
        let mut pairs = Vec::with_capacity(jobs.len());
        let mut results = Vec::with_capacity(jobs.len());
        for (&(i, j), (r, hv)) in jobs.iter().zip(checked) {
            let (a, b) = (named[i].1, named[j].1);
            let pair = pair_report(&ids[i], &ids[j], &r, hv, lat, time_origin_ns);
            pairs.push(with_unsure_spans(
                pair,
                (&ids[i], a),
                (&ids[j], b),
                time_origin_ns,
            ));
            results.push(r);
        }
        Ok((prepared, pairs, results))
    }
}

/// `pair` with its verdict and unsure spans: where either body (`a`, `b`: id and mesh) was
/// not observed well enough, over the time both exist.
fn with_unsure_spans(
    mut pair: PairReport,
    (ia, a): (&String, &BodyMesh),
    (ib, b): (&String, &BodyMesh),
    time_origin_ns: i64,
) -> PairReport {
    let both_from = a.stamps_ns.first().max(b.stamps_ns.first()).copied();
    let both_to = a.stamps_ns.last().min(b.stamps_ns.last()).copied();
    if let (Some(from), Some(to)) = (both_from, both_to) {
        let (fast_a, fast_b) = fast_spans(a, b);
        let (spans, not_listed) = UnsureSpanReport::of_pair(
            &[
                (ia, &a.unsure),
                (ib, &b.unsure),
                (ia, &fast_a),
                (ib, &fast_b),
            ],
            from,
            to,
            time_origin_ns,
        );
        pair.verdict = Verdict::of(pair.interfering, !spans.is_empty() || not_listed > 0);
        pair.unsure_spans_s = spans;
        pair.unsure_spans_not_listed = not_listed;
    }
    pair
}

/// The resolutions of movable body `im` (an index into `prepared`) against the bodies it is
/// checked with (`checked`: pairs of indices and their results), if it interferes with any:
/// the whole checked time is the episode they clear.
fn resolve_movable(
    im: usize,
    prepared: &[Prepared],
    checked: &[(usize, usize, PairResult)],
    lat: &CommonLattice,
    c: f64,
    rotation: &RotationSpec,
    time_origin_ns: i64,
) -> Vec<Resolution> {
    let mut others = Vec::new();
    let mut rs = Vec::new();
    for (i, j, r) in checked {
        if *i == im {
            others.push(&prepared[*j]);
            rs.push(std::borrow::Cow::Borrowed(r));
        } else if *j == im {
            others.push(&prepared[*i]);
            rs.push(std::borrow::Cow::Owned(r.clone().swapped()));
        }
    }
    if !rs.iter().any(|r| r.interfering()) {
        return Vec::new();
    }
    let rs: Vec<&PairResult> = rs.iter().map(|r| r.as_ref()).collect();
    let episode = [
        lat.time_s(0.0, time_origin_ns),
        lat.time_s(
            ((lat.stamps_ns.len() - 1) as i64 * lat.per_step()) as f64,
            time_origin_ns,
        ),
    ];
    resolve(
        &prepared[im],
        &others,
        &rs,
        lat,
        c,
        rotation,
        time_origin_ns,
        episode,
    )
}

/// Translation, time scaling and rotation (about `rotation`'s axis) of body `a` against
/// `others`, each verified; `episode` is the contact episode they clear (s since `origin`).
#[allow(clippy::too_many_arguments)]
pub fn resolve(
    a: &Prepared,
    others: &[&Prepared],
    rs: &[&PairResult],
    lat: &CommonLattice,
    c: f64,
    rotation: &RotationSpec,
    origin: i64,
    episode: [f64; 2],
) -> Vec<Resolution> {
    let m = Metric::new(lat, c);
    let found = suggest(a, others, rs, &m, lat, rotation);
    resolutions(&a.id, &found, lat, &m, c, origin, episode)
}

/// What [`suggest`] found, in checker lattice units.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Suggestions {
    /// The translation in space and time.
    pub translation: Option<Translation>,
    /// The time scaling.
    pub time_scaling: Option<TimeScaling>,
    /// The rotation with time fixed.
    pub rotation: Option<Rotation>,
}

/// The translation, the time scaling and the rotation of body `a` against `others`, each
/// verified, in checker lattice units: they depend only on the prepared bodies, the metric
/// and the rotation asked for on `lat`.
pub fn suggest(
    a: &Prepared,
    others: &[&Prepared],
    rs: &[&PairResult],
    m: &Metric,
    lat: &CommonLattice,
    rotation: &RotationSpec,
) -> Suggestions {
    // The three searches are independent: all at once.
    let ((translation, time_scaling), rotation) = rayon::join(
        || {
            rayon::join(
                || suggest_translation(a, others, rs, m),
                || suggest_time_scaling(a, others, rs),
            )
        },
        || suggest_rotation(a, others, rs, lat, rotation),
    );
    Suggestions {
        translation,
        time_scaling,
        rotation,
    }
}

/// The report's resolutions of body `id` from what [`suggest`] found on `lat` with metric
/// `m` (time scale `c`); `episode` is the contact episode they clear (s since `origin`).
pub fn resolutions(
    id: &str,
    found: &Suggestions,
    lat: &CommonLattice,
    m: &Metric,
    c: f64,
    origin: i64,
    episode: [f64; 2],
) -> Vec<Resolution> {
    let mut out = Vec::new();
    if let Some(t) = &found.translation {
        let v = [0, 1, 2, 3].map(|k| {
            if k < 3 {
                t.lattice[k] as f64 * m.sigma[k]
            } else {
                t.lattice[k] as f64 * m.sigma[3] / c
            }
        });
        let snap = m.sigma.iter().map(|s| s * s).sum::<f64>().sqrt();
        let period = m.sigma[3] * lat.per_step() as f64 / c;
        out.push(Resolution::Translate {
            body: id.to_string(),
            vector: v,
            distance: t.distance_m,
            verified_clear: t.verified_clear,
            direction: t.direction,
            distance_error_bound_m: bounds::translation_bound(lat.resolution, period, c, snap),
            episode_s: episode,
            unsure_s: Vec::new(),
        });
    } else {
        tracing::warn!(body = %id, "no translation found (no interior point of the body lies inside another)");
    }
    if let Some(ts) = &found.time_scaling {
        out.push(Resolution::TimeScale {
            body: id.to_string(),
            t0_s: lat.time_s(ts.t0 as f64, origin),
            scale: ts.scale,
            verified_clear: ts.verified_clear,
            episode_s: episode,
            unsure_s: Vec::new(),
        });
    }
    if let Some(r) = &found.rotation {
        let per_step = lat.per_step() as f64;
        if let Some(why) = &r.reason {
            tracing::debug!(body = %id, "no rotation found that clears: {why}");
        }
        out.push(Resolution::Rotate {
            body: id.to_string(),
            axis: r.axis.unit(),
            point_m: [0, 1, 2]
                .map(|k| lat.voxel0_centre[k] + f64::from(r.point[k]) / per_step * lat.resolution),
            angle_rad: r.angle_rad,
            verified_clear: r.verified_clear,
            episode_s: episode,
            axis_deviation_rad: r.axis.deviation_rad,
            failing_angle_rad: r.failing_rad,
            lattice_refinement: r.n,
            reason: r.reason.clone(),
            unsure_s: Vec::new(),
        });
    }
    out
}

/// The bodies of `pairs`, each once, in order of first appearance.
fn pair_bodies<'a>(
    bodies: &'a BTreeMap<String, BodyMesh>,
    pairs: &'a [(String, String)],
) -> Vec<(&'a str, &'a BodyMesh)> {
    let mut named: Vec<(&str, &BodyMesh)> = Vec::new();
    for id in pairs.iter().flat_map(|(a, b)| [a, b]) {
        if !named.iter().any(|(n, _)| *n == id.as_str()) {
            named.push((id.as_str(), &bodies[id]));
        }
    }
    named
}

/// The checkable pairs split into groups whose bodies share one lattice: connected groups
/// of pairs, each group's bodies checked for one common lattice; a group that has none is
/// split into its single pairs (each checkable on its own).
fn lattice_groups(
    bodies: &BTreeMap<String, BodyMesh>,
    pairs: &[(String, String)],
) -> Vec<Vec<(String, String)>> {
    // Connected components of the pair graph.
    let mut comp: BTreeMap<String, usize> = BTreeMap::new();
    let mut groups: Vec<Vec<(String, String)>> = Vec::new();
    for (a, b) in pairs {
        let (ca, cb) = (comp.get(a).copied(), comp.get(b).copied());
        let g = match (ca, cb) {
            (Some(x), Some(y)) if x != y => {
                let moved = std::mem::take(&mut groups[y]);
                for (p, q) in &moved {
                    comp.insert(p.clone(), x);
                    comp.insert(q.clone(), x);
                }
                groups[x].extend(moved);
                x
            }
            (Some(x), _) | (None, Some(x)) => x,
            (None, None) => {
                groups.push(Vec::new());
                groups.len() - 1
            }
        };
        comp.insert(a.clone(), g);
        comp.insert(b.clone(), g);
        groups[g].push((a.clone(), b.clone()));
    }
    let mut out = Vec::new();
    for g in groups.into_iter().filter(|g| !g.is_empty()) {
        if g.len() == 1 || CommonLattice::of(&pair_bodies(bodies, &g)).is_ok() {
            out.push(g);
        } else {
            out.extend(g.into_iter().map(|p| vec![p]));
        }
    }
    out
}

/// Overlap hypervolume (m³·s) from the intersection of the two bodies' frames, meshed
/// like a body, with its error bound (see `checker::bounds`).
pub fn overlap_hypervolume(a: &BodyMesh, b: &BodyMesh, opts: MesherOptions) -> Option<(f64, f64)> {
    let (ga, gb) = (a.geometry?, b.geometry?);
    let mut asm = BodyAssembler::new(opts).ok()?;
    let mut geometry = None;
    let mut j = 0;
    for (i, &s) in a.stamps_ns.iter().enumerate() {
        while j < b.stamps_ns.len() && b.stamps_ns[j] < s {
            j += 1;
        }
        if j < b.stamps_ns.len() && b.stamps_ns[j] == s {
            let (both, g) = chronotope_mesh::grid::intersect_across(
                a.frames.get(i)?,
                &ga,
                b.frames.get(j)?,
                &gb,
            )?;
            geometry = Some(g);
            asm.push_derived(s, g, both).ok()?;
        }
    }
    let body = asm.finish();
    let n = body.stamps_ns.len();
    let period = if n >= 2 {
        (body.stamps_ns[n - 1] - body.stamps_ns[0]) as f64 * 1e-9 / (n - 1) as f64
    } else {
        0.0
    };
    let bound = bounds::hypervolume_bound(&body.mesh, &geometry.unwrap_or(ga), period);
    Some((body.stats.hypervolume_m3s, bound))
}

fn pair_report(
    a: &str,
    b: &str,
    r: &PairResult,
    hv: Option<(f64, f64)>,
    lat: &CommonLattice,
    origin: i64,
) -> PairReport {
    let (ca, cb) = r.counts();
    let first = r.first_contact();
    let bound = |t: f64, speed: Option<f64>| bounds::contact_time_bound(lat.period_s(t), speed);
    PairReport {
        a: a.to_owned(),
        b: b.to_owned(),
        verdict: Verdict::of(r.interfering(), false),
        unsure_spans_s: Vec::new(),
        unsure_spans_not_listed: 0,
        interfering: r.interfering(),
        intervals_s: r
            .intervals
            .iter()
            .map(|&(s, e)| [lat.time_s(s, origin), lat.time_s(e, origin)])
            .collect(),
        first_contact_s: first.map(|t| lat.time_s(t, origin)),
        overlap_hypervolume_m3s: hv.map(|h| h.0),
        labels: PairLabels { a: ca, b: cb },
        frame_period_s: first.map(|t| lat.period_s(t)),
        voxel_size_m: lat.resolution,
        first_contact_error_bound_s: first
            .and_then(|t| bound(t, r.interval_speeds.first().and_then(|s| s.0))),
        closing_speed_mps: first.and_then(|t| {
            r.interval_speeds
                .first()
                .and_then(|s| s.0)
                .map(|v| v * lat.resolution / lat.period_s(t))
        }),
        interval_error_bounds_s: r
            .intervals
            .iter()
            .zip(&r.interval_speeds)
            .map(|(&(s, e), &(vs, ve))| [bound(s, vs), bound(e, ve)])
            .collect(),
        overlap_hypervolume_error_bound_m3s: hv.map(|h| h.1),
        candidate_pairs: r.candidate_pairs,
        crossing_pairs: r.interfering_pairs,
    }
}

/// Where a body of the pair moves fast in a slab near the other body (as the
/// rolling checker decides it, [`chronotope_mesh::unsure::moves_fast_near`]): each body's spans
/// ([`chronotope_mesh::unsure::Unsure::MovesFast`]).
fn fast_spans(a: &BodyMesh, b: &BodyMesh) -> (UnsureLog, UnsureLog) {
    use chronotope_mesh::unsure::{moves_fast_near, Unsure, UnsureSpan};
    let mut logs = (UnsureLog::default(), UnsureLog::default());
    let (Some(ga), Some(gb)) = (a.geometry, b.geometry) else {
        return logs;
    };
    for ma in &a.motions {
        let Ok(kb) = b
            .motions
            .binary_search_by_key(&ma.stamps_ns.0, |m| m.stamps_ns.0)
        else {
            continue;
        };
        let mb = &b.motions[kb];
        if mb.stamps_ns.1 != ma.stamps_ns.1 {
            continue;
        }
        let (da, db) = moves_fast_near(
            (&ga, ma.bounds, ma.displacement),
            (&gb, mb.bounds, mb.displacement),
        );
        let (lo, hi) = ma.stamps_ns;
        // A slab with a doubt of its own is listed with that one, the stronger.
        for (log, d, own) in [(&mut logs.0, da, ma.unsure), (&mut logs.1, db, mb.unsure)] {
            if d > 0 && own.is_none() {
                log.push(UnsureSpan {
                    from_ns: lo,
                    to_ns: hi,
                    why: Unsure::MovesFast { voxels: d },
                    period_ns: hi - lo,
                });
            }
        }
    }
    logs
}
