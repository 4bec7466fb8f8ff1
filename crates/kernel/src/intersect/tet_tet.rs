//! Tet against tet in R^4: crossing, touching, coplanar overlap, disjoint.
//!
//! The rule, how it is decided and why, are in the [parent module notes](super).

use super::separating_axis::{
    difference_contains_origin, drop_coordinate, separating_axes, separating_axes_low,
};
use super::{
    cross3, dot4, edge_index, rel_tet, sign, sub4, Exact, LatticeTet, TET_EDGES, TET_TRIANGLES, V4,
};

/// How two tets of R^4 relate (see the [module notes](super) for the exact rules).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TetPairRelation {
    /// The closed tets have no common point.
    Disjoint,
    /// The closed tets meet but do not cross: a shared vertex, edge or face, contact
    /// along a ridge, an intersection inside a face of one of them, or a flat tet.
    Touching,
    /// Different hyperplanes and the relative interiors meet: a polygon of positive area
    /// where the two boundaries cross transversally ([`tets_cross`]).
    Crossing,
    /// Both tets are non-flat, lie in the same hyperplane (3-flat) and meet.
    Coplanar {
        /// Their interiors within the hyperplane overlap (a positive 3-volume). With
        /// `same_orientation` this is interference (the bodies' interiors lie on the same
        /// side); with opposite orientation it is face-to-face contact.
        overlap_volume_positive: bool,
        /// The oriented normals N = cross3(b−a, c−a, d−a) point the same way.
        same_orientation: bool,
    },
}

/// Whether the tets lie in different hyperplanes and their relative interiors meet, i.e.
/// they intersect in a polygon of positive area where they cross transversally.
///
/// `false` for touching (see the [module notes](super)), for tets in one hyperplane (use
/// [`classify`]) and for flat tets. Exact for every input; never panics.
///
/// ```
/// use chronotope_kernel::intersect::tets_cross;
/// let a = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 4, 0]]; // in t = 0
/// let b = [[1, 1, 1, -1], [2, 1, 1, -1], [1, 2, 1, -1], [1, 1, 1, 2]]; // in z = 1
/// assert!(tets_cross(&a, &b));
/// let c = [[0, 0, 0, 0], [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 0, 4]]; // shares a face
/// assert!(!tets_cross(&a, &c));
/// ```
pub fn tets_cross(a: &LatticeTet, b: &LatticeTet) -> bool {
    let points = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
    with_exact_width!(&points, cross_in(a, b))
}

/// The relation of two tets: [`TetPairRelation`]. Symmetric in `a` and `b`; invariant
/// under lattice translations and vertex permutations, except that an odd permutation of
/// one tet flips `same_orientation`. Exact for every input; never panics.
///
/// ```
/// use chronotope_kernel::intersect::{classify, TetPairRelation};
/// let a = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
/// let flipped = [a[1], a[0], a[2], a[3]];
/// assert_eq!(
///     classify(&a, &flipped),
///     TetPairRelation::Coplanar { overlap_volume_positive: true, same_orientation: false }
/// );
/// ```
pub fn classify(a: &LatticeTet, b: &LatticeTet) -> TetPairRelation {
    classify_if(a, b, true)
}

/// [`classify`], but when `touching_matters` is false a pair that is `Touching` may be
/// reported `Disjoint` (the costly touching-or-disjoint decision is skipped; `Crossing`
/// and `Coplanar` are decided as always). For callers that already know both tets touch
/// the other boundary somewhere.
pub fn classify_if(a: &LatticeTet, b: &LatticeTet, touching_matters: bool) -> TetPairRelation {
    let points = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
    with_exact_width!(&points, classify_in(a, b, touching_matters))
}

/// The two tets relative to a[0], their normals and the sides of each one's vertices
/// with respect to the other's hyperplane.
struct Pair<T> {
    a: [V4<T>; 4],
    b: [V4<T>; 4],
    na: V4<T>,
    nb: V4<T>,
    /// sign O(A, b_j) = sign N_A·(b_j − a_0).
    sides_of_b: [i8; 4],
    /// sign O(B, a_i) = sign N_B·(a_i − b_0).
    sides_of_a: [i8; 4],
}

