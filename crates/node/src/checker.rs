//! The checker node: the mesh pieces of every body in (`mesh_topic`, chronotope_msgs/MeshSlab),
//! and the bodies' VoxelGrid frames (to measure overlaps and close its windows), checked frame
//! period by frame period as they arrive (see [`chronotope_checker::rolling`]). While the streams go
//! on it publishes each contact as it begins, goes on and ends (`~/contacts`, ContactEvent),
//! each slab's labels once final (`~/labels`, TetLabels), the cumulative report whenever an
//! answer changes (`~/report`), resolve suggestions per contact episode of the movable bodies
//! (`~/suggestions`) and, if asked, each body's t-slice at each frame period's later frame,
//! coloured by label (`~/markers`).
//!
//! Parameters: `pairs` (string array, each `"BODY_A BODY_B"`; default: every pair of the
//! bodies the transport names), `movable` (string array, default none: no resolution),
//! `time_scale_m_per_s` (double, 0 = one voxel per frame period), `labels` (bool, default
//! true), `markers` (bool, default false), `markers_period_s` (double, default 0: a body's
//! slab is sliced for the markers only if it starts this long after the last one sliced;
//! 0 = every slab), `markers_every_slab` (bool, default false: a markers part that falls
//! behind draws each body's newest slab; true: every slab, for a recording meant for review,
//! within the queue's bound), `mesh_topic` (default `/mesher/mesh_slabs`),
//! `max_lead_frames` (int, default 64: how many slabs one body may run ahead of a silent
//! partner before they are checked without it), `resolve_horizon_s` (double, default 1: the
//! time around a contact episode its resolutions are checked over), `max_episode_s` (double,
//! default 4: a longer contact is resolved over its first this many seconds),
//! `resolve_max_tets` (int, default 1 500 000: most tets of slabs kept for resolutions alone,
//! all bodies together; older ones are dropped first), `resolve_in_flight` (int, default 1:
//! resolutions computed on their own pool while the windows go on; 0 = on the node's
//! thread, in turn), `rotation_axis` (double[3], default [0, 0, 1]: the axis a movable body
//! is turned about), `rotation_point` (double[3], metres; default: the body's centroid at
//! its first contact), `rotation_max_rad` (double, default π: the largest turn tried in
//! either sense; 0 = no rotation suggested), and the mesher's
//! decoding parameters (`iso_percent`, `unknown_occupied`, `percent_scale`, `max_slab_tets`),
//! which must match the mesher's.

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::launch::{LaunchError, NodeSpec, Params};
use super::markers::{body_color, slab_end_plane, triangle_list_of};
use super::mesher::mesher_options;
use super::{Message, Node, NodeStatus, Payload, TopicRef};
use chronotope_checker::labels::Label;
use chronotope_checker::pipeline::CheckPlan;
use chronotope_checker::report::{Report, Resolution, Verdict};
use chronotope_checker::rolling::{
    ContactPhase, Piece, PieceKind, RollingChecker, RollingConfig, RollingOutput, SlabDone,
};
use chronotope_checker::rotate::RotationSpec;
use chronotope_mesh::flat::{merge_flat_with, FlatFaces};
use chronotope_mesh::hash::WordHasher;
use chronotope_mesh::slice::{Slicer, TriMesh};
use chronotope_mesh::GridGeometry;
use chronotope_mesh::TetMesh;
use chronotope_mesh::{Encoding, MesherOptions, OccupancyGrid};
use chronotope_msg::{
    BodySummary, ColorRGBA, ContactEvent, Header, InterferenceReport, MarkerArray, MeshSlab,
    PairInterference, Point, ResolveSuggestion, ResolveSuggestions, RosMessage, TetLabels, Time,
    Vector3, VoxelGrid,
};

/// Label colours of the markers.
const INTERFERENCE_COLOR: ColorRGBA = ColorRGBA::new(0.9, 0.05, 0.05, 1.0);
const INSIDE_COLOR: ColorRGBA = ColorRGBA::new(1.0, 0.6, 0.0, 0.95);

/// The checker node.
pub struct CheckerNode {
    fqn: String,
    opts: MesherOptions,
    mesh_topic: String,
    report_topic: String,
    contacts_topic: String,
    labels_topic: Option<String>,
    suggestions_topic: Option<String>,
    markers_topic: Option<String>,
    bodies: BTreeSet<String>,
    engine: RollingChecker,
    /// The latest report (what `report` returns).
    report: Option<Report>,
    frame_id: String,
    /// Stamp of the latest piece (ns): the report's stamp.
    latest_ns: i64,
    /// An answer changed since the report was last published.
    dirty: bool,
    /// Live: steps since the report was left for the statistics it waits for (see
    /// [`CheckerNode::publish_report_if_changed`]).
    report_waited: u32,
    /// Whether anything reads `~/report` and `~/suggestions` (the transport says so:
    /// [`Node::set_demand`]; each is read until it says otherwise, the suggestions only if
    /// there are any, a movable body). With neither read, only the last report is built
    /// (see [`CheckerNode::publish_report_if_changed`]).
    report_read: (bool, bool),
    /// Episodes resolved so far, and when the suggestions were last published (the report
    /// keeps a bounded number of resolutions, so their count stops telling).
    resolved: (u64, u64),
    /// With `markers`: the slabs every pair has labelled, waiting for the markers part
    /// ([`CheckerNode::markers_part`]) to slice them.
    markers_queue: Option<Arc<Mutex<MarkerQueue>>>,
    /// Hidden topic (`~/_slabs_done`, Clock) telling the markers part slabs are queued.
    slabs_done_topic: String,
    /// Least time (ns) between the starts of two slabs of a body sliced for the markers.
    markers_period_ns: i64,
    /// Per body, the start stamp of its last slab queued for the markers.
    markers_last: std::collections::BTreeMap<String, i64>,
    /// A live transport has polled the node ([`Node::poll`]): resolutions are published
    /// as soon as they are done (a replay takes them at points that do not depend on their
    /// speed).
    live: bool,
    status: NodeStatus,
}

