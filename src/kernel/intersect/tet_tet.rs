//! Tet against tet in R^4: crossing, touching, coplanar overlap, disjoint.
//!
//! # The rule
//!
//! Two boundary tets A and B *cross* when they lie in different hyperplanes H_A ≠ H_B
//! and their relative interiors (all barycentric coordinates > 0) have a common point.
//! Relative interiors are open in the 2-plane P = H_A ∩ H_B, so a common point means a
//! common open polygon of positive area, where the two bodies' boundaries pass through
//! each other transversally. Everything else that meets is touching: a shared vertex,
//! edge or face; an edge or face of one tet lying in the other's hyperplane with the
//! rest on one side; a polygon A ∩ B of positive area that lies in a face of A or of B
//! (the hyperplanes meet exactly along a ridge of the mesh); either tet flat. Tets in
//! the same hyperplane are reported separately ([`TetPairRelation::Coplanar`]).
//!
//! # How it is decided
//!
//! 1. Reject unless all four of B's vertices are *not* weakly on one side of H_A, and
//!    vice versa (if B is weakly on one side and a relative-interior point of B lies on
//!    H_A, all of B does). This also rejects flat tets, parallel and equal hyperplanes.
//! 2. DESIGN §4 vertex tests: 12 segment–tet ([`segment_crosses_tet`]) and 16
//!    triangle–triangle ([`triangles_cross`]) tests, sharing the 48 orient4 values
//!    O(tri, edge) between them (O(pq, xyz) = O(xyz, pq)). Each test says yes, no (a
//!    strict sign conflict), or degenerate (a zero without a strict conflict). A yes is
//!    a point of both relative interiors nearby, so the tets cross.
//! 3. If no test says yes and none says degenerate and no vertex lies on the other
//!    hyperplane, they do not cross: every vertex of the polygon A ∩ B is then an
//!    edge(A) ∩ tet(B), edge(B) ∩ tet(A) or tri(A) ∩ tri(B) point, and that point makes
//!    its test say yes (strictly inside) or degenerate (on the boundary).
//! 4. Otherwise (a degenerate position: the polygon's vertices may all be vertices or
//!    edge–edge points, e.g. two tets cut by P in the same triangle) decide exactly with
//!    the strict separating-axis test ([`relative_interiors_meet`]): the relative
//!    interiors meet iff 0 is interior to A − B, iff no axis of the 50 makes the
//!    projections only touch or separate.
//!
//! No symbolic perturbation is used: a perturbation (translating B by εw) would turn
//! half of all face-to-face contacts between bodies in adjacent voxels into
//! interference, contradicting "touching is not interference".
//!
//! # What the checker must know
//!
//! With lattice-aligned bodies the boundaries often cross *exactly along mesh ridges*
//! (two overlapping boxes: their boundary facets cut along a 2-plane made of triangles of
//! both meshes). Such a crossing lies on the boundary of every tet involved, so those
//! pairs are [`TetPairRelation::Touching`], not [`TetPairRelation::Crossing`]; the
//! checker must not assume that every overlap of two bodies shows up as a crossing tet
//! pair (inside tests on untouched components are still needed).
//!
//! [`segment_crosses_tet`]: super::segment_crosses_tet
//! [`triangles_cross`]: super::triangles_cross
//! [`relative_interiors_meet`]: super::relative_interiors_meet

use super::segment_tet::segment_rule;
use super::separating_axis::{difference_contains_origin, separating_axes};
use super::tri_tri::triangles_rule;
use super::{
    cross3, dot4, edge_index, orient4, rel_tet, sign, sub4, Exact, LatticeTet, Outcome, TET_EDGES,
    TET_TRIANGLES, V4,
};

