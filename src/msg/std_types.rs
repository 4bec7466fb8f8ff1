//! Standard ROS 2 messages the suite speaks, beyond the three `VoxelGrid` needs
//! (`Header`, `Time`, `Point`, which stay in `voxel_grid.rs`):
//! `builtin_interfaces/Duration`, `std_msgs/ColorRGBA`, the `geometry_msgs` poses, vectors and
//! wrenches, `sensor_msgs` point clouds and compressed images, and `visualization_msgs` markers.
//!
//! Each struct mirrors its upstream `.msg` field by field (same names, order and types), and
//! carries the exact upstream `.msg` text from `msgs/deps/<pkg>/msg/<Type>.msg`, comments and
//! whitespace included, for MCAP `ros2msg` schemas (rosbag2 stores the full file text).
//!
//! # Distribution
//!
//! The definitions are those of ROS 2 **Jazzy** (the current LTS): `ros2/common_interfaces`
//! branch `jazzy` (5.3.x) and `builtin_interfaces` from `ros2/rcl_interfaces` branch `jazzy`
//! (2.0.x). The stored copies of upstream that were available mixed releases with
//! pull-request branches and other distributions, so the Jazzy text was established from the
//! release changelogs and checked against the raw source text and byte length that rosidl
//! (Iron and later) compiles into each type's generated type description:
//!
//! - `Marker` has `ARROW_STRIP=12` (common_interfaces 5.3.3, before Jazzy branched; Humble
//!   does not have it) and links resource_retriever at `docs.ros.org/en/rolling` (#244,
//!   released into Jazzy as 5.3.5). A variant with `# Currently unimplemented` after
//!   `ARROW_STRIP` and an `index.ros.org` link matches the unmerged pull request #218.
//! - `UVCoordinate` is `float32 u`, `float32 v`; a `float64` variant is in no release.
//! - `ColorRGBA` has no default values; `float32 a 1` was the closed pull request #130.
//! - `PointField` has the eight constants `INT8`..`FLOAT64`; Rolling added more after Jazzy
//!   (common_interfaces 5.8.3), which Jazzy does not have.
//! - `Duration` is the text of rcl_interfaces #176 (backported to Jazzy in 2.0.3): its
//!   `nanosec` comment line ends in a space, kept because rosbag2 copies the file verbatim.
//!   (The same change gave Jazzy's `Time.msg` that trailing space too; the older copy in
//!   `msgs/deps/builtin_interfaces/msg/Time.msg`, shared with `VoxelGrid`, does not have it.)
//!
//! None of these types has a fixed-size array field.

use serde::{Deserialize, Serialize};

use super::voxel_grid::{Header, Point};
use super::RosMessage;

/// `(pkg/msg/Type, .msg text)` of every definition this module refers to.
mod defs {
    pub(super) type Def = (&'static str, &'static str);

