//! The robot node: a robot as a body of the cell. Its URDF (the latest `std_msgs/String` on
//! `robot_description_topic`, or `urdf_file`), its joint states (`joint_states_topic`,
//! partial messages merged by name as robot_state_publisher does) or a plan
//! (`trajectory_topic`), and where it stands (`base_pose`, or `/tf_static`) become
//! VoxelGrid frames of its links' `<collision>` geometry on `~/occupancy` (or one topic per
//! body of `bodies`), on a lattice given or taken from another body (`lattice_from`), at
//! that body's frame stamps or on the `rate_hz` grid; each frame is the robot at the
//! frame's time, joint positions interpolated to it. With a plan, the checker's time
//! scalings of the robot come back as the plan retimed (`~/retimed_trajectory`).
//!
//! The geometry, kinematics, merging, sampling and rasterising are `chronotope_robot`'s;
//! this node only orders them in time. A frame waits until it can be made: a frame time
//! needs a joint-state sample at or after it for every joint (interpolation needs the
//! sample after), the lattice and the base pose. What waits is bounded
//! ([`MAX_PENDING_FRAMES`]), and so is the joint-state history (`history_s`).
//!
//! Bad input never stops the node. A URDF that does not load (malformed, unexpanded
//! xacro, a mesh that cannot be found or is over the limits, a loop, a zero scale) is a
//! counted problem naming what was wrong, and the node waits for another description; a
//! JointState message that cannot be applied whole (names not in the URDF, arrays of
//! different lengths, a non-finite position, a stamp going back) is refused and counted;
//! positions beyond a joint's limits are kept (the cell did move there), warned once and
//! counted; a plan whose times do not increase or that names unknown joints is refused.

mod params;
mod plan;
mod tf;

pub use tf::MAX_TF_FRAMES;

use std::collections::{BTreeSet, VecDeque};
use std::sync::Arc;

use chronotope_robot::math::Pose;
use chronotope_robot::{
    Encoding, JointStateError, JointStateHistory, Lattice, LimitViolation, LinkPoses, LoadOptions,
    RasterOptions, Rasterizer, Robot, RobotError, Stamp,
};

use self::params::{BodySpec, Description, LatticeSource, Settings};
use self::plan::Plan;
use self::tf::StaticTree;
use super::launch::{LaunchError, NodeSpec};
use super::{Message, Node, NodeStatus, Payload, TopicRef};
use chronotope_msg::{
    Header, InterferenceReport, JointState, JointTrajectory, Point, ResolveSuggestion,
    ResolveSuggestions, RosMessage, RosString, TFMessage, Time, VoxelGrid,
};

/// Frame times waiting to be made at most (`MAX_PENDING_FRAMES`); beyond it the oldest is
/// dropped and counted (`frames_dropped`).
pub const MAX_PENDING_FRAMES: usize = 4096;

/// Frames of a plan on the `rate_hz` grid at most (`MAX_PLAN_FRAMES`): a plan longer than
/// this many periods is checked over its first ones (`plan_cut`).
pub const MAX_PLAN_FRAMES: usize = 36_000;

/// Frames made per message or tick at most while a plan's frames are made ahead of time (the
/// rest follow on the next ones and at the end), so that what one step publishes stays
/// bounded.
const FRAMES_PER_STEP: usize = 32;

/// Retimings remembered, to publish each once.
const MAX_RETIMINGS: usize = 1024;

/// A robot loaded from a description, ready to make frames.
struct Loaded {
    robot: Robot,
    /// One per published body.
    bodies: Vec<chronotope_robot::Body>,
    history: JointStateHistory,
    /// A hash of the description it came from (the same text again changes nothing).
    source: u64,
    q: Vec<f64>,
    poses: LinkPoses,
    violations: Vec<LimitViolation>,
}

/// Why a robot is refused as it is loaded: its URDF or meshes, or the bodies it is cut into.
#[derive(Debug, thiserror::Error)]
enum LoadError {
    /// The URDF or a mesh does not load.
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// A body of parameter `bodies` names a link the URDF does not have.
    #[error("parameter bodies: {body} names link `{link}`, which is not a link of the URDF")]
    UnknownLink {
        /// The body, as messages name it ("the body", "body `arm`").
        body: String,
        /// The link.
        link: String,
    },
}

