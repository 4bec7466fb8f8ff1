//! Occupancy as robot and machine-tool cells publish it, turned into voxel
//! occupancy frames on a given lattice, exactly as `chronotope_msgs/VoxelGrid`
//! stores them (`bits` or `percent`).
//!
//! Two sources, over plain Rust values (the message fields, already decoded
//! from the wire):
//! - [`OctomapRasterizer`]: `octomap_msgs/Octomap`, the binary and the full
//!   streams of `OcTree`, `OcTreeStamped` and `ColorOcTree`, at any resolution,
//!   leaves at any depth. Rules in [`octomap`].
//! - [`CloudRasterizer`]: `sensor_msgs/PointCloud2`, any layout of FLOAT32 or
//!   FLOAT64 x, y, z, either byte order, organised or padded; with noise
//!   rejection, a safety margin, column fills and a rigid transform. Rules in
//!   [`cloud`].
//!
//! Both write into a reusable [`VoxelFrame`] and keep their working buffers, so
//! a stream of frames allocates once. Every size is checked against [`Limits`]
//! before anything is allocated for it; bad input is a typed error naming the
//! field or byte offset at fault, never a panic; octrees are walked with an
//! explicit stack of at most 17 frames.
//!
//! The crate knows nothing of ROS, DDS or bags: decoding the messages from CDR,
//! topics and parameters belong to the node that uses it.
//!
//! ```
//! use chronotope_occupancy::{Encoding, Lattice, OctomapMsg, OctomapOptions, OctomapRasterizer, VoxelFrame};
//! let lattice = Lattice::new([-1.0, -1.0, 0.0], 0.05, [40, 40, 20])?;
//! let mut raster = OctomapRasterizer::new(OctomapOptions::new().unknown_occupied(true));
//! let mut frame = VoxelFrame::new();
//! // An empty message is an empty tree: everything unknown, here occupied.
//! let msg = OctomapMsg { binary: true, id: "OcTree", resolution: 0.05, data: &[] };
//! let stats = raster.rasterize(&msg, &lattice, Encoding::Bits, &mut frame)?;
//! assert_eq!(stats.occupied_voxels, 40 * 40 * 20);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod cloud;
pub mod lattice;
pub mod octomap;
mod rows;
pub mod transform;

pub use cloud::{
    Axis, CloudError, CloudOptions, CloudRasterizer, CloudStats, Fill, PointCloud2Ref, PointField,
    Toward, FLOAT32, FLOAT64,
};
pub use lattice::{
    Encoding, Lattice, LatticeError, Limits, VoxelFrame, ENCODING_BITS, ENCODING_PERCENT,
    HARD_MAX_VOXELS, PERCENT_UNKNOWN,
};
pub use octomap::{
    read_leaves, OctomapError, OctomapMsg, OctomapOptions, OctomapRasterizer, OctomapStats,
    OctreeLeaf, StreamSummary, TreeKind, PARALLEL_BYTES,
};
pub use transform::{RigidTransform, TransformError};

/// Whether the machine has more than one core, for the rasterisers' second threads (asked
/// once: the answer reads cgroup files).
pub(crate) fn several_cores() -> bool {
    static SEVERAL: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *SEVERAL.get_or_init(|| std::thread::available_parallelism().is_ok_and(|n| n.get() > 1))
}