impl<T: Exact> Pair<T> {
    fn new(a: &LatticeTet, b: &LatticeTet) -> Self {
        let o = a[0];
        let a = rel_tet::<T>(a, &o);
        let b = rel_tet::<T>(b, &o);
        let na = cross3(
            &sub4(&a[1], &a[0]),
            &sub4(&a[2], &a[0]),
            &sub4(&a[3], &a[0]),
        );
        let nb = cross3(
            &sub4(&b[1], &b[0]),
            &sub4(&b[2], &b[0]),
            &sub4(&b[3], &b[0]),
        );
        let sides_of_b = b.map(|x| sign(dot4(&na, &sub4(&x, &a[0]))));
        let sides_of_a = a.map(|x| sign(dot4(&nb, &sub4(&x, &b[0]))));
        Pair {
            a,
            b,
            na,
            nb,
            sides_of_b,
            sides_of_a,
        }
    }
}

fn straddles(sides: &[i8; 4]) -> bool {
    sides.iter().any(|&s| s > 0) && sides.iter().any(|&s| s < 0)
}

fn strictly_one_side(sides: &[i8; 4]) -> bool {
    sides.iter().all(|&s| s > 0) || sides.iter().all(|&s| s < 0)
}

fn cross_in<T: Exact>(a: &LatticeTet, b: &LatticeTet) -> bool {
    let pair = Pair::<T>::new(a, b);
    crosses(&pair)
}

/// Steps 1–3 of the module notes: the relative interiors meet.
fn crosses<T: Exact>(p: &Pair<T>) -> bool {
    straddling(p) && Sections::new(p).meet(true)
}

/// Both tets have vertices strictly on both sides of the other's hyperplane.
fn straddling<T: Exact>(p: &Pair<T>) -> bool {
    straddles(&p.sides_of_b) && straddles(&p.sides_of_a)
}

/// The cross-sections Pa = A ∩ P and Pb = B ∩ P of straddling tets, as vertex lists
/// with lazily computed barycentric signs (steps 2 and 3 of the module notes).
struct Sections<'a, T> {
    /// Vertices of Pa: (edge of A, sign of g_B(p) − g_B(q) for that edge as (p, q)).
    verts_a: ([(usize, i8); 4], usize),
    /// Vertices of Pb: (edge of B, sign of g_A(p) − g_A(q)).
    verts_b: ([(usize, i8); 4], usize),
    /// O(edge of A, face of B).
    ea_tb: TriEdgeSigns<'a, T>,
    /// O(edge of B, face of A).
    eb_ta: TriEdgeSigns<'a, T>,
}

impl<'a, T: Exact> Sections<'a, T> {
    fn new(p: &'a Pair<T>) -> Self {
        Sections {
            verts_a: section_vertices(&p.sides_of_a),
            verts_b: section_vertices(&p.sides_of_b),
            ea_tb: TriEdgeSigns::new(&p.b, &p.a),
            eb_ta: TriEdgeSigns::new(&p.a, &p.b),
        }
    }

    /// `strict`: int Pa ∩ int Pb ≠ ∅; otherwise Pa ∩ Pb ≠ ∅.
    fn meet(&mut self, strict: bool) -> bool {
        let need = if strict { 1 } else { 0 };
        for t in 0..4 {
            let parity = if t % 2 == 0 { 1 } else { -1 };
            let (va, na) = self.verts_a;
            if !va[..na]
                .iter()
                .any(|&(e, s)| s * parity * self.ea_tb.get(e, t) >= need)
            {
                return false;
            }
            let (vb, nb) = self.verts_b;
            if !vb[..nb]
                .iter()
                .any(|&(e, s)| s * parity * self.eb_ta.get(e, t) >= need)
            {
                return false;
            }
        }
        true
    }
}

/// The vertices of a straddling tet's cross-section by the other hyperplane, given the
/// sides of its vertices: each as (edge (i, j), i < j, sign of g(v_i) − g(v_j)).
fn section_vertices(sides: &[i8; 4]) -> ([(usize, i8); 4], usize) {
    let mut out = [(0, 0); 4];
    let mut n = 0;
    for (e, &[i, j]) in TET_EDGES.iter().enumerate() {
        if sides[i] * sides[j] == -1 && n < 4 {
            out[n] = (e, sides[i]);
            n += 1;
        }
    }
    for i in 0..4 {
        if sides[i] == 0 && n < 4 {
            // Any vertex off the hyperplane (one exists: the tet straddles it).
            if let Some(j) = (0..4).find(|&j| sides[j] != 0) {
                let (lo, hi) = if i < j { (i, j) } else { (j, i) };
                out[n] = (edge_index(lo, hi), sides[lo] - sides[hi]);
                n += 1;
            }
        }
    }
    (out, n)
}

