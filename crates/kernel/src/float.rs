//! Floating-point space-time helpers for *measurements* (times, distances, volumes to
//! report). Nothing here decides whether things touch: that is the exact predicates' job.

use super::{LatticePoint, SpaceTimePoint};

/// a − b.
#[inline]
pub fn sub4(a: &SpaceTimePoint, b: &SpaceTimePoint) -> SpaceTimePoint {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
}

/// a · b.
#[inline]
pub fn dot4(a: &SpaceTimePoint, b: &SpaceTimePoint) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// det of the 4x4 matrix with rows a, b, c, d.
#[inline]
pub fn det4(a: &SpaceTimePoint, b: &SpaceTimePoint, c: &SpaceTimePoint, d: &SpaceTimePoint) -> f64 {
    let s = |i: usize, j: usize| c[i] * d[j] - c[j] * d[i];
    let t = |i: usize, j: usize| a[i] * b[j] - a[j] * b[i];
    t(0, 1) * s(2, 3) - t(0, 2) * s(1, 3) + t(0, 3) * s(1, 2) + t(1, 2) * s(0, 3)
        - t(1, 3) * s(0, 2)
        + t(2, 3) * s(0, 1)
}

/// N with N·x = det[u, v, w, x] (the generalised cross product).
#[inline]
pub fn cross4(u: &SpaceTimePoint, v: &SpaceTimePoint, w: &SpaceTimePoint) -> SpaceTimePoint {
    [0, 1, 2, 3].map(|k| {
        let mut e = [0.0; 4];
        e[k] = 1.0;
        det4(u, v, w, &e)
    })
}

/// A lattice point as floats.
#[inline]
pub fn to_f64(p: &LatticePoint) -> SpaceTimePoint {
    p.map(f64::from)
}

/// The normal N = cross4(b−a, c−a, d−a) of a lattice tet (outward for the mesh's
/// orientation convention), as floats.
pub fn tet_normal(t: &[LatticePoint; 4]) -> SpaceTimePoint {
    let a = to_f64(&t[0]);
    let d = |q: &LatticePoint| sub4(&to_f64(q), &a);
    cross4(&d(&t[1]), &d(&t[2]), &d(&t[3]))
}