impl CheckerNode {
    /// The node a launch config describes; `default_bodies` give the pairs when it names
    /// none (every pair of them).
    ///
    /// # Errors
    /// A bad parameter.
    pub fn from_spec(spec: &NodeSpec, default_bodies: &[String]) -> Result<Self, LaunchError> {
        let mut p = Params::of(spec);
        let node = p.node().to_owned();
        let bad = |param: &str, reason: String| LaunchError::Param {
            node: node.clone(),
            param: param.to_owned(),
            reason,
        };
        let pairs = match p.strings("pairs")? {
            None => None,
            Some(list) => {
                let mut out = Vec::new();
                for s in list {
                    let parts: Vec<&str> = s.split_whitespace().collect();
                    let [a, b] = parts.as_slice() else {
                        return Err(bad(
                            "pairs",
                            format!("{s:?}: a pair is two topics separated by a space"),
                        ));
                    };
                    if a == b {
                        return Err(bad(
                            "pairs",
                            format!("{s:?}: a body is not checked against itself"),
                        ));
                    }
                    out.push((p.resolve("pairs", a)?, p.resolve("pairs", b)?));
                }
                Some(out)
            }
        };
        let movable = p.topics("movable")?.unwrap_or_default();
        let c = p.double("time_scale_m_per_s", 0.0, 0.0..=1e12)?;
        let labels = p.bool("labels", true)?;
        let markers = p.bool("markers", false)?;
        let markers_period_s = p.double("markers_period_s", 0.0, 0.0..=3600.0)?;
        let markers_every_slab = p.bool("markers_every_slab", false)?;
        let mesh_topic = p.topic("mesh_topic", "/mesher/mesh_slabs")?;
        let max_lead = p.int("max_lead_frames", 64, 1..=100_000)?;
        let horizon_s = p.double("resolve_horizon_s", 1.0, 0.0..=3600.0)?;
        let max_episode_s = p.double("max_episode_s", 4.0, 0.001..=86_400.0)?;
        let max_horizon_tets = p.int("resolve_max_tets", 1_500_000, 0..=1_000_000_000)?;
        let in_flight = p.int("resolve_in_flight", 1, 0..=16)?;
        let defaults = RotationSpec::default();
        let axis = p.doubles("rotation_axis", defaults.axis)?;
        if axis.iter().all(|&c| c == 0.0) {
            return Err(bad(
                "rotation_axis",
                "[0, 0, 0] is no direction: give the axis as [x, y, z], not all zero".into(),
            ));
        }
        let point_given = spec.params.contains_key("rotation_point");
        let point = p.doubles("rotation_point", [0.0; 3])?;
        let rotation = RotationSpec {
            axis,
            point_m: point_given.then_some(point),
            max_rad: p.double("rotation_max_rad", defaults.max_rad, 0.0..=defaults.max_rad)?,
        };
        let opts = mesher_options(&mut p)?;
        let report_topic = p.resolve("~/report", "~/report")?;
        let contacts_topic = p.resolve("~/contacts", "~/contacts")?;
        let labels_topic = labels
            .then(|| p.resolve("~/labels", "~/labels"))
            .transpose()?;
        let suggestions_topic = (!movable.is_empty())
            .then(|| p.resolve("~/suggestions", "~/suggestions"))
            .transpose()?;
        let markers_topic = markers
            .then(|| p.resolve("~/markers", "~/markers"))
            .transpose()?;
        let slabs_done_topic = p.resolve("~/_slabs_done", "~/_slabs_done")?;
        p.finish()?;
        let defaulted = pairs.is_none();
        let pairs = pairs.unwrap_or_else(|| {
            let mut ids = default_bodies.to_vec();
            ids.sort();
            ids.dedup();
            (0..ids.len())
                .flat_map(|i| (i + 1..ids.len()).map(move |j| (i, j)))
                .map(|(i, j)| (ids[i].clone(), ids[j].clone()))
                .collect()
        });
        let in_pairs: BTreeSet<String> = pairs
            .iter()
            .flat_map(|(a, b)| [a.clone(), b.clone()])
            .collect();
        // A lone body (one body, no pair to check) is still meshed and reported.
        let solo: Vec<String> = if defaulted && pairs.is_empty() {
            default_bodies.to_vec()
        } else {
            Vec::new()
        };
        if let Some(m) = movable.iter().find(|m| !in_pairs.contains(*m)) {
            return Err(bad("movable", format!("{m} is in no checked pair")));
        }
        let plan = CheckPlan {
            pairs: Some(pairs),
            movable,
            time_scale: (c > 0.0).then_some(c),
            frame_ids: Default::default(),
            rotation,
        };
        let cfg = RollingConfig {
            max_lead_frames: max_lead as usize,
            labels: labels_topic.is_some(),
            slabs_done: markers_topic.is_some(),
            horizon_s,
            max_episode_s,
            max_horizon_tets: max_horizon_tets as usize,
            resolve_in_flight: in_flight as usize,
            ..RollingConfig::default()
        };
        // No suggestions topic (no movable body): nothing reads one.
        let suggested = suggestions_topic.is_some();
        Ok(Self {
            fqn: node,
            opts,
            mesh_topic,
            report_topic,
            contacts_topic,
            labels_topic,
            suggestions_topic,
            markers_topic,
            bodies: in_pairs.iter().chain(&solo).cloned().collect(),
            engine: {
                let mut e = RollingChecker::new(plan, opts, cfg);
                for b in &solo {
                    e.track_body(b);
                }
                e
            },
            report: None,
            frame_id: String::new(),
            latest_ns: 0,
            dirty: false,
            report_waited: 0,
            report_read: (true, suggested),
            resolved: (0, 0),
            markers_queue: markers.then(|| {
                Arc::new(Mutex::new(MarkerQueue {
                    every_slab: markers_every_slab,
                    ..MarkerQueue::default()
                }))
            }),
            markers_period_ns: (markers_period_s * 1e9).round() as i64,
            markers_last: Default::default(),
            slabs_done_topic,
            live: false,
            status: NodeStatus::default(),
        })
    }

    /// The bodies its pairs use (the mesher need not mesh any other).
    pub fn bodies(&self) -> impl Iterator<Item = &str> {
        self.bodies.iter().map(String::as_str)
    }

    /// The topic it reads mesh pieces from.
    pub fn mesh_topic(&self) -> &str {
        &self.mesh_topic
    }

    /// Runs the checker's bookkeeping (statistics, overlaps, the frames' decoding) on
    /// `pool` (rayon's when `None`) instead of the process's low-priority bookkeeping pool
    /// ([`chronotope_checker::rolling::shared_bookkeeping_pool`]); what it computes is the
    /// same on any pool.
    pub fn set_bookkeeping_pool(&mut self, pool: chronotope_checker::rolling::BookkeepingPool) {
        self.engine.set_bookkeeping_pool(pool);
    }

    /// The latest report (cumulative; final after [`Node::finish`]).
    pub fn report(&self) -> Option<&Report> {
        self.report.as_ref()
    }

    fn on_piece(&mut self, s: &MeshSlab, out: &mut Vec<Message>) {
        if !self.bodies.contains(&s.body_id) {
            return; // a body no pair uses
        }
        if self.frame_id.is_empty() {
            self.frame_id = s.header.frame_id.clone();
        }
        let kind = match s.kind {
            MeshSlab::KIND_CAP_START => PieceKind::CapStart,
            MeshSlab::KIND_LATERAL => PieceKind::Lateral,
            MeshSlab::KIND_CAP_END => PieceKind::CapEnd,
            k => {
                let why = format!(
                    "{}: piece kind {k} is none of the three; ignored",
                    s.body_id
                );
                self.status.problem(&self.fqn, "bad_piece", why);
                return;
            }
        };
        self.latest_ns = self.latest_ns.max(s.stamp_hi.as_nanos());
        let piece = Piece {
            body: s.body_id.clone(),
            kind,
            index: s.index,
            stamps_ns: (s.stamp_lo.as_nanos(), s.stamp_hi.as_nanos()),
            geometry: s.geometry(),
            occupied: s.occupied_voxels,
            unsure: s.unsure(),
            displacement: s.displacement_voxels,
            mesh: Arc::clone(&s.mesh),
            frame_id: s.header.frame_id.clone(),
        };
        let mut rolled = Vec::new();
        self.engine.on_piece(piece, &mut rolled);
        // A stream's end changes the report (the body closed, its frames) even when no
        // contact does: republished, so that a live reader sees it before the node finishes.
        if kind == PieceKind::CapEnd {
            self.dirty = true;
        }
        self.emit(rolled, out);
    }

