//! Separating-axis tests for two tets in R^4 (DESIGN §4), exact, for any input.
//!
//! Let D = A − B = conv{a − b} (a Minkowski difference). The closed tets meet iff
//! 0 ∈ D, and their relative interiors meet iff 0 ∈ relint D (Rockafellar, Convex
//! Analysis, Cor. 6.6.2: ri(A − B) = ri A − ri B). When D spans R^4 every facet of D is
//! F_A − F_B for faces F_A of A and F_B of B whose directions span a 3-space, and its
//! normal is cross3 of three edge vectors: three of A (A's hyperplane normal), three of B,
//! a triangle of A and an edge of B, or an edge of A and a triangle of B: the 50 axes
//! 1 + 1 + 24 + 24. Hence, for full-dimensional D:
//!
//! - 0 ∈ D iff on every nonzero axis n the intervals n·A and n·B overlap (closed test);
//! - 0 ∈ int D iff on every nonzero axis they overlap in an interval of positive length
//!   (strict test). Extra axes that are not facet normals never give a wrong answer.
//!
//! When D is flat (A, B in parallel or equal hyperplanes, or a flat tet) the test first
//! checks that the affine hull of D contains 0, then drops a coordinate along which the
//! projection is injective on that hull (so it preserves both membership and relative
//! interior) and repeats in R^3, R^2, R^1 with the same axis families one dimension
//! down (in R^3: 4 + 4 triangle normals and 36 edge×edge normals; in R^2: edge normals).
//! All arithmetic is exact (see the [module notes](super)).

use super::{cross3, dot4, rel_tet, sub4, Exact, LatticeTet, TET_EDGES, TET_TRIANGLES, V4};

/// Whether the closed tets `a` and `b` have a common point (touching counts).
///
/// Exact for every input, including flat tets and tets in one hyperplane; never panics.
///
/// ```
/// use chronotope_kernel::intersect::tets_intersect;
/// let a = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
/// let b = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]]; // shares a face
/// let c = [[2, 0, 0, 0], [3, 0, 0, 0], [2, 1, 0, 0], [2, 0, 0, 1]];
/// assert!(tets_intersect(&a, &b));
/// assert!(!tets_intersect(&a, &c));
/// ```
pub fn tets_intersect(a: &LatticeTet, b: &LatticeTet) -> bool {
    let points = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
    with_exact_width!(&points, difference_contains_origin_at(a, b, false))
}

/// Whether the relative interiors of `a` and `b` meet: the points with all four
/// barycentric coordinates strictly positive, in both tets.
///
/// For tets in different hyperplanes this is [`tets_cross`](super::tets_cross) (a
/// positive-area crossing); for tets in one hyperplane it is an overlap of positive
/// 3-volume; for a flat tet it is the relative interior of its convex hull. Exact for
/// every input; never panics.
///
/// ```
/// use chronotope_kernel::intersect::relative_interiors_meet;
/// let a = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
/// let b = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]];
/// assert!(!relative_interiors_meet(&a, &b)); // only a common face
/// assert!(relative_interiors_meet(&a, &a));
/// ```
pub fn relative_interiors_meet(a: &LatticeTet, b: &LatticeTet) -> bool {
    let points = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
    with_exact_width!(&points, difference_contains_origin_at(a, b, true))
}

fn difference_contains_origin_at<T: Exact>(a: &LatticeTet, b: &LatticeTet, strict: bool) -> bool {
    let o = a[0];
    difference_contains_origin(&rel_tet::<T>(a, &o), &rel_tet::<T>(b, &o), 4, strict)
}

/// Whether 0 ∈ A − B (`strict`: 0 ∈ relint(A − B)) for tets whose coordinates beyond
/// the first `d` are zero.
pub(super) fn difference_contains_origin<T: Exact>(
    a: &[V4<T>; 4],
    b: &[V4<T>; 4],
    d: usize,
    strict: bool,
) -> bool {
    if d == 0 {
        return true;
    }
    // Directions of A − B, and one point of it (the last vector).
    let vs = [
        sub4(&a[1], &a[0]),
        sub4(&a[2], &a[0]),
        sub4(&a[3], &a[0]),
        sub4(&b[1], &b[0]),
        sub4(&b[2], &b[0]),
        sub4(&b[3], &b[0]),
        sub4(&a[0], &b[0]),
    ];
    let r = rank(&vs[..6], d);
    if r == d {
        return separating_axes(a, b, d, strict);
    }
    if rank(&vs, d) > r {
        // 0 is not in the affine hull of A − B: the affine hulls of A and B do not meet.
        return false;
    }
    for k in 0..d {
        let projected = [0, 1, 2, 3, 4, 5].map(|i| drop_coordinate(&vs[i], k));
        if rank(&projected, d - 1) == r {
            let pa = a.map(|p| drop_coordinate(&p, k));
            let pb = b.map(|p| drop_coordinate(&p, k));
            return difference_contains_origin(&pa, &pb, d - 1, strict);
        }
    }
    // Unreachable: a proper subspace misses some coordinate axis.
    false
}