    pub(super) const TIME: Def = (
        "builtin_interfaces/msg/Time",
        include_str!("../../msgs/deps/builtin_interfaces/msg/Time.msg"),
    );
    pub(super) const DURATION: Def = (
        "builtin_interfaces/msg/Duration",
        include_str!("../../msgs/deps/builtin_interfaces/msg/Duration.msg"),
    );
    pub(super) const HEADER: Def = (
        "std_msgs/msg/Header",
        include_str!("../../msgs/deps/std_msgs/msg/Header.msg"),
    );
    pub(super) const COLOR_RGBA: Def = (
        "std_msgs/msg/ColorRGBA",
        include_str!("../../msgs/deps/std_msgs/msg/ColorRGBA.msg"),
    );
    pub(super) const POINT: Def = (
        "geometry_msgs/msg/Point",
        include_str!("../../msgs/deps/geometry_msgs/msg/Point.msg"),
    );
    pub(super) const QUATERNION: Def = (
        "geometry_msgs/msg/Quaternion",
        include_str!("../../msgs/deps/geometry_msgs/msg/Quaternion.msg"),
    );
    pub(super) const POSE: Def = (
        "geometry_msgs/msg/Pose",
        include_str!("../../msgs/deps/geometry_msgs/msg/Pose.msg"),
    );
    pub(super) const POSE_STAMPED: Def = (
        "geometry_msgs/msg/PoseStamped",
        include_str!("../../msgs/deps/geometry_msgs/msg/PoseStamped.msg"),
    );
    pub(super) const VECTOR3: Def = (
        "geometry_msgs/msg/Vector3",
        include_str!("../../msgs/deps/geometry_msgs/msg/Vector3.msg"),
    );
    pub(super) const WRENCH: Def = (
        "geometry_msgs/msg/Wrench",
        include_str!("../../msgs/deps/geometry_msgs/msg/Wrench.msg"),
    );
    pub(super) const WRENCH_STAMPED: Def = (
        "geometry_msgs/msg/WrenchStamped",
        include_str!("../../msgs/deps/geometry_msgs/msg/WrenchStamped.msg"),
    );
    pub(super) const POINT_FIELD: Def = (
        "sensor_msgs/msg/PointField",
        include_str!("../../msgs/deps/sensor_msgs/msg/PointField.msg"),
    );
    pub(super) const POINT_CLOUD2: Def = (
        "sensor_msgs/msg/PointCloud2",
        include_str!("../../msgs/deps/sensor_msgs/msg/PointCloud2.msg"),
    );
    pub(super) const COMPRESSED_IMAGE: Def = (
        "sensor_msgs/msg/CompressedImage",
        include_str!("../../msgs/deps/sensor_msgs/msg/CompressedImage.msg"),
    );
    pub(super) const UV_COORDINATE: Def = (
        "visualization_msgs/msg/UVCoordinate",
        include_str!("../../msgs/deps/visualization_msgs/msg/UVCoordinate.msg"),
    );
    pub(super) const MESH_FILE: Def = (
        "visualization_msgs/msg/MeshFile",
        include_str!("../../msgs/deps/visualization_msgs/msg/MeshFile.msg"),
    );
    pub(super) const MARKER: Def = (
        "visualization_msgs/msg/Marker",
        include_str!("../../msgs/deps/visualization_msgs/msg/Marker.msg"),
    );
    pub(super) const MARKER_ARRAY: Def = (
        "visualization_msgs/msg/MarkerArray",
        include_str!("../../msgs/deps/visualization_msgs/msg/MarkerArray.msg"),
    );

    /// Everything `visualization_msgs/Marker` refers to, directly or not.
    pub(super) const MARKER_DEPENDENCIES: [Def; 11] = [
        HEADER,
        TIME,
        POSE,
        POINT,
        QUATERNION,
        VECTOR3,
        COLOR_RGBA,
        DURATION,
        COMPRESSED_IMAGE,
        UV_COORDINATE,
        MESH_FILE,
    ];
}

/// Implements [`RosMessage`] from a `defs` entry and the list of its transitive dependencies.
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

// ---------------------------------------------------------------------------------------------
// builtin_interfaces

/// `builtin_interfaces/msg/Duration`: a signed span of ROS time.
///
/// `-1.7 s` is `{sec: -2, nanosec: 300_000_000}`: `nanosec` is always added.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Duration {
    /// Whole seconds (s), any `i32`.
    pub sec: i32,
    /// Nanoseconds (ns) added to `sec`, `0..1_000_000_000`.
    pub nanosec: u32,
}

impl Duration {
    /// The span in nanoseconds (exact; `sec` may be negative).
    pub fn as_nanos(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// The duration of `ns` nanoseconds (floor division, so `nanosec` stays in range).
    ///
    /// Spans beyond the `i32` seconds range (about ±68 years) wrap.
    pub fn from_nanos(ns: i64) -> Self {
        Self {
            sec: ns.div_euclid(1_000_000_000) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }
}

ros_message!(Duration, defs::DURATION, []);

// ---------------------------------------------------------------------------------------------
// std_msgs

/// `std_msgs/msg/ColorRGBA`: a colour, each component in `0.0..=1.0`.
///
/// The default is transparent black (`a = 0`), as in ROS: set `a` or nothing shows in RViz.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRGBA {
    /// Red, `0.0..=1.0`.
    pub r: f32,
    /// Green, `0.0..=1.0`.
    pub g: f32,
    /// Blue, `0.0..=1.0`.
    pub b: f32,
    /// Alpha (opacity), `0.0` transparent ..= `1.0` opaque.
    pub a: f32,
}

impl ColorRGBA {
    /// The colour with these components.
    pub const fn new(r: f32, g: f32, b: f32, a: f32) -> Self {
        Self { r, g, b, a }
    }
}

ros_message!(ColorRGBA, defs::COLOR_RGBA, []);

// ---------------------------------------------------------------------------------------------
// geometry_msgs

/// `geometry_msgs/msg/Quaternion`: an orientation as a unit quaternion `(x, y, z, w)`.
///
/// The default is the identity rotation `(0, 0, 0, 1)`: the `.msg` declares the default values
/// `x 0`, `y 0`, `z 0`, `w 1`, which every ROS client library uses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// Vector part, x (dimensionless).
    pub x: f64,
    /// Vector part, y (dimensionless).
    pub y: f64,
    /// Vector part, z (dimensionless).
    pub z: f64,
    /// Scalar part (dimensionless).
    pub w: f64,
}