    fn on_frame(&mut self, topic: &str, g: &Arc<VoxelGrid>, out: &mut Vec<Message>) {
        if !self.bodies.contains(topic) {
            return;
        }
        // Frames the mesher refuses for their own fields are refused here too (and counted
        // there); a frame refused for the stream (another lattice, a repeated stamp) is told
        // apart when it is used (`frame_at`).
        if g.message_check("").is_err() {
            return;
        }
        // Decoded on the pool, off this thread (a 128³ PERCENT frame takes milliseconds),
        // by the time a window needs it; a frame that does not decode counts as not received.
        let geometry = GridGeometry {
            origin: [g.origin.x, g.origin.y, g.origin.z],
            resolution: g.resolution,
            size: [g.size_x, g.size_y, g.size_z],
            encoding: g.encoding,
            scale: if g.encoding == VoxelGrid::ENCODING_PERCENT {
                self.opts.percent_scale
            } else {
                2
            },
        };
        let encoding = if g.encoding == VoxelGrid::ENCODING_PERCENT {
            Encoding::Percent
        } else {
            Encoding::Bits
        };
        let expected_bytes =
            chronotope_mesh::grid::decoded_bytes([g.size_x, g.size_y, g.size_z], encoding);
        let (frame, opts) = (Arc::clone(g), self.opts.decode);
        let mut rolled = Vec::new();
        self.engine.on_frame_with(
            topic,
            g.header.stamp.as_nanos(),
            geometry,
            expected_bytes,
            Box::new(move || OccupancyGrid::decode(&frame.frame_ref(), &opts).ok()),
            &mut rolled,
        );
        self.emit(rolled, out);
    }

    fn header(&self, stamp_ns: i64) -> Header {
        Header {
            stamp: Time::from_nanos(stamp_ns),
            frame_id: self.frame_id.clone(),
        }
    }

    /// Publishes what the rolling checker gave, then the report if an answer changed.
    fn emit(&mut self, rolled: Vec<RollingOutput>, out: &mut Vec<Message>) {
        self.emit_then_report(rolled, false, out);
    }

    /// [`Self::emit`]; with `final_report` the report is published now, whatever it waits
    /// for.
    fn emit_then_report(
        &mut self,
        rolled: Vec<RollingOutput>,
        final_report: bool,
        out: &mut Vec<Message>,
    ) {
        let before = out.len();
        // The newest stamp of the slabs queued for the markers part in this step.
        let mut queued: Option<i64> = None;
        for r in rolled {
            match r {
                RollingOutput::Labels(l) => {
                    let Some(topic) = &self.labels_topic else {
                        continue;
                    };
                    let m = TetLabels {
                        header: self.header(l.stamps_ns.1),
                        body_id: l.body,
                        other_id: l.other,
                        index: l.index,
                        stamp_lo: Time::from_nanos(l.stamps_ns.0),
                        stamp_hi: Time::from_nanos(l.stamps_ns.1),
                        with_cap_start: l.with_cap_start,
                        with_cap_end: l.with_cap_end,
                        labels: l.labels,
                        interference: l.counts.interference,
                        inside: l.counts.inside,
                        outside: l.counts.outside,
                    };
                    out.push(Message::new(
                        topic,
                        l.stamps_ns.1,
                        Payload::TetLabels(Arc::new(m)),
                    ));
                }
                RollingOutput::SlabDone(d) => {
                    // A display rate: a body's slab that starts less than `markers_period_s`
                    // after the last one sliced is not (decided on the stamps, so a replay
                    // gives the markers live gives; a stream that starts again earlier is
                    // sliced).
                    let period = self.markers_period_ns;
                    let recent = |l: i64| (l..l.saturating_add(period)).contains(&d.stamps_ns.0);
                    if self.markers_last.get(&d.body).is_some_and(|&l| recent(l)) {
                        continue;
                    }
                    if let Some(q) = &self.markers_queue {
                        self.markers_last.insert(d.body.clone(), d.stamps_ns.0);
                        queued = Some(queued.map_or(d.stamps_ns.1, |s| s.max(d.stamps_ns.1)));
                        let dropped = q.lock().map_or(0, |mut q| q.push(&self.frame_id, d));
                        if dropped > 0 {
                            self.status
                                .count_quietly(&self.fqn, "markers_behind", dropped, || {
                                    format!(
                                        "the markers part is behind: the oldest slabs waiting \
                                     for it were dropped (at most {MARKER_QUEUE_TETS} tets \
                                     wait); labels, contacts and the report are complete"
                                    )
                                });
                        }
                    }
                }
                RollingOutput::Contact(c) => {
                    self.dirty = true;
                    let fields = self.engine.contact_fields(&c.a, &c.b);
                    let time_origin = Time::from_nanos(fields.map_or(0, |f| f.time_origin_ns));
                    let first_contact_s = nan_if_none(fields.and_then(|f| f.first_contact_s));
                    let overlap_hypervolume_m3s =
                        nan_if_none(fields.and_then(|f| f.overlap_hypervolume_m3s));
                    let m = ContactEvent {
                        header: self.header(c.stamp_ns),
                        body_a: c.a,
                        body_b: c.b,
                        event: match c.phase {
                            ContactPhase::Begin => ContactEvent::BEGIN,
                            ContactPhase::Ongoing => ContactEvent::ONGOING,
                            ContactPhase::End => ContactEvent::END,
                        },
                        contact_index: c.index,
                        time_origin,
                        start_s: c.start_s,
                        end_s: c.end_s,
                        start_error_bound_s: nan_if_none(c.start_bound_s),
                        end_error_bound_s: nan_if_none(c.end_bound_s),
                        first_contact_s,
                        overlap_hypervolume_m3s,
                        unsure_reason: String::new(),
                    };
                    out.push(Message::new(
                        &self.contacts_topic,
                        c.stamp_ns,
                        Payload::Contact(Arc::new(m)),
                    ));
                }
                RollingOutput::Unsure(u) => {
                    self.dirty = true;
                    let fields = self.engine.contact_fields(&u.a, &u.b);
                    let m = ContactEvent {
                        header: self.header(u.stamp_ns),
                        body_a: u.a,
                        body_b: u.b,
                        event: if u.ended {
                            ContactEvent::UNSURE_END
                        } else {
                            ContactEvent::UNSURE_BEGIN
                        },
                        contact_index: u.index,
                        time_origin: Time::from_nanos(fields.map_or(0, |f| f.time_origin_ns)),
                        start_s: u.span.span_s[0],
                        end_s: u.span.span_s[1],
                        start_error_bound_s: f64::NAN,
                        end_error_bound_s: f64::NAN,
                        first_contact_s: nan_if_none(fields.and_then(|f| f.first_contact_s)),
                        overlap_hypervolume_m3s: nan_if_none(
                            fields.and_then(|f| f.overlap_hypervolume_m3s),
                        ),
                        unsure_reason: u.span.line(),
                    };
                    out.push(Message::new(
                        &self.contacts_topic,
                        u.stamp_ns,
                        Payload::Contact(Arc::new(m)),
                    ));
                }
                RollingOutput::Resolved => {
                    self.resolved.0 += 1;
                    self.dirty = true;
                }
                RollingOutput::Problem(kind, text) => self.status.problem(&self.fqn, kind, text),
            }
        }
        if let Some(stamp) = queued {
            if let Some(q) = &self.markers_queue {
                if let Ok(mut q) = q.lock() {
                    q.end_step();
                }
            }
            out.push(Message::new(
                &self.slabs_done_topic,
                stamp,
                Payload::Clock(Arc::new(chronotope_msg::Clock {
                    clock: Time::from_nanos(stamp),
                })),
            ));
        }
        self.publish_report_if_changed(final_report, out);
        self.status.published += (out.len() - before) as u64;
    }