/// The separating-axis test proper, valid when A − B spans R^d: no nonzero axis
/// separates (`strict`: none separates or makes the intervals touch).
pub(super) fn separating_axes<T: Exact>(
    a: &[V4<T>; 4],
    b: &[V4<T>; 4],
    d: usize,
    strict: bool,
) -> bool {
    if d == 4 {
        return separating_axes_4d(a, b, strict);
    }
    if d == 0 || d > 4 {
        return true;
    }
    let verdict = separating_axes_low(a, b, d, strict);
    if strict {
        verdict.interiors_meet
    } else {
        verdict.meet
    }
}

/// Both verdicts of the separating-axis test in R^d (d < 4) from one pass over the axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct SatVerdict {
    /// No axis separates: the closed sets meet.
    pub(super) meet: bool,
    /// No axis separates or makes the intervals touch: the interiors meet.
    pub(super) interiors_meet: bool,
}

/// [`separating_axes`] for d < 4, closed and strict at once: each axis's intervals are
/// computed once. With `strict_only` the walk stops at the first axis that separates or
/// touches (then `meet` is not decided and reads `true`). Axis families: i edge vectors from an i-face of A and d−1−i from a face
/// of B; the faces' own normals (A's, then B's) come first, since they separate most
/// pairs that are apart, then the mixed ones.
pub(super) fn separating_axes_low<T: Exact>(
    a: &[V4<T>; 4],
    b: &[V4<T>; 4],
    d: usize,
    strict_only: bool,
) -> SatVerdict {
    let mut out = SatVerdict {
        meet: true,
        interiors_meet: true,
    };
    if d == 0 || d >= 4 {
        return out;
    }
    let zero = [T::ZERO; 4];
    // R^3: A's triangles, B's triangles, edge × edge; R^2: A's edges, B's edges; R^1: x.
    let families: &[usize] = match d {
        3 => &[2, 0, 1],
        2 => &[1, 0],
        _ => &[0],
    };
    for &i in families {
        let j = d - 1 - i;
        for fa in 0..face_count(i) {
            for fb in 0..face_count(j) {
                let mut vs = [zero; 3];
                let na = face_vectors(a, i, fa, &mut vs[..i]);
                let nb = face_vectors(b, j, fb, &mut vs[na..na + j]);
                debug_assert_eq!(na + nb, d - 1);
                let n = generalized_cross(&vs[..d - 1], d);
                if is_zero(&n) {
                    continue;
                }
                let ((lo_a, hi_a), (lo_b, hi_b)) = (interval(&n, a), interval(&n, b));
                if hi_a < lo_b || hi_b < lo_a {
                    return SatVerdict {
                        meet: false,
                        interiors_meet: false,
                    };
                }
                if hi_a == lo_b || hi_b == lo_a {
                    out.interiors_meet = false;
                    if strict_only {
                        return out;
                    }
                }
            }
        }
    }
    out
}

