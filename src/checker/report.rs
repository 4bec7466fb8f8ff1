//! The report of a check (CONTRACT.md, schema `chronotope.report/1`): bodies, pairs with
//! their contact intervals, labels and overlaps, and verified resolutions. Built by the
//! rolling checker ([`rolling`](super::rolling)) and by the whole-bag check
//! ([`pipeline`](super::pipeline)); what a command read from its bag is reported beside it
//! by the command.

use super::labels::LabelCounts;
use crate::mesh::stream::{LossKind, LossLog, UNKNOWN_STAMP};
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

/// The report (CONTRACT.md).
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
    },
}