/// What a frame time can be made from now.
enum Readiness {
    /// The joints' positions are in `q`.
    Ready,
    /// Not yet: more input is needed.
    Wait,
    /// Never: the frame is dropped (the problem kind and text).
    Drop(&'static str, String),
}

/// The robot node.
pub struct RobotNode {
    s: Settings,
    loaded: Option<Loaded>,
    lattice: Option<Lattice>,
    frame_id: Option<String>,
    rasters: Vec<Rasterizer>,
    /// Per body, the frames it published lately (see [`Recent`]).
    recent: Vec<Recent>,
    base: Option<Pose>,
    tf: StaticTree,
    /// Frame times waiting to be made, increasing.
    pending: VecDeque<Stamp>,
    /// The last frame time queued.
    last_queued: Option<Stamp>,
    /// The next time on the `rate_hz` grid (rate mode).
    next_grid: Option<Stamp>,
    plan: Option<Plan>,
    /// The checker's time origin (from its report), for its suggestions' times.
    time_origin: Option<Stamp>,
    /// Suggestions that came before any report.
    waiting_suggestions: Option<Arc<ResolveSuggestions>>,
    retimed: BTreeSet<[u64; 3]>,
    /// Frames made so far.
    frames: u64,
    status: NodeStatus,
}

fn hash_text(text: &str) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    text.hash(&mut h);
    h.finish()
}

impl RobotNode {
    /// The node a launch config describes. A `urdf_file` is loaded here, so that a robot
    /// that cannot be loaded is refused at launch with the reason.
    ///
    /// # Errors
    /// A bad parameter, or a `urdf_file` that does not load.
    pub fn from_spec(spec: &NodeSpec) -> Result<Self, LaunchError> {
        let s = params::settings(spec)?;
        let lattice = match &s.lattice {
            LatticeSource::Given(l) => Some(*l),
            LatticeSource::From(_) => None,
        };
        let mut node = Self {
            frame_id: s.frame_id.clone(),
            base: s.base_pose.map(|b| b.to_pose()),
            s,
            loaded: None,
            lattice: None,
            rasters: Vec::new(),
            recent: Vec::new(),
            tf: StaticTree::default(),
            pending: VecDeque::new(),
            last_queued: None,
            next_grid: None,
            plan: None,
            time_origin: None,
            waiting_suggestions: None,
            retimed: BTreeSet::new(),
            frames: 0,
            status: NodeStatus::default(),
        };
        if let Some(l) = lattice {
            node.set_lattice(l);
            if node.frame_id.is_none() {
                node.frame_id = Some("world".into());
            }
        }
        if let Description::File(path) = node.s.description.clone() {
            let options = LoadOptions::new().package_path(node.s.package_path.clone());
            let loaded = Robot::from_urdf_file(&path, options)
                .map_err(LoadError::from)
                .and_then(|r| node.prepare(r, 0));
            match loaded {
                Ok(l) => node.loaded = Some(l),
                Err(reason) => {
                    return Err(LaunchError::Param {
                        node: node.s.fqn.clone(),
                        param: "urdf_file".into(),
                        reason: format!("{}: {reason}", path.display()),
                    })
                }
            }
            node.after_load();
        }
        Ok(node)
    }

    /// The topics of the bodies it publishes, in order.
    pub fn body_topics(&self) -> impl Iterator<Item = &str> {
        self.s.bodies.iter().map(|b| b.topic.as_str())
    }

    /// The body whose lattice (and, by default, frame times) it takes (`lattice_from`).
    pub fn lattice_from(&self) -> Option<&str> {
        match &self.s.lattice {
            LatticeSource::From(t) => Some(t),
            LatticeSource::Given(_) => None,
        }
    }

    /// The loaded robot, if any.
    pub fn robot(&self) -> Option<&Robot> {
        self.loaded.as_ref().map(|l| &l.robot)
    }

    /// Frames made so far (all bodies together count once per time).
    pub fn frames(&self) -> u64 {
        self.frames
    }

    fn problem(&mut self, kind: &str, text: String) {
        self.status.problem(&self.s.fqn, kind, text);
    }

    fn quietly(&mut self, kind: &str, n: u64, text: impl FnOnce() -> String) {
        self.status.count_quietly(&self.s.fqn, kind, n, text);
    }

