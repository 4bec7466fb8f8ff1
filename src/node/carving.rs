//! The carving node: a haptic tool's poses in (geometry_msgs/PoseStamped on `pose_topic`),
//! a penalty force back per pose (`~/wrench`, WrenchStamped), and the workpiece published
//! every `occupancy_period_s` as VoxelGrid frames (`~/occupancy`, so the mesher can watch it)
//! and as PointCloud2 surfels (`~/surfels`: x, y, z and the outward normal of each boundary
//! voxel).
//!
//! The workpiece here is a voxel block carved by a ball tool: every voxel whose centre lies
//! within the ball is removed, and the force is `stiffness · depth` along the direction from
//! the material to the tool centre, from the material the ball was in before it cut. The
//! surfel workpiece and the other tools of issue 6 replace this model; the topics, messages
//! and input checks stay.
//!
//! Parameters: `pose_topic` (required), `frame_id` (default `world`; poses in another frame are
//! refused), `tool_radius_m` (0.004), `workpiece_min` / `workpiece_max` ([m], the block),
//! `resolution_m` (0.002), `stiffness_n_per_m` (800), `occupancy_period_s` (0.1).

use std::sync::Arc;

use super::launch::{LaunchError, NodeSpec, Params};
use super::{Message, Node, NodeStatus, Payload, TopicRef};
use crate::msg::{
    Header, Point, PointCloud2, PointField, PoseStamped, RosMessage, Time, Vector3, VoxelGrid,
    Wrench, WrenchStamped,
};

/// Most voxels of a workpiece.
const MAX_VOXELS: u64 = 1 << 24;