/// [`separating_axes`] in R^4, with the edge vectors and each triangle's 2x2 minors
/// computed once: A's normal, B's normal, then the 24 + 24 triangle × edge axes.
fn separating_axes_4d<T: Exact>(a: &[V4<T>; 4], b: &[V4<T>; 4], strict: bool) -> bool {
    let edges = |t: &[V4<T>; 4]| TET_EDGES.map(|[i, j]| sub4(&t[j], &t[i]));
    let (ea, eb) = (edges(a), edges(b));
    // Edges 0, 1, 2 are v1−v0, v2−v0, v3−v0.
    let na = cross3(&ea[0], &ea[1], &ea[2]);
    let nb = cross3(&eb[0], &eb[1], &eb[2]);
    for n in [na, nb] {
        if !is_zero(&n) && separates(&n, a, b, strict) {
            return false;
        }
    }
    for (tris, edges_other) in [(a, &eb), (b, &ea)] {
        for [x, y, z] in TET_TRIANGLES {
            let (u, v) = (sub4(&tris[y], &tris[x]), sub4(&tris[z], &tris[x]));
            let m = |i: usize, j: usize| u[i] * v[j] - u[j] * v[i];
            let m = [m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3)];
            for w in edges_other {
                // cross3(u, v, w) from the minors (see `cross3`); for a triangle of B
                // against an edge of A this is cross3(edge, u, v) (a cyclic shift).
                let d3 = |i: usize, j: usize, k: usize, mjk: T, mik: T, mij: T| {
                    w[i] * mjk - w[j] * mik + w[k] * mij
                };
                let n = [
                    -d3(1, 2, 3, m[5], m[4], m[3]),
                    d3(0, 2, 3, m[5], m[2], m[1]),
                    -d3(0, 1, 3, m[4], m[2], m[0]),
                    d3(0, 1, 2, m[3], m[1], m[0]),
                ];
                if !is_zero(&n) && separates(&n, a, b, strict) {
                    return false;
                }
            }
        }
    }
    true
}

fn is_zero<T: Exact>(n: &V4<T>) -> bool {
    n.iter().all(|&c| c == T::ZERO)
}

/// Whether axis `n` separates A and B (`strict`: or makes their intervals touch).
fn separates<T: Exact>(n: &V4<T>, a: &[V4<T>; 4], b: &[V4<T>; 4], strict: bool) -> bool {
    let (lo_a, hi_a) = interval(n, a);
    let (lo_b, hi_b) = interval(n, b);
    if strict {
        hi_a <= lo_b || hi_b <= lo_a
    } else {
        hi_a < lo_b || hi_b < lo_a
    }
}

/// min and max of n·x over the tet's vertices.
fn interval<T: Exact>(n: &V4<T>, t: &[V4<T>; 4]) -> (T, T) {
    let v = t.map(|x| dot4(n, &x));
    let lo = v[0].min(v[1]).min(v[2].min(v[3]));
    let hi = v[0].max(v[1]).max(v[2].max(v[3]));
    (lo, hi)
}

/// Number of faces of a tet of dimension `dim` used to build axes (a vertex contributes
/// no vector, so one stands for all four).
fn face_count(dim: usize) -> usize {
    match dim {
        0 => 1,
        1 => 6,
        2 => 4,
        3 => 1,
        _ => 0,
    }
}

/// Writes the `dim` edge vectors of face `idx` of dimension `dim` into `out`; returns `dim`.
fn face_vectors<T: Exact>(t: &[V4<T>; 4], dim: usize, idx: usize, out: &mut [V4<T>]) -> usize {
    match dim {
        1 => {
            let [i, j] = TET_EDGES[idx];
            out[0] = sub4(&t[j], &t[i]);
        }
        2 => {
            let [x, y, z] = TET_TRIANGLES[idx];
            out[0] = sub4(&t[y], &t[x]);
            out[1] = sub4(&t[z], &t[x]);
        }
        3 => {
            out[0] = sub4(&t[1], &t[0]);
            out[1] = sub4(&t[2], &t[0]);
            out[2] = sub4(&t[3], &t[0]);
        }
        _ => {}
    }
    dim
}

/// The vector n of R^d (coordinates ≥ d zero) with n·x = det[v_1, …, v_{d−1}, x].
fn generalized_cross<T: Exact>(vs: &[V4<T>], d: usize) -> V4<T> {
    let z = T::ZERO;
    match d {
        4 => cross3(&vs[0], &vs[1], &vs[2]),
        3 => {
            let (u, v) = (&vs[0], &vs[1]);
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
                z,
            ]
        }
        2 => [-vs[0][1], vs[0][0], z, z],
        1 => [T::from_i64(1), z, z, z],
        _ => [z; 4],
    }
}

/// `p` without coordinate `k` (the later ones move down; the last becomes 0).
pub(super) fn drop_coordinate<T: Exact>(p: &V4<T>, k: usize) -> V4<T> {
    let mut out = [T::ZERO; 4];
    let mut m = 0;
    for (i, &c) in p.iter().enumerate() {
        if i != k {
            out[m] = c;
            m += 1;
        }
    }
    out
}

