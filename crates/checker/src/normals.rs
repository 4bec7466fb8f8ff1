//! Tets as lattice points, and their exact 4D normals and sides: what the walk's predicates
//! are built from.

use super::*;

#[inline]
pub(crate) fn tet_of(m: &TetMesh, i: u32) -> [LatticePoint; 4] {
    m.tets[i as usize].map(|v| m.vertices[v as usize])
}

pub(crate) fn t_range(t: &[LatticePoint; 4]) -> (f64, f64) {
    let ts = t.map(|p| p[3]);
    (
        f64::from(*ts.iter().min().expect("4")),
        f64::from(*ts.iter().max().expect("4")),
    )
}

/// Marks a tet normal that does not fit `i32` (the exact predicate decides alone).
pub const NO_NORMAL: [i32; 4] = [i32::MIN; 4];

/// A normal of each tet's hyperplane: N_k = (−1)^k det of the edge vectors without
/// coordinate k (zero for a flat tet), or [`NO_NORMAL`].
#[cfg(test)]
pub(super) fn tet_normals(m: &TetMesh) -> Vec<[i32; 4]> {
    m.tets
        .iter()
        .map(|t| tet_normal(t.map(|v| m.vertices[v as usize])))
        .collect()
}

/// A normal of the hyperplane through `p` (see [`Prepared::normals`]).
#[inline]
pub(crate) fn tet_normal(p: [LatticePoint; 4]) -> [i32; 4] {
    let p = p.map(|q| q.map(i64::from));
    let e = [1, 2, 3].map(|i| [0, 1, 2, 3].map(|k| p[i][k] - p[0][k]));
    // Edges below 2^20 keep the minors' six triple products below 2^63: i64 is exact
    // there (every voxel-sized tet); longer ones take i128.
    if e.iter().flatten().all(|c| c.abs() < 1 << 20) {
        normal_in_i32(edge_minors(e).map(i128::from))
    } else {
        normal_in_i32(edge_minors(e.map(|r| r.map(i128::from))))
    }
}

/// The signed 3×3 minors (−1)^k det(edges without coordinate k) of three edge vectors.
pub(super) fn edge_minors<T>(e: [[T; 4]; 3]) -> [T; 4]
where
    T: Copy
        + std::ops::Mul<Output = T>
        + std::ops::Sub<Output = T>
        + std::ops::Add<Output = T>
        + std::ops::Neg<Output = T>,
{
    let minor = |c: [usize; 3]| {
        e[0][c[0]] * (e[1][c[1]] * e[2][c[2]] - e[1][c[2]] * e[2][c[1]])
            - e[0][c[1]] * (e[1][c[0]] * e[2][c[2]] - e[1][c[2]] * e[2][c[0]])
            + e[0][c[2]] * (e[1][c[0]] * e[2][c[1]] - e[1][c[1]] * e[2][c[0]])
    };
    [
        minor([1, 2, 3]),
        -minor([0, 2, 3]),
        minor([0, 1, 3]),
        -minor([0, 1, 2]),
    ]
}

/// The normals of tets mapped by x_k → mul_k·x_k + add_k (every `mul_k > 0`), written to
/// `out`. The edge vectors scale by diag(mul), so each minor without coordinate k scales by
/// the product of the other three: N'_k = N_k · Π_{j≠k} mul_j (the cofactor rule). Only
/// the direction matters to the side tests of the walk, so the weights are divided by their gcd;
/// the signs are exact, with no minors recomputed.
pub(super) fn map_normals(normals: &[[i32; 4]], mul: [i64; 4], out: &mut Vec<[i32; 4]>) {
    let others = |k: usize| {
        (0..4)
            .filter(|&j| j != k)
            .map(|j| i128::from(mul[j]))
            .product::<i128>()
    };
    let weight = [0, 1, 2, 3].map(others);
    let g = weight
        .iter()
        .fold(0u128, |g, &w| gcd(g, w.unsigned_abs()))
        .max(1) as i128;
    let weight = weight.map(|w| w / g);
    out.clear();
    if weight == [1; 4] {
        // A translation, or the same scale on every axis: the normals are the source's.
        out.extend_from_slice(normals);
        return;
    }
    out.extend(normals.iter().map(|n| {
        if *n == NO_NORMAL {
            NO_NORMAL
        } else {
            normal_in_i32([0, 1, 2, 3].map(|k| i128::from(n[k]) * weight[k]))
        }
    }));
}

