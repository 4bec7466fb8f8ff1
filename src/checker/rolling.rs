//! The rolling checker: the planned pairs of bodies checked frame period by frame period as
//! their mesh pieces arrive, with memory bounded by a window instead of the history.
//!
//! Each body's stream comes as the mesher's pieces (first cap, one lateral slab per frame
//! period, last cap) and, for the overlap measure and the windows' artificial caps, its
//! decoded frames. For each pair, the frame period starting at stamp `s` is checked as soon
//! as both bodies' slabs for it are in, with what follows each of them (the next slab, or
//! the last cap): see [`window`](super::window) for why one slab closed by two caps gives
//! exactly the labels and crossings of the full check. What a period gives (labels of its
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

use super::window::{
    check_window, prepare_window, PreparedWindow, TakenLabels, WindowBody, WindowResult,
};
use super::{check_pair, CommonLattice, PairResult};
use super::{origin_offset, CHECKER_FACTOR};
use crate::kernel::float::tet_normal as float_normal;
use crate::mesh::glue::BodyMesh;
use crate::mesh::march::Welder;
use crate::mesh::stats::{LateralRef, StatsAccumulator};
use crate::mesh::{CapSide, GridGeometry, Mesher, MesherOptions, OccupancyGrid, TetMesh};
use crate::checker::pipeline::{resolve, CheckPlan};
use crate::checker::report::{
    BodyReport, PairLabels, PairReport, Report, Resolution, Timings,
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
    /// Report each slab's labels ([`RollOut::Labels`]).
    pub labels: bool,
    /// Report each slab when every pair has labelled it ([`RollOut::SlabDone`], for
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
pub struct PieceIn {
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
    /// The body vanishes between the slab's frames.
    pub vanishes: bool,
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
pub enum RollOut {
    /// A slab's labels against one other body.
    Labels(SlabLabels),
    /// A slab labelled by every pair.
    SlabDone(SlabDone),
    /// A contact began, went on or ended.
    Contact(ContactUpdate),
    /// A contact episode of a movable body was resolved (the report's resolutions grew).
    Resolved,
    /// Something in the input was wrong or lost (kind, text).
    Problem(&'static str, String),
}

#[derive(Debug)]
struct RSlab {
    run: u64,
    index: u32,
    hi: i64,
    mesh: Arc<TetMesh>,
    /// Number of the slab's first tet in the body's run (first cap, slabs, last cap).
    first_tet: u64,
    /// Strongest label per tet over the pairs so far (if slabs are reported).
    worst: Vec<u8>,
}

#[derive(Debug)]
struct Run {
    id: u64,
    geometry: GridGeometry,
    first_stamp: i64,
    first_cap: Arc<TetMesh>,
    first_occupied: u64,
    /// Stamp of the latest frame (the last slab's upper one).
    frontier: i64,
    next_index: u32,
    /// The closing cap came (stamp, cap), or the run was closed without one.
    end: Option<RunEnd>,
    tets: u64,
    acc: StatsAccumulator,
    /// The run's statistics, once it ended.
    stats: Option<crate::mesh::stats::BodyStats>,
}

impl Run {
    /// The run's figures without its meshes (for the report).
    fn clone_summary(&self) -> Run {
        Run {
            id: self.id,
            geometry: self.geometry,
            first_stamp: self.first_stamp,
            first_cap: self.first_cap.clone(),
            first_occupied: self.first_occupied,
            frontier: self.frontier,
            next_index: self.next_index,
            end: self.end.clone(),
            tets: self.tets,
            acc: StatsAccumulator::new(),
            stats: self.stats.clone(),
        }
    }

    /// Ends the run at its latest frame, with its closing cap if one came.
    fn close(&mut self, cap: Option<(Arc<TetMesh>, u64)>) {
        if self.end.is_some() {
            return;
        }
        let acc = std::mem::take(&mut self.acc);
        let last = cap.as_ref().map(|(c, o)| (c.as_ref(), *o));
        let frames = u64::from(self.next_index) + 1;
        self.stats = Some(acc.finish(
            frames,
            Some((self.first_cap.as_ref(), self.first_occupied)),
            last,
        ));
        self.end = Some((self.frontier, cap));
    }

    fn ended(&self) -> bool {
        self.end.is_some()
    }
    fn last_cap_at(&self, stamp: i64) -> Option<&Arc<TetMesh>> {
        match &self.end {
            Some((s, Some((cap, _)))) if *s == stamp => Some(cap),
            _ => None,
        }
    }
}

/// Cumulative figures of a body's finished runs.
#[derive(Debug, Default, Clone)]
struct Totals {
    frames: u64,
    tets: u64,
    vertices: u64,
    hypervolume_m3s: f64,
    vanishing: u64,
    closed: bool,
    runs: u64,
}

/// How a run ended: the stamp of its last frame, and its last cap with its occupied voxels
/// (`None`: closed without one).
type RunEnd = (i64, Option<(Arc<TetMesh>, u64)>);

#[derive(Debug, Default)]
struct BodyStream {
    runs: Vec<Run>,
    next_run: u64,
    slabs: BTreeMap<i64, RSlab>,
    frames: BTreeMap<i64, KeptGrid>,
    totals: Totals,
    /// The lattice of its latest stream.
    geometry: Option<GridGeometry>,
    joined_late: bool,
    /// Pairs it is in.
    pairs: usize,
    /// End stamp of the latest slab dropped for `max_horizon_tets` (0: none).
    horizon_cut_until: i64,
    /// `header.frame_id` of its latest piece.
    frame_id: String,
}

/// Default of [`RollingConfig::max_frame_bytes`]: 1 GiB of decoded frames per body.
pub const DEFAULT_MAX_FRAME_BYTES: u64 = 1 << 30;

/// A decoded frame of a body and the lattice it came on.
#[derive(Debug, Clone)]
struct KeptGrid {
    geometry: GridGeometry,
    grid: Arc<OccupancyGrid>,
}

impl BodyStream {
    /// The body's frame at `stamp` on lattice `g`, as its mesher accepted it: the frame
    /// received there if it is on `g`; otherwise (a frame the mesher filled in, the received
    /// one refused) the union of the nearest frames on `g` around it, which is what the mesher
    /// filled the gap with.
    fn frame_at(&self, stamp: i64, g: &GridGeometry) -> Option<Arc<OccupancyGrid>> {
        if let Some(k) = self.frames.get(&stamp) {
            if k.geometry == *g {
                return Some(k.grid.clone());
            }
        }
        let below = self
            .frames
            .range(..stamp)
            .rev()
            .find(|(_, k)| k.geometry == *g)?;
        let above = self
            .frames
            .range(stamp + 1..)
            .find(|(_, k)| k.geometry == *g)?;
        below.1.grid.union(&above.1.grid).map(Arc::new)
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
    t: (f64, f64),
    tets: (u64, u64),
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
    index: u64,
}

#[derive(Debug, Default)]
struct Overlap {
    /// Overlap and bound of the runs of periods closed by a gap (see `overlap_push`).
    closed: (f64, f64),
    mesher: Option<Mesher>,
    acc: StatsAccumulator,
    first_cap: Option<TetMesh>,
    sums: (f64, f64),
    last_pushed: Option<i64>,
    stamps: (i64, i64, u64),
    unknown: bool,
    geometry: Option<GridGeometry>,
}

#[derive(Debug)]
struct PairRoll {
    a: String,
    b: String,
    /// Stamp of the next period to decide.
    next: Option<i64>,
    /// Common frame index of `next`, and of the time origin of the checker coordinates.
    index: i64,
    base: i64,
    /// Stamps of recent common frame indices.
    stamps: BTreeMap<i64, i64>,
    counts: (LabelCounts, LabelCounts),
    candidates: u64,
    crossings: u64,
    intervals: VecDeque<Interval>,
    dropped_intervals: u64,
    open: Option<Interval>,
    contacts: u64,
    records: VecDeque<Record>,
    overlap: Overlap,
    stopped: Option<String>,
    /// Steps per frame period of the pair's lattice (0 until the first window).
    per: i64,
    /// Spent any window: the pair is in the report.
    checked: bool,
    undecided: u64,
    /// Said once per absence that the partner is late.
    partner_absent: bool,
}

/// The rolling checker of a set of pairs.
#[derive(Debug)]
pub struct RollingChecker {
    cfg: RollingConfig,
    opts: MesherOptions,
    plan: CheckPlan,
    bodies: BTreeMap<String, BodyStream>,
    pairs: Vec<PairRoll>,
    origin_ns: Option<i64>,
    union: UnionStamps,
    finishing: bool,
    /// Problems for the report.
    problems: Vec<String>,
    dropped_problems: u64,
    /// Per movable body: contacts ending before this (s) are resolved.
    resolved_until: BTreeMap<String, f64>,
    resolutions: VecDeque<Resolution>,
    dropped_resolutions: u64,
    /// Windows checked ahead, in parallel, at the start of a pump (see [`Prefetched`]).
    prefetched: Vec<Prefetched>,
    /// Per body, its latest prepared window (one per body at most): a body in several pairs
    /// has the same window in each, prepared once.
    prepared: BTreeMap<String, (WindowSpec, Arc<PreparedWindow>)>,
    /// The lateral piece just accepted still has to be added to its run's statistics
    /// (run id, and the run's first cap if the piece is its first slab): done while the
    /// windows it makes ready are checked.
    pending_stats: Option<(u64, Option<Arc<TetMesh>>)>,
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
                    stopped: None,
                    per: 0,
                    checked: false,
                    undecided: 0,
                    partner_absent: false,
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
            pending_stats: None,
        }
    }

    /// The bodies of the checked pairs.
    pub fn bodies(&self) -> impl Iterator<Item = &str> {
        self.bodies.keys().map(String::as_str)
    }

    fn problem(&mut self, out: &mut Vec<RollOut>, kind: &'static str, text: String) {
        if self.problems.len() < KEPT_PROBLEMS {
            self.problems.push(text.clone());
        } else {
            self.dropped_problems += 1;
        }
        out.push(RollOut::Problem(kind, text));
    }

    /// A decoded frame of a body (for the overlap and the windows' caps).
    pub fn on_frame(
        &mut self,
        body: &str,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: OccupancyGrid,
        out: &mut Vec<RollOut>,
    ) {
        let Some(b) = self.bodies.get_mut(body) else {
            return;
        };
        // The first frame at a stamp is the one a mesher keeps (a repeated stamp is refused).
        b.frames.entry(stamp_ns).or_insert(KeptGrid {
            geometry,
            grid: Arc::new(grid),
        });
        self.pump(out);
    }

    /// Also reports `body`, which is in no pair (a lone body): its pieces are taken for its
    /// figures and dropped as they come.
    pub fn track_body(&mut self, body: &str) {
        self.bodies.entry(body.to_owned()).or_default();
    }

    /// One mesh piece of a body.
    pub fn on_piece(&mut self, p: PieceIn, out: &mut Vec<RollOut>) {
        if !self.bodies.contains_key(&p.body) {
            return;
        }
        self.pending_stats = None;
        if let Err((kind, text)) = self.accept(&p) {
            self.problem(out, kind, text);
        }
        let Some((run, first_cap)) = self.pending_stats.take() else {
            self.pump(out);
            return;
        };
        // The body's statistics of the piece (closedness, hypervolume) and the windows it
        // makes ready are independent: both at once.
        let acc = self
            .bodies
            .get_mut(&p.body)
            .and_then(|b| b.runs.iter_mut().find(|r| r.id == run))
            .map(|r| std::mem::take(&mut r.acc));
        let Some(mut acc) = acc else {
            self.pump(out);
            return;
        };
        let lateral = LateralRef {
            index: u64::from(p.index),
            stamps_ns: p.stamps_ns,
            geometry: &p.geometry,
            mesh: &p.mesh,
            vanishes: p.vanishes,
        };
        let (_, ahead) = rayon::join(
            || acc.add_lateral(lateral, first_cap.as_deref()),
            || self.prefetch(1),
        );
        if let Some(r) = self
            .bodies
            .get_mut(&p.body)
            .and_then(|b| b.runs.iter_mut().find(|r| r.id == run))
        {
            r.acc = acc;
        }
        self.prefetched = ahead;
        self.pump_prefetched(out);
    }

    fn accept(&mut self, p: &PieceIn) -> Result<(), (&'static str, String)> {
        let id = p.body.clone();
        // What a window relies on: a lattice step that is a power of two (so two bodies'
        // lattices map onto their common one exactly), and tets that name their vertices.
        let scale = p.geometry.scale;
        if scale < 1 || scale.count_ones() != 1 {
            return Err((
                "bad_piece",
                format!(
                    "{id}: a piece with lattice scale {scale} (a power of two is needed); ignored"
                ),
            ));
        }
        let nv = p.mesh.vertices.len();
        if let Some(t) = p
            .mesh
            .tets
            .iter()
            .position(|t| t.iter().any(|&v| v as usize >= nv))
        {
            return Err((
                "bad_piece",
                format!("{id}: tet {t} of a piece names a vertex past its {nv}; ignored"),
            ));
        }
        let origin = &mut self.origin_ns;
        let union = &mut self.union;
        let b = self.bodies.get_mut(&id).expect("checked above");
        if b.frame_id != p.frame_id {
            b.frame_id.clone_from(&p.frame_id);
        }
        match p.kind {
            PieceKind::CapStart => {
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
                    return Err((
                        "bad_piece",
                        format!(
                            "{id}: a stream starting at {} ns, not after the previous one's last \
                             frame; ignored",
                            p.stamps_ns.0
                        ),
                    ));
                }
                let run = Run {
                    id: b.next_run,
                    geometry: p.geometry,
                    first_stamp: p.stamps_ns.0,
                    first_cap: p.mesh.clone(),
                    first_occupied: p.occupied,
                    frontier: p.stamps_ns.0,
                    next_index: 0,
                    end: None,
                    tets: p.mesh.tets.len() as u64,
                    acc: StatsAccumulator::new(),
                    stats: None,
                };
                b.next_run += 1;
                b.joined_late = false;
                b.geometry = Some(p.geometry);
                b.runs.push(run);
                *origin = Some(origin.map_or(p.stamps_ns.0, |o: i64| o.min(p.stamps_ns.0)));
                union.add(p.stamps_ns.0);
                if let Some(why) = restarted {
                    return Err(("stream_restarted", why));
                }
                Ok(())
            }
            PieceKind::Lateral | PieceKind::CapEnd => {
                let Some(r) = b.runs.last_mut().filter(|r| !r.ended()) else {
                    if b.joined_late {
                        return Ok(());
                    }
                    b.joined_late = true;
                    return Err((
                        "joined_mid_stream",
                        format!(
                            "{id}: the first piece seen is index {} (this node started after the \
                             body's stream did, or missed its start): the pieces before are gone, \
                             so this stream of the body is skipped; it is checked from its next \
                             stream",
                            p.index
                        ),
                    ));
                };
                if p.geometry != r.geometry {
                    return Err((
                        "bad_piece",
                        format!("{id}: a piece on another lattice; ignored"),
                    ));
                }
                if p.kind == PieceKind::CapEnd {
                    if r.next_index == 0 || p.index != r.next_index {
                        return Err((
                            "piece_out_of_order",
                            format!(
                                "{id}: closing cap at index {} (expected index {}); ignored",
                                p.index, r.next_index
                            ),
                        ));
                    }
                    r.tets += p.mesh.tets.len() as u64;
                    r.close(Some((p.mesh.clone(), p.occupied)));
                    return Ok(());
                }
                if p.index != r.next_index
                    || p.stamps_ns.0 != r.frontier
                    || p.stamps_ns.1 <= p.stamps_ns.0
                {
                    return Err((
                        "piece_out_of_order",
                        format!(
                            "{id}: piece index {} out of order (expected index {}); ignored, the \
                             body's mesh will not be closed",
                            p.index, r.next_index
                        ),
                    ));
                }
                // Added to the run's statistics by `on_piece`, while windows are checked.
                self.pending_stats = Some((r.id, (r.next_index == 0).then(|| r.first_cap.clone())));
                let first_tet = r.tets;
                r.tets += p.mesh.tets.len() as u64;
                r.next_index += 1;
                r.frontier = p.stamps_ns.1;
                union.add(p.stamps_ns.1);
                let worst = if self.cfg.slabs_done {
                    vec![0; p.mesh.tets.len()]
                } else {
                    Vec::new()
                };
                b.slabs.insert(
                    p.stamps_ns.0,
                    RSlab {
                        run: r.id,
                        index: p.index,
                        hi: p.stamps_ns.1,
                        mesh: p.mesh.clone(),
                        first_tet,
                        worst,
                    },
                );
                Ok(())
            }
        }
    }

    /// The inputs have ended: every open stream is closed at its last slab, every period
    /// decided with what there is, every open contact closed.
    pub fn finish(&mut self, out: &mut Vec<RollOut>) {
        self.finishing = true;
        for b in self.bodies.values_mut() {
            if let Some(r) = b.runs.last_mut() {
                r.close(None);
            }
        }
        self.pump(out);
        for i in 0..self.pairs.len() {
            self.close_open(i, out);
            self.finish_speeds(i, true);
        }
        self.prune(out);
    }

    /// Decides every period that can be decided, then drops what nothing needs any more.
    fn pump(&mut self, out: &mut Vec<RollOut>) {
        self.prefetched = self.prefetch(2);
        self.pump_prefetched(out);
    }

    /// [`Self::pump`] with the windows checked ahead already in `self.prefetched`.
    fn pump_prefetched(&mut self, out: &mut Vec<RollOut>) {
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
    /// slab at the next stamp and what follows it, on one lattice and in one frame. Anything
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
        let (sa, sb) = (a.slabs.get(&s)?, b.slabs.get(&s)?);
        let hi = sa.hi;
        let known = |body: &BodyStream, run: u64| {
            body.slabs.contains_key(&hi) || body.run(run).is_some_and(|r| r.ended())
        };
        if sb.hi != hi || !known(a, sa.run) || !known(b, sb.run) || a.frame_id != b.frame_id {
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
        let wa = self.window_spec(
            &p.a,
            &p.b,
            s,
            k,
            (base, per),
            (lattice.shift_a, lattice.ratio_a),
        )?;
        let wb = self.window_spec(
            &p.b,
            &p.a,
            s,
            k,
            (base, per),
            (lattice.shift_b, lattice.ratio_b),
        )?;
        (!apart(&wa, &wb)).then_some((s, wa, wb))
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
        ready
            .into_par_iter()
            .map(|(i, s, wa, wb)| {
                let p = &self.pairs[i];
                let result = check_specs((&p.a, &wa), (&p.b, &wb), &self.prepared);
                Prefetched {
                    pair: i,
                    s,
                    specs: (wa, wb),
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
    fn step(&mut self, i: usize, out: &mut Vec<RollOut>) -> bool {
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

    fn seconds_of_stamp(&self, s: i64) -> f64 {
        (s - self.origin_ns.unwrap_or(s)) as f64 * 1e-9
    }

    /// The slab of `body` at `s` is decided for pair `i` without the other body: OUTSIDE.
    fn alone(&mut self, i: usize, body: &str, s: i64, out: &mut Vec<RollOut>) {
        let (hi, index, run, lateral) = {
            let sl = &self.bodies[body].slabs[&s];
            (sl.hi, sl.index, sl.run, sl.mesh.tets.len())
        };
        if self.cfg.labels {
            let b = &self.bodies[body];
            let r = b.run(run);
            let cap_start = r
                .filter(|r| r.first_stamp == s)
                .map(|r| r.first_cap.tets.len());
            let cap_end = r.and_then(|r| r.last_cap_at(hi)).map(|c| c.tets.len());
            let n = cap_start.unwrap_or(0) + lateral + cap_end.unwrap_or(0);
            let p = &self.pairs[i];
            let other = if p.a == body { &p.b } else { &p.a };
            out.push(RollOut::Labels(SlabLabels {
                body: body.to_string(),
                other: other.clone(),
                index,
                stamps_ns: (s, hi),
                with_cap_start: cap_start.is_some(),
                with_cap_end: cap_end.is_some(),
                labels: vec![Label::Outside as u8; n],
                counts: LabelCounts {
                    outside: n as u64,
                    ..LabelCounts::default()
                },
            }));
        }
        let k = self.period_index(i, s);
        self.advance(i, s, hi, k, out);
    }

    /// Moves pair `i` past the period [s, hi] of common index `k`.
    fn advance(&mut self, i: usize, s: i64, hi: i64, k: i64, out: &mut Vec<RollOut>) {
        let p = &mut self.pairs[i];
        p.stamps.insert(k, s);
        p.stamps.insert(k + 1, hi);
        p.next = Some(hi);
        p.index = k + 1;
        while p
            .stamps
            .first_key_value()
            .is_some_and(|(j, _)| *j < k - CONTEXT_SLABS as i64)
        {
            p.stamps.pop_first();
        }
        // Nothing later can start before the end of this period, and nothing goes on past
        // it where either body's stream ends there.
        let hi_t = ((k + 1 - p.base) * p.per) as f64;
        let before_end = p.open.as_ref().is_some_and(|o| o.t.1 < hi_t);
        let (a, b) = (p.a.clone(), p.b.clone());
        let ends_here = |id: &str| {
            let body = &self.bodies[id];
            body.slabs
                .get(&s)
                .and_then(|x| body.run(x.run))
                .is_some_and(|r| r.last_cap_at(hi).is_some())
        };
        if before_end || ends_here(&a) || ends_here(&b) {
            self.close_open(i, out);
        }
        self.finish_speeds(i, false);
    }

    /// What one body's window is made of (owned, so that the pair can be changed while it
    /// is checked).
    fn window_spec(
        &self,
        me: &str,
        other: &str,
        s: i64,
        k: i64,
        (base, per): (i64, i64),
        (shift, ratio): ([i64; 3], i64),
    ) -> Option<WindowSpec> {
        let body = &self.bodies[me];
        let centre_slab = body.slabs.get(&s)?;
        let r = body.run(centre_slab.run)?;
        let o = self.bodies[other].run(self.bodies[other].slabs.get(&s)?.run)?;
        let hi = centre_slab.hi;
        let prev = |stamp: i64| {
            body.slabs
                .range(..stamp)
                .next_back()
                .filter(|(_, x)| x.hi == stamp && x.run == r.id)
                .map(|(key, x)| (*key, x))
        };
        let mut slabs: VecDeque<(i64, &RSlab)> = VecDeque::from([(s, centre_slab)]);
        let mut centre = 0;
        let mut lo_stamp = s;
        let mut hi_stamp = hi;
        // The other body's real cap in an end plane: reach one slab further.
        if o.first_stamp == s {
            if let Some(x) = prev(s) {
                slabs.push_front(x);
                centre += 1;
                lo_stamp = x.0;
            }
        }
        if o.last_cap_at(hi).is_some() {
            if let Some(x) = body.slabs.get(&hi).filter(|x| x.run == r.id) {
                slabs.push_back((hi, x));
                hi_stamp = x.hi;
            }
        }
        let low = (r.first_stamp == lo_stamp).then(|| r.first_cap.clone());
        let high = r.last_cap_at(hi_stamp).cloned();
        let lo_common = k - centre as i64;
        Some(WindowSpec {
            geometry: r.geometry,
            lo: slabs[0].1.index,
            slabs: slabs.iter().map(|(_, x)| x.mesh.clone()).collect(),
            centre,
            low,
            high,
            mul: ratio,
            add: [
                shift[0] * per,
                shift[1] * per,
                shift[2] * per,
                (lo_common - base) * per,
            ],
            first_tet: if r.first_stamp == s {
                0
            } else {
                centre_slab.first_tet
            },
        })
    }

    /// Checks the period of pair `i` starting at `s` where both bodies have a slab; `false`
    /// if it must wait for what follows a slab or for a frame.
    fn window(&mut self, i: usize, s: i64, out: &mut Vec<RollOut>) -> bool {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let (hi, hb) = (self.bodies[&a].slabs[&s].hi, self.bodies[&b].slabs[&s].hi);
        if hi != hb {
            let why = format!(
                "pair {a} x {b}: frames at different times (the periods from {:.3} s end at \
                 {:.3} s and {:.3} s); the pair is not checked from there on",
                self.seconds_of_stamp(s),
                self.seconds_of_stamp(hi),
                self.seconds_of_stamp(hb)
            );
            self.pairs[i].stopped = Some(why.clone());
            self.problem(out, "time_mismatch", why);
            return false;
        }
        // What follows each slab must be known: the next slab, or the end of its stream.
        let known = |me: &Self, id: &str| {
            let body = &me.bodies[id];
            body.slabs.contains_key(&hi) || body.run(body.slabs[&s].run).is_some_and(|r| r.ended())
        };
        if !known(self, &a) || !known(self, &b) {
            // Nothing follows a slab while the other body runs far ahead: the stream stalled
            // (a lost piece or cap). Its run is closed there, so that the pair goes on and
            // the other body's slabs do not pile up.
            if self.lead(&a, s).max(self.lead(&b, s)) <= self.cfg.max_lead_frames {
                return false;
            }
            for id in [&a, &b] {
                if known(self, id) {
                    continue;
                }
                let why = format!(
                    "{id}: nothing follows its slab at {:.3} s while its partner is more than \
                     {} slabs ahead (a lost piece or cap); its stream is taken as ended there",
                    self.seconds_of_stamp(s),
                    self.cfg.max_lead_frames
                );
                let body = self.bodies.get_mut(id.as_str()).expect("a paired body");
                let run = body.slabs[&s].run;
                if let Some(r) = body.runs.iter_mut().find(|r| r.id == run) {
                    r.close(None);
                }
                self.problem(out, "stream_stalled", why);
            }
            if !known(self, &a) || !known(self, &b) {
                return false;
            }
        }
        let geometry = |id: &str| {
            let body = &self.bodies[id];
            body.run(body.slabs[&s].run).map(|r| r.geometry)
        };
        let (Some(ga), Some(gb)) = (geometry(&a), geometry(&b)) else {
            return false;
        };
        let (fa, fb) = (&self.bodies[&a].frame_id, &self.bodies[&b].frame_id);
        if fa != fb {
            let why = format!(
                "pair {a} x {b}: not checked: {a} is in frame {fa:?} and {b} in frame {fb:?}: \
                 bodies in different frames are not compared (publish them in one frame)"
            );
            self.pairs[i].stopped = Some(why.clone());
            self.problem(out, "frame_mismatch", why);
            return false;
        }
        let lattice = match pair_lattice(&ga, &gb) {
            Ok(l) => l,
            Err(reason) => {
                let why = format!(
                    "pair {a} x {b}: not on one lattice ({reason}); the pair is not checked from \
                     there on"
                );
                self.pairs[i].stopped = Some(why.clone());
                self.problem(out, "lattice_mismatch", why);
                return false;
            }
        };
        let k = self.period_index(i, s);
        let per = i64::from(lattice.scale) * i64::from(CHECKER_FACTOR);
        let base = {
            let p = &self.pairs[i];
            if k - p.base > REBASE_FRAMES {
                k - CONTEXT_SLABS as i64
            } else {
                p.base
            }
        };
        let specs = (
            self.window_spec(
                &a,
                &b,
                s,
                k,
                (base, per),
                (lattice.shift_a, lattice.ratio_a),
            ),
            self.window_spec(
                &b,
                &a,
                s,
                k,
                (base, per),
                (lattice.shift_b, lattice.ratio_b),
            ),
        );
        self.rebase(i, base, per);
        let (Some(wa), Some(wb)) = specs else {
            // A frame for a cap has not come (yet).
            let behind = self.lead(&a, s).max(self.lead(&b, s)) > self.cfg.max_lead_frames;
            if !self.finishing && !behind {
                return false;
            }
            let why = format!(
                "pair {a} x {b}: no frame to close the period {:.3}-{:.3} s (a frame the mesher \
                 filled in, or one that never came); that period is not checked",
                self.seconds_of_stamp(s),
                self.seconds_of_stamp(hi)
            );
            self.problem(out, "period_unchecked", why);
            self.pairs[i].overlap.unknown = true;
            self.advance(i, s, hi, k, out);
            return true;
        };
        let r = if apart(&wa, &wb) {
            // Boxes apart in space: no tet meets the other body, every one is outside.
            WindowResult {
                labels: [wa.all_outside(), wb.all_outside()],
                ..WindowResult::default()
            }
        } else {
            let ahead = self.prefetched.iter().position(|x| {
                x.pair == i && x.s == s && x.specs.0.same_as(&wa) && x.specs.1.same_as(&wb)
            });
            let result = match ahead {
                Some(n) => self.prefetched.swap_remove(n).result,
                None => check_specs((&a, &wa), (&b, &wb), &self.prepared),
            };
            match result {
                Ok((r, [pa, pb])) => {
                    self.prepared.insert(a.clone(), (wa.clone(), pa));
                    self.prepared.insert(b.clone(), (wb.clone(), pb));
                    r
                }
                Err(e) => {
                    let why = format!(
                        "pair {a} x {b}: the period {:.3}-{:.3} s cannot be checked: {e}",
                        self.seconds_of_stamp(s),
                        self.seconds_of_stamp(hi)
                    );
                    self.problem(out, "period_unchecked", why);
                    self.advance(i, s, hi, k, out);
                    return true;
                }
            }
        };
        self.overlap_push(i, s, hi);
        {
            let p = &mut self.pairs[i];
            p.stamps.insert(k, s);
            p.stamps.insert(k + 1, hi);
        }
        self.fold(i, s, hi, &r, (wa.first_tet, wb.first_tet), out);
        self.advance(i, s, hi, k, out);
        true
    }

    /// Moves pair `i`'s checker-time origin to common frame `base` (the crossings and the
    /// open interval kept shift with it) and sets its lattice step.
    fn rebase(&mut self, i: usize, base: i64, per: i64) {
        let p = &mut self.pairs[i];
        if base != p.base {
            let d = ((base - p.base) * p.per) as f64;
            for r in &mut p.records {
                r.t = (r.t.0 - d, r.t.1 - d);
            }
            if let Some(o) = &mut p.open {
                o.t = (o.t.0 - d, o.t.1 - d);
            }
            for o in &mut p.intervals {
                o.t = (o.t.0 - d, o.t.1 - d);
            }
            p.base = base;
        }
        p.per = per;
    }

    /// Folds a window's result into pair `i`'s answer.
    fn fold(
        &mut self,
        i: usize,
        s: i64,
        hi: i64,
        r: &WindowResult,
        starts: (u64, u64),
        out: &mut Vec<RollOut>,
    ) {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        {
            let p = &mut self.pairs[i];
            p.checked = true;
            p.partner_absent = false;
            p.candidates += r.candidate_pairs;
            p.crossings += r.crossings.len() as u64;
            p.undecided += u64::from(r.undecided);
            for (c, l) in [
                (&mut p.counts.0, &r.labels[0]),
                (&mut p.counts.1, &r.labels[1]),
            ] {
                c.interference += l.counts.interference;
                c.inside += l.counts.inside;
            }
            for c in &r.crossings {
                p.records.push_back(Record {
                    t: c.t,
                    tets: (
                        starts.0 + u64::from(c.tets.0),
                        starts.1 + u64::from(c.tets.1),
                    ),
                    normals: c.normals,
                });
            }
        }
        for (k, (me, other)) in [(&a, &b), (&b, &a)].into_iter().enumerate() {
            let l = &r.labels[k];
            if self.cfg.labels {
                let index = self.bodies[me].slabs[&s].index;
                out.push(RollOut::Labels(SlabLabels {
                    body: me.clone(),
                    other: other.clone(),
                    index,
                    stamps_ns: (s, hi),
                    with_cap_start: l.pieces[0] > 0,
                    with_cap_end: l.pieces[2] > 0,
                    labels: l.labels.clone(),
                    counts: l.counts,
                }));
            }
            if self.cfg.slabs_done {
                let lateral = &l.labels[l.pieces[0]..l.pieces[0] + l.pieces[1]];
                if let Some(sl) = self
                    .bodies
                    .get_mut(me.as_str())
                    .and_then(|b| b.slabs.get_mut(&s))
                {
                    for (w, &x) in sl.worst.iter_mut().zip(lateral) {
                        *w = (*w).max(x);
                    }
                }
            }
        }
        // The window's ranges merged (so that a contact begins with all this period gives
        // it, whatever order the walk found them in), then in order: merged into the open
        // interval, or closing it and opening another.
        let mut ranges = r.ranges.clone();
        ranges.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)));
        let mut merged: Vec<(f64, f64)> = Vec::new();
        for (t0, t1) in ranges {
            match merged.last_mut() {
                Some(m) if t0 <= m.1 => m.1 = m.1.max(t1),
                _ => merged.push((t0, t1)),
            }
        }
        for (t0, t1) in merged {
            let merges = self.pairs[i].open.as_ref().is_some_and(|o| t0 <= o.t.1);
            if merges {
                let mut extended = false;
                if let Some(o) = &mut self.pairs[i].open {
                    if t1 > o.t.1 {
                        o.t.1 = t1;
                        extended = true;
                    }
                }
                if extended {
                    self.convert_open(i);
                    out.extend(self.update(i, ContactPhase::Ongoing, hi));
                }
                continue;
            }
            self.close_open(i, out);
            let p = &mut self.pairs[i];
            let index = p.contacts;
            p.contacts += 1;
            p.open = Some(Interval {
                t: (t0, t1),
                s: (0.0, 0.0),
                speeds: (None, None),
                periods: (0.0, 0.0),
                index,
            });
            self.convert_open(i);
            out.extend(self.update(i, ContactPhase::Begin, hi));
        }
    }

    /// Seconds and periods of the open interval's ends (the start once, when it opens).
    fn convert_open(&mut self, i: usize) {
        let origin = self.origin_ns.unwrap_or(0);
        let p = &mut self.pairs[i];
        let Some(mut o) = p.open.take() else { return };
        if o.periods.0 == 0.0 {
            if let Some(x) = time_at(p, o.t.0, origin) {
                o.s.0 = x.0;
                o.periods.0 = x.1;
            }
        }
        if let Some(y) = time_at(p, o.t.1, origin) {
            o.s.1 = y.0;
            o.periods.1 = y.1;
        }
        p.open = Some(o);
    }

    fn update(&self, i: usize, phase: ContactPhase, stamp_ns: i64) -> Option<RollOut> {
        let p = &self.pairs[i];
        let o = match phase {
            ContactPhase::End => p.intervals.back()?,
            _ => p.open.as_ref()?,
        };
        let bound = |speed: Option<Option<f64>>, period: f64| {
            bounds::contact_time_bound(period, speed.flatten())
        };
        Some(RollOut::Contact(ContactUpdate {
            a: p.a.clone(),
            b: p.b.clone(),
            phase,
            index: o.index,
            start_s: o.s.0,
            end_s: o.s.1,
            start_bound_s: bound(o.speeds.0, o.periods.0),
            end_bound_s: bound(o.speeds.1, o.periods.1),
            stamp_ns,
        }))
    }

    /// Closes pair `i`'s open interval (its end speed from the crossings near its end).
    fn close_open(&mut self, i: usize, out: &mut Vec<RollOut>) {
        let p = &mut self.pairs[i];
        let Some(mut o) = p.open.take() else { return };
        let per = p.per as f64;
        let end = o.t.1;
        o.speeds.1 = Some(
            speed(
                p.records
                    .iter()
                    .filter(|r| r.t.1 <= end && r.t.1 >= end - per),
            )
            .map(|v| -v),
        );
        let stamp = p.next.unwrap_or(0);
        p.intervals.push_back(o);
        if p.intervals.len() > self.cfg.max_intervals {
            p.intervals.pop_front();
            p.dropped_intervals += 1;
        }
        out.extend(self.update(i, ContactPhase::End, stamp));
    }

    /// Start speeds that can be decided: no crossing can start before the start plus one
    /// frame period any more (or the pair is done); crossings nothing needs are dropped.
    fn finish_speeds(&mut self, i: usize, all: bool) {
        let p = &mut self.pairs[i];
        let per = p.per as f64;
        let done_t = ((p.index - p.base) * p.per) as f64;
        let records = &p.records;
        let decide = |o: &mut Interval| {
            if o.speeds.0.is_none() && (all || o.t.0 + per < done_t) {
                o.speeds.0 = Some(speed(
                    records
                        .iter()
                        .filter(|r| r.t.0 >= o.t.0 && r.t.0 <= o.t.0 + per),
                ));
            }
        };
        for o in p.intervals.iter_mut().rev().take(4) {
            decide(o);
        }
        if let Some(o) = &mut p.open {
            decide(o);
        }
        let keep = done_t - 3.0 * per;
        let pending = p
            .intervals
            .iter()
            .rev()
            .take(4)
            .chain(p.open.iter())
            .filter(|o| o.speeds.0.is_none())
            .map(|o| o.t.0)
            .fold(f64::INFINITY, f64::min);
        while p
            .records
            .front()
            .is_some_and(|r| r.t.1 < keep && r.t.0 < pending)
        {
            p.records.pop_front();
        }
    }

    /// Feeds the intersection of the two bodies' frames at `s` and `hi` to the pair's
    /// overlap mesher.
    fn overlap_push(&mut self, i: usize, s: i64, hi: i64) {
        let (a, b) = (self.pairs[i].a.clone(), self.pairs[i].b.clone());
        let opts = self.opts;
        let geometry = |id: &str| {
            let body = &self.bodies[id];
            body.run(body.slabs[&s].run).map(|r| r.geometry)
        };
        let (ga, gb) = (geometry(&a), geometry(&b));
        // Periods left out since the last one (a partner absent or stopped): the intersection
        // stream has a gap there. Its run so far is closed and counted, and a new one starts.
        let gap = {
            let ov = &self.pairs[i].overlap;
            !ov.unknown && ov.last_pushed.is_some_and(|l| l != s)
        };
        if gap {
            let ov = &mut self.pairs[i].overlap;
            match run_overlap(ov) {
                Some((hv, b)) => {
                    ov.closed.0 += hv;
                    ov.closed.1 += b;
                    ov.mesher = None;
                    ov.acc = StatsAccumulator::default();
                    ov.first_cap = None;
                    ov.sums = (0.0, 0.0);
                    ov.last_pushed = None;
                    ov.stamps = (0, 0, 0);
                }
                None => ov.unknown = true,
            }
        }
        for stamp in [s, hi] {
            let ov = &self.pairs[i].overlap;
            if ov.unknown || ov.last_pushed.is_some_and(|l| l >= stamp) {
                continue;
            }
            let (Some(ga), Some(gb)) = (ga, gb) else {
                self.pairs[i].overlap.unknown = true;
                continue;
            };
            let (fa, fb) = (
                self.bodies[&a].frame_at(stamp, &ga),
                self.bodies[&b].frame_at(stamp, &gb),
            );
            let ov = &mut self.pairs[i].overlap;
            let (Some(fa), Some(fb)) = (fa, fb) else {
                ov.unknown = true;
                continue;
            };
            let Some((both, ga)) = crate::mesh::grid::intersect_across(&fa, &ga, &fb, &gb) else {
                ov.unknown = true;
                continue;
            };
            if ov.geometry.is_some_and(|g| g != ga) {
                ov.unknown = true;
                continue;
            }
            if ov.mesher.is_none() {
                match Mesher::new(opts) {
                    Ok(m) => ov.mesher = Some(m),
                    Err(_) => {
                        ov.unknown = true;
                        continue;
                    }
                }
            }
            let m = ov.mesher.as_mut().expect("set above");
            ov.geometry = Some(ga);
            match m.push_decoded(stamp, ga, both) {
                Ok(slab) => {
                    ov.last_pushed = Some(stamp);
                    ov.stamps = if ov.stamps.2 == 0 {
                        (stamp, stamp, 1)
                    } else {
                        (ov.stamps.0, stamp, ov.stamps.2 + 1)
                    };
                    if let Some(slab) = slab {
                        if slab.index == 0 {
                            let cap = m.first_frame().and_then(|k| m.cap(k, CapSide::Low));
                            if let Some(cap) = &cap {
                                ov.sums = add_normals(ov.sums, cap);
                            }
                            ov.first_cap = cap;
                        }
                        ov.acc
                            .add_lateral(slab.lateral_ref(), ov.first_cap.as_ref());
                        ov.sums = add_normals(ov.sums, &slab.mesh);
                    }
                }
                Err(_) => ov.unknown = true,
            }
        }
    }

    /// Resolves the contact episodes of the movable bodies that are complete: no contact of
    /// their pairs can join them any more (or the inputs ended).
    fn resolve_episodes(&mut self, out: &mut Vec<RollOut>) {
        let movable: Vec<String> = self.resolved_until.keys().cloned().collect();
        for m in movable {
            while let Some(ep) = self.next_episode(&m) {
                let until = self.resolved_until[&m];
                self.resolve_episode(&m, ep, out);
                // Every episode moves the resolved time on; one that cannot (an empty
                // episode) ends the loop rather than repeat itself.
                if self.resolved_until[&m] <= until {
                    break;
                }
            }
        }
    }

    /// Pairs of body `m`, in the report's order.
    fn pairs_of(&self, m: &str) -> Vec<usize> {
        (0..self.pairs.len())
            .filter(|&i| self.pairs[i].a == m || self.pairs[i].b == m)
            .collect()
    }

    /// The earliest complete episode of `m` not resolved yet: its contacts merged when
    /// closer than two horizons, cut at `max_episode_s`.
    fn next_episode(&self, m: &str) -> Option<[f64; 2]> {
        let until = self.resolved_until[m];
        let h = self.cfg.horizon_s;
        let mut spans: Vec<[f64; 2]> = Vec::new();
        let mut decided = f64::INFINITY;
        for i in self.pairs_of(m) {
            let p = &self.pairs[i];
            let done = p
                .next
                .map_or(f64::NEG_INFINITY, |n| self.seconds_of_stamp(n));
            if p.stopped.is_none() {
                decided = decided.min(done);
            }
            for o in p.intervals.iter().rev().chain(p.open.iter()) {
                if o.s.1 > until || (o.s.1 == until && o.s.0 > until) {
                    spans.push([o.s.0.max(until), o.s.1]);
                }
            }
        }
        if self.finishing {
            decided = f64::INFINITY;
        }
        spans.sort_by(|x, y| x[0].total_cmp(&y[0]));
        let mut first = *spans.first()?;
        for s in &spans[1..] {
            if s[0] <= first[1] + 2.0 * h {
                first[1] = first[1].max(s[1]);
            } else {
                break;
            }
        }
        if first[1] - first[0] > self.cfg.max_episode_s {
            first[1] = first[0] + self.cfg.max_episode_s;
            return (decided >= first[1] + h).then_some(first);
        }
        (decided >= first[1] + 2.0 * h).then_some(first)
    }

    /// Builds the horizon bodies of `m` and its partners around `ep`, checks them, and
    /// suggests and verifies a translation and a time scaling of `m`.
    fn resolve_episode(&mut self, m: &str, ep: [f64; 2], out: &mut Vec<RollOut>) {
        self.resolved_until.insert(m.to_string(), ep[1]);
        let h = self.cfg.horizon_s;
        let origin = self.origin_ns.unwrap_or(0);
        let stamp = |s: f64| origin.saturating_add((s * 1e9).round() as i64);
        let (lo, hi) = (stamp(ep[0] - h), stamp(ep[1] + h));
        let pair_ids = self.pairs_of(m);
        let mut ids: Vec<String> = vec![m.to_string()];
        for &i in &pair_ids {
            let p = &self.pairs[i];
            ids.push(if p.a == m { p.b.clone() } else { p.a.clone() });
        }
        ids.sort();
        ids.dedup();
        // Where older slabs were dropped (max_horizon_tets), the horizon starts later.
        let cut_until = ids
            .iter()
            .filter_map(|id| self.bodies.get(id).map(|b| b.horizon_cut_until))
            .max()
            .unwrap_or(0);
        let lo_kept = lo.max(cut_until);
        let mut ep = ep;
        if lo_kept > lo {
            let from = self.seconds_of_stamp(lo_kept);
            let why = if from >= ep[1] {
                format!(
                    "{m}: the contact episode {:.3}-{:.3} s is not resolved: its slabs were \
                     dropped (resolve_max_tets {})",
                    ep[0], ep[1], self.cfg.max_horizon_tets
                )
            } else {
                format!(
                    "{m}: the contact episode {:.3}-{:.3} s is resolved over {from:.3}-{:.3} s \
                     only (older slabs were dropped: resolve_max_tets {})",
                    ep[0],
                    ep[1],
                    ep[1] + h,
                    self.cfg.max_horizon_tets
                )
            };
            self.problem(out, "resolution_horizon_cut", why);
            if from >= ep[1] {
                return;
            }
            ep[0] = ep[0].max(from);
        }
        let lo = lo_kept;
        let mut meshes: BTreeMap<String, BodyMesh> = BTreeMap::new();
        for id in &ids {
            if let Some(b) = self.horizon_body(id, lo, hi) {
                meshes.insert(id.clone(), b);
            }
        }
        if !meshes.contains_key(m) {
            return;
        }
        let named: Vec<(&str, &BodyMesh)> = meshes.iter().map(|(k, v)| (k.as_str(), v)).collect();
        let result = CommonLattice::of(&named).and_then(|lat| {
            // One body at a time: preparing them side by side saved 7 % of a periodic
            // replay's time for 15 % more peak memory.
            let prepared = named
                .iter()
                .map(|(id, b)| lat.prepare(id, b))
                .collect::<Result<Vec<_>, _>>()?;
            Ok((lat, prepared))
        });
        let (lat, prepared) = match result {
            Ok(x) => x,
            Err(e) => {
                let why = format!(
                    "{m}: the contact episode {:.3}-{:.3} s cannot be resolved: {e}",
                    ep[0], ep[1]
                );
                self.problem(out, "resolution_failed", why);
                return;
            }
        };
        let index = |id: &str| named.iter().position(|(k, _)| *k == id);
        let Some(im) = index(m) else { return };
        let mut others = Vec::new();
        let mut rs: Vec<PairResult> = Vec::new();
        for &i in &pair_ids {
            let p = &self.pairs[i];
            let (Some(ia), Some(ib)) = (index(&p.a), index(&p.b)) else {
                continue;
            };
            let r = check_pair(&prepared[ia], &prepared[ib]);
            if ia == im {
                others.push(&prepared[ib]);
                rs.push(r);
            } else {
                others.push(&prepared[ia]);
                rs.push(r.swapped());
            }
        }
        if !rs.iter().any(|r| r.interfering()) {
            return;
        }
        let resolution = prepared[im].geometry.resolution;
        let c = self
            .plan
            .time_scale
            .or_else(|| self.union.period_s().map(|p| resolution / p))
            .unwrap_or(resolution);
        let rs: Vec<&PairResult> = rs.iter().collect();
        let found = resolve(&prepared[im], &others, &rs, &lat, c, origin, ep);
        for r in found {
            self.resolutions.push_back(r);
            if self.resolutions.len() > self.cfg.max_resolutions {
                self.resolutions.pop_front();
                self.dropped_resolutions += 1;
            }
        }
        out.push(RollOut::Resolved);
    }

    /// Body `id` between stamps `lo` and `hi` as a closed mesh: its kept slabs there (of
    /// one run), closed by its own caps or caps from its frames.
    fn horizon_body(&self, id: &str, lo: i64, hi: i64) -> Option<BodyMesh> {
        let b = self.bodies.get(id)?;
        let mut slabs = b
            .slabs
            .range(lo..)
            .take_while(|(_, x)| x.hi <= hi)
            .peekable();
        let run_id = slabs.peek()?.1.run;
        let r = b.run(run_id)?;
        let mut chosen: Vec<(i64, &RSlab)> = Vec::new();
        for (s, x) in slabs {
            if x.run != run_id || chosen.last().is_some_and(|(_, p)| p.hi != *s) {
                break;
            }
            chosen.push((*s, x));
        }
        let (first_s, first) = *chosen.first()?;
        let last_hi = chosen.last()?.1.hi;
        let g = r.geometry;
        let shift = i64::from(g.scale) * i64::from(first.index);
        let shifted = |m: &TetMesh| -> Option<TetMesh> {
            let mut out = m.clone();
            for p in &mut out.vertices {
                p[3] = i32::try_from(i64::from(p[3]) - shift).ok()?;
            }
            Some(out)
        };
        let frame_cap = |stamp: i64, local: u32, side: CapSide| -> Option<TetMesh> {
            let f = b.frame_at(stamp, &g)?;
            let f = f.as_ref();
            let mut out = TetMesh::default();
            let at = crate::mesh::SlabPlacement {
                scale: g.scale,
                frame: i64::from(local),
                iso: self.opts.decode.iso_percent,
            };
            crate::mesh::march::march_cap(
                crate::mesh::table::table(),
                f,
                at,
                side,
                self.opts.max_slab_tets,
                &mut out,
            )
            .then_some(out)
        };
        let low = if r.first_stamp == first_s {
            shifted(&r.first_cap)?
        } else {
            frame_cap(first_s, 0, CapSide::Low)?
        };
        let high = match r.last_cap_at(last_hi) {
            Some(c) => shifted(c)?,
            None => frame_cap(last_hi, chosen.len() as u32, CapSide::High)?,
        };
        let mut body = BodyMesh {
            geometry: Some(g),
            ..BodyMesh::default()
        };
        let mut welder = Welder::default();
        let mut push = |part: &TetMesh, body: &mut BodyMesh| {
            body.pieces.push(body.mesh.tets.len());
            welder.append(&mut body.mesh, part);
        };
        push(&low, &mut body);
        body.stamps_ns.push(first_s);
        for (_, x) in &chosen {
            push(&shifted(&x.mesh)?, &mut body);
            body.stamps_ns.push(x.hi);
        }
        push(&high, &mut body);
        body.stats.frames = body.stamps_ns.len() as u64;
        Some(body)
    }

    /// Stamp (ns) before which nothing of body `id` is needed for resolutions: the start of
    /// a pending episode of a movable body it is paired with, less the horizon, or the
    /// horizon behind that body's decided time.
    fn horizon_keep(&self, id: &str) -> i64 {
        let h = self.cfg.horizon_s;
        let origin = self.origin_ns.unwrap_or(0);
        let mut keep = i64::MAX;
        for (m, &until) in &self.resolved_until {
            let related = m == id
                || self
                    .pairs
                    .iter()
                    .any(|p| (p.a == *m && p.b == id) || (p.b == *m && p.a == id));
            if !related {
                continue;
            }
            let mut from = f64::INFINITY;
            for i in self.pairs_of(m) {
                let p = &self.pairs[i];
                if p.stopped.is_some() {
                    continue;
                }
                let done = p
                    .next
                    .map_or(f64::NEG_INFINITY, |n| self.seconds_of_stamp(n));
                from = from.min(done);
                for o in p.intervals.iter().rev().chain(p.open.iter()) {
                    if o.s.1 > until {
                        from = from.min(o.s.0.max(until));
                    }
                }
            }
            if from.is_finite() {
                let s = origin.saturating_add(((from - h) * 1e9).floor() as i64);
                keep = keep.min(s);
            } else if from == f64::NEG_INFINITY {
                keep = i64::MIN;
            }
        }
        keep
    }

    /// Reports the slabs every pair has labelled, then drops the slabs and frames nothing
    /// needs any more.
    fn prune(&mut self, out: &mut Vec<RollOut>) {
        let keeps: BTreeMap<String, i64> = self
            .bodies
            .keys()
            .map(|id| (id.clone(), self.horizon_keep(id)))
            .collect();
        let pairs = &self.pairs;
        let finishing = self.finishing;
        let max_frames = self.cfg.max_lead_frames + 2 * CONTEXT_SLABS + 2;
        let mut oldest_of: BTreeMap<String, i64> = BTreeMap::new();
        for (id, b) in &mut self.bodies {
            // The oldest stamp a pair of this body has not decided.
            let oldest = pairs
                .iter()
                .filter(|p| (p.a == *id || p.b == *id) && p.stopped.is_none())
                .map(|p| p.next.unwrap_or(i64::MIN))
                .min()
                .unwrap_or(i64::MAX);
            if self.cfg.slabs_done {
                for (s, sl) in b.slabs.range_mut(..oldest) {
                    if sl.worst.is_empty() {
                        continue;
                    }
                    let worst = std::mem::take(&mut sl.worst);
                    if let Some(r) = b.runs.iter().find(|r| r.id == sl.run) {
                        out.push(RollOut::SlabDone(SlabDone {
                            body: id.clone(),
                            index: sl.index,
                            stamps_ns: (*s, sl.hi),
                            geometry: r.geometry,
                            mesh: sl.mesh.clone(),
                            worst,
                        }));
                    }
                }
            }
            oldest_of.insert(id.clone(), oldest);
            let decided = b.slabs.range(..oldest).count();
            let horizon = keeps.get(id).copied().unwrap_or(i64::MAX);
            for _ in 0..decided.saturating_sub(CONTEXT_SLABS) {
                if b.slabs
                    .first_key_value()
                    .is_some_and(|(_, x)| x.hi >= horizon)
                {
                    break;
                }
                b.slabs.pop_first();
            }
            let keep_from = b.slabs.keys().next().copied().unwrap_or(oldest).min(oldest);
            while b
                .frames
                .first_key_value()
                .is_some_and(|(s, _)| *s < keep_from)
            {
                b.frames.pop_first();
            }
            // Frames of a stream no piece has come for yet: only the latest ones.
            while b.frames.len() > max_frames + b.slabs.len() {
                b.frames.pop_first();
            }
            // And never more than `max_frame_bytes` of decoded frames per body (the oldest
            // go first; an overlap that needed one is then not measured, and says so).
            let mut bytes: u64 = b.frames.values().map(|k| k.grid.heap_bytes()).sum();
            while bytes > self.cfg.max_frame_bytes {
                let Some((_, k)) = b.frames.pop_first() else {
                    break;
                };
                bytes -= k.grid.heap_bytes();
            }
            // Finished runs none of whose slabs are kept: their figures go to the totals.
            while let Some(r) = b.runs.first() {
                let last = b.runs.len() == 1;
                let in_use = b.slabs.values().any(|s| s.run == r.id);
                if !r.ended() || in_use || (last && !finishing) {
                    break;
                }
                let r = b.runs.remove(0);
                add_run(&mut b.totals, r);
            }
        }
        self.cut_horizon(&oldest_of);
    }

    /// Drops the oldest slabs kept for resolutions alone (those before what every pair
    /// still needs, less [`CONTEXT_SLABS`]) while they hold more than
    /// [`RollingConfig::max_horizon_tets`] tets.
    fn cut_horizon(&mut self, oldest_of: &BTreeMap<String, i64>) {
        let only_horizon = |b: &BodyStream, oldest: i64| -> Vec<(i64, usize)> {
            let decided: Vec<(i64, usize)> = b
                .slabs
                .range(..oldest)
                .map(|(s, x)| (*s, x.mesh.tets.len()))
                .collect();
            let n = decided.len().saturating_sub(CONTEXT_SLABS);
            decided[..n].to_vec()
        };
        let mut kept: Vec<(i64, String, usize)> = Vec::new();
        for (id, b) in &self.bodies {
            let oldest = oldest_of.get(id).copied().unwrap_or(i64::MIN);
            kept.extend(
                only_horizon(b, oldest)
                    .into_iter()
                    .map(|(s, n)| (s, id.clone(), n)),
            );
        }
        let mut total: usize = kept.iter().map(|k| k.2).sum();
        if total <= self.cfg.max_horizon_tets {
            return;
        }
        kept.sort();
        for (s, id, n) in kept {
            if total <= self.cfg.max_horizon_tets {
                break;
            }
            if let Some(b) = self.bodies.get_mut(&id) {
                if let Some(x) = b.slabs.remove(&s) {
                    b.horizon_cut_until = b.horizon_cut_until.max(x.hi);
                }
                b.frames.remove(&s);
            }
            total -= n;
        }
    }

    /// The answer so far (CONTRACT.md's report): bodies, pairs, intervals, overlaps.
    pub fn report(&self) -> Report {
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
            .map(|p| pair_report(p, tets(&p.a), tets(&p.b), resolution))
            .collect();
        let unchecked_pairs = self
            .pairs
            .iter()
            .filter(|p| !p.checked)
            .filter_map(|p| {
                let why = p.stopped.as_ref()?;
                Some(crate::checker::report::UncheckedPair {
                    a: p.a.clone(),
                    b: p.b.clone(),
                    reason: why.clone(),
                })
            })
            .collect();
        Report {
            schema: "chronotope.report/1",
            time_origin_ns: origin,
            time_scale_m_per_s: c,
            bodies,
            pairs,
            resolutions: self.resolutions.iter().cloned().collect(),
            timings_ms: Timings::default(),
            problems,
            unchecked_pairs,
        }
    }
}

fn plan_movable(plan: &CheckPlan) -> BTreeMap<String, f64> {
    plan.movable
        .iter()
        .map(|m| (m.clone(), f64::NEG_INFINITY))
        .collect()
}

/// What one body's window is made of (see [`WindowBody`]).
#[derive(Debug, Clone)]
struct WindowSpec {
    geometry: GridGeometry,
    lo: u32,
    slabs: Vec<Arc<TetMesh>>,
    centre: usize,
    low: Option<Arc<TetMesh>>,
    high: Option<Arc<TetMesh>>,
    mul: i64,
    add: [i64; 4],
    /// Run number of the first taken tet.
    first_tet: u64,
}

/// Whether two windows' boxes are apart (a gap on some spatial axis) on the pair's
/// lattice: then no tet of one meets the other body, nor lies inside it.
fn apart(a: &WindowSpec, b: &WindowSpec) -> bool {
    let (Some(x), Some(y)) = (a.spatial_box(), b.spatial_box()) else {
        return true;
    };
    (0..3).any(|k| x.1[k] < y.0[k] || y.1[k] < x.0[k])
}

/// Prepares and checks the two bodies' windows of a pair (`(id, window)` each).
///
/// A body's window prepared for another pair's period is taken from `cache` when it is the
/// same window (a body in several pairs is then prepared once per period); the two prepared
/// windows are returned with the result, for the cache.
fn check_specs(
    (a, wa): (&str, &WindowSpec),
    (b, wb): (&str, &WindowSpec),
    cache: &BTreeMap<String, (WindowSpec, Arc<PreparedWindow>)>,
) -> WindowChecked {
    let prepared = |id: &str, w: &WindowSpec| match cache.get(id).filter(|c| c.0.same_as(w)) {
        Some((_, p)) => Ok(p.clone()),
        None => prepare_window(&w.body(id)).map(Arc::new),
    };
    let (ra, rb) = rayon::join(|| prepared(a, wa), || prepared(b, wb));
    let (pa, pb) = (ra?, rb?);
    Ok((check_window(&pa, &pb), [pa, pb]))
}

/// A window's result, with the two bodies' prepared windows.
type WindowChecked = Result<(WindowResult, [Arc<PreparedWindow>; 2]), super::window::WindowError>;

impl WindowSpec {
    /// The same window: the same pieces (by identity), placement and numbering.
    fn same_as(&self, o: &WindowSpec) -> bool {
        let same = |x: &Arc<TetMesh>, y: &Arc<TetMesh>| Arc::ptr_eq(x, y);
        let same_opt = |x: &Option<Arc<TetMesh>>, y: &Option<Arc<TetMesh>>| match (x, y) {
            (Some(x), Some(y)) => same(x, y),
            (None, None) => true,
            _ => false,
        };
        self.geometry == o.geometry
            && self.lo == o.lo
            && self.slabs.len() == o.slabs.len()
            && self.slabs.iter().zip(&o.slabs).all(|(x, y)| same(x, y))
            && self.centre == o.centre
            && same_opt(&self.low, &o.low)
            && same_opt(&self.high, &o.high)
            && self.mul == o.mul
            && self.add == o.add
            && self.first_tet == o.first_tet
    }

    /// The box of every vertex of the window on the pair's lattice, spatial axes only
    /// (`None` for a window without vertices).
    fn spatial_box(&self) -> Option<([i64; 3], [i64; 3])> {
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        let parts = self
            .low
            .iter()
            .chain(self.slabs.iter())
            .chain(self.high.iter());
        for m in parts {
            for v in &m.vertices {
                for k in 0..3 {
                    lo[k] = lo[k].min(i64::from(v[k]));
                    hi[k] = hi[k].max(i64::from(v[k]));
                }
            }
        }
        if lo[0] > hi[0] {
            return None;
        }
        let f = i64::from(CHECKER_FACTOR) * self.mul;
        let map = |x: [i64; 3]| [0, 1, 2].map(|k| x[k] * f + self.add[k]);
        Some((map(lo), map(hi)))
    }

    /// Every taken tet OUTSIDE.
    fn all_outside(&self) -> TakenLabels {
        let n = self.slabs.len();
        let pieces = [
            if self.centre == 0 {
                self.low.as_ref().map_or(0, |m| m.tets.len())
            } else {
                0
            },
            self.slabs[self.centre].tets.len(),
            if self.centre + 1 == n {
                self.high.as_ref().map_or(0, |m| m.tets.len())
            } else {
                0
            },
        ];
        let total: usize = pieces.iter().sum();
        TakenLabels {
            labels: vec![Label::Outside as u8; total],
            counts: LabelCounts {
                outside: total as u64,
                ..LabelCounts::default()
            },
            pieces,
        }
    }

    fn body<'a>(&'a self, id: &'a str) -> WindowBody<'a> {
        WindowBody {
            id,
            geometry: self.geometry,
            lo: self.lo,
            slabs: self.slabs.iter().map(|m| m.as_ref()).collect(),
            centre: self.centre,
            low: self.low.as_deref(),
            high: self.high.as_deref(),
            mul: self.mul,
            add: self.add,
        }
    }
}

/// The map of two bodies onto their pair's lattice.
struct PairLattice {
    scale: i32,
    ratio_a: i64,
    ratio_b: i64,
    shift_a: [i64; 3],
    shift_b: [i64; 3],
}

fn pair_lattice(ga: &GridGeometry, gb: &GridGeometry) -> Result<PairLattice, String> {
    if (ga.resolution - gb.resolution).abs() > 1e-9 * ga.resolution {
        return Err(format!(
            "voxel edges of {} m and {} m",
            ga.resolution, gb.resolution
        ));
    }
    let off = origin_offset(&ga.origin, &gb.origin, ga.resolution)?;
    let scale = ga.scale.max(gb.scale).max(2);
    Ok(PairLattice {
        scale,
        ratio_a: i64::from(scale / ga.scale.max(1)).max(1),
        ratio_b: i64::from(scale / gb.scale.max(1)).max(1),
        shift_a: [0; 3],
        shift_b: off,
    })
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

fn body_report(id: &str, b: &BodyStream) -> BodyReport {
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
                let so_far = r.acc.so_far();
                tets += r.tets;
                t.frames += u64::from(r.next_index) + 1;
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

fn pair_report(p: &PairRoll, tets_a: u64, tets_b: u64, resolution: f64) -> PairReport {
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
    let interfering =
        p.counts.0.interference + p.counts.0.inside + p.counts.1.interference + p.counts.1.inside
            > 0;
    let overlap = if !interfering {
        Some((0.0, 0.0))
    } else {
        overlap_so_far(&p.overlap)
    };
    PairReport {
        a: p.a.clone(),
        b: p.b.clone(),
        interfering,
        intervals_s: all.iter().map(|o| [o.s.0, o.s.1]).collect(),
        first_contact_s: first.map(|o| o.s.0),
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

/// The overlap hypervolume so far and its error bound (`None`: not measurable).
fn overlap_so_far(o: &Overlap) -> Option<(f64, f64)> {
    run_overlap(o).map(|(hv, b)| (hv + o.closed.0, b + o.closed.1))
}

/// The overlap of the current run of consecutive periods, and its bound.
fn run_overlap(o: &Overlap) -> Option<(f64, f64)> {
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
    let mut sums = o.sums;
    if n >= 2 {
        if let Some(m) = &o.mesher {
            if let Some(cap) = m.last_frame().and_then(|k| m.cap(k, CapSide::High)) {
                sums = add_normals(sums, &cap);
            }
        }
    }
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
