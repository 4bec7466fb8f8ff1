//! The lattice a frame is rasterised onto, the two output encodings of
//! `chronotope_msgs/VoxelGrid`, the reusable output frame and the limits.
//!
//! Relies on nothing but `std`. Every size is checked here, by name, before a
//! rasteriser allocates anything for it.

use thiserror::Error;

/// `VoxelGrid.encoding` value of [`Encoding::Bits`] (`ENCODING_BITS`).
pub const ENCODING_BITS: u8 = 0;
/// `VoxelGrid.encoding` value of [`Encoding::Percent`] (`ENCODING_PERCENT`).
pub const ENCODING_PERCENT: u8 = 1;
/// The percent value that means "nothing is known of this voxel".
pub const PERCENT_UNKNOWN: u8 = 255;

/// Smallest and largest accepted voxel or octree leaf edge, in metres.
pub const RESOLUTION_RANGE: (f64, f64) = (1e-6, 1e6);

/// How the occupancy of a frame is stored, exactly as `VoxelGrid.data` holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// One bit per voxel, 1 = occupied; least significant bit first; x fastest,
    /// then y, then z; `ceil(n / 8)` bytes.
    Bits,
    /// One byte per voxel: 0..=100 percent occupied, [`PERCENT_UNKNOWN`] (255) unknown.
    Percent,
}

impl Encoding {
    /// The `VoxelGrid.encoding` constant.
    pub fn as_u8(self) -> u8 {
        match self {
            Encoding::Bits => ENCODING_BITS,
            Encoding::Percent => ENCODING_PERCENT,
        }
    }

    /// Bytes of `VoxelGrid.data` for `voxels` voxels.
    pub fn data_len(self, voxels: u64) -> u64 {
        match self {
            Encoding::Bits => voxels.div_ceil(8),
            Encoding::Percent => voxels,
        }
    }
}

/// An axis-aligned voxel lattice: voxel `(i, j, k)` is the cube from
/// `origin + (i, j, k)·resolution` to `origin + (i+1, j+1, k+1)·resolution`.
///
/// Built by [`Lattice::new`], which refuses non-finite or non-positive values and
/// empty sizes; the size limits are checked by the rasterisers against their
/// [`Limits`], since what a frame needs depends on the encoding and the options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    origin: [f64; 3],
    resolution: f64,
    size: [u32; 3],
}

impl Lattice {
    /// A lattice with its min corner at `origin` (metres), voxel edge
    /// `resolution` (metres) and `size` voxels along x, y and z.
    ///
    /// # Errors
    /// [`LatticeError::Origin`] if a coordinate is not finite,
    /// [`LatticeError::Resolution`] if the edge is not finite or outside
    /// [`RESOLUTION_RANGE`], [`LatticeError::EmptySize`] if a size is 0.
    ///
    /// ```
    /// use chronotope_occupancy::Lattice;
    /// let lattice = Lattice::new([0.0, 0.0, 0.0], 0.05, [64, 64, 32]).unwrap();
    /// assert_eq!(lattice.voxel_count(), 64 * 64 * 32);
    /// assert!(Lattice::new([0.0; 3], 0.0, [1, 1, 1]).is_err());
    /// ```
    pub fn new(origin: [f64; 3], resolution: f64, size: [u32; 3]) -> Result<Self, LatticeError> {
        for (axis, &o) in origin.iter().enumerate() {
            if !o.is_finite() {
                return Err(LatticeError::Origin {
                    axis: AXES[axis],
                    value: o,
                });
            }
        }
        if !resolution.is_finite()
            || resolution < RESOLUTION_RANGE.0
            || resolution > RESOLUTION_RANGE.1
        {
            return Err(LatticeError::Resolution { value: resolution });
        }
        for (axis, &n) in size.iter().enumerate() {
            if n == 0 {
                return Err(LatticeError::EmptySize { axis: AXES[axis] });
            }
        }
        Ok(Lattice {
            origin,
            resolution,
            size,
        })
    }

