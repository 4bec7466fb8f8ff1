//! Reference marginals of the uniform (area) measure on an implicit surface `F = 0` in R^3
//! inside its walls, by a quadrature that owes nothing to the walk: the benchmark's yardstick
//! for figures without a closed form (the seed's Figs. 1 and 2).
//!
//! The surface is triangulated by marching tetrahedra on a grid of spacing `h` (each cube
//! cut into the 6 tetrahedra of Freudenthal's triangulation along its main diagonal,
//! which agree on shared faces); each triangle's vertices are the roots of F on the tet's
//! edges (regula falsi, to 1e-12 of the edge), so they lie on the surface. Each triangle is
//! then cut into 16, the new vertices projected onto the surface (Gauss-Newton), so that the
//! flat pieces sag below a curved surface by about (h/4)²κ/8 rather than h²κ/8. Triangles
//! that straddle a wall are cut into four, five times over, and the pieces kept by their
//! centroids. A uniform point
//! of a flat triangle has, along each axis, a tent-shaped density from the smallest vertex
//! coordinate to the largest; its exact CDF is added, weighted by the triangle's area,
//! into fine bins, whose running sum is the marginal CDF.
//!
//! How close this comes is measured, not assumed: the benchmark runs it on the sphere and
//! the torus, whose marginals are exact ([`super::exact`]), with the same spacing relative
//! to the features, and reports the difference (docs/sampler-error.md).

use super::exact::TabulatedCdf;
use super::field::Q;
use super::figure::Figure;
use super::SamplerError;

/// Most grid cells of one quadrature (4·10^8: a few seconds and 2 layers of nodes in memory).
pub const MAX_CELLS: u64 = 400_000_000;
/// Times a triangle that straddles a wall is cut into four.
const CLIP_DEPTH: u32 = 5;
/// Times each triangle is cut into four with the new vertices projected onto the surface:
/// each time the flat pieces sag below the surface four times less.
const REFINE: u32 = 2;

/// The marginal CDFs of x, y and z of the uniform measure on a surface.
#[derive(Debug, Clone)]
pub struct SurfaceMarginals {
    /// Area of the surface inside the walls (m²).
    pub area: f64,
    /// Triangles of the triangulation (before clipping).
    pub triangles: usize,
    /// CDF of x, y and z, tabulated at the bin edges.
    pub cdf: [TabulatedCdf; 3],
}

