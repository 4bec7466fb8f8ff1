//! Exact intersection of tetrahedra (3-simplices) in R^4 on lattice points: no epsilon.
//!
//! Each moving body is bounded by tets lying in R^4 (DESIGN §3); the checker asks, for a
//! candidate pair of boundary tets, whether the two boundaries *cross* there.
//! Touching is not interference. The rules, all decided exactly:
//!
//! - [`segment_crosses_tet`]: the open segment meets the relative interior of the tet at
//!   one point, transversally (DESIGN §4 signs; any zero predicate means "no").
//! - [`triangles_cross`]: two triangles meet at one point interior to both, transversally
//!   (DESIGN §4 signs, checked by derivation: the six numbers are the coefficients of the
//!   affine dependence of the six vertices; both groups must have one strict sign, and
//!   then it is the same sign for both groups because the coefficients sum to zero).
//! - [`tets_cross`]: the tets lie in different hyperplanes and their *relative
//!   interiors* meet. Then they meet in a convex polygon of positive area in the 2-plane
//!   P where the hyperplanes cut. Decided exactly, degenerate positions included, by a
//!   separating-axis test on the two cross-sections A ∩ P and B ∩ P whose vertex
//!   positions come from the DESIGN §4 segment–tet signs (below; the DESIGN vertex
//!   tests with strict signs alone miss crossings whose polygon has only degenerate
//!   vertices).
//! - [`classify`]: [`TetPairRelation`]: `Disjoint` (the closed tets share no point),
//!   else `Coplanar` for two non-flat tets in one 3-flat (positive-volume overlap by an
//!   exact 3D separating-axis test after dropping a coordinate in which the normal does
//!   not vanish; orientation by the sign of that normal coordinate), else `Crossing`
//!   as [`tets_cross`], else `Touching` (flat tets are always `Touching` or `Disjoint`).
//! - [`tets_intersect`] / [`relative_interiors_meet`]: the separating-axis versions
//!   (50 axes in R^4, with an exact reduction to lower dimension when the tets are flat,
//!   coplanar or parallel); any input, used as a cross-check.
//!
//! # Tet–tet: the rule
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
//! # Tet–tet: how it is decided
//!
//! With g_B(x) = O(B, x) = orient4(b0, b1, b2, b3, x) and g_A likewise:
//!
//! 1. Reject unless B has vertices strictly on both sides of H_A and A strictly on both
//!    sides of H_B. (If B is weakly on one side and a relative-interior point of B lies
//!    on H_A, all of B does.) This also rejects flat tets, parallel and equal
//!    hyperplanes.
//! 2. Now P meets both relative interiors, so the cross-sections Pa = A ∩ P and
//!    Pb = B ∩ P are convex polygons of positive area and relint A ∩ P = int Pa. The
//!    vertices of Pa are the points X = line(pq) ∩ H_B for the edges pq of A whose ends
//!    are strictly on opposite sides of H_B, and the vertices of A on H_B (for those take
//!    any edge pq to a vertex off H_B: X = that vertex). By the segment–tet formula of
//!    DESIGN §4 (see [`segment_crosses_tet`]) the barycentric coordinates of X in B are
//!    λ_t(X) = (−1)^t O(pq, face_t(B)) / (g_B(p) − g_B(q)): their *signs* are exact
//!    orient4 signs, O(pq, xyz) = orient4(x, y, z, p, q).
//! 3. Pb = {x ∈ P : λ_t(x) ≥ 0, t = 0..3}, so every edge of Pb lies on a line λ_t = 0.
//!    Separating axes in the plane: two convex polygons have disjoint interiors iff
//!    a line through an edge of one has the other on its closed outer side. So
//!
//!    ```text
//!    int Pa ∩ int Pb ≠ ∅  ⟺  for every face t of B some vertex X of Pa has λ_t(X) > 0,
//!                             and for every face s of A some vertex Y of Pb has λ_s(Y) > 0.
//!    ```
//!
//!    With "≥ 0" in place of "> 0" the same test decides whether the closed tets meet.
//!
//! This needs at most 16 + 16 orient4 signs (each computed once, on first use, and the
//! search stops early) and no case analysis of degenerate positions: zeros (vertices on
//! the other hyperplane, polygon vertices on the other tet's boundary, coincident
//! cross-sections) are handled by the exact inequalities. It decides exactly what the
//! DESIGN §4 vertex tests (12 segment–tet and 16 triangle–triangle, all signs strict)
//! decide in general position; those tests alone miss crossings in degenerate position
//! (for example two tets cut by P in the same triangle, through their vertices and edge
//! midpoints), which this rule finds. The unit tests check it against the DESIGN tests
//! completed by an exact fallback, and `tests/it/tet_tet.rs` against an exact LP oracle.
//!
//! No symbolic perturbation is used: a perturbation (translating B by εw) would turn
//! half of all face-to-face contacts between bodies in adjacent voxels into
//! interference, contradicting "touching is not interference".
//!
//! # Tet–tet: what the checker must know
//!
//! With lattice-aligned bodies the boundaries often cross *exactly along mesh ridges*
//! (two overlapping boxes: their boundary facets cut along a 2-plane made of triangles of
//! both meshes). Such a crossing lies on the boundary of every tet involved, so those
//! pairs are [`TetPairRelation::Touching`], not [`TetPairRelation::Crossing`]; the
//! checker must not assume that every overlap of two bodies shows up as a crossing tet
//! pair (inside tests on untouched components are still needed). Measured on meshed
//! voxel boxes (`tests/it/tet_tet.rs`): two boxes overlapping by one voxel column give no
//! `Crossing` pair at all, only `Coplanar` overlaps with the same orientation; a box
//! overlapping diagonally gives `Crossing` pairs; boxes in adjacent voxels give only
//! `Touching` and opposite-orientation `Coplanar` pairs.
//!
//! # Exactness and overflow
//!
//! Every predicate is a determinant of coordinate *differences*. Let M be the largest
//! coordinate spread (max − min in one coordinate) over the points of one call. The
//! largest quantity evaluated is a 4x4 determinant or a dot product with a separating
//! axis, both at most 24 M^4 in absolute value, with the intermediate 2x2 minors at most
//! 2 M^2. Each call picks the narrowest integer that is exact for its M:
//! `i64` for M ≤ 2^14 (24·2^56 < 2^63: all real candidate pairs, whose tets are
//! neighbours on the lattice), `i128` for M ≤ 2^30 (24·2^120 < 2^127), and a small
//! 256-bit integer otherwise (any `i32` input: M < 2^32, 24 M^4 < 2^133). Results never
//! depend on the width, and no input panics.

