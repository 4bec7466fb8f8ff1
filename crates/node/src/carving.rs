//! The carving node: a haptic tool's poses in (geometry_msgs/PoseStamped on `pose_topic`),
//! the cutting force back per pose (`~/wrench`, WrenchStamped), and the workpiece published
//! every `occupancy_period_s` as VoxelGrid frames (`~/occupancy`: the grid points still
//! material, so the mesher can watch it) and as PointCloud2 surfels (x, y, z, normal,
//! radius, rgb): the surfels changed since the last frame on `~/surfels_changed` every
//! frame, the whole cloud on `~/surfels` every `surfels_period_s` and at the end.
//!
//! It is two parts, so the force path never waits for a display frame: [`CarvingNode`]
//! (poses, force) and [`CarvingDisplay`] (`<name>/display`: occupancy frames and surfel
//! clouds). The force part keeps a bit per changed surfel slot and per changed occupancy
//! byte; when a frame is due it parks the changes ([`SurfelDelta`]) for the display and says
//! so on the hidden topic `~/_frame` (rosgraph_msgs/Clock, never on the wire). The display
//! applies them to its own copies and builds the frames there. A live launch runs the two on
//! different threads (the force part may be `realtime`); a replay runs them one after the
//! other on its bus, giving the same messages. If the display is behind, the changes keep
//! accumulating until it has taken the last delta (counted as `display_behind`): nothing is
//! lost and nothing waits. Without a display (tests) the force part publishes the occupancy.
//!
//! Work is scheduled by the next due time, never by catching up: a pose publishes at most
//! one workpiece frame, at the latest due time on the `occupancy_period_s` grid (periods in
//! which no pose arrived get no frame: the workpiece did not change), and the force
//! integrates at most 0.1 s of a pause. A pause in the pose stream (over 0.1 s) is counted
//! (`pose_pause`) and costs one pose's work. Frames are also held to
//! [`MAX_FRAME_BYTES_PER_S`]: when a frame of the workpiece is too big for the period, the
//! next due time moves by whole periods and the frames left out are counted
//! (`occupancy_throttled`).
//!
//! A parameter set whose virtual coupling would be unstable is refused at launch
//! ([`chronotope_carving::ForceParams::validate`], naming the condition); a force that still
//! comes out non-finite is replaced by the last finite one and counted (`non_finite_force`).
//!
//! Bad input never stops the node: a pose with a non-finite position or a zero quaternion, a
//! stamp older than the last, a pose in another frame are refused (counted problems, the
//! workpiece unchanged); a non-unit quaternion is normalised (counted); an image that does not
//! load or an unknown tool in the schedule is a counted problem at start and is skipped.

use std::sync::{Arc, Mutex};

use super::launch::{LaunchError, NodeSpec, Params};
use super::{Message, Node, NodeStatus, Payload, TopicRef};
use chronotope_carving::cutout::{Axis, BinaryImage, ImageError};
use chronotope_carving::{
    CarveError, ForceModel, ForceParams, ForceRenderer, SurfelDelta, Tool, ToolKind, ToolPose,
    Workpiece, SURFEL_BYTES,
};
use chronotope_msg::{
    Header, Point, PointCloud2, PointField, PoseStamped, RosMessage, Time, Vector3, VoxelGrid,
    Wrench, WrenchStamped,
};

/// Most bytes of workpiece frames (occupancy bits plus surfel cloud) the node publishes per
/// second of pose time: 512 MiB/s, a third of the ~1.5 GB/s a frame's copy was measured at
/// (docs/carving.md, speed: 10 ms for 15 MB at 256³), so frames take at most about a third
/// of the node's core and the 1 kHz force loop keeps the rest.
pub const MAX_FRAME_BYTES_PER_S: f64 = 512.0 * 1024.0 * 1024.0;

/// A gap between two poses longer than this (ns) is a pause: counted, and integrated by the
/// force as [`chronotope_carving::MAX_MOVE_DT_S`] only.
const PAUSE_NS: i64 = 100_000_000;