    /// Checks a freshly loaded robot against the bodies and makes its history.
    fn prepare(&self, robot: Robot, source: u64) -> Result<Loaded, LoadError> {
        let mut bodies = Vec::new();
        for b in &self.s.bodies {
            let body = if b.links.is_empty() {
                robot.whole_body()
            } else {
                robot.body(&b.links).map_err(|e| match e {
                    RobotError::UnknownLink(link) => LoadError::UnknownLink {
                        body: body_label(b),
                        link,
                    },
                    e => LoadError::Robot(e),
                })?
            };
            bodies.push(body);
        }
        let history = JointStateHistory::new(robot.kinematics(), self.s.history);
        Ok(Loaded {
            q: vec![0.0; robot.kinematics().dof()],
            bodies,
            history,
            source,
            poses: LinkPoses::new(),
            violations: Vec::new(),
            robot,
        })
    }

    /// Logs what loading found and resolves the base pose if it can.
    fn after_load(&mut self) {
        let Some(l) = &self.loaded else { return };
        let model = l.robot.model();
        let open: Vec<String> = l
            .robot
            .load_report()
            .open_meshes()
            .map(|m| format!("{} ({} boundary edges)", m.path.display(), m.boundary_edges))
            .collect();
        tracing::info!(
            node = self.s.fqn,
            "robot `{}`: {} links, {} joints, {} movable, {} mesh triangles",
            model.name,
            model.links.len(),
            model.joints.len(),
            l.robot.kinematics().dof(),
            l.robot.load_report().triangles
        );
        let covered: BTreeSet<usize> = l
            .bodies
            .iter()
            .flat_map(|b| b.links().iter().copied())
            .collect();
        let left: Vec<&str> = (0..model.links.len())
            .filter(|i| !covered.contains(i) && !model.links[*i].collisions.is_empty())
            .map(|i| model.links[i].name.as_str())
            .collect();
        if !left.is_empty() {
            tracing::info!(
                node = self.s.fqn,
                "links in no body (not rasterised): {}",
                left.join(", ")
            );
        }
        if !open.is_empty() {
            let text = format!(
                "open collision meshes (no inside: only their surface is occupied): {}",
                open.join(", ")
            );
            self.problem("open_mesh", text);
        }
        self.resolve_base();
    }

    fn set_lattice(&mut self, l: Lattice) {
        let options = RasterOptions::default().subsamples(self.s.subsamples);
        self.rasters = self
            .s
            .bodies
            .iter()
            .map(|_| Rasterizer::new(l, self.s.encoding, options))
            .collect();
        self.recent = self.s.bodies.iter().map(|_| Recent::default()).collect();
        self.lattice = Some(l);
    }

    /// The base pose from `/tf_static`, once the lattice frame and the robot are known.
    fn resolve_base(&mut self) {
        if self.base.is_some() || self.s.tf_static_topic.is_none() {
            return;
        }
        let (Some(frame), Some(l)) = (&self.frame_id, &self.loaded) else {
            return;
        };
        let model = l.robot.model();
        let root = &model.links[model.root()].name;
        if let Some(p) = self.tf.pose_of(root, frame) {
            tracing::info!(
                node = self.s.fqn,
                "base pose from /tf_static: `{root}` at ({:.3}, {:.3}, {:.3}) m in `{frame}`",
                p.translation.vector.x,
                p.translation.vector.y,
                p.translation.vector.z
            );
            self.base = Some(p);
        }
    }

    fn on_description(&mut self, m: &RosString) {
        let h = hash_text(&m.data);
        if self.loaded.as_ref().is_some_and(|l| l.source == h) {
            return;
        }
        let options = LoadOptions::new().package_path(self.s.package_path.clone());
        let result = Robot::from_urdf_str(&m.data, &options)
            .map_err(LoadError::from)
            .and_then(|r| self.prepare(r, h));
        match result {
            Ok(l) => {
                if self.loaded.is_some() {
                    tracing::warn!(
                        node = self.s.fqn,
                        "a new robot description: the robot is loaded again and its joint \
                         states start afresh"
                    );
                }
                self.loaded = Some(l);
                if self.s.tf_static_topic.is_some() {
                    self.base = None;
                }
                self.after_load();
            }
            Err(reason) => self.problem(
                "bad_robot_description",
                format!(
                    "{}: the robot description is refused: {reason}",
                    description_topic(&self.s)
                ),
            ),
        }
    }