impl Quaternion {
    /// The identity rotation, the `.msg` default.
    pub const IDENTITY: Self = Self {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    };
}

impl Default for Quaternion {
    /// [`Quaternion::IDENTITY`], the `.msg` default values.
    fn default() -> Self {
        Self::IDENTITY
    }
}

ros_message!(Quaternion, defs::QUATERNION, []);

/// `geometry_msgs/msg/Vector3`: a free vector (transforms apply only their rotation to it).
///
/// Units depend on use: m for a `Marker` scale, N for a force, N·m for a torque.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
}

impl Vector3 {
    /// The vector with these components.
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Self { x, y, z }
    }
}

ros_message!(Vector3, defs::VECTOR3, []);

/// `geometry_msgs/msg/Pose`: a position and an orientation.
///
/// The default is the origin with the identity orientation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position (m).
    pub position: Point,
    /// Orientation (unit quaternion).
    pub orientation: Quaternion,
}

ros_message!(Pose, defs::POSE, [defs::POINT, defs::QUATERNION]);

/// `geometry_msgs/msg/PoseStamped`: a pose in a frame at a time.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// stamp: time of the pose; frame_id: frame it is expressed in.
    pub header: Header,
    /// The pose (m, unit quaternion).
    pub pose: Pose,
}

ros_message!(
    PoseStamped,
    defs::POSE_STAMPED,
    [
        defs::HEADER,
        defs::TIME,
        defs::POSE,
        defs::POINT,
        defs::QUATERNION
    ]
);

/// `geometry_msgs/msg/Wrench`: a force and a torque.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Wrench {
    /// Linear part, force (N).
    pub force: Vector3,
    /// Angular part, torque (N·m).
    pub torque: Vector3,
}

ros_message!(Wrench, defs::WRENCH, [defs::VECTOR3]);

/// `geometry_msgs/msg/WrenchStamped`: a wrench in a frame at a time.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WrenchStamped {
    /// stamp: time of the measurement; frame_id: frame the wrench is expressed in.
    pub header: Header,
    /// Force (N) and torque (N·m).
    pub wrench: Wrench,
}

ros_message!(
    WrenchStamped,
    defs::WRENCH_STAMPED,
    [defs::HEADER, defs::TIME, defs::WRENCH, defs::VECTOR3]
);

// ---------------------------------------------------------------------------------------------
// sensor_msgs

/// `sensor_msgs/msg/PointField`: one named channel of a [`PointCloud2`] point.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PointField {
    /// Channel name; common ones are `x`, `y`, `z`, `intensity`, `rgb`, `rgba`.
    pub name: String,
    /// Byte offset of the channel from the start of a point (bytes).
    pub offset: u32,
    /// Element type, one of [`Self::INT8`] ..= [`Self::FLOAT64`].
    pub datatype: u8,
    /// Number of elements of `datatype` in the channel.
    pub count: u32,
}

impl PointField {
    /// `int8` elements.
    pub const INT8: u8 = 1;
    /// `uint8` elements.
    pub const UINT8: u8 = 2;
    /// `int16` elements.
    pub const INT16: u8 = 3;
    /// `uint16` elements.
    pub const UINT16: u8 = 4;
    /// `int32` elements.
    pub const INT32: u8 = 5;
    /// `uint32` elements.
    pub const UINT32: u8 = 6;
    /// `float32` elements.
    pub const FLOAT32: u8 = 7;
    /// `float64` elements.
    pub const FLOAT64: u8 = 8;

    /// The channel `name` of `count` elements of `datatype` at byte `offset`.
    pub fn new(name: impl Into<String>, offset: u32, datatype: u8, count: u32) -> Self {
        Self {
            name: name.into(),
            offset,
            datatype,
            count,
        }
    }