/// Why the display part cannot be made ([`CarvingNode::display`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DisplayError {
    /// The memory for its copy of the surfels cannot be reserved.
    #[error(
        "cannot reserve {:.1} MB for the display's copy of the surfels",
        *.points as f64 * 32.0 / 1e6
    )]
    Surfels {
        /// Grid points, each of which may hold a surfel.
        points: usize,
    },
    /// The memory for its copy of the occupancy cannot be reserved.
    #[error("cannot reserve the display's copy of the occupancy")]
    Occupancy,
}

/// Why a `cutouts` entry is skipped.
#[derive(Debug, thiserror::Error)]
enum CutoutError {
    /// The entry is not an axis and a path.
    #[error("expected \"AXIS PATH\"")]
    Entry,
    /// The axis is not one of x, y, z.
    #[error(transparent)]
    Axis(#[from] CarveError),
    /// The image cannot be read or used.
    #[error(transparent)]
    Image(#[from] ImageError),
}

/// The carving node.
pub struct CarvingNode {
    fqn: String,
    pose_topic: String,
    wrench_topic: String,
    occupancy_topic: String,
    surfels_topic: String,
    frame_id: String,
    work: Workpiece,
    knife: Tool,
    chisel: Tool,
    tool: ToolKind,
    /// `(ns after the first pose, tool)`, sorted.
    schedule: Vec<(i64, ToolKind)>,
    force: ForceRenderer,
    period_ns: i64,
    first_stamp: Option<i64>,
    last: Option<(i64, ToolPose, ToolKind)>,
    next_publish: Option<i64>,
    last_force: [f64; 3],
    /// Due times on the period grid that got no frame (no pose in them, or throttled).
    skipped_periods: u64,
    /// Hidden topic (`~/_frame`, Clock) telling the display a frame is due.
    frame_topic: String,
    /// The changed surfels parked for the display, with their frame's stamp.
    mailbox: Arc<Mutex<Option<(i64, SurfelDelta)>>>,
    /// Whether a display was made ([`CarvingNode::display`]): only then are deltas parked.
    has_display: bool,
    surfels_period_ns: i64,
    status: NodeStatus,
}

impl CarvingNode {
    /// The node a launch config describes.
    ///
    /// # Errors
    /// A bad or missing parameter.
    pub fn from_spec(spec: &NodeSpec) -> Result<Self, LaunchError> {
        let mut p = Params::of(spec);
        let node = p.node().to_owned();
        let bad = |param: &str, reason: String| LaunchError::Param {
            node: node.clone(),
            param: param.to_owned(),
            reason,
        };
        let Some(pose) = p.string("pose_topic")? else {
            return Err(bad(
                "pose_topic",
                "required: the haptic device's PoseStamped topic".into(),
            ));
        };
        let pose_topic = p.resolve("pose_topic", &pose)?;
        let frame_id = p.string("frame_id")?.unwrap_or_else(|| "world".into());
        let lo = p.doubles("workpiece_min", [0.0, 0.0, 0.0])?;
        let hi = p.doubles("workpiece_max", [0.06, 0.06, 0.03])?;
        let spacing = p.double("spacing_m", 0.002, 1e-5..=1.0)?;
        let tool_name = p.string("tool")?.unwrap_or_else(|| "knife".into());
        let tool: ToolKind = tool_name
            .parse()
            .map_err(|e: CarveError| bad("tool", e.to_string()))?;
        let schedule_raw = p.strings("tool_schedule")?.unwrap_or_default();
        let knife_len = p.double("knife_length_m", 0.02, 1e-5..=1.0)?;
        let knife_width = p.double("knife_width_m", 0.01, 1e-5..=1.0)?;
        let knife_thick = p.double("knife_thickness_m", 0.002, 0.0..=1.0)?;
        let chisel_width = p.double("chisel_width_m", 0.008, 1e-5..=1.0)?;
        let chisel_height = p.double("chisel_height_m", 0.004, 1e-5..=1.0)?;
        let chisel_thick = p.double("chisel_thickness_m", 0.002, 0.0..=1.0)?;
        let cutouts = p.strings("cutouts")?.unwrap_or_default();
        let model = match p.string("force_model")?.as_deref() {
            None => ForceModel::Section,
            Some(s) => s
                .parse()
                .map_err(|e: CarveError| bad("force_model", e.to_string()))?,
        };
        let defaults = ForceParams::default();
        let force = ForceParams {
            model,
            newtons_per_point: p.double(
                "newtons_per_point",
                defaults.newtons_per_point,
                0.0..=1e3,
            )?,
            pressure: p.double("cutting_pressure_n_per_m2", defaults.pressure, 0.0..=1e9)?,
            cutoff_hz: p.double("filter_cutoff_hz", defaults.cutoff_hz, 0.0..=1e4)?,
            coupling_stiffness: p.double(
                "coupling_stiffness_n_per_m",
                defaults.coupling_stiffness,
                0.0..=1e7,
            )?,
            coupling_damping: p.double(
                "coupling_damping_ns_per_m",
                defaults.coupling_damping,
                0.0..=1e5,
            )?,
            proxy_mass: p.double("proxy_mass_kg", defaults.proxy_mass, 1e-6..=100.0)?,
            max_force: p.double("max_force_n", defaults.max_force, 0.0..=1e4)?,
        };
        if let Err(CarveError::Force { param, reason }) = force.validate() {
            return Err(bad(param, reason));
        }
        let period = p.double("occupancy_period_s", 1.0 / 30.0, 1e-3..=3600.0)?;
        let surfels_period = p.double("surfels_period_s", 2.0, 1e-3..=3600.0)?;
        let wrench_topic = p.resolve("~/wrench", "~/wrench")?;
        let occupancy_topic = p.resolve("~/occupancy", "~/occupancy")?;
        let surfels_topic = p.resolve("~/surfels", "~/surfels")?;
        let frame_topic = p.resolve("~/_frame", "~/_frame")?;
        p.finish()?;
        let work =
            Workpiece::block(lo, hi, spacing).map_err(|e| bad("workpiece_max", e.to_string()))?;
        let knife = Tool::knife(knife_len, knife_width, knife_thick, spacing)
            .map_err(|e| bad("knife_length_m", e.to_string()))?;
        let chisel = Tool::chisel(chisel_width, chisel_height, chisel_thick, spacing)
            .map_err(|e| bad("chisel_width_m", e.to_string()))?;
        let mut status = NodeStatus::default();
        let mut schedule = Vec::new();
        for entry in &schedule_raw {
            let mut it = entry.split_whitespace();
            let parsed = match (it.next().map(str::parse::<f64>), it.next(), it.next()) {
                (Some(Ok(t)), Some(name), None) if t.is_finite() && (0.0..=1e6).contains(&t) => {
                    name.parse::<ToolKind>()
                        .map(|k| ((t * 1e9).round() as i64, k))
                        .map_err(|e| e.to_string())
                }
                _ => Err(
                    "expected \"SECONDS TOOL\" (seconds after the first pose, knife or chisel)"
                        .into(),
                ),
            };
            match parsed {
                Ok(e) => schedule.push(e),
                Err(why) => status.problem(
                    &node,
                    "unknown_tool",
                    format!("tool_schedule entry {entry:?}: {why}; skipped"),
                ),
            }
        }
        schedule.sort_by_key(|e| e.0);
        let mut me = Self {
            fqn: node.clone(),
            pose_topic,
            wrench_topic,
            occupancy_topic,
            surfels_topic,
            frame_topic,
            frame_id,
            work,
            knife,
            chisel,
            tool,
            schedule,
            force: ForceRenderer::new(force),
            period_ns: (period * 1e9).round() as i64,
            first_stamp: None,
            last: None,
            next_publish: None,
            last_force: [0.0; 3],
            skipped_periods: 0,
            mailbox: Arc::new(Mutex::new(None)),
            has_display: false,
            surfels_period_ns: (surfels_period * 1e9).round() as i64,
            status,
        };
        for t in [&me.knife, &me.chisel] {
            if let Some(asked) = t.thickened() {
                let text = format!(
                    "the {} is {asked} m thick, thinner than the grid spacing {spacing} m: cut as {} m thick",
                    t.kind().name(),
                    t.cut_thickness()
                );
                me.status.problem(&node, "thin_blade", text);
            }
        }
        for entry in &cutouts {
            me.apply_cutout(entry);
        }
        Ok(me)
    }

    /// Applies one `cutouts` entry ("AXIS PATH"); a bad entry or image is a counted problem.
    fn apply_cutout(&mut self, entry: &str) {
        let (axis, path) = match entry.trim().split_once(char::is_whitespace) {
            Some((a, path)) => (a.parse::<Axis>().map_err(CutoutError::from), path.trim()),
            None => (Err(CutoutError::Entry), ""),
        };
        let result = axis.and_then(|axis| {
            BinaryImage::load(std::path::Path::new(path))
                .map(|img| (axis, img))
                .map_err(CutoutError::from)
        });
        match result {
            Ok((axis, img)) => {
                let s = self.work.cut_out(&img, axis);
                tracing::info!(node = %self.fqn, "cut-out {entry:?}: {} points removed", s.removed);
            }
            Err(why) => self.status.problem(
                &self.fqn,
                "bad_image",
                format!("cut-out {entry:?}: {why}; skipped, workpiece unchanged"),
            ),
        }
    }

    /// The topic of the workpiece's occupancy frames.
    pub fn occupancy_topic(&self) -> &str {
        &self.occupancy_topic
    }

    /// The workpiece.
    pub fn workpiece(&self) -> &Workpiece {
        &self.work
    }

    /// The force published with the last pose (N).
    pub fn last_force(&self) -> [f64; 3] {
        self.last_force
    }

    /// Due times of the occupancy period grid that got no frame: periods in which no pose
    /// arrived (the workpiece did not change), or frames left out by
    /// [`MAX_FRAME_BYTES_PER_S`].
    pub fn skipped_periods(&self) -> u64 {
        self.skipped_periods
    }

    /// Bytes one workpiece frame costs now: the occupancy bits, and the whole surfel cloud's
    /// share (it goes out every `surfels_period_s`, so a frame carries
    /// `occupancy_period_s / surfels_period_s` of it; the changed surfels are small beside).
    pub fn frame_bytes(&self) -> usize {
        let share = (self.period_ns as f64 / self.surfels_period_ns.max(1) as f64).min(1.0);
        self.work.occupancy_bits().len() + (self.work.surfel_bytes().len() as f64 * share) as usize
    }

    /// Counts a problem of `kind`, logging (and keeping the text of) only its first one:
    /// for kinds that may recur at the pose rate.
    fn count_quietly(&mut self, kind: &str, n: u64, text: impl FnOnce() -> String) {
        self.status.count_quietly(&self.fqn, kind, n, text);
    }

    /// Publishes the frame due at or before `stamp`, if any: one frame, at the latest due
    /// time on the period grid; the due times before it are skipped (nothing to catch up).
    /// The next due time is the next grid time, or later by whole periods if this frame's
    /// bytes need longer at [`MAX_FRAME_BYTES_PER_S`].
    fn publish_due(&mut self, stamp: i64, out: &mut Vec<Message>) {
        let next = *self.next_publish.get_or_insert(stamp);
        if stamp < next {
            return;
        }
        let period = i128::from(self.period_ns.max(1));
        let k = (i128::from(stamp) - i128::from(next)) / period;
        let due = i128::from(next) + k * period;
        self.skipped_periods = self
            .skipped_periods
            .saturating_add(u64::try_from(k).unwrap_or(u64::MAX));
        let due = i64::try_from(due).unwrap_or(stamp);
        self.publish_workpiece(due, false, out);
        // Whole periods covering the time this frame's bytes take at the budget.
        let bytes = self.frame_bytes() as f64;
        let need_ns = bytes / MAX_FRAME_BYTES_PER_S * 1e9;
        let periods = (need_ns / period as f64).ceil().max(1.0);
        let periods = if periods.is_finite() && periods < 1e12 {
            periods as i128
        } else {
            1
        };
        if periods > 1 {
            let left_out = (periods - 1) as u64;
            self.skipped_periods = self.skipped_periods.saturating_add(left_out);
            let period_s = self.period_ns as f64 * 1e-9;
            self.count_quietly("occupancy_throttled", left_out, || {
                format!(
                    "a workpiece frame is {:.1} MB: at most {:.0} MiB/s of frames \
                     (MAX_FRAME_BYTES_PER_S), so frames go out every {:.4} s instead of every \
                     occupancy_period_s {period_s} s; the periods left out are counted",
                    bytes / 1e6,
                    MAX_FRAME_BYTES_PER_S / 1048576.0,
                    periods as f64 * period_s
                )
            });
        }
        let after = i128::from(due) + periods * period;
        self.next_publish = Some(i64::try_from(after).unwrap_or(i64::MAX));
    }

    /// Occupied grid points left.
    pub fn occupied_voxels(&self) -> usize {
        self.work.material_points() as usize
    }

    fn tool_at(&self, stamp: i64) -> ToolKind {
        let since = stamp - self.first_stamp.unwrap_or(stamp);
        self.schedule
            .iter()
            .take_while(|e| e.0 <= since)
            .last()
            .map_or(self.tool, |e| e.1)
    }

    /// Parks what changed since the last frame (surfels and occupancy) for the display and
    /// tells it a frame is due at `stamp` (or, if the display has not taken the last delta
    /// yet, leaves the changes accumulating; `last` merges them in regardless, for the final
    /// frame). Without a display, publishes the occupancy frame itself. Nothing large is
    /// copied here: the force path never builds a frame.
    fn publish_workpiece(&mut self, stamp: i64, last: bool, out: &mut Vec<Message>) {
        if !self.has_display {
            out.push(Message::new(
                &self.occupancy_topic,
                stamp,
                Payload::VoxelGrid(Arc::new(occupancy_frame(
                    &self.work,
                    &self.frame_id,
                    stamp,
                    self.work.occupancy_bits().to_vec(),
                ))),
            ));
            return;
        }
        let behind = {
            let mut parked = self.mailbox.lock().unwrap_or_else(|p| p.into_inner());
            match parked.as_mut() {
                None => {
                    *parked = Some((stamp, self.work.take_surfel_delta()));
                    false
                }
                Some((t, d)) if last => {
                    *t = stamp;
                    d.merge(self.work.take_surfel_delta());
                    false
                }
                Some(_) => true,
            }
        };
        if behind {
            self.count_quietly("display_behind", 1, || {
                "the display has not taken the last changes yet: they accumulate until it \
                 has (nothing is lost; its frames come later)"
                    .into()
            });
        }
        out.push(Message::new(
            &self.frame_topic,
            stamp,
            Payload::Clock(Arc::new(chronotope_msg::Clock {
                clock: Time::from_nanos(stamp),
            })),
        ));
    }

    /// The display part: it reads this node's occupancy frames and publishes the surfel
    /// clouds from the changed surfels parked for it. Its copy of the cloud is reserved
    /// here, for a surfel on every point.
    ///
    /// # Errors
    /// [`DisplayError`]: the memory for a copy cannot be reserved.
    pub fn display(&mut self) -> Result<CarvingDisplay, DisplayError> {
        let mut cloud = Vec::new();
        let points = self.work.dims().iter().product::<usize>();
        cloud
            .try_reserve_exact(points * SURFEL_BYTES)
            .map_err(|_| DisplayError::Surfels { points })?;
        // The display starts from the cloud and occupancy as they are (the block, cut out).
        let start = self.work.take_surfel_delta();
        start.apply(&mut cloud);
        let mut bits = Vec::new();
        bits.try_reserve_exact(self.work.occupancy_bits().len())
            .map_err(|_| DisplayError::Occupancy)?;
        bits.extend_from_slice(self.work.occupancy_bits());
        self.has_display = true;
        let (lo, _) = self.work.block_bounds();
        Ok(CarvingDisplay {
            fqn: format!("{}/display", self.fqn),
            frame_topic: self.frame_topic.clone(),
            occupancy_topic: self.occupancy_topic.clone(),
            grid: GridShape {
                origin: lo,
                spacing: self.work.spacing(),
                dims: self.work.dims(),
            },
            bits,
            surfels_topic: self.surfels_topic.clone(),
            changed_topic: format!("{}_changed", self.surfels_topic),
            frame_id: self.frame_id.clone(),
            mailbox: self.mailbox.clone(),
            cloud,
            period_ns: self.surfels_period_ns.max(1),
            next_full: None,
            last_stamp: None,
            last_full: None,
            status: NodeStatus::default(),
        })
    }

    fn on_pose(&mut self, p: &PoseStamped, out: &mut Vec<Message>) {
        let stamp = p.header.stamp.as_nanos();
        let pos = [p.pose.position.x, p.pose.position.y, p.pose.position.z];
        let q = p.pose.orientation;
        let last_stamp = self.last.map(|l| l.0);
        let pose = ToolPose::new(pos, [q.x, q.y, q.z, q.w]);
        let refuse = match &pose {
            Err(e) => Some(("bad_pose", format!("pose at {stamp} ns: {e}"))),
            Ok(_) if last_stamp.is_some_and(|l| stamp < l) => Some((
                "stamp_backwards",
                format!(
                    "pose at {stamp} ns is older than the last one ({} ns)",
                    last_stamp.unwrap_or(0)
                ),
            )),
            Ok(_) if !p.header.frame_id.is_empty() && p.header.frame_id != self.frame_id => Some((
                "unknown_frame",
                format!(
                    "pose at {stamp} ns in frame {:?}, not {:?}",
                    p.header.frame_id, self.frame_id
                ),
            )),
            Ok(_) => None,
        };
        if let Some((kind, why)) = refuse {
            self.status.problem(
                &self.fqn,
                kind,
                format!("{why}; ignored, workpiece unchanged"),
            );
            return;
        }
        let Ok(pose) = pose else { return };
        let qn = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
        if (qn - 1.0).abs() > 1e-6 {
            self.status.problem(
                &self.fqn,
                "non_unit_quaternion",
                format!("pose at {stamp} ns: quaternion of norm {qn} normalised"),
            );
        }
        self.first_stamp.get_or_insert(stamp);
        let kind = self.tool_at(stamp);
        let tool = match kind {
            ToolKind::Knife => &self.knife,
            ToolKind::Chisel => &self.chisel,
        };
        // A new stroke (first pose, or a tool change) starts where the tool is.
        let (from, dt) = match self.last {
            Some((t, prev, k)) if k == kind => (prev, (stamp - t) as f64 * 1e-9),
            Some((t, _, _)) => (pose, (stamp - t) as f64 * 1e-9),
            None => (pose, 0.0),
        };
        let cut = match self.work.carve(tool, &from, &pose) {
            Ok(c) => c,
            Err(e) => {
                self.status.problem(
                    &self.fqn,
                    "bad_move",
                    format!("pose at {stamp} ns: {e}; not cut"),
                );
                Default::default()
            }
        };
        self.last = Some((stamp, pose, kind));
        if let Some(t) = last_stamp.filter(|&t| stamp.saturating_sub(t) > PAUSE_NS) {
            let gap = (i128::from(stamp) - i128::from(t)) as f64 * 1e-9;
            self.status.problem(
                &self.fqn,
                "pose_pause",
                format!(
                    "no pose for {gap:.3} s before the pose at {stamp} ns: the force filter \
                     and coupling integrate {} s of it, and one workpiece frame is published \
                     for the pause",
                    chronotope_carving::MAX_MOVE_DT_S
                ),
            );
        }
        let motion = [0, 1, 2].map(|a| pose.position[a] - from.position[a]);
        let bad_before = self.force.non_finite_steps();
        let f = self.force.step(&cut, self.work.spacing(), motion, dt);
        if self.force.non_finite_steps() > bad_before {
            self.status.problem(
                &self.fqn,
                "non_finite_force",
                format!(
                    "pose at {stamp} ns: the rendered force came out non-finite; the last \
                     finite force ({:.3}, {:.3}, {:.3}) N is sent instead and the filter \
                     and coupling are reset to rest",
                    f[0], f[1], f[2]
                ),
            );
        }
        self.last_force = f;
        // The force first: the workpiece frames due are published after it.
        out.push(Message::new(
            &self.wrench_topic,
            stamp,
            Payload::WrenchStamped(Arc::new(WrenchStamped {
                header: Header {
                    stamp: p.header.stamp,
                    frame_id: self.frame_id.clone(),
                },
                wrench: Wrench {
                    force: Vector3::new(f[0], f[1], f[2]),
                    torque: Vector3::default(),
                },
            })),
        ));
        // The frame due, if any, showing the workpiece after this pose.
        self.publish_due(stamp, out);
    }
}

impl Node for CarvingNode {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        vec![TopicRef {
            topic: self.pose_topic.clone(),
            type_name: PoseStamped::TYPE_NAME,
        }]
    }

    fn publications(&self) -> Vec<TopicRef> {
        vec![
            TopicRef {
                topic: self.wrench_topic.clone(),
                type_name: WrenchStamped::TYPE_NAME,
            },
            if self.has_display {
                TopicRef {
                    topic: self.frame_topic.clone(),
                    type_name: chronotope_msg::Clock::TYPE_NAME,
                }
            } else {
                TopicRef {
                    topic: self.occupancy_topic.clone(),
                    type_name: VoxelGrid::TYPE_NAME,
                }
            },
        ]
    }

    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        self.status.received += 1;
        let before = out.len();
        match &msg.payload {
            Payload::PoseStamped(p) => self.on_pose(p, out),
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
        self.status.published += (out.len() - before) as u64;
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        // The final workpiece, on the period grid.
        if let Some(t) = self.next_publish {
            let before = out.len();
            self.publish_workpiece(t, true, out);
            self.status.published += (out.len() - before) as u64;
        }
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        0
    }
}

/// The carving node's display part (see the module): the surfel clouds, built from its own
/// copy of the cloud, off the force path.
pub struct CarvingDisplay {
    fqn: String,
    frame_topic: String,
    occupancy_topic: String,
    grid: GridShape,
    /// The occupancy bits, as of the last delta taken.
    bits: Vec<u8>,
    surfels_topic: String,
    changed_topic: String,
    frame_id: String,
    mailbox: Arc<Mutex<Option<(i64, SurfelDelta)>>>,
    /// The surfels' PointCloud2 bytes, as of the last delta taken.
    cloud: Vec<u8>,
    period_ns: i64,
    next_full: Option<i64>,
    last_stamp: Option<i64>,
    last_full: Option<i64>,
    status: NodeStatus,
}

/// Where the workpiece's grid points are.
struct GridShape {
    origin: [f64; 3],
    spacing: f64,
    dims: [usize; 3],
}

/// A VoxelGrid of the workpiece's points with occupancy `bits`.
fn occupancy_frame(work: &Workpiece, frame_id: &str, stamp: i64, bits: Vec<u8>) -> VoxelGrid {
    let (lo, _) = work.block_bounds();
    grid_frame(
        &GridShape {
            origin: lo,
            spacing: work.spacing(),
            dims: work.dims(),
        },
        frame_id,
        stamp,
        bits,
    )
}

fn grid_frame(g: &GridShape, frame_id: &str, stamp: i64, bits: Vec<u8>) -> VoxelGrid {
    VoxelGrid {
        header: Header {
            stamp: Time::from_nanos(stamp),
            frame_id: frame_id.to_owned(),
        },
        origin: Point {
            x: g.origin[0],
            y: g.origin[1],
            z: g.origin[2],
        },
        resolution: g.spacing,
        size_x: g.dims[0] as u32,
        size_y: g.dims[1] as u32,
        size_z: g.dims[2] as u32,
        encoding: VoxelGrid::ENCODING_BITS,
        data: bits,
    }
}

fn surfel_cloud(header: Header, data: Vec<u8>) -> PointCloud2 {
    let mut fields: Vec<PointField> = ["x", "y", "z", "normal_x", "normal_y", "normal_z", "radius"]
        .iter()
        .enumerate()
        .map(|(i, n)| PointField::new(*n, 4 * i as u32, PointField::FLOAT32, 1))
        .collect();
    fields.push(PointField::new("rgb", 28, PointField::UINT32, 1));
    let count = (data.len() / 32) as u32;
    PointCloud2 {
        header,
        height: 1,
        width: count,
        fields,
        is_bigendian: false,
        point_step: 32,
        row_step: 32 * count,
        data,
        is_dense: true,
    }
}

impl CarvingDisplay {
    /// The topic of the surfels changed since the last frame.
    pub fn changed_topic(&self) -> &str {
        &self.changed_topic
    }