/// Signs of O(edge e of `edges`, triangle t of `tris`) = orient4(triangle, edge),
/// computed on first use; each triangle's 2x2 minors are computed once.
struct TriEdgeSigns<'a, T> {
    tris: &'a [V4<T>; 4],
    edges: &'a [V4<T>; 4],
    minors: [Option<[T; 6]>; 4],
    signs: [[i8; 4]; 6],
}

/// Marks a sign not computed yet.
const UNKNOWN: i8 = 2;

impl<'a, T: Exact> TriEdgeSigns<'a, T> {
    fn new(tris: &'a [V4<T>; 4], edges: &'a [V4<T>; 4]) -> Self {
        TriEdgeSigns {
            tris,
            edges,
            minors: [None; 4],
            signs: [[UNKNOWN; 4]; 6],
        }
    }

    /// sign orient4(y0, y1, y2, p, q) = sign det[y1−y0, y2−y0, p−y0, q−y0].
    fn get(&mut self, e: usize, t: usize) -> i8 {
        if self.signs[e][t] != UNKNOWN {
            return self.signs[e][t];
        }
        let [y0, y1, y2] = TET_TRIANGLES[t].map(|i| self.tris[i]);
        let m = *self.minors[t].get_or_insert_with(|| {
            let (u, v) = (sub4(&y1, &y0), sub4(&y2, &y0));
            let m = |i: usize, j: usize| u[i] * v[j] - u[j] * v[i];
            [m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3)]
        });
        let [i, j] = TET_EDGES[e];
        let (x, y) = (sub4(&self.edges[i], &y0), sub4(&self.edges[j], &y0));
        let s = |i: usize, j: usize| x[i] * y[j] - x[j] * y[i];
        let det = m[0] * s(2, 3) - m[1] * s(1, 3) + m[2] * s(1, 2) + m[3] * s(0, 3)
            - m[4] * s(0, 2)
            + m[5] * s(0, 1);
        let sg = sign(det);
        self.signs[e][t] = sg;
        sg
    }
}

fn classify_in<T: Exact>(
    a: &LatticeTet,
    b: &LatticeTet,
    touching_matters: bool,
) -> TetPairRelation {
    let p = Pair::<T>::new(a, b);
    let zero = [T::ZERO; 4];
    let touching_or_disjoint = |meet: &mut dyn FnMut() -> bool| {
        if touching_matters && meet() {
            TetPairRelation::Touching
        } else {
            TetPairRelation::Disjoint
        }
    };
    if p.na == zero || p.nb == zero {
        return touching_or_disjoint(&mut || difference_contains_origin(&p.a, &p.b, 4, false));
    }
    if p.sides_of_b == [0; 4] {
        return coplanar(&p, touching_matters);
    }
    if strictly_one_side(&p.sides_of_b) || strictly_one_side(&p.sides_of_a) {
        return TetPairRelation::Disjoint;
    }
    if straddling(&p) {
        let mut sections = Sections::new(&p);
        if sections.meet(true) {
            return TetPairRelation::Crossing;
        }

        return touching_or_disjoint(&mut || sections.meet(false));
    }
    // One tet, say B, lies weakly on one side of the other's hyperplane H_A with some
    // vertices Z on it. Then B ∩ H_A = conv(Z) and A ∩ B = A ∩ conv(Z): a question inside
    // the 3-flat H_A (and symmetrically with A and H_B).
    if !straddles(&p.sides_of_b) {
        touching_or_disjoint(&mut || meets_in_hyperplane(&p.a, &p.na, &p.b, &p.sides_of_b))
    } else {
        touching_or_disjoint(&mut || meets_in_hyperplane(&p.b, &p.nb, &p.a, &p.sides_of_a))
    }
}