/// The marginals of `fig` (N = 3, M = 1) in the box `[lo, hi]`, on a grid of spacing about
/// `h`, tabulated on `bins` bins per axis.
///
/// # Errors
/// [`SamplerError::BadFigure`] for a figure that is not one surface in R^3, a box that is
/// empty or not finite, a spacing that is not positive, more than [`MAX_CELLS`] cells, or
/// a surface with no area inside the walls.
pub fn surface_marginals(
    fig: &Figure,
    lo: [f64; 3],
    hi: [f64; 3],
    h: f64,
    bins: usize,
) -> Result<SurfaceMarginals, SamplerError> {
    let bad = |s: String| Err(SamplerError::BadFigure(s));
    if fig.dim() != 3 || fig.constraints() != 1 {
        return bad(format!(
            "reference marginals need one surface in R^3, not {} constraints in R^{}",
            fig.constraints(),
            fig.dim()
        ));
    }
    if !(h > 0.0 && h.is_finite())
        || (0..3).any(|i| !(lo[i] < hi[i] && (hi[i] - lo[i]).is_finite()))
    {
        return bad(format!(
            "reference marginals: box {lo:?}..{hi:?} with spacing {h}"
        ));
    }
    let cells: [usize; 3] = std::array::from_fn(|i| ((hi[i] - lo[i]) / h).ceil().max(1.0) as usize);
    let total = cells.iter().map(|&c| c as u64).product::<u64>();
    if total > MAX_CELLS {
        return bad(format!(
            "reference marginals: {total} grid cells, more than {MAX_CELLS}: use a larger spacing"
        ));
    }
    let step: [f64; 3] = std::array::from_fn(|i| (hi[i] - lo[i]) / cells[i] as f64);
    let bins = bins.max(16);
    let mut acc = Accumulator {
        fig,
        lo,
        hi,
        bins,
        mass: vec![vec![0.0; bins]; 3],
        area: 0.0,
        evals: 0,
    };
    let (nx, ny) = (cells[0] + 1, cells[1] + 1);
    let node = |i: usize, j: usize, k: usize| -> Q {
        [
            lo[0] + i as f64 * step[0],
            lo[1] + j as f64 * step[1],
            lo[2] + k as f64 * step[2],
            0.0,
        ]
    };
    let layer = |k: usize, acc: &mut Accumulator| -> Vec<f64> {
        let mut v = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                v.push(acc.value(&node(i, j, k)));
            }
        }
        v
    };
    // The 6 tets of a cube: from corner 0 to corner 7 along the axes in each order.
    const ORDERS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut triangles = 0usize;
    let mut below = layer(0, &mut acc);
    for k in 0..cells[2] {
        let above = layer(k + 1, &mut acc);
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                let corner = |c: [usize; 3]| -> (Q, f64) {
                    let (ii, jj) = (i + c[0], j + c[1]);
                    let v = if c[2] == 0 { &below } else { &above };
                    (node(ii, jj, k + c[2]), v[ii + nx * jj])
                };
                // Skip cubes whose 8 corners have one sign.
                let mut neg = 0;
                for c in 0..8 {
                    if corner([c & 1, (c >> 1) & 1, c >> 2]).1 < 0.0 {
                        neg += 1;
                    }
                }
                if neg == 0 || neg == 8 {
                    continue;
                }
                for order in ORDERS {
                    let mut c = [0usize; 3];
                    let mut tet = [([0.0; 4], 0.0); 4];
                    tet[0] = corner(c);
                    for (v, &axis) in order.iter().enumerate() {
                        c[axis] = 1;
                        tet[v + 1] = corner(c);
                    }
                    triangles += acc.tet(&tet);
                }
            }
        }
        below = above;
    }
    if !(acc.area > 0.0) {
        return bad(
            "reference marginals: the surface has no area inside the walls and the box".into(),
        );
    }
    let area = acc.area;
    let cdf = std::array::from_fn(|axis| {
        let mut values = Vec::with_capacity(bins + 1);
        let mut run = 0.0;
        values.push(0.0);
        for m in &acc.mass[axis] {
            run += m;
            values.push((run / area).clamp(0.0, 1.0));
        }
        TabulatedCdf {
            lo: lo[axis],
            hi: hi[axis],
            values,
        }
    });
    Ok(SurfaceMarginals {
        area,
        triangles,
        cdf,
    })
}

struct Accumulator<'a> {
    fig: &'a Figure,
    lo: [f64; 3],
    hi: [f64; 3],
    bins: usize,
    mass: Vec<Vec<f64>>,
    area: f64,
    evals: u64,
}