    /// Surfels in its copy of the cloud.
    pub fn surfel_count(&self) -> usize {
        self.cloud.len() / 32
    }

    fn header(&self, stamp: i64) -> Header {
        Header {
            stamp: Time::from_nanos(stamp),
            frame_id: self.frame_id.clone(),
        }
    }

    /// Takes the parked delta, if any: applies it, publishes the changed surfels, and the
    /// whole cloud when it is due (or `force_full`).
    fn take(&mut self, force_full: bool, out: &mut Vec<Message>) {
        let parked = self
            .mailbox
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take();
        if let Some((stamp, delta)) = parked {
            delta.apply(&mut self.cloud);
            delta.apply_bits(&mut self.bits);
            self.last_stamp = Some(stamp);
            out.push(Message::new(
                &self.occupancy_topic,
                stamp,
                Payload::VoxelGrid(Arc::new(grid_frame(
                    &self.grid,
                    &self.frame_id,
                    stamp,
                    self.bits.clone(),
                ))),
            ));
            let mut data = Vec::with_capacity(delta.writes.len() * 32);
            for (_, b) in &delta.writes {
                data.extend_from_slice(b);
            }
            out.push(Message::new(
                &self.changed_topic,
                stamp,
                Payload::PointCloud2(Arc::new(surfel_cloud(self.header(stamp), data))),
            ));
            let due = *self.next_full.get_or_insert(stamp);
            if stamp >= due && !force_full {
                self.publish_full(stamp, out);
                let k = (i128::from(stamp) - i128::from(due)) / i128::from(self.period_ns) + 1;
                let next = i128::from(due) + k * i128::from(self.period_ns);
                self.next_full = Some(i64::try_from(next).unwrap_or(i64::MAX));
            }
        }
        if force_full && self.last_full != self.last_stamp {
            if let Some(stamp) = self.last_stamp {
                self.publish_full(stamp, out);
            }
        }
    }

