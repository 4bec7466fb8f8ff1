//! Rasterising a union of shapes onto a voxel lattice, in either `VoxelGrid` encoding.
//!
//! Both encodings scan lines parallel to x: for each line, every shape whose bounding box
//! meets it gives the open interval where the line is inside ([`Shape::x_interval`]), and the
//! samples inside the union of those intervals are marked. So only the bounding boxes of the
//! shapes are visited, the work per line is a handful of square roots, and nothing is
//! allocated once the workspace has grown to the lattice width.
//!
//! - **BITS**: the samples are the voxel centres; a voxel is occupied iff its centre is
//!   strictly inside some shape (docs/formats.md#input-message: "sampled at the cube's
//!   centre").
//! - **PERCENT**: the samples are the centres of the `S³` sub-cells of each voxel
//!   (`S` = [`PERCENT_SUBSAMPLES`]); the value is `round(100 · inside / S³)`. This is exact
//!   midpoint supersampling of the union, computed a whole line of voxels at a time: voxels
//!   deep inside come out 100 and voxels away from the surface 0 without being sampled one
//!   by one, only the sub-cells the surface passes through are resolved.

use super::{Shape, VoxelLattice};
use chronotope_msg::VoxelEncoding;

/// Sub-samples per voxel edge for the PERCENT encoding (`8³ = 512` per voxel).
pub const PERCENT_SUBSAMPLES: u32 = 8;

/// A reusable workspace for rasterising shapes; holds no results between calls.
#[derive(Debug, Default, Clone)]
pub struct Rasterizer {
    placed: Vec<Placed>,
    active: Vec<usize>,
    spans: Vec<(i64, i64)>,
    direct: Vec<u32>,
    diff: Vec<i32>,
}

/// A shape in its world pose with the voxel range (inclusive, one voxel of margin) its
/// bounding box can touch.
#[derive(Debug, Clone, Copy)]
struct Placed {
    shape: Shape,
    lo: [u32; 3],
    hi: [u32; 3],
}

impl Placed {
    #[inline]
    fn meets_row(&self, j: u32, k: u32) -> bool {
        self.lo[1] <= j && j <= self.hi[1] && self.lo[2] <= k && k <= self.hi[2]
    }
}

impl Rasterizer {
    /// An empty workspace.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes the union of `shapes`, each moved by `offset`, on `lattice` into `data` in
    /// `encoding` (resizing it to `ceil(n/8)` bytes for BITS, `n` for PERCENT, where `n` is
    /// the voxel count). Everything outside the shapes is 0; parts of shapes outside the
    /// lattice are dropped.
    pub fn rasterize(
        &mut self,
        shapes: &[Shape],
        offset: [f64; 3],
        lattice: &VoxelLattice,
        encoding: VoxelEncoding,
        data: &mut Vec<u8>,
    ) {
        let n = lattice.voxel_count();
        data.clear();
        data.resize(
            if encoding == VoxelEncoding::Bits {
                n.div_ceil(8)
            } else {
                n
            },
            0,
        );
        if n == 0 {
            return;
        }
        self.place(shapes, offset, lattice);
        if self.placed.is_empty() {
            return;
        }
        match encoding {
            VoxelEncoding::Bits => self.bits(lattice, data),
            VoxelEncoding::Percent => self.percent(lattice, data),
        }
    }

