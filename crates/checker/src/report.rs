//! The report of a check (docs/formats.md#report, schema `chronotope.report/1`): bodies,
//! pairs with their contact intervals, labels and overlaps, and verified resolutions. Built
//! by the rolling checker ([`rolling`](super::rolling)) and by the whole-bag check
//! ([`pipeline`](super::pipeline)); what a command read from its bag is reported beside it
//! by the command.

use super::labels::LabelCounts;
use chronotope_mesh::stream::{LossKind, LossLog, UNKNOWN_STAMP};
use chronotope_mesh::unsure::{UnsureLog, UnsureSpan};
use serde::Serialize;

/// One body in the report.
#[derive(Debug, Clone, Serialize)]
pub struct BodyReport {
    /// Topic.
    pub id: String,
    /// Frames accepted.
    pub frames: u64,
    /// Tets of the closed mesh.
    pub tets: u64,
    /// Vertices of the closed mesh.
    pub vertices: u64,
    /// Closed and consistently oriented.
    pub closed: bool,
    /// Hypervolume (m³·s).
    pub hypervolume_m3s: f64,
    /// Frames refused (extra field).
    pub skipped_frames: u64,
    /// Slabs in which the body vanishes between its frames: the frame rate is too low for
    /// its motion and contacts there can be missed (extra field).
    pub vanishing_slabs: u64,
    /// Frames filled in gaps between accepted frames (extra field; absent when none).
    #[serde(skip_serializing_if = "is_zero")]
    pub filled_frames: u64,
    /// Where the body's stream lost frames: refused, filled or spanned, in seconds since
    /// `time_origin_ns` (extra field; the latest spans, absent when none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lost_spans: Vec<LostSpan>,
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

/// A span of a body's stream where frames were refused or missing (extra field of a body).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LostSpan {
    /// `refused`, `filled` or `spanned`.
    pub kind: LossKind,
    /// Start and end (s since `time_origin_ns`); `null` for frames whose stamp is not known
    /// (they did not decode).
    pub span_s: Option<[f64; 2]>,
    /// Frames refused, filled or missing in it.
    pub frames: u64,
    /// Why (`lattice_changed`, `frames_missing`, ...).
    pub code: &'static str,
    /// The reason in words.
    pub reason: String,
}

impl LostSpan {
    /// The spans of `log`, in seconds since `origin_ns`.
    pub fn of(log: &LossLog, origin_ns: i64) -> Vec<Self> {
        log.spans
            .iter()
            .map(|s| Self {
                kind: s.kind,
                span_s: (s.from_ns != UNKNOWN_STAMP && s.to_ns != UNKNOWN_STAMP).then(|| {
                    [
                        (s.from_ns - origin_ns) as f64 * 1e-9,
                        (s.to_ns - origin_ns) as f64 * 1e-9,
                    ]
                }),
                frames: s.frames,
                code: s.code,
                reason: s.reason.clone(),
            })
            .collect()
    }
}

/// A pair that could not be checked, and why (extra field of the report).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UncheckedPair {
    /// First body (a < b).
    pub a: String,
    /// Second body.
    pub b: String,
    /// Why, in words.
    pub reason: String,
}

/// Label counts of both bodies of a pair.
#[derive(Debug, Clone, Serialize)]
pub struct PairLabels {
    /// First body.
    pub a: LabelCounts,
    /// Second body.
    pub b: LabelCounts,
}

/// What can be said of a pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The bodies interfere somewhere in space-time.
    Collide,
    /// No interference, and both bodies are observed well enough everywhere they were
    /// compared for that to hold.
    Clear,
    /// No interference was found, but in some spans a body is not observed well enough for
    /// the check to hold there (`unsure_spans_s`): a contact there can be missed.
    Unsure,
}

impl Verdict {
    /// The verdict of a pair that interferes or not, with or without unsure spans.
    pub fn of(interfering: bool, unsure: bool) -> Self {
        match (interfering, unsure) {
            (true, _) => Self::Collide,
            (false, true) => Self::Unsure,
            (false, false) => Self::Clear,
        }
    }

