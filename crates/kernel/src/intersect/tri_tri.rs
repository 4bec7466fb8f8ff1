//! Triangle against triangle in R^4: do two triangles cross at one point?
//!
//! DESIGN §4, checked by derivation. Six points a, b, c, d, e, f of R^4 have an affine
//! dependence Σ c_x x̂ = 0 (x̂ = (x, 1)) with, by Cramer's rule, c_x = ± the 5x5
//! homogeneous determinant of the other five:
//!
//! ```text
//! c_a = O(def,b,c)   c_b = O(def,c,a)   c_c = O(def,a,b)
//! −c_d = O(abc,e,f)  −c_e = O(abc,f,d)  −c_f = O(abc,d,e)
//! ```
//!
//! where O(def,x,y) = orient4(d,e,f,x,y) (a cyclic shift of five points is an even
//! permutation). The triangles meet at a point interior to both, transversally (the six
//! points span R^4, so that point is unique), iff c_a, c_b, c_c have one strict sign and
//! c_d, c_e, c_f the opposite one, i.e. iff all six numbers above have one strict sign.
//! The DESIGN text asks for "one sign" per group only; that is the same condition,
//! because Σ c_x = 0 forbids the two groups from having opposite signs. We test all six.

use super::{common_strict_sign, orient4, rel, sign, Exact, LatticeTriangle, Outcome};

/// Whether the triangles `abc` and `def` cross at a single point interior to both,
/// transversally (their six vertices affinely span R^4).
///
/// Any zero predicate gives `false`: the crossing point on an edge or vertex of either
/// triangle, triangles in a common 3-flat, flat triangles. Exact for every input; never
/// panics.
///
/// ```
/// use chronotope_kernel::intersect::triangles_cross;
/// let abc = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0]];
/// let def = [[1, 1, -1, -1], [1, 1, 3, -1], [1, 1, -1, 3]];
/// assert!(triangles_cross(&abc, &def)); // at (1, 1, 0, 0)
/// let edge_hit = [[0, 1, -1, -1], [0, 1, 3, -1], [0, 1, -1, 3]];
/// assert!(!triangles_cross(&abc, &edge_hit)); // at (0, 1, 0, 0), on the edge x = 0
/// ```
pub fn triangles_cross(abc: &LatticeTriangle, def: &LatticeTriangle) -> bool {
    let points = [abc[0], abc[1], abc[2], def[0], def[1], def[2]];
    with_exact_width!(&points, triangles_outcome(abc, def)) == Outcome::Yes
}

/// [`Outcome`] of the DESIGN §4 test, computed in `T`.
fn triangles_outcome<T: Exact>(abc: &LatticeTriangle, def: &LatticeTriangle) -> Outcome {
    let o = abc[0];
    let [a, b, c] = abc.map(|x| rel::<T>(&x, &o));
    let [d, e, f] = def.map(|x| rel::<T>(&x, &o));
    triangles_rule(
        |k| match k {
            0 => sign(orient4(&d, &e, &f, &b, &c)),
            1 => sign(orient4(&d, &e, &f, &c, &a)),
            _ => sign(orient4(&d, &e, &f, &a, &b)),
        },
        |k| match k {
            0 => sign(orient4(&a, &b, &c, &e, &f)),
            1 => sign(orient4(&a, &b, &c, &f, &d)),
            _ => sign(orient4(&a, &b, &c, &d, &e)),
        },
    )
}

/// The rule on signs: `first(k)`, k = 0, 1, 2 = signs of O(def,b,c), O(def,c,a),
/// O(def,a,b); `second(k)` = signs of O(abc,e,f), O(abc,f,d), O(abc,d,e). All six must
/// share one strict sign (evaluated lazily, up to the first conflict).
pub(super) fn triangles_rule(
    mut first: impl FnMut(usize) -> i8,
    mut second: impl FnMut(usize) -> i8,
) -> Outcome {
    common_strict_sign(6, |k| if k < 3 { first(k) } else { second(k - 3) })
}

#[cfg(test)]
mod tests {
    use super::super::LatticePoint;
    use super::*;

    #[test]
    fn the_two_groups_sum_to_the_same_value() {
        // c_a + c_b + c_c = −(c_d + c_e + c_f): the two groups of DESIGN §4 have equal sums,
        // so they can never have strictly opposite signs.
        let pts: [LatticePoint; 6] = [
            [3, -1, 4, 1],
            [-5, 9, 2, 6],
            [5, 3, -5, 8],
            [9, 7, 9, -3],
            [2, -3, 8, 4],
            [6, 2, 6, -4],
        ];
        let o = [0; 4];
        let [a, b, c, d, e, f] = pts.map(|x| rel::<i64>(&x, &o));
        let first =
            orient4(&d, &e, &f, &b, &c) + orient4(&d, &e, &f, &c, &a) + orient4(&d, &e, &f, &a, &b);
        let second =
            orient4(&a, &b, &c, &e, &f) + orient4(&a, &b, &c, &f, &d) + orient4(&a, &b, &c, &d, &e);
        assert_eq!(first, second);
    }

    #[test]
    fn symmetric_and_permutation_invariant() {
        let abc = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0]];
        let def = [[1, 1, -1, -1], [1, 1, 3, -1], [1, 1, -1, 3]];
        assert!(triangles_cross(&def, &abc));
        assert!(triangles_cross(
            &[abc[1], abc[0], abc[2]],
            &[def[2], def[0], def[1]]
        ));
        // Same 3-flat (x4 = 0 for both after flattening def): never a crossing.
        let flat = [[1, 1, -1, 0], [1, 1, 3, 0], [1, 2, -1, 0]];
        assert!(!triangles_cross(&abc, &flat));
    }
}