    /// Moves the shapes into place and finds the voxel ranges their bounding boxes touch.
    fn place(&mut self, shapes: &[Shape], offset: [f64; 3], lattice: &VoxelLattice) {
        self.placed.clear();
        'shapes: for s in shapes {
            let shape = s.translated(offset);
            let bb = shape.aabb();
            let mut lo = [0u32; 3];
            let mut hi = [0u32; 3];
            for a in 0..3 {
                let last = f64::from(lattice.size[a]) - 1.0;
                let first_f = ((bb.min[a] - lattice.origin[a]) / lattice.resolution).floor() - 1.0;
                let last_f = ((bb.max[a] - lattice.origin[a]) / lattice.resolution).floor() + 1.0;
                // `!(x <= y)` also rejects NaN.
                if !(first_f <= last && last_f >= 0.0 && first_f <= last_f) {
                    continue 'shapes;
                }
                lo[a] = first_f.max(0.0) as u32;
                hi[a] = last_f.min(last) as u32;
            }
            self.placed.push(Placed { shape, lo, hi });
        }
    }

    /// The (j, k) row range covering every placed shape.
    fn rows(&self) -> ([u32; 2], [u32; 2]) {
        let mut lo = [u32::MAX; 2];
        let mut hi = [0u32; 2];
        for p in &self.placed {
            for a in 0..2 {
                lo[a] = lo[a].min(p.lo[a + 1]);
                hi[a] = hi[a].max(p.hi[a + 1]);
            }
        }
        (lo, hi)
    }

    fn bits(&mut self, lattice: &VoxelLattice, data: &mut [u8]) {
        let nx = i64::from(lattice.size[0]);
        let (lo, hi) = self.rows();
        for k in lo[1]..=hi[1] {
            let z = lattice.sample(2, u64::from(k), 1);
            for j in lo[0]..=hi[0] {
                let y = lattice.sample(1, u64::from(j), 1);
                let base = lattice.index(0, j, k);
                for p in self.placed.iter().filter(|p| p.meets_row(j, k)) {
                    let Some((x0, x1)) = p.shape.x_interval(y, z) else {
                        continue;
                    };
                    let Some((m0, m1)) =
                        sample_range(x0, x1, lattice.origin[0], lattice.resolution, nx)
                    else {
                        continue;
                    };
                    for idx in base + m0 as usize..=base + m1 as usize {
                        data[idx >> 3] |= 1 << (idx & 7);
                    }
                }
            }
        }
    }

    fn percent(&mut self, lattice: &VoxelLattice, data: &mut [u8]) {
        const S: u32 = PERCENT_SUBSAMPLES;
        const TOTAL: u32 = S * S * S;
        let nx = lattice.size[0] as usize;
        let step = lattice.resolution / f64::from(S);
        let samples = i64::from(lattice.size[0]) * i64::from(S);
        self.direct.clear();
        self.direct.resize(nx + 1, 0);
        self.diff.clear();
        self.diff.resize(nx + 1, 0);
        let (lo, hi) = self.rows();
        for k in lo[1]..=hi[1] {
            for j in lo[0]..=hi[0] {
                self.active.clear();
                let (mut x0, mut x1) = (u32::MAX, 0u32);
                for (a, p) in self.placed.iter().enumerate() {
                    if p.meets_row(j, k) {
                        self.active.push(a);
                        x0 = x0.min(p.lo[0]);
                        x1 = x1.max(p.hi[0]);
                    }
                }
                if self.active.is_empty() {
                    continue;
                }
                let (x0, x1) = (x0 as usize, x1 as usize);
                self.direct[x0..=x1 + 1].fill(0);
                self.diff[x0..=x1 + 1].fill(0);
                // Samples outside the row's voxel range cannot be inside (one voxel margin).
                let (m_min, m_max) = (
                    (x0 as i64) * i64::from(S),
                    (x1 as i64 + 1) * i64::from(S) - 1,
                );
                for c in 0..S {
                    let z = lattice.sample(2, u64::from(k) * u64::from(S) + u64::from(c), S);
                    for b in 0..S {
                        let y = lattice.sample(1, u64::from(j) * u64::from(S) + u64::from(b), S);
                        self.spans.clear();
                        for &a in &self.active {
                            if let Some((s0, s1)) = self.placed[a].shape.x_interval(y, z) {
                                if let Some((m0, m1)) =
                                    sample_range(s0, s1, lattice.origin[0], step, samples)
                                {
                                    let (m0, m1) = (m0.max(m_min), m1.min(m_max));
                                    if m0 <= m1 {
                                        self.spans.push((m0, m1));
                                    }
                                }
                            }
                        }
                        if self.spans.is_empty() {
                            continue;
                        }
                        // Union of the intervals: sort, then merge overlapping or adjacent ones.
                        self.spans.sort_unstable();
                        let mut cur = self.spans[0];
                        for &(s0, s1) in &self.spans[1..] {
                            if s0 <= cur.1 + 1 {
                                cur.1 = cur.1.max(s1);
                            } else {
                                accumulate(&mut self.direct, &mut self.diff, cur, S);
                                cur = (s0, s1);
                            }
                        }
                        accumulate(&mut self.direct, &mut self.diff, cur, S);
                    }
                }
                let base = lattice.index(0, j, k);
                let mut run = 0i32;
                for i in x0..=x1 {
                    run += self.diff[i];
                    let count = run as u32 + self.direct[i];
                    data[base + i] = ((count * 100 + TOTAL / 2) / TOTAL) as u8;
                }
            }
        }
    }
}