    /// The verdict as the console and messages print it.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Collide => "collide",
            Self::Clear => "clear",
            Self::Unsure => "unsure",
        }
    }
}

/// A span of a pair's time in which a body is not observed well enough for the check to
/// hold (see [`chronotope_mesh::unsure`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UnsureSpanReport {
    /// Start and end (s since `time_origin_ns`).
    pub span_s: [f64; 2],
    /// The body not observed well enough.
    pub body: String,
    /// `vanishes`, `frames_filled` or `gap_spanned`.
    pub code: &'static str,
    /// Why, in words.
    pub reason: &'static str,
    /// What would resolve it (a frame rate, the missing frames).
    pub resolve: String,
}

impl UnsureSpanReport {
    /// The span in one line, as messages carry it: `body: code: why; resolve: what`.
    pub fn line(&self) -> String {
        format!(
            "{}: {}: {}; resolve: {}",
            self.body, self.code, self.reason, self.resolve
        )
    }

    /// The report of `span` of `body`, in seconds since `origin_ns`.
    pub fn of(body: &str, span: &UnsureSpan, origin_ns: i64) -> Self {
        Self {
            span_s: [
                (span.from_ns - origin_ns) as f64 * 1e-9,
                (span.to_ns - origin_ns) as f64 * 1e-9,
            ],
            body: body.to_owned(),
            code: span.why.code(),
            reason: span.why.reason(),
            resolve: span.why.remedy(span.period_ns as f64 * 1e-9),
        }
    }

    /// The pair's unsure spans from its bodies' logs (each body's own, and the pair's
    /// spans of each) over `[from_ns, to_ns]` (the time both are checked), in time order,
    /// with how many more there were than listed.
    pub fn of_pair(
        logs: &[(&str, &UnsureLog)],
        from_ns: i64,
        to_ns: i64,
        origin_ns: i64,
    ) -> (Vec<Self>, u64) {
        let mut spans: Vec<(i64, Self)> = Vec::new();
        for (body, log) in logs {
            for s in log.within(from_ns, to_ns) {
                spans.push((s.from_ns, Self::of(body, &s, origin_ns)));
            }
        }
        spans.sort_by(|x, y| x.0.cmp(&y.0).then_with(|| x.1.body.cmp(&y.1.body)));
        let dropped = logs.iter().map(|(_, l)| l.dropped().0).sum();
        (spans.into_iter().map(|(_, s)| s).collect(), dropped)
    }
}

/// One pair in the report.
#[derive(Debug, Clone, Serialize)]
pub struct PairReport {
    /// First body.
    pub a: String,
    /// Second body.
    pub b: String,
    /// The interiors overlap somewhere in space-time.
    pub interfering: bool,
    /// Time intervals of overlap (s since `time_origin_ns`).
    pub intervals_s: Vec<[f64; 2]>,
    /// Earliest time of overlap, or null.
    pub first_contact_s: Option<f64>,
    /// 4D measure of the overlap (m³·s), or null when the bodies' frames are not on one grid.
    pub overlap_hypervolume_m3s: Option<f64>,
    /// Label counts.
    pub labels: PairLabels,
    /// `collide`, `clear` or `unsure` (extra field): `clear` only where both bodies are
    /// observed well enough for the check to hold.
    pub verdict: Verdict,
    /// Where a contact can be missed, and why (extra field; empty unless some span is
    /// unsure). A pair that collides lists them too.
    pub unsure_spans_s: Vec<UnsureSpanReport>,
    /// Unsure spans older than those listed (extra field; absent when none).
    #[serde(skip_serializing_if = "is_zero")]
    pub unsure_spans_not_listed: u64,
    /// The frame period at the first contact (s), the time resolution of the input (extra
    /// field).
    pub frame_period_s: Option<f64>,
    /// Voxel edge (m), the space resolution of the input (extra field).
    pub voxel_size_m: f64,
    /// Bound on the error of `first_contact_s` (s): Δt/2 + h/v at closing speed v; null
    /// for a grazing contact or one not made by crossing boundaries (extra field; docs/checker.md,
    /// "Error bounds").
    pub first_contact_error_bound_s: Option<f64>,
    /// The closing speed v of the two boundaries at the first contact (m/s, extra field).
    pub closing_speed_mps: Option<f64>,
    /// Bounds on the errors of each interval's start and end (s; null as above; extra
    /// field).
    pub interval_error_bounds_s: Vec<[Option<f64>; 2]>,
    /// Bound on the error of `overlap_hypervolume_m3s` (m³·s, extra field).
    pub overlap_hypervolume_error_bound_m3s: Option<f64>,
    /// Candidate tet pairs from the trees (extra field).
    pub candidate_pairs: u64,
    /// Tet pairs whose boundaries cross (extra field).
    pub crossing_pairs: u64,
}