/// How two tets of R^4 relate (see the [module notes](self) for the exact rules).
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
/// `false` for touching (see the [module notes](self)), for tets in one hyperplane (use
/// [`classify`]) and for flat tets. Exact for every input; never panics.
///
/// ```
/// use chronotope::kernel::intersect::tets_cross;
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
/// use chronotope::kernel::intersect::{classify, TetPairRelation};
/// let a = [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
/// let flipped = [a[1], a[0], a[2], a[3]];
/// assert_eq!(
///     classify(&a, &flipped),
///     TetPairRelation::Coplanar { overlap_volume_positive: true, same_orientation: false }
/// );
/// ```
pub fn classify(a: &LatticeTet, b: &LatticeTet) -> TetPairRelation {
    let points = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
    with_exact_width!(&points, classify_in(a, b))
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

/// Steps 1–4 of the module notes.
fn crosses<T: Exact>(p: &Pair<T>) -> bool {
    if !straddles(&p.sides_of_b) || !straddles(&p.sides_of_a) {
        return false;
    }
    match vertex_tests(p) {
        Outcome::Yes => true,
        Outcome::No => false,
        // Both tets are non-flat in transverse hyperplanes here, so A − B spans R^4.
        Outcome::Degenerate => separating_axes(&p.a, &p.b, 4, true),
    }
}

/// The DESIGN §4 vertex tests for straddling tets: [`Outcome::Yes`] if one finds a
/// crossing, [`Outcome::Degenerate`] if none does but the position is degenerate.
fn vertex_tests<T: Exact>(p: &Pair<T>) -> Outcome {
    let (a, b) = (&p.a, &p.b);
    let (sa, sb) = (&p.sides_of_a, &p.sides_of_b);
    let mut degenerate = sa.contains(&0) || sb.contains(&0);

    // ea_tb[e][t] = orient4(triangle t of B, edge e of A) = O(edge, triangle);
    // ta_eb[t][e] = orient4(triangle t of A, edge e of B).
    let table = |tris: &[V4<T>; 4], edges: &[V4<T>; 4]| {
        let mut out = [[0i8; 4]; 6];
        for (e, &[i, j]) in TET_EDGES.iter().enumerate() {
            for (t, &[x, y, z]) in TET_TRIANGLES.iter().enumerate() {
                out[e][t] = sign(orient4(&tris[x], &tris[y], &tris[z], &edges[i], &edges[j]));
            }
        }
        out
    };
    let ea_tb = table(b, a);
    let eb_ta = table(a, b);

    // Edges of A against B, then edges of B against A.
    for (sides, tab) in [(sa, &ea_tb), (sb, &eb_ta)] {
        for (e, &[i, j]) in TET_EDGES.iter().enumerate() {
            if sides[i] * sides[j] != -1 {
                continue;
            }
            match segment_rule(sides[i], sides[j], tab[e]) {
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
            // O(def,b,c), O(def,c,a), O(def,a,b) with abc = x0x1x2, def = y0y1y2.
            let first = [
                ea_tb[edge_index(x1, x2)][tb],
                -ea_tb[edge_index(x0, x2)][tb],
                ea_tb[edge_index(x0, x1)][tb],
            ];
            // O(abc,e,f), O(abc,f,d), O(abc,d,e).
            let second = [
                eb_ta[edge_index(y1, y2)][ta],
                -eb_ta[edge_index(y0, y2)][ta],
                eb_ta[edge_index(y0, y1)][ta],
            ];
            match triangles_rule(first, second) {
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

fn classify_in<T: Exact>(a: &LatticeTet, b: &LatticeTet) -> TetPairRelation {
    let p = Pair::<T>::new(a, b);
    let zero = [T::ZERO; 4];
    let touching_or_disjoint = |meet: bool| {
        if meet {
            TetPairRelation::Touching
        } else {
            TetPairRelation::Disjoint
        }
    };
    if p.na == zero || p.nb == zero {
        return touching_or_disjoint(difference_contains_origin(&p.a, &p.b, 4, false));
    }
    if p.sides_of_b == [0; 4] {
        return coplanar(&p);
    }
    if strictly_one_side(&p.sides_of_b) || strictly_one_side(&p.sides_of_a) {
        return TetPairRelation::Disjoint;
    }
    if crosses(&p) {
        return TetPairRelation::Crossing;
    }
    // Non-flat tets in transverse hyperplanes: A − B spans R^4.
    touching_or_disjoint(separating_axes(&p.a, &p.b, 4, false))
}

/// Non-flat tets in one hyperplane: an exact 3D test after dropping a coordinate in which
/// the normal does not vanish (an affine bijection of the hyperplane onto R^3).
fn coplanar<T: Exact>(p: &Pair<T>) -> TetPairRelation {
    let mut k = 0;
    while k < 3 && p.na[k] == T::ZERO {
        k += 1;
    }
    let drop = |x: &V4<T>| {
        let mut out = [T::ZERO; 4];
        let mut m = 0;
        for (i, &c) in x.iter().enumerate() {
            if i != k {
                out[m] = c;
                m += 1;
            }
        }
        out
    };
    let a3 = p.a.map(|x| drop(&x));
    let b3 = p.b.map(|x| drop(&x));
    if !separating_axes(&a3, &b3, 3, false) {
        return TetPairRelation::Disjoint;
    }
    TetPairRelation::Coplanar {
        overlap_volume_positive: separating_axes(&a3, &b3, 3, true),
        same_orientation: sign(p.na[k]) == sign(p.nb[k]),
    }
}