    fn on_joint_state(&mut self, m: &JointState, arrival: Stamp) {
        let Some(l) = self.loaded.as_mut() else {
            let topic = self.s.joint_states_topic.clone();
            self.quietly("joint_states_before_description", 1, || {
                format!("{topic}: joint states before any robot description are not kept")
            });
            return;
        };
        let stamp = match m.header.stamp.as_nanos() {
            0 => arrival,
            s => s,
        };
        for (field, len) in [("velocity", m.velocity.len()), ("effort", m.effort.len())] {
            if len != 0 && len != m.name.len() {
                let text = format!(
                    "{}: JointState has {} names but {len} values in `{field}` (all arrays \
                     have one value per name, or none); the message is not applied",
                    self.s.joint_states_topic,
                    m.name.len()
                );
                self.problem("joint_state_refused", text);
                return;
            }
        }
        match l.history.merge(stamp, &m.name, &m.position) {
            Ok(merged) => {
                if merged.beyond_limits > 0 {
                    l.violations.clear();
                    if l.history.positions_at(stamp, &mut l.q).is_ok() {
                        l.robot
                            .kinematics()
                            .limit_violations(&l.q, &mut l.violations);
                    }
                    let first = l.violations.first().map(|v| {
                        format!(
                            "{}: joint `{}` at {:.4} is beyond its limits [{:.4}, {:.4}]; kept \
                             (the cell did move there)",
                            self.s.joint_states_topic,
                            v.joint,
                            v.position,
                            v.limits.lower,
                            v.limits.upper
                        )
                    });
                    let n = merged.beyond_limits as u64;
                    self.quietly("beyond_limits", n, || {
                        first.unwrap_or_else(|| "a position beyond its joint's limits".into())
                    });
                }
                if self.s.follow_stamps || self.plan.is_some() {
                    return;
                }
                self.queue_grid_until(stamp);
            }
            Err(e) => {
                let kind = match e {
                    JointStateError::NonFinite { .. } => "non_finite_position",
                    _ => "joint_state_refused",
                };
                let text = format!("{}: {e}", self.s.joint_states_topic);
                if kind == "non_finite_position" {
                    let n = m.position.iter().filter(|p| !p.is_finite()).count() as u64;
                    self.quietly(kind, n.max(1), || text);
                } else {
                    self.problem(kind, text);
                }
            }
        }
    }

    /// Queues the `rate_hz` grid times up to `until`.
    fn queue_grid_until(&mut self, until: Stamp) {
        let period = self.s.period_ns.max(1);
        let next = *self
            .next_grid
            .get_or_insert_with(|| (until.div_euclid(period) * period).saturating_add(period));
        // Only the newest MAX_PENDING_FRAMES grid times can wait: a stamp far ahead of the
        // last (a clock jump, a bad stamp) skips the older ones, counted, without visiting
        // them one by one.
        let mut t = next;
        if until >= next {
            let n = (i128::from(until) - i128::from(next)) / i128::from(period) + 1;
            let keep = MAX_PENDING_FRAMES as i128;
            if n > keep {
                let skipped = n - keep;
                let jump = i64::try_from(skipped * i128::from(period)).unwrap_or(i64::MAX);
                t = t.saturating_add(jump);
                self.quietly(
                    "frames_dropped",
                    u64::try_from(skipped).unwrap_or(u64::MAX),
                    || {
                        format!(
                            "the grid times jump by more than MAX_PENDING_FRAMES = \
                         {MAX_PENDING_FRAMES} frames (to {:.3} s): the {skipped} oldest are not \
                         made",
                            until as f64 * 1e-9
                        )
                    },
                );
            }
        }
        while t <= until {
            self.queue(t);
            match t.checked_add(period) {
                Some(x) => t = x,
                None => break,
            }
        }
        self.next_grid = Some(t);
    }

    fn queue(&mut self, t: Stamp) {
        if self.last_queued.is_some_and(|l| t <= l) {
            return;
        }
        self.last_queued = Some(t);
        self.pending.push_back(t);
        if self.pending.len() > MAX_PENDING_FRAMES {
            self.pending.pop_front();
            self.quietly("frames_dropped", 1, || {
                format!(
                    "more than MAX_PENDING_FRAMES = {MAX_PENDING_FRAMES} frames wait (for the \
                     robot description, the lattice, the base pose or joint states): the \
                     oldest are dropped"
                )
            });
        }
    }