impl PairReport {
    /// For a pair that is not clear for want of observation: the unsure spans in one line
    /// for the console (at most three, then how many more), e.g. `during 0.300-0.500 s:
    /// /a/occupancy: vanishes: …; resolve: …`.
    pub fn unsure_line(&self) -> String {
        let mut parts: Vec<String> = self
            .unsure_spans_s
            .iter()
            .take(3)
            .map(|u| format!("{:.3}-{:.3} s: {}", u.span_s[0], u.span_s[1], u.line()))
            .collect();
        let more =
            self.unsure_spans_s.len().saturating_sub(3) as u64 + self.unsure_spans_not_listed;
        if more > 0 {
            parts.push(format!("and {more} more span(s)"));
        }
        parts.join("; ")
    }
}

/// Timings (ms).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Timings {
    /// Reading and meshing.
    pub mesh: f64,
    /// Detection and labels (trees, exact tests, inclusion).
    pub check: f64,
    /// Resolution suggestions.
    pub resolve: f64,
    /// Everything.
    pub total: f64,
}

/// The report (docs/formats.md#report).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// `chronotope.report/1`.
    pub schema: &'static str,
    /// Earliest frame stamp in the bag (ns); report times are seconds since it.
    pub time_origin_ns: i64,
    /// c (m/s) of the 4D metric.
    pub time_scale_m_per_s: f64,
    /// Bodies, sorted by id.
    pub bodies: Vec<BodyReport>,
    /// Every pair (a < b).
    pub pairs: Vec<PairReport>,
    /// Resolve suggestions for the movable bodies.
    pub resolutions: Vec<Resolution>,
    /// Timings.
    pub timings_ms: Timings,
    /// What went wrong with the input and was skipped (extra field; empty when nothing did).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub problems: Vec<String>,
    /// Pairs that were asked for but could not be checked, and why (extra field; absent when
    /// none). Their bodies' other pairs are checked as usual.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub unchecked_pairs: Vec<UncheckedPair>,
}

/// A resolve suggestion (one entry of the report's `resolutions`).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Resolution {
    /// Move the body in space and time.
    Translate {
        /// The body.
        body: String,
        /// (dx, dy, dz) in metres and dt in seconds.
        vector: [f64; 4],
        /// sqrt(dx² + dy² + dz² + (c·dt)²) (m).
        distance: f64,
        /// Checked again against every other body: clear.
        verified_clear: bool,
        /// How the direction was found (extra field).
        direction: &'static str,
        /// Bound on the distance's excess over the shortest clearing shift (m, extra field).
        distance_error_bound_m: f64,
        /// The contact episode it clears: start and end (s since the time origin; extra
        /// field).
        episode_s: [f64; 2],
        /// Where the check that verified it cannot hold (a body unsure there): it is verified
        /// clear everywhere else (extra field; absent when none).
        #[serde(skip_serializing_if = "Vec::is_empty")]
        unsure_s: Vec<[f64; 2]>,
    },
    /// Retime the body: t -> t0 + scale·(t − t0).
    TimeScale {
        /// The body.
        body: String,
        /// Fixed time (s since the time origin).
        t0_s: f64,
        /// Factor on durations after t0.
        scale: f64,
        /// Checked again against every other body: clear.
        verified_clear: bool,
        /// The contact episode it clears (s since the time origin; extra field).
        episode_s: [f64; 2],
        /// Where the check that verified it cannot hold (extra field; absent when none).
        #[serde(skip_serializing_if = "Vec::is_empty")]
        unsure_s: Vec<[f64; 2]>,
    },
    /// Turn the body about an axis by the same angle at every instant (time fixed).
    Rotate {
        /// The body.
        body: String,
        /// Unit direction of the axis used (an integer direction near the one asked for).
        axis: [f64; 3],
        /// A point on the axis (m).
        point_m: [f64; 3],
        /// The angle, right-handed about `axis` (rad).
        angle_rad: f64,
        /// Checked again against every other body: clear.
        verified_clear: bool,
        /// The contact episode it clears (s since the time origin; extra field).
        episode_s: [f64; 2],
        /// Angle between `axis` and the axis asked for (rad, extra field).
        axis_deviation_rad: f64,
        /// The largest angle of the same sense tried that does not clear (rad, extra
        /// field): the search's answer lies between the two; null if none was tried below.
        failing_angle_rad: Option<f64>,
        /// n of the exact rotation matrix M/n: the lattice it was verified on is n times
        /// finer (extra field).
        lattice_refinement: i64,
        /// Why no angle was found that clears (extra field; absent when one was).
        #[serde(skip_serializing_if = "Option::is_none")]
        reason: Option<String>,
        /// Where the check that verified it cannot hold (a body unsure there): it is verified
        /// only where both bodies are observed (extra field; empty: everywhere).
        unsure_s: Vec<[f64; 2]>,
    },
}