/// Whether the non-flat tet `t` (normal `n`) meets the convex hull of the vertices of
/// `other` that lie on its hyperplane (`sides[j] == 0`; one to three of them). Exact, in
/// R^3 after dropping a coordinate in which `n` does not vanish (an affine bijection of
/// the hyperplane onto R^3); t − conv(Z) is full-dimensional there, so the 3D
/// separating-axis test applies.
fn meets_in_hyperplane<T: Exact>(
    t: &[V4<T>; 4],
    n: &V4<T>,
    other: &[V4<T>; 4],
    sides: &[i8; 4],
) -> bool {
    let k = (0..4).find(|&k| n[k] != T::ZERO).unwrap_or(3);
    let drop = |x: &V4<T>| drop_coordinate(x, k);
    let mut z = [[T::ZERO; 4]; 4];
    let mut count = 0;
    for (j, v) in other.iter().enumerate() {
        if sides[j] == 0 {
            z[count] = drop(v);
            count += 1;
        }
    }
    if count == 0 {
        return false;
    }
    let t3 = t.map(|x| drop(&x));
    // Most such pairs are told apart by their boxes in the hyperplane (exact, closed).
    let apart = (0..3).any(|k| {
        let (tlo, thi) = (t3.iter().map(|p| p[k]).min(), t3.iter().map(|p| p[k]).max());
        let (zlo, zhi) = (
            z[..count].iter().map(|p| p[k]).min(),
            z[..count].iter().map(|p| p[k]).max(),
        );
        thi < zlo || zhi < tlo
    });
    if apart {
        return false;
    }
    if count == 1 {
        if let Some(inside) = point_in_tet_3d(&z[0], &t3) {
            return inside;
        }
    }
    // Pad with the last point: a repeated vertex adds only zero axes, which never separate.
    for j in count..4 {
        z[j] = z[count - 1];
    }
    separating_axes(&t3, &z, 3, false)
}

/// Whether `p` lies in the closed 3D tet `t` (first three coordinates): on the inner
/// side of, or on, each face, as the sign of the tet's orientation with that face's
/// opposite vertex replaced by `p`. `None` for a flat `t`.
fn point_in_tet_3d<T: Exact>(p: &V4<T>, t: &[V4<T>; 4]) -> Option<bool> {
    let orient = |q: &[V4<T>; 4]| {
        let e = [1, 2, 3].map(|i| sub4(&q[i], &q[0]));
        sign(
            e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1])
                - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
                + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]),
        )
    };
    let o = orient(t);
    (o != 0).then(|| {
        (0..4).all(|i| {
            let mut q = *t;
            q[i] = *p;
            orient(&q) * o >= 0
        })
    })
}

/// Non-flat tets in one hyperplane: an exact 3D test after dropping a coordinate in which
/// the normal does not vanish (an affine bijection of the hyperplane onto R^3). Unless
/// `touching_matters`, a pair whose interiors do not meet is `Disjoint` and the test stops
/// at the first axis that separates or touches (tets face to face share many faces and
/// edges: proving they only touch takes every axis).
fn coplanar<T: Exact>(p: &Pair<T>, touching_matters: bool) -> TetPairRelation {
    let mut k = 0;
    while k < 3 && p.na[k] == T::ZERO {
        k += 1;
    }
    let drop = |x: &V4<T>| drop_coordinate(x, k);
    let a3 = p.a.map(|x| drop(&x));
    let b3 = p.b.map(|x| drop(&x));
    let verdict = separating_axes_low(&a3, &b3, 3, !touching_matters);
    if !verdict.meet || !(touching_matters || verdict.interiors_meet) {
        return TetPairRelation::Disjoint;
    }
    TetPairRelation::Coplanar {
        overlap_volume_positive: verdict.interiors_meet,
        same_orientation: sign(p.na[k]) == sign(p.nb[k]),
    }
}

#[cfg(test)]
mod tests {
    //! The DESIGN §4 vertex tests (12 segment–tet, 16 triangle–triangle) as a second,
    //! independent decision of "cross": with a three-valued outcome per test and the
    //! exact strict separating-axis test as the fallback in degenerate positions.

    use super::super::segment_tet::segment_rule;
    use super::super::tri_tri::triangles_rule;
    use super::super::Outcome;
    use super::*;

    /// "Cross" decided the DESIGN way. If some test says yes, they cross. If every test
    /// says no and no vertex lies on the other hyperplane, they do not: every vertex of
    /// the polygon A ∩ P ∩ B is an edge(A) ∩ tet(B), edge(B) ∩ tet(A) or tri(A) ∩ tri(B)
    /// point, whose test would say yes (inside) or degenerate (on the boundary).
    fn crosses_by_vertex_tests<T: Exact>(p: &Pair<T>) -> bool {
        if !straddling(p) {
            return false;
        }
        match vertex_tests(p) {
            Outcome::Yes => true,
            Outcome::No => false,
            Outcome::Degenerate => separating_axes(&p.a, &p.b, 4, true),
        }
    }