impl Accumulator<'_> {
    fn value(&mut self, q: &Q) -> f64 {
        self.fig.local(q, &mut self.evals).f[0]
    }

    /// The root of F on the edge from `a` to `b` (values of opposite signs).
    fn root(&mut self, a: (Q, f64), b: (Q, f64)) -> [f64; 3] {
        let at = |u: f64| -> Q { std::array::from_fn(|i| a.0[i] + u * (b.0[i] - a.0[i])) };
        let (mut u0, mut f0, mut u1, mut f1) = (0.0, a.1, 1.0, b.1);
        let mut side = 0;
        for _ in 0..60 {
            if !(u1 - u0 > 1e-12) {
                break;
            }
            // Regula falsi with the Illinois modification (halve the value kept twice).
            let u = if f1 != f0 {
                (u0 - f0 * (u1 - u0) / (f1 - f0)).clamp(u0, u1)
            } else {
                0.5 * (u0 + u1)
            };
            let f = self.value(&at(u));
            if f == 0.0 {
                u0 = u;
                u1 = u;
                break;
            }
            if (f < 0.0) == (f0 < 0.0) {
                u0 = u;
                f0 = f;
                if side == -1 {
                    f1 *= 0.5;
                }
                side = -1;
            } else {
                u1 = u;
                f1 = f;
                if side == 1 {
                    f0 *= 0.5;
                }
                side = 1;
            }
        }
        let q = at(0.5 * (u0 + u1));
        [q[0], q[1], q[2]]
    }

    /// The piece of surface in one tet (0, 1 or 2 triangles); returns how many.
    fn tet(&mut self, t: &[(Q, f64); 4]) -> usize {
        let inside: Vec<usize> = (0..4).filter(|&v| t[v].1 < 0.0).collect();
        let outside: Vec<usize> = (0..4).filter(|&v| t[v].1 >= 0.0).collect();
        match (inside.len(), outside.len()) {
            (1, 3) | (3, 1) => {
                let (lone, rest) = if inside.len() == 1 {
                    (inside[0], outside)
                } else {
                    (outside[0], inside)
                };
                let p: Vec<[f64; 3]> = rest.iter().map(|&o| self.root(t[lone], t[o])).collect();
                self.refined([p[0], p[1], p[2]], REFINE);
                1
            }
            (2, 2) => {
                let (a, b, c, d) = (inside[0], inside[1], outside[0], outside[1]);
                let ac = self.root(t[a], t[c]);
                let ad = self.root(t[a], t[d]);
                let bd = self.root(t[b], t[d]);
                let bc = self.root(t[b], t[c]);
                self.refined([ac, ad, bd], REFINE);
                self.refined([ac, bd, bc], REFINE);
                2
            }
            _ => 0,
        }
    }

    /// Cuts a triangle with vertices on the surface into four, `level` times over, the
    /// edge midpoints projected onto the surface (kept flat where the projection fails).
    fn refined(&mut self, p: [[f64; 3]; 3], level: u32) {
        if level == 0 {
            self.triangle(p, 0);
            return;
        }
        let mut mid = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] {
            let m = [
                0.5 * (a[0] + b[0]),
                0.5 * (a[1] + b[1]),
                0.5 * (a[2] + b[2]),
                0.0,
            ];
            let len =
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            match self
                .fig
                .pull_onto(m, 1e-13 * (1.0 + len), 20, len, &mut self.evals)
            {
                Some(q) => [q[0], q[1], q[2]],
                None => [m[0], m[1], m[2]],
            }
        };
        let (m01, m12, m20) = (mid(p[0], p[1]), mid(p[1], p[2]), mid(p[2], p[0]));
        self.refined([p[0], m01, m20], level - 1);
        self.refined([m01, p[1], m12], level - 1);
        self.refined([m20, m12, p[2]], level - 1);
        self.refined([m01, m12, m20], level - 1);
    }

    /// Adds a flat triangle, clipped to the walls by subdivision.
    fn triangle(&mut self, p: [[f64; 3]; 3], depth: u32) {
        let admitted = p.map(|v| self.fig.admits(&[v[0], v[1], v[2], 0.0]));
        if admitted.iter().all(|&a| !a) {
            return;
        }
        if !admitted.iter().all(|&a| a) {
            if depth < CLIP_DEPTH {
                let mid = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] {
                    std::array::from_fn(|i| 0.5 * (a[i] + b[i]))
                };
                let (m01, m12, m20) = (mid(p[0], p[1]), mid(p[1], p[2]), mid(p[2], p[0]));
                self.triangle([p[0], m01, m20], depth + 1);
                self.triangle([m01, p[1], m12], depth + 1);
                self.triangle([m20, m12, p[2]], depth + 1);
                self.triangle([m01, m12, m20], depth + 1);
                return;
            }
            let c: [f64; 3] = std::array::from_fn(|i| (p[0][i] + p[1][i] + p[2][i]) / 3.0);
            if !self.fig.admits(&[c[0], c[1], c[2], 0.0]) {
                return;
            }
        }
        let e1: [f64; 3] = std::array::from_fn(|i| p[1][i] - p[0][i]);
        let e2: [f64; 3] = std::array::from_fn(|i| p[2][i] - p[0][i]);
        let cr = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let area = 0.5 * (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
        if !(area > 0.0) {
            return;
        }
        self.area += area;
        for axis in 0..3 {
            let mut v = [p[0][axis], p[1][axis], p[2][axis]];
            v.sort_by(f64::total_cmp);
            self.add_tent(axis, v, area);
        }
    }

    /// Adds `area` spread along `axis` with the tent density of a triangle whose vertex
    /// coordinates are `v` (sorted).
    fn add_tent(&mut self, axis: usize, v: [f64; 3], area: f64) {
        let (lo, hi, n) = (self.lo[axis], self.hi[axis], self.bins);
        let w = (hi - lo) / n as f64;
        let bin = |x: f64| (((x - lo) / w).floor().max(0.0) as usize).min(n - 1);
        let (b0, b1) = (bin(v[0]), bin(v[2]));
        let mass = &mut self.mass[axis];
        if b0 == b1 {
            mass[b0] += area;
            return;
        }
        let mut prev = 0.0;
        for b in b0..b1 {
            let g = tent_cdf(v, lo + (b + 1) as f64 * w);
            mass[b] += area * (g - prev);
            prev = g;
        }
        mass[b1] += area * (1.0 - prev);
    }
}