use std::cmp::Ordering;
use std::ops::{Add, Mul, Neg, Sub};

use super::LatticePoint;

/// Runs `$f::<T>($args)` with the narrowest exact integer `T` for the points `$pts`.
macro_rules! with_exact_width {
    ($pts:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        match $crate::intersect::width_for($pts) {
            $crate::intersect::Width::I64 => $f::<i64>($($arg),*),
            $crate::intersect::Width::I128 => $f::<i128>($($arg),*),
            $crate::intersect::Width::I256 => {
                $f::<$crate::intersect::I256>($($arg),*)
            }
        }
    };
}

mod segment_tet;
mod separating_axis;
mod tet_tet;
mod tri_tri;

pub use segment_tet::segment_crosses_tet;
pub use separating_axis::{relative_interiors_meet, tets_intersect};
pub use tet_tet::{classify, classify_if, tets_cross, TetPairRelation};
pub use tri_tri::triangles_cross;

/// A tetrahedron (3-simplex) in R^4 given by its four lattice vertices. Its orientation is
/// that of the normal N = cross3(b−a, c−a, d−a), N·x = det[b−a, c−a, d−a, x].
pub type LatticeTet = [LatticePoint; 4];

/// A triangle in R^4 given by its three lattice vertices.
pub type LatticeTriangle = [LatticePoint; 3];

// ---------------------------------------------------------------------------------------
// Exact integer arithmetic shared by the predicates of this module.
// ---------------------------------------------------------------------------------------

/// Largest coordinate spread for which `i64` is exact (24 M^4 < 2^63).
const SPREAD_I64: i64 = 1 << 14;
/// Largest coordinate spread for which `i128` is exact (24 M^4 < 2^127).
const SPREAD_I128: i64 = 1 << 30;

/// Which integer type a call computes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Width {
    I64,
    I128,
    I256,
}

