//! ROS 2 message types the suite speaks, mirrored field by field from their `.msg` text.
//!
//! The `.msg` files under `msgs/` are the source of truth: every Rust type here carries its
//! definition text (for MCAP `ros2msg` schemas) and a test checks that the fields match.
//! Serialisation is CDR (little endian) through serde, as ros2-client does on the wire.
#![warn(missing_docs)]

mod cdr;
mod definition;
mod octomap;
mod robot_types;
mod schema;
mod std_types;
mod suite;
mod voxel_grid;

pub use cdr::{decode_cdr, encapsulation, encode_cdr, encode_cdr_into, CdrEndianness, CdrError};
pub use definition::{Definition, DefinitionError};
pub use octomap::Octomap;
pub use robot_types::{
    JointState, JointTrajectory, JointTrajectoryPoint, RosString, TFMessage, Transform,
    TransformStamped,
};
pub use schema::{
    parse_msg_fields, ros2msg_schema, try_ros2msg_schema, MsgField, SchemaError, SCHEMA_SEPARATOR,
};
pub use std_types::{
    Clock, ColorRGBA, CompressedImage, DiagnosticArray, DiagnosticStatus, Duration, KeyValue,
    Marker, MarkerArray, MeshFile, PointCloud2, PointField, Pose, PoseStamped, Quaternion,
    UVCoordinate, Vector3, Wrench, WrenchStamped,
};
pub use suite::{
    BodySummary, ContactEvent, InterferenceReport, MeshSlab, PairInterference, ResolveSuggestion,
    ResolveSuggestions, TetLabels,
};
pub use voxel_grid::{Header, Point, Time, VoxelEncoding, VoxelGrid};

/// A ROS message type with its fully qualified name and `.msg` definition text.
pub trait RosMessage: serde::Serialize + serde::de::DeserializeOwned {
    /// `pkg/msg/Type`, as used in MCAP schema names.
    const TYPE_NAME: &'static str;
    /// The type's own `.msg` text.
    const DEFINITION: &'static str;
    /// Types this one refers to, as `(pkg/msg/Type, .msg text)` pairs, in any order.
    fn dependencies() -> Vec<(&'static str, &'static str)>;
}
