//! The rolling checker: the planned pairs of bodies checked frame period by frame period as
//! their mesh pieces arrive, with memory bounded by a window instead of the history.
//!
//! Each body's stream comes as the mesher's pieces (first cap, one lateral slab per frame
//! period, last cap) and, for the overlap measure and the windows' artificial caps, its
//! decoded frames. For each pair, the frame period starting at stamp `s` is checked as soon
//! as both bodies' slabs for it are in: see the `period` module for why one slab closed by
//! two caps gives exactly the labels and crossings of the full check. What follows each
//! slab (the next slab, or the last cap) may not be known yet; the period's contacts are
//! said at once all the same, and its labels, with what a last cap there adds, once it is
//! (`PendingPeriod`). What a period gives (labels of its
//! tets, ranges of overlap, crossing pairs) is folded into the pair's running answer:
//! label counts, intervals (merged exactly as the full check merges them), closing speeds
//! at each interval's ends (from the crossings within one frame period of the end), and
//! the overlap hypervolume (the intersection of the two bodies' frames, meshed by its own
//! rolling mesher). Then the period's pieces and frames are dropped, unless a later window
//! or a resolution horizon still needs them.
//!
//! **Streams.** A period is decided once it is known what both bodies have there. A body
//! that has not started yet, or whose stream stopped, has nothing there: the other body's
//! slab is labelled OUTSIDE against it. A body that is merely behind is waited for, up to
//! [`RollingConfig::max_lead_frames`] slabs of the other; then the other's slab is decided
//! without it, and its late pieces for that time are refused by the pair (counted, with the
//! time span). Stamps that do not line up between two bodies (frames of one body falling
//! between the other's) stop that pair with a problem; every other pair goes on.
//!
//! **Memory.** Per body: the slabs not yet decided by every pair (at most
//! `max_lead_frames` ahead of the slowest partner), [`CONTEXT_SLABS`] behind them, the
//! slabs of the resolution horizon, and the decoded frames at their stamps. Per pair: the
//! crossings of the last two periods and the intervals found (the report's answer).

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::sync::Arc;

use rayon::prelude::*;

use super::bounds;
use super::labels::{Label, LabelCounts};

use super::period::{
    check_window, on_pair_lattice, prepare_window, Crossing, Partner, PreparedWindow, SpatialBox,
    TakenLabels, WindowBody, WindowResult,
};
use super::{check_pair, CommonLattice, PairResult};
use super::{origin_offset, CHECKER_FACTOR};
use crate::pipeline::CheckPlan;
use crate::report::{
    BodyReport, PairLabels, PairReport, Report, Resolution, Timings, UnsureSpanReport, Verdict,
};
use chronotope_kernel::float::tet_normal as float_normal;
use chronotope_mesh::glue::BodyMesh;
use chronotope_mesh::march::{union_bounds, SpatialBounds, Welder};
use chronotope_mesh::stats::{BodyStats, LateralRef, StatsAccumulator};
use chronotope_mesh::unsure::{UnsureLog, UnsureSpan};
use chronotope_mesh::{CapSide, GridGeometry, Mesher, MesherOptions, OccupancyGrid, TetMesh};

mod bookkeeping;
use bookkeeping::PoolJob;
pub use bookkeeping::{shared_bookkeeping_pool, BookkeepingPool, BOOKKEEPING_NICE};
mod episodes;
pub use episodes::{lower_own_priority, RESOLVER_NICE};
mod periods;
mod report;
pub use report::ContactFields;

use episodes::ResolveOutcome;
use periods::{
    apart, approach, cached, check_near, pair_lattice, prepare_spec, Approach, WindowChecked,
    WindowSpec,
};

/// Slabs kept behind the oldest undecided one, for windows that reach one slab further
/// (another body's real cap in their time plane).
pub const CONTEXT_SLABS: usize = 1;

/// After this many frame periods the pair's time coordinates start again at the current
/// period (they must stay within the exact predicates' range).
const REBASE_FRAMES: i64 = 1 << 16;

/// Limits and switches of the rolling checker.
#[derive(Debug, Clone, PartialEq)]
pub struct RollingConfig {
    /// Slabs one body may run ahead of a pair partner that has nothing there yet before
    /// they are decided without it.
    pub max_lead_frames: usize,
    /// Report each slab's labels ([`RollingOutput::Labels`]).
    pub labels: bool,
    /// Report each slab when every pair has labelled it ([`RollingOutput::SlabDone`], for
    /// markers).
    pub slabs_done: bool,
    /// Most intervals kept per pair in the report (older ones are dropped and counted).
    pub max_intervals: usize,
    /// Time (s) on each side of a contact episode that its resolutions are checked over;
    /// contacts closer than twice this are one episode.
    pub horizon_s: f64,
    /// A contact episode longer than this (s) is resolved over its first this many
    /// seconds, and what follows is a new episode.
    pub max_episode_s: f64,
    /// Most resolutions kept in the report (older ones are dropped and counted).
    pub max_resolutions: usize,
    /// Most tets of lateral slabs kept for resolutions alone (all bodies together): older
    /// slabs are dropped first, and an episode is then resolved over the horizon that is
    /// left (said as a problem, `resolution_horizon_cut`).
    pub max_horizon_tets: usize,
    /// Most bytes of decoded frames kept per body (for overlaps and resolution caps).
    pub max_frame_bytes: u64,
    /// Most resolutions running on the resolver's pool at once, while the checker goes on;
    /// when one more is handed over, the oldest is waited for. 0: each runs in turn on the
    /// checker's own thread. Results are taken oldest first, so the answers and their order
    /// never depend on it; only when they are published does.
    pub resolve_in_flight: usize,
    /// How many periods back a pair's new window is compared with the windows it checked,
    /// to take a result moved instead of checking again (see [`KeptWindow`]); 0 checks
    /// every window. The windows hold their slabs: at most this many per body and pair, most
    /// often still held for the statistics or as context.
    pub kept_windows: usize,
    /// Reports are read on the way ([`RollingChecker::report`] asked for while the streams
    /// go on): an interfering pair's overlap bound, which needs the overlap closed by a cap
    /// at its latest frame, is then worked out frame by frame on the bookkeeping, beside
    /// the overlap. Off, it is worked out when a report is asked for (the last one), and a
    /// contact event's overlap comes without it.
    pub reports: bool,
}

impl Default for RollingConfig {
    fn default() -> Self {
        Self {
            max_lead_frames: 64,
            labels: true,
            slabs_done: false,
            max_intervals: 4096,
            horizon_s: 1.0,
            max_episode_s: 4.0,
            max_resolutions: 1024,
            max_horizon_tets: 1_500_000,
            max_frame_bytes: DEFAULT_MAX_FRAME_BYTES,
            resolve_in_flight: 1,
            kept_windows: 4,
            reports: true,
        }
    }
}

/// Which piece of a body's mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PieceKind {
    /// Closes the body at its first frame.
    CapStart,
    /// Tets between frames `index` and `index + 1`.
    Lateral,
    /// Closes the body at its last frame.
    CapEnd,
}

/// One mesh piece of a body, as the mesher sent it.
#[derive(Debug, Clone)]
pub struct Piece {
    /// Body id.
    pub body: String,
    /// Which piece.
    pub kind: PieceKind,
    /// Frame index (a slab: its earlier frame).
    pub index: u32,
    /// Stamps of its frames (a cap: twice its frame's).
    pub stamps_ns: (i64, i64),
    /// The body's lattice.
    pub geometry: GridGeometry,
    /// Occupied voxels of the later frame (a cap: of its frame).
    pub occupied: u64,
    /// Why the slab does not show every contact, if it does not (a part of the body vanishes
    /// between its frames, or they were filled into a gap).
    pub unsure: Option<chronotope_mesh::unsure::Unsure>,
    /// How far the body moves between the slab's frames (voxels; 0 for a cap; see
    /// [`chronotope_mesh::Slab::displacement`]).
    pub displacement: u16,
    /// The tets, in the body's lattice.
    pub mesh: Arc<TetMesh>,
    /// The body's `header.frame_id`: bodies in different frames are not compared.
    pub frame_id: String,
}

/// A slab's labels against one other body.
#[derive(Debug, Clone)]
pub struct SlabLabels {
    /// The labelled body.
    pub body: String,
    /// The body they are labelled against.
    pub other: String,
    /// The slab's frame index in the body's stream.
    pub index: u32,
    /// Stamps of the slab's frames.
    pub stamps_ns: (i64, i64),
    /// The labels start with the body's first cap.
    pub with_cap_start: bool,
    /// The labels end with the body's last cap.
    pub with_cap_end: bool,
    /// One label per tet (first cap, slab, last cap), [`Label`] as `u8`.
    pub labels: Vec<u8>,
    /// Counts of `labels`.
    pub counts: LabelCounts,
}

/// A slab that every pair of its body has labelled: its tets with the strongest label of
/// each over the pairs.
#[derive(Debug, Clone)]
pub struct SlabDone {
    /// The body.
    pub body: String,
    /// Frame index of the slab's earlier frame.
    pub index: u32,
    /// Stamps of its frames.
    pub stamps_ns: (i64, i64),
    /// The body's lattice.
    pub geometry: GridGeometry,
    /// The slab's tets (body lattice).
    pub mesh: Arc<TetMesh>,
    /// Strongest label of each tet over the pairs ([`Label`] as `u8`).
    pub worst: Vec<u8>,
}

/// What happened to a contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactPhase {
    /// A new contact: its interval so far.
    Begin,
    /// It went on through another frame period.
    Ongoing,
    /// It ended: its interval is final.
    End,
}

/// A span of a pair in which a body is not observed well enough for the check to hold (see
/// [`chronotope_mesh::unsure`]), as it begins and when it ends.
#[derive(Debug, Clone, PartialEq)]
pub struct UnsureUpdate {
    /// First body (ids in sorted order).
    pub a: String,
    /// Second body.
    pub b: String,
    /// True when the span ends (its end is final), false when it begins.
    pub ended: bool,
    /// The span's place among the pair's unsure spans (0, 1, ...).
    pub index: u64,
    /// The span: its body, times (s since the time origin), why and what would resolve it.
    pub span: crate::report::UnsureSpanReport,
    /// Stamp of the later frame of the period that began or ended it (ns).
    pub stamp_ns: i64,
}