    /// Publishes the report if an answer changed since it was last published. The report
    /// waits for the statistics of the pieces being added on the pool (its bodies' tets,
    /// closedness, hypervolume); the contact events never do. Live, a report that would
    /// wait is left to a later step, or to the next tick ([`Node::poll`], which comes once the
    /// node has caught up with its input), so that the step's contact events go out first;
    /// after [`REPORT_WAIT`] steps without a tick the report goes out as it stands (the
    /// statistics and overlaps still on the pool left out:
    /// [`RollingChecker::report_as_it_stands`]), and the complete one follows once they are
    /// in. A replay publishes it in the step that changed it, complete, so that what it
    /// records does not depend on how fast the pool ran.
    fn publish_report_if_changed(&mut self, now: bool, out: &mut Vec<Message>) {
        if !self.dirty || !self.report_wanted() {
            return;
        }
        if self.live && !now && self.engine.statistics_pending() {
            self.report_waited += 1;
            if self.report_waited < REPORT_WAIT {
                return;
            }
            // Behind its input that long: the report as it stands, what the pool is still
            // working out left for the next one. Waiting for it here would compute the
            // queued statistics on this thread, at the contacts' priority, while the pool
            // that should have them runs lower: a node behind would fall further behind.
            let report = self.engine.report_as_it_stands();
            self.publish_report(report, out);
            self.dirty = true;
            return;
        }
        let report = self.engine.report();
        self.publish_report(report, out);
    }

    /// Whether a report is to be built now: something reads it or the suggestions sent with
    /// it. Nobody does in a replay recording neither: its reports went nowhere, and each
    /// waited for the statistics and overlaps of the pieces so far (on the replay's path);
    /// the last one, which the replay's answer is, is built at [`Node::finish`]. A reader
    /// that comes gets the report as it stands at the next step or tick.
    fn report_wanted(&self) -> bool {
        self.report_read.0 || self.report_read.1
    }

    /// The report (the engine's answer now), and the suggestions if there are new ones.
    fn publish_report(&mut self, report: Report, out: &mut Vec<Message>) {
        self.dirty = false;
        self.report_waited = 0;
        let stamp = self.latest_ns;
        let voxel = report.pairs.first().map_or(0.0, |p| p.voxel_size_m);
        out.push(Message::new(
            &self.report_topic,
            stamp,
            Payload::Report(Arc::new(report_message(&report, voxel, self.header(stamp)))),
        ));
        if let Some(topic) = &self.suggestions_topic {
            if self.resolved.0 != self.resolved.1 {
                self.resolved.1 = self.resolved.0;
                let m = ResolveSuggestions {
                    header: self.header(stamp),
                    suggestions: report.resolutions.iter().map(suggestion_message).collect(),
                };
                out.push(Message::new(
                    topic,
                    stamp,
                    Payload::Suggestions(Arc::new(m)),
                ));
            }
        }
        self.report = Some(report);
    }

    /// Publishes the resolutions that have finished on the resolver's pool.
    fn poll_resolutions(&mut self, out: &mut Vec<Message>) {
        if self.engine.resolutions_in_flight() == 0 {
            return;
        }
        let mut rolled = Vec::new();
        self.engine.poll_resolutions(&mut rolled);
        if !rolled.is_empty() {
            self.emit(rolled, out);
        }
    }

    /// Reports slabs for the markers part only while someone reads the markers (the part
    /// hears it from the transport: [`Node::set_demand`]).
    fn follow_markers_demand(&mut self) {
        if let Some(q) = &self.markers_queue {
            let read = q.lock().map_or(true, |q| !q.unread);
            self.engine.set_slabs_done(read);
        }
    }

    /// The markers part: a node of its own (`<name>/markers`, its own thread in a live
    /// launch) that slices the slabs every pair has labelled and publishes `~/markers`, so
    /// that the checker's thread goes on with the next windows. `None` without `markers`.
    pub fn markers_part(&self) -> Option<CheckerMarkers> {
        let topic = self.markers_topic.clone()?;
        let queue = self.markers_queue.clone()?;
        Some(CheckerMarkers {
            shown: Default::default(),
            fqn: format!("{}/markers", self.fqn),
            slabs_done_topic: self.slabs_done_topic.clone(),
            markers_topic: topic,
            queue,
            nudges: 0,
            pool: MarkersPool::Unmade,
            status: NodeStatus::default(),
        })
    }
}

/// Most tets of slabs waiting for the markers part; beyond it the oldest are dropped.
pub const MARKER_QUEUE_TETS: usize = 4_000_000;

/// Slabs waiting for the markers part, oldest first.
#[derive(Debug, Default)]
pub struct MarkerQueue {
    /// Each slab with the checker's `frame_id` and the checker step that queued it.
    slabs: std::collections::VecDeque<(String, SlabDone, u64)>,
    tets: usize,
    /// The checker's steps that queued slabs so far (one `_slabs_done` message each).
    step: u64,
    /// Nobody reads the markers now: nothing is queued, and the checker stops reporting
    /// slabs until someone does.
    unread: bool,
    /// Set when reading starts again: the markers part then draws every body anew.
    restart: bool,
    /// Draw every slab even when behind (`markers_every_slab`).
    every_slab: bool,
    /// The markers part runs behind the checker on an in-process bus (a replay): each
    /// nudge takes exactly the slabs of its step, and nothing is dropped (the bus bounds
    /// how many steps wait).
    behind: bool,
}