/// The narrowest exact width for predicates on `points` (by their coordinate spread).
fn width_for(points: &[LatticePoint]) -> Width {
    let mut spread = 0i64;
    for k in 0..4 {
        let mut lo = i64::MAX;
        let mut hi = i64::MIN;
        for p in points {
            let v = i64::from(p[k]);
            lo = lo.min(v);
            hi = hi.max(v);
        }
        spread = spread.max(hi - lo);
    }
    if spread <= SPREAD_I64 {
        Width::I64
    } else if spread <= SPREAD_I128 {
        Width::I128
    } else {
        Width::I256
    }
}

/// An exact signed integer ring. Implementations must not overflow on the values this
/// module feeds them (guaranteed by [`width_for`]).
trait Exact:
    Copy
    + Ord
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Neg<Output = Self>
{
    const ZERO: Self;
    fn from_i64(v: i64) -> Self;
}

impl Exact for i64 {
    const ZERO: Self = 0;
    fn from_i64(v: i64) -> Self {
        v
    }
}

impl Exact for i128 {
    const ZERO: Self = 0;
    fn from_i64(v: i64) -> Self {
        i128::from(v)
    }
}

/// A 256-bit two's-complement integer (little-endian 64-bit limbs). Only what the
/// predicates need: wrapping add, sub, mul, neg and signed comparison. Wrapping is never
/// observed because every value fits (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct I256([u64; 4]);

impl I256 {
    fn is_negative(self) -> bool {
        self.0[3] >> 63 == 1
    }
}

impl Exact for I256 {
    const ZERO: Self = I256([0; 4]);
    fn from_i64(v: i64) -> Self {
        let ext = if v < 0 { u64::MAX } else { 0 };
        I256([v as u64, ext, ext, ext])
    }
}

impl Add for I256 {
    type Output = Self;
    fn add(self, rhs: Self) -> Self {
        let mut out = [0u64; 4];
        let mut carry = false;
        for (i, o) in out.iter_mut().enumerate() {
            let (s1, c1) = self.0[i].overflowing_add(rhs.0[i]);
            let (s2, c2) = s1.overflowing_add(u64::from(carry));
            *o = s2;
            carry = c1 || c2;
        }
        I256(out)
    }
}

impl Neg for I256 {
    type Output = Self;
    fn neg(self) -> Self {
        I256(self.0.map(|l| !l)) + I256([1, 0, 0, 0])
    }
}

impl Sub for I256 {
    type Output = Self;
    fn sub(self, rhs: Self) -> Self {
        self + (-rhs)
    }
}

impl Mul for I256 {
    type Output = Self;
    fn mul(self, rhs: Self) -> Self {
        // Schoolbook product truncated to 256 bits: modulo 2^256 the two's-complement
        // product equals the unsigned one.
        let mut out = [0u64; 4];
        for i in 0..4 {
            let mut carry: u128 = 0;
            for j in 0..4 - i {
                let t =
                    u128::from(self.0[i]) * u128::from(rhs.0[j]) + u128::from(out[i + j]) + carry;
                out[i + j] = t as u64;
                carry = t >> 64;
            }
        }
        I256(out)
    }
}

impl Ord for I256 {
    fn cmp(&self, other: &Self) -> Ordering {
        match (self.is_negative(), other.is_negative()) {
            (true, false) => Ordering::Less,
            (false, true) => Ordering::Greater,
            // Same sign: two's-complement order is the unsigned order of the limbs.
            _ => self.0.iter().rev().cmp(other.0.iter().rev()),
        }
    }
}

impl PartialOrd for I256 {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// A point or vector in the chosen width.
type V4<T> = [T; 4];

/// Sign of `v` as -1, 0 or 1.
fn sign<T: Exact>(v: T) -> i8 {
    match v.cmp(&T::ZERO) {
        Ordering::Less => -1,
        Ordering::Equal => 0,
        Ordering::Greater => 1,
    }
}

/// `p − o` in the chosen width (exact: |difference| < 2^32 fits `i64`).
fn rel<T: Exact>(p: &LatticePoint, o: &LatticePoint) -> V4<T> {
    [0, 1, 2, 3].map(|k| T::from_i64(i64::from(p[k]) - i64::from(o[k])))
}

fn sub4<T: Exact>(a: &V4<T>, b: &V4<T>) -> V4<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
}