/// The carving node.
pub struct CarvingNode {
    fqn: String,
    pose_topic: String,
    wrench_topic: String,
    occupancy_topic: String,
    surfels_topic: String,
    frame_id: String,
    radius: f64,
    origin: [f64; 3],
    res: f64,
    size: [u32; 3],
    stiffness: f64,
    period_ns: i64,
    occupied: Vec<bool>,
    last_stamp: Option<i64>,
    next_publish: Option<i64>,
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
        let radius = p.double("tool_radius_m", 0.004, 1e-6..=10.0)?;
        let lo = p.doubles("workpiece_min", [0.0, 0.0, 0.0])?;
        let hi = p.doubles("workpiece_max", [0.06, 0.06, 0.03])?;
        let res = p.double("resolution_m", 0.002, 1e-6..=10.0)?;
        let stiffness = p.double("stiffness_n_per_m", 800.0, 0.0..=1e9)?;
        let period = p.double("occupancy_period_s", 0.1, 1e-3..=3600.0)?;
        let wrench_topic = p.resolve("~/wrench", "~/wrench")?;
        let occupancy_topic = p.resolve("~/occupancy", "~/occupancy")?;
        let surfels_topic = p.resolve("~/surfels", "~/surfels")?;
        p.finish()?;
        let mut size = [0u32; 3];
        for k in 0..3 {
            let n = ((hi[k] - lo[k]) / res).round();
            if !(1.0..=4096.0).contains(&n) {
                return Err(bad(
                    "workpiece_max",
                    format!("the block is {n} voxels along axis {k}; 1..=4096 allowed"),
                ));
            }
            size[k] = n as u32;
        }
        let voxels = size.iter().map(|&v| u64::from(v)).product::<u64>();
        if voxels > MAX_VOXELS {
            return Err(bad(
                "resolution_m",
                format!("{voxels} voxels: at most {MAX_VOXELS}"),
            ));
        }
        Ok(Self {
            fqn: node,
            pose_topic,
            wrench_topic,
            occupancy_topic,
            surfels_topic,
            frame_id,
            radius,
            origin: lo,
            res,
            size,
            stiffness,
            period_ns: (period * 1e9).round() as i64,
            occupied: vec![true; voxels as usize],
            last_stamp: None,
            next_publish: None,
            status: NodeStatus::default(),
        })
    }

    /// The topic of the workpiece's occupancy frames.
    pub fn occupancy_topic(&self) -> &str {
        &self.occupancy_topic
    }

    fn idx(&self, i: u32, j: u32, k: u32) -> usize {
        (i as usize) + self.size[0] as usize * (j as usize + self.size[1] as usize * k as usize)
    }

    fn centre(&self, i: u32, j: u32, k: u32) -> [f64; 3] {
        let v = [i, j, k];
        [0, 1, 2].map(|a| self.origin[a] + (f64::from(v[a]) + 0.5) * self.res)
    }

    /// Occupied voxels left.
    pub fn occupied_voxels(&self) -> usize {
        self.occupied.iter().filter(|&&o| o).count()
    }

    /// Carves with the ball at `c`; returns the force on the tool (N).
    fn carve(&mut self, c: [f64; 3]) -> [f64; 3] {
        let r = self.radius;
        let range = |a: usize| {
            let lo = ((c[a] - r - self.origin[a]) / self.res).floor().max(0.0);
            let hi = ((c[a] + r - self.origin[a]) / self.res)
                .ceil()
                .min(f64::from(self.size[a]));
            (lo as u32, (hi as u32).max(lo as u32))
        };
        let (x, y, z) = (range(0), range(1), range(2));
        let mut dir = [0.0; 3];
        let mut nearest = f64::INFINITY;
        for k in z.0..z.1 {
            for j in y.0..y.1 {
                for i in x.0..x.1 {
                    let n = self.idx(i, j, k);
                    if !self.occupied[n] {
                        continue;
                    }
                    let v = self.centre(i, j, k);
                    let d = [c[0] - v[0], c[1] - v[1], c[2] - v[2]];
                    let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    if dist <= r {
                        self.occupied[n] = false;
                        nearest = nearest.min(dist);
                        for a in 0..3 {
                            dir[a] += d[a];
                        }
                    }
                }
            }
        }
        let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        if !nearest.is_finite() || len == 0.0 {
            return [0.0; 3];
        }
        let depth = r - nearest;
        dir.map(|d| self.stiffness * depth * d / len)
    }

    fn publish_workpiece(&self, stamp: i64, out: &mut Vec<Message>) {
        let header = Header {
            stamp: Time::from_nanos(stamp),
            frame_id: self.frame_id.clone(),
        };
        let n = self.occupied.len();
        let mut data = vec![0u8; n.div_ceil(8)];
        for (i, &o) in self.occupied.iter().enumerate() {
            if o {
                data[i / 8] |= 1 << (i % 8);
            }
        }
        let grid = VoxelGrid {
            header: header.clone(),
            origin: Point {
                x: self.origin[0],
                y: self.origin[1],
                z: self.origin[2],
            },
            resolution: self.res,
            size_x: self.size[0],
            size_y: self.size[1],
            size_z: self.size[2],
            encoding: VoxelGrid::ENCODING_BITS,
            data,
        };
        out.push(Message::new(
            &self.occupancy_topic,
            stamp,
            Payload::VoxelGrid(Arc::new(grid)),
        ));
        // Surfels: occupied voxels with a free face neighbour; normal = sum of free directions.
        let mut pts: Vec<u8> = Vec::new();
        let mut count = 0u32;
        let s = self.size.map(|v| v as i64);
        let occ = |i: i64, j: i64, k: i64| {
            i >= 0
                && j >= 0
                && k >= 0
                && i < s[0]
                && j < s[1]
                && k < s[2]
                && self.occupied[self.idx(i as u32, j as u32, k as u32)]
        };
        for k in 0..s[2] {
            for j in 0..s[1] {
                for i in 0..s[0] {
                    if !occ(i, j, k) {
                        continue;
                    }
                    let mut nrm = [0.0f32; 3];
                    for (a, step) in [(0usize, [1i64, 0, 0]), (1, [0, 1, 0]), (2, [0, 0, 1])] {
                        if !occ(i + step[0], j + step[1], k + step[2]) {
                            nrm[a] += 1.0;
                        }
                        if !occ(i - step[0], j - step[1], k - step[2]) {
                            nrm[a] -= 1.0;
                        }
                    }
                    let len = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]).sqrt();
                    if len == 0.0 {
                        continue;
                    }
                    let c = self.centre(i as u32, j as u32, k as u32);
                    for v in [
                        c[0] as f32,
                        c[1] as f32,
                        c[2] as f32,
                        nrm[0] / len,
                        nrm[1] / len,
                        nrm[2] / len,
                    ] {
                        pts.extend_from_slice(&v.to_le_bytes());
                    }
                    count += 1;
                }
            }
        }
        let fields = ["x", "y", "z", "normal_x", "normal_y", "normal_z"]
            .iter()
            .enumerate()
            .map(|(i, n)| PointField::new(*n, 4 * i as u32, PointField::FLOAT32, 1))
            .collect();
        let cloud = PointCloud2 {
            header,
            height: 1,
            width: count,
            fields,
            is_bigendian: false,
            point_step: 24,
            row_step: 24 * count,
            data: pts,
            is_dense: true,
        };
        out.push(Message::new(
            &self.surfels_topic,
            stamp,
            Payload::PointCloud2(Arc::new(cloud)),
        ));
    }

    fn on_pose(&mut self, p: &PoseStamped, out: &mut Vec<Message>) {
        let stamp = p.header.stamp.as_nanos();
        let pos = [p.pose.position.x, p.pose.position.y, p.pose.position.z];
        let q = p.pose.orientation;
        let qn = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
        let refuse = if !pos.iter().all(|v| v.is_finite()) {
            Some((
                "bad_pose",
                format!("pose at {stamp} ns: position {pos:?} is not finite"),
            ))
        } else if !qn.is_finite() || qn < 1e-9 {
            Some((
                "bad_pose",
                format!("pose at {stamp} ns: orientation quaternion has norm {qn}"),
            ))
        } else if self.last_stamp.is_some_and(|l| stamp < l) {
            Some((
                "stamp_backwards",
                format!(
                    "pose at {stamp} ns is older than the last one ({} ns)",
                    self.last_stamp.unwrap_or(0)
                ),
            ))
        } else if !p.header.frame_id.is_empty() && p.header.frame_id != self.frame_id {
            Some((
                "unknown_frame",
                format!(
                    "pose at {stamp} ns in frame {:?}, not {:?}",
                    p.header.frame_id, self.frame_id
                ),
            ))
        } else {
            None
        };
        if let Some((kind, why)) = refuse {
            self.status.problem(
                &self.fqn,
                kind,
                format!("{why}; ignored, workpiece unchanged"),
            );
            return;
        }
        // (A non-unit quaternion would be normalised; the ball tool does not depend on it.)
        let next = *self.next_publish.get_or_insert(stamp);
        // Workpiece frames on the period grid up to this pose (state before the cut).
        let mut t = next;
        while t <= stamp {
            self.publish_workpiece(t, out);
            t += self.period_ns;
        }
        self.next_publish = Some(t);
        self.last_stamp = Some(stamp);
        let f = self.carve(pos);
        let w = WrenchStamped {
            header: Header {
                stamp: p.header.stamp,
                frame_id: self.frame_id.clone(),
            },
            wrench: Wrench {
                force: Vector3::new(f[0], f[1], f[2]),
                torque: Vector3::default(),
            },
        };
        out.push(Message::new(
            &self.wrench_topic,
            stamp,
            Payload::WrenchStamped(Arc::new(w)),
        ));
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
            TopicRef {
                topic: self.occupancy_topic.clone(),
                type_name: VoxelGrid::TYPE_NAME,
            },
            TopicRef {
                topic: self.surfels_topic.clone(),
                type_name: PointCloud2::TYPE_NAME,
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
            self.publish_workpiece(t, out);
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
