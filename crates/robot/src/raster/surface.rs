//! The voxels a triangle meets, conservatively: for each voxel row (j, k) the triangle is
//! clipped to the row's slab `[j, j+1] × [k, k+1]` (grown by the margin) and the row's voxels
//! that meet the clipped polygon's x extent are set.
//!
//! This is exact for closed cubes and a closed triangle: the triangle meets voxel (i, j, k)
//! iff its part inside the slab has a point with x in `[i, i+1]`, and that part is convex, so
//! its x extent is an interval and the voxels meeting it are a run. Floating point can only
//! shrink the clipped polygon by rounding, by far less than the margin, so growing the slab
//! and the extent by the margin keeps the answer a superset.

use super::bitset::set_range;

/// The outward margin, in voxel edges, added to every clipping bound and extent: 2⁻²⁰
/// (1e-6) of a voxel edge. Coordinates within ±2³⁰ voxels round by less than 2⁻²² voxels per
/// operation, so a voxel whose cube meets the solid is never missed; a voxel farther than
/// the margin from the solid is never set by it.
pub const MARGIN: f64 = 1.0 / 1048576.0;

/// Lattice dimensions, for clipping and indexing.
#[derive(Clone, Copy)]
pub(crate) struct Dims {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
}

/// `x.floor()` without the library call (the baseline x86-64 has no rounding
/// instruction); exact for |x| < 2⁶³, which the callers' coordinates are.
#[inline]
pub(crate) fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// `x.ceil()`, as [`floor`].
#[inline]
pub(crate) fn ceil(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t < x {
        t + 1.0
    } else {
        t
    }
}

/// First and last voxel (clamped to `[0, n)`) whose closed unit cell meets `[lo, hi]`
/// grown by the margin; `None` if no cell of the lattice does.
#[inline]
fn cells(lo: f64, hi: f64, n: usize) -> Option<(usize, usize)> {
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return None;
    }
    let a = ceil(lo - MARGIN - 1.0).max(0.0);
    let b = floor(hi + MARGIN).min(n as f64 - 1.0);
    if a > b {
        None
    } else {
        Some((a as usize, b as usize))
    }
}

/// A convex polygon of at most 8 vertices (a triangle clipped by two planes has 5).
#[derive(Clone, Copy)]
pub(crate) struct Polygon {
    v: [[f64; 3]; 8],
    n: usize,
}

impl Polygon {
    fn triangle(t: &[[f64; 3]; 3]) -> Polygon {
        let mut v = [[0.0; 3]; 8];
        v[..3].copy_from_slice(t);
        Polygon { v, n: 3 }
    }

    fn vertices(&self) -> &[[f64; 3]] {
        &self.v[..self.n]
    }
}

/// Clips a convex polygon to `lo <= p[axis] <= hi`.
fn clip(poly: &Polygon, axis: usize, lo: f64, hi: f64) -> Polygon {
    let half = |src: &[[f64; 3]], bound: f64, keep_above: bool| {
        let mut out = Polygon {
            v: [[0.0; 3]; 8],
            n: 0,
        };
        for i in 0..src.len() {
            let (p, q) = (src[i], src[(i + 1) % src.len()]);
            let inside = |x: f64| if keep_above { x >= bound } else { x <= bound };
            let (pin, qin) = (inside(p[axis]), inside(q[axis]));
            if pin {
                out.v[out.n] = p;
                out.n += 1;
            }
            if pin != qin {
                let t = (bound - p[axis]) / (q[axis] - p[axis]);
                let mut r = [0.0; 3];
                for a in 0..3 {
                    r[a] = p[a] + t * (q[a] - p[a]);
                }
                r[axis] = bound;
                out.v[out.n] = r;
                out.n += 1;
            }
        }
        out
    };
    let low = half(poly.vertices(), lo, true);
    half(low.vertices(), hi, false)
}