/// Rank of `vs` restricted to the first `d` coordinates, by exact minors (largest first).
fn rank<T: Exact>(vs: &[V4<T>], d: usize) -> usize {
    let n = vs.len();
    for k in (1..=d.min(n)).rev() {
        for rows in 0u32..(1 << n) {
            if rows.count_ones() as usize != k {
                continue;
            }
            for cols in 0u32..(1 << d) {
                if cols.count_ones() as usize != k {
                    continue;
                }
                let r = bits(rows);
                let c = bits(cols);
                if minor(vs, &r.0[..r.1], &c.0[..c.1]) != T::ZERO {
                    return k;
                }
            }
        }
    }
    0
}

/// Indices of the set bits of `mask` (at most 8 bits used here).
fn bits(mask: u32) -> ([usize; 8], usize) {
    let mut out = [0; 8];
    let mut n = 0;
    for i in 0..8 {
        if mask & (1 << i) != 0 {
            out[n] = i;
            n += 1;
        }
    }
    (out, n)
}

/// The minor of `vs` on `rows` × `cols` (equal lengths ≤ 4), by Laplace expansion.
fn minor<T: Exact>(vs: &[V4<T>], rows: &[usize], cols: &[usize]) -> T {
    match rows.len() {
        0 => T::from_i64(1),
        1 => vs[rows[0]][cols[0]],
        len => {
            let mut sum = T::ZERO;
            for c in 0..len {
                let mut rest = [0usize; 4];
                let mut m = 0;
                for (cc, &col) in cols.iter().enumerate() {
                    if cc != c {
                        rest[m] = col;
                        m += 1;
                    }
                }
                let term = vs[rows[0]][cols[c]] * minor(vs, &rows[1..], &rest[..m]);
                sum = if c % 2 == 0 { sum + term } else { sum - term };
            }
            sum
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{det4, rel};
    use super::*;

    #[test]
    fn fifty_axes_in_four_dimensions() {
        let t = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
        let mut count = 0;
        for i in [3, 0, 1, 2] {
            count += face_count(i) * face_count(3 - i);
        }
        assert_eq!(count, 50);
        // B above A's hyperplane (parallel): the reduction to R^3 is taken.
        let b = t.map(|p| [p[0], p[1], p[2], p[3] + 1]);
        assert!(!tets_intersect(&t, &b));
    }

    #[test]
    fn rank_and_minors() {
        let o = [0; 4];
        let v =
            [[1, 2, 3, 4], [2, 4, 6, 8], [0, 1, 0, 0], [0, 0, 0, 0]].map(|p| rel::<i64>(&p, &o));
        assert_eq!(rank(&v, 4), 2);
        assert_eq!(rank(&v[..1], 4), 1);
        assert_eq!(rank(&v[3..], 4), 0);
        let w =
            [[1, 2, 3, 4], [0, 1, 5, 2], [7, 0, 1, 1], [2, 2, 0, 9]].map(|p| rel::<i64>(&p, &o));
        assert_eq!(
            minor(&w, &[0, 1, 2, 3], &[0, 1, 2, 3]),
            det4(&w[0], &w[1], &w[2], &w[3])
        );
        assert_eq!(rank(&w, 4), 4);
        assert_eq!(rank(&w, 2), 2);
    }

    #[test]
    fn flat_and_coplanar_inputs() {
        let a = [[0, 0, 0, 0], [2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0]];
        // Same hyperplane, disjoint within it: the 4D axes alone cannot see this.
        let b = [[3, 3, 3, 0], [4, 3, 3, 0], [3, 4, 3, 0], [3, 3, 4, 0]];
        assert!(!tets_intersect(&a, &b));
        // Same hyperplane, overlapping.
        let c = [[1, 0, 0, 0], [3, 0, 0, 0], [1, 2, 0, 0], [1, 0, 2, 0]];
        assert!(tets_intersect(&a, &c) && relative_interiors_meet(&a, &c));
        // A flat tet (a segment, repeated) through the middle of a.
        let seg = [[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]];
        assert!(tets_intersect(&a, &seg) && !relative_interiors_meet(&a, &seg));
        let pierce = [[0, 0, 0, 0], [0, 0, 0, 0], [1, 1, 1, 1], [1, 1, 1, -1]];
        assert!(tets_intersect(&a, &pierce));
        // Points.
        let p = [[1, 1, 0, 0]; 4];
        assert!(
            tets_intersect(&a, &p) && tets_intersect(&p, &p) && relative_interiors_meet(&p, &p)
        );
        assert!(!tets_intersect(&p, &[[1, 1, 0, 1]; 4]));
    }
}