/// A contact of a pair, as it is found.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactUpdate {
    /// First body (ids in sorted order).
    pub a: String,
    /// Second body.
    pub b: String,
    /// Begin, ongoing or end.
    pub phase: ContactPhase,
    /// The contact's place among the pair's contacts (0, 1, ...).
    pub index: u64,
    /// Interval start (s since the time origin).
    pub start_s: f64,
    /// Interval end so far (s).
    pub end_s: f64,
    /// Bound on the start's error (s), once the crossings after the start are in.
    pub start_bound_s: Option<f64>,
    /// Bound on the end's error (s), at the end.
    pub end_bound_s: Option<f64>,
    /// Stamp of the later frame of the period that found or extended it (ns).
    pub stamp_ns: i64,
}

/// What the rolling checker gives as the streams go on.
#[derive(Debug, Clone)]
pub enum RollingOutput {
    /// A slab's labels against one other body.
    Labels(SlabLabels),
    /// A slab labelled by every pair.
    SlabDone(SlabDone),
    /// A contact began, went on or ended.
    Contact(ContactUpdate),
    /// A span in which a pair cannot be called clear began or ended.
    Unsure(UnsureUpdate),
    /// A contact episode of a movable body was resolved (the report's resolutions grew).
    Resolved,
    /// Something in the input was wrong or lost (kind, text).
    Problem(&'static str, String),
}

#[derive(Debug)]
struct HeldSlab {
    /// The run (stream of the body) it belongs to ([`Run::id`]).
    run: u64,
    /// Its index in the run (0: the run's first slab).
    index: u32,
    /// Stamp of its upper frame (its lower one is its key in [`BodyStream::slabs`]).
    hi: i64,
    /// Its lateral tets, shared with the windows that hold it.
    mesh: Arc<TetMesh>,
    /// Its vertices' box (see [`TetMesh::spatial_bounds`]).
    bounds: Option<SpatialBounds>,
    /// Number of the slab's first tet in the body's run (first cap, slabs, last cap).
    first_tet: u64,
    /// Strongest label per tet over the pairs so far (if slabs are reported).
    worst: Vec<u8>,
    /// Why the slab does not show every contact, if it does not.
    unsure: Option<chronotope_mesh::unsure::Unsure>,
    /// How far the body moves in the slab (voxels).
    displacement: u16,
}

#[derive(Debug)]
struct Run {
    /// Its number in the body ([`BodyStream::next_run`] when it began).
    id: u64,
    /// The lattice of its frames (one per run: another lattice begins another run).
    geometry: GridGeometry,
    /// Stamp of its first frame.
    first_stamp: i64,
    /// The cap closing it below, at its first frame (empty if it began mid-stream, and once
    /// its first slab is no longer kept: see [`RollingChecker::release_opening_caps`]).
    first_cap: Arc<TetMesh>,
    /// Tets of that cap.
    first_cap_tets: u64,
    /// Occupied voxels of its first frame (the first cap's interior vertices).
    first_occupied: u64,
    /// Stamp of the latest frame (the last slab's upper one).
    frontier: i64,
    /// Index of the run's first frame: 0, or the first piece after lost ones (the run then
    /// has no opening cap).
    first_index: u32,
    /// Index of its latest frame (the upper frame of its latest slab).
    next_index: u32,
    /// The closing cap came (stamp, cap), or the run was closed without one.
    end: Option<RunEnd>,
    /// Tets of its caps and slabs so far (the next slab's first tet number).
    tets: u64,
    /// Its mesh's statistics so far, slab by slab (empty while the bookkeeping adds a
    /// piece: [`BodyStream::stats_job`]; the pieces after it wait in
    /// [`BodyStream::stats_queue`]).
    acc: StatsAccumulator,
    /// What [`Self::acc`] said when the bookkeeping took it out to add a piece or to finish
    /// the run, until it is given back: what a report that waits for nothing says of the
    /// run ([`RollingChecker::report_as_it_stands`]).
    away: Option<SoFar>,
    /// The run's statistics, once it ended.
    stats: Option<BodyStats>,
}

/// A run's figures from its statistics so far that a report reads while the run is open:
/// hypervolume (m³·s) and vanishing slabs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct SoFar {
    hypervolume_m3s: f64,
    vanishing_slabs: u64,
}

impl SoFar {
    fn of(acc: &StatsAccumulator) -> Self {
        let s = acc.so_far();
        Self {
            hypervolume_m3s: s.hypervolume_m3s,
            vanishing_slabs: s.vanishing_slabs,
        }
    }
}

impl Run {
    /// Run `id` beginning at piece `p` (its first frame, at index `first_index`), closed
    /// below by `first_cap` (empty for a run that begins mid-stream) over `first_occupied`
    /// voxels.
    fn begun(
        id: u64,
        p: &Piece,
        first_cap: Arc<TetMesh>,
        first_occupied: u64,
        first_index: u32,
    ) -> Self {
        // An opening cap's tets are the run's first; a slab's are counted as it is held.
        let tets = if p.kind == PieceKind::CapStart {
            p.mesh.tets.len() as u64
        } else {
            0
        };
        Run {
            id,
            geometry: p.geometry,
            first_stamp: p.stamps_ns.0,
            first_cap_tets: first_cap.tets.len() as u64,
            first_cap,
            first_occupied,
            frontier: p.stamps_ns.0,
            first_index,
            next_index: first_index,
            end: None,
            tets,
            acc: StatsAccumulator::new(),
            away: None,
            stats: None,
        }
    }

    /// The run's figures without its meshes (for the report).
    fn clone_summary(&self) -> Run {
        Run {
            id: self.id,
            geometry: self.geometry,
            first_stamp: self.first_stamp,
            first_cap: self.first_cap.clone(),
            first_cap_tets: self.first_cap_tets,
            first_occupied: self.first_occupied,
            frontier: self.frontier,
            first_index: self.first_index,
            next_index: self.next_index,
            end: self.end.clone(),
            tets: self.tets,
            acc: StatsAccumulator::new(),
            away: self.away,
            stats: self.stats.clone(),
        }
    }

    /// Ends the run at its latest frame, with its closing cap if one came.
    fn close(&mut self, cap: Option<(Arc<TetMesh>, u64)>) {
        if let Some(closing) = self.end_at_frontier(cap) {
            self.stats = Some(closing.finish());
            self.away = None;
        }
    }

    /// Ends the run as [`Self::close`] does, leaving its statistics to be finished (by
    /// whoever sets [`Self::stats`]); `None` if it had ended.
    fn end_at_frontier(&mut self, cap: Option<(Arc<TetMesh>, u64)>) -> Option<Closing> {
        if self.end.is_some() {
            return None;
        }
        self.away = Some(SoFar::of(&self.acc));
        let closing = Closing {
            acc: std::mem::take(&mut self.acc),
            frames: self.frames(),
            first: (self.first_cap_tets, self.first_occupied),
            last: cap.clone(),
        };
        self.end = Some((self.frontier, cap));
        Some(closing)
    }

    fn ended(&self) -> bool {
        self.end.is_some()
    }
    /// Frames of the run so far.
    fn frames(&self) -> u64 {
        u64::from(self.next_index - self.first_index) + 1
    }
    fn last_cap_at(&self, stamp: i64) -> Option<&Arc<TetMesh>> {
        match &self.end {
            Some((s, Some((cap, _)))) if *s == stamp => Some(cap),
            _ => None,
        }
    }
}

/// An ended run's statistics, to be finished: its accumulator, frames, its first cap's tets
/// and the last cap, each with their occupied voxels.
#[derive(Debug)]
struct Closing {
    acc: StatsAccumulator,
    frames: u64,
    first: (u64, u64),
    last: Option<(Arc<TetMesh>, u64)>,
}

impl Closing {
    fn finish(self) -> BodyStats {
        let last = self.last.as_ref().map(|(c, o)| (c.as_ref(), *o));
        self.acc.finish(self.frames, Some(self.first), last)
    }
}

/// Cumulative figures of a body's finished runs.
#[derive(Debug, Default, Clone)]
struct Totals {
    /// Frames accepted.
    frames: u64,
    /// Tets of their meshes (caps and slabs).
    tets: u64,
    /// Vertices of their meshes.
    vertices: u64,
    /// Hypervolume of their 4D solids (m³·s).
    hypervolume_m3s: f64,
    /// Slabs in which part of the body vanishes within one frame period.
    vanishing: u64,
    /// Every finished run's mesh closed and consistently oriented.
    closed: bool,
    /// Runs finished.
    runs: u64,
}

/// How a run ended: the stamp of its last frame, and its last cap with its occupied voxels
/// (`None`: closed without one).
type RunEnd = (i64, Option<(Arc<TetMesh>, u64)>);

#[derive(Debug, Default)]
struct BodyStream {
    /// Its runs (streams), oldest first: the finished ones kept for the report's figures,
    /// the last one current.
    runs: Vec<Run>,
    /// Number of the next run to begin.
    next_run: u64,
    /// The slabs kept, by the stamp of their lower frame (the rolling window, and the
    /// slabs behind it that later windows and the horizon still reach).
    slabs: BTreeMap<i64, HeldSlab>,
    /// Its decoded frames kept, by stamp, for the pairs' overlap measure (as long as a
    /// slab starting or ending there is kept, within `max_frame_bytes`).
    frames: BTreeMap<i64, KeptGrid>,
    /// Figures of its finished runs.
    totals: Totals,
    /// The lattice of its latest stream.
    geometry: Option<GridGeometry>,
    /// Said that the checker joined this body's stream mid-way (said once; cleared when a
    /// stream of it begins at its first frame).
    joined_late: bool,
    /// Pairs it is in.
    pairs: usize,
    /// End stamp of the latest slab dropped for `max_horizon_tets` (0: none).
    horizon_cut_until: i64,
    /// `header.frame_id` of its latest piece.
    frame_id: String,
    /// Slabs since its latest one that was the one before moved one period later (0: the
    /// body is at rest; counted once its slabs come).
    moving_for: u32,
    /// The statistics of a piece being added by the bookkeeping (or an ended run's being
    /// finished), see [`RollingChecker::settle_stats`].
    stats_job: Option<StatsJob>,
    /// The pieces accepted after it, to be added in order (at most [`STATS_QUEUED`]).
    stats_queue: VecDeque<QueuedAdd>,
}