impl MarkerQueue {
    /// Queues `d`; returns how many of the oldest were dropped to stay within
    /// [`MARKER_QUEUE_TETS`] (the newest always stays).
    fn push(&mut self, frame_id: &str, d: SlabDone) -> u64 {
        if self.unread {
            return 0;
        }
        self.tets += d.mesh.tets.len();
        self.slabs.push_back((frame_id.to_owned(), d, self.step));
        let mut dropped = 0;
        while !self.behind && self.tets > MARKER_QUEUE_TETS && self.slabs.len() > 1 {
            if let Some((_, old, _)) = self.slabs.pop_front() {
                self.tets -= old.mesh.tets.len();
                dropped += 1;
            }
        }
        dropped
    }

    /// Ends the checker's step: the slabs queued so far are announced by one message.
    fn end_step(&mut self) {
        self.step += 1;
    }

    /// The slabs to draw, in order. When they come from several checker steps the markers
    /// part has fallen behind: a display wants the latest state, not a queue, so only each
    /// body's newest slab is kept (with `true`, and how many were passed over).
    ///
    /// Run behind (a replay), the part takes the slabs of steps up to `through` only (those
    /// its nudges so far announced; the checker may have queued the next step's already):
    /// one step at a time, every slab drawn.
    fn take(&mut self, through: Option<u64>) -> (Vec<(String, SlabDone)>, u64, bool) {
        let restart = std::mem::take(&mut self.restart);
        let n = match through {
            Some(step) if self.behind => self.slabs.iter().take_while(|x| x.2 <= step).count(),
            _ => self.slabs.len(),
        };
        let slabs: Vec<(String, SlabDone, u64)> = self.slabs.drain(..n).collect();
        self.tets -= slabs.iter().map(|x| x.1.mesh.tets.len()).sum::<usize>();
        let one_step = slabs.windows(2).all(|w| w[0].2 == w[1].2);
        if one_step || self.every_slab {
            return (
                slabs.into_iter().map(|(f, d, _)| (f, d)).collect(),
                0,
                restart,
            );
        }
        let n = slabs.len();
        let mut newest: Vec<(String, SlabDone)> = Vec::new();
        for (f, d, _) in slabs.into_iter().rev() {
            if !newest.iter().any(|(_, x)| x.body == d.body) {
                newest.push((f, d));
            }
        }
        newest.reverse();
        let skipped = (n - newest.len()) as u64;
        (newest, skipped, restart)
    }
}

/// A slab's t-slice as the markers draw it: the slice, each triangle's tet, the plane of
/// each flat triangle (found once, for the whole slice and its labelled parts) and the whole
/// slice with its flat faces merged ([`chronotope_mesh::flat`]).
#[derive(Debug)]
struct Drawn {
    mesh: TriMesh,
    sources: Vec<u32>,
    flats: FlatFaces,
    merged: Vec<[u32; 3]>,
}

/// What the markers part last drew of one body: the slab's slice (kept, so that a body at
/// rest whose labels change is not sliced again) and what its three markers show.
#[derive(Debug)]
struct Shown {
    /// Hash of the slab's tets in space (a body at rest repeats it, moved in time).
    geometry: u64,
    /// The slice, with each triangle's tet.
    slice: Arc<Drawn>,
    /// Per label marker (INSIDE, INTERFERENCE): its triangles in the slice (none: not shown).
    labels: [Vec<u32>; 2],
}

/// The checker's markers part (see [`CheckerNode::markers_part`]).
pub struct CheckerMarkers {
    /// Per body, what its markers show now.
    shown: std::collections::BTreeMap<String, Shown>,
    fqn: String,
    slabs_done_topic: String,
    markers_topic: String,
    queue: Arc<Mutex<MarkerQueue>>,
    /// The checker's nudges handled so far (`~/_slabs_done`, one per step that queued
    /// slabs): run behind, the part takes the slabs of those steps.
    nudges: u64,
    /// Where the slabs are sliced: live, a pool of the part's own whose threads run at a
    /// lower priority ([`MARKERS_NICE`]), made at the first slabs; run behind on a replay's
    /// bus, rayon's pool (a replay's time is the sum of all the work).
    pool: MarkersPool,
    status: NodeStatus,
}

/// How much the live markers part's pool lowers its threads' priority (nice values added):
/// a display is the first thing a cell can wait for. Sliced on rayon's pool, a display
/// reading the markers held up the mesher's frames on the same cores (lag p99 about a
/// second at 30 Hz with the markers at 5 Hz on a 2-core machine, 50 ms without a display);
/// at a lower priority the meshers and the check take the cores first and the markers the
/// time they leave, coalescing to each body's newest slab when behind.
pub const MARKERS_NICE: i32 = 10;

/// The markers part's pool (see [`CheckerMarkers`]).
enum MarkersPool {
    /// Not made yet (live, before the first slabs).
    Unmade,
    /// Its own, at a lower priority.
    Own(rayon::ThreadPool),
    /// Rayon's: run behind, or the own pool could not be made.
    Global,
}

impl MarkersPool {
    /// Runs `work` on the pool, making it first if needed.
    fn install<R: Send>(&mut self, work: impl FnOnce() -> R + Send) -> R {
        if matches!(self, Self::Unmade) {
            let made = rayon::ThreadPoolBuilder::new()
                .num_threads(rayon::current_num_threads())
                .thread_name(|i| format!("markers-{i}"))
                .start_handler(|_| chronotope_checker::rolling::lower_own_priority(MARKERS_NICE))
                .build();
            *self = match made {
                Ok(p) => Self::Own(p),
                Err(e) => {
                    tracing::warn!(
                        "markers: no pool of their own ({e}); drawing on the shared one"
                    );
                    Self::Global
                }
            };
        }
        match self {
            Self::Own(p) => p.install(work),
            _ => work(),
        }
    }
}

impl CheckerMarkers {
    /// Draws the queued slabs, in queue order: each body's markers only where they changed
    /// (see [`slab_markers`]); the slabs whose geometry changed are sliced in parallel, on
    /// the part's pool. Run behind, only the slabs of the steps up to `through` (`None`:
    /// all).
    fn publish(&mut self, through: Option<u64>, out: &mut Vec<Message>) {
        let (slabs, skipped, restart) = self
            .queue
            .lock()
            .map(|mut q| q.take(through))
            .unwrap_or_default();
        if restart {
            self.shown.clear();
        }
        if skipped > 0 {
            self.status
                .count_quietly(&self.fqn, "markers_coalesced", skipped, || {
                    "the markers part fell behind: only each body's newest slab was drawn (a \
                     display wants the latest state); labels, contacts and the report are \
                     complete"
                        .to_owned()
                });
        }
        if slabs.is_empty() {
            return;
        }
        let (shown, topic) = (&mut self.shown, self.markers_topic.as_str());
        let drawn = self.pool.install(|| draw(shown, topic, &slabs));
        self.status.published += drawn.len() as u64;
        out.extend(drawn);
    }
}

