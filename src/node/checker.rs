//! The checker node: the mesh pieces of every body in (`mesh_topic`, chronotope_msgs/MeshSlab),
//! and the bodies' VoxelGrid frames (to measure overlaps); when the inputs end, the report
//! (`~/report`), every tet's label per pair (`~/labels`), resolve suggestions for the movable
//! bodies (`~/suggestions`) and, if asked, a MarkerArray per frame period with each body's
//! t-slice coloured by label (`~/markers`).
//!
//! Parameters: `pairs` (string array, each `"BODY_A BODY_B"`; default: every pair of the
//! bodies the transport names), `movable` (string array, default none: no resolution),
//! `time_scale_m_per_s` (double, 0 = one voxel per frame period), `labels` (bool, default
//! true), `markers` (bool, default false), `mesh_topic` (default `/mesher/mesh_slabs`), and the
//! mesher's decoding parameters (`iso_percent`, `unknown_occupied`, `percent_scale`,
//! `max_slab_tets`), which must match the mesher's.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

use super::launch::{LaunchError, NodeSpec, Params};
use super::markers::{body_color, mid_slab_plane, triangle_list};
use super::mesher::mesher_options;
use super::{Message, Node, NodeStatus, Payload, TopicRef};
use crate::checker::labels::Label;
use crate::checker::prep::BodyPrep;
use crate::checker::StreamWalk;
use crate::cli::frame_ref;
use crate::mesh::glue::{BodyGluer, BodyMesh};
use crate::mesh::slice::Slicer;
use crate::mesh::stats::LateralRef;
use crate::mesh::{GridGeometry, MesherOptions, OccupancyGrid};
use crate::msg::{
    BodySummary, ColorRGBA, Header, InterferenceReport, MarkerArray, MeshSlab, PairInterference,
    ResolveSuggestion, ResolveSuggestions, RosMessage, TetLabels, Time, Vector3, VoxelGrid,
};
use crate::report::{check_streamed, CheckOutcome, CheckPlan, Report, Resolution};

/// Label colours of the markers.
const INTERFERENCE_COLOR: ColorRGBA = ColorRGBA::new(0.9, 0.05, 0.05, 1.0);
const INSIDE_COLOR: ColorRGBA = ColorRGBA::new(1.0, 0.6, 0.0, 0.95);

#[derive(Default)]
struct Body {
    gluer: BodyGluer,
    /// The body's trees, adjacency and normals, built piece by piece as they are welded,
    /// so that a check at the end of the stream does not wait for them.
    prep: BodyPrep,
    stamps_ns: Vec<i64>,
    geometry: Option<GridGeometry>,
    frame_id: String,
    started: bool,
    ended: bool,
    next_index: u32,
    frames: BTreeMap<i64, OccupancyGrid>,
    /// Pieces came without the opening cap (this node started after the body's stream did):
    /// said once; the body's pieces are skipped until its next stream starts.
    joined_late: bool,
    /// Preparing the mesh failed (said once).
    prep_failed: bool,
}

