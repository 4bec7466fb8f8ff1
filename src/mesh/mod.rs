//! 4D meshing: voxel time series to a closed, oriented boundary mesh of tetrahedra.
//!
//! - [`table_gen`] builds the marching-hypercubes table (exact hulls, pulling
//!   triangulation); [`table`] serves it.
//! - [`grid`] decodes frames; [`march`] meshes one slab and its caps; [`mesher`] rolls
//!   over a stream of frames.
//! - [`validate`] checks closedness and orientation and measures hypervolume; [`slice`](mod@slice)
//!   cuts the 4D mesh by an axis hyperplane into a closed 3D triangle mesh.
//! - [`stats`] accumulates per-body statistics over a stream with bounded memory.

pub mod glue;
pub mod grid;
pub mod march;
pub mod mesher;
pub mod slice;
pub mod stats;
pub mod table;
pub mod table_gen;
pub mod validate;

pub use grid::{DecodeOptions, Encoding, FrameRef, OccupancyGrid};
pub use march::{CapSide, SlabMarcher, SlabPlacement, TetMesh};
pub use mesher::{GridGeometry, KeptFrame, Mesher, MesherOptions, Slab};

/// Why a frame (or an option) was refused by the mesher.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The voxel edge is zero, negative or not finite.
    #[error("resolution {resolution} is not a positive finite number of metres")]
    BadResolution {
        /// The value received.
        resolution: f64,
    },
    /// The origin has a NaN or infinite coordinate.
    #[error("origin {origin:?} is not finite")]
    BadOrigin {
        /// The value received.
        origin: [f64; 3],
    },
    /// The encoding field is neither BITS (0) nor PERCENT (1).
    #[error("unknown encoding {encoding} (expected 0 = BITS or 1 = PERCENT)")]
    UnknownEncoding {
        /// The value received.
        encoding: u8,
    },
    /// A size is zero.
    #[error("size {size:?} has a zero dimension")]
    EmptySize {
        /// The sizes received.
        size: [u32; 3],
    },
    /// The voxel count exceeds the configured limit (refused before allocating).
    #[error("size {size:?} is {voxels} voxels, over the limit of {limit} (raise max_voxels if this is intended)")]
    TooLarge {
        /// The sizes received.
        size: [u32; 3],
        /// Their product (saturated).
        voxels: u64,
        /// The limit.
        limit: u64,
    },
    /// Decoding the frame would take more memory than allowed (thin grids cost more per
    /// voxel than their data), or its lattice coordinates would overflow.
    #[error("size {size:?} would need {bytes} bytes once decoded, over the limit of {limit}")]
    TooMuchMemory {
        /// The sizes received.
        size: [u32; 3],
        /// Bytes needed (saturated).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A size is so large that lattice coordinates (scale × index) would overflow.
    #[error("size {size:?} at lattice scale {scale} overflows the lattice coordinates (at most {max} voxels per axis)")]
    LatticeOverflow {
        /// The sizes received.
        size: [u32; 3],
        /// Lattice steps per voxel.
        scale: i32,
        /// Largest size per axis at this scale.
        max: u32,
    },
    /// The data length does not match sizes and encoding.
    #[error("data is {got} bytes but sizes and encoding {encoding:?} need {expected}")]
    DataLength {
        /// Bytes needed.
        expected: u64,
        /// Bytes received.
        got: u64,
        /// The frame's encoding.
        encoding: Encoding,
    },
    /// The frame is not on the lattice of the body's earlier frames.
    #[error("frame is on a different lattice than the previous frames: expected {expected:?}, got {got:?}")]
    LatticeMismatch {
        /// The body's lattice.
        expected: Box<GridGeometry>,
        /// This frame's lattice.
        got: Box<GridGeometry>,
    },
    /// The stamp is not after the previous frame's.
    #[error("stamp {got_ns} ns does not increase (previous frame at {previous_ns} ns)")]
    StampNotIncreasing {
        /// Previous accepted stamp.
        previous_ns: i64,
        /// This frame's stamp.
        got_ns: i64,
    },
    /// The slab this frame completes would have more tets than allowed (noise-like
    /// occupancy makes a surface in almost every hypercube).
    #[error("the slab this frame completes exceeds {limit} tets (raise max_slab_tets if this is a real scene)")]
    SlabTooComplex {
        /// The limit.
        limit: usize,
    },
    /// The lattice time coordinate would overflow.
    #[error("more than {limit} frames in one stream: lattice time would overflow")]
    TooManyFrames {
        /// Frames accepted at most.
        limit: u64,
    },
    /// A mesher option is out of range.
    #[error("option {name}: {reason}")]
    BadOption {
        /// The option.
        name: &'static str,
        /// Why.
        reason: String,
    },
}
