//! The per-point loop: read x, y, z, skip what is not finite, transform, find
//! the voxel `floor((p - origin) · (1 / resolution))` and mark it.
//!
//! Monomorphised per storage (f32/f64, either byte order) when x, y and z share
//! one, so the hot loop has no per-field dispatch; a mixed layout takes a
//! general path. Points outside the lattice only bump a counter, unless a
//! margin or column rule keeps them (see [`Reach`]).

use std::ops::Range;

use super::layout::{Scalar, XyzLayout};
use super::{Axis, CloudStats, Fill, Toward};
use crate::rows::BitRows;
use crate::transform::RigidTransform;

/// What a point outside the lattice can still mark.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reach {
    /// Squared dilation radius in voxel units (0: no dilation). A point within
    /// it of the lattice's box marks the nearest voxel (clamped), whose
    /// dilation then reaches every voxel the point's own would.
    pub dilate2: f64,
    /// A column fill: a point beyond the face the columns start from (above the
    /// top for columns down to the floor), inside the other two ranges, marks
    /// the end voxel of its column, which the fill then runs through.
    pub fill: Fill,
}

/// Marks voxels of one frame.
pub(crate) struct Marker<'a> {
    pub origin: [f64; 3],
    pub inv_res: f64,
    pub n: [usize; 3],
    pub rows: &'a mut BitRows,
    /// Per-voxel point counts (VoxelGrid order) when `min_points > 1`.
    pub counts: Option<&'a mut [u8]>,
    pub min_points: u8,
    pub transform: Option<RigidTransform>,
    pub reach: Reach,
    pub stats: CloudStats,
}

trait ReadXyz {
    fn read(p: &[u8], off: &[usize; 3], layout: &XyzLayout) -> [f64; 3];
}

struct F32<const BE: bool>;
struct F64<const BE: bool>;
/// x, y and z of different storages: dispatched per field.
struct Mixed;

impl ReadXyz for Mixed {
    #[inline(always)]
    fn read(p: &[u8], _: &[usize; 3], layout: &XyzLayout) -> [f64; 3] {
        read_mixed(p, layout)
    }
}

impl<const BE: bool> ReadXyz for F32<BE> {
    #[inline(always)]
    fn read(p: &[u8], off: &[usize; 3], _: &XyzLayout) -> [f64; 3] {
        off.map(|o| {
            let b: [u8; 4] = p[o..o + 4].try_into().expect("4 bytes");
            f64::from(if BE {
                f32::from_be_bytes(b)
            } else {
                f32::from_le_bytes(b)
            })
        })
    }
}

impl<const BE: bool> ReadXyz for F64<BE> {
    #[inline(always)]
    fn read(p: &[u8], off: &[usize; 3], _: &XyzLayout) -> [f64; 3] {
        off.map(|o| {
            let b: [u8; 8] = p[o..o + 8].try_into().expect("8 bytes");
            if BE {
                f64::from_be_bytes(b)
            } else {
                f64::from_le_bytes(b)
            }
        })
    }
}

fn read_mixed(p: &[u8], layout: &XyzLayout) -> [f64; 3] {
    std::array::from_fn(|a| {
        let o = layout.offsets[a];
        match (layout.scalars[a], layout.big_endian) {
            (Scalar::F32, false) => {
                f64::from(f32::from_le_bytes(p[o..o + 4].try_into().expect("4 bytes")))
            }
            (Scalar::F32, true) => {
                f64::from(f32::from_be_bytes(p[o..o + 4].try_into().expect("4 bytes")))
            }
            (Scalar::F64, false) => f64::from_le_bytes(p[o..o + 8].try_into().expect("8 bytes")),
            (Scalar::F64, true) => f64::from_be_bytes(p[o..o + 8].try_into().expect("8 bytes")),
        }
    })
}

/// Points decoded before their voxels are marked: the marks of a batch are
/// independent stores the processor overlaps, instead of one cache miss at a
/// time between decodes.
const BATCH: usize = 64;