    /// The DESIGN §4 vertex tests for straddling tets: [`Outcome::Yes`] if one finds a
    /// crossing, [`Outcome::Degenerate`] if none does but the position is degenerate.
    pub(super) fn vertex_tests<T: Exact>(p: &Pair<T>) -> Outcome {
        let (sa, sb) = (&p.sides_of_a, &p.sides_of_b);
        let mut degenerate = sa.contains(&0) || sb.contains(&0);
        // O(edge of A, triangle of B) and O(edge of B, triangle of A). The segment and the
        // triangle tests share them: O(pq, xyz) = O(xyz, pq) (an even permutation).
        let mut ea_tb = TriEdgeSigns::new(&p.b, &p.a);
        let mut eb_ta = TriEdgeSigns::new(&p.a, &p.b);

        // Edges of A against B, then edges of B against A.
        for (sides, tab) in [(sa, &mut ea_tb), (sb, &mut eb_ta)] {
            for (e, &[i, j]) in TET_EDGES.iter().enumerate() {
                if sides[i] * sides[j] != -1 {
                    continue;
                }
                match segment_rule(sides[i], sides[j], |t| tab.get(e, t)) {
                    Outcome::Yes => return Outcome::Yes,
                    Outcome::Degenerate => degenerate = true,
                    Outcome::No => {}
                }
            }
        }

        // Triangles of A against triangles of B; a triangle strictly on one side of the
        // other hyperplane cannot meet the other tet.
        let off = |sides: &[i8; 4], [x, y, z]: [usize; 3]| {
            sides[x] != 0 && sides[x] == sides[y] && sides[y] == sides[z]
        };
        for (ta, &[x0, x1, x2]) in TET_TRIANGLES.iter().enumerate() {
            if off(sa, [x0, x1, x2]) {
                continue;
            }
            for (tb, &[y0, y1, y2]) in TET_TRIANGLES.iter().enumerate() {
                if off(sb, [y0, y1, y2]) {
                    continue;
                }
                // abc = x0x1x2 (of A), def = y0y1y2 (of B).
                let outcome = triangles_rule(
                    // O(def,b,c), O(def,c,a), O(def,a,b).
                    |k| match k {
                        0 => ea_tb.get(edge_index(x1, x2), tb),
                        1 => -ea_tb.get(edge_index(x0, x2), tb),
                        _ => ea_tb.get(edge_index(x0, x1), tb),
                    },
                    // O(abc,e,f), O(abc,f,d), O(abc,d,e).
                    |k| match k {
                        0 => eb_ta.get(edge_index(y1, y2), ta),
                        1 => -eb_ta.get(edge_index(y0, y2), ta),
                        _ => eb_ta.get(edge_index(y0, y1), ta),
                    },
                );
                match outcome {
                    Outcome::Yes => return Outcome::Yes,
                    Outcome::Degenerate => degenerate = true,
                    Outcome::No => {}
                }
            }
        }
        if degenerate {
            Outcome::Degenerate
        } else {
            Outcome::No
        }
    }

    use super::super::test_rng::Rng;

    #[test]
    fn sections_agree_with_the_design_vertex_tests_and_the_strict_axes() {
        let mut rng = Rng(0x5eed_1234_abcd_0001);
        let mut crossing = 0;
        for round in 0..40_000 {
            let (lo, hi) = if round % 2 == 0 { (0, 2) } else { (-6, 6) };
            let a = rng.tet(lo, hi);
            let mut b = rng.tet(lo, hi);
            if round % 3 == 0 {
                b[0] = a[(round / 3) % 4];
            }
            let p = Pair::<i64>::new(&a, &b);
            let by_sections = crosses(&p);
            assert_eq!(by_sections, crosses_by_vertex_tests(&p), "{a:?} {b:?}");
            let transverse = straddling(&p);
            assert_eq!(
                by_sections,
                transverse && separating_axes(&p.a, &p.b, 4, true),
                "{a:?} {b:?}"
            );
            if transverse {
                assert_eq!(
                    Sections::new(&p).meet(false),
                    separating_axes(&p.a, &p.b, 4, false),
                    "{a:?} {b:?}"
                );
            }
            crossing += usize::from(by_sections);
        }
        assert!(crossing > 2_000, "{crossing}");
    }

    #[test]
    fn design_tests_miss_a_crossing_with_only_degenerate_polygon_vertices() {
        let a: LatticeTet = [[0, 0, 0, 0], [2, 0, 0, 0], [0, 2, 1, 0], [0, 2, -1, 0]];
        let b: LatticeTet = [[0, 0, 0, 0], [2, 0, 0, 0], [0, 2, 0, 1], [0, 2, 0, -1]];
        let p = Pair::<i64>::new(&a, &b);
        assert_eq!(vertex_tests(&p), Outcome::Degenerate);
        assert!(crosses(&p) && crosses_by_vertex_tests(&p));
    }
}
