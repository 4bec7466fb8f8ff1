//! The mesher node: one VoxelGrid topic per body in, the pieces of each body's closed 4D mesh
//! out (`~/mesh_slabs`, chronotope_msgs/MeshSlab) as frames arrive, and optionally a t-slice
//! of each slab at its later frame as a TRIANGLE_LIST marker (`~/slices`).
//!
//! Parameters: `bodies` (string array, the VoxelGrid topics to mesh; required unless the
//! transport supplies the default), `iso_percent` (int, 1..=100), `unknown_occupied` (bool),
//! `percent_scale` (int, power of two 2..=256), `max_slab_tets` (int), `max_fill_tets` (int,
//! the tets of one gap's filled frames together), `slice_markers` (bool, default false).

use std::collections::BTreeMap;
use std::sync::Arc;

use rayon::prelude::*;

use super::launch::{LaunchError, NodeSpec, ParamValue, Params};
use super::markers::{body_color, slab_end_plane, triangle_list};
use super::{Message, Node, NodeStatus, ParamError, Payload, TopicRef};
use chronotope_mesh::slice::Slicer;
use chronotope_mesh::stream::{Accepted, BodyStream, LossKind, LossLog};
use chronotope_mesh::{CapSide, GridGeometry, KeptFrame, MeshError, MesherOptions, Slab, TetMesh};
use chronotope_msg::{Header, Marker, MeshSlab, RosMessage, Time, VoxelGrid};

struct Body {
    stream: BodyStream,
    frame_id: String,
    /// A frame came since the last tick.
    fresh: bool,
    /// Transport time of the last tick that saw a fresh frame.
    last_seen_ns: Option<i64>,
    /// The stream went idle and its mesh was closed; the next frame starts a new one.
    closed: bool,
}

impl Body {
    fn new(opts: MesherOptions) -> Result<Self, chronotope_mesh::MeshError> {
        Ok(Self {
            stream: BodyStream::new(opts)?,
            frame_id: String::new(),
            fresh: false,
            last_seen_ns: None,
            closed: false,
        })
    }
}

/// The mesher node.
pub struct MesherNode {
    fqn: String,
    opts: MesherOptions,
    bodies: BTreeMap<String, Body>,
    slab_topic: String,
    slice_topic: Option<String>,
    /// Something reads the slice markers ([`Node::set_demand`]); none are built otherwise.
    slice_read: bool,
    /// Live use: a body whose frames stop for this long (transport time) is closed.
    idle_timeout_ns: i64,
    status: NodeStatus,
}

impl MesherNode {
    /// The node a launch config describes; `default_bodies` when it names none.
    ///
    /// # Errors
    /// A bad parameter.
    pub fn from_spec(spec: &NodeSpec, default_bodies: &[String]) -> Result<Self, LaunchError> {
        let mut p = Params::of(spec);
        let bodies = p.topics("bodies")?;
        let opts = mesher_options(&mut p)?;
        let slice_markers = p.bool("slice_markers", false)?;
        let idle_timeout_s = p.double("idle_timeout_s", 2.0, 1e-3..=1e6)?;
        let slab_topic = p.resolve("~/mesh_slabs", "~/mesh_slabs")?;
        let slice_topic = if slice_markers {
            Some(p.resolve("~/slices", "~/slices")?)
        } else {
            None
        };
        let node = p.node().to_owned();
        p.finish()?;
        let bodies = bodies.unwrap_or_else(|| default_bodies.to_vec());
        if bodies.is_empty() {
            return Err(LaunchError::Param {
                node,
                param: "bodies".into(),
                reason: "no bodies to mesh: name their VoxelGrid topics".into(),
            });
        }
        let mut map = BTreeMap::new();
        for b in bodies {
            let body = Body::new(opts).map_err(|e| LaunchError::Param {
                node: node.clone(),
                param: "iso_percent/percent_scale".into(),
                reason: e.to_string(),
            })?;
            map.insert(b, body);
        }
        Ok(Self {
            fqn: node,
            opts,
            bodies: map,
            slab_topic,
            slice_topic,
            slice_read: true,
            idle_timeout_ns: (idle_timeout_s * 1e9) as i64,
            status: NodeStatus::default(),
        })
    }

    /// The topic of the mesh pieces.
    pub fn slab_topic(&self) -> &str {
        &self.slab_topic
    }

    /// The bodies meshed.
    pub fn bodies(&self) -> impl Iterator<Item = &str> {
        self.bodies.keys().map(String::as_str)
    }

