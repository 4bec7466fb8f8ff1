//! Lattice points (exact) and the map from the lattice to metres and seconds.

/// A point of the integer lattice in (x, y, z, t). Voxel centre (i, j, k) of frame n is
/// `(S·i, S·j, S·k, S·n)` for the lattice scale S; surface vertices lie between, on
/// multiples of 1 (an edge is cut into S steps).
pub type LatticePoint = [i32; 4];

/// A point in metres and seconds (x, y, z, t). Only for reporting: never fed to a predicate.
pub type SpaceTimePoint = [f64; 4];

/// How lattice coordinates map to metres and seconds for one body.
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeFrame {
    /// Centre of voxel (0, 0, 0) (m).
    pub voxel0_centre: [f64; 3],
    /// Voxel edge (m).
    pub resolution: f64,
    /// Lattice steps per voxel edge and per frame (2 for binary input, 2^k for percent).
    pub scale: i32,
    /// Frame stamps (ns), frame n at lattice time S·n.
    pub stamps_ns: Vec<i64>,
}

impl LatticeFrame {
    /// Metres of one lattice step.
    pub fn step_m(&self) -> f64 {
        self.resolution / f64::from(self.scale)
    }

    /// Time (s since `origin_ns`) of lattice time `t` (piecewise linear between frames).
    /// Outside the recorded frames it extrapolates with the nearest frame period.
    pub fn time_s(&self, t: i64, origin_ns: i64) -> f64 {
        let s = i64::from(self.scale);
        let n = self.stamps_ns.len() as i64;
        if n == 0 {
            return 0.0;
        }
        if n == 1 {
            return (self.stamps_ns[0] - origin_ns) as f64 * 1e-9;
        }
        let k = t.div_euclid(s).clamp(0, n - 2);
        let frac = (t - k * s) as f64 / s as f64;
        let a = self.stamps_ns[k as usize] - origin_ns;
        let b = self.stamps_ns[k as usize + 1] - origin_ns;
        (a as f64 + frac * (b - a) as f64) * 1e-9
    }

    /// The point in metres and seconds.
    pub fn to_space_time(&self, p: &LatticePoint, origin_ns: i64) -> SpaceTimePoint {
        let h = self.step_m();
        [
            self.voxel0_centre[0] + f64::from(p[0]) * h,
            self.voxel0_centre[1] + f64::from(p[1]) * h,
            self.voxel0_centre[2] + f64::from(p[2]) * h,
            self.time_s(i64::from(p[3]), origin_ns),
        ]
    }
}