/// Adds the samples `span.0..=span.1` of a line (sub-sample indices, `s` per voxel) to the
/// per-voxel counts: partial voxels directly, whole voxels through a difference array.
#[inline]
fn accumulate(direct: &mut [u32], diff: &mut [i32], span: (i64, i64), s: u32) {
    let s = i64::from(s);
    let (v0, v1) = ((span.0 / s) as usize, (span.1 / s) as usize);
    if v0 == v1 {
        direct[v0] += (span.1 - span.0 + 1) as u32;
    } else {
        direct[v0] += (s - span.0 % s) as u32;
        direct[v1] += (span.1 % s + 1) as u32;
        if v1 > v0 + 1 {
            diff[v0 + 1] += s as i32;
            diff[v1] -= s as i32;
        }
    }
}

/// The samples `m ∈ [0, count)` at `origin + (m + 1/2)·step` that lie strictly inside
/// `(lo, hi)`, as an inclusive index range. The first guess comes from division; the
/// fix-ups compare against the sample formula itself, so the answer agrees exactly with
/// testing each sample ([`VoxelLattice::sample`] uses the same formula).
#[inline]
fn sample_range(lo: f64, hi: f64, origin: f64, step: f64, count: i64) -> Option<(i64, i64)> {
    let x = |m: i64| origin + (m as f64 + 0.5) * step;
    let mut m0 = (((lo - origin) / step - 0.5).floor() as i64)
        .saturating_add(1)
        .clamp(0, count);
    while m0 > 0 && x(m0 - 1) > lo {
        m0 -= 1;
    }
    while m0 < count && x(m0) <= lo {
        m0 += 1;
    }
    let mut m1 = (((hi - origin) / step - 0.5).ceil() as i64)
        .saturating_sub(1)
        .clamp(-1, count - 1);
    while m1 < count - 1 && x(m1 + 1) < hi {
        m1 += 1;
    }
    while m1 >= 0 && x(m1) >= hi {
        m1 -= 1;
    }
    (m0 <= m1).then_some((m0, m1))
}

/// Rasterises `shapes` moved by `offset` on `lattice` in `encoding` with a fresh workspace;
/// see [`Rasterizer::rasterize`].
pub fn rasterize(
    shapes: &[Shape],
    offset: [f64; 3],
    lattice: &VoxelLattice,
    encoding: VoxelEncoding,
) -> Vec<u8> {
    let mut data = Vec::new();
    Rasterizer::new().rasterize(shapes, offset, lattice, encoding, &mut data);
    data
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_range_is_exact() {
        // Samples at 0.5, 1.5, ..., 9.5.
        assert_eq!(sample_range(0.5, 9.5, 0.0, 1.0, 10), Some((1, 8)));
        assert_eq!(sample_range(0.4, 9.6, 0.0, 1.0, 10), Some((0, 9)));
        assert_eq!(sample_range(-5.0, 50.0, 0.0, 1.0, 10), Some((0, 9)));
        assert_eq!(sample_range(2.6, 3.4, 0.0, 1.0, 10), None);
        assert_eq!(sample_range(20.0, 30.0, 0.0, 1.0, 10), None);
        assert_eq!(sample_range(-3.0, -1.0, 0.0, 1.0, 10), None);
    }

    #[test]
    fn accumulate_counts_every_sample_once() {
        let mut direct = vec![0u32; 5];
        let mut diff = vec![0i32; 5];
        accumulate(&mut direct, &mut diff, (3, 28), 8);
        let mut run = 0;
        let counts: Vec<u32> = (0..4)
            .map(|i| {
                run += diff[i];
                run as u32 + direct[i]
            })
            .collect();
        assert_eq!(counts, vec![5, 8, 8, 5]);
    }
}