    /// Keeps only the bodies `keep` says (a body no checked pair uses is not meshed).
    pub fn retain_bodies(&mut self, keep: impl Fn(&str) -> bool) {
        self.bodies.retain(|k, _| keep(k));
    }

    /// Frames of `body` the mesher refused.
    pub fn skipped(&self, body: &str) -> u64 {
        self.bodies
            .get(body)
            .map_or(0, |b| b.stream.losses().refused_frames)
    }

    /// What `body`'s stream lost so far (refused frames, filled and spanned gaps).
    pub fn losses(&self, body: &str) -> Option<&LossLog> {
        self.bodies.get(body).map(|b| b.stream.losses())
    }

    /// The mesher options.
    pub fn options(&self) -> MesherOptions {
        self.opts
    }

    /// What the bodies' handlers share (all of it read only, so bodies can be handled on
    /// several threads).
    fn ctx(&self) -> Ctx<'_> {
        Ctx {
            fqn: &self.fqn,
            slab_topic: &self.slab_topic,
            slice_topic: self.slice_topic.as_deref().filter(|_| self.slice_read),
        }
    }

    fn on_frame(&mut self, topic: &str, grid: &VoxelGrid, out: &mut Vec<Message>) {
        let ctx = Ctx {
            fqn: &self.fqn,
            slab_topic: &self.slab_topic,
            slice_topic: self.slice_topic.as_deref().filter(|_| self.slice_read),
        };
        let Some(b) = self.bodies.get_mut(topic) else {
            return;
        };
        let mut problems = Vec::new();
        ctx.on_frame(topic, b, grid, out, &mut problems);
        for (kind, text) in problems {
            self.status.problem(&self.fqn, kind, text);
        }
    }
}

/// A problem found while handling a message: its kind and text, counted in the node's
/// status in message order.
type Problem = (&'static str, String);

/// One message of a batch handled: its place in the batch, what it published, its problems.
type Handled = (usize, Vec<Message>, Vec<Problem>);

/// The node's names a body's handler needs.
#[derive(Clone, Copy)]
struct Ctx<'a> {
    fqn: &'a str,
    slab_topic: &'a str,
    slice_topic: Option<&'a str>,
}