    /// Size in bytes of one element of `datatype`, or `None` for an unknown code.
    pub fn datatype_size(datatype: u8) -> Option<u32> {
        match datatype {
            Self::INT8 | Self::UINT8 => Some(1),
            Self::INT16 | Self::UINT16 => Some(2),
            Self::INT32 | Self::UINT32 | Self::FLOAT32 => Some(4),
            Self::FLOAT64 => Some(8),
            _ => None,
        }
    }
}

ros_message!(PointField, defs::POINT_FIELD, []);

/// `sensor_msgs/msg/PointCloud2`: points as a binary blob laid out by [`PointField`]s.
///
/// Point `(row, col)` starts at byte `row * row_step + col * point_step` of `data`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    /// stamp: acquisition time; frame_id: frame of the points.
    pub header: Header,
    /// Rows; 1 for an unordered cloud.
    pub height: u32,
    /// Points per row; the point count for an unordered cloud.
    pub width: u32,
    /// The channels of a point and their layout.
    pub fields: Vec<PointField>,
    /// True if multi-byte elements in `data` are big endian.
    pub is_bigendian: bool,
    /// Length of a point (bytes).
    pub point_step: u32,
    /// Length of a row (bytes).
    pub row_step: u32,
    /// The points, `row_step * height` bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    /// True if there are no invalid (NaN) points.
    pub is_dense: bool,
}

ros_message!(
    PointCloud2,
    defs::POINT_CLOUD2,
    [defs::HEADER, defs::TIME, defs::POINT_FIELD]
);

/// `sensor_msgs/msg/CompressedImage`: an image in a compressed format (JPEG, PNG, ...).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// stamp: acquisition time; frame_id: optical frame of the camera.
    pub header: Header,
    /// The encoding, as the image transport names it (e.g. `jpeg`, `png`,
    /// `bgr8; jpeg compressed bgr8`).
    pub format: String,
    /// The compressed image bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

ros_message!(
    CompressedImage,
    defs::COMPRESSED_IMAGE,
    [defs::HEADER, defs::TIME]
);

// ---------------------------------------------------------------------------------------------
// visualization_msgs

/// `visualization_msgs/msg/UVCoordinate`: a texture coordinate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UVCoordinate {
    /// Horizontal position as a fraction of the texture width, `0.0..=1.0`.
    pub u: f32,
    /// Vertical position as a fraction of the texture height, `0.0..=1.0`.
    pub v: f32,
}

ros_message!(UVCoordinate, defs::UV_COORDINATE, []);

