//! The exact solid swept by a translating box (the knife), and signed distances to it: the
//! oracle of the accuracy benchmark and the tests.
//!
//! A box `B` (centre `c0`, rotation `R`, half-extents `e`) translated by `d` sweeps the convex
//! solid `S = B ⊕ [0, d]`. Outside `S`, the distance is `min over s of dist(p - s d, B)`, a
//! convex function of `s` minimised by golden-section search to 1e-12 of `s`. Inside, it is
//! the smallest slack over the facet normals of `S`: the box's face normals and the normals
//! `±(a_i × d)` of the faces the box's edges sweep, with support `h_B(n) + max(0, n · d)`.

use super::math::{cross, dot, norm, scale, sub, Vec3};
use super::Quat;

/// A box translating from `c0` by `d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxSweep {
    /// Centre at the start (m).
    pub c0: Vec3,
    /// Orientation.
    pub rotation: Quat,
    /// Half-extents along the box's axes (m).
    pub half: Vec3,
    /// Translation (m).
    pub d: Vec3,
}

impl BoxSweep {
    fn axes(&self) -> [Vec3; 3] {
        [
            self.rotation.rotate([1.0, 0.0, 0.0]),
            self.rotation.rotate([0.0, 1.0, 0.0]),
            self.rotation.rotate([0.0, 0.0, 1.0]),
        ]
    }

    fn box_distance(&self, ax: &[Vec3; 3], q: Vec3) -> f64 {
        let mut out = 0.0;
        for a in 0..3 {
            let t = dot(ax[a], q).abs() - self.half[a];
            if t > 0.0 {
                out += t * t;
            }
        }
        out.sqrt()
    }

    /// Is `p` in the swept solid (the interval test of
    /// docs/methods/carving.md#what-the-project-does-instead)?
    pub fn contains(&self, p: Vec3) -> bool {
        let ax = self.axes();
        let q = sub(p, self.c0);
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for a in 0..3 {
            let x = dot(ax[a], q);
            let v = dot(ax[a], self.d);
            let e = self.half[a];
            if v.abs() < 1e-300 {
                if x.abs() > e {
                    return false;
                }
            } else {
                let (s1, s2) = ((x - e) / v, (x + e) / v);
                lo = lo.max(s1.min(s2));
                hi = hi.min(s1.max(s2));
            }
        }
        lo <= hi
    }

    /// Signed distance to the swept solid's boundary (negative inside, m).
    pub fn signed_distance(&self, p: Vec3) -> f64 {
        let ax = self.axes();
        let q = sub(p, self.c0);
        if !self.contains(p) {
            let f = |s: f64| self.box_distance(&ax, sub(q, scale(self.d, s)));
            let mid = super::sweep::golden_section_min(f, 60);
            return f(0.0).min(f(1.0)).min(f(mid));
        }
        // Inside: the smallest slack over the facet normals.
        let support = |n: Vec3| -> f64 {
            (0..3)
                .map(|a| self.half[a] * dot(n, ax[a]).abs())
                .sum::<f64>()
                + dot(n, self.d).max(0.0)
        };
        let mut best = f64::INFINITY;
        let mut slack = |n: Vec3| {
            let l = norm(n);
            if l > 1e-12 {
                let n = scale(n, 1.0 / l);
                best = best.min(support(n) - dot(n, q));
            }
        };
        for a in ax {
            slack(a);
            slack(scale(a, -1.0));
            let c = cross(a, self.d);
            slack(c);
            slack(scale(c, -1.0));
        }
        -best.max(0.0)
    }
}

/// Signed distance to an axis-aligned box `[lo, hi]` (exact, m).
pub fn box_signed_distance(lo: Vec3, hi: Vec3, p: Vec3) -> f64 {
    let mut out = 0.0;
    let mut inside = f64::NEG_INFINITY;
    for a in 0..3 {
        let c = (lo[a] + hi[a]) / 2.0;
        let e = (hi[a] - lo[a]) / 2.0;
        let t = (p[a] - c).abs() - e;
        inside = inside.max(t);
        if t > 0.0 {
            out += t * t;
        }
    }
    if inside > 0.0 {
        out.sqrt()
    } else {
        inside
    }
}

/// A solid swept by a box: a union of translation sweeps (one for a translation; many fine
/// ones to stand for a rotating move).
#[derive(Debug, Clone, Default)]
pub struct SweptSolid {
    /// The pieces.
    pub pieces: Vec<BoxSweep>,
}

impl SweptSolid {
    /// Is `p` in the solid?
    pub fn contains(&self, p: Vec3) -> bool {
        self.pieces.iter().any(|s| s.contains(p))
    }

    /// Signed distance: exact outside; inside, the smallest of the pieces' (a lower bound of
    /// the depth for a union).
    pub fn signed_distance(&self, p: Vec3) -> f64 {
        self.pieces
            .iter()
            .map(|s| s.signed_distance(p))
            .fold(f64::INFINITY, f64::min)
    }

    /// Signed distance to the block `[lo, hi]` minus the solid: `max(d_block, -d_solid)`
    /// (exact away from the creases where the cut meets the block's faces).
    pub fn carved_block_distance(&self, lo: Vec3, hi: Vec3, p: Vec3) -> f64 {
        box_signed_distance(lo, hi, p).max(-self.signed_distance(p))
    }
}
