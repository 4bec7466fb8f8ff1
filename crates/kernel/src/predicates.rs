//! Exact predicates on lattice points.

use super::LatticePoint;

/// det of the 4x4 matrix with rows a, b, c, d, exact in i128 (|entries| < 2^31: |det| <
/// 24·2^124 < 2^129 can exceed i128 only for entries near the i32 limits; lattice
/// coordinates here stay far below 2^30).
pub fn det4_i128(a: &LatticePoint, b: &LatticePoint, c: &LatticePoint, d: &LatticePoint) -> i128 {
    let m = |p: &LatticePoint| p.map(i128::from);
    let (a, b, c, d) = (m(a), m(b), m(c), m(d));
    // 2x2 minors of the last two rows, then expansion over the first two.
    let s = |i: usize, j: usize| c[i] * d[j] - c[j] * d[i];
    let (s01, s02, s03, s12, s13, s23) = (s(0, 1), s(0, 2), s(0, 3), s(1, 2), s(1, 3), s(2, 3));
    let t = |i: usize, j: usize| a[i] * b[j] - a[j] * b[i];
    t(0, 1) * s23 - t(0, 2) * s13 + t(0, 3) * s12 + t(1, 2) * s03 - t(1, 3) * s02 + t(2, 3) * s01
}

/// orient4(p0..p4) = det[p1-p0, p2-p0, p3-p0, p4-p0], exact while coordinate differences
/// stay within 2^30 in magnitude (then |det| < 24·2^120 < 2^127).
pub fn orient4_i128(p: [&LatticePoint; 5]) -> i128 {
    let d = |q: &LatticePoint| {
        [
            i64::from(q[0]) - i64::from(p[0][0]),
            i64::from(q[1]) - i64::from(p[0][1]),
            i64::from(q[2]) - i64::from(p[0][2]),
            i64::from(q[3]) - i64::from(p[0][3]),
        ]
        .map(i128::from)
    };
    let (a, b, c, e) = (d(p[1]), d(p[2]), d(p[3]), d(p[4]));
    let s = |i: usize, j: usize| c[i] * e[j] - c[j] * e[i];
    let t = |i: usize, j: usize| a[i] * b[j] - a[j] * b[i];
    t(0, 1) * s(2, 3) - t(0, 2) * s(1, 3) + t(0, 3) * s(1, 2) + t(1, 2) * s(0, 3)
        - t(1, 3) * s(0, 2)
        + t(2, 3) * s(0, 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn det_of_identity_and_swap() {
        let e = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
        assert_eq!(det4_i128(&e[0], &e[1], &e[2], &e[3]), 1);
        assert_eq!(det4_i128(&e[1], &e[0], &e[2], &e[3]), -1);
        let o = [0, 0, 0, 0];
        assert_eq!(orient4_i128([&o, &e[0], &e[1], &e[2], &e[3]]), 1);
    }

    #[test]
    fn det_matches_laplace_on_samples() {
        // Compare with a straightforward Leibniz sum.
        let rows = [[3, -1, 4, 1], [5, 9, -2, 6], [5, 3, 5, -8], [9, 7, 9, 3]];
        let mut leibniz = 0i128;
        let perms = permutations4();
        for (p, sign) in perms {
            let mut prod = i128::from(sign);
            for (r, &c) in p.iter().enumerate() {
                prod *= i128::from(rows[r][c]);
            }
            leibniz += prod;
        }
        assert_eq!(det4_i128(&rows[0], &rows[1], &rows[2], &rows[3]), leibniz);
    }

    fn permutations4() -> Vec<([usize; 4], i32)> {
        let mut out = Vec::new();
        for a in 0..4 {
            for b in 0..4 {
                for c in 0..4 {
                    for d in 0..4 {
                        let p = [a, b, c, d];
                        if (0..4).all(|i| p.contains(&i)) {
                            let mut inv = 0;
                            for i in 0..4 {
                                for j in i + 1..4 {
                                    if p[i] > p[j] {
                                        inv += 1;
                                    }
                                }
                            }
                            out.push((p, if inv % 2 == 0 { 1 } else { -1 }));
                        }
                    }
                }
            }
        }
        out
    }
}