impl Ctx<'_> {
    #[allow(clippy::too_many_arguments)]
    fn piece(
        &self,
        body: &str,
        b: &Body,
        kind: u8,
        g: &GridGeometry,
        index: u64,
        stamps: (i64, i64),
        occupied: u64,
        (unsure, displacement): (Option<chronotope_mesh::unsure::Unsure>, u16),
        mesh: TetMesh,
    ) -> Message {
        let mut m = MeshSlab {
            header: Header {
                stamp: Time::from_nanos(stamps.1),
                frame_id: b.frame_id.clone(),
            },
            body_id: body.to_owned(),
            kind,
            index: index as u32,
            stamp_lo: Time::from_nanos(stamps.0),
            stamp_hi: Time::from_nanos(stamps.1),
            occupied_voxels: occupied,
            displacement_voxels: displacement,
            mesh: Arc::new(mesh),
            ..MeshSlab::default()
        };
        m.set_unsure(unsure);
        m.set_geometry(g);
        Message::new(self.slab_topic, stamps.1, Payload::MeshSlab(Arc::new(m)))
    }

    /// The cap of `b` at frame `k`. A cap over `max_slab_tets` is sent without tets, so the
    /// checker still knows where the body's mesh starts or ends (it reports the body as not
    /// closed), and the problem says so.
    fn cap(
        &self,
        body: &str,
        b: &Body,
        k: &KeptFrame,
        side: CapSide,
        problems: &mut Vec<Problem>,
    ) -> Option<Message> {
        let cap = b.stream.mesher().cap(k, side);
        self.cap_marched(body, b, k, side, cap, problems)
    }

    /// [`Self::cap`] with the cap marched already (`None`: over `max_slab_tets`).
    fn cap_marched(
        &self,
        body: &str,
        b: &Body,
        k: &KeptFrame,
        side: CapSide,
        cap: Option<TetMesh>,
        problems: &mut Vec<Problem>,
    ) -> Option<Message> {
        let g = *b.stream.mesher().geometry()?;
        let cap = cap.unwrap_or_else(|| {
            problems.push((
                "cap_too_complex",
                format!(
                    "{body}: the cap closing the mesh at frame {} ({} occupied voxels) exceeds \
                     max_slab_tets ({}): it is sent without tets, so the body's mesh is open \
                     there (its slabs are checked as usual; raise max_slab_tets to close it)",
                    k.index,
                    k.grid.occupied,
                    b.stream.mesher().options().max_slab_tets
                ),
            ));
            TetMesh::default()
        });
        let kind = match side {
            CapSide::Low => MeshSlab::KIND_CAP_START,
            CapSide::High => MeshSlab::KIND_CAP_END,
        };
        Some(self.piece(
            body,
            b,
            kind,
            &g,
            k.index,
            (k.stamp_ns, k.stamp_ns),
            k.grid.occupied,
            (None, 0),
            cap,
        ))
    }

    fn slice_marker(&self, body: &str, b: &Body, slab: &Slab) -> Option<Message> {
        let topic = self.slice_topic?;
        // The body at the slab's later frame, as the checker's markers draw it.
        let mut slicer = Slicer::new(3, slab_end_plane(slab.index, slab.geometry.scale));
        slicer.add_par(&slab.mesh);
        let tri = slicer.finish();
        let stamp = slab.stamp_hi_ns;
        let header = Header {
            stamp: Time::from_nanos(stamp),
            frame_id: b.frame_id.clone(),
        };
        let color = body_color(body);
        let m = triangle_list(header, body, 0, &slab.geometry, &tri, |_| color);
        Some(Message::new(topic, stamp, Payload::Marker(Arc::new(m))))
    }

    /// Handles one frame of body `b` (on `topic`): what it publishes goes to `out`, its
    /// problems to `problems`. Touches nothing but `b`.
    fn on_frame(
        &self,
        topic: &str,
        b: &mut Body,
        grid: &VoxelGrid,
        out: &mut Vec<Message>,
        problems: &mut Vec<Problem>,
    ) {
        let stamp = grid.header.stamp.as_nanos();
        let refused = |problems: &mut Vec<Problem>, e: &MeshError| {
            problems.push((
                "frame_refused",
                format!("{topic}: frame at {} skipped: {e}", stamp_text(grid)),
            ));
        };
        // Checks of the message itself, before the stream sees it.
        let pre = grid
            .message_check(if b.closed { "" } else { &b.frame_id })
            .err();
        if let Some(e) = pre {
            b.stream.refuse(Some(stamp), &e);
            refused(problems, &e);
            return;
        }
        // After an idle close the next accepted frame starts a new stream (the losses go on).
        let mut next = None;
        if b.closed {
            match b.stream.restarted() {
                Ok(s) => next = Some(s),
                Err(e) => {
                    refused(problems, &e);
                    return;
                }
            }
        }
        let result = match next.as_mut() {
            Some(s) => s.push(&grid.frame_ref()),
            None => b.stream.push(&grid.frame_ref()),
        };
        match result {
            Err(e) => {
                if next.is_some() {
                    // Refused as the first frame of a new stream: the old one stays closed.
                    b.stream.refuse(Some(stamp), &e);
                }
                refused(problems, &e);
            }
            Ok(accepted) => {
                if let Some(s) = next {
                    tracing::info!(
                        node = self.fqn,
                        "{topic}: frames again after going idle: a new stream"
                    );
                    b.stream = s;
                    b.closed = false;
                    b.frame_id.clear();
                }
                b.fresh = true;
                if b.frame_id.is_empty() {
                    b.frame_id = grid.header.frame_id.clone();
                }
                self.after_push(topic, b, accepted, out, problems);
            }
        }
    }

    fn after_push(
        &self,
        topic: &str,
        b: &mut Body,
        a: Accepted,
        out: &mut Vec<Message>,
        problems: &mut Vec<Problem>,
    ) {
        if a.clamped > 0 {
            let stamp = a.frames.last().map_or(0, |f| f.0);
            problems.push((
                "percent_out_of_range",
                format!(
                    "{topic}: frame at {:.3} s: {}",
                    stamp as f64 * 1e-9,
                    MeshError::PercentOutOfRange { voxels: a.clamped }
                ),
            ));
        }
        if let Some(g) = &a.gap {
            let how = match g.kind {
                LossKind::Filled => format!(
                    "{} frame(s) filled with the union of the two frames around the gap",
                    g.frames
                ),
                _ => "one slab spans the gap".to_owned(),
            };
            problems.push((
                "frames_missing",
                format!(
                    "{topic}: frames missing from {:.3} s to {:.3} s (stamps {} to {} ns): {}; {how}",
                    g.from_ns as f64 * 1e-9,
                    g.to_ns as f64 * 1e-9,
                    g.from_ns,
                    g.to_ns,
                    g.reason
                ),
            ));
        }
        // The filled frames come first; each slab's later frame is a fill but the last's.
        let last = a.frames.len().saturating_sub(1);
        let fill_occupied = a.fill.as_ref().map(|g| g.occupied);
        for (i, (_, slab)) in a.frames.into_iter().enumerate() {
            if let Some(slab) = slab {
                let occupied = fill_occupied.filter(|_| i < last);
                self.accepted(topic, b, slab, occupied, out, problems);
            }
        }
    }

    /// Publishes `slab` (and the first cap before slab 0). `occupied`: voxels of the slab's
    /// later frame when it is not the last accepted one (a filled frame).
    fn accepted(
        &self,
        topic: &str,
        b: &mut Body,
        slab: Slab,
        occupied: Option<u64>,
        out: &mut Vec<Message>,
        problems: &mut Vec<Problem>,
    ) {
        if slab.index == 0 {
            if let Some(m) = b
                .stream
                .mesher()
                .first_frame()
                .and_then(|k| self.cap(topic, b, k, CapSide::Low, problems))
            {
                out.push(m);
            }
        }
        if let Some(m) = self.slice_marker(topic, b, &slab) {
            out.push(m);
        }
        let occupied = occupied.unwrap_or_else(|| {
            b.stream
                .mesher()
                .last_frame()
                .map_or(0, |k| k.grid.occupied)
        });
        out.push(self.piece(
            topic,
            b,
            MeshSlab::KIND_LATERAL,
            &slab.geometry,
            slab.index,
            (slab.stamp_lo_ns, slab.stamp_hi_ns),
            occupied,
            (slab.unsure, slab.displacement),
            slab.mesh,
        ));
    }
}

