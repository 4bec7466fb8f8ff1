//! The lattice frames are made on, and the two encodings of `chronotope_msgs/VoxelGrid`.

use crate::limits::MAX_VOXELS;

/// A lattice that cannot be rasterised onto.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LatticeError {
    /// The voxel edge is not a positive finite number.
    #[error("lattice resolution {0} m is not a positive finite number")]
    BadResolution(f64),
    /// The origin is not finite.
    #[error("lattice origin {0:?} is not finite")]
    BadOrigin([f64; 3]),
    /// A size of zero.
    #[error("lattice size {0:?} has a zero")]
    Empty([u32; 3]),
    /// More voxels than `MAX_VOXELS`.
    #[error("lattice size {size:?} is {voxels} voxels, over MAX_VOXELS = {limit}")]
    TooLarge {
        /// The size.
        size: [u32; 3],
        /// Its voxels.
        voxels: u64,
        /// The limit.
        limit: u64,
    },
}

/// An axis-aligned lattice: voxel (i, j, k) is the closed cube
/// `origin + resolution · ([i, i+1] × [j, j+1] × [k, k+1])` in the lattice frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    origin: [f64; 3],
    resolution: f64,
    size: [u32; 3],
}

impl Lattice {
    /// A checked lattice.
    ///
    /// # Errors
    /// [`LatticeError`] for a non-positive or non-finite resolution, a non-finite origin, a
    /// zero size, or more than `MAX_VOXELS` voxels.
    pub fn new(origin: [f64; 3], resolution: f64, size: [u32; 3]) -> Result<Self, LatticeError> {
        if !(resolution > 0.0 && resolution.is_finite()) {
            return Err(LatticeError::BadResolution(resolution));
        }
        if !origin.iter().all(|v| v.is_finite()) {
            return Err(LatticeError::BadOrigin(origin));
        }
        if size.contains(&0) {
            return Err(LatticeError::Empty(size));
        }
        let voxels = size.iter().map(|&s| u64::from(s)).product::<u64>();
        if voxels > MAX_VOXELS {
            return Err(LatticeError::TooLarge {
                size,
                voxels,
                limit: MAX_VOXELS,
            });
        }
        Ok(Lattice {
            origin,
            resolution,
            size,
        })
    }

    /// A cubic lattice of `n³` voxels covering `[min, min + edge]³`.
    ///
    /// # Errors
    /// As [`new`](Self::new).
    pub fn cube(min: [f64; 3], edge: f64, n: u32) -> Result<Self, LatticeError> {
        Self::new(min, edge / f64::from(n), [n; 3])
    }

    /// Min corner of voxel (0, 0, 0) (m).
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Voxel edge (m).
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Voxels along x, y, z.
    pub fn size(&self) -> [u32; 3] {
        self.size
    }

    /// Number of voxels.
    pub fn voxels(&self) -> usize {
        self.size.iter().map(|&s| s as usize).product()
    }

    /// Index of voxel (i, j, k) in the data: x fastest, then y, then z.
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        let [nx, ny, _] = self.size;
        i as usize + nx as usize * (j as usize + ny as usize * k as usize)
    }

    /// Bytes of a frame's data in `encoding`.
    pub fn data_len(&self, encoding: Encoding) -> usize {
        match encoding {
            Encoding::Bits => self.voxels().div_ceil(8),
            Encoding::Percent => self.voxels(),
        }
    }
}

/// How a frame's data stores occupancy (VoxelGrid's `encoding`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// 1 bit per voxel, 1 = the voxel meets the body; LSB first, x fastest, then y, then z.
    Bits,
    /// 1 byte per voxel: the percent (0..100) of the voxel's volume inside the body.
    Percent,
}

impl Encoding {
    /// The VoxelGrid `encoding` value (`ENCODING_BITS = 0`, `ENCODING_PERCENT = 1`).
    pub fn wire_value(self) -> u8 {
        match self {
            Encoding::Bits => 0,
            Encoding::Percent => 1,
        }
    }
}

/// Whether voxel `index` is set in `bits` data.
pub fn bit_at(data: &[u8], index: usize) -> bool {
    data[index / 8] >> (index % 8) & 1 == 1
}