/// CDF at `s` of the projection of a uniform point of a triangle whose vertex coordinates
/// are `a ≤ b ≤ c`: the density rises linearly from a to b and falls to c.
fn tent_cdf([a, b, c]: [f64; 3], s: f64) -> f64 {
    if s <= a {
        0.0
    } else if s >= c {
        1.0
    } else if s <= b {
        (s - a).powi(2) / ((c - a) * (b - a))
    } else {
        1.0 - (c - s).powi(2) / ((c - a) * (c - b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact::{sphere_coordinate_cdf, TorusTheta};
    use crate::{Body, Shape, ShapeAxis, Wall};
    use std::sync::Arc;

    #[test]
    fn the_tent_is_a_cdf() {
        let v = [0.0, 0.3, 1.0];
        assert_eq!(tent_cdf(v, -1.0), 0.0);
        assert_eq!(tent_cdf(v, 2.0), 1.0);
        // Continuous at the middle vertex: the mass left of b is (b - a)/(c - a).
        assert!((tent_cdf(v, 0.3) - 0.3).abs() < 1e-15);
        assert!((tent_cdf(v, 0.3 + 1e-12) - 0.3).abs() < 1e-9);
    }

    #[test]
    fn sphere_and_torus_marginals_come_out_exact_to_a_thousandth() {
        let (c, r) = ([0.3, -0.2, 0.1], 0.7);
        let fig = Figure::new(
            3,
            vec![Arc::new(Body::fixed(Shape::Sphere {
                centre: c,
                radius: r,
            }))],
        )
        .unwrap();
        let m = surface_marginals(
            &fig,
            [c[0] - 0.8, c[1] - 0.8, c[2] - 0.8],
            [c[0] + 0.8, c[1] + 0.8, c[2] + 0.8],
            0.05,
            1024,
        )
        .unwrap();
        let exact_area = 4.0 * std::f64::consts::PI * r * r;
        assert!(
            (m.area / exact_area - 1.0).abs() < 5e-3,
            "{} vs {exact_area}",
            m.area
        );
        for i in 0..3 {
            let d = m.cdf[i].max_difference(sphere_coordinate_cdf(c[i], r), 2000);
            assert!(d < 1e-3, "axis {i}: {d}");
        }
        let torus = Body::fixed(Shape::Torus {
            centre: [0.0; 3],
            axis: ShapeAxis::Z,
            major: 1.0,
            minor: 0.4,
        });
        let fig = Figure::new(3, vec![Arc::new(torus)]).unwrap();
        // The z-marginal is the arcsine law, whose CDF has square-root edges at z = ±r: a
        // linear interpolation inside one bin there is off by about sqrt(2·bin/r)/π · 0.3,
        // so this check needs narrow bins (8192 over 1 m: 2e-3).
        let m = surface_marginals(&fig, [-1.5, -1.5, -0.5], [1.5, 1.5, 0.5], 0.05, 8192).unwrap();
        let t = TorusTheta {
            major: 1.0,
            minor: 0.4,
        };
        let across = t.across_cdf(2000);
        let dx = m.cdf[0].max_difference(|x| across.eval(x), 2000);
        let dz = m.cdf[2].max_difference(|z| t.axial_cdf(z), 2000);
        assert!(dx < 1e-3, "{dx}");
        assert!(dz < 3e-3, "{dz}");
    }

    #[test]
    fn walls_cut_the_surface() {
        // A unit sphere cut by the box z ≥ 0.5 keeps the cap of height 0.5: a quarter of the
        // area (Archimedes), with z uniform on [0.5, 1].
        let fig = Figure::new(
            3,
            vec![Arc::new(Body::fixed(Shape::Sphere {
                centre: [0.0; 3],
                radius: 1.0,
            }))],
        )
        .unwrap()
        .wall(Wall::Box {
            min: [-2.0, -2.0, 0.5, 0.0],
            max: [2.0, 2.0, 2.0, 0.0],
        })
        .unwrap();
        let m = surface_marginals(&fig, [-1.1; 3], [1.1; 3], 0.05, 1024).unwrap();
        assert!(
            (m.area / std::f64::consts::PI - 1.0).abs() < 5e-3,
            "{}",
            m.area
        );
        let d = m.cdf[2].max_difference(|z| ((z - 0.5) / 0.5).clamp(0.0, 1.0), 2000);
        assert!(d < 3e-3, "{d}");
        assert!(surface_marginals(&fig, [0.0; 3], [0.0; 3], 0.1, 10).is_err());
    }
}
