//! The cumulative report of the rolling checker, from its bodies' and pairs' running answers.

use super::{
    add_run, bounds, closing_sums, BodyReport, BodyStream, Interval, LabelCounts, Overlap,
    PairLabels, PairReport, PairRoll, Report, RollingChecker, Run, SoFar, Timings, Totals,
    UnsureSpanReport, Verdict,
};

impl RollingChecker {
    /// The answer so far (the report of docs/formats.md#report): bodies, pairs, intervals,
    /// overlaps. The statistics of pieces still being added are waited for.
    pub fn report(&mut self) -> Report {
        self.settle_all_stats();
        self.assemble_report()
    }

    /// [`Self::report`] waiting for nothing: the statistics and overlaps that have finished
    /// on the pool are taken in, the pieces queued for it started there, and what is still
    /// being worked out is left out: each open run's hypervolume and vanishing slabs as of
    /// the pieces added so far (its frames and tets are counted as they are accepted), a
    /// run whose closing statistics are still out is reported open, and each pair's overlap
    /// is that of the periods before the one on the pool (what its contact events say). A
    /// later [`Self::report`] has everything. Live, for a report that has waited long while
    /// the node is behind its input: computing the statistics there would put the
    /// bookkeeping on the checker's thread, at the contacts' priority.
    pub fn report_as_it_stands(&mut self) -> Report {
        self.advance_statistics();
        for i in 0..self.pairs.len() {
            if self.pairs[i]
                .overlap_job
                .as_ref()
                .is_some_and(|j| j.finished())
            {
                self.settle_overlap(i);
            }
        }
        self.assemble_report()
    }

    /// The report from the bodies' and pairs' figures as they stand.
    fn assemble_report(&self) -> Report {
        let origin = self.origin_ns.unwrap_or(0);
        let mut problems = self.problems.clone();
        for p in &self.pairs {
            if p.undecided > 0 {
                problems.push(format!(
                    "pair {} x {}: {} region(s) or contact tet(s) stayed undecided (labelled OUTSIDE)",
                    p.a, p.b, p.undecided
                ));
            }
        }
        let bodies: Vec<BodyReport> = self
            .bodies
            .iter()
            .map(|(id, b)| body_report(id, b))
            .collect();
        let tets = |id: &str| bodies.iter().find(|b| b.id == id).map_or(0, |b| b.tets);
        // The first body's voxel edge, as the full check's common lattice takes it.
        let resolution = self
            .bodies
            .values()
            .find_map(|b| b.geometry.map(|g| g.resolution))
            .unwrap_or(0.0);
        let period = self.union.period_s();
        let c = self
            .plan
            .time_scale
            .or_else(|| period.map(|p| resolution / p))
            .unwrap_or(0.0);
        let pairs = self
            .pairs
            .iter()
            .filter(|p| p.checked)
            .map(|p| pair_report(p, tets(&p.a), tets(&p.b), resolution, origin))
            .collect();
        let unchecked_pairs = self
            .pairs
            .iter()
            .filter(|p| !p.checked)
            .filter_map(|p| {
                let why = p.stopped.as_ref()?;
                Some(crate::report::UncheckedPair {
                    a: p.a.clone(),
                    b: p.b.clone(),
                    reason: why.clone(),
                })
            })
            .collect();
        let mut report = Report {
            schema: "chronotope.report/1",
            time_origin_ns: origin,
            time_scale_m_per_s: c,
            bodies,
            pairs,
            resolutions: self.resolutions.iter().cloned().collect(),
            timings_ms: Timings::default(),
            problems,
            unchecked_pairs,
        };
        report.note_unsure_resolutions();
        report
    }
}

/// What a contact event says of its pair's answer so far, beside the contact itself (see
/// [`RollingChecker::contact_fields`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactFields {
    /// The report's time origin (ns).
    pub time_origin_ns: i64,
    /// The pair's first contact (s since the time origin), as the report gives it.
    pub first_contact_s: Option<f64>,
    /// The pair's overlap (m³·s; `None`: not measurable) before the latest period whose
    /// overlap was handed to the pool, i.e. before the event's own period; the report has
    /// that period too.
    pub overlap_hypervolume_m3s: Option<f64>,
}