    /// Min corner of voxel `(0, 0, 0)`, metres.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Voxel edge, metres.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Voxels along x, y and z.
    pub fn size(&self) -> [u32; 3] {
        self.size
    }

    /// Number of voxels, `size_x · size_y · size_z` (never overflows: at most 2^96).
    pub fn voxel_count(&self) -> u64 {
        // Three u32 factors can pass u64; saturate, which every limit refuses.
        let [x, y, z] = self.size.map(u64::from);
        x.saturating_mul(y).saturating_mul(z)
    }

    /// Index of voxel `(i, j, k)` in `VoxelGrid.data` order (x fastest, then y, then z).
    pub fn index(&self, i: u32, j: u32, k: u32) -> u64 {
        let [nx, ny, _] = self.size.map(u64::from);
        u64::from(i) + nx * (u64::from(j) + ny * u64::from(k))
    }

    /// Checks the lattice against `limits` for a frame that needs
    /// `work_bytes` of working memory besides its output in `encoding`.
    pub(crate) fn check(
        &self,
        limits: &Limits,
        encoding: Encoding,
        work_bytes: u64,
    ) -> Result<(), LatticeError> {
        let voxels = self.voxel_count();
        // Indices are kept in 32 bits inside the rasterisers, whatever the limit says.
        let limit = limits.max_voxels.min(HARD_MAX_VOXELS);
        if voxels > limit || self.size.iter().any(|&n| n > i32::MAX as u32) {
            return Err(LatticeError::TooManyVoxels { voxels, limit });
        }
        let bytes = encoding.data_len(voxels).saturating_add(work_bytes);
        if bytes > limits.max_decoded_bytes {
            return Err(LatticeError::TooManyBytes {
                bytes,
                limit: limits.max_decoded_bytes,
            });
        }
        Ok(())
    }

    /// Bytes of the padded bit rows every rasteriser works in: one 64-bit word
    /// per started 64 voxels of each x row.
    pub(crate) fn row_bytes(&self) -> u64 {
        let [nx, ny, nz] = self.size.map(u64::from);
        nx.div_ceil(64)
            .saturating_mul(8)
            .saturating_mul(ny)
            .saturating_mul(nz)
    }
}

pub(crate) const AXES: [char; 3] = ['x', 'y', 'z'];

/// The most voxels any lattice may have, whatever [`Limits::max_voxels`] says
/// (2^32; rows and voxel indices are kept in 32 bits).
pub const HARD_MAX_VOXELS: u64 = 1 << 32;

/// Limits on one frame, checked by name before anything is allocated.
///
/// The defaults bound a frame to 2^30 voxels and 512 MiB of output plus working
/// memory, a cloud to 2^25 points, and an octree message to 512 MiB and 2^26 nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most voxels in a lattice (default 2^30; at most [`HARD_MAX_VOXELS`]).
    pub max_voxels: u64,
    /// Most bytes of output plus working buffers for one frame (default 512 MiB).
    pub max_decoded_bytes: u64,
    /// Most points (`width · height`) in one cloud (default 2^25 = 33 554 432).
    pub max_points: u64,
    /// Most bytes of `Octomap.data` (default 512 MiB).
    pub max_octree_bytes: u64,
    /// Most octree nodes, inner and leaves, in one message (default 2^26).
    pub max_octree_nodes: u64,
    /// Largest dilation radius, in voxels (default 64).
    pub max_dilate_voxels: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_voxels: 1 << 30,
            max_decoded_bytes: 512 << 20,
            max_points: 1 << 25,
            max_octree_bytes: 512 << 20,
            max_octree_nodes: 1 << 26,
            max_dilate_voxels: 64,
        }
    }
}

/// A reusable output frame: the lattice, the encoding and `VoxelGrid.data`.
///
/// Rasterisers overwrite it in place and keep its allocation, so one frame per
/// stream bounds the memory of a run. On an error the frame is left as it was.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoxelFrame {
    lattice: Option<Lattice>,
    encoding: Option<Encoding>,
    data: Vec<u8>,
}

