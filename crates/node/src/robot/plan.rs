//! A planned motion (`trajectory_msgs/JointTrajectory`) as the robot node follows it: the
//! positions joint_trajectory_controller would command at any time, and the plan retimed by
//! the checker's time scaling, as a message to send to the controller.
//!
//! The controller (ros2_controllers, `interpolation_method: splines`, its default) starts a
//! plan at its header stamp, or on arrival when the stamp is zero; from the state it had
//! then, it interpolates to the first point, then between points (linear with positions
//! only, cubic Hermite with velocities, quintic with accelerations), and holds the last
//! point. The start state here is the robot's joint-state positions at the plan's arrival
//! (positions only, so the segment to the first point is linear), or the first point when no
//! joint state gives them. Joints the plan leaves out stay where the joint states put them
//! at its arrival.

use chronotope_robot::trajectory::{Sample, StartState, TrajectoryPoint};
use chronotope_robot::{JointStateHistory, Kinematics, Stamp, TrajectoryError};

use chronotope_msg::{Duration, Header, JointTrajectory, JointTrajectoryPoint, Time};

/// A plan being followed.
#[derive(Debug)]
pub(super) struct Plan {
    traj: chronotope_robot::JointTrajectory,
    start: StartState,
    /// When it arrived (ns): the controller's start state is taken then.
    pub arrival: Stamp,
    /// Its last point's time (ns).
    pub end: Stamp,
    frame_id: String,
    /// Independent joint index of each of the plan's joints.
    index: Vec<usize>,
    /// Every independent joint at arrival (the plan's joints overwritten per sample).
    held: Vec<f64>,
    sample: Sample,
    /// Its own effort arrays, kept for the retimed message.
    efforts: Vec<Vec<f64>>,
}

/// Why a plan is refused.
#[derive(Debug, thiserror::Error)]
pub(super) enum PlanError {
    /// The trajectory itself (times that do not increase, lengths, non-finite values, ...).
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// Joint names the URDF has no movable, independent joint of.
    #[error("the plan names joints that are not movable joints of the URDF: {}", .0.join(", "))]
    UnknownJoints(Vec<String>),
    /// A joint the plan leaves out whose position no joint state gives.
    #[error("the plan leaves joint `{0}` out and no joint state gives its position at the plan's arrival")]
    Unplaced(String),
    /// An `effort` array of the wrong length.
    #[error("point {point}: `effort` has {len} values for {joints} joints")]
    Effort {
        point: usize,
        len: usize,
        joints: usize,
    },
}

impl Plan {
    /// The plan of message `m`, arrived at `arrival` (ns), for the robot `kin` whose joint
    /// states so far are `history`.
    ///
    /// # Errors
    /// [`PlanError`], naming what is wrong.
    pub fn new(
        m: &JointTrajectory,
        arrival: Stamp,
        kin: &Kinematics,
        history: &JointStateHistory,
    ) -> Result<Plan, PlanError> {
        let unknown: Vec<String> = m
            .joint_names
            .iter()
            .filter(|n| kin.joint_index(n).is_none())
            .take(16)
            .cloned()
            .collect();
        if !unknown.is_empty() {
            return Err(PlanError::UnknownJoints(unknown));
        }
        let n = m.joint_names.len();
        for (i, p) in m.points.iter().enumerate() {
            if !p.effort.is_empty() && p.effort.len() != n {
                return Err(PlanError::Effort {
                    point: i,
                    len: p.effort.len(),
                    joints: n,
                });
            }
        }
        let stamp = m.header.stamp.as_nanos();
        let start = if stamp == 0 { arrival } else { stamp };
        let points: Vec<TrajectoryPoint> = m
            .points
            .iter()
            .map(|p| TrajectoryPoint {
                positions: p.positions.clone(),
                velocities: p.velocities.clone(),
                accelerations: p.accelerations.clone(),
                time_from_start: p.time_from_start.as_nanos() as f64 * 1e-9,
            })
            .collect();
        let traj = chronotope_robot::JointTrajectory::new(start, m.joint_names.clone(), points)?;
        let index: Vec<usize> = m
            .joint_names
            .iter()
            .filter_map(|n| kin.joint_index(n))
            .collect();
        let mut held = vec![f64::NAN; kin.dof()];
        let known =
            history.positions_at(arrival, &mut held).is_ok() || history.latest(&mut held).is_ok();
        if !known {
            held.fill(f64::NAN);
        }
        if let Some(i) = (0..kin.dof()).find(|&i| held[i].is_nan() && !index.contains(&i)) {
            return Err(PlanError::Unplaced(kin.joint_names()[i].clone()));
        }
        let first = &traj.points()[0];
        let start_positions = if known {
            index.iter().map(|&i| held[i]).collect()
        } else {
            first.positions.clone()
        };
        let end = traj.point_time(traj.points().len() - 1);
        Ok(Plan {
            start: StartState {
                time: arrival.min(traj.point_time(0)),
                point: TrajectoryPoint {
                    positions: start_positions,
                    ..TrajectoryPoint::default()
                },
            },
            arrival,
            end,
            frame_id: m.header.frame_id.clone(),
            index,
            held,
            sample: Sample::default(),
            efforts: m.points.iter().map(|p| p.effort.clone()).collect(),
            traj,
        })
    }

    /// Every independent joint's position at `t` (ns, not before the arrival) into `q`.
    ///
    /// # Errors
    /// A time before the start state (never for `t` at or after the arrival).
    pub fn positions_at(&mut self, t: Stamp, q: &mut [f64]) -> Result<(), TrajectoryError> {
        self.traj.sample(t, Some(&self.start), &mut self.sample)?;
        q.copy_from_slice(&self.held);
        for (k, &i) in self.index.iter().enumerate() {
            q[i] = self.sample.positions[k];
        }
        Ok(())
    }

    /// The plan under the time scaling t' = t0 + scale (t − t0), as a message: the start
    /// stamp mapped (an explicit stamp even when the original's was zero), each point's
    /// `time_from_start` multiplied by `scale`, velocities divided by it and accelerations
    /// by its square; efforts as they were.
    ///
    /// # Errors
    /// A scale that is not positive and finite.
    pub fn retimed(&self, t0: Stamp, scale: f64) -> Result<JointTrajectory, TrajectoryError> {
        let r = self.traj.retimed(t0, scale)?;
        Ok(JointTrajectory {
            header: Header {
                stamp: Time::from_nanos(r.start()),
                frame_id: self.frame_id.clone(),
            },
            joint_names: r.joint_names().to_vec(),
            points: r
                .points()
                .iter()
                .zip(&self.efforts)
                .map(|(p, e)| JointTrajectoryPoint {
                    positions: p.positions.clone(),
                    velocities: p.velocities.clone(),
                    accelerations: p.accelerations.clone(),
                    effort: e.clone(),
                    time_from_start: Duration::from_nanos((p.time_from_start * 1e9).round() as i64),
                })
                .collect(),
        })
    }

    /// The plan's start (ns): its header stamp, or its arrival when that is zero.
    pub fn start(&self) -> Stamp {
        self.traj.start()
    }
}