impl RollingChecker {
    /// What a contact event of pair `a` × `b` says beside the contact, without waiting for
    /// anything being worked out on the pool: its first contact as the report gives it,
    /// and its overlap through the start of the latest period whose overlap was handed to
    /// the pool (that period's own is being measured as the event goes out; the report has
    /// it), or everything once the inputs have ended. The same whenever it is asked until
    /// the pair's next period is checked. `None` for a pair not checked (the report lists
    /// none).
    pub fn contact_fields(&self, a: &str, b: &str) -> Option<ContactFields> {
        let p = self
            .pairs
            .iter()
            .find(|p| p.checked && p.a == a && p.b == b)?;
        Some(ContactFields {
            time_origin_ns: self.origin_ns.unwrap_or(0),
            first_contact_s: first_contact(p),
            overlap_hypervolume_m3s: p.overlap_known.map(|o| o.0),
        })
    }

    /// Whether the statistics or an overlap of a piece are still being worked out by the
    /// bookkeeping (or queued for it), so that [`Self::report`] would wait for them (see
    /// [`Self::advance_statistics`]).
    pub fn statistics_pending(&self) -> bool {
        self.bodies.values().any(|b| {
            !b.stats_queue.is_empty() || b.stats_job.as_ref().is_some_and(|j| !j.job.finished())
        }) || self
            .pairs
            .iter()
            .any(|p| p.overlap_job.as_ref().is_some_and(|j| !j.finished()))
    }
}

/// A pair's first contact (s since the time origin).
fn first_contact(p: &PairRoll) -> Option<f64> {
    p.intervals
        .iter()
        .chain(p.open.iter())
        .next()
        .map(|o| o.s.0)
}

/// A pair's overlap so far and its bound: none for a pair that never interfered. While
/// a period's overlap is being measured on the pool, the overlap before it.
pub(super) fn pair_overlap(p: &PairRoll) -> Option<(f64, f64)> {
    pair_overlap_as(p, true)
}

/// [`pair_overlap`]; without `bound_here`, a bound that would need the closing cap's
/// normals worked out here is NaN (not known), the overlap itself as ever.
pub(super) fn pair_overlap_as(p: &PairRoll, bound_here: bool) -> Option<(f64, f64)> {
    if !p.interfering() {
        Some((0.0, 0.0))
    } else if p.overlap_job.is_some() {
        p.overlap_known
    } else {
        overlap_so_far_as(&p.overlap, bound_here)
    }
}

pub(super) fn body_report(id: &str, b: &BodyStream) -> BodyReport {
    let mut t = b.totals.clone();
    let mut tets = t.tets;
    for r in &b.runs {
        match &r.stats {
            Some(_) => {
                let mut one = Totals::default();
                add_run(
                    &mut one,
                    Run {
                        ..r.clone_summary()
                    },
                );
                t.closed = if t.runs == 0 {
                    one.closed
                } else {
                    t.closed && one.closed
                };
                t.runs += 1;
                t.frames += one.frames;
                tets += one.tets;
                t.vertices += one.vertices;
                t.hypervolume_m3s += one.hypervolume_m3s;
                t.vanishing += one.vanishing;
            }
            None => {
                // Its statistics so far, or what they said when the bookkeeping took them.
                let so_far = r.away.unwrap_or_else(|| SoFar::of(&r.acc));
                tets += r.tets;
                t.frames += r.frames();
                t.hypervolume_m3s += so_far.hypervolume_m3s;
                t.vanishing += so_far.vanishing_slabs;
                t.closed = false;
                t.runs += 1;
            }
        }
    }
    BodyReport {
        id: id.to_string(),
        frames: t.frames,
        tets,
        vertices: t.vertices,
        closed: t.closed && t.runs > 0,
        hypervolume_m3s: t.hypervolume_m3s,
        skipped_frames: 0,
        vanishing_slabs: t.vanishing,
        filled_frames: 0,
        lost_spans: Vec::new(),
    }
}