/// Voxels found in one batch: x and the row `y + ny·z`.
struct Found {
    x: [u32; BATCH],
    row: [u32; BATCH],
    len: usize,
}

impl Marker<'_> {
    /// Marks points `points` of the cloud (numbered row by row, `width` a row).
    pub(crate) fn run(&mut self, layout: &XyzLayout, data: &[u8], points: Range<usize>) {
        let same = layout.scalars[0] == layout.scalars[1] && layout.scalars[1] == layout.scalars[2];
        match (same, layout.scalars[0], layout.big_endian) {
            (true, Scalar::F32, false) => self.all::<F32<false>>(layout, data, points),
            (true, Scalar::F32, true) => self.all::<F32<true>>(layout, data, points),
            (true, Scalar::F64, false) => self.all::<F64<false>>(layout, data, points),
            (true, Scalar::F64, true) => self.all::<F64<true>>(layout, data, points),
            _ => self.all::<Mixed>(layout, data, points),
        }
    }

    fn all<R: ReadXyz>(&mut self, layout: &XyzLayout, data: &[u8], points: Range<usize>) {
        match self.transform {
            Some(t) => self.batches::<R, true>(layout, data, points, t),
            None => self.batches::<R, false>(layout, data, points, RigidTransform::identity()),
        }
    }

    fn batches<R: ReadXyz, const MOVE: bool>(
        &mut self,
        layout: &XyzLayout,
        data: &[u8],
        points: Range<usize>,
        t: RigidTransform,
    ) {
        let off = layout.offsets;
        let step = layout.point_step;
        let width = layout.width;
        if width == 0 || step == 0 || points.is_empty() {
            return;
        }
        let mut found = Found {
            x: [0; BATCH],
            row: [0; BATCH],
            len: 0,
        };
        let mut xyz = [[0.0f64; BATCH]; 3];
        let mut cell = [[0i32; BATCH]; 3];
        let mut ok = [false; BATCH];
        let [nx, ny, nz] = self.n;
        let nf = [nx as f64, ny as f64, nz as f64];
        let top = [nx as i32 - 1, ny as i32 - 1, nz as i32 - 1];
        let rows = points.start / width..points.end.div_ceil(width).min(layout.height);
        for r in rows {
            // This row's points within `points`.
            let first = points.start.saturating_sub(r * width);
            let end = (points.end - r * width).min(width);
            let at = r * layout.row_step;
            let row = &data[at + first * step..at + end * step];
            for batch in row.chunks(BATCH * step) {
                // 1. Decode.
                let mut n = 0;
                for p in batch.chunks_exact(step) {
                    let p = R::read(p, &off, layout);
                    xyz[0][n] = p[0];
                    xyz[1][n] = p[1];
                    xyz[2][n] = p[2];
                    n += 1;
                }
                // 1b. Transform, array by array (the compiler vectorises it;
                //     each value is computed as `RigidTransform::apply` does).
                if MOVE {
                    let (r, tr) = (t.rotation(), t.translation());
                    let [xs, ys, zs] = &mut xyz;
                    for ((px, py), pz) in xs[..n].iter_mut().zip(&mut ys[..n]).zip(&mut zs[..n]) {
                        let (x, y, z) = (*px, *py, *pz);
                        *px = r[0][0] * x + r[0][1] * y + r[0][2] * z + tr[0];
                        *py = r[1][0] * x + r[1][1] * y + r[1][2] * z + tr[1];
                        *pz = r[2][0] * x + r[2][1] * y + r[2][2] * z + tr[2];
                    }
                }
                // 2. Voxel coordinates and the inside test, branch-free (the
                //    compiler vectorises it). NaN fails every compare.
                for i in 0..n {
                    let mut inside = true;
                    for a in 0..3 {
                        let u = (xyz[a][i] - self.origin[a]) * self.inv_res;
                        inside &= (u >= 0.0) & (u < nf[a]);
                        cell[a][i] = (u as i32).min(top[a]);
                    }
                    ok[i] = inside;
                }
                // 3. Record the inside ones; the rest are counted one by one.
                found.len = 0;
                for i in 0..n {
                    if ok[i] {
                        found.x[found.len] = cell[0][i] as u32;
                        found.row[found.len] =
                            (cell[1][i] as usize + ny * cell[2][i] as usize) as u32;
                        found.len += 1;
                    } else {
                        self.not_inside([xyz[0][i], xyz[1][i], xyz[2][i]]);
                    }
                }
                self.mark_found(&found);
            }
        }
    }

    /// A point that is not finite or not inside the lattice.
    #[cold]
    fn not_inside(&mut self, p: [f64; 3]) {
        if !(p[0].is_finite() && p[1].is_finite() && p[2].is_finite()) {
            self.stats.nonfinite += 1;
            return;
        }
        let u = [
            (p[0] - self.origin[0]) * self.inv_res,
            (p[1] - self.origin[1]) * self.inv_res,
            (p[2] - self.origin[2]) * self.inv_res,
        ];
        self.outside(u);
    }

    fn mark_found(&mut self, found: &Found) {
        let wpr = self.rows.words_per_row();
        let nx = self.n[0];
        let min = self.min_points;
        let xs = &found.x[..found.len];
        let rs = &found.row[..found.len];
        match self.counts.as_deref_mut() {
            None => {
                let words = self.rows.words_mut();
                for (&x, &r) in xs.iter().zip(rs) {
                    let (x, r) = (x as usize, r as usize);
                    words[r * wpr + x / 64] |= 1u64 << (x % 64);
                }
            }
            Some(counts) => {
                let words = self.rows.words_mut();
                for (&x, &r) in xs.iter().zip(rs) {
                    let (x, r) = (x as usize, r as usize);
                    let i = x + nx * r;
                    let c = counts[i].saturating_add(1);
                    counts[i] = c;
                    if c == min {
                        words[r * wpr + x / 64] |= 1u64 << (x % 64);
                    }
                }
            }
        }
    }

    /// Marks voxel `v` at once (the rare points kept by the margin rules).
    fn mark(&mut self, v: [usize; 3]) {
        let ny = self.n[1];
        let found = Found {
            x: [v[0] as u32; BATCH],
            row: [(v[1] + ny * v[2]) as u32; BATCH],
            len: 1,
        };
        self.mark_found(&found);
    }

    #[cold]
    fn outside(&mut self, u: [f64; 3]) {
        if u.iter().any(|v| !v.is_finite()) {
            self.stats.outside += 1;
            return;
        }
        let n = self.n.map(|n| n as f64);
        let clamp = |a: usize| (u[a].floor().clamp(0.0, n[a] - 1.0)) as usize;
        if self.reach.dilate2 > 0.0 {
            let d2: f64 = (0..3)
                .map(|a| {
                    let d = (-u[a]).max(u[a] - n[a]).max(0.0);
                    d * d
                })
                .sum();
            if d2 <= self.reach.dilate2 {
                self.stats.margin_points += 1;
                self.mark([clamp(0), clamp(1), clamp(2)]);
                return;
            }
        }
        if let Fill::Columns { axis, toward } = self.reach.fill {
            let a = match axis {
                Axis::X => 0,
                Axis::Y => 1,
                Axis::Z => 2,
            };
            let beyond = match toward {
                Toward::Min => u[a] >= n[a],
                Toward::Max => u[a] < 0.0,
            };
            let others_in = (0..3)
                .filter(|&b| b != a)
                .all(|b| u[b] >= 0.0 && u[b] < n[b]);
            if beyond && others_in {
                self.stats.margin_points += 1;
                self.mark([clamp(0), clamp(1), clamp(2)]);
                return;
            }
        }
        self.stats.outside += 1;
    }
}