impl MesherNode {
    /// Publishes the closing cap of `b`'s mesh (or says why there is none).
    fn close(&mut self, topic: &str, b: &mut Body, out: &mut Vec<Message>) {
        let cap = closing_cap(b);
        self.close_with(topic, b, cap, out);
    }

    /// [`Self::close`] with the closing cap marched already (see [`closing_cap`]).
    fn close_with(
        &mut self,
        topic: &str,
        b: &mut Body,
        cap: Option<TetMesh>,
        out: &mut Vec<Message>,
    ) {
        b.closed = true;
        if b.stream.mesher().frames() >= 2 {
            let mut problems = Vec::new();
            if let Some(m) = b.stream.mesher().last_frame().and_then(|k| {
                self.ctx()
                    .cap_marched(topic, b, k, CapSide::High, cap, &mut problems)
            }) {
                out.push(m);
            }
            for (kind, text) in problems {
                self.status.problem(&self.fqn, kind, text);
            }
        } else {
            let why = format!(
                "{topic}: {} frame(s): a body needs two for a 4D mesh",
                b.stream.mesher().frames()
            );
            self.status.problem(&self.fqn, "too_few_frames", why);
        }
    }
}

/// The cap closing `b`'s mesh at its last frame, if it has the two frames a 4D mesh needs
/// (`None` too for a cap over `max_slab_tets`).
fn closing_cap(b: &Body) -> Option<TetMesh> {
    let m = b.stream.mesher();
    (m.frames() >= 2)
        .then(|| m.last_frame().and_then(|k| m.cap(k, CapSide::High)))
        .flatten()
}

/// A frame's stamp in words: seconds, and the raw fields when they are out of range.
fn stamp_text(grid: &VoxelGrid) -> String {
    let t = grid.header.stamp;
    if t.nanosec >= 1_000_000_000 {
        format!("sec {} nanosec {}", t.sec, t.nanosec)
    } else {
        format!("{:.3} s ({} ns)", t.as_nanos() as f64 * 1e-9, t.as_nanos())
    }
}