impl BodyStream {
    /// Puts back what a statistics job of run `run` gave.
    fn give_back_stats(&mut self, run: u64, done: StatsDone) {
        let r = self.runs.iter_mut().find(|r| r.id == run);
        match done {
            StatsDone::Finished(stats) => {
                if let Some(r) = r {
                    r.stats = Some(stats);
                    r.away = None;
                }
            }
            StatsDone::Added(acc, at_rest) => {
                self.moving_for = if at_rest {
                    0
                } else {
                    self.moving_for.saturating_add(1)
                };
                if let Some(r) = r {
                    r.acc = acc;
                    r.away = None;
                }
            }
        }
    }
}

/// Run `run`'s statistics so far, taken out to add a piece (`None`: no such run).
fn take_acc(b: &mut BodyStream, run: u64) -> Option<StatsAccumulator> {
    b.runs.iter_mut().find(|r| r.id == run).map(|r| {
        r.away = Some(SoFar::of(&r.acc));
        std::mem::take(&mut r.acc)
    })
}

/// The most pieces of a body left waiting for the statistics of the one before (each holds
/// its slab): with more, the checker brings the body's statistics up to date itself. The
/// bookkeeping runs at a lower priority, so a contact that keeps the cores busy for a few
/// frame periods leaves its pieces queued rather than waited for.
const STATS_QUEUED: usize = 4;

/// A lateral piece accepted, to be added to run `run`'s statistics.
#[derive(Debug)]
struct QueuedAdd {
    run: u64,
    /// The run's first cap, if the piece is its first slab.
    first_cap: Option<Arc<TetMesh>>,
    index: u64,
    stamps_ns: (i64, i64),
    geometry: GridGeometry,
    mesh: Arc<TetMesh>,
    unsure: Option<chronotope_mesh::unsure::Unsure>,
}

impl QueuedAdd {
    /// `acc` with the piece added.
    fn add_to(self, mut acc: StatsAccumulator) -> StatsDone {
        let lateral = LateralRef {
            index: self.index,
            stamps_ns: self.stamps_ns,
            geometry: &self.geometry,
            mesh: &self.mesh,
            unsure: self.unsure,
            displacement: 0,
        };
        let at_rest = acc.add_lateral_shared(lateral, self.first_cap.as_deref(), &self.mesh);
        StatsDone::Added(acc, at_rest)
    }
}

/// A piece's statistics being added on the pool (or an ended run's being finished), and
/// its run.
#[derive(Debug)]
struct StatsJob {
    run: u64,
    job: PoolJob<StatsDone>,
}

/// What a [`StatsJob`] gives back.
enum StatsDone {
    /// The run's accumulator with a lateral piece added, and whether the piece repeats the
    /// one before.
    Added(StatsAccumulator, bool),
    /// The ended run's statistics.
    Finished(BodyStats),
}

/// What [`RollingChecker::accept`] did with a piece.
#[derive(Debug)]
enum Accepted {
    /// Taken into its body's stream.
    Taken,
    /// Taken, with something to tell: its stream restarted, pieces before it are missing, or
    /// the node joined the stream mid-way (counted under `kind`).
    Noted { kind: &'static str, text: String },
    /// Refused and ignored: a bad piece, or one out of order (counted under `kind`).
    Refused { kind: &'static str, text: String },
}

impl Accepted {
    fn refused(kind: &'static str, text: String) -> Self {
        Accepted::Refused { kind, text }
    }
}

/// What the piece just accepted leaves to the statistics (see
/// [`RollingChecker::pending_stats`]).
#[derive(Debug)]
enum PendingStats {
    /// A lateral piece to add to run `run` (with the run's first cap if it is its first
    /// slab).
    Add(u64, Option<Arc<TetMesh>>),
    /// Run `run`, ended by its closing cap, to finish.
    Finish(u64, Closing),
}

/// Refuses a piece no window can rely on: a lattice step that is not a power of two (two
/// bodies' lattices must map onto their common one exactly), or a tet naming a vertex the
/// piece does not have.
fn malformed(p: &Piece) -> Option<Accepted> {
    let id = &p.body;
    let scale = p.geometry.scale;
    if scale < 1 || scale.count_ones() != 1 {
        return Some(Accepted::refused(
            "bad_piece",
            format!("{id}: a piece with lattice scale {scale} (a power of two is needed); ignored"),
        ));
    }
    let nv = p.mesh.vertices.len();
    // The largest id first (a reduction over all the ids, which vectorises), the tet naming
    // it only if it is past the vertices.
    let past = |t: &[u32; 4]| t.iter().any(|&v| v as usize >= nv);
    let largest = p
        .mesh
        .tets
        .iter()
        .fold(0, |m, t| m.max(t[0]).max(t[1]).max(t[2]).max(t[3]));
    let t = (!p.mesh.tets.is_empty() && largest as usize >= nv)
        .then(|| p.mesh.tets.iter().position(past))
        .flatten()?;
    Some(Accepted::refused(
        "bad_piece",
        format!("{id}: tet {t} of a piece names a vertex past its {nv}; ignored"),
    ))
}

/// A body's window kept from its last rest ([`RollingChecker::moved`]) is dropped once it
/// has moved for more slabs than this.
const REST_KEPT_SLABS: u32 = 32;

/// Default of [`RollingConfig::max_frame_bytes`]: 1 GiB of decoded frames per body.
pub const DEFAULT_MAX_FRAME_BYTES: u64 = 1 << 30;

/// A frame of a body and the lattice it came on.
#[derive(Debug, Clone)]
struct KeptGrid {
    geometry: GridGeometry,
    grid: LazyGrid,
}

/// A body's frames at a stamp and around it, nearest first (see [`BodyStream::frame_at`]).
#[derive(Debug)]
struct FramesAround {
    at: Option<KeptGrid>,
    below: Vec<KeptGrid>,
    above: Vec<KeptGrid>,
}

impl FramesAround {
    /// The body's frame at the stamp on lattice `g`, as [`BodyStream::frame_at`] finds it.
    fn frame(&self, g: &GridGeometry) -> Option<Arc<OccupancyGrid>> {
        frame_among(self.at.as_ref(), self.below.iter(), self.above.iter(), g)
    }
}

/// The frame received at a stamp (`at`) if it is on `g`; otherwise (a frame the mesher
/// filled in, the received one refused) the union of the nearest frames on `g` below and
/// above it, which is what the mesher filled the gap with.
fn frame_among<'a>(
    at: Option<&KeptGrid>,
    mut below: impl Iterator<Item = &'a KeptGrid>,
    mut above: impl Iterator<Item = &'a KeptGrid>,
    g: &GridGeometry,
) -> Option<Arc<OccupancyGrid>> {
    if let Some(k) = at {
        if k.geometry == *g {
            if let Some(grid) = k.grid.get() {
                return Some(grid);
            }
        }
    }
    let on_g = |k: &KeptGrid| (k.geometry == *g).then(|| k.grid.get()).flatten();
    let below = below.find_map(on_g)?;
    let above = above.find_map(on_g)?;
    below.union(&above).map(Arc::new)
}

/// How a frame is decoded, when the checker is given it undecoded
/// ([`RollingChecker::on_frame_with`]).
pub type DecodeFrame = Box<dyn FnOnce() -> Option<OccupancyGrid> + Send>;

/// A frame decoded by whoever needs it first (another who needs it meanwhile waits for that
/// decoding, which has started), or never.
#[derive(Clone)]
struct LazyGrid(Arc<LazyInner>);

struct LazyInner {
    grid: std::sync::OnceLock<Option<Arc<OccupancyGrid>>>,
    decode: std::sync::Mutex<Option<DecodeFrame>>,
    /// A bound of the decoded frame's heap bytes, counted until it is decoded.
    expected_bytes: u64,
}

impl std::fmt::Debug for LazyGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LazyGrid")
            .field("decoded", &self.0.grid.get().is_some())
            .field("expected_bytes", &self.0.expected_bytes)
            .finish()
    }
}

impl LazyGrid {
    fn ready(grid: OccupancyGrid) -> Self {
        let bytes = grid.heap_bytes();
        let cell = std::sync::OnceLock::new();
        let _ = cell.set(Some(Arc::new(grid)));
        LazyGrid(Arc::new(LazyInner {
            grid: cell,
            decode: std::sync::Mutex::new(None),
            expected_bytes: bytes,
        }))
    }

    fn later(decode: DecodeFrame, expected_bytes: u64) -> Self {
        LazyGrid(Arc::new(LazyInner {
            grid: std::sync::OnceLock::new(),
            decode: std::sync::Mutex::new(Some(decode)),
            expected_bytes,
        }))
    }

    /// The decoded frame (`None` if it does not decode).
    fn get(&self) -> Option<Arc<OccupancyGrid>> {
        self.0
            .grid
            .get_or_init(|| {
                let decode = self.0.decode.lock().ok()?.take()?;
                decode().map(Arc::new)
            })
            .clone()
    }

    /// Heap bytes it takes (or will, decoded).
    fn heap_bytes(&self) -> u64 {
        match self.0.grid.get() {
            Some(Some(g)) => g.heap_bytes(),
            Some(None) => 0,
            None => self.0.expected_bytes,
        }
    }
}

impl BodyStream {
    /// The body's frame at `stamp` on lattice `g`, as its mesher accepted it: the frame
    /// received there if it is on `g`; otherwise (a frame the mesher filled in, the received
    /// one refused) the union of the nearest frames on `g` around it, which is what the mesher
    /// filled the gap with.
    fn frame_at(&self, stamp: i64, g: &GridGeometry) -> Option<Arc<OccupancyGrid>> {
        frame_among(
            self.frames.get(&stamp),
            self.frames.range(..stamp).rev().map(|(_, k)| k),
            self.frames.range(stamp + 1..).map(|(_, k)| k),
            g,
        )
    }

    /// The frames [`Self::frame_at`] looks at for `stamp`, to find it later (by the
    /// bookkeeping, which decodes them).
    fn frames_around(&self, stamp: i64) -> FramesAround {
        FramesAround {
            at: self.frames.get(&stamp).cloned(),
            below: self
                .frames
                .range(..stamp)
                .rev()
                .map(|(_, k)| k.clone())
                .collect(),
            above: self
                .frames
                .range(stamp + 1..)
                .map(|(_, k)| k.clone())
                .collect(),
        }
    }

