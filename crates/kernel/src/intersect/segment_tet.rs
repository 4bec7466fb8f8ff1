//! Segment against tet in R^4: does an open segment cross a tet's relative interior?
//!
//! DESIGN §4. With O(abcd, x) = orient4(a, b, c, d, x) and O(pq, xyz) =
//! orient4(p, q, x, y, z), the line pq meets the hyperplane of abcd at the point X whose
//! barycentric coordinates in abcd are
//!
//! ```text
//! (O(pq,bcd), −O(pq,acd), O(pq,abd), −O(pq,abc)) / (O(abcd,p) − O(abcd,q))
//! ```
//!
//! (expand the 5x5 homogeneous determinants; the four numerators sum to the
//! denominator). So the open segment crosses the open tet iff O(abcd,p) and O(abcd,q)
//! have strictly opposite signs and the four numerators have one strict sign.

use super::{
    common_strict_sign, orient4, rel, rel_tet, sign, Exact, LatticePoint, LatticeTet, Outcome,
    TET_TRIANGLES,
};

/// Whether the open segment `p`–`q` crosses the relative interior of `tet` at a single
/// point, transversally: `p` and `q` strictly on opposite sides of the tet's hyperplane
/// and the crossing point strictly inside the tet.
///
/// Any zero predicate gives `false`: an end point on the hyperplane, a crossing point on
/// the tet's boundary, a flat tet, a segment inside the hyperplane. Exact for every input
/// (see the [module notes](super) on integer widths); never panics.
///
/// ```
/// use chronotope_kernel::intersect::segment_crosses_tet;
/// let tet = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 4, 0]];
/// assert!(segment_crosses_tet(&[1, 1, 1, -1], &[1, 1, 1, 1], &tet));
/// // Ending on the tet is touching, not crossing.
/// assert!(!segment_crosses_tet(&[1, 1, 1, 0], &[1, 1, 1, 1], &tet));
/// // Passing beside it.
/// assert!(!segment_crosses_tet(&[3, 3, 3, -1], &[3, 3, 3, 1], &tet));
/// ```
pub fn segment_crosses_tet(p: &LatticePoint, q: &LatticePoint, tet: &LatticeTet) -> bool {
    let points = [*p, *q, tet[0], tet[1], tet[2], tet[3]];
    with_exact_width!(&points, segment_outcome(p, q, tet)) == Outcome::Yes
}

/// [`Outcome`] of the DESIGN §4 test, computed in `T`.
fn segment_outcome<T: Exact>(p: &LatticePoint, q: &LatticePoint, tet: &LatticeTet) -> Outcome {
    let o = *p;
    let (p, q) = (rel::<T>(p, &o), rel::<T>(q, &o));
    let t = rel_tet::<T>(tet, &o);
    let side_p = sign(orient4(&t[0], &t[1], &t[2], &t[3], &p));
    let side_q = sign(orient4(&t[0], &t[1], &t[2], &t[3], &q));
    segment_rule(side_p, side_q, |v| {
        let [x, y, z] = TET_TRIANGLES[v];
        sign(orient4(&p, &q, &t[x], &t[y], &t[z]))
    })
}

/// The DESIGN §4 rule on signs: `side_p`, `side_q` = sign O(abcd, p), sign O(abcd, q);
/// `face(v)` = sign O(pq, face opposite v) with the face's vertices in increasing order
/// (asked for only when the sides are strictly opposite, and only until a conflict).
pub(super) fn segment_rule(side_p: i8, side_q: i8, mut face: impl FnMut(usize) -> i8) -> Outcome {
    match side_p * side_q {
        1 => Outcome::No,
        0 => Outcome::Degenerate,
        // λ_v ∝ (−1)^v O(pq, face opposite v).
        _ => common_strict_sign(4, |v| if v % 2 == 0 { face(v) } else { -face(v) }),
    }
}

#[cfg(test)]
mod tests {
    use super::super::{orient4, rel};
    use super::*;

    #[test]
    fn numerators_sum_to_the_denominator() {
        // O(pq,bcd) − O(pq,acd) + O(pq,abd) − O(pq,abc) = O(abcd,p) − O(abcd,q).
        let pts: [LatticePoint; 6] = [
            [3, -1, 4, 1],
            [-5, 9, 2, 6],
            [5, 3, -5, 8],
            [9, 7, 9, -3],
            [2, -3, 8, 4],
            [6, 2, 6, -4],
        ];
        let o = [0; 4];
        let [p, q, a, b, c, d] = pts.map(|x| rel::<i64>(&x, &o));
        let lhs = orient4(&p, &q, &b, &c, &d) - orient4(&p, &q, &a, &c, &d)
            + orient4(&p, &q, &a, &b, &d)
            - orient4(&p, &q, &a, &b, &c);
        let rhs = orient4(&a, &b, &c, &d, &p) - orient4(&a, &b, &c, &d, &q);
        assert_eq!(lhs, rhs);
    }

    #[test]
    fn crossing_point_on_a_face_or_edge_is_not_a_crossing() {
        let tet = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 4, 0]];
        // Through the face x3 = 0, through the edge x2 = x3 = 0, through a vertex.
        assert!(!segment_crosses_tet(&[1, 1, 0, -1], &[1, 1, 0, 1], &tet));
        assert!(!segment_crosses_tet(&[1, 0, 0, -1], &[1, 0, 0, 1], &tet));
        assert!(!segment_crosses_tet(&[4, 0, 0, -1], &[4, 0, 0, 1], &tet));
        // Inside the hyperplane, and a flat tet.
        assert!(!segment_crosses_tet(&[1, 1, 1, 0], &[2, 1, 1, 0], &tet));
        let flat = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0], [4, 4, 0, 0]];
        assert!(!segment_crosses_tet(&[1, 1, 0, -1], &[1, 1, 0, 1], &flat));
        // Reversing the segment or permuting the tet does not matter.
        let tet2 = [tet[2], tet[0], tet[3], tet[1]];
        assert!(segment_crosses_tet(&[1, 1, 1, 1], &[1, 1, 1, -1], &tet2));
    }
}