/// The mesher options from a node's parameters (shared with the checker, which decodes the
/// same frames to measure overlaps).
///
/// # Errors
/// A bad parameter.
pub fn mesher_options(p: &mut Params<'_>) -> Result<MesherOptions, LaunchError> {
    let mut opts = MesherOptions::default();
    opts.decode.iso_percent =
        p.int("iso_percent", i64::from(opts.decode.iso_percent), 1..=100)? as u8;
    opts.decode.unknown_occupied = p.bool("unknown_occupied", opts.decode.unknown_occupied)?;
    let scale = p.int("percent_scale", i64::from(opts.percent_scale), 2..=256)?;
    if (scale as u32).count_ones() != 1 {
        return Err(LaunchError::Param {
            node: p.node().to_owned(),
            param: "percent_scale".into(),
            reason: format!("{scale} is not a power of two"),
        });
    }
    opts.percent_scale = scale as i32;
    opts.max_slab_tets = p.int(
        "max_slab_tets",
        opts.max_slab_tets as i64,
        1..=i64::from(u32::MAX),
    )? as usize;
    opts.max_fill_tets = p.int(
        "max_fill_tets",
        opts.max_fill_tets as i64,
        0..=i64::from(u32::MAX),
    )? as usize;
    Ok(opts)
}