/// The markers of `slabs` (with their frame ids), in order, where they changed from what
/// `shown` holds (updated).
fn draw(
    shown: &mut std::collections::BTreeMap<String, Shown>,
    topic: &str,
    slabs: &[(String, SlabDone)],
) -> Vec<Message> {
    // Each slab's geometry hash, and its slice where it is new to its body (bodies in
    // order; a body's later slab compares with its earlier one in this batch).
    let hashes: Vec<u64> = slabs
        .par_iter()
        .map(|(_, d)| geometry_hash(&d.mesh))
        .collect();
    let mut last: std::collections::BTreeMap<&str, u64> = shown
        .iter()
        .map(|(b, s)| (b.as_str(), s.geometry))
        .collect();
    let new: Vec<bool> = slabs
        .iter()
        .zip(&hashes)
        .map(|((_, d), &h)| last.insert(d.body.as_str(), h) != Some(h))
        .collect();
    let slices: Vec<Option<Arc<Drawn>>> = slabs
        .par_iter()
        .zip(&new)
        .map(|((_, d), &is_new)| is_new.then(|| Arc::new(slice_slab(d))))
        .collect();
    slabs
        .iter()
        .zip(hashes)
        .zip(slices)
        .filter_map(|(((f, d), h), slice)| slab_markers(shown, f, topic, d, h, slice))
        .collect()
}

impl Node for CheckerMarkers {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        vec![TopicRef {
            topic: self.slabs_done_topic.clone(),
            type_name: chronotope_msg::Clock::TYPE_NAME,
        }]
    }

    fn publications(&self) -> Vec<TopicRef> {
        vec![TopicRef {
            topic: self.markers_topic.clone(),
            type_name: MarkerArray::TYPE_NAME,
        }]
    }

    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        let _ = msg;
        self.status.received += 1;
        self.publish(Some(self.nudges), out);
        self.nudges += 1;
    }

    fn run_behind(&mut self) -> bool {
        // Each nudge then takes its own step's slabs, whenever it is handled; nothing is
        // dropped or coalesced (the bus bounds the steps waiting), so what is drawn is what
        // drawing in turn draws.
        if let Ok(mut q) = self.queue.lock() {
            q.behind = true;
        }
        self.pool = MarkersPool::Global;
        true
    }

    fn set_demand(&mut self, topic: &str, read: bool) {
        if topic != self.markers_topic {
            return;
        }
        if let Ok(mut q) = self.queue.lock() {
            if q.unread && read {
                q.restart = true;
            }
            q.unread = !read;
            if !read {
                q.take(None);
            }
        }
    }

    fn on_messages(&mut self, msgs: &[Message], out: &mut Vec<Message>) {
        // Several nudges waiting: the queue holds all their slabs; one pass takes them.
        self.status.received += msgs.len() as u64;
        self.nudges += msgs.len() as u64;
        self.publish(self.nudges.checked_sub(1), out);
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        self.publish(None, out);
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        4
    }
}

/// A hash of a slab's tets in space (vertices' x, y, z and the tets), which a body at rest
/// repeats from slab to slab (the mesher moves its rest slab in time).
fn geometry_hash(mesh: &TetMesh) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = WordHasher::default();
    mesh.vertices.len().hash(&mut h);
    for v in &mesh.vertices {
        (v[0], v[1], v[2]).hash(&mut h);
    }
    mesh.tets.hash(&mut h);
    h.finish()
}

/// The slab's t-slice at its later frame ([`slab_end_plane`]: the faces of its tets in that
/// plane), with each triangle's tet (the tets are scanned on rayon's pool: the same slice),
/// and its flat faces merged for display.
fn slice_slab(d: &SlabDone) -> Drawn {
    let mut slicer =
        Slicer::new(3, slab_end_plane(u64::from(d.index), d.geometry.scale)).with_sources();
    slicer.add_par(&d.mesh);
    let (mesh, sources) = slicer.finish_with_sources();
    let flats = FlatFaces::of(&mesh);
    let (merged, _) = merge_flat_with(&mesh, &flats, |_| Some(0));
    Drawn {
        mesh,
        sources,
        flats,
        merged,
    }
}

/// The markers of slab `d` where they changed, as one MarkerArray (`None`: nothing changed).
/// A body has three markers, kept until replaced (persistent, as rviz2 and Foxglove keep
/// them), stamped with the slab's later frame, the instant they show: id 0 the body's
/// t-slice there in its own colour, translucent; id 1 the triangles INSIDE
/// another body (orange) and id 2 those that INTERFERE (red), drawn over it. The slice is
/// published when the body's geometry changes (`slice` is then the new one); the label
/// markers when their triangles change (a DELETE when they have none left); a body at rest
/// away from the others publishes nothing after its first slab.
fn slab_markers(
    shown: &mut std::collections::BTreeMap<String, Shown>,
    frame_id: &str,
    topic: &str,
    d: &SlabDone,
    geometry: u64,
    slice: Option<Arc<Drawn>>,
) -> Option<Message> {
    let g = d.geometry;
    // The instant drawn: the slab's later frame.
    let stamp = d.stamps_ns.1;
    let header = Header {
        stamp: Time::from_nanos(stamp),
        frame_id: frame_id.to_owned(),
    };
    let base = body_color(&d.body);
    let (slice, new_geometry) = match (slice, shown.get(&d.body)) {
        (Some(s), _) => (s, true),
        (None, Some(prev)) => (prev.slice.clone(), false),
        // The body's geometry is new to the part after all: slice it now.
        (None, None) => (Arc::new(slice_slab(d)), true),
    };
    let (tri, src) = (&slice.mesh, &slice.sources);
    let label_of = |t: usize| d.worst.get(src[t] as usize).copied().unwrap_or(0);
    let wanted = [Label::Inside as u8, Label::Interference as u8];
    let colors = [INSIDE_COLOR, INTERFERENCE_COLOR];
    let labelled: [Vec<u32>; 2] = wanted.map(|want| {
        (0..tri.triangles.len() as u32)
            .filter(|&t| label_of(t as usize) == want)
            .collect()
    });
    let before = shown.get(&d.body).map(|s| &s.labels);
    let mut markers = Vec::new();
    if new_geometry {
        markers.push(triangle_list_of(
            header.clone(),
            &d.body,
            0,
            &g,
            tri,
            &slice.merged,
            ColorRGBA { a: 0.45, ..base },
        ));
    }
    for k in 0..2 {
        let was = before.map_or(&[][..], |b| &b[k][..]);
        // Redrawn where its triangles changed, and over a new slice (its points moved).
        let redraw = labelled[k] != was || (new_geometry && !labelled[k].is_empty());
        if !redraw {
            continue;
        }
        let (merged, _) = merge_flat_with(tri, &slice.flats, |t| {
            (label_of(t) == wanted[k]).then_some(0)
        });
        markers.push(triangle_list_of(
            header.clone(),
            &d.body,
            k as i32 + 1,
            &g,
            tri,
            &merged,
            colors[k],
        ));
    }
    shown.insert(
        d.body.clone(),
        Shown {
            geometry,
            slice: slice.clone(),
            labels: labelled,
        },
    );
    (!markers.is_empty()).then(|| {
        Message::new(
            topic,
            stamp,
            Payload::MarkerArray(Arc::new(MarkerArray { markers })),
        )
    })
}