    fn publish_full(&mut self, stamp: i64, out: &mut Vec<Message>) {
        self.last_full = Some(stamp);
        out.push(Message::new(
            &self.surfels_topic,
            stamp,
            Payload::PointCloud2(Arc::new(surfel_cloud(
                self.header(stamp),
                self.cloud.clone(),
            ))),
        ));
    }
}

impl Node for CarvingDisplay {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        vec![TopicRef {
            topic: self.frame_topic.clone(),
            type_name: chronotope_msg::Clock::TYPE_NAME,
        }]
    }

    fn publications(&self) -> Vec<TopicRef> {
        vec![
            TopicRef {
                topic: self.occupancy_topic.clone(),
                type_name: VoxelGrid::TYPE_NAME,
            },
            TopicRef {
                topic: self.surfels_topic.clone(),
                type_name: PointCloud2::TYPE_NAME,
            },
            TopicRef {
                topic: self.changed_topic.clone(),
                type_name: PointCloud2::TYPE_NAME,
            },
        ]
    }

    fn on_message(&mut self, frame: &Message, out: &mut Vec<Message>) {
        self.on_messages(std::slice::from_ref(frame), out);
    }

    fn on_messages(&mut self, msgs: &[Message], out: &mut Vec<Message>) {
        // Several frames waiting: the parked delta is one, whatever their number.
        self.status.received += msgs.len() as u64;
        let before = out.len();
        self.take(false, out);
        self.status.published += (out.len() - before) as u64;
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        let before = out.len();
        self.take(true, out);
        self.status.published += (out.len() - before) as u64;
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        // After the carving node, whose last frame it takes.
        1
    }
}