    fn on_reference_frame(&mut self, g: &VoxelGrid) {
        let l = Lattice::new(
            [g.origin.x, g.origin.y, g.origin.z],
            g.resolution,
            [g.size_x, g.size_y, g.size_z],
        );
        match (self.lattice, l) {
            (None, Ok(l)) => {
                self.set_lattice(l);
                match &self.frame_id {
                    None => self.frame_id = Some(g.header.frame_id.clone()),
                    Some(f) if *f != g.header.frame_id => {
                        let text = format!(
                            "frame_id `{f}` differs from the lattice_from body's `{}`: bodies \
                             in different frames are not compared",
                            g.header.frame_id
                        );
                        self.problem("frame_mismatch", text);
                    }
                    Some(_) => {}
                }
                self.resolve_base();
            }
            (None, Err(e)) => {
                let text = format!(
                    "{}: its lattice cannot be rasterised onto: {e}",
                    self.lattice_from().unwrap_or_default()
                );
                self.problem("bad_reference_lattice", text);
                return;
            }
            (Some(have), Ok(l)) if have != l => {
                let from = self.lattice_from().unwrap_or_default().to_owned();
                self.quietly("reference_lattice_changed", 1, || {
                    format!("{from}: a frame on another lattice; the robot stays on the first one")
                });
            }
            _ => {}
        }
        if self.s.follow_stamps {
            self.queue(g.header.stamp.as_nanos());
        }
    }

    fn on_plan(&mut self, m: &JointTrajectory, arrival: Stamp) {
        let topic = self.s.trajectory_topic.clone().unwrap_or_default();
        let Some(l) = &self.loaded else {
            self.problem(
                "plan_refused",
                format!("{topic}: a plan before any robot description; ignored"),
            );
            return;
        };
        match Plan::new(m, arrival, l.robot.kinematics(), &l.history) {
            Ok(p) => {
                tracing::info!(
                    node = self.s.fqn,
                    "{topic}: a plan of {} points for {} joints, from {:.3} s to {:.3} s",
                    m.points.len(),
                    m.joint_names.len(),
                    p.start() as f64 * 1e-9,
                    p.end as f64 * 1e-9
                );
                if !self.s.follow_stamps {
                    let period = self.s.period_ns.max(1);
                    let first = (arrival.div_euclid(period) * period).saturating_add(period);
                    // Grid times from the first after the arrival through the first at or after the end.
                    let span = (i128::from(p.end) - i128::from(first)).max(0);
                    let frames =
                        usize::try_from((span + i128::from(period) - 1) / i128::from(period) + 1)
                            .unwrap_or(usize::MAX);
                    if frames > MAX_PLAN_FRAMES {
                        self.problem(
                            "plan_cut",
                            format!(
                                "{topic}: the plan lasts {frames} frame periods; it is checked \
                                 over its first MAX_PLAN_FRAMES = {MAX_PLAN_FRAMES}"
                            ),
                        );
                    }
                    let until =
                        first.saturating_add((frames.min(MAX_PLAN_FRAMES) as i64 - 1) * period);
                    self.next_grid = self.next_grid.map(|g| g.min(first)).or(Some(first));
                    self.queue_grid_until(until);
                }
                self.plan = Some(p);
            }
            Err(e) => self.problem("plan_refused", format!("{topic}: plan refused: {e}")),
        }
    }

    fn on_report(&mut self, r: &InterferenceReport, out: &mut Vec<Message>) {
        self.time_origin = Some(r.time_origin.as_nanos());
        if let Some(s) = self.waiting_suggestions.take() {
            self.on_suggestions(&s, out);
        }
    }

    fn on_suggestions(&mut self, m: &Arc<ResolveSuggestions>, out: &mut Vec<Message>) {
        let Some(origin) = self.time_origin else {
            self.waiting_suggestions = Some(m.clone());
            return;
        };
        for s in &m.suggestions {
            if s.kind != ResolveSuggestion::KIND_TIME_SCALE
                || !self.s.bodies.iter().any(|b| b.topic == s.body_id)
            {
                continue;
            }
            let key = [s.episode_start_s, s.t0_s, s.scale].map(f64::to_bits);
            if self.retimed.contains(&key) || self.retimed.len() >= MAX_RETIMINGS {
                continue;
            }
            self.retimed.insert(key);
            self.retime(s, origin, out);
        }
    }