/// The checker node.
pub struct CheckerNode {
    fqn: String,
    plan: CheckPlan,
    opts: MesherOptions,
    mesh_topic: String,
    report_topic: String,
    labels_topic: Option<String>,
    suggestions_topic: Option<String>,
    markers_topic: Option<String>,
    bodies: BTreeMap<String, Body>,
    /// A piece came since the last check.
    pending: bool,
    /// Each planned pair's tree walk, done piece by piece while both bodies share one
    /// lattice and first frame (keyed by the ids in sorted order).
    walks: BTreeMap<(String, String), StreamWalk>,
    outcome: Option<CheckOutcome>,
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
                    out.push((p.resolve("pairs", a)?, p.resolve("pairs", b)?));
                }
                Some(out)
            }
        };
        let movable = p.topics("movable")?.unwrap_or_default();
        let c = p.double("time_scale_m_per_s", 0.0, 0.0..=1e12)?;
        let labels = p.bool("labels", true)?;
        let markers = p.bool("markers", false)?;
        let mesh_topic = p.topic("mesh_topic", "/mesher/mesh_slabs")?;
        let opts = mesher_options(&mut p)?;
        let report_topic = p.resolve("~/report", "~/report")?;
        let labels_topic = labels
            .then(|| p.resolve("~/labels", "~/labels"))
            .transpose()?;
        let suggestions_topic = (!movable.is_empty())
            .then(|| p.resolve("~/suggestions", "~/suggestions"))
            .transpose()?;
        let markers_topic = markers
            .then(|| p.resolve("~/markers", "~/markers"))
            .transpose()?;
        p.finish()?;
        let pairs = pairs.unwrap_or_else(|| {
            let mut ids = default_bodies.to_vec();
            ids.sort();
            ids.dedup();
            (0..ids.len())
                .flat_map(|i| (i + 1..ids.len()).map(move |j| (i, j)))
                .map(|(i, j)| (ids[i].clone(), ids[j].clone()))
                .collect()
        });
        let in_pairs: BTreeSet<&String> = pairs.iter().flat_map(|(a, b)| [a, b]).collect();
        if let Some(m) = movable.iter().find(|m| !in_pairs.contains(m)) {
            return Err(bad("movable", format!("{m} is in no checked pair")));
        }
        let bodies = in_pairs
            .iter()
            .map(|id| ((*id).clone(), Body::default()))
            .collect();
        Ok(Self {
            fqn: node,
            plan: CheckPlan {
                pairs: Some(pairs),
                movable,
                time_scale: (c > 0.0).then_some(c),
            },
            opts,
            mesh_topic,
            report_topic,
            labels_topic,
            suggestions_topic,
            markers_topic,
            bodies,
            pending: false,
            walks: BTreeMap::new(),
            outcome: None,
            status: NodeStatus::default(),
        })
    }

    /// The bodies its pairs use (the mesher need not mesh any other).
    pub fn bodies(&self) -> impl Iterator<Item = &str> {
        self.bodies.keys().map(String::as_str)
    }

    /// The topic it reads mesh pieces from.
    pub fn mesh_topic(&self) -> &str {
        &self.mesh_topic
    }

    /// The report of the last check (after [`Node::finish`]).
    pub fn report(&self) -> Option<&Report> {
        self.outcome.as_ref().map(|o| &o.report)
    }

    fn on_piece(&mut self, s: &MeshSlab) {
        let Some(b) = self.bodies.get_mut(&s.body_id) else {
            return; // a body no pair uses
        };
        let g = s.geometry();
        let mut problem = None;
        if b.ended {
            problem = Some(format!(
                "{}: a piece after the closing cap; ignored",
                s.body_id
            ));
        } else if b.geometry.is_some_and(|bg| bg != g) {
            problem = Some(format!(
                "{}: a piece on another lattice; ignored",
                s.body_id
            ));
        }
        if let Some(p) = problem {
            self.status.problem(&self.fqn, "bad_piece", p);
            return;
        }
        b.geometry = Some(g);
        if b.frame_id.is_empty() {
            b.frame_id = s.header.frame_id.clone();
        }
        self.pending = true;
        if s.kind == MeshSlab::KIND_CAP_START && b.started {
            // The mesher started this body's mesh again: it was restarted, or the stream
            // went idle and resumed. What came before of this body is dropped.
            let why = format!(
                "{}: the mesh starts again after {} piece(s){}; the earlier pieces are dropped",
                s.body_id,
                b.next_index,
                if b.ended {
                    ""
                } else {
                    " without a closing cap (a restarted mesher?)"
                }
            );
            self.status.problem(&self.fqn, "stream_restarted", why);
            self.walks
                .retain(|(x, y), _| *x != s.body_id && *y != s.body_id);
            *b = Body {
                frames: std::mem::take(&mut b.frames),
                ..Body::default()
            };
        }
        match s.kind {
            MeshSlab::KIND_CAP_START if !b.started && b.next_index == 0 => {
                b.started = true;
                b.joined_late = false;
                b.gluer.first_cap(&s.mesh, s.occupied_voxels);
            }
            MeshSlab::KIND_LATERAL if s.index == b.next_index => {
                if b.stamps_ns.is_empty() {
                    b.stamps_ns.push(s.stamp_lo.as_nanos());
                }
                b.stamps_ns.push(s.stamp_hi.as_nanos());
                b.next_index += 1;
                b.gluer.lateral(
                    LateralRef {
                        index: u64::from(s.index),
                        stamps_ns: (s.stamp_lo.as_nanos(), s.stamp_hi.as_nanos()),
                        geometry: &g,
                        mesh: &s.mesh,
                        vanishes: s.vanishes,
                    },
                    None,
                );
            }
            MeshSlab::KIND_CAP_END if b.next_index > 0 => {
                b.ended = true;
                b.gluer.last_cap(&s.mesh, s.occupied_voxels);
            }
            _ if !b.started && b.joined_late => {}
            MeshSlab::KIND_LATERAL | MeshSlab::KIND_CAP_END if !b.started => {
                b.joined_late = true;
                let why = format!(
                    "{}: the first piece seen is index {} (this node started after the body's \
                     stream did, or missed its start): the pieces before are gone, so this \
                     stream of the body is skipped; it is checked from its next stream",
                    s.body_id, s.index
                );
                self.status.problem(&self.fqn, "joined_mid_stream", why);
            }
            kind => {
                let why = format!(
                    "{}: piece kind {kind} index {} out of order (expected index {}); ignored, \
                     the body's mesh will not be closed",
                    s.body_id, s.index, b.next_index
                );
                self.status.problem(&self.fqn, "piece_out_of_order", why);
            }
        }
        if b.prep.len() < b.gluer.tets() {
            match b.prep.add(b.gluer.mesh()) {
                Ok(()) => self.advance_walks(&s.body_id),
                Err(e) => {
                    // Said once: the check names the body and the reason again.
                    if !b.prep_failed {
                        b.prep_failed = true;
                        let why = format!(
                            "{}: the mesh cannot be prepared for checking: {e}",
                            s.body_id
                        );
                        self.status.problem(&self.fqn, "bad_mesh", why);
                    }
                }
            }
        }
    }

    /// Walks the new pieces of body `id` against the bodies it is paired with, for each
    /// pair whose bodies share one lattice and first frame (others are walked at the end).
    fn advance_walks(&mut self, id: &str) {
        let Some(me) = self.bodies.get(id) else {
            return;
        };
        let same_start = |a: &Body, b: &Body| {
            a.geometry.is_some()
                && a.geometry == b.geometry
                && a.stamps_ns.first().is_some()
                && a.stamps_ns.first() == b.stamps_ns.first()
        };
        for (other_id, other) in &self.bodies {
            if other_id == id || !self.plan.pairs_with(id, other_id) || !same_start(me, other) {
                continue;
            }
            let (x, y, key) = if id < other_id.as_str() {
                (me, other, (id.to_string(), other_id.clone()))
            } else {
                (other, me, (other_id.clone(), id.to_string()))
            };
            self.walks.entry(key).or_default().advance(&x.prep, &y.prep);
        }
    }

    fn on_frame(&mut self, topic: &str, g: &VoxelGrid) {
        let Some(b) = self.bodies.get_mut(topic) else {
            return;
        };
        // Frames the mesher refuses are refused here too (and counted there).
        if let Ok(grid) = OccupancyGrid::decode(&frame_ref(g), &self.opts.decode) {
            b.frames.insert(g.header.stamp.as_nanos(), grid);
        }
    }

    /// The glued meshes of every body, and what of them is prepared for checking; the
    /// bodies start over, empty, for the next stream.
    fn body_meshes(&mut self) -> (BTreeMap<String, BodyMesh>, BTreeMap<String, BodyPrep>) {
        let (mut out, mut preps) = (BTreeMap::new(), BTreeMap::new());
        let bodies = std::mem::take(&mut self.bodies);
        self.bodies = bodies
            .keys()
            .map(|k| (k.clone(), Body::default()))
            .collect();
        for (id, b) in bodies {
            let mut frames: Vec<OccupancyGrid> = Vec::with_capacity(b.stamps_ns.len());
            let mut frame_map = b.frames;
            for s in &b.stamps_ns {
                match frame_map.remove(s) {
                    Some(f) => frames.push(f),
                    None => {
                        frames.clear();
                        break;
                    }
                }
            }
            let n = b.stamps_ns.len() as u64;
            let mut body = b.gluer.finish(n, b.stamps_ns, b.geometry);
            body.frames = frames;
            preps.insert(id.clone(), b.prep);
            out.insert(id, body);
        }
        (out, preps)
    }

    fn publish(&self, o: &CheckOutcome, frame_id: &str, out: &mut Vec<Message>) {
        let Some(lat) = &o.lattice else {
            return;
        };
        let last = *lat.stamps_ns.last().expect("a lattice has frames");
        let header = Header {
            stamp: Time::from_nanos(last),
            frame_id: frame_id.to_owned(),
        };
        out.push(Message::new(
            &self.report_topic,
            last,
            Payload::Report(Arc::new(report_message(
                &o.report,
                lat.resolution,
                header.clone(),
            ))),
        ));
        if let Some(topic) = &self.labels_topic {
            for (i, j, r) in &o.results {
                for (me, other, labels) in [(*i, *j, &r.labels_a), (*j, *i, &r.labels_b)] {
                    let raw: Vec<u8> = labels.labels.iter().map(|&l| l as u8).collect();
                    let c = labels.counts();
                    let m = TetLabels {
                        header: header.clone(),
                        body_id: o.ids[me].clone(),
                        other_id: o.ids[other].clone(),
                        labels: o.prepared[me].in_original_order(&raw),
                        interference: c.interference,
                        inside: c.inside,
                        outside: c.outside,
                    };
                    out.push(Message::new(topic, last, Payload::TetLabels(Arc::new(m))));
                }
            }
        }
        if let Some(topic) = &self.suggestions_topic {
            let m = ResolveSuggestions {
                header: header.clone(),
                suggestions: o
                    .report
                    .resolutions
                    .iter()
                    .map(suggestion_message)
                    .collect(),
            };
            out.push(Message::new(topic, last, Payload::Suggestions(Arc::new(m))));
        }
        if let Some(topic) = &self.markers_topic {
            marker_frames(o, frame_id, topic, out);
        }
    }
}

