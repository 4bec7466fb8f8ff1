//! 4D meshing: voxel time series to a closed, oriented boundary mesh of tetrahedra.
//!
//! - [`table_gen`] builds the marching-hypercubes table (exact hulls, pulling
//!   triangulation); [`table`] serves it.
//! - [`grid`] decodes frames; [`march`] meshes one slab and its caps; [`mesher`] rolls
//!   over a stream of frames.
//! - [`validate`] checks closedness and orientation and measures hypervolume; [`slice`](mod@slice)
//!   cuts the 4D mesh by an axis hyperplane into a closed 3D triangle mesh.
//! - [`stats`] accumulates per-body statistics over a stream with bounded memory.

#![warn(missing_docs)]

pub mod flat;
pub mod glue;
pub mod grid;
pub mod hash;
pub mod march;
pub mod mesher;
pub mod slice;
pub mod stats;
pub mod stream;
pub mod table;
pub mod table_gen;
pub mod unsure;
pub mod validate;
pub mod vanish;

pub use grid::{DecodeOptions, Encoding, FrameRef, GridGeometry, OccupancyGrid, Values};
pub use march::{CapSide, SlabMarcher, SlabPlacement, TetMesh};
pub use mesher::{KeptFrame, Mesher, MesherOptions, Slab};

/// Why a frame (or an option) was refused by the mesher.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The voxel edge is not a finite number of metres in [`MIN_RESOLUTION_M`,
    /// `MAX_RESOLUTION_M`].
    #[error("resolution {} m is not a finite number of metres from {MIN_RESOLUTION_M} to {MAX_RESOLUTION_M}", num(*resolution))]
    BadResolution {
        /// The value received.
        resolution: f64,
    },
    /// The origin has a coordinate that is not finite or beyond [`MAX_ORIGIN_M`].
    #[error("origin ({}, {}, {}) m is not finite or beyond ±{MAX_ORIGIN_M} m", num(origin[0]), num(origin[1]), num(origin[2]))]
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
    #[error("size {}×{}×{} voxels has a zero dimension", size[0], size[1], size[2])]
    EmptySize {
        /// The sizes received.
        size: [u32; 3],
    },
    /// The voxel count exceeds the configured limit (refused before allocating).
    #[error("size {}×{}×{} is {voxels} voxels, over the limit max_voxels = {limit} per frame", size[0], size[1], size[2])]
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
    #[error("size {}×{}×{} would need {bytes} bytes once decoded, over the limit max_decoded_bytes = {limit} per frame", size[0], size[1], size[2])]
    TooMuchMemory {
        /// The sizes received.
        size: [u32; 3],
        /// Bytes needed (saturated).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A size is so large that lattice coordinates (scale × index) would overflow.
    #[error("size {}×{}×{} at lattice scale {scale} overflows the lattice coordinates (at most {max} voxels per axis)", size[0], size[1], size[2])]
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
    /// PERCENT voxels hold values outside 0..=100 and 255 (unknown): not a refusal, the frame is
    /// accepted with them read as 100; this names what the stream counts.
    #[error("{voxels} PERCENT voxel(s) hold values outside 0..=100 and 255 (unknown); read as 100 (occupied)")]
    PercentOutOfRange {
        /// How many voxels hold such values.
        voxels: u64,
    },
    /// The frame is not on the lattice of the body's earlier frames.
    #[error(
        "frame is on a different lattice than the body's earlier frames: {}",
        lattice_change(expected, got)
    )]
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
    /// The header stamp is not a valid time (`nanosec` must be below 10^9).
    #[error("header.stamp nanosec {nanosec} is not below 1000000000 (sec {sec})")]
    BadStamp {
        /// The `sec` field.
        sec: i32,
        /// The `nanosec` field.
        nanosec: u32,
    },
    /// The frame's `header.frame_id` is not the one of the body's earlier frames.
    #[error("header.frame_id {got} where the body's earlier frames have {expected:?}")]
    FrameIdChanged {
        /// The body's frame.
        expected: String,
        /// This frame's, quoted and shortened.
        got: String,
    },
    /// The message did not decode as a VoxelGrid.
    #[error("the message does not decode as a chronotope_msgs/msg/VoxelGrid")]
    Undecodable,
    /// A mesher option is out of range.
    #[error("option {name}: {reason}")]
    BadOption {
        /// The option.
        name: &'static str,
        /// Why.
        reason: String,
    },
}