impl VoxelFrame {
    /// An empty frame (no lattice yet, no data).
    pub fn new() -> Self {
        Self::default()
    }

    /// The lattice of the last frame written, if any.
    pub fn lattice(&self) -> Option<&Lattice> {
        self.lattice.as_ref()
    }

    /// The encoding of the last frame written, if any.
    pub fn encoding(&self) -> Option<Encoding> {
        self.encoding
    }

    /// `VoxelGrid.data` of the last frame written.
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// Takes the data out, leaving the frame empty.
    pub fn take_data(&mut self) -> Vec<u8> {
        self.lattice = None;
        self.encoding = None;
        std::mem::take(&mut self.data)
    }

    /// Whether voxel `(i, j, k)` is occupied: its bit for [`Encoding::Bits`];
    /// for [`Encoding::Percent`], `Some(true)` at 50 % and above (unknown counts
    /// as `None`). `None` outside the lattice or before any frame.
    pub fn occupied(&self, i: u32, j: u32, k: u32) -> Option<bool> {
        let lattice = self.lattice.as_ref()?;
        let [nx, ny, nz] = lattice.size;
        if i >= nx || j >= ny || k >= nz {
            return None;
        }
        let n = usize::try_from(lattice.index(i, j, k)).ok()?;
        match self.encoding? {
            Encoding::Bits => Some(self.data.get(n / 8)? >> (n % 8) & 1 == 1),
            Encoding::Percent => match *self.data.get(n)? {
                PERCENT_UNKNOWN => None,
                v => Some(v >= 50),
            },
        }
    }

    /// Voxel `(i, j, k)`'s byte for [`Encoding::Percent`] frames, its bit (0 or 1)
    /// for [`Encoding::Bits`]. `None` outside the lattice or before any frame.
    pub fn value(&self, i: u32, j: u32, k: u32) -> Option<u8> {
        let lattice = self.lattice.as_ref()?;
        let [nx, ny, nz] = lattice.size;
        if i >= nx || j >= ny || k >= nz {
            return None;
        }
        let n = usize::try_from(lattice.index(i, j, k)).ok()?;
        match self.encoding? {
            Encoding::Bits => Some(self.data.get(n / 8)? >> (n % 8) & 1),
            Encoding::Percent => self.data.get(n).copied(),
        }
    }

    /// Sets the frame's header and hands out its data buffer for the writer.
    pub(crate) fn begin(&mut self, lattice: Lattice, encoding: Encoding) -> &mut Vec<u8> {
        self.lattice = Some(lattice);
        self.encoding = Some(encoding);
        &mut self.data
    }
}

/// What is wrong with a lattice, or which limit it passes.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LatticeError {
    /// A coordinate of the origin is NaN or infinite.
    #[error("lattice origin {axis} is {value}: it must be finite")]
    Origin {
        /// The axis, `x`, `y` or `z`.
        axis: char,
        /// The value given.
        value: f64,
    },
    /// The voxel edge is not finite or outside [`RESOLUTION_RANGE`].
    #[error("lattice resolution is {value} m: it must be finite and within 1e-6..=1e6 m")]
    Resolution {
        /// The value given.
        value: f64,
    },
    /// A size is 0.
    #[error("lattice size_{axis} is 0: every size must be at least 1")]
    EmptySize {
        /// The axis, `x`, `y` or `z`.
        axis: char,
    },
    /// More voxels than [`Limits::max_voxels`].
    #[error("lattice has {voxels} voxels, more than the limit max_voxels = {limit}: use a coarser or smaller lattice")]
    TooManyVoxels {
        /// Voxels asked for.
        voxels: u64,
        /// The limit.
        limit: u64,
    },
    /// Output plus working memory beyond [`Limits::max_decoded_bytes`].
    #[error("frame needs {bytes} bytes of output and working memory, more than the limit max_decoded_bytes = {limit}: use a coarser or smaller lattice, or the bits encoding")]
    TooManyBytes {
        /// Bytes the frame would need.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
}