/// Live, the most steps a changed report is left waiting for the statistics being added
/// before it is published as it stands (without them), when no tick comes between them (a
/// node behind its input): at 30 frames a second about half a second of a cell's messages.
const REPORT_WAIT: u32 = 16;

fn nan_if_none(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

/// The report as a ROS message (`voxel_size_m`: the common lattice's voxel edge).
pub fn report_message(r: &Report, voxel_size_m: f64, header: Header) -> InterferenceReport {
    InterferenceReport {
        header,
        time_origin: Time::from_nanos(r.time_origin_ns),
        time_scale_m_per_s: r.time_scale_m_per_s,
        voxel_size_m,
        bodies: r
            .bodies
            .iter()
            .map(|b| BodySummary {
                body_id: b.id.clone(),
                frames: b.frames,
                skipped_frames: b.skipped_frames,
                tets: b.tets,
                vertices: b.vertices,
                closed: b.closed,
                hypervolume_m3s: b.hypervolume_m3s,
                vanishing_slabs: b.vanishing_slabs,
            })
            .collect(),
        pairs: r
            .pairs
            .iter()
            .map(|p| PairInterference {
                body_a: p.a.clone(),
                body_b: p.b.clone(),
                verdict: match p.verdict {
                    Verdict::Clear => PairInterference::VERDICT_CLEAR,
                    Verdict::Collide => PairInterference::VERDICT_COLLIDE,
                    Verdict::Unsure => PairInterference::VERDICT_UNSURE,
                },
                unsure_start_s: p.unsure_spans_s.iter().map(|u| u.span_s[0]).collect(),
                unsure_end_s: p.unsure_spans_s.iter().map(|u| u.span_s[1]).collect(),
                unsure_reason: p.unsure_spans_s.iter().map(|u| u.line()).collect(),
                interfering: p.interfering,
                interval_start_s: p.intervals_s.iter().map(|i| i[0]).collect(),
                interval_end_s: p.intervals_s.iter().map(|i| i[1]).collect(),
                first_contact_s: nan_if_none(p.first_contact_s),
                first_contact_error_bound_s: nan_if_none(p.first_contact_error_bound_s),
                closing_speed_mps: nan_if_none(p.closing_speed_mps),
                overlap_hypervolume_m3s: nan_if_none(p.overlap_hypervolume_m3s),
                overlap_hypervolume_error_bound_m3s: nan_if_none(
                    p.overlap_hypervolume_error_bound_m3s,
                ),
                a_interference: p.labels.a.interference,
                a_inside: p.labels.a.inside,
                a_outside: p.labels.a.outside,
                b_interference: p.labels.b.interference,
                b_inside: p.labels.b.inside,
                b_outside: p.labels.b.outside,
            })
            .collect(),
    }
}

fn suggestion_message(r: &Resolution) -> ResolveSuggestion {
    let mut m = suggestion_fields(r);
    m.unsure_start_s = r.unsure_s().iter().map(|u| u[0]).collect();
    m.unsure_end_s = r.unsure_s().iter().map(|u| u[1]).collect();
    m
}

fn suggestion_fields(r: &Resolution) -> ResolveSuggestion {
    match r {
        Resolution::Translate {
            body,
            vector,
            distance,
            verified_clear,
            distance_error_bound_m,
            episode_s,
            ..
        } => ResolveSuggestion {
            body_id: body.clone(),
            kind: ResolveSuggestion::KIND_TRANSLATE,
            translation: Vector3::new(vector[0], vector[1], vector[2]),
            time_shift_s: vector[3],
            distance: *distance,
            distance_error_bound_m: *distance_error_bound_m,
            t0_s: f64::NAN,
            scale: f64::NAN,
            axis: Vector3::default(),
            point: Point::default(),
            angle_rad: f64::NAN,
            verified_clear: *verified_clear,
            episode_start_s: episode_s[0],
            episode_end_s: episode_s[1],
            ..ResolveSuggestion::default()
        },
        Resolution::TimeScale {
            body,
            t0_s,
            scale,
            verified_clear,
            episode_s,
            ..
        } => ResolveSuggestion {
            body_id: body.clone(),
            kind: ResolveSuggestion::KIND_TIME_SCALE,
            translation: Vector3::default(),
            time_shift_s: f64::NAN,
            distance: f64::NAN,
            distance_error_bound_m: f64::NAN,
            t0_s: *t0_s,
            scale: *scale,
            axis: Vector3::default(),
            point: Point::default(),
            angle_rad: f64::NAN,
            verified_clear: *verified_clear,
            episode_start_s: episode_s[0],
            episode_end_s: episode_s[1],
            ..ResolveSuggestion::default()
        },
        Resolution::Rotate {
            body,
            axis,
            point_m,
            angle_rad,
            verified_clear,
            episode_s,
            ..
        } => ResolveSuggestion {
            body_id: body.clone(),
            kind: ResolveSuggestion::KIND_ROTATE,
            translation: Vector3::default(),
            time_shift_s: f64::NAN,
            distance: f64::NAN,
            distance_error_bound_m: f64::NAN,
            t0_s: f64::NAN,
            scale: f64::NAN,
            axis: Vector3::new(axis[0], axis[1], axis[2]),
            point: Point {
                x: point_m[0],
                y: point_m[1],
                z: point_m[2],
            },
            angle_rad: *angle_rad,
            verified_clear: *verified_clear,
            episode_start_s: episode_s[0],
            episode_end_s: episode_s[1],
            ..ResolveSuggestion::default()
        },
    }
}

impl Node for CheckerNode {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        let mut s = vec![TopicRef {
            topic: self.mesh_topic.clone(),
            type_name: MeshSlab::TYPE_NAME,
        }];
        s.extend(self.bodies.iter().map(|t| TopicRef {
            topic: t.clone(),
            type_name: VoxelGrid::TYPE_NAME,
        }));
        s
    }

    fn publications(&self) -> Vec<TopicRef> {
        let mut p = vec![
            TopicRef {
                topic: self.report_topic.clone(),
                type_name: InterferenceReport::TYPE_NAME,
            },
            TopicRef {
                topic: self.contacts_topic.clone(),
                type_name: ContactEvent::TYPE_NAME,
            },
        ];
        // With `markers`, its markers part publishes them; this node tells it when.
        let slabs_done = self
            .markers_queue
            .as_ref()
            .map(|_| self.slabs_done_topic.clone());
        let optional = [
            (&self.labels_topic, TetLabels::TYPE_NAME),
            (&self.suggestions_topic, ResolveSuggestions::TYPE_NAME),
            (&slabs_done, chronotope_msg::Clock::TYPE_NAME),
        ];
        for (topic, type_name) in optional {
            p.extend(topic.iter().map(|t| TopicRef {
                topic: t.clone(),
                type_name,
            }));
        }
        p
    }

    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        self.status.received += 1;
        self.follow_markers_demand();
        match &msg.payload {
            Payload::MeshSlab(s) if *msg.topic == *self.mesh_topic => self.on_piece(s, out),
            Payload::VoxelGrid(g) if *msg.topic != *self.mesh_topic => {
                self.on_frame(&msg.topic, g, out)
            }
            other => self.status.problem(
                &self.fqn,
                "wrong_type",
                format!(
                    "{}: an unexpected {}; ignored",
                    msg.topic,
                    other.type_name()
                ),
            ),
        }
        if self.live {
            self.poll_resolutions(out);
        }
    }

    fn on_tick(&mut self, _now_ns: i64, _out: &mut Vec<Message>) {
        self.follow_markers_demand();
    }

    fn poll(&mut self, out: &mut Vec<Message>) {
        self.live = true;
        self.poll_resolutions(out);
        // A tick comes when the node has caught up with its input: waiting for the
        // statistics here holds back no event.
        let before = out.len();
        self.publish_report_if_changed(true, out);
        self.status.published += (out.len() - before) as u64;
    }

    fn set_demand(&mut self, topic: &str, read: bool) {
        if self.labels_topic.as_deref() == Some(topic) {
            self.engine.set_labels(read);
        }
        let report = if topic == self.report_topic {
            Some(&mut self.report_read.0)
        } else if self.suggestions_topic.as_deref() == Some(topic) {
            Some(&mut self.report_read.1)
        } else {
            None
        };
        if let Some(r) = report {
            // Its new reader is owed the answer so far (a late joiner of the transient
            // local report gets it at once from the writer, but only once it is written).
            if read && !*r {
                self.dirty = true;
            }
            *r = read;
            let wanted = self.report_wanted();
            self.engine.set_reports(wanted);
        }
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        self.follow_markers_demand();
        let mut rolled = Vec::new();
        self.engine.finish(&mut rolled);
        self.dirty = true;
        // The last report is the answer (the replay's, a stream's end): built read or not.
        self.report_read = (true, true);
        self.engine.set_reports(true);
        self.emit_then_report(rolled, true, out);
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        3
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronotope_mesh::TetMesh;

    fn slab(index: u32, tets: usize) -> SlabDone {
        SlabDone {
            body: "/a".into(),
            index,
            stamps_ns: (i64::from(index), i64::from(index) + 1),
            geometry: GridGeometry {
                origin: [0.0; 3],
                resolution: 0.1,
                size: [2, 2, 2],
                encoding: VoxelGrid::ENCODING_BITS,
                scale: 2,
            },
            mesh: Arc::new(TetMesh {
                vertices: Vec::new(),
                tets: vec![[0, 0, 0, 0]; tets],
            }),
            worst: Vec::new(),
        }
    }

    #[test]
    fn the_markers_queue_drops_its_oldest_slabs_beyond_its_tet_limit_and_keeps_the_newest() {
        let mut q = MarkerQueue::default();
        let third = MARKER_QUEUE_TETS / 3;
        assert_eq!(q.push("w", slab(0, third)), 0);
        assert_eq!(q.push("w", slab(1, third)), 0);
        assert_eq!(q.push("w", slab(2, third)), 0);
        // A fourth third is over the limit: the oldest goes.
        assert_eq!(q.push("w", slab(3, third)), 1);
        // A slab over the limit on its own still waits (the newest is never dropped).
        assert_eq!(q.push("w", slab(4, MARKER_QUEUE_TETS + 1)), 3);
        let (left, skipped, _) = q.take(None);
        assert_eq!((left.len(), skipped), (1, 0));
        assert_eq!(left[0].1.index, 4);
        assert_eq!(left[0].0, "w");
        assert!(q.take(None).0.is_empty());
    }

    #[test]
    fn a_markers_part_behind_draws_each_bodys_newest_slab_only() {
        let mut q = MarkerQueue::default();
        let with_body = |i: u32, body: &str| {
            let mut d = slab(i, 8);
            d.body = body.to_owned();
            d
        };
        // One checker step: every slab is drawn, in order.
        q.push("w", with_body(0, "/a"));
        q.push("w", with_body(1, "/a"));
        q.end_step();
        let (all, skipped, _) = q.take(None);
        assert_eq!((all.len(), skipped), (2, 0));
        // Three steps queued before the part takes them: the newest of each body.
        for (i, b) in [(2, "/a"), (3, "/b")] {
            q.push("w", with_body(i, b));
            q.end_step();
        }
        q.push("w", with_body(4, "/a"));
        q.end_step();
        let (newest, skipped, _) = q.take(None);
        let got: Vec<(u32, &str)> = newest
            .iter()
            .map(|(_, d)| (d.index, d.body.as_str()))
            .collect();
        assert_eq!(got, [(3, "/b"), (4, "/a")]);
        assert_eq!(skipped, 1);
    }

    /// The live markers part's pool runs at a lower priority than the thread that drew on
    /// it, which keeps its own; run behind, it draws on rayon's pool.
    #[cfg(target_os = "linux")]
    #[test]
    fn the_live_markers_pool_yields_to_the_check() {
        // The calling thread's nice value (field 19 of its stat, after the name).
        let nice = || -> i32 {
            let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
            let after_name = &stat[stat.rfind(')').unwrap() + 2..];
            after_name.split(' ').nth(16).unwrap().parse().unwrap()
        };
        let mine = nice();
        let mut pool = MarkersPool::Unmade;
        let theirs = pool.install(nice);
        assert!(matches!(pool, MarkersPool::Own(_)));
        assert_eq!(theirs, (mine + MARKERS_NICE).min(19), "mine {mine}");
        assert_eq!(nice(), mine);
        assert_eq!(MarkersPool::Global.install(nice), mine);
    }

    #[test]
    fn a_markers_part_run_behind_takes_each_nudges_step_whole_and_drops_nothing() {
        let mut q = MarkerQueue {
            behind: true,
            ..MarkerQueue::default()
        };
        let half = MARKER_QUEUE_TETS / 2;
        // Step 0 and step 1 queued before the part handles the first nudge, over the limit.
        assert_eq!(q.push("w", slab(0, half)), 0);
        assert_eq!(q.push("w", slab(1, half)), 0);
        q.end_step();
        assert_eq!(q.push("w", slab(2, half)), 0);
        let index = |v: &[(String, SlabDone)]| v.iter().map(|x| x.1.index).collect::<Vec<_>>();
        let (first, skipped, _) = q.take(Some(0));
        assert_eq!((index(&first), skipped), (vec![0, 1], 0));
        q.end_step();
        let (second, skipped, _) = q.take(Some(1));
        assert_eq!((index(&second), skipped), (vec![2], 0));
        assert_eq!(q.tets, 0);
    }
}
