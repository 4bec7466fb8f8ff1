//! `chronotope_msgs/msg/VoxelGrid` (docs/formats.md#input-message) and the standard types
//! it refers to.

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Time {
    /// Seconds since the epoch.
    pub sec: i32,
    /// Nanoseconds, `0..1_000_000_000`.
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the epoch (exact; `sec` may be negative).
    pub fn as_nanos(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
    /// The stamp of `ns` nanoseconds since the epoch (floor division, so `nanosec` stays in range).
    pub fn from_nanos(ns: i64) -> Self {
        let sec = ns.div_euclid(1_000_000_000);
        Self {
            sec: sec as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time of the frame.
    pub stamp: Time,
    /// Frame of the lattice.
    pub frame_id: String,
}

/// `geometry_msgs/msg/Point`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// (m)
    pub x: f64,
    /// (m)
    pub y: f64,
    /// (m)
    pub z: f64,
}

/// The two encodings of [`VoxelGrid::data`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VoxelEncoding {
    /// 1 bit per voxel, LSB first, x fastest then y then z.
    Bits,
    /// 1 byte per voxel: 0..=100 occupied percent, 255 unknown.
    Percent,
}

impl VoxelEncoding {
    /// The `encoding` field value.
    pub fn code(self) -> u8 {
        match self {
            Self::Bits => VoxelGrid::ENCODING_BITS,
            Self::Percent => VoxelGrid::ENCODING_PERCENT,
        }
    }
    /// The encoding named by an `encoding` field value, if known.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            VoxelGrid::ENCODING_BITS => Some(Self::Bits),
            VoxelGrid::ENCODING_PERCENT => Some(Self::Percent),
            _ => None,
        }
    }
}

/// `chronotope_msgs/msg/VoxelGrid`: one occupancy frame of one body on an axis-aligned lattice.
///
/// Voxel (i,j,k) is the cube from `origin + (i,j,k)·resolution` to `origin + (i+1,j+1,k+1)·resolution`,
/// sampled at its centre. Everything outside the grid is free.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct VoxelGrid {
    /// stamp: time of the frame; frame_id: frame of the lattice.
    pub header: Header,
    /// Min corner of voxel (0,0,0) (m).
    pub origin: Point,
    /// Voxel edge (m), > 0.
    pub resolution: f64,
    /// Voxels along x.
    pub size_x: u32,
    /// Voxels along y.
    pub size_y: u32,
    /// Voxels along z.
    pub size_z: u32,
    /// [`Self::ENCODING_BITS`] or [`Self::ENCODING_PERCENT`].
    pub encoding: u8,
    /// The voxels, as `encoding` says.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

impl VoxelGrid {
    /// The mesher's view of this frame: its stamp, lattice and data, borrowed.
    pub fn frame_ref(&self) -> chronotope_mesh::FrameRef<'_> {
        chronotope_mesh::FrameRef {
            stamp_ns: self.header.stamp.as_nanos(),
            origin: [self.origin.x, self.origin.y, self.origin.z],
            resolution: self.resolution,
            size: [self.size_x, self.size_y, self.size_z],
            encoding: self.encoding,
            data: &self.data,
        }
    }

    /// The checks of a frame's message fields that its body's stream cannot make: `nanosec`
    /// below 10^9, and `header.frame_id` the same as the body's earlier frames
    /// (`body_frame_id`; empty before the body's first accepted frame).
    ///
    /// # Errors
    /// [`MeshError::BadStamp`](chronotope_mesh::MeshError::BadStamp) or
    /// [`MeshError::FrameIdChanged`](chronotope_mesh::MeshError::FrameIdChanged).
    pub fn message_check(&self, body_frame_id: &str) -> Result<(), chronotope_mesh::MeshError> {
        use chronotope_mesh::MeshError;
        if self.header.stamp.nanosec >= 1_000_000_000 {
            return Err(MeshError::BadStamp {
                sec: self.header.stamp.sec,
                nanosec: self.header.stamp.nanosec,
            });
        }
        if !body_frame_id.is_empty() && self.header.frame_id != body_frame_id {
            return Err(MeshError::FrameIdChanged {
                expected: body_frame_id.to_owned(),
                got: chronotope_mesh::quote(&self.header.frame_id),
            });
        }
        Ok(())
    }

    /// 1 bit per voxel, 1 = occupied; LSB first; x fastest, then y, then z.
    pub const ENCODING_BITS: u8 = 0;
    /// 1 byte per voxel: 0..100 occupied percent, 255 unknown.
    pub const ENCODING_PERCENT: u8 = 1;
    /// Percent value meaning "unknown".
    pub const PERCENT_UNKNOWN: u8 = 255;

    /// Number of voxels, if it fits in `u64` (it always does for `u32` sizes).
    pub fn voxel_count(&self) -> u64 {
        u64::from(self.size_x) * u64::from(self.size_y) * u64::from(self.size_z)
    }

    /// The data length the sizes and encoding call for, or `None` for an unknown encoding.
    pub fn expected_data_len(&self) -> Option<u64> {
        match VoxelEncoding::from_code(self.encoding)? {
            VoxelEncoding::Bits => Some(self.voxel_count().div_ceil(8)),
            VoxelEncoding::Percent => Some(self.voxel_count()),
        }
    }
}

impl super::RosMessage for VoxelGrid {
    const TYPE_NAME: &'static str = "chronotope_msgs/msg/VoxelGrid";
    const DEFINITION: &'static str = include_str!("../../../msgs/msg/VoxelGrid.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        vec![
            (
                "std_msgs/msg/Header",
                include_str!("../../../msgs/deps/std_msgs/msg/Header.msg"),
            ),
            (
                "builtin_interfaces/msg/Time",
                include_str!("../../../msgs/deps/builtin_interfaces/msg/Time.msg"),
            ),
            (
                "geometry_msgs/msg/Point",
                include_str!("../../../msgs/deps/geometry_msgs/msg/Point.msg"),
            ),
        ]
    }
}