impl MeshError {
    /// A short stable name of the kind of refusal (for counters and merged loss spans).
    pub fn code(&self) -> &'static str {
        match self {
            Self::BadResolution { .. } => "bad_resolution",
            Self::BadOrigin { .. } => "bad_origin",
            Self::UnknownEncoding { .. } => "unknown_encoding",
            Self::EmptySize { .. } => "empty_size",
            Self::TooLarge { .. } => "max_voxels",
            Self::TooMuchMemory { .. } => "max_decoded_bytes",
            Self::LatticeOverflow { .. } => "lattice_overflow",
            Self::DataLength { .. } => "data_length",
            Self::PercentOutOfRange { .. } => "percent_out_of_range",
            Self::LatticeMismatch { .. } => "lattice_changed",
            Self::StampNotIncreasing { .. } => "stamp_not_increasing",
            Self::SlabTooComplex { .. } => "max_slab_tets",
            Self::TooManyFrames { .. } => "too_many_frames",
            Self::BadOption { .. } => "bad_option",
            Self::BadStamp { .. } => "bad_stamp",
            Self::Undecodable => "undecodable",
            Self::FrameIdChanged { .. } => "frame_id_changed",
        }
    }
}

/// Smallest voxel edge accepted (1 µm).
pub const MIN_RESOLUTION_M: f64 = 1e-6;
/// Largest voxel edge accepted (1 km).
pub const MAX_RESOLUTION_M: f64 = 1e3;
/// Largest origin coordinate accepted, in metres from the frame's origin.
pub const MAX_ORIGIN_M: f64 = 1e6;

/// A number for a message: plain when it is short, in exponent form otherwise (never 300
/// digits).
pub fn num(v: f64) -> String {
    let plain = format!("{v}");
    if plain.len() <= 16 {
        plain
    } else {
        format!("{v:e}")
    }
}

/// A user-supplied string for a message: quoted, at most 64 characters.
pub fn quote(s: &str) -> String {
    const MAX: usize = 64;
    if s.chars().count() <= MAX {
        format!("{s:?}")
    } else {
        let head: String = s.chars().take(MAX).collect();
        format!("{head:?}… ({} bytes)", s.len())
    }
}

/// What differs between two lattices, in user terms.
fn lattice_change(expected: &GridGeometry, got: &GridGeometry) -> String {
    let enc = |e: u8| match e {
        0 => "BITS".to_owned(),
        1 => "PERCENT".to_owned(),
        e => format!("encoding {e}"),
    };
    let mut d = Vec::new();
    if expected.resolution != got.resolution {
        d.push(format!(
            "resolution {} m where they have {} m",
            num(got.resolution),
            num(expected.resolution)
        ));
    }
    if expected.origin != got.origin {
        let o = |v: [f64; 3]| format!("({}, {}, {}) m", num(v[0]), num(v[1]), num(v[2]));
        d.push(format!(
            "origin {} where they have {}",
            o(got.origin),
            o(expected.origin)
        ));
    }
    if expected.size != got.size {
        let s = |v: [u32; 3]| format!("{}×{}×{} voxels", v[0], v[1], v[2]);
        d.push(format!(
            "size {} where they have {}",
            s(got.size),
            s(expected.size)
        ));
    }
    if expected.encoding != got.encoding {
        d.push(format!(
            "{} where they are {}",
            enc(got.encoding),
            enc(expected.encoding)
        ));
    }
    if d.is_empty() {
        d.push("its decoded grid does not match its sizes".to_owned());
    }
    d.join("; ")
}