/// x extent of a convex polygon's part with `lo <= y <= hi`; `slopes[i]` is dx/dy of edge
/// i (from vertex i to i + 1), 0 for an edge parallel to x (never crossed).
fn x_extent_in_y_slab(poly: &[[f64; 3]], slopes: &[f64], lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (mut xmin, mut xmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let n = poly.len();
    for i in 0..n {
        let (p, q) = (poly[i], poly[(i + 1) % n]);
        if p[1] >= lo && p[1] <= hi {
            xmin = xmin.min(p[0]);
            xmax = xmax.max(p[0]);
        }
        for bound in [lo, hi] {
            if (p[1] < bound) != (q[1] < bound) {
                let x = p[0] + (bound - p[1]) * slopes[i];
                xmin = xmin.min(x);
                xmax = xmax.max(x);
            }
        }
    }
    (xmin <= xmax).then_some((xmin, xmax))
}

/// Sets every voxel the closed triangle `t` (voxel coordinates) meets.
pub(crate) fn rasterize_triangle(t: &[[f64; 3]; 3], dims: Dims, words: &mut [u64]) {
    let mut lo = t[0];
    let mut hi = t[0];
    for p in &t[1..] {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let Some((k0, k1)) = cells(lo[2], hi[2], dims.nz) else {
        return;
    };
    let Some((j0, j1)) = cells(lo[1], hi[1], dims.ny) else {
        return;
    };
    let Some((i0, i1)) = cells(lo[0], hi[0], dims.nx) else {
        return;
    };
    let row = |j: usize, k: usize| (j + dims.ny * k) * dims.nx;
    // A triangle inside one row: its whole x extent is in the row's slab.
    let single = |lo: f64, hi: f64| floor(lo - MARGIN) == floor(hi + MARGIN);
    if single(lo[1], hi[1]) && single(lo[2], hi[2]) {
        let r = row(j0, k0);
        set_range(words, r + i0, r + i1 + 1);
        return;
    }
    let one_layer = single(lo[2], hi[2]);
    let whole = Polygon::triangle(t);
    for k in k0..=k1 {
        let (zlo, zhi) = (k as f64 - MARGIN, k as f64 + 1.0 + MARGIN);
        let slab = if one_layer {
            whole
        } else {
            clip(&whole, 2, zlo, zhi)
        };
        if slab.n == 0 {
            continue;
        }
        let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in slab.vertices() {
            ylo = ylo.min(p[1]);
            yhi = yhi.max(p[1]);
        }
        let Some((ja, jb)) = cells(ylo, yhi, dims.ny) else {
            continue;
        };
        let poly = slab.vertices();
        let mut slopes = [0.0; 8];
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            if q[1] != p[1] {
                slopes[i] = (q[0] - p[0]) / (q[1] - p[1]);
            }
        }
        for j in ja.max(j0)..=jb.min(j1) {
            let (lo_y, hi_y) = (j as f64 - MARGIN, j as f64 + 1.0 + MARGIN);
            let Some((xlo, xhi)) = x_extent_in_y_slab(poly, &slopes, lo_y, hi_y) else {
                continue;
            };
            if let Some((a, b)) = cells(xlo, xhi, dims.nx) {
                let r = row(j, k);
                set_range(words, r + a, r + b + 1);
            }
        }
    }
}

/// Sets every voxel the closed ball of centre `c` and radius `r` (voxel units) meets.
pub(crate) fn rasterize_sphere(c: [f64; 3], r: f64, dims: Dims, words: &mut [u64]) {
    let Some((k0, k1)) = cells(c[2] - r, c[2] + r, dims.nz) else {
        return;
    };
    let Some((j0, j1)) = cells(c[1] - r, c[1] + r, dims.ny) else {
        return;
    };
    let rm = r + MARGIN;
    for k in k0..=k1 {
        let dz = (k as f64 - c[2]).max(0.0).max(c[2] - (k as f64 + 1.0));
        for j in j0..=j1 {
            let dy = (j as f64 - c[1]).max(0.0).max(c[1] - (j as f64 + 1.0));
            let d2 = dy * dy + dz * dz;
            if d2 > rm * rm {
                continue;
            }
            let half = (rm * rm - d2).sqrt();
            if let Some((a, b)) = cells(c[0] - half, c[0] + half, dims.nx) {
                let row = (j + dims.ny * k) * dims.nx;
                set_range(words, row + a, row + b + 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_floor_and_ceil_agree_with_std() {
        for x in [
            -2.5,
            -2.0,
            -0.0,
            0.0,
            1e-300,
            0.5,
            1.0,
            7.999999999,
            1e15 + 0.5,
            -1e15 - 0.5,
        ] {
            assert_eq!(floor(x), x.floor(), "{x}");
            assert_eq!(ceil(x), x.ceil(), "{x}");
        }
    }

    #[test]
    fn a_triangle_touching_a_cell_corner_sets_every_cell_it_meets() {
        // A tiny triangle around the lattice point (2, 2, 2): all 8 cells around it meet it.
        let dims = Dims {
            nx: 4,
            ny: 4,
            nz: 4,
        };
        let mut w = vec![0u64; 1];
        let t = [
            [2.0, 2.0, 2.0],
            [2.0 + 1e-9, 2.0, 2.0],
            [2.0, 2.0 + 1e-9, 2.0],
        ];
        rasterize_triangle(&t, dims, &mut w);
        let set: Vec<usize> = (0..64).filter(|&b| w[0] >> b & 1 == 1).collect();
        let want: Vec<usize> = (0..64)
            .filter(|&b| {
                (1..=2).contains(&(b % 4))
                    && (1..=2).contains(&(b / 4 % 4))
                    && (1..=2).contains(&(b / 16))
            })
            .collect();
        assert_eq!(set, want);
    }

    #[test]
    fn clipping_keeps_the_part_within_the_bounds() {
        let t = Polygon::triangle(&[[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]]);
        let c = clip(&t, 0, 1.0, 2.0);
        assert_eq!(c.n, 4);
        assert!(c.vertices().iter().all(|p| (1.0..=2.0).contains(&p[0])));
    }
}