/// One MarkerArray per frame period: each checked body's slice a little after the middle of
/// the period, its triangles coloured by the strongest label of their tet over all pairs.
fn marker_frames(o: &CheckOutcome, frame_id: &str, topic: &str, out: &mut Vec<Message>) {
    let Some(lat) = &o.lattice else {
        return;
    };
    let per = lat.per_step();
    let g = GridGeometry {
        origin: lat.voxel0_centre.map(|c| c - 0.5 * lat.resolution),
        resolution: lat.resolution,
        size: [0; 3],
        encoding: 0,
        scale: per as i32,
    };
    let slabs = lat.stamps_ns.len() - 1;
    // Per body: strongest label per tet, and its tets bucketed by frame period.
    let mut worst: Vec<Vec<u8>> = o
        .prepared
        .iter()
        .map(|p| vec![0; p.mesh.tets.len()])
        .collect();
    for (i, j, r) in &o.results {
        for (me, l) in [(*i, &r.labels_a), (*j, &r.labels_b)] {
            for (w, &x) in worst[me].iter_mut().zip(&l.labels) {
                *w = (*w).max(x as u8);
            }
        }
    }
    let buckets: Vec<Vec<Vec<u32>>> = o
        .prepared
        .iter()
        .map(|p| {
            let mut b = vec![Vec::new(); slabs];
            for (ti, t) in p.mesh.tets.iter().enumerate() {
                let ts = t.map(|v| i64::from(p.mesh.vertices[v as usize][3]));
                let (lo, hi) = (*ts.iter().min().unwrap(), *ts.iter().max().unwrap());
                if lo == hi {
                    continue; // a cap tet lies in a frame plane; mid-period planes miss it
                }
                let first = lo.div_euclid(per).max(0) as usize;
                let last = ((hi - 1).div_euclid(per).max(0) as usize).min(slabs.saturating_sub(1));
                for bucket in &mut b[first..=last] {
                    bucket.push(ti as u32);
                }
            }
            b
        })
        .collect();
    #[allow(clippy::needless_range_loop)] // k indexes the stamps and every body's buckets
    for k in 0..slabs {
        let stamp = lat.stamps_ns[k] + (lat.stamps_ns[k + 1] - lat.stamps_ns[k]) / 2;
        let header = Header {
            stamp: Time::from_nanos(stamp),
            frame_id: frame_id.to_owned(),
        };
        let markers = o
            .prepared
            .iter()
            .enumerate()
            .map(|(bi, p)| {
                let mut s = Slicer::new(3, mid_slab_plane(k as u64, per as i32)).with_sources();
                s.add_some(&p.mesh, &buckets[bi][k]);
                let (tri, src) = s.finish_with_sources();
                let base = body_color(&p.id);
                let outside = ColorRGBA { a: 0.45, ..base };
                triangle_list(header.clone(), &p.id, 0, &g, &tri, |t| {
                    match worst[bi][src[t] as usize] {
                        x if x == Label::Interference as u8 => INTERFERENCE_COLOR,
                        x if x == Label::Inside as u8 => INSIDE_COLOR,
                        _ => outside,
                    }
                })
            })
            .collect();
        out.push(Message::new(
            topic,
            stamp,
            Payload::MarkerArray(Arc::new(MarkerArray { markers })),
        ));
    }
}

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
    match r {
        Resolution::Translate {
            body,
            vector,
            distance,
            verified_clear,
            distance_error_bound_m,
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
            verified_clear: *verified_clear,
        },
        Resolution::TimeScale {
            body,
            t0_s,
            scale,
            verified_clear,
        } => ResolveSuggestion {
            body_id: body.clone(),
            kind: ResolveSuggestion::KIND_TIME_SCALE,
            translation: Vector3::default(),
            time_shift_s: f64::NAN,
            distance: f64::NAN,
            distance_error_bound_m: f64::NAN,
            t0_s: *t0_s,
            scale: *scale,
            verified_clear: *verified_clear,
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
        s.extend(self.bodies.keys().map(|t| TopicRef {
            topic: t.clone(),
            type_name: VoxelGrid::TYPE_NAME,
        }));
        s
    }

    fn publications(&self) -> Vec<TopicRef> {
        let mut p = vec![TopicRef {
            topic: self.report_topic.clone(),
            type_name: InterferenceReport::TYPE_NAME,
        }];
        let optional = [
            (&self.labels_topic, TetLabels::TYPE_NAME),
            (&self.suggestions_topic, ResolveSuggestions::TYPE_NAME),
            (&self.markers_topic, MarkerArray::TYPE_NAME),
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
        match &msg.payload {
            Payload::MeshSlab(s) if *msg.topic == *self.mesh_topic => {
                self.on_piece(s);
                // Live, streams end at different times: the check runs as soon as every
                // body's mesh is closed, not only when the node shuts down.
                if self.pending && self.bodies.values().all(|b| b.ended) {
                    self.check(out);
                }
            }
            Payload::VoxelGrid(g) if *msg.topic != *self.mesh_topic => self.on_frame(&msg.topic, g),
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
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        // A body this node joined mid-stream has no mesh to check (that was said once).
        let joined_late = self.bodies.values().any(|b| b.joined_late && !b.started);
        if (self.pending || self.outcome.is_none()) && !joined_late {
            self.check(out);
        }
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        2
    }
}

impl CheckerNode {
    /// Checks the bodies received so far and publishes the results.
    fn check(&mut self, out: &mut Vec<Message>) {
        self.pending = false;
        let ends = self.stream_ends();
        let frame_id = self
            .bodies
            .values()
            .map(|b| b.frame_id.clone())
            .find(|f| !f.is_empty())
            .unwrap_or_default();
        let walks = std::mem::take(&mut self.walks);
        let (bodies, preps) = self.body_meshes();
        match check_streamed(&bodies, preps, walks, &self.plan, self.opts) {
            Ok(mut o) => {
                o.report.problems.extend(ends);
                let before = out.len();
                self.publish(&o, &frame_id, out);
                self.status.published += (out.len() - before) as u64;
                for p in &o.report.problems {
                    self.status.problem(&self.fqn, "check", p.clone());
                }
                self.outcome = Some(o);
            }
            Err(e) => self.status.problem(
                &self.fqn,
                "check_failed",
                format!("bodies cannot be checked: {e}"),
            ),
        }
    }

    /// A line for each body whose mesh ends before the others' (its stream stopped early):
    /// its pairs are checked only over the time it covers.
    fn stream_ends(&self) -> Vec<String> {
        let last = |b: &Body| b.stamps_ns.last().copied();
        let Some(end) = self.bodies.values().filter_map(last).max() else {
            return Vec::new();
        };
        self.bodies
            .iter()
            .filter_map(|(id, b)| {
                let t = last(b)?;
                (t < end).then(|| {
                    format!(
                        "{id}: its frames end {:.3} s before the others' (the stream stopped): \
                         pairs with it are checked only up to its last frame",
                        (end - t) as f64 * 1e-9
                    )
                })
            })
            .collect()
    }
}