    /// Publishes the plan retimed as the checker's verified time scaling `s` says.
    fn retime(&mut self, s: &ResolveSuggestion, origin: Stamp, out: &mut Vec<Message>) {
        let at = |sec: f64| origin.saturating_add((sec * 1e9).round() as i64);
        let what = format!(
            "retiming of {} (t0 {:.3} s, scale {:.4}) for the contact episode {:.3}-{:.3} s",
            s.body_id, s.t0_s, s.scale, s.episode_start_s, s.episode_end_s
        );
        if !s.verified_clear {
            self.problem(
                "retiming_not_verified",
                format!("{what}: not verified clear by the checker; not published"),
            );
            return;
        }
        let Some(plan) = &self.plan else {
            self.problem(
                "retiming_without_plan",
                format!("{what}: the robot follows joint states, no plan to retime"),
            );
            return;
        };
        let (a, b) = (at(s.episode_start_s), at(s.episode_end_s));
        if b < plan.arrival || a > plan.end {
            let text = format!("{what}: the episode is outside the plan's time; not published");
            self.problem("retiming_outside_plan", text);
            return;
        }
        let Some(topic) = self.s.retimed_topic.clone() else {
            return;
        };
        match plan.retimed(at(s.t0_s), s.scale) {
            Ok(m) => {
                let stamp = m.header.stamp.as_nanos();
                tracing::info!(
                    node = self.s.fqn,
                    "{what}: the plan retimed, starting at {:.3} s, on {topic}{}",
                    stamp as f64 * 1e-9,
                    if s.unsure_start_s.is_empty() {
                        String::new()
                    } else {
                        " (verified clear except where a body is not observed well enough)".into()
                    }
                );
                out.push(Message::new(
                    &topic,
                    stamp,
                    Payload::JointTrajectory(Arc::new(m)),
                ));
            }
            Err(e) => self.problem("retiming_refused", format!("{what}: {e}")),
        }
    }

    /// Whether frame time `t` can be made now; on `Ready`, the positions are in `q`.
    fn readiness(&mut self, t: Stamp, finishing: bool) -> Readiness {
        let timeout = self.s.joint_states_timeout_ns;
        let Some(l) = self.loaded.as_mut() else {
            return if finishing {
                Readiness::Drop(
                    "no_robot",
                    format!(
                        "no robot description was loaded from {}: no frame made",
                        description_topic(&self.s)
                    ),
                )
            } else {
                Readiness::Wait
            };
        };
        if self.lattice.is_none() {
            return if finishing {
                Readiness::Drop(
                    "no_lattice",
                    format!(
                        "no frame of {} came: no lattice to make frames on",
                        self.lattice_from().unwrap_or_default()
                    ),
                )
            } else {
                Readiness::Wait
            };
        }
        if self.base.is_none() {
            return if finishing {
                let root = &l.robot.model().links[l.robot.model().root()].name;
                Readiness::Drop(
                    "no_base_pose",
                    format!(
                        "where the robot stands is not known: no transform from `{}` to its \
                         root link `{root}` on {}; give base_pose, or record /tf_static",
                        self.frame_id.as_deref().unwrap_or("?"),
                        self.s.tf_static_topic.as_deref().unwrap_or("/tf_static")
                    ),
                )
            } else {
                Readiness::Wait
            };
        }
        if let Some(p) = self.plan.as_mut().filter(|p| t >= p.arrival) {
            return match p.positions_at(t, &mut l.q) {
                Ok(()) => Readiness::Ready,
                Err(e) => Readiness::Drop("plan_refused", e.to_string()),
            };
        }
        match l.history.positions_at(t, &mut l.q) {
            Ok(how) if how.held == 0 => Readiness::Ready,
            Ok(how) if finishing && how.max_hold <= timeout => Readiness::Ready,
            Ok(how) if finishing => Readiness::Drop(
                "joint_states_ended",
                format!(
                    "frames after the last joint states ({} joint(s) silent for {:.3} s, over \
                     joint_states_timeout_s) are not made",
                    how.held,
                    how.max_hold as f64 * 1e-9
                ),
            ),
            Ok(_) => Readiness::Wait,
            // A joint no message has given yet (the first partial messages of an instant).
            Err(JointStateError::NotKnown { first: None, .. }) if !finishing => Readiness::Wait,
            Err(e) => Readiness::Drop(
                "before_joint_states",
                format!("a frame at {:.3} s cannot be made: {e}", t as f64 * 1e-9),
            ),
        }
    }