/// `n` as `i32`, divided by the gcd of its components if it does not fit as it is (only
/// the direction matters), or [`NO_NORMAL`].
#[inline]
pub(super) fn normal_in_i32(n: [i128; 4]) -> [i32; 4] {
    if let [Some(a), Some(b), Some(c), Some(d)] = n.map(fit_i32) {
        return [a, b, c, d];
    }
    reduced_normal(n)
}

/// `v` as `i32` unless it is out of range or `i32::MIN` (the [`NO_NORMAL`] marker).
#[inline]
pub(super) fn fit_i32(v: i128) -> Option<i32> {
    i32::try_from(v).ok().filter(|&v| v != i32::MIN)
}

/// [`normal_in_i32`] for a normal that does not fit as it is (fine lattices).
#[cold]
pub(super) fn reduced_normal(n: [i128; 4]) -> [i32; 4] {
    // Only the direction matters: divide by the gcd so that fine lattices fit too.
    let g = n
        .iter()
        .fold(0u128, |g, &c| gcd(g, c.unsigned_abs()))
        .max(1) as i128;
    match n.map(|v| fit_i32(v / g)) {
        [Some(a), Some(b), Some(c), Some(d)] => [a, b, c, d],
        _ => NO_NORMAL,
    }
}

pub(super) fn gcd(mut a: u128, mut b: u128) -> u128 {
    // 64-bit remainders while both fit (128-bit division is a slow library call).
    while b != 0 {
        if let (Ok(x), Ok(y)) = (u64::try_from(a), u64::try_from(b)) {
            return u128::from(gcd64(x, y));
        }
        (a, b) = (b, a % b);
    }
    a
}

pub(super) fn gcd64(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The sides (signs −1, 0, 1) of the vertices of tet `q` with respect to the hyperplane
/// of tet `p` (normal `n`), exactly; `None` when `n` is [`NO_NORMAL`]. All zero for a
/// flat `p` (zero normal).
#[inline]
pub(super) fn sides(n: &[i32; 4], p: &[LatticePoint; 4], q: &[LatticePoint; 4]) -> Option<[i8; 4]> {
    if *n == NO_NORMAL {
        return None;
    }
    // Checker coordinates lie within ±2^30, so each difference x_k − p_k is below 2^31
    // and each term n_k·(x_k − p_k) below 2^62: i64 products. With every |n_k| < 2^29
    // (any voxel-sized tet) the terms are below 2^60 and their sum fits i64; otherwise two
    // partial sums below 2^63 and one i128 addition.
    let term =
        |x: &LatticePoint, k: usize| i64::from(n[k]) * (i64::from(x[k]) - i64::from(p[0][k]));
    if n.iter().all(|c| c.unsigned_abs() < 1 << 29) {
        return Some(
            q.map(|x| (term(&x, 0) + term(&x, 1) + term(&x, 2) + term(&x, 3)).signum() as i8),
        );
    }
    let side = |x: &LatticePoint| {
        (i128::from(term(x, 0) + term(x, 1)) + i128::from(term(x, 2) + term(x, 3))).signum() as i8
    };
    Some(q.map(|x| side(&x)))
}

/// Parallel normals `na` and `nb` (of tets in one hyperplane) point opposite ways: the
/// tets' orientations differ, as [`chronotope_kernel::classify`] compares them (the sign of
/// the first coordinate where `na` is not zero). False for a zero normal or
/// [`NO_NORMAL`].
pub(super) fn facing(na: &[i32; 4], nb: &[i32; 4]) -> bool {
    if *na == NO_NORMAL || *nb == NO_NORMAL {
        return false;
    }
    match na.iter().position(|&c| c != 0) {
        Some(k) => nb[k] != 0 && (na[k] > 0) != (nb[k] > 0),
        None => false,
    }
}

/// All vertices strictly on one side: the closed tets are disjoint.
pub(super) fn strictly_one_side(s: &[i8; 4]) -> bool {
    s[0] != 0 && s[1] == s[0] && s[2] == s[0] && s[3] == s[0]
}

/// Vertices strictly on both sides.
pub(super) fn straddles(s: &[i8; 4]) -> bool {
    let (hi, lo) = (
        s[0].max(s[1]).max(s[2].max(s[3])),
        s[0].min(s[1]).min(s[2].min(s[3])),
    );
    hi > 0 && lo < 0
}