impl Resolution {
    /// The time the moved body and the bodies it was checked against take part in, from the
    /// episode and the move (a shift in time moves the episode; a scaling stretches it).
    fn verified_window(&self) -> (&str, [f64; 2]) {
        match self {
            Self::Translate {
                body,
                vector,
                episode_s,
                ..
            } => {
                let [a, b] = *episode_s;
                (body, [a.min(a + vector[3]), b.max(b + vector[3])])
            }
            Self::TimeScale {
                body,
                t0_s,
                scale,
                episode_s,
                ..
            } => {
                let [a, b] = *episode_s;
                let map = |t: f64| t0_s + scale * (t - t0_s);
                let (x, y) = (map(a), map(b));
                (body, [a.min(x).min(y), b.max(x).max(y)])
            }
            // Turned with time fixed: the episode's own time.
            Self::Rotate {
                body, episode_s, ..
            } => (body, *episode_s),
        }
    }

    fn unsure_mut(&mut self) -> &mut Vec<[f64; 2]> {
        match self {
            Self::Translate { unsure_s, .. }
            | Self::TimeScale { unsure_s, .. }
            | Self::Rotate { unsure_s, .. } => unsure_s,
        }
    }

    /// Where the check that verified it cannot hold (empty: nowhere).
    pub fn unsure_s(&self) -> &[[f64; 2]] {
        match self {
            Self::Translate { unsure_s, .. }
            | Self::TimeScale { unsure_s, .. }
            | Self::Rotate { unsure_s, .. } => unsure_s,
        }
    }
}

impl Report {
    /// Marks each resolution with the unsure spans (of the pairs of its body) that fall in the
    /// time its verification covers: it is verified clear where the bodies are observed, and
    /// says where it could not be.
    pub fn note_unsure_resolutions(&mut self) {
        for r in &mut self.resolutions {
            let (body, [w0, w1]) = r.verified_window();
            let mut spans: Vec<[f64; 2]> = self
                .pairs
                .iter()
                .filter(|p| p.a == body || p.b == body)
                .flat_map(|p| p.unsure_spans_s.iter())
                .filter(|u| u.span_s[1] >= w0 && u.span_s[0] <= w1)
                .map(|u| [u.span_s[0].max(w0), u.span_s[1].min(w1)])
                .collect();
            spans.sort_by(|x, y| x[0].total_cmp(&y[0]));
            let mut merged: Vec<[f64; 2]> = Vec::new();
            for s in spans {
                match merged.last_mut() {
                    Some(m) if s[0] <= m[1] => m[1] = m[1].max(s[1]),
                    _ => merged.push(s),
                }
            }
            *r.unsure_mut() = merged;
        }
    }
}