/// `visualization_msgs/msg/MeshFile`: a mesh file sent inside a [`Marker`].
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct MeshFile {
    /// File name, for debugging and for its extension, which selects the parser.
    pub filename: String,
    /// The file's bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

ros_message!(MeshFile, defs::MESH_FILE, []);

/// `visualization_msgs/msg/Marker`: a shape for RViz and other viewers.
///
/// `r#type` is one of [`Self::ARROW`] ..= [`Self::ARROW_STRIP`], `action` one of [`Self::ADD`],
/// [`Self::DELETE`], [`Self::DELETEALL`]. The default is an `ADD` of an `ARROW` at the origin
/// with zero scale and a transparent colour: set at least `scale` and `color.a`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// stamp: time of the marker; frame_id: frame of `pose`.
    pub header: Header,
    /// Namespace; with `id`, names the marker.
    pub ns: String,
    /// Identifier within `ns`.
    pub id: i32,
    /// Shape, one of the shape constants ([`Self::ARROW`] ...). `type` in the `.msg`.
    pub r#type: i32,
    /// [`Self::ADD`] (or `MODIFY`, the same), [`Self::DELETE`] or [`Self::DELETEALL`].
    pub action: i32,
    /// Pose of the shape in `header.frame_id` (m, unit quaternion).
    pub pose: Pose,
    /// Size of the shape (m); `1, 1, 1` is the default size (usually a 1 m cube).
    pub scale: Vector3,
    /// Colour of the whole shape (components `0.0..=1.0`).
    pub color: ColorRGBA,
    /// Time until the viewer deletes the marker; zero keeps it forever.
    pub lifetime: Duration,
    /// If true, the marker is re-transformed into its frame every frame.
    pub frame_locked: bool,
    /// Points (m) of list and strip shapes (`POINTS`, `LINE_STRIP`, `ARROW_STRIP`, ...).
    pub points: Vec<Point>,
    /// Per-point colours: empty, or as many as `points`.
    pub colors: Vec<ColorRGBA>,
    /// Texture URI (resource_retriever), or `embedded://name` to use `texture`.
    pub texture_resource: String,
    /// The texture image, used if `texture_resource` is `embedded://...`.
    pub texture: CompressedImage,
    /// Texture coordinate of each vertex (`0.0..=1.0`).
    pub uv_coordinates: Vec<UVCoordinate>,
    /// Text of `TEXT_VIEW_FACING` markers.
    pub text: String,
    /// Mesh URI of `MESH_RESOURCE` markers (resource_retriever), or `embedded://name` to use
    /// `mesh_file`.
    pub mesh_resource: String,
    /// The mesh, used if `mesh_resource` is `embedded://...`.
    pub mesh_file: MeshFile,
    /// If true, the mesh's own materials are used.
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// Shape: an arrow along +x of `pose` (or from `points[0]` to `points[1]`).
    pub const ARROW: i32 = 0;
    /// Shape: a box.
    pub const CUBE: i32 = 1;
    /// Shape: a sphere (ellipsoid).
    pub const SPHERE: i32 = 2;
    /// Shape: a cylinder along z.
    pub const CYLINDER: i32 = 3;
    /// Shape: a polyline through `points`.
    pub const LINE_STRIP: i32 = 4;
    /// Shape: a segment per pair of `points`.
    pub const LINE_LIST: i32 = 5;
    /// Shape: a box at each of `points`.
    pub const CUBE_LIST: i32 = 6;
    /// Shape: a sphere at each of `points`.
    pub const SPHERE_LIST: i32 = 7;
    /// Shape: a square point at each of `points`.
    pub const POINTS: i32 = 8;
    /// Shape: `text`, facing the camera.
    pub const TEXT_VIEW_FACING: i32 = 9;
    /// Shape: the mesh of `mesh_resource`.
    pub const MESH_RESOURCE: i32 = 10;
    /// Shape: a triangle per three `points`.
    pub const TRIANGLE_LIST: i32 = 11;
    /// Shape: arrows tip to tail through `points` (Jazzy and later; older viewers ignore it).
    pub const ARROW_STRIP: i32 = 12;

    /// Action: add the marker, or replace the one with the same `ns` and `id`.
    pub const ADD: i32 = 0;
    /// Action: the same as [`Self::ADD`].
    pub const MODIFY: i32 = 0;
    /// Action: delete the marker with this `ns` and `id`.
    pub const DELETE: i32 = 2;
    /// Action: delete all markers (of `ns`, if it is not empty).
    pub const DELETEALL: i32 = 3;
}

impl RosMessage for Marker {
    const TYPE_NAME: &'static str = defs::MARKER.0;
    const DEFINITION: &'static str = defs::MARKER.1;
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        defs::MARKER_DEPENDENCIES.to_vec()
    }
}

/// `visualization_msgs/msg/MarkerArray`: markers published together.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers, applied in order.
    pub markers: Vec<Marker>,
}

impl RosMessage for MarkerArray {
    const TYPE_NAME: &'static str = defs::MARKER_ARRAY.0;
    const DEFINITION: &'static str = defs::MARKER_ARRAY.1;
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        let mut deps = vec![defs::MARKER];
        deps.extend(defs::MARKER_DEPENDENCIES);
        deps
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{decode_cdr, encode_cdr, Time};

    fn header(frame_id: &str) -> Header {
        Header {
            stamp: Time {
                sec: 1_700_000_000,
                nanosec: 123_456_789,
            },
            frame_id: frame_id.into(),
        }
    }

    #[test]
    fn quaternion_default_is_the_msg_default_identity() {
        assert_eq!(Quaternion::default(), Quaternion::IDENTITY);
        assert_eq!(Pose::default().orientation.w, 1.0);
        assert_eq!(Marker::default().pose.orientation, Quaternion::IDENTITY);
        // The `.msg` default values are exactly these.
        let defaults: Vec<_> = crate::msg::parse_msg_fields(Quaternion::DEFINITION)
            .into_iter()
            .map(|f| (f.name, f.value))
            .collect();
        assert_eq!(
            defaults,
            [
                ("x".to_owned(), Some("0".to_owned())),
                ("y".to_owned(), Some("0".to_owned())),
                ("z".to_owned(), Some("0".to_owned())),
                ("w".to_owned(), Some("1".to_owned())),
            ]
        );
    }