    /// Makes the waiting frames that can be made, in order (at most `limit`).
    fn make_frames(&mut self, finishing: bool, limit: usize, out: &mut Vec<Message>) {
        let mut made = 0;
        while let Some(&t) = self.pending.front() {
            if made >= limit {
                break;
            }
            match self.readiness(t, finishing) {
                Readiness::Wait => break,
                Readiness::Drop(kind, text) => {
                    self.pending.pop_front();
                    self.quietly(kind, 1, || text);
                }
                Readiness::Ready => {
                    self.pending.pop_front();
                    self.frame(t, out);
                    made += 1;
                }
            }
        }
    }

    /// Publishes every body's frame at `t` from the positions in `q`.
    fn frame(&mut self, t: Stamp, out: &mut Vec<Message>) {
        let (Some(l), Some(lattice), Some(base)) = (self.loaded.as_mut(), self.lattice, self.base)
        else {
            return;
        };
        l.robot.kinematics().forward_from(&l.q, &base, &mut l.poses);
        let frame_id = self.frame_id.clone().unwrap_or_else(|| "world".into());
        let size = lattice.size();
        let o = lattice.origin();
        for (k, spec) in self.s.bodies.iter().enumerate() {
            let raster = &mut self.rasters[k];
            raster.rasterize(&l.robot, &l.bodies[k], &l.poses);
            let (data, written) = self.recent[k].data_for(raster);
            let g = VoxelGrid {
                header: Header {
                    stamp: Time::from_nanos(t),
                    frame_id: frame_id.clone(),
                },
                origin: Point {
                    x: o[0],
                    y: o[1],
                    z: o[2],
                },
                resolution: lattice.resolution(),
                size_x: size[0],
                size_y: size[1],
                size_z: size[2],
                encoding: match self.s.encoding {
                    Encoding::Bits => VoxelGrid::ENCODING_BITS,
                    Encoding::Percent => VoxelGrid::ENCODING_PERCENT,
                },
                data,
            };
            let g = Arc::new(g);
            self.recent[k].keep(&g, written);
            out.push(Message::new(&spec.topic, t, Payload::VoxelGrid(g)));
        }
        self.frames += 1;
    }
}

/// How many of a body's last frames are kept to lend their buffers (see [`Recent`]).
const RECENT_FRAMES: usize = 4;

/// A body's last [`RECENT_FRAMES`] published frames, each with the spans of its data that may
/// be non-zero. A frame every reader has dropped lends its buffer to the next frame, which
/// then rewrites only those spans and its own ([`Rasterizer::copy_into`]) instead of copying
/// the whole frame into fresh memory: a robot covers a small part of its lattice, and copying
/// and faulting in each 2 MB (128³) to 17 MB (256³) `percent` frame was most of the node's
/// time. Frames still held elsewhere are left alone; the memory kept is at most
/// [`RECENT_FRAMES`] frames a body.
#[derive(Default)]
struct Recent {
    frames: VecDeque<(Arc<VoxelGrid>, Vec<(usize, usize)>)>,
}

impl Recent {
    /// The next frame's data, copied from `raster` into a free buffer when there is one.
    fn data_for(&mut self, raster: &Rasterizer) -> (Vec<u8>, Vec<(usize, usize)>) {
        let free = self
            .frames
            .iter()
            .position(|(g, _)| Arc::strong_count(g) == 1 && Arc::weak_count(g) == 0);
        let (mut data, mut written) = match free.and_then(|i| self.frames.remove(i)) {
            Some((g, written)) => match Arc::try_unwrap(g) {
                Ok(g) => (g.data, written),
                Err(_) => (Vec::new(), Vec::new()),
            },
            None => (Vec::new(), Vec::new()),
        };
        raster.copy_into(&mut data, &mut written);
        (data, written)
    }

    /// Keeps `g` (published with `written`) to lend its buffer once nobody else holds it.
    fn keep(&mut self, g: &Arc<VoxelGrid>, written: Vec<(usize, usize)>) {
        if self.frames.len() >= RECENT_FRAMES {
            self.frames.pop_front();
        }
        self.frames.push_back((Arc::clone(g), written));
    }
}

fn body_label(b: &BodySpec) -> String {
    if b.name.is_empty() {
        "the body".into()
    } else {
        format!("body `{}`", b.name)
    }
}

fn description_topic(s: &Settings) -> String {
    match &s.description {
        Description::Topic(t) => t.clone(),
        Description::File(f) => f.display().to_string(),
    }
}