pub(super) fn pair_report(
    p: &PairRoll,
    tets_a: u64,
    tets_b: u64,
    resolution: f64,
    origin: i64,
) -> PairReport {
    let all: Vec<&Interval> = p.intervals.iter().chain(p.open.iter()).collect();
    let bound = |speed: Option<Option<f64>>, period: f64| {
        bounds::contact_time_bound(period, speed.flatten())
    };
    let first = all.first();
    let counts = |c: &LabelCounts, n: u64| LabelCounts {
        interference: c.interference,
        inside: c.inside,
        outside: n.saturating_sub(c.interference + c.inside),
    };
    let interfering = p.interfering();
    let overlap = pair_overlap(p);
    let (unsure_spans_s, unsure_spans_not_listed) = UnsureSpanReport::of_pair(
        &[(&p.a, &p.unsure.0), (&p.b, &p.unsure.1)],
        i64::MIN,
        i64::MAX,
        origin,
    );
    PairReport {
        a: p.a.clone(),
        b: p.b.clone(),
        verdict: Verdict::of(
            interfering,
            !unsure_spans_s.is_empty() || unsure_spans_not_listed > 0,
        ),
        unsure_spans_s,
        unsure_spans_not_listed,
        interfering,
        intervals_s: all.iter().map(|o| [o.s.0, o.s.1]).collect(),
        first_contact_s: first_contact(p),
        overlap_hypervolume_m3s: overlap.map(|o| o.0),
        labels: PairLabels {
            a: counts(&p.counts.0, tets_a),
            b: counts(&p.counts.1, tets_b),
        },
        frame_period_s: first.map(|o| o.periods.0),
        voxel_size_m: resolution,
        first_contact_error_bound_s: first.and_then(|o| bound(o.speeds.0, o.periods.0)),
        closing_speed_mps: first
            .and_then(|o| o.speeds.0.flatten().map(|v| v * resolution / o.periods.0)),
        interval_error_bounds_s: all
            .iter()
            .map(|o| {
                [
                    bound(o.speeds.0, o.periods.0),
                    bound(o.speeds.1, o.periods.1),
                ]
            })
            .collect(),
        overlap_hypervolume_error_bound_m3s: overlap.map(|o| o.1),
        candidate_pairs: p.candidates,
        crossing_pairs: p.crossings,
    }
}

/// The overlap hypervolume so far and its error bound (`None`: not measurable); without
/// `bound_here` as [`run_overlap_as`] gives it.
fn overlap_so_far_as(o: &Overlap, bound_here: bool) -> Option<(f64, f64)> {
    run_overlap_as(o, bound_here).map(|(hv, b)| (hv + o.closed.0, b + o.closed.1))
}

/// The overlap of the current run of consecutive periods, and its bound.
pub(super) fn run_overlap(o: &Overlap) -> Option<(f64, f64)> {
    run_overlap_as(o, true)
}

/// [`run_overlap`]; without `bound_here`, the bound is NaN where the closing cap's normals
/// were not worked out with the overlap.
fn run_overlap_as(o: &Overlap, bound_here: bool) -> Option<(f64, f64)> {
    if o.unknown {
        return None;
    }
    let Some(g) = o.geometry else {
        return Some((0.0, 0.0));
    };
    let (first, last, n) = o.stamps;
    let period = if n >= 2 {
        (last - first) as f64 * 1e-9 / (n - 1) as f64
    } else {
        0.0
    };
    // Worked out as the last frame was fed for a pair interfering by then, else here.
    let sums = if n >= 2 {
        match o.closed_sums {
            Some(s) => s,
            None if !bound_here => (f64::NAN, f64::NAN),
            None => closing_sums(o).unwrap_or(o.sums),
        }
    } else {
        o.sums
    };
    let hv = if n >= 2 {
        o.acc.so_far().hypervolume_m3s
    } else {
        0.0
    };
    let s = f64::from(g.scale);
    let (hx, ht) = (g.resolution / s, period / s);
    let (ns_phys, nt_phys) = (sums.0 * hx * hx * ht, sums.1 * hx * hx * hx);
    let b = (0.5 * g.resolution * ns_phys + 0.5 * period * nt_phys) / 6.0;
    Some((hv, b))
}