impl Node for MesherNode {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        self.bodies
            .keys()
            .map(|t| TopicRef {
                topic: t.clone(),
                type_name: VoxelGrid::TYPE_NAME,
            })
            .collect()
    }

    fn publications(&self) -> Vec<TopicRef> {
        let mut p = vec![TopicRef {
            topic: self.slab_topic.clone(),
            type_name: MeshSlab::TYPE_NAME,
        }];
        p.extend(self.slice_topic.iter().map(|t| TopicRef {
            topic: t.clone(),
            type_name: Marker::TYPE_NAME,
        }));
        p
    }

    fn set_demand(&mut self, topic: &str, read: bool) {
        if self.slice_topic.as_deref() == Some(topic) {
            self.slice_read = read;
        }
    }

    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        self.status.received += 1;
        let before = out.len();
        match &msg.payload {
            Payload::VoxelGrid(g) => self.on_frame(&msg.topic, g, out),
            other => self.status.problem(
                &self.fqn,
                "wrong_type",
                format!(
                    "{}: a {} where a {} was expected; ignored",
                    msg.topic,
                    other.type_name(),
                    VoxelGrid::TYPE_NAME
                ),
            ),
        }
        self.status.published += (out.len() - before) as u64;
    }

    /// The bodies' frames of the batch are handled in parallel (each body's in order, on
    /// rayon's pool); what they publish and the problems they count come out in the order
    /// one-by-one handling gives.
    fn on_messages(&mut self, msgs: &[Message], out: &mut Vec<Message>) {
        let body_of = |m: &Message| match &m.payload {
            Payload::VoxelGrid(_) if self.bodies.contains_key(&*m.topic) => Some(m.topic.clone()),
            _ => None,
        };
        let mut jobs: BTreeMap<Arc<str>, Vec<usize>> = BTreeMap::new();
        for (i, m) in msgs.iter().enumerate() {
            if let Some(t) = body_of(m) {
                jobs.entry(t).or_default().push(i);
            }
        }
        if jobs.len() < 2 || rayon::current_num_threads() < 2 {
            for m in msgs {
                self.on_message(m, out);
            }
            return;
        }
        let mut work: Vec<(Arc<str>, Body, Vec<usize>)> = jobs
            .into_iter()
            .filter_map(|(t, idx)| self.bodies.remove(&*t).map(|b| (t, b, idx)))
            .collect();
        let ctx = self.ctx();
        let done: Vec<Vec<Handled>> = work
            .par_iter_mut()
            .map(|(topic, b, idx)| {
                idx.iter()
                    .map(|&i| {
                        let (mut o, mut p) = (Vec::new(), Vec::new());
                        if let Payload::VoxelGrid(g) = &msgs[i].payload {
                            ctx.on_frame(topic, b, g, &mut o, &mut p);
                        }
                        (i, o, p)
                    })
                    .collect()
            })
            .collect();
        for (topic, b, _) in work {
            self.bodies.insert(topic.to_string(), b);
        }
        let mut results: Vec<Option<(Vec<Message>, Vec<Problem>)>> =
            (0..msgs.len()).map(|_| None).collect();
        for (i, o, p) in done.into_iter().flatten() {
            results[i] = Some((o, p));
        }
        for (m, r) in msgs.iter().zip(results) {
            match r {
                None => self.on_message(m, out),
                Some((o, problems)) => {
                    self.status.received += 1;
                    for (kind, text) in problems {
                        self.status.problem(&self.fqn, kind, text);
                    }
                    self.status.published += o.len() as u64;
                    out.extend(o);
                }
            }
        }
    }

    fn runtime_parameters(&self) -> Vec<(String, ParamValue)> {
        vec![(
            "idle_timeout_s".into(),
            ParamValue::Double(self.idle_timeout_ns as f64 * 1e-9),
        )]
    }

    /// `idle_timeout_s` can change while the node runs (1 ms to 10^6 s); the rest is taken at
    /// start.
    fn set_parameter(&mut self, name: &str, value: &ParamValue) -> Result<(), ParamError> {
        let seconds = match value {
            ParamValue::Double(v) => Some(*v),
            ParamValue::Integer(i) => Some(*i as f64),
            _ => None,
        };
        match (name, seconds) {
            ("idle_timeout_s", Some(v)) if (1e-3..=1e6).contains(&v) => {
                self.idle_timeout_ns = (v * 1e9) as i64;
                tracing::info!(node = self.fqn, "idle_timeout_s set to {v}");
                Ok(())
            }
            ("idle_timeout_s", _) => Err(ParamError::BadValue {
                name: "idle_timeout_s",
                value: format!("{value:?}"),
                expected: "a number of seconds in [0.001, 1e6]",
            }),
            (other, _) => Err(ParamError::StartOnly {
                name: other.to_owned(),
                node: self.fqn.clone(),
                changeable: Some("idle_timeout_s"),
            }),
        }
    }

    fn on_tick(&mut self, now_ns: i64, out: &mut Vec<Message>) {
        let before = out.len();
        for b in self.bodies.values_mut() {
            if std::mem::take(&mut b.fresh) {
                b.last_seen_ns = Some(now_ns);
            }
        }
        let idle = |b: &Body| {
            !b.closed
                && b.last_seen_ns
                    .is_some_and(|t| now_ns - t > self.idle_timeout_ns)
        };
        let stopped: Vec<String> = self
            .bodies
            .iter()
            .filter(|(_, b)| idle(b))
            .map(|(t, _)| t.clone())
            .collect();
        // Every stream going quiet is the end of a run; one going quiet while another still
        // had frames well after it (half the timeout) is a stream that stopped, a problem.
        let latest = |except: &str| {
            self.bodies
                .iter()
                .filter(|(t, b)| t.as_str() != except && !b.closed)
                .filter_map(|(_, b)| b.last_seen_ns)
                .max()
        };
        let stopped: Vec<(String, bool)> = stopped
            .into_iter()
            .map(|t| {
                let seen = self.bodies[&t].last_seen_ns.unwrap_or(now_ns);
                let others_go_on = latest(&t).is_some_and(|l| l > seen + self.idle_timeout_ns / 2);
                (t, others_go_on)
            })
            .collect();
        for (topic, others_go_on) in stopped {
            let Some(mut b) = self.bodies.remove(&topic) else {
                continue;
            };
            let quiet = (now_ns - b.last_seen_ns.unwrap_or(now_ns)) as f64 * 1e-9;
            if others_go_on {
                let why = format!(
                    "{topic}: no frame for {quiet:.1} s after {} frame(s) while the other \
                     bodies go on: the stream stopped; its mesh is closed at its last frame",
                    b.stream.mesher().frames()
                );
                self.status.problem(&self.fqn, "stream_stopped", why);
            } else {
                tracing::info!(
                    node = self.fqn,
                    "{topic}: no frame for {quiet:.1} s: the run ended; the mesh is closed"
                );
            }
            self.close(&topic, &mut b, out);
            self.bodies.insert(topic, b);
        }
        self.status.published += (out.len() - before) as u64;
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        let before = out.len();
        // Every open body's closing cap, marched at once on rayon's pool (a cap fills the
        // body's volume: the end of a replay waits for them), then published in order.
        let open: Vec<String> = self
            .bodies
            .iter()
            .filter(|(_, b)| !b.closed)
            .map(|(t, _)| t.clone())
            .collect();
        let caps: Vec<Option<TetMesh>> = open
            .par_iter()
            .map(|t| closing_cap(&self.bodies[t]))
            .collect();
        for (topic, cap) in open.into_iter().zip(caps) {
            if let Some(mut b) = self.bodies.remove(&topic) {
                self.close_with(&topic, &mut b, cap, out);
                self.bodies.insert(topic, b);
            }
        }
        self.status.published += (out.len() - before) as u64;
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        // After the carving display, whose last occupancy frame it meshes.
        2
    }
}
