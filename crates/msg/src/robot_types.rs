//! Standard ROS 2 messages a robot cell publishes, read by the robot node: the robot
//! description (`std_msgs/String` on `/robot_description`), joint states
//! (`sensor_msgs/JointState`), planned motion (`trajectory_msgs/JointTrajectory` and
//! `JointTrajectoryPoint`) and transforms (`tf2_msgs/TFMessage` of
//! `geometry_msgs/TransformStamped`, `Transform`).
//!
//! As in `std_types.rs`, each struct mirrors its upstream `.msg` field by field and carries
//! the exact ROS 2 **Jazzy** text from `msgs/deps/<pkg>/msg/<Type>.msg` (`common_interfaces`
//! branch `jazzy`, 5.3.x; `tf2_msgs` from `geometry2` branch `jazzy`), checked by
//! `tests/it/msg_definitions.rs`. Decoding goes through the suite's CDR codec, so every array
//! length is checked against the bytes present before anything is allocated.

use serde::{Deserialize, Serialize};

use super::std_types::{Duration, Quaternion, Vector3};
use super::voxel_grid::Header;
use super::RosMessage;

/// `(pkg/msg/Type, .msg text)` of every definition this module refers to (the shared ones
/// from [`super::std_types`]).
mod defs {
    pub(super) use super::super::std_types::defs::{
        Def, DURATION, HEADER, QUATERNION, TIME, VECTOR3,
    };

    pub(super) const STRING: Def = (
        "std_msgs/msg/String",
        include_str!("../../../msgs/deps/std_msgs/msg/String.msg"),
    );
    pub(super) const TRANSFORM: Def = (
        "geometry_msgs/msg/Transform",
        include_str!("../../../msgs/deps/geometry_msgs/msg/Transform.msg"),
    );
    pub(super) const TRANSFORM_STAMPED: Def = (
        "geometry_msgs/msg/TransformStamped",
        include_str!("../../../msgs/deps/geometry_msgs/msg/TransformStamped.msg"),
    );
    pub(super) const TF_MESSAGE: Def = (
        "tf2_msgs/msg/TFMessage",
        include_str!("../../../msgs/deps/tf2_msgs/msg/TFMessage.msg"),
    );
    pub(super) const JOINT_STATE: Def = (
        "sensor_msgs/msg/JointState",
        include_str!("../../../msgs/deps/sensor_msgs/msg/JointState.msg"),
    );
    pub(super) const JOINT_TRAJECTORY_POINT: Def = (
        "trajectory_msgs/msg/JointTrajectoryPoint",
        include_str!("../../../msgs/deps/trajectory_msgs/msg/JointTrajectoryPoint.msg"),
    );
    pub(super) const JOINT_TRAJECTORY: Def = (
        "trajectory_msgs/msg/JointTrajectory",
        include_str!("../../../msgs/deps/trajectory_msgs/msg/JointTrajectory.msg"),
    );
}

/// Implements [`RosMessage`] from a `defs` entry and its transitive dependencies.
macro_rules! ros_message {
    ($ty:ty, $def:expr, [$($dep:expr),* $(,)?]) => {
        impl RosMessage for $ty {
            const TYPE_NAME: &'static str = $def.0;
            const DEFINITION: &'static str = $def.1;
            fn dependencies() -> Vec<(&'static str, &'static str)> {
                vec![$($dep),*]
            }
        }
    };
}

/// `std_msgs/msg/String`: one string; robot_state_publisher's `/robot_description` (the
/// URDF text).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RosString {
    /// The text.
    pub data: String,
}

ros_message!(RosString, defs::STRING, []);

/// `geometry_msgs/msg/Transform`: a rigid transform (translation, then rotation).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation (m).
    pub translation: Vector3,
    /// Rotation (unit quaternion).
    pub rotation: Quaternion,
}

ros_message!(
    Transform,
    defs::TRANSFORM,
    [defs::VECTOR3, defs::QUATERNION]
);

/// `geometry_msgs/msg/TransformStamped`: the pose of frame `child_frame_id` in
/// `header.frame_id` at `header.stamp`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// stamp: when; frame_id: the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// Child frame in the parent frame.
    pub transform: Transform,
}

ros_message!(
    TransformStamped,
    defs::TRANSFORM_STAMPED,
    [
        defs::HEADER,
        defs::TIME,
        defs::TRANSFORM,
        defs::VECTOR3,
        defs::QUATERNION
    ]
);

/// `tf2_msgs/msg/TFMessage`: transforms, as on `/tf` and `/tf_static`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

ros_message!(
    TFMessage,
    defs::TF_MESSAGE,
    [
        defs::TRANSFORM_STAMPED,
        defs::HEADER,
        defs::TIME,
        defs::TRANSFORM,
        defs::VECTOR3,
        defs::QUATERNION
    ]
);

/// `sensor_msgs/msg/JointState`: positions (rad or m), velocities and efforts of named
/// joints at `header.stamp`; a message may carry only some of a robot's joints.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// stamp: when the states were measured.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (rad or m), one per name.
    pub position: Vec<f64>,
    /// Velocities (rad/s or m/s): one per name, or empty.
    pub velocity: Vec<f64>,
    /// Efforts (N·m or N): one per name, or empty.
    pub effort: Vec<f64>,
}

ros_message!(JointState, defs::JOINT_STATE, [defs::HEADER, defs::TIME]);

/// `trajectory_msgs/msg/JointTrajectoryPoint`: where the joints are to be
/// `time_from_start` after the trajectory's start.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectoryPoint {
    /// Positions, one per joint of the trajectory.
    pub positions: Vec<f64>,
    /// Velocities: one per joint, or empty.
    pub velocities: Vec<f64>,
    /// Accelerations: one per joint, or empty.
    pub accelerations: Vec<f64>,
    /// Efforts: one per joint, or empty (not read by the suite).
    pub effort: Vec<f64>,
    /// Time after the trajectory's start.
    pub time_from_start: Duration,
}

ros_message!(
    JointTrajectoryPoint,
    defs::JOINT_TRAJECTORY_POINT,
    [defs::DURATION]
);

/// `trajectory_msgs/msg/JointTrajectory`: a plan for named joints; `header.stamp` is when
/// it starts (zero: when the controller receives it).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectory {
    /// stamp: the start time (zero: on arrival).
    pub header: Header,
    /// The joints, in the order of every point's arrays.
    pub joint_names: Vec<String>,
    /// The points, in time order.
    pub points: Vec<JointTrajectoryPoint>,
}

ros_message!(
    JointTrajectory,
    defs::JOINT_TRAJECTORY,
    [
        defs::HEADER,
        defs::TIME,
        defs::JOINT_TRAJECTORY_POINT,
        defs::DURATION
    ]
);