impl Node for RobotNode {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.s.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        let mut v = Vec::new();
        let mut add = |topic: &str, type_name: &'static str| {
            v.push(TopicRef {
                topic: topic.to_owned(),
                type_name,
            })
        };
        if let Description::Topic(t) = &self.s.description {
            add(t, RosString::TYPE_NAME);
        }
        add(&self.s.joint_states_topic, JointState::TYPE_NAME);
        if let Some(t) = &self.s.tf_static_topic {
            add(t, TFMessage::TYPE_NAME);
        }
        if let LatticeSource::From(t) = &self.s.lattice {
            add(t, VoxelGrid::TYPE_NAME);
        }
        if let Some(t) = &self.s.trajectory_topic {
            add(t, JointTrajectory::TYPE_NAME);
        }
        if let Some(t) = &self.s.suggestions_topic {
            add(t, ResolveSuggestions::TYPE_NAME);
        }
        if let Some(t) = &self.s.report_topic {
            add(t, InterferenceReport::TYPE_NAME);
        }
        v
    }

    fn publications(&self) -> Vec<TopicRef> {
        let mut v: Vec<TopicRef> = self
            .s
            .bodies
            .iter()
            .map(|b| TopicRef {
                topic: b.topic.clone(),
                type_name: VoxelGrid::TYPE_NAME,
            })
            .collect();
        if let Some(t) = &self.s.retimed_topic {
            v.push(TopicRef {
                topic: t.clone(),
                type_name: JointTrajectory::TYPE_NAME,
            });
        }
        v
    }

    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        self.status.received += 1;
        let before = out.len();
        let topic = &*msg.topic;
        match &msg.payload {
            Payload::Text(m) if matches!(&self.s.description, Description::Topic(t) if t == topic) => {
                self.on_description(m)
            }
            Payload::JointState(m) if topic == self.s.joint_states_topic => {
                self.on_joint_state(m, msg.stamp_ns)
            }
            Payload::TFMessage(m) if self.s.tf_static_topic.as_deref() == Some(topic) => {
                let added = self.tf.add(m);
                for r in added.refused {
                    self.problem("bad_transform", format!("{topic}: {r}; ignored"));
                }
                self.resolve_base();
            }
            Payload::VoxelGrid(g) if self.lattice_from() == Some(topic) => {
                self.on_reference_frame(g)
            }
            Payload::JointTrajectory(m) if self.s.trajectory_topic.as_deref() == Some(topic) => {
                self.on_plan(m, msg.stamp_ns)
            }
            Payload::Report(r) if self.s.report_topic.as_deref() == Some(topic) => {
                self.on_report(r, out)
            }
            Payload::Suggestions(s) if self.s.suggestions_topic.as_deref() == Some(topic) => {
                self.on_suggestions(s, out)
            }
            other => {
                let text = format!("{topic}: an unexpected {}; ignored", other.type_name());
                self.problem("wrong_type", text);
            }
        }
        self.make_frames(false, FRAMES_PER_STEP, out);
        self.status.published += (out.len() - before) as u64;
    }

    fn on_tick(&mut self, now_ns: i64, out: &mut Vec<Message>) {
        let before = out.len();
        self.make_frames(false, FRAMES_PER_STEP, out);
        // Live: a frame whose joint states have not come within the timeout of the clock is
        // not waited for any longer (its joint states stopped).
        let timeout = self.s.joint_states_timeout_ns;
        while let Some(&t) = self.pending.front() {
            if now_ns.saturating_sub(t) <= timeout.saturating_mul(4) || self.plan.is_some() {
                break;
            }
            match self.readiness(t, true) {
                Readiness::Ready => {
                    self.pending.pop_front();
                    self.frame(t, out);
                }
                Readiness::Drop(kind, text) => {
                    self.pending.pop_front();
                    self.quietly(kind, 1, || text);
                }
                Readiness::Wait => break,
            }
        }
        self.status.published += (out.len() - before) as u64;
    }

    fn finish(&mut self, out: &mut Vec<Message>) {
        let before = out.len();
        self.make_frames(true, usize::MAX, out);
        if self.frames == 0 && self.s.trajectory_topic.is_none() {
            let why = format!(
                "no frame was made (robot loaded: {}, lattice: {}, base pose: {})",
                self.loaded.is_some(),
                self.lattice.is_some(),
                self.base.is_some()
            );
            self.problem("no_frames", why);
        }
        self.status.published += (out.len() - before) as u64;
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        // Before the mesher, which meshes its last frames.
        1
    }
}