    #[test]
    fn duration_nanos_round_trip() {
        for ns in [0, 1, -1, 1_700_000_000, -1_700_000_000, 999_999_999_999] {
            let d = Duration::from_nanos(ns);
            assert!(d.nanosec < 1_000_000_000);
            assert_eq!(d.as_nanos(), ns);
        }
        assert_eq!(
            Duration::from_nanos(-1_700_000_000),
            Duration {
                sec: -2,
                nanosec: 300_000_000
            }
        );
    }

    #[test]
    fn point_field_sizes() {
        assert_eq!(PointField::datatype_size(PointField::INT8), Some(1));
        assert_eq!(PointField::datatype_size(PointField::UINT16), Some(2));
        assert_eq!(PointField::datatype_size(PointField::FLOAT32), Some(4));
        assert_eq!(PointField::datatype_size(PointField::FLOAT64), Some(8));
        assert_eq!(PointField::datatype_size(0), None);
        assert_eq!(PointField::datatype_size(9), None);
    }

    #[test]
    fn marker_cdr_round_trip() {
        let marker = Marker {
            header: header("map"),
            ns: "bodies".into(),
            id: -7,
            r#type: Marker::TRIANGLE_LIST,
            action: Marker::ADD,
            pose: Pose {
                position: Point {
                    x: 1.0,
                    y: -2.5,
                    z: 0.125,
                },
                orientation: Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: std::f64::consts::FRAC_1_SQRT_2,
                    w: std::f64::consts::FRAC_1_SQRT_2,
                },
            },
            scale: Vector3::new(1.0, 1.0, 1.0),
            color: ColorRGBA::new(0.25, 0.5, 0.75, 1.0),
            lifetime: Duration {
                sec: 2,
                nanosec: 500_000_000,
            },
            frame_locked: true,
            points: vec![
                Point {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                },
                Point {
                    x: 1.0,
                    y: 0.0,
                    z: 0.0,
                },
                Point {
                    x: 0.0,
                    y: 1.0,
                    z: 0.0,
                },
            ],
            colors: vec![ColorRGBA::new(1.0, 0.0, 0.0, 1.0); 3],
            texture_resource: "embedded://tex".into(),
            texture: CompressedImage {
                header: header("cam"),
                format: "png".into(),
                data: vec![0x89, b'P', b'N', b'G', 0, 255],
            },
            uv_coordinates: vec![
                UVCoordinate { u: 0.0, v: 0.0 },
                UVCoordinate { u: 1.0, v: 0.0 },
                UVCoordinate { u: 0.0, v: 1.0 },
            ],
            text: "héllo".into(),
            mesh_resource: "embedded://mesh".into(),
            mesh_file: MeshFile {
                filename: "part.stl".into(),
                data: b"solid part\nendsolid part\n".to_vec(),
            },
            mesh_use_embedded_materials: true,
        };
        let bytes = encode_cdr(&marker).unwrap();
        assert_eq!(decode_cdr::<Marker>(&bytes).unwrap(), marker);
        let array = MarkerArray {
            markers: vec![marker.clone(), Marker::default(), marker],
        };
        let bytes = encode_cdr(&array).unwrap();
        assert_eq!(decode_cdr::<MarkerArray>(&bytes).unwrap(), array);
    }

    #[test]
    fn point_cloud2_cdr_round_trip() {
        let data: Vec<u8> = [[1.0f32, 2.0, 3.0], [-4.0, 5.5, 0.0]]
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let cloud = PointCloud2 {
            header: header("lidar"),
            height: 1,
            width: 2,
            fields: vec![
                PointField::new("x", 0, PointField::FLOAT32, 1),
                PointField::new("yz", 4, PointField::FLOAT32, 2),
            ],
            is_bigendian: false,
            point_step: 12,
            row_step: 24,
            data,
            is_dense: true,
        };
        let bytes = encode_cdr(&cloud).unwrap();
        assert_eq!(decode_cdr::<PointCloud2>(&bytes).unwrap(), cloud);
        assert_eq!(
            decode_cdr::<PointCloud2>(&encode_cdr(&PointCloud2::default()).unwrap()).unwrap(),
            PointCloud2::default()
        );
    }
}