    fn current(&self) -> Option<&Run> {
        self.runs.last()
    }
    fn run(&self, id: u64) -> Option<&Run> {
        self.runs.iter().find(|r| r.id == id)
    }
    /// What the body has at stamp `s`: a slab, nothing for sure, or not known yet.
    fn status(&self, s: i64, finishing: bool) -> Status {
        if self.slabs.contains_key(&s) {
            return Status::Has;
        }
        for r in self.runs.iter().rev() {
            if s >= r.first_stamp && s < r.frontier {
                return Status::Mismatch;
            }
        }
        match self.current() {
            Some(r) if !r.ended() && s >= r.frontier && !finishing => Status::Maybe,
            Some(r) if r.ended() && s >= r.frontier && !finishing => Status::Maybe,
            None if !finishing => Status::Maybe,
            _ => Status::Never,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Status {
    Has,
    Never,
    Maybe,
    Mismatch,
}

/// A crossing kept for the closing speeds: checker times, tets (body run numbers), normals.
#[derive(Debug, Clone, Copy)]
struct Record {
    /// Checker-time range of the crossing's section (pair base).
    t: (f64, f64),
    /// The two tets (numbers in their bodies' runs: a's, b's).
    tets: (u64, u64),
    /// Their outward 4D normals (a's, b's).
    normals: ([f64; 4], [f64; 4]),
}

#[derive(Debug, Clone)]
struct Interval {
    /// Checker times (pair base).
    t: (f64, f64),
    /// Seconds since the origin.
    s: (f64, f64),
    /// Closing speeds at start and end (voxels per frame period), once known.
    speeds: (Option<Option<f64>>, Option<Option<f64>>),
    /// Frame periods (s) at start and end.
    periods: (f64, f64),
    /// Its number among the pair's contacts (0: the first), as announced.
    index: u64,
}

#[derive(Debug, Default)]
struct Overlap {
    /// Overlap and bound of the runs of periods closed by a gap (see `overlap_push`).
    closed: (f64, f64),
    /// Meshes the intersection of the two bodies' frames, period by period (made at the
    /// first frame fed, dropped when a gap closes the run).
    mesher: Option<Mesher>,
    /// The intersection mesh's statistics so far: its hypervolume is the overlap.
    acc: StatsAccumulator,
    /// Sums of the intersection mesh's normals' spatial and temporal parts so far, in
    /// lattice units: the overlap's error bound (`run_overlap`).
    sums: (f64, f64),
    /// `sums` with the normals of the cap closing the run at its last frame (the bound's
    /// sums once two frames are in), worked out as the frame is fed when the pair
    /// interferes (only then is it reported), else when it is reported.
    closed_sums: Option<(f64, f64)>,
    /// Stamp of the latest frame fed (a frame at or before it is not fed again).
    last_pushed: Option<i64>,
    /// The intersection of two empty frames on the two lattices, fed for a period known
    /// to have none (see `empty_intersection`): one frame's memory per pair.
    empty: Option<(
        GridGeometry,
        GridGeometry,
        Option<(OccupancyGrid, GridGeometry)>,
    )>,
    /// The run's first and latest stamps fed, and how many frames (its mean period).
    stamps: (i64, i64, u64),
    /// Not measurable any more: a frame was missing, refused, or on another lattice (the
    /// report then says the overlap is unknown).
    unknown: bool,
    /// The intersection's lattice (the run's frames must all be on it).
    geometry: Option<GridGeometry>,
}

#[derive(Debug)]
struct PairRoll {
    /// The two bodies' ids (`a` < `b`).
    a: String,
    b: String,
    /// Stamp of the next period to decide.
    next: Option<i64>,
    /// Common frame index of `next`, and of the time origin of the checker coordinates.
    index: i64,
    base: i64,
    /// Stamps of recent common frame indices.
    stamps: BTreeMap<i64, i64>,
    /// INTERFERENCE and INSIDE tets of a and of b over the periods decided.
    counts: (LabelCounts, LabelCounts),
    /// Candidate tet pairs walked (boxes overlapping), over the periods decided.
    candidates: u64,
    /// Tet pairs whose boundaries cross, over the periods decided.
    crossings: u64,
    /// The latest closed contact intervals (at most `max_intervals`).
    intervals: VecDeque<Interval>,
    /// Closed intervals dropped from `intervals` for `max_intervals` (counted).
    dropped_intervals: u64,
    /// The contact interval going on, if one is.
    open: Option<Interval>,
    /// Contacts begun so far (the next one's [`Interval::index`]).
    contacts: u64,
    /// Crossings kept for the closing speeds at the ends of intervals (dropped once no
    /// start or end can use them: [`RollingChecker::finish_speeds`]).
    records: VecDeque<Record>,
    /// The overlap hypervolume measured so far.
    overlap: Overlap,
    /// The overlap being fed on rayon's pool, if it is (then `overlap` is a stand-in).
    overlap_job: Option<PoolJob<Overlap>>,
    /// The overlap so far and its bound (`None`: not measurable) through the start of the
    /// latest period whose overlap was fed (everything once the inputs ended): what its
    /// contact events say, without waiting for the pool ([`RollingChecker::contact_fields`]).
    overlap_known: Option<(f64, f64)>,
    /// Why the pair is no longer checked (its bodies on lattices that cannot be compared,
    /// in different frames, ...), once it is not: said once, in the report.
    stopped: Option<String>,
    /// Steps per frame period of the pair's lattice (0 until the first window).
    per: i64,
    /// Spent any window: the pair is in the report.
    checked: bool,
    /// Regions or contact tets whose inclusion stayed undecided (labelled OUTSIDE), over
    /// the periods decided.
    undecided: u64,
    /// Said once per absence that the partner is late.
    partner_absent: bool,
    /// Where each body (a, b) was not observed well enough, over the periods checked.
    unsure: (UnsureLog, UnsureLog),
    /// The unsure span going on: its index, the body, start and latest end (ns), and why.
    unsure_open: Option<OpenUnsure>,
    /// Unsure spans begun so far.
    unsure_count: u64,
    /// The period checked before what follows its slabs was known, if one is waiting for
    /// that (see [`PendingPeriod`]).
    pending: Option<PendingPeriod>,
    /// The windows checked in the last [`RollingConfig::kept_windows`] periods whose result
    /// a later period of the pair can take moved (see [`KeptWindow`]), oldest first.
    kept: VecDeque<KeptWindow>,
    /// Periods whose windows were taken moved from a kept one.
    taken_moved: u64,
}

/// A window of a pair as checked, kept so that a later period whose two windows are both
/// this one's moved by the same lattice vector (two bodies at rest, or at rest again after
/// stepping together by whole voxels: [`WindowSpec::moved_copy_of`], compared exactly)
/// takes its result moved instead of being walked and labelled again: a cell at rest costs
/// its meshing, not its check. Kept only for a result that moves exactly: no crossings
/// (their time ranges are rounded) and nothing left undecided; its labels are then the
/// geometry's own, and a lattice vector moves the geometry with them. Comparing a window
/// with the kept ones costs a pass over their vertices and tets at most.
#[derive(Debug)]
struct KeptWindow {
    /// The pair's period index of the window.
    k: i64,
    specs: (WindowSpec, WindowSpec),
    result: WindowResult,
}

/// A pair's period checked as soon as both bodies' slabs were there, before it was known
/// whether either stream ends at the period's later frame (then closed there by a cap).
///
/// A lateral tet's labels and crossings do not depend on what follows its slab (see
/// [`crate::period`]), so the period's contacts and unsure spans are said at once; a cap at
/// the later frame can only add its own tets, crossings in that time plane, and the ends
/// of the streams. The labels wait, so that a slab's labels are one message as the full
/// window gives them: once the next slabs or the ends are known, the pair settles the
/// period ([`RollingChecker::settle_pending`]) before it goes on.
#[derive(Debug)]
struct PendingPeriod {
    /// The period's two frames.
    s: i64,
    hi: i64,
    /// Its common frame index.
    k: i64,
    /// What the window without caps at `hi` gave (`None`: it could not be checked).
    result: Option<WindowResult>,
    /// The labels it gave, to be published once settled (if no cap comes).
    labels: Vec<RollingOutput>,
}

/// A pair's unsure span that is going on (see [`UnsureUpdate`]).
#[derive(Debug, Clone)]
struct OpenUnsure {
    /// Its number among the pair's unsure spans.
    index: u64,
    /// The body not observed well enough.
    body: String,
    /// Its start and latest end (ns).
    from_ns: i64,
    to_ns: i64,
    /// Why the body was not observed well enough.
    why: chronotope_mesh::unsure::Unsure,
    /// The frame period (ns) at its start.
    period_ns: i64,
}

/// A body's window prepared for one partner, kept for the periods after
/// ([`RollingChecker`]'s `prepared` and `rest`).
#[derive(Debug, Clone)]
struct HeldWindow {
    /// The other body of the pair it was prepared for (its tets are those that pair needs;
    /// it serves any partner [`PreparedWindow::serves`] says it does).
    partner: String,
    /// The window.
    spec: WindowSpec,
    /// Its preparation.
    window: Arc<PreparedWindow>,
    /// The stamp of the period it was checked for.
    s: i64,
}

/// Per body, its [`HeldWindow`]s: one per partner at most.
type HeldWindows = BTreeMap<String, Vec<HeldWindow>>;

/// Keeps `held` for body `id`, in place of the one held for the same partner.
fn hold(windows: &mut HeldWindows, id: &str, held: HeldWindow) {
    let v = windows.entry(id.to_owned()).or_default();
    match v.iter_mut().find(|h| h.partner == held.partner) {
        Some(h) => *h = held,
        None => v.push(held),
    }
}

/// The rolling checker of a set of pairs.
#[derive(Debug)]
pub struct RollingChecker {
    cfg: RollingConfig,
    /// The options the bodies' meshers use (and the overlap's).
    opts: MesherOptions,
    /// Which pairs, which bodies move (resolutions), the rotation asked for.
    plan: CheckPlan,
    /// Every body seen, by id.
    bodies: BTreeMap<String, BodyStream>,
    /// The planned pairs whose bodies have been seen, in the order of their ids.
    pairs: Vec<PairRoll>,
    /// Earliest first stamp of any body (the report's time origin).
    origin_ns: Option<i64>,
    /// The distinct frame stamps over the bodies (the report's frames).
    union: UnionStamps,
    /// The streams are over ([`RollingChecker::finish`]): what is not there will not come.
    finishing: bool,
    /// Problems for the report (at most [`KEPT_PROBLEMS`]).
    problems: Vec<String>,
    /// Problems not kept for [`KEPT_PROBLEMS`] (counted).
    dropped_problems: u64,
    /// Per movable body: contacts ending before this (s) are resolved.
    resolved_until: BTreeMap<String, f64>,
    /// The latest resolutions (at most `max_resolutions`).
    resolutions: VecDeque<Resolution>,
    /// Resolutions not kept for `max_resolutions` (counted).
    dropped_resolutions: u64,
    /// Windows checked ahead, in parallel, at the start of a pump (see [`Prefetched`]).
    prefetched: Vec<Prefetched>,
    /// Per body, its latest prepared window for each partner (one per pair of the body at
    /// most) and the stamp of the period it was checked for: a body in several pairs has
    /// the same window in each, prepared once where one preparation serves them all.
    /// Dropped once every pair of the body has decided that period.
    prepared: HeldWindows,
    /// The last prepared windows of each body at rest, kept after its pairs have gone past
    /// them: a later window of the body that is a moved copy of one (at rest, or at rest
    /// again after a step by whole voxels: [`WindowSpec::moved_copy_of`]) is that one moved,
    /// not prepared again. One window per pair of the body; dropped once the body has moved
    /// for [`REST_KEPT_SLABS`] slabs.
    rest: HeldWindows,
    /// The piece just accepted still has to be added to its run's statistics (or, a
    /// closing cap, the run's statistics finished): done on the pool while the windows it
    /// makes ready are checked.
    pending_stats: Option<PendingStats>,
    /// Where the statistics, the overlaps and the frames' decoding run
    /// ([`shared_bookkeeping_pool`] unless set).
    bookkeeping: BookkeepingPool,
    /// The resolver's pool (made when the first resolution is handed over).
    resolver: Option<rayon::ThreadPool>,
    /// Resolutions running there, oldest first: which episode, and where its result will
    /// come.
    in_flight: VecDeque<(String, crossbeam_channel::Receiver<ResolveOutcome>)>,
    /// Each body's last horizon (with its preparation once it has repeated) and each
    /// movable body's last search (shared with the resolutions).
    horizons: Arc<episodes::KeptHorizons>,
}

/// A window of a pair checked ahead of its turn: the pairs' windows that are ready when
/// a pump starts are checked at once on rayon's pool, then taken in pair order by the
/// sequential steps. A step uses one only if the window it builds is the same (same
/// pieces, caps and placement); otherwise it checks its own, so the answer never depends
/// on what was checked ahead, nor on the thread count.
#[derive(Debug)]
struct Prefetched {
    pair: usize,
    s: i64,
    specs: (WindowSpec, WindowSpec),
    result: WindowChecked,
}

/// Distinct frame stamps over the checked bodies: first, last and how many.
#[derive(Debug, Default)]
struct UnionStamps {
    recent: BTreeSet<i64>,
    first: Option<i64>,
    last: Option<i64>,
    count: u64,
}

impl UnionStamps {
    fn add(&mut self, s: i64) {
        if self.recent.insert(s) {
            self.count += 1;
            self.first = Some(self.first.map_or(s, |f| f.min(s)));
            self.last = Some(self.last.map_or(s, |l| l.max(s)));
            while self.recent.len() > 4096 {
                self.recent.pop_first();
            }
        }
    }
    /// Mean frame period (s), as the full check's common lattice gives it.
    fn period_s(&self) -> Option<f64> {
        let (f, l) = (self.first?, self.last?);
        (self.count >= 2).then(|| (l - f) as f64 * 1e-9 / (self.count - 1) as f64)
    }
}

/// Problems kept for the report.
const KEPT_PROBLEMS: usize = 256;

impl RollingChecker {
    /// A checker of the plan's pairs (`plan.pairs` must name them).
    pub fn new(plan: CheckPlan, opts: MesherOptions, cfg: RollingConfig) -> Self {
        let plan_copy = plan.clone();
        let mut pairs: Vec<(String, String)> = plan
            .pairs
            .clone()
            .unwrap_or_default()
            .into_iter()
            .filter(|(a, b)| a != b)
            .map(|(a, b)| if a < b { (a, b) } else { (b, a) })
            .collect();
        pairs.sort();
        pairs.dedup();
        let mut bodies: BTreeMap<String, BodyStream> = BTreeMap::new();
        for (a, b) in &pairs {
            bodies.entry(a.clone()).or_default().pairs += 1;
            bodies.entry(b.clone()).or_default().pairs += 1;
        }
        Self {
            cfg,
            opts,
            plan,
            bodies,
            pairs: pairs
                .into_iter()
                .map(|(a, b)| PairRoll {
                    a,
                    b,
                    next: None,
                    index: 0,
                    base: 0,
                    stamps: BTreeMap::new(),
                    counts: Default::default(),
                    candidates: 0,
                    crossings: 0,
                    intervals: VecDeque::new(),
                    dropped_intervals: 0,
                    open: None,
                    contacts: 0,
                    records: VecDeque::new(),
                    overlap: Overlap::default(),
                    overlap_job: None,
                    overlap_known: Some((0.0, 0.0)),
                    stopped: None,
                    per: 0,
                    checked: false,
                    undecided: 0,
                    partner_absent: false,
                    unsure: Default::default(),
                    unsure_open: None,
                    unsure_count: 0,
                    pending: None,
                    kept: VecDeque::new(),
                    taken_moved: 0,
                })
                .collect(),
            origin_ns: None,
            union: UnionStamps::default(),
            finishing: false,
            problems: Vec::new(),
            dropped_problems: 0,
            resolved_until: plan_movable(&plan_copy),
            resolutions: VecDeque::new(),
            dropped_resolutions: 0,
            prefetched: Vec::new(),
            prepared: BTreeMap::new(),
            rest: BTreeMap::new(),
            pending_stats: None,
            bookkeeping: shared_bookkeeping_pool(),
            resolver: None,
            in_flight: VecDeque::new(),
            horizons: Arc::default(),
        }
    }

    /// Runs the bookkeeping (statistics, overlaps, the frames' decoding) on `pool` (rayon's
    /// when `None`) from now on; what it computes is the same on any pool.
    pub fn set_bookkeeping_pool(&mut self, pool: BookkeepingPool) {
        self.bookkeeping = pool;
    }

    /// Turns [`RollingOutput::Labels`] on or off while the streams go on (nobody reads them).
    pub fn set_labels(&mut self, on: bool) {
        self.cfg.labels = on;
    }

    /// Turns [`RollingConfig::reports`] on or off while the streams go on.
    pub fn set_reports(&mut self, on: bool) {
        self.cfg.reports = on;
    }

    /// Turns [`RollingOutput::SlabDone`] on or off while the streams go on. Turned on, it reports
    /// the slabs that arrive from then on: a slab kept from before has not been seen by
    /// every pair's check since, so its worst labels would be partial.
    pub fn set_slabs_done(&mut self, on: bool) {
        if self.cfg.slabs_done == on {
            return;
        }
        self.cfg.slabs_done = on;
        if !on {
            for b in self.bodies.values_mut() {
                for s in b.slabs.values_mut() {
                    s.worst = Vec::new();
                }
            }
        }
    }

    /// The bodies of the checked pairs.
    pub fn bodies(&self) -> impl Iterator<Item = &str> {
        self.bodies.keys().map(String::as_str)
    }

    fn problem(&mut self, out: &mut Vec<RollingOutput>, kind: &'static str, text: String) {
        if self.problems.len() < KEPT_PROBLEMS {
            self.problems.push(text.clone());
        } else {
            self.dropped_problems += 1;
        }
        out.push(RollingOutput::Problem(kind, text));
    }

    /// A decoded frame of a body (for the overlap and the windows' caps).
    pub fn on_frame(
        &mut self,
        body: &str,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: OccupancyGrid,
        out: &mut Vec<RollingOutput>,
    ) {
        if self
            .keep_frame(body, stamp_ns, geometry, LazyGrid::ready(grid))
            .is_some()
        {
            self.pump(out);
        }
    }

    /// [`Self::on_frame`] with the frame still encoded: `decode` runs where the frame is
    /// first needed (a pair's overlap in a period where the bodies overlap or a frame
    /// cannot be known empty, an episode's horizon cap), on the bookkeeping's or the
    /// resolver's pool; a frame nothing needs is never decoded. `expected_bytes` bounds the
    /// decoded frame's heap size (it counts toward the frames' memory limit until the frame
    /// is decoded; e.g. [`chronotope_mesh::grid::decoded_bytes`]). A frame that does not
    /// decode counts as not received.
    pub fn on_frame_with(
        &mut self,
        body: &str,
        stamp_ns: i64,
        geometry: GridGeometry,
        expected_bytes: u64,
        decode: DecodeFrame,
        out: &mut Vec<RollingOutput>,
    ) {
        self.advance_statistics();
        let grid = LazyGrid::later(decode, expected_bytes);
        if self.keep_frame(body, stamp_ns, geometry, grid).is_none() {
            return;
        }
        self.pump(out);
    }

    /// Keeps `grid` as `body`'s frame at `stamp_ns`: `None` if the body is unknown, `false`
    /// (and dropped) if it has a frame there, the first being the one a mesher keeps (a
    /// repeated stamp is refused).
    fn keep_frame(
        &mut self,
        body: &str,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: LazyGrid,
    ) -> Option<bool> {
        let b = self.bodies.get_mut(body)?;
        Some(match b.frames.entry(stamp_ns) {
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert(KeptGrid { geometry, grid });
                true
            }
            std::collections::btree_map::Entry::Occupied(_) => false,
        })
    }

    /// Also reports `body`, which is in no pair (a lone body): its pieces are taken for its
    /// figures and dropped as they come.
    pub fn track_body(&mut self, body: &str) {
        self.bodies.entry(body.to_owned()).or_default();
    }

    /// One mesh piece of a body.
    pub fn on_piece(&mut self, p: Piece, out: &mut Vec<RollingOutput>) {
        if !self.bodies.contains_key(&p.body) {
            return;
        }
        self.advance_statistics();
        self.pending_stats = None;
        match self.accept(&p) {
            Accepted::Taken => {}
            Accepted::Noted { kind, text } | Accepted::Refused { kind, text } => {
                self.problem(out, kind, text)
            }
        }
        let Some(pending) = self.pending_stats.take() else {
            self.pump(out);
            return;
        };
        // The body's statistics of the piece (closedness, hypervolume) do not wait for the
        // windows it makes ready, nor they for them: the statistics go to the bookkeeping,
        // queued behind the body's earlier pieces, and are taken back when something reads
        // them (a report, a closed stream) or when more than `STATS_QUEUED` wait.
        let Some(b) = self.bodies.get_mut(&p.body) else {
            self.pump(out);
            return;
        };
        match pending {
            PendingStats::Finish(run, closing) => {
                // Every piece of the run was added first (`accept_closing_cap`).
                let job = move || StatsDone::Finished(closing.finish());
                b.stats_job = Some(StatsJob {
                    run,
                    job: PoolJob::spawn(&self.bookkeeping, job),
                });
            }
            PendingStats::Add(run, first_cap) => {
                b.stats_queue.push_back(QueuedAdd {
                    run,
                    first_cap,
                    index: u64::from(p.index),
                    stamps_ns: p.stamps_ns,
                    geometry: p.geometry,
                    mesh: p.mesh.clone(),
                    unsure: p.unsure,
                });
                if b.stats_queue.len() > STATS_QUEUED {
                    self.settle_stats(&p.body);
                } else {
                    self.advance_stats(&p.body);
                }
            }
        }
        self.prefetched = self.prefetch(1);
        self.pump_prefetched(out);
    }

    /// Takes back body `body`'s statistics job if it has finished and starts the next piece
    /// queued, as long as that does not wait.
    fn advance_stats(&mut self, body: &str) {
        loop {
            let Some(b) = self.bodies.get(body) else {
                return;
            };
            match &b.stats_job {
                Some(j) if !j.job.finished() => return,
                Some(_) => self.take_back_stats(body),
                None => {}
            }
            let Some(b) = self.bodies.get_mut(body) else {
                return;
            };
            let Some(q) = b.stats_queue.pop_front() else {
                return;
            };
            let Some(acc) = take_acc(b, q.run) else {
                continue;
            };
            let run = q.run;
            let job = move || q.add_to(acc);
            b.stats_job = Some(StatsJob {
                run,
                job: PoolJob::spawn(&self.bookkeeping, job),
            });
        }
    }

    /// Every body's statistics job taken back if it has finished, and the next pieces
    /// started (nothing waits): live, the checker's node does this when it has caught up.
    pub fn advance_statistics(&mut self) {
        for id in self.bodies_with_stats_work() {
            self.advance_stats(&id);
        }
    }

    /// The bodies with a statistics job out or pieces queued for one.
    fn bodies_with_stats_work(&self) -> Vec<String> {
        self.bodies
            .iter()
            .filter(|(_, b)| b.stats_job.is_some() || !b.stats_queue.is_empty())
            .map(|(id, _)| id.clone())
            .collect()
    }

    /// Brings body `body`'s statistics up to its latest piece: its job taken back (run here
    /// if the pool has not started it, else waited for) and the pieces queued behind it
    /// added here.
    pub(super) fn settle_stats(&mut self, body: &str) {
        self.take_back_stats(body);
        while let Some(b) = self.bodies.get_mut(body) {
            let Some(q) = b.stats_queue.pop_front() else {
                return;
            };
            let Some(acc) = take_acc(b, q.run) else {
                continue;
            };
            let run = q.run;
            let done = q.add_to(acc);
            b.give_back_stats(run, done);
            // Piece by piece, as the pool's jobs are taken back.
            self.forget_rest_if_moving(body);
        }
    }

    /// Takes back body `body`'s statistics job, if any (run here if the pool has not
    /// started it, else waited for).
    fn take_back_stats(&mut self, body: &str) {
        let Some(b) = self.bodies.get_mut(body) else {
            return;
        };
        let Some(job) = b.stats_job.take() else {
            return;
        };
        let done = match job.job.wait() {
            Some(Ok(done)) => done,
            Some(Err(panic)) => std::panic::resume_unwind(panic),
            None => panic!("{body}: the statistics of a piece were lost"),
        };
        b.give_back_stats(job.run, done);
        self.forget_rest_if_moving(body);
    }

    /// A window kept from body `body`'s last rest serves it once it rests again, moved or
    /// not (a table that steps by whole voxels now and then); not once it has moved for
    /// long.
    fn forget_rest_if_moving(&mut self, body: &str) {
        if self
            .bodies
            .get(body)
            .is_some_and(|b| b.moving_for > REST_KEPT_SLABS)
        {
            self.rest.remove(body);
        }
    }

    /// Takes back pair `i`'s overlap being fed, if it is (waiting for it).
    pub(super) fn settle_overlap(&mut self, i: usize) {
        let Some(job) = self.pairs.get_mut(i).and_then(|p| p.overlap_job.take()) else {
            return;
        };
        match job.wait() {
            Some(Ok(ov)) => self.pairs[i].overlap = ov,
            Some(Err(panic)) => std::panic::resume_unwind(panic),
            None => panic!("pair {i}: its overlap was lost"),
        }
    }

    /// Takes back every body's statistics being added.
    pub(super) fn settle_all_stats(&mut self) {
        for i in 0..self.pairs.len() {
            self.settle_overlap(i);
        }
        for id in self.bodies_with_stats_work() {
            self.settle_stats(&id);
        }
    }

    fn accept(&mut self, p: &Piece) -> Accepted {
        if let Some(refused) = malformed(p) {
            return refused;
        }
        let b = self.bodies.get_mut(&p.body).expect("checked above");
        if b.frame_id != p.frame_id {
            b.frame_id.clone_from(&p.frame_id);
        }
        match p.kind {
            PieceKind::CapStart => self.accept_opening_cap(p),
            PieceKind::Lateral => self.accept_slab(p),
            PieceKind::CapEnd => self.accept_closing_cap(p),
        }
    }

    /// A stream's opening cap begins a run (closing the one before, if it was open: its
    /// mesher restarted).
    fn accept_opening_cap(&mut self, p: &Piece) -> Accepted {
        let id = &p.body;
        // A run left open is closed here: its statistics up to date first.
        self.settle_stats(id);
        let b = self.bodies.get_mut(id).expect("checked above");
        let mut restarted = None;
        if let Some(r) = b.runs.last_mut() {
            if !r.ended() {
                r.close(None);
                restarted = Some(format!(
                    "{id}: the mesh starts again at {} ns without a closing cap after \
                     {} slab(s) (a restarted mesher?); the earlier stream is checked up to \
                     its last slab",
                    p.stamps_ns.0, r.next_index
                ));
            }
        }
        if b.runs.last().is_some_and(|r| p.stamps_ns.0 <= r.frontier) {
            return Accepted::refused(
                "bad_piece",
                format!(
                    "{id}: a stream starting at {} ns, not after the previous one's last \
                     frame; ignored",
                    p.stamps_ns.0
                ),
            );
        }
        b.joined_late = false;
        let run = Run::begun(b.next_run, p, p.mesh.clone(), p.occupied, 0);
        self.begin_run(id, run);
        match restarted {
            Some(text) => Accepted::Noted {
                kind: "stream_restarted",
                text,
            },
            None => Accepted::Taken,
        }
    }

    /// A slab (lateral piece) extends the body's open run; with no run open, or after
    /// pieces of it were lost, it begins a run of its own, without an opening cap.
    fn accept_slab(&mut self, p: &Piece) -> Accepted {
        let begun = self.begin_run_at_slab(p);
        if let Accepted::Refused { .. } = begun {
            return begun;
        }
        let id = &p.body;
        let b = self.bodies.get_mut(id).expect("checked above");
        let Some(r) = b.runs.last_mut().filter(|r| !r.ended()) else {
            return Accepted::Taken;
        };
        if p.geometry != r.geometry {
            return Accepted::refused(
                "bad_piece",
                format!("{id}: a piece on another lattice; ignored"),
            );
        }
        if p.index != r.next_index || p.stamps_ns.0 != r.frontier || p.stamps_ns.1 <= p.stamps_ns.0
        {
            return Accepted::refused(
                "piece_out_of_order",
                format!(
                    "{id}: piece index {} out of order (expected index {}); ignored, the \
                     body's mesh will not be closed",
                    p.index, r.next_index
                ),
            );
        }
        // Added to the run's statistics by `on_piece`, while windows are checked.
        // A run that starts after lost pieces has no opening cap to pair with.
        let first_cap = (r.next_index == 0).then(|| r.first_cap.clone());
        self.pending_stats = Some(PendingStats::Add(r.id, first_cap));
        let first_tet = r.tets;
        r.tets += p.mesh.tets.len() as u64;
        r.next_index += 1;
        r.frontier = p.stamps_ns.1;
        self.union.add(p.stamps_ns.1);
        let worst = if self.cfg.slabs_done {
            vec![0; p.mesh.tets.len()]
        } else {
            Vec::new()
        };
        b.slabs.insert(
            p.stamps_ns.0,
            HeldSlab {
                run: r.id,
                index: p.index,
                hi: p.stamps_ns.1,
                mesh: p.mesh.clone(),
                bounds: p.mesh.spatial_bounds(),
                first_tet,
                worst,
                unsure: p.unsure,
                displacement: p.displacement,
            },
        );
        begun
    }

    /// Begins a run at slab `p` if the body has no run open, or if pieces of its open run
    /// are missing before `p` (the open run is then closed at its last slab): taken,
    /// noted (what was missing, or that the checker joined the stream mid-way), or
    /// refused (a slab before the body's last frame).
    fn begin_run_at_slab(&mut self, p: &Piece) -> Accepted {
        let id = &p.body;
        let b = self.bodies.get_mut(id).expect("checked above");
        let open = b.runs.last().filter(|r| !r.ended());
        let jumped = open.is_some_and(|r| {
            p.index > r.next_index && p.stamps_ns.0 > r.frontier && p.geometry == r.geometry
        });
        if open.is_some() && !jumped {
            return Accepted::Taken;
        }
        let after = b.runs.last().map(|r| r.frontier);
        if after.is_some_and(|f| p.stamps_ns.0 < f) || p.stamps_ns.1 <= p.stamps_ns.0 {
            return Accepted::refused(
                "piece_out_of_order",
                format!(
                    "{id}: piece index {} ({} ns) before the body's last frame; ignored",
                    p.index, p.stamps_ns.0
                ),
            );
        }
        let resumed = "checked again from this piece; the mesh is open where the pieces are \
                       missing";
        let mut note = Accepted::Taken;
        // The run left open is closed here: its statistics up to date first.
        self.settle_stats(id);
        let b = self.bodies.get_mut(id).expect("checked above");
        if let Some(r) = b.runs.last_mut().filter(|r| !r.ended()) {
            r.close(None);
            note = Accepted::Noted {
                kind: "pieces_missing",
                text: format!(
                    "{id}: pieces {} to {} missing ({} ns to {} ns, lost on the way or dropped \
                     by a node that was behind): {resumed}",
                    r.next_index,
                    p.index - 1,
                    r.frontier,
                    p.stamps_ns.0
                ),
            };
        } else if let Some(f) = after {
            note = Accepted::Noted {
                kind: "pieces_missing",
                text: format!(
                    "{id}: piece index {} at {} ns with no stream open (its first cap is \
                     missing, or the stream was taken as ended at {f} ns): {resumed}",
                    p.index, p.stamps_ns.0
                ),
            };
        } else if !b.joined_late {
            b.joined_late = true;
            note = Accepted::Noted {
                kind: "joined_mid_stream",
                text: format!(
                    "{id}: the first piece seen is index {} (this node started after the \
                     body's stream did, or missed its start): the pieces before are gone; the \
                     stream is checked from this piece, its mesh open there",
                    p.index
                ),
            };
        }
        let run = Run::begun(b.next_run, p, Arc::new(TetMesh::default()), 0, p.index);
        self.begin_run(id, run);
        note
    }

    /// A stream's closing cap ends the body's open run at its last slab (its statistics are
    /// finished by `on_piece`, on the pool); with no run open there is nothing to close.
    fn accept_closing_cap(&mut self, p: &Piece) -> Accepted {
        let id = &p.body;
        // The run's statistics are finished from every piece it has.
        self.settle_stats(id);
        let b = self.bodies.get_mut(id).expect("checked above");
        let Some(r) = b.runs.last_mut().filter(|r| !r.ended()) else {
            return Accepted::Taken;
        };
        if p.geometry != r.geometry {
            return Accepted::refused(
                "bad_piece",
                format!("{id}: a piece on another lattice; ignored"),
            );
        }
        if r.next_index == r.first_index || p.index != r.next_index {
            return Accepted::refused(
                "piece_out_of_order",
                format!(
                    "{id}: closing cap at index {} (expected index {}); ignored",
                    p.index, r.next_index
                ),
            );
        }
        r.tets += p.mesh.tets.len() as u64;
        // Its statistics (the cap's faces paired: a cap fills the body's volume) are
        // finished by `on_piece`, on the pool.
        let cap = Some((p.mesh.clone(), p.occupied));
        if let Some(closing) = r.end_at_frontier(cap) {
            self.pending_stats = Some(PendingStats::Finish(r.id, closing));
        }
        Accepted::Taken
    }

    /// Adds `run` (numbered [`BodyStream::next_run`]) to body `id` as its current run.
    fn begin_run(&mut self, id: &str, run: Run) {
        let first = run.first_stamp;
        let b = self.bodies.get_mut(id).expect("checked above");
        b.next_run += 1;
        b.geometry = Some(run.geometry);
        b.runs.push(run);
        self.origin_ns = Some(self.origin_ns.map_or(first, |o| o.min(first)));
        self.union.add(first);
    }

    /// The inputs have ended: every open stream is closed at its last slab, every period
    /// decided with what there is, every open contact closed.
    pub fn finish(&mut self, out: &mut Vec<RollingOutput>) {
        self.settle_all_stats();
        for i in 0..self.pairs.len() {
            self.pairs[i].overlap_known = report::pair_overlap(&self.pairs[i]);
        }
        self.finishing = true;
        for b in self.bodies.values_mut() {
            if let Some(r) = b.runs.last_mut() {
                r.close(None);
            }
        }
        self.pump(out);
        for i in 0..self.pairs.len() {
            // Every stream has ended, so every pending period was settled above; were one
            // not, it would keep the labels it had rather than lose them.
            if let Some(p) = self.pairs[i].pending.take() {
                out.extend(p.labels);
            }
            self.close_open(i, out);
            self.close_unsure(i, out);
            self.finish_speeds(i, true);
            let p = &self.pairs[i];
            tracing::debug!(
                "pair {} x {}: {} periods taken moved from a kept window",
                p.a,
                p.b,
                p.taken_moved
            );
        }
        self.prune(out);
        self.join_resolutions(out);
    }

    /// Periods of each pair (by their ids) whose result was taken moved from an earlier
    /// window instead of being checked (see [`KeptWindow`]).
    pub fn taken_moved(&self) -> Vec<(&str, &str, u64)> {
        self.pairs
            .iter()
            .map(|p| (p.a.as_str(), p.b.as_str(), p.taken_moved))
            .collect()
    }

    /// Decides every period that can be decided, then drops what nothing needs any more.
    fn pump(&mut self, out: &mut Vec<RollingOutput>) {
        self.prefetched = self.prefetch(2);
        self.pump_prefetched(out);
    }

    /// [`Self::pump`] with the windows checked ahead already in `self.prefetched`.
    fn pump_prefetched(&mut self, out: &mut Vec<RollingOutput>) {
        for i in 0..self.pairs.len() {
            while self.pairs[i].stopped.is_none() {
                if !self.step(i, out) {
                    break;
                }
            }
        }
        self.prefetched.clear();
        self.resolve_episodes(out);
        self.prune(out);
    }

    /// The window pair `i` would check next, if it is plainly ready: both bodies have their
    /// slab at the next stamp, on one lattice and in one frame. Anything
    /// less plain is left to [`Self::step`].
    fn ready_window(&self, i: usize) -> Option<(i64, WindowSpec, WindowSpec)> {
        let p = &self.pairs[i];
        if p.stopped.is_some() {
            return None;
        }
        let s = self.next_stamp(i)?;
        if p.next.is_some_and(|n| s > n) {
            return None;
        }
        let (a, b) = (&self.bodies[&p.a], &self.bodies[&p.b]);
        if a.status(s, self.finishing) != Status::Has || b.status(s, self.finishing) != Status::Has
        {
            return None;
        }
        // What follows the slabs need not be known: the window is the one checked before
        // it is (see `PendingPeriod`).
        let (sa, sb) = (a.slabs.get(&s)?, b.slabs.get(&s)?);
        if sb.hi != sa.hi || a.frame_id != b.frame_id || !self.period_ready(&p.a, &p.b, s, sa.hi) {
            return None;
        }
        let (ga, gb) = (a.run(sa.run)?.geometry, b.run(sb.run)?.geometry);
        let lattice = pair_lattice(&ga, &gb).ok()?;
        let k = self.period_index(i, s);
        let per = i64::from(lattice.scale) * i64::from(CHECKER_FACTOR);
        let base = if k - p.base > REBASE_FRAMES {
            k - CONTEXT_SLABS as i64
        } else {
            p.base
        };
        let (Some(wa), Some(wb)) = self.window_specs(i, s, k, (base, per), &lattice) else {
            return None;
        };
        // A window the pair has checked before, moved, is not checked again.
        (!apart(&wa, &wb) && self.repeated(i, k, &wa, &wb).is_none()).then_some((s, wa, wb))
    }

    /// The windows ready for checking at the start of a pump, checked on rayon's pool, if
    /// there are at least `least` (one window alone splits its own check over the cores).
    fn prefetch(&self, least: usize) -> Vec<Prefetched> {
        let ready: Vec<(usize, i64, WindowSpec, WindowSpec)> = (0..self.pairs.len())
            .filter_map(|i| self.ready_window(i).map(|(s, wa, wb)| (i, s, wa, wb)))
            .collect();
        if ready.len() < least.max(1) {
            return Vec::new();
        }
        // On rayon's pool, like the windows' other work: a parallel iterator of one item
        // would run on the calling thread (live, the node's own), which only waits.
        rayon::scope(|_| self.check_ahead(&ready))
    }

    /// The windows `ready` (pair, stamp, both windows) checked, for [`Self::prefetch`].
    fn check_ahead(&self, ready: &[(usize, i64, WindowSpec, WindowSpec)]) -> Vec<Prefetched> {
        // Windows with no tet near each other are answered without being prepared.
        let approaches: Vec<Approach> = ready
            .par_iter()
            .map(|(_, _, wa, wb)| approach(wa, wb))
            .collect();
        // Each distinct body window once: a body in several pairs often has the same
        // window in each (the same pieces and placement). It holds the tets any of its
        // partners needs. In each pair the window keeping fewer tets near the other's box
        // is prepared first, near that box; the other then near the tets it kept (see
        // `check_near`).
        let near: Vec<(&str, &WindowSpec, &str, &WindowSpec)> = ready
            .iter()
            .zip(&approaches)
            .filter_map(|((i, _, wa, wb), x)| match x {
                Approach::Near { a_first } => Some((i, wa, wb, *a_first)),
                Approach::Separated(_) => None,
            })
            .map(|(i, wa, wb, a_first)| {
                let p = &self.pairs[*i];
                if a_first {
                    (p.a.as_str(), wa, p.b.as_str(), wb)
                } else {
                    (p.b.as_str(), wb, p.a.as_str(), wa)
                }
            })
            .collect();
        let prepare = |needs: &[Need]| -> Vec<Option<Arc<PreparedWindow>>> {
            needs
                .par_iter()
                .map(|(id, w, partner)| {
                    self.moved(id, w, partner)
                        .or_else(|| prepare_spec(id, w, Some(*partner)).ok())
                })
                .collect()
        };
        let found = |needs: &[Need],
                     shared: &[Option<Arc<PreparedWindow>>],
                     id: &str,
                     w: &WindowSpec,
                     partner: &Partner| {
            let n = needs
                .iter()
                .position(|(d, x, _)| *d == id && x.same_as(w))?;
            shared.get(n)?.clone().filter(|p| p.serves(partner))
        };
        // A window that fails to prepare is prepared again by its pair, for the error.
        let firsts = shared_partners(
            near.iter()
                .filter_map(|(f, wf, _, wo)| Some((*f, *wf, Partner::whole(wo.spatial_box()?))))
                .filter(|(id, w, p)| cached(&self.prepared, id, w, p).is_none()),
        );
        let first_windows = prepare(&firsts);
        let seconds = shared_partners(
            near.iter()
                .filter_map(|(f, wf, o, wo)| {
                    let whole = Partner::whole(wo.spatial_box()?);
                    let pf = cached(&self.prepared, f, wf, &whole)
                        .or_else(|| found(&firsts, &first_windows, f, wf, &whole))?;
                    Some((*o, *wo, Partner::prepared(wf.spatial_box()?, &pf)))
                })
                .filter(|(id, w, p)| cached(&self.prepared, id, w, p).is_none()),
        );
        let second_windows = prepare(&seconds);
        let ready_for = |id: &str, w: &WindowSpec, partner: &Partner| {
            cached(&self.prepared, id, w, partner)
                .or_else(|| found(&firsts, &first_windows, id, w, partner))
                .or_else(|| found(&seconds, &second_windows, id, w, partner))
        };
        ready
            .par_iter()
            .zip(approaches)
            .map(|((i, s, wa, wb), approach)| {
                let p = &self.pairs[*i];
                let result = match approach {
                    Approach::Separated(r) => Ok((*r, None)),
                    Approach::Near { a_first } => {
                        check_near((&p.a, wa), (&p.b, wb), a_first, ready_for)
                    }
                };
                Prefetched {
                    pair: *i,
                    s: *s,
                    specs: (wa.clone(), wb.clone()),
                    result,
                }
            })
            .collect()
    }

    /// The next stamp pair `i` has to decide, if any body has a slab at or after it.
    fn next_stamp(&self, i: usize) -> Option<i64> {
        let p = &self.pairs[i];
        let from = p.next.unwrap_or(i64::MIN);
        let first = |id: &str| self.bodies[id].slabs.range(from..).next().map(|(s, _)| *s);
        match (first(&p.a), first(&p.b)) {
            (Some(x), Some(y)) => Some(x.min(y)),
            (x, y) => x.or(y),
        }
    }

    /// Common frame index of the period of pair `i` that starts at `s` (the next one).
    fn period_index(&self, i: usize, s: i64) -> i64 {
        let p = &self.pairs[i];
        match p.next {
            None => 0,
            Some(n) if n == s => p.index,
            Some(_) => p.index + 1,
        }
    }

    /// Slabs of `id` at or after `s`.
    fn lead(&self, id: &str, s: i64) -> usize {
        self.bodies[id].slabs.range(s..).count()
    }

    /// Decides one period of pair `i`; `false` if it must wait.
    fn step(&mut self, i: usize, out: &mut Vec<RollingOutput>) -> bool {
        if self.pairs[i].pending.is_some() {
            return self.settle_pending(i, out);
        }
        let finishing = self.finishing;
        let Some(s) = self.next_stamp(i) else {
            return false;
        };
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let over = |me: &Self, n: i64| me.lead(&a, n).max(me.lead(&b, n)) > me.cfg.max_lead_frames;
        // Nothing of either body at the expected stamp: the next slab of either starts
        // later. Wait while a body may still send the expected one.
        if let Some(n) = self.pairs[i].next {
            if s > n {
                let (sa, sb) = (
                    self.bodies[&a].status(n, finishing),
                    self.bodies[&b].status(n, finishing),
                );
                if [sa, sb].contains(&Status::Maybe) && !over(self, n) {
                    return false;
                }
            }
        }
        let (sa, sb) = (
            self.bodies[&a].status(s, finishing),
            self.bodies[&b].status(s, finishing),
        );
        if sa == Status::Mismatch || sb == Status::Mismatch {
            let why = format!(
                "pair {a} x {b}: frames at different times (a frame of one body falls between two \
                 of the other's at {:.3} s); the pair is not checked from there on (different \
                 frame rates or phases are not resampled)",
                self.seconds_of_stamp(s)
            );
            self.pairs[i].stopped = Some(why.clone());
            self.problem(out, "time_mismatch", why);
            return false;
        }
        match (sa, sb) {
            (Status::Has, Status::Has) => self.window(i, s, out),
            (Status::Has, other) | (other, Status::Has) => {
                let (me, partner) = if sa == Status::Has {
                    (&a, &b)
                } else {
                    (&b, &a)
                };
                if other == Status::Maybe && !over(self, s) {
                    return false;
                }
                // A partner that stopped is gone; one that never said anything is late.
                let stopped = self.bodies[partner]
                    .runs
                    .iter()
                    .any(|r| r.ended() && r.frontier <= s);
                if stopped && !self.pairs[i].partner_absent {
                    self.pairs[i].partner_absent = true;
                    let why = format!(
                        "{partner}: its frames end before {:.3} s while {me} goes on (the \
                         stream stopped); pair {a} x {b} has nothing to check from there until \
                         it comes back",
                        self.seconds_of_stamp(s)
                    );
                    self.problem(out, "partner_stopped", why);
                } else if other == Status::Maybe && !self.pairs[i].partner_absent {
                    self.pairs[i].partner_absent = true;
                    let hi = self.bodies[me].slabs[&s].hi;
                    let why = format!(
                        "pair {a} x {b}: {partner} has nothing for {:.3}-{:.3} s while {me} is \
                         {} slabs ahead; {me} is checked without it from there (pieces of \
                         {partner} that come later for that time are refused)",
                        self.seconds_of_stamp(s),
                        self.seconds_of_stamp(hi),
                        self.cfg.max_lead_frames
                    );
                    self.problem(out, "partner_late", why);
                }
                let me = me.clone();
                self.alone(i, &me, s, out);
                true
            }
            _ => false,
        }
    }
}

impl PairRoll {
    /// The stamp from which its answer may still change: the period waiting to be settled,
    /// else the next one to decide.
    fn undecided_from(&self) -> Option<i64> {
        self.pending.as_ref().map(|x| x.s).or(self.next)
    }

    /// Whether a tet of either body has interfered with the other or lain inside it.
    fn interfering(&self) -> bool {
        let (a, b) = &self.counts;
        a.interference + a.inside + b.interference + b.inside > 0
    }
}

fn plan_movable(plan: &CheckPlan) -> BTreeMap<String, f64> {
    plan.movable
        .iter()
        .map(|m| (m.clone(), f64::NEG_INFINITY))
        .collect()
}

/// Seconds since `origin` and the frame period (s) at checker time `t` of pair `p`, from
/// the stamps of the frames around it (as the full check's common lattice gives them).
fn time_at(p: &PairRoll, t: f64, origin: i64) -> Option<(f64, f64)> {
    let per = p.per as f64;
    if per <= 0.0 {
        return None;
    }
    let k_raw = (t / per).floor().max(0.0) as i64 + p.base;
    // The last known frame: the period before it (as the full check clamps to its last).
    let last = *p.stamps.keys().next_back()?;
    let k = k_raw.min(last - 1);
    let frac = t / per - (k - p.base) as f64;
    let (a, b) = (*p.stamps.get(&k)?, *p.stamps.get(&(k + 1))?);
    let s = ((a - origin) as f64 + frac * (b - a) as f64) * 1e-9;
    // The period: of [k_raw, k_raw + 1] where that is known.
    let period = match (p.stamps.get(&k_raw), p.stamps.get(&(k_raw + 1))) {
        (Some(x), Some(y)) => (y - x) as f64 * 1e-9,
        _ => (b - a) as f64 * 1e-9,
    };
    Some((s, period))
}

/// The closing speed of two boundary patches from the crossings near a contact's end (see
/// `contact_speeds` in the checker): normals summed once per tet, exact in `f64`.
fn speed<'a>(records: impl Iterator<Item = &'a Record>) -> Option<f64> {
    let mut a: BTreeMap<u64, [f64; 4]> = BTreeMap::new();
    let mut b: BTreeMap<u64, [f64; 4]> = BTreeMap::new();
    for r in records {
        a.insert(r.tets.0, r.normals.0);
        b.insert(r.tets.1, r.normals.1);
    }
    if a.is_empty() {
        return None;
    }
    let surface = |m: &BTreeMap<u64, [f64; 4]>| {
        let mut n = [0.0f64; 4];
        for v in m.values() {
            (0..4).for_each(|k| n[k] += v[k]);
        }
        let ns = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        (ns > 0.0).then(|| -n[3] / ns)
    };
    Some(surface(&a)? + surface(&b)?)
}

/// Running sums of |N_s| and |N_t| over tets (see [`bounds::hypervolume_bound`]).
/// The overlap's normal sums with those of the cap that would close its run at its last
/// frame, if the mesher has one (see `Overlap::closed_sums`).
fn closing_sums(o: &Overlap) -> Option<(f64, f64)> {
    let m = o.mesher.as_ref()?;
    let cap = m.last_frame().and_then(|k| m.cap(k, CapSide::High))?;
    Some(add_normals(o.sums, &cap))
}

fn add_normals(mut sums: (f64, f64), m: &TetMesh) -> (f64, f64) {
    for t in &m.tets {
        let n = float_normal(&t.map(|v| m.vertices[v as usize]));
        let ns = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        sums = (sums.0 + ns, sums.1 + n[3].abs());
    }
    sums
}

fn add_run(t: &mut Totals, r: Run) {
    let Some(stats) = &r.stats else { return };
    let closed = stats.closed.is_closed() && matches!(r.end, Some((_, Some(_))));
    t.closed = if t.runs == 0 {
        closed
    } else {
        t.closed && closed
    };
    t.runs += 1;
    t.frames += stats.frames;
    t.tets += stats.tets;
    t.vertices += stats.vertices;
    t.hypervolume_m3s += stats.hypervolume_m3s;
    t.vanishing += stats.vanishing_slabs;
}

/// A body's window to prepare (body id, window) and the partners it serves.
type Need<'a> = (&'a str, &'a WindowSpec, Partner);

/// Each distinct body window of `needs` once (the same body, the same window), with the
/// partners of all its needs together ([`Partner::union`]): one preparation serves them all.
fn shared_partners<'a>(needs: impl Iterator<Item = Need<'a>>) -> Vec<Need<'a>> {
    let mut distinct: Vec<Need> = Vec::new();
    for (id, w, partner) in needs {
        match distinct
            .iter_mut()
            .find(|(d, x, _)| *d == id && x.same_as(w))
        {
            Some((_, _, p)) => *p = p.union(&partner),
            None => distinct.push((id, w, partner)),
        }
    }
    distinct
}