fn dot4<T: Exact>(a: &V4<T>, b: &V4<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// det of the 4x4 matrix with rows u, v, w, x (Laplace expansion by the 2x2 minors of
/// the first two rows).
fn det4<T: Exact>(u: &V4<T>, v: &V4<T>, w: &V4<T>, x: &V4<T>) -> T {
    let t = |i: usize, j: usize| u[i] * v[j] - u[j] * v[i];
    let s = |i: usize, j: usize| w[i] * x[j] - w[j] * x[i];
    t(0, 1) * s(2, 3) - t(0, 2) * s(1, 3) + t(0, 3) * s(1, 2) + t(1, 2) * s(0, 3)
        - t(1, 3) * s(0, 2)
        + t(2, 3) * s(0, 1)
}

/// orient4(p0..p4) = det[p1−p0, p2−p0, p3−p0, p4−p0].
fn orient4<T: Exact>(p0: &V4<T>, p1: &V4<T>, p2: &V4<T>, p3: &V4<T>, p4: &V4<T>) -> T {
    det4(&sub4(p1, p0), &sub4(p2, p0), &sub4(p3, p0), &sub4(p4, p0))
}

/// N = cross3(u, v, w): the vector with N·x = det[u, v, w, x] for every x.
fn cross3<T: Exact>(u: &V4<T>, v: &V4<T>, w: &V4<T>) -> V4<T> {
    let m = |i: usize, j: usize| u[i] * v[j] - u[j] * v[i];
    // 3x3 determinant of rows u, v, w on columns i < j < k, expanded along w.
    let d3 = |i: usize, j: usize, k: usize| w[i] * m(j, k) - w[j] * m(i, k) + w[k] * m(i, j);
    [-d3(1, 2, 3), d3(0, 2, 3), -d3(0, 1, 3), d3(0, 1, 2)]
}

/// The four vertices of a tet relative to `origin`, in the chosen width.
fn rel_tet<T: Exact>(t: &LatticeTet, origin: &LatticePoint) -> [V4<T>; 4] {
    [
        rel(&t[0], origin),
        rel(&t[1], origin),
        rel(&t[2], origin),
        rel(&t[3], origin),
    ]
}

/// Three-valued result of a vertex test of DESIGN §4 on exact signs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    /// All values of one strict sign: a transversal crossing.
    Yes,
    /// Two values of strictly opposite sign: certainly no crossing here.
    No,
    /// No strict conflict but some value is zero: a degenerate (touching) position.
    Degenerate,
}

/// [`Outcome`] of "the `n` signs `sign(0)`, …, `sign(n − 1)` have one strict sign",
/// evaluating them in order and stopping at the first strict conflict.
fn common_strict_sign(n: usize, mut sign: impl FnMut(usize) -> i8) -> Outcome {
    let (mut pos, mut neg, mut zero) = (false, false, false);
    for k in 0..n {
        let s = sign(k);
        pos |= s > 0;
        neg |= s < 0;
        zero |= s == 0;
        if pos && neg {
            return Outcome::No;
        }
    }
    if zero {
        Outcome::Degenerate
    } else {
        Outcome::Yes
    }
}

/// Edges of a tet as vertex index pairs (i < j), in a fixed order.
const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];
/// Triangles of a tet, `TET_TRIANGLES[v]` = the face opposite vertex v, increasing order.
const TET_TRIANGLES: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// Index in [`TET_EDGES`] of the edge {i, j} (i ≠ j).
fn edge_index(i: usize, j: usize) -> usize {
    let (i, j) = if i < j { (i, j) } else { (j, i) };
    match (i, j) {
        (0, 1) => 0,
        (0, 2) => 1,
        (0, 3) => 2,
        (1, 2) => 3,
        (1, 3) => 4,
        _ => 5,
    }
}

