//! The voxel lattice every frame of a scene uses.

/// An axis-aligned voxel lattice, laid out as in `chronotope_msgs/msg/VoxelGrid`: voxel
/// `(i, j, k)` is the cube from `origin + (i, j, k)·resolution` to
/// `origin + (i + 1, j + 1, k + 1)·resolution`, and its linear index is `i + nx·(j + ny·k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelLattice {
    /// Minimum corner of voxel (0, 0, 0) (m).
    pub origin: [f64; 3],
    /// Voxel edge (m).
    pub resolution: f64,
    /// Voxels along x, y and z.
    pub size: [u32; 3],
}

impl VoxelLattice {
    /// The cube `[origin, origin + edge]³` cut into `n³` voxels.
    pub fn cube(origin: [f64; 3], edge: f64, n: u32) -> Self {
        Self {
            origin,
            resolution: edge / f64::from(n),
            size: [n; 3],
        }
    }

    /// Number of voxels.
    pub fn voxel_count(&self) -> usize {
        self.size.iter().map(|&n| n as usize).product()
    }

    /// Linear index of voxel `(i, j, k)` (x fastest, then y, then z).
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        let [nx, ny, _] = self.size.map(|n| n as usize);
        i as usize + nx * (j as usize + ny * k as usize)
    }

    /// Coordinate along `axis` (0, 1, 2) of the sample at `(m + 1/2)·resolution/sub` from the
    /// origin: with `sub = 1` the voxel centres, with `sub = s` the centres of the `s` equal
    /// sub-cells of each voxel. The rasteriser uses exactly this formula.
    #[inline]
    pub fn sample(&self, axis: usize, m: u64, sub: u32) -> f64 {
        self.origin[axis] + (m as f64 + 0.5) * (self.resolution / f64::from(sub))
    }

    /// The centre of voxel `(i, j, k)`.
    pub fn voxel_centre(&self, i: u32, j: u32, k: u32) -> [f64; 3] {
        [
            self.sample(0, u64::from(i), 1),
            self.sample(1, u64::from(j), 1),
            self.sample(2, u64::from(k), 1),
        ]
    }
}
