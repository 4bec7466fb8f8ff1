//! `tf2_msgs/msg/TFMessage` and the `geometry_msgs` types it carries
//! (`TransformStamped`, `Transform`): what `/tf_static` holds, read to place a sensor's
//! cloud in the cell's frame.
//!
//! Mirrored field by field from the ROS 2 Jazzy texts (`ros2/common_interfaces` and
//! `ros2/geometry2`, branch `jazzy`), kept under `msgs/deps/` and checked against these types
//! by `tests/msg_definitions.rs`.

use serde::{Deserialize, Serialize};

use super::std_types::{Quaternion, Vector3};
use super::voxel_grid::Header;
use super::RosMessage;

type Def = (&'static str, &'static str);

const HEADER: Def = (
    "std_msgs/msg/Header",
    include_str!("../../msgs/deps/std_msgs/msg/Header.msg"),
);
const TIME: Def = (
    "builtin_interfaces/msg/Time",
    include_str!("../../msgs/deps/builtin_interfaces/msg/Time.msg"),
);
const VECTOR3: Def = (
    "geometry_msgs/msg/Vector3",
    include_str!("../../msgs/deps/geometry_msgs/msg/Vector3.msg"),
);
const QUATERNION: Def = (
    "geometry_msgs/msg/Quaternion",
    include_str!("../../msgs/deps/geometry_msgs/msg/Quaternion.msg"),
);
const TRANSFORM: Def = (
    "geometry_msgs/msg/Transform",
    include_str!("../../msgs/deps/geometry_msgs/msg/Transform.msg"),
);
const TRANSFORM_STAMPED: Def = (
    "geometry_msgs/msg/TransformStamped",
    include_str!("../../msgs/deps/geometry_msgs/msg/TransformStamped.msg"),
);

/// `geometry_msgs/msg/Transform`: a child frame's pose in its parent frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Origin of the child frame in the parent frame (m).
    pub translation: Vector3,
    /// Orientation of the child frame in the parent frame.
    pub rotation: Quaternion,
}

impl RosMessage for Transform {
    const TYPE_NAME: &'static str = TRANSFORM.0;
    const DEFINITION: &'static str = TRANSFORM.1;
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        vec![VECTOR3, QUATERNION]
    }
}

/// `geometry_msgs/msg/TransformStamped`: the pose of `child_frame_id` in `header.frame_id`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// stamp: when the transform holds; frame_id: the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child frame's pose in the parent frame.
    pub transform: Transform,
}

impl RosMessage for TransformStamped {
    const TYPE_NAME: &'static str = TRANSFORM_STAMPED.0;
    const DEFINITION: &'static str = TRANSFORM_STAMPED.1;
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        vec![HEADER, TIME, TRANSFORM, VECTOR3, QUATERNION]
    }
}

/// `tf2_msgs/msg/TFMessage`: transforms, as `/tf` and `/tf_static` carry them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

impl RosMessage for TFMessage {
    const TYPE_NAME: &'static str = "tf2_msgs/msg/TFMessage";
    const DEFINITION: &'static str = include_str!("../../msgs/deps/tf2_msgs/msg/TFMessage.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        vec![
            TRANSFORM_STAMPED,
            HEADER,
            TIME,
            TRANSFORM,
            VECTOR3,
            QUATERNION,
        ]
    }
}