/// Deterministic pseudo-random numbers (xorshift) for the unit tests of this crate and the
/// layers above it (feature `test-support`).
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub mod test_rng {
    use super::LatticeTet;

    /// A xorshift64 generator.
    pub struct Rng(pub u64);

    impl Rng {
        /// The next number.
        pub fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        /// A number in `lo..=hi`.
        pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
            lo + (self.next() % (hi - lo + 1) as u64) as i64
        }
        /// A tet of lattice points with coordinates in `lo..=hi`.
        pub fn tet(&mut self, lo: i32, hi: i32) -> LatticeTet {
            [0; 4].map(|_| [0; 4].map(|_| self.range(i64::from(lo), i64::from(hi)) as i32))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::test_rng::Rng;

    fn to_i128(v: I256) -> Option<i128> {
        let lo = u128::from(v.0[0]) | (u128::from(v.0[1]) << 64);
        let hi_ok = if (lo as i128) < 0 {
            v.0[2] == u64::MAX && v.0[3] == u64::MAX
        } else {
            v.0[2] == 0 && v.0[3] == 0
        };
        hi_ok.then_some(lo as i128)
    }

    #[test]
    fn i256_matches_i128() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for _ in 0..20_000 {
            let a = rng.range(-(1 << 40), 1 << 40) * rng.range(-(1 << 20), 1 << 20);
            let b = rng.range(-(1 << 40), 1 << 40) * rng.range(-(1 << 20), 1 << 20);
            let (x, y) = (I256::from_i64(a), I256::from_i64(b));
            let (a, b) = (i128::from(a), i128::from(b));
            assert_eq!(to_i128(x + y), Some(a + b));
            assert_eq!(to_i128(x - y), Some(a - b));
            assert_eq!(to_i128(-x), Some(-a));
            // |a|, |b| < 2^61: the product fits i128.
            assert_eq!(to_i128(x * y), Some(a * b));
            assert_eq!(x.cmp(&y), a.cmp(&b));
            assert_eq!(sign(x * y), sign(a * b));
        }
        // Beyond i128: (2^100)^2 = 2^200 > 0, and -(2^200) < 2^200.
        let big = I256::from_i64(1 << 50) * I256::from_i64(1 << 50);
        let sq = big * big;
        assert!(sq > big && -sq < I256::ZERO && -sq < -big);
    }

    #[test]
    fn cross3_is_the_cofactor_vector_of_det4() {
        let mut rng = Rng(12345);
        for _ in 0..2_000 {
            let mut r = || [0; 4].map(|_: i64| rng.range(-1000, 1000));
            let (u, v, w, x) = (r(), r(), r(), r());
            let n = cross3(&u, &v, &w);
            assert_eq!(dot4(&n, &x), det4(&u, &v, &w, &x));
            assert_eq!(det4(&u, &v, &w, &x), -det4(&v, &u, &w, &x));
        }
    }

    #[test]
    fn det4_agrees_with_the_kernel_and_across_widths() {
        let mut rng = Rng(777);
        for _ in 0..2_000 {
            let mut r = || [0; 4].map(|_: i32| rng.range(-3000, 3000) as i32);
            let (a, b, c, d, e) = (r(), r(), r(), r(), r());
            let o = [0, 0, 0, 0];
            let want = crate::orient4_i128([&a, &b, &c, &d, &e]);
            let l64 = [a, b, c, d, e].map(|p| rel::<i64>(&p, &o));
            let l256 = [a, b, c, d, e].map(|p| rel::<I256>(&p, &o));
            assert_eq!(
                i128::from(orient4(&l64[0], &l64[1], &l64[2], &l64[3], &l64[4])),
                want
            );
            let got = orient4(&l256[0], &l256[1], &l256[2], &l256[3], &l256[4]);
            assert_eq!(to_i128(got), Some(want));
        }
    }

    #[test]
    fn width_is_chosen_by_spread() {
        let o = [0, 0, 0, 0];
        assert_eq!(width_for(&[o, [1 << 14, 0, 0, 0]]), Width::I64);
        assert_eq!(width_for(&[o, [0, (1 << 14) + 1, 0, 0]]), Width::I128);
        assert_eq!(width_for(&[o, [0, 0, 0, 1 << 30]]), Width::I128);
        assert_eq!(width_for(&[[i32::MIN; 4], [i32::MAX; 4]]), Width::I256);
        // Far from the origin but close together: still i64.
        assert_eq!(width_for(&[[i32::MAX; 4], [i32::MAX - 5; 4]]), Width::I64);
    }

    #[test]
    fn edge_index_inverts_the_edge_table() {
        for (k, e) in TET_EDGES.iter().enumerate() {
            assert_eq!(edge_index(e[0], e[1]), k);
            assert_eq!(edge_index(e[1], e[0]), k);
        }
    }
}
