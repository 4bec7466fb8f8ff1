//! Rotation with time fixed (the interference paper's third resolution,
//! docs/methods/interference.md#rotation-with-time-fixed): the smallest turn of one body
//! about a given axis, the same at every instant, that clears it of every other body,
//! verified exactly like the other suggestions ([`resolve`]).
//!
//! **Exact rotations.** A rotation by the integer quaternion q = (a, k·u), u an integer
//! direction with s = |u|², has the rational matrix R = M/n with the integer matrix
//! M = (a² − k²s)·I + 2k²·u·uᵀ + 2ak·\[u\]ₓ and n = a² + k²s (divided by the gcd of M's
//! entries and n): MᵀM = n²·I and det M = n³ > 0. Its angle is 2·atan(k·√s/a), so the
//! parameter τ = k/a runs over the rationals, and the angles it gives are dense. Every body
//! is put on a lattice n times finer about the rotation point p (a lattice point): the
//! moved body by x → M·(x − p) in space and t → n·(t − p_t) in time, the others by
//! x → n·(x − p) on all four axes. That is the rotation scaled by n, so every predicate on
//! the result is the exact answer for the rotated body; coordinates stay multiples of 8
//! (interior points of tets stay lattice points) and within ±2^29 (which bounds n). The
//! moved body's tree is refitted and its normals mapped ([`Placement::place_linear`]);
//! the others are scaled as they are read, not placed.
//!
//! **Search.** For each sense (first the one the overlap shrinks in: dV/dθ from the
//! seed's gradient, the sum over the moved body's tets inside the others of N/6 · (u × r)),
//! the angle grows by doubling from a half-voxel turn at the body's farthest point until
//! one clears, then the bracket [last failing, first clearing] is bisected over the
//! reachable rationals (each step the simplest rational in its middle half: the smallest
//! n) until the farthest point's arc across it is an eighth of a voxel, or no reachable
//! angle lies inside. The other sense is searched only below the first sense's answer. A
//! candidate is refuted, when it can be, by a witness: a tet of the moved body that was
//! inside another body and whose rotated interior point still is (one exact ray, against
//! the other body scaled as it is read, `Inclusion::scaled`: no placement); a clear
//! verdict always comes from the full exact check. Clearing need not be monotone in the
//! angle, so the answer is the least the search finds, not proven minimal.

use super::inclusion::Inclusion;
use super::labels::Label;
use super::resolve::{clears_scaled, meet, Meet};
use super::*;
use chronotope_kernel::float::tet_normal as float_normal;
use chronotope_mesh::slice::{slice_mesh, PlaneValue};
use std::f64::consts::PI;

/// Most candidate angles tried per suggestion, both senses together.
pub const MAX_ANGLES: usize = 48;

/// Most full exact checks per suggestion (every candidate a witness does not refute).
pub const MAX_FULL_CHECKS: usize = 24;

/// Largest component of the integer direction that stands for the axis asked for.
pub const MAX_AXIS_COMPONENT: i64 = 12;

/// An axis direction within this angle of the one asked for is taken at once (the
/// smallest integer direction that close).
const AXIS_TOLERANCE_RAD: f64 = 0.5 * PI / 180.0;

/// Coordinates on the finer lattice stay within ±2^29 (the predicates' far points add a
/// few thousand and must fit ±2^30).
const COORDINATE_LIMIT: f64 = (1u64 << 29) as f64;

/// Witnesses tried per candidate angle before a full check.
const WITNESSES: usize = 256;

/// Sample tets of the moved body kept as witnesses, per other body.
const MAX_SAMPLES: usize = 4000;

/// What a rotation suggestion is asked about: the axis, a point on it and the largest
/// angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationSpec {
    /// Direction of the axis (any length but zero).
    pub axis: [f64; 3],
    /// A point on the axis (m); `None`: the moved body's centroid at its first contact
    /// (the centroid of its section at the first frame at or after it).
    pub point_m: Option<[f64; 3]>,
    /// The largest angle tried in either sense (rad, at most π); 0: no rotation suggested.
    pub max_rad: f64,
}

impl Default for RotationSpec {
    /// The vertical axis through the body's centroid at first contact, up to half a turn.
    fn default() -> Self {
        Self {
            axis: [0.0, 0.0, 1.0],
            point_m: None,
            max_rad: PI,
        }
    }
}

/// An integer direction standing for an axis given in floats.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntegerAxis {
    /// The direction (components without a common factor).
    pub u: [i64; 3],
    /// Angle between it and the axis asked for (rad).
    pub deviation_rad: f64,
}

impl IntegerAxis {
    /// The smallest integer direction (largest component 1, 2, … up to
    /// [`MAX_AXIS_COMPONENT`]) within half a degree of `axis`, or the closest of them;
    /// `None` for a zero or non-finite axis. Small components keep n small, so the
    /// reachable angles fine.
    pub fn near(axis: [f64; 3]) -> Option<Self> {
        let len = axis.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(len.is_finite() && len > 0.0) {
            return None;
        }
        let unit = axis.map(|c| c / len);
        let top = unit.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        let mut best: Option<Self> = None;
        for d in 1..=MAX_AXIS_COMPONENT {
            let u = unit.map(|c| (c / top * d as f64).round() as i64);
            let g = u.iter().fold(0, |g, &c| gcd64(g, c.unsigned_abs())).max(1) as i64;
            let u = u.map(|c| c / g);
            let deviation = angle_between(&u.map(|c| c as f64), &unit);
            let candidate = Self {
                u,
                deviation_rad: deviation,
            };
            if deviation <= AXIS_TOLERANCE_RAD {
                return Some(candidate);
            }
            if best.is_none_or(|b| deviation < b.deviation_rad) {
                best = Some(candidate);
            }
        }
        best
    }

    /// |u|².
    fn norm2(&self) -> i64 {
        self.u.iter().map(|c| c * c).sum()
    }

    /// The unit direction.
    pub fn unit(&self) -> [f64; 3] {
        let len = (self.norm2() as f64).sqrt();
        self.u.map(|c| c as f64 / len)
    }
}

/// Angle between two non-zero vectors (rad).
fn angle_between(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let dot: f64 = (0..3).map(|k| a[k] * b[k]).sum();
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let c = cross.iter().map(|x| x * x).sum::<f64>().sqrt();
    c.atan2(dot)
}

/// A rotation about an integer axis with a rational matrix M/n.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RationalRotation {
    /// M (rows), with MᵀM = n²·I and det M = n³.
    pub matrix: [[i64; 3]; 3],
    /// The denominator n > 0.
    pub n: i64,
}

impl RationalRotation {
    /// The rotation by the quaternion (a, k·u) (a ≥ 0, not both zero): right-handed about
    /// u by 2·atan2(k·|u|, a), with M and n divided by their common factor. `None` if a
    /// number overflows `i64`.
    pub fn of(u: [i64; 3], k: i64, a: i64) -> Option<Self> {
        let s: i128 = u.iter().map(|&c| i128::from(c) * i128::from(c)).sum();
        let (k, a) = (i128::from(k), i128::from(a));
        let n = a * a + k * k * s;
        if n == 0 {
            return None;
        }
        let u = u.map(i128::from);
        let cross = [[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]];
        let mut m = [[0i128; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                let diagonal = if i == j { a * a - k * k * s } else { 0 };
                m[i][j] = diagonal + 2 * k * k * u[i] * u[j] + 2 * a * k * cross[i][j];
            }
        }
        let g = m
            .iter()
            .flatten()
            .fold(n.unsigned_abs(), |g, &x| gcd(g, x.unsigned_abs())) as i128;
        let matrix = m.map(|r| r.map(|x| i64::try_from(x / g).ok()));
        if matrix.iter().flatten().any(Option::is_none) {
            return None;
        }
        Some(Self {
            matrix: matrix.map(|r| r.map(|x| x.unwrap_or_default())),
            n: i64::try_from(n / g).ok()?,
        })
    }

    /// The map of the moved body onto the lattice n times finer about `p`:
    /// x → M·(x − p) in space, t → n·(t − p_t).
    pub fn about(&self, p: &LatticePoint) -> LinearMap {
        let mut matrix = [[0i64; 4]; 4];
        for (row, m) in matrix.iter_mut().zip(&self.matrix) {
            row[..3].copy_from_slice(m);
        }
        matrix[3][3] = self.n;
        let p = p.map(i64::from);
        let shift = [0, 1, 2, 3].map(|i| -(0..4).map(|j| matrix[i][j] * p[j]).sum::<i64>());
        LinearMap { matrix, shift }
    }
}

/// An angle of the search: τ = k/a = tan(θ/2)/|u| in lowest terms, its sense apart (a = 0:
/// half a turn).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Tau {
    k: i128,
    a: i128,
}

impl Tau {
    const ZERO: Tau = Tau { k: 0, a: 1 };
    const HALF_TURN: Tau = Tau { k: 1, a: 0 };

    fn angle(&self, axis: &IntegerAxis) -> f64 {
        2.0 * (self.k as f64 * (axis.norm2() as f64).sqrt()).atan2(self.a as f64)
    }

    /// The τ of angle θ ∈ [0, π) as a fraction (to 2^-30), or a half turn.
    fn of_angle(theta: f64, axis: &IntegerAxis) -> Tau {
        if theta >= PI {
            return Tau::HALF_TURN;
        }
        let t = (theta / 2.0).tan() / (axis.norm2() as f64).sqrt();
        Tau {
            k: (t * f64::from(1 << 30)).round() as i128,
            a: 1 << 30,
        }
    }

    fn less(&self, other: &Tau) -> bool {
        self.k * other.a < other.k * self.a
    }

    /// The larger of this and `other`, if any.
    fn max_of(self, other: Option<Tau>) -> Tau {
        match other {
            Some(o) if self.less(&o) => o,
            _ => self,
        }
    }
}

/// The simplest fraction strictly between `lo` and `hi` (`hi` `None`: no upper end), for
/// 0 ≤ lo < hi: the one with the smallest numerator and denominator (continued fractions).
fn simplest_between(lo: Tau, hi: Option<Tau>) -> Tau {
    let floor = lo.k.div_euclid(lo.a);
    let next = floor + 1;
    let Some(hi) = hi.filter(|h| h.a != 0) else {
        return Tau { k: next, a: 1 };
    };
    if next * hi.a < hi.k {
        return Tau { k: next, a: 1 };
    }
    // floor ≤ lo < hi ≤ floor + 1: floor + 1/z with z strictly between 1/(hi − floor)
    // and 1/(lo − floor).
    let l = Tau {
        k: lo.k - floor * lo.a,
        a: lo.a,
    };
    let h = Tau {
        k: hi.k - floor * hi.a,
        a: hi.a,
    };
    let z = simplest_between(
        Tau { k: h.a, a: h.k },
        (l.k != 0).then_some(Tau { k: l.a, a: l.k }),
    );
    Tau {
        k: floor * z.k + z.a,
        a: z.k,
    }
}

/// A suggested rotation, in checker lattice units.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotation {
    /// The axis direction used.
    pub axis: IntegerAxis,
    /// The rotation point (checker coordinates; its time is the frame whose section gave
    /// the default point, or the first contact's frame).
    pub point: LatticePoint,
    /// The angle, right-handed about the axis (rad).
    pub angle_rad: f64,
    /// The lattice refinement n of its exact matrix.
    pub n: i64,
    /// The rotated body was checked against every other body and nothing interferes.
    pub verified_clear: bool,
    /// The largest angle of the same sense tried that does not clear (the answer's
    /// bracket), if one was.
    pub failing_rad: Option<f64>,
    /// Why it does not clear.
    pub reason: Option<String>,
    /// Angles the search tried, and of those checked in full (the others a witness
    /// refuted).
    pub tried: (usize, usize),
}

/// What the cheap tests say of a candidate angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// It interferes, proven: a witness inside, or a tet pair that interferes.
    Interferes,
    /// No tet pair interferes (proven), so it clears unless a part of one body lies wholly
    /// inside the other: the full check decides.
    NoPairInterferes,
    /// Its n is beyond the lattice's room, or a map does not fit.
    Unreachable,
}

/// A sample tet of the moved body that was inside another body.
#[derive(Debug, Clone, Copy)]
struct Witness {
    tet: u32,
    other: usize,
}

/// The search's state: the bodies, the placements it reuses, its witnesses and budget.
struct Search<'a> {
    a: &'a Prepared,
    others: &'a [&'a Prepared],
    axis: IntegerAxis,
    point: LatticePoint,
    /// Largest n the lattice has room for.
    n_max: i64,
    moved: Placement<'a>,
    /// Witnesses in the order they are tried: the latest that refuted an angle first.
    witnesses: Vec<Witness>,
    /// The node pairs of [`pair_interferes`]'s walk.
    stack: Vec<(u32, u32)>,
    angles: usize,
    full_checks: usize,
}

impl Search<'_> {
    /// The rotation of parameter τ in sense `sense`.
    fn rotation(&self, tau: Tau, sense: i128) -> Option<RationalRotation> {
        let k = i64::try_from(sense * tau.k).ok()?;
        let a = i64::try_from(tau.a).ok()?;
        RationalRotation::of(self.axis.u, k, a)
    }

    /// Whether the parameter can be tried: its n fits the lattice.
    fn reachable(&self, tau: Tau) -> bool {
        self.rotation(tau, 1).is_some_and(|r| r.n <= self.n_max)
    }

    fn budget_left(&self) -> bool {
        self.angles < MAX_ANGLES && self.full_checks < MAX_FULL_CHECKS
    }

    /// The cheap tests of one angle: witnesses first, then every tet pair of the rotated
    /// body against every other body's, mapped as they are read ([`pair_interferes`]).
    fn evaluate(&mut self, tau: Tau, sense: i128) -> Verdict {
        let Some(rot) = self.rotation(tau, sense).filter(|r| r.n <= self.n_max) else {
            return Verdict::Unreachable;
        };
        self.angles += 1;
        let map = rot.about(&self.point);
        if let Some(i) = self.refuting_witness(&map, rot.n) {
            let w = self.witnesses.remove(i);
            self.witnesses.insert(0, w);
            return Verdict::Interferes;
        }
        let Some(moved) = View::linear(self.a, map) else {
            return Verdict::Unreachable;
        };
        for b in self.others {
            match View::scaled(b, rot.n, &self.point) {
                Some(other) if pair_interferes(&moved, &other, &mut self.stack) => {
                    return Verdict::Interferes
                }
                Some(_) => {}
                None => return Verdict::Unreachable,
            }
        }
        Verdict::NoPairInterferes
    }

    /// The full exact check of one angle: the rotated body placed on the finer lattice and
    /// checked against each other body scaled onto it as the checker checks a pair
    /// ([`clears_scaled`]: the others are scaled as they are read, not placed). `None` if
    /// a body does not fit.
    fn verify(&mut self, tau: Tau, sense: i128) -> Option<bool> {
        let rot = self.rotation(tau, sense).filter(|r| r.n <= self.n_max)?;
        self.full_checks += 1;
        let moved = self.moved.place_linear(&rot.about(&self.point))?;
        clears_scaled(moved, self.others, rot.n, self.point)
    }

    /// The first witness (of at most [`WITNESSES`]) whose tet, mapped by `map`, has its
    /// interior point inside its other body scaled by `n` about the point: then the
    /// rotated body interferes with it (see [`mapped_tet_inside`]).
    fn refuting_witness(&self, map: &LinearMap, n: i64) -> Option<usize> {
        let mut tests: Vec<Option<Inclusion>> = self
            .others
            .iter()
            .map(|b| Inclusion::with_normals(&b.mesh, &b.bvh, &b.normals).scaled(n, self.point))
            .collect();
        // The latest refuters and those nearest the axis first, then some from all radii.
        let near = WITNESSES / 2;
        let spread = (self.witnesses.len().saturating_sub(near) / (WITNESSES - near)).max(1);
        let tried = (0..self.witnesses.len().min(near))
            .chain((near..self.witnesses.len()).step_by(spread))
            .take(WITNESSES);
        tried.into_iter().find(|&i| {
            let w = self.witnesses[i];
            {
                let Some(test) = tests[w.other].as_mut() else {
                    return false;
                };
                let mut tet = tet_of(&self.a.mesh, w.tet);
                for p in &mut tet {
                    match map.apply(p) {
                        Some(q) => *p = q,
                        None => return false,
                    }
                }
                test.contains(&interior_point(&tet, &INTERIOR_WEIGHTS[0])) == Some(true)
            }
        })
    }
}

/// A prepared body seen through an affine map, its tree's boxes, tets and normals mapped
/// as they are read (no placement).
struct View<'a> {
    body: &'a Prepared,
    map: LinearMap,
    /// The map of its normals (see [`LinearMap`]), in `i64`.
    normal_map: [[i64; 4]; 4],
}

impl<'a> View<'a> {
    /// `body` mapped by `map`, if its image fits ±2^30 and the normal map `i64` with
    /// entries below 2^30 (so that a normal's image is exact in `i64`).
    fn linear(body: &'a Prepared, map: LinearMap) -> Option<Self> {
        let normal_map = map.normal_map()?;
        if normal_map.iter().flatten().any(|c| c.abs() >= 1 << 30) {
            return None;
        }
        let root = body.bvh.aabb().affine_image(&map.matrix, &map.shift)?;
        if !root.is_empty() && (0..4).any(|k| root.min[k] <= -(1 << 30) || root.max[k] >= 1 << 30) {
            return None;
        }
        Some(Self {
            body,
            map,
            normal_map: normal_map.map(|r| r.map(|c| c as i64)),
        })
    }

    /// `body` scaled by `n` about `p` on every axis.
    fn scaled(body: &'a Prepared, n: i64, p: &LatticePoint) -> Option<Self> {
        let mut matrix = [[0; 4]; 4];
        for (k, row) in matrix.iter_mut().enumerate() {
            row[k] = n;
        }
        let shift = p.map(|c| -i64::from(c) * n);
        Self::linear(body, LinearMap { matrix, shift })
    }

    fn image(&self, b: &chronotope_kernel::Aabb4) -> chronotope_kernel::Aabb4 {
        // Inside the root's image, which fits.
        b.affine_image(&self.map.matrix, &self.map.shift)
            .unwrap_or(chronotope_kernel::Aabb4::EMPTY)
    }

    fn tet(&self, i: u32) -> [LatticePoint; 4] {
        tet_of(&self.body.mesh, i).map(|p| {
            [0, 1, 2, 3].map(|k| {
                let row = &self.map.matrix[k];
                let v: i128 = (0..4).map(|j| i128::from(row[j]) * i128::from(p[j])).sum();
                (v + i128::from(self.map.shift[k])) as i32
            })
        })
    }

    fn normal(&self, i: u32, tet: &[LatticePoint; 4]) -> [i32; 4] {
        let n = self.body.normals[i as usize];
        if n == NO_NORMAL {
            return tet_normal(*tet);
        }
        let m = self
            .normal_map
            .map(|row| (0..4).map(|j| row[j] * i64::from(n[j])).sum::<i64>());
        normal_in_i32(m.map(i128::from))
    }
}

/// Whether some tet of `a` and some tet of `b`, both as seen, interfere as the checker's
/// walk decides it (their relative interiors cross, or they overlap in one hyperplane
/// facing the same way): exact, and complete for tet pairs, with containment left to the
/// full check. The trees are walked against each other with their boxes mapped as they
/// are reached (an image of a box holds the images of what it holds), and each pair is
/// filtered as the walk filters a pair whose touching does not matter.
fn pair_interferes(a: &View, b: &View, stack: &mut Vec<(u32, u32)>) -> bool {
    let (ta, tb) = (&a.body.bvh, &b.body.bvh);
    if ta.nodes().is_empty() || tb.nodes().is_empty() {
        return false;
    }
    stack.clear();
    stack.push((0, 0));
    while let Some((i, j)) = stack.pop() {
        let (na, nb) = (ta.nodes()[i as usize], tb.nodes()[j as usize]);
        if !a.image(&na.aabb).overlaps(&b.image(&nb.aabb)) {
            continue;
        }
        match (na.is_leaf(), nb.is_leaf()) {
            (true, true) => {
                for sa in na.slots() {
                    let box_a = a.image(&ta.leaf_boxes()[sa]);
                    let ia = ta.order()[sa];
                    let tet_a = a.tet(ia);
                    let normal_a = a.normal(ia, &tet_a);
                    for sb in nb.slots() {
                        if !box_a.overlaps(&b.image(&tb.leaf_boxes()[sb])) {
                            continue;
                        }
                        let ib = tb.order()[sb];
                        let tet_b = b.tet(ib);
                        if tets_interfere(&tet_a, &normal_a, &tet_b, &b.normal(ib, &tet_b)) {
                            return true;
                        }
                    }
                }
            }
            (false, true) => stack.extend([(na.first, j), (na.first + 1, j)]),
            (true, false) => stack.extend([(i, nb.first), (i, nb.first + 1)]),
            (false, false) => stack.extend([
                (na.first, nb.first),
                (na.first, nb.first + 1),
                (na.first + 1, nb.first),
                (na.first + 1, nb.first + 1),
            ]),
        }
    }
    false
}

/// Whether two tets interfere, as the walk's `visit` decides when touching does not
/// matter ([`meet`]).
fn tets_interfere(
    ta: &[LatticePoint; 4],
    na: &[i32; 4],
    tb: &[LatticePoint; 4],
    nb: &[i32; 4],
) -> bool {
    meet(ta, na, tb, nb, false) == Meet::Interferes
}

/// What one sense's search found: its smallest clearing parameter, with the largest
/// failing one below it, and the largest parameter tried.
#[derive(Debug, Clone, Copy, Default)]
struct SenseResult {
    clear: Option<Tau>,
    failing: Option<Tau>,
    largest_tried: Option<Tau>,
}

/// Suggests a rotation of `a` about `spec`'s axis that clears every body of `others`
/// (`results[i]` is the check of `a` against `others[i]`); `None` if nothing interferes,
/// no rotation is asked for, or the axis is zero.
pub fn suggest_rotation(
    a: &Prepared,
    others: &[&Prepared],
    results: &[&PairResult],
    lat: &CommonLattice,
    spec: &RotationSpec,
) -> Option<Rotation> {
    if !results.iter().any(|r| r.interfering()) || spec.max_rad.is_nan() || spec.max_rad <= 0.0 {
        return None;
    }
    let started = std::time::Instant::now();
    let max_rad = spec.max_rad.min(PI);
    let axis = IntegerAxis::near(spec.axis)?;
    let point = rotation_point(a, results, lat, spec)?;
    let unit = axis.unit();
    let per_step = lat.per_step() as f64;
    let r_max = farthest_from_axis(a, &point, &unit).max(per_step);
    let mut search = Search {
        a,
        others,
        axis,
        point,
        n_max: room(a, others, &point),
        moved: Placement::new(a),
        witnesses: witnesses(a, results, &point, &unit),
        stack: Vec::new(),
        angles: 0,
        full_checks: 0,
    };
    let first = if turn_rate(a, results, &point, &unit) > 0.0 {
        -1
    } else {
        1
    };
    // Bisection stops when the farthest point's arc across the bracket is 1/8 voxel.
    let tolerance = per_step / 8.0 / r_max;
    let start = (per_step / 2.0 / r_max).min(max_rad);
    let one = search_sense(&mut search, first, start, max_rad, true, tolerance);
    let limit = one.clear.map_or(max_rad, |t| t.angle(&axis));
    let two = search_sense(&mut search, -first, start, limit, false, tolerance);
    let (sense, found) = match (one.clear, two.clear) {
        (_, Some(_)) => (-first, two),
        (Some(_), None) => (first, one),
        (None, None) => (first, one),
    };
    let signed = |t: Tau| sense as f64 * t.angle(&axis);
    let n_of = |t: Tau| search.rotation(t, sense).map_or(0, |r| r.n);
    tracing::debug!(
        body = %a.id,
        tets = a.mesh.tets.len(),
        others = others.iter().map(|b| b.mesh.tets.len()).sum::<usize>(),
        angles = search.angles,
        full_checks = search.full_checks,
        ms = started.elapsed().as_secs_f64() * 1e3,
        clear = found.clear.map(signed),
        "rotation search"
    );
    if let Some(clear) = found.clear {
        return Some(Rotation {
            axis,
            point,
            angle_rad: signed(clear),
            n: n_of(clear),
            verified_clear: true,
            failing_rad: found.failing.map(signed),
            reason: None,
            tried: (search.angles, search.full_checks),
        });
    }
    let largest = found.largest_tried;
    let reason = if search.budget_left() {
        format!(
            "no angle tried up to {:.1}° in either sense clears ({} angles tried, {} checked in \
             full)",
            max_rad.to_degrees(),
            search.angles,
            search.full_checks
        )
    } else {
        format!(
            "the search stopped after {} angles ({} checked in full) without one that clears",
            search.angles, search.full_checks
        )
    };
    Some(Rotation {
        axis,
        point,
        angle_rad: largest.map_or(0.0, signed),
        n: largest.map_or(0, n_of),
        verified_clear: false,
        failing_rad: largest.map(signed),
        reason: Some(reason),
        tried: (search.angles, search.full_checks),
    })
}

/// One sense's search: grow by doubling from `start` (rad) up to `limit` (included when
/// `to_limit`, below it otherwise) until no tet pair interferes, then bisect the bracket to
/// `tolerance` (rad), and verify the smallest angle without an interfering pair in full; if
/// a part of one body lies inside the other there, that angle fails and the search goes on
/// above it.
fn search_sense(
    s: &mut Search,
    sense: i128,
    start: f64,
    limit: f64,
    to_limit: bool,
    tolerance: f64,
) -> SenseResult {
    let axis = s.axis;
    let mut out = SenseResult::default();
    let mut failing = Tau::ZERO;
    let top = Tau::of_angle(limit, &axis);
    // Angles above `failing` where no tet pair interferes, in increasing order: not
    // verified yet.
    let mut open: Vec<Tau> = Vec::new();
    let mut target = start;
    loop {
        if open.is_empty() {
            // Grow: each target's simplest parameter above the last failing one.
            loop {
                if !s.budget_left() {
                    break;
                }
                let last = target >= limit;
                let goal = if last {
                    top
                } else {
                    Tau::of_angle(target, &axis)
                };
                let tau = if last && to_limit && s.reachable(top) {
                    top
                } else {
                    simplest_between(failing, Some(goal))
                };
                target = (target * 2.0).min(limit);
                if failing.less(&tau) && (tau.less(&top) || (to_limit && tau == top)) {
                    match s.evaluate(tau, sense) {
                        Verdict::Interferes => {
                            out.largest_tried = Some(tau);
                            failing = tau;
                        }
                        Verdict::NoPairInterferes => {
                            out.largest_tried = Some(tau.max_of(out.largest_tried));
                            open.push(tau);
                            break;
                        }
                        Verdict::Unreachable => {}
                    }
                }
                if last {
                    break;
                }
            }
        }
        if open.is_empty() {
            break;
        }
        // Bisect between the last failing angle and the lowest open one: the simplest
        // parameter in the middle half, else the simplest in all of it.
        loop {
            let upper = open[0];
            let (lo, hi) = (failing.angle(&axis), upper.angle(&axis));
            if hi - lo <= tolerance || !s.budget_left() {
                break;
            }
            let inner = simplest_between(
                Tau::of_angle(lo + (hi - lo) / 4.0, &axis),
                Some(Tau::of_angle(hi - (hi - lo) / 4.0, &axis)),
            );
            let inside = |t: &Tau| failing.less(t) && t.less(&upper);
            let tau = if inside(&inner) && s.reachable(inner) {
                inner
            } else {
                simplest_between(failing, Some(upper))
            };
            if !(inside(&tau) && s.reachable(tau)) {
                break;
            }
            match s.evaluate(tau, sense) {
                Verdict::Interferes => failing = tau,
                Verdict::NoPairInterferes => open.insert(0, tau),
                Verdict::Unreachable => break,
            }
        }
        // Verify the lowest open angle in full.
        let upper = open.remove(0);
        match s.verify(upper, sense) {
            Some(true) => {
                out.clear = Some(upper);
                break;
            }
            Some(false) => failing = upper,
            None => {}
        }
        open.retain(|t| failing.less(t));
        if !s.budget_left() {
            break;
        }
    }
    out.failing = (failing != Tau::ZERO).then_some(failing);
    out
}

/// The rotation point on the checker lattice (a multiple of [`CHECKER_FACTOR`] on every
/// axis): `spec`'s point, or the centroid of `a`'s section at the first frame at or after
/// its first contact; its time is that frame's.
fn rotation_point(
    a: &Prepared,
    results: &[&PairResult],
    lat: &CommonLattice,
    spec: &RotationSpec,
) -> Option<LatticePoint> {
    let per_step = lat.per_step();
    let first = results
        .iter()
        .filter(|r| r.interfering())
        .filter_map(|r| r.first_contact())
        .fold(f64::INFINITY, f64::min);
    let (lo, hi) = a
        .mesh
        .vertices
        .iter()
        .fold((i32::MAX, i32::MIN), |(lo, hi), p| {
            (lo.min(p[3]), hi.max(p[3]))
        });
    if lo > hi {
        return None;
    }
    let frame = if first.is_finite() {
        ((first / per_step as f64).ceil() as i64 * per_step).clamp(i64::from(lo), i64::from(hi))
    } else {
        i64::from(lo)
    };
    let centre = match spec.point_m {
        Some(m) => {
            let c = lat.voxel0_centre;
            [0, 1, 2].map(|k| (m[k] - c[k]) / lat.resolution * per_step as f64)
        }
        None => section_centroid(a, frame)?,
    };
    let snap = |x: f64| {
        let f = f64::from(CHECKER_FACTOR);
        let v = (x / f).round() * f;
        (v.is_finite() && v.abs() < COORDINATE_LIMIT).then_some(v as i32)
    };
    Some([
        snap(centre[0])?,
        snap(centre[1])?,
        snap(centre[2])?,
        i32::try_from(frame).ok()?,
    ])
}

/// The centroid of `a`'s 3D section at checker time `t` (checker units), from the
/// section's closed triangle mesh (a frame's section is that frame's meshed occupancy).
fn section_centroid(a: &Prepared, t: i64) -> Option<[f64; 3]> {
    let section = slice_mesh(&[&a.mesh], 3, PlaneValue::lattice(t));
    let o = *section.vertices.first()?;
    let (mut volume, mut moment) = (0.0, [0.0; 3]);
    for tri in &section.triangles {
        let v = tri.map(|i| {
            let p = section.vertices[i as usize];
            [p[0] - o[0], p[1] - o[1], p[2] - o[2]]
        });
        let det = v[0][0] * (v[1][1] * v[2][2] - v[1][2] * v[2][1])
            - v[0][1] * (v[1][0] * v[2][2] - v[1][2] * v[2][0])
            + v[0][2] * (v[1][0] * v[2][1] - v[1][1] * v[2][0]);
        volume += det;
        for k in 0..3 {
            moment[k] += det * (v[0][k] + v[1][k] + v[2][k]) / 4.0;
        }
    }
    if volume.abs() <= f64::EPSILON {
        return None;
    }
    Some([0, 1, 2].map(|k| o[k] + moment[k] / volume))
}

/// The largest distance of a vertex of `a` from the axis through `p` along `unit`
/// (checker units).
fn farthest_from_axis(a: &Prepared, p: &LatticePoint, unit: &[f64; 3]) -> f64 {
    a.mesh
        .vertices
        .iter()
        .map(|v| radius(&[0, 1, 2].map(|k| f64::from(v[k] - p[k])), unit))
        .fold(0.0, f64::max)
}

/// Distance of offset `d` from the axis along `unit`.
fn radius(d: &[f64; 3], unit: &[f64; 3]) -> f64 {
    let along: f64 = (0..3).map(|k| d[k] * unit[k]).sum();
    (d.iter().map(|x| x * x).sum::<f64>() - along * along)
        .max(0.0)
        .sqrt()
}

/// The largest n for which every body, mapped onto the lattice n times finer about `p`,
/// stays within ±2^29: n·|x − p| for the moved body (Euclidean in space, as a rotation
/// keeps it) and the others (per axis), bounded from their trees' boxes.
fn room(a: &Prepared, others: &[&Prepared], p: &LatticePoint) -> i64 {
    let d = |b: &chronotope_kernel::Aabb4, k: usize| {
        let (lo, hi) = (f64::from(b.min[k]), f64::from(b.max[k]));
        (lo - f64::from(p[k]))
            .abs()
            .max((hi - f64::from(p[k])).abs())
    };
    let ab = a.bvh.aabb();
    let space = (0..3).map(|k| d(&ab, k).powi(2)).sum::<f64>().sqrt().ceil();
    let mut extent = space.max(d(&ab, 3));
    for b in others {
        let bb = b.bvh.aabb();
        if !bb.is_empty() {
            extent = (0..4).fold(extent, |e, k| e.max(d(&bb, k)));
        }
    }
    (COORDINATE_LIMIT / extent.max(1.0)).floor() as i64
}

/// The sample tets of `a` inside each other body (INSIDE, then INTERFERENCE), nearest the
/// axis first: points near the axis move least, so they stay inside longest.
fn witnesses(
    a: &Prepared,
    results: &[&PairResult],
    p: &LatticePoint,
    unit: &[f64; 3],
) -> Vec<Witness> {
    let mut all: Vec<(f64, Witness)> = Vec::new();
    for (other, r) in results.iter().enumerate() {
        let labels = &r.labels_a.labels;
        let picked: Vec<u32> = [Label::Inside, Label::Interference]
            .iter()
            .flat_map(|want| (0..labels.len() as u32).filter(move |&i| labels[i as usize] == *want))
            .collect();
        let step = (picked.len() / MAX_SAMPLES).max(1);
        for &tet in picked.iter().step_by(step) {
            let t = tet_of(&a.mesh, tet);
            let c = [0, 1, 2].map(|k| t.iter().map(|v| f64::from(v[k] - p[k])).sum::<f64>() / 4.0);
            all.push((radius(&c, unit), Witness { tet, other }));
        }
    }
    all.sort_by(|x, y| x.0.total_cmp(&y.0));
    all.into_iter().map(|(_, w)| w).collect()
}

/// dV/dθ, the rate at which the overlap grows as `a` turns about the axis (seed §4.2's
/// Reynolds transport with the velocity u × r): Σ w·N_s/6 · (u × (c − p)) over `a`'s tets
/// inside the others (INTERFERENCE at half weight), in checker units.
fn turn_rate(a: &Prepared, results: &[&PairResult], p: &LatticePoint, unit: &[f64; 3]) -> f64 {
    let mut rate = 0.0;
    for r in results {
        for (i, l) in r.labels_a.labels.iter().enumerate() {
            let w = match l {
                Label::Inside => 1.0 / 6.0,
                Label::Interference => 0.5 / 6.0,
                Label::Outside => continue,
            };
            let t = tet_of(&a.mesh, i as u32);
            let n = float_normal(&t);
            let c = [0, 1, 2].map(|k| t.iter().map(|v| f64::from(v[k] - p[k])).sum::<f64>() / 4.0);
            let v = [
                unit[1] * c[2] - unit[2] * c[1],
                unit[2] * c[0] - unit[0] * c[2],
                unit[0] * c[1] - unit[1] * c[0],
            ];
            rate += w * (0..3).map(|k| n[k] * v[k]).sum::<f64>();
        }
    }
    rate
}

#[cfg(test)]
mod tests {
    use super::*;

    /// M·Mᵀ = n²·I and det M = n³ for many quaternions and axes, and the angle is the one
    /// the quaternion says.
    #[test]
    fn rational_rotations_are_rotations() {
        let axes = [
            [0, 0, 1],
            [1, 0, 0],
            [1, 1, 0],
            [1, 2, 3],
            [-3, 5, 7],
            [12, -1, 4],
        ];
        let mut seen = 0;
        for u in axes {
            let axis = IntegerAxis {
                u,
                deviation_rad: 0.0,
            };
            for a in 0..40 {
                for k in -40..40 {
                    let Some(r) = RationalRotation::of(u, k, a) else {
                        continue;
                    };
                    let m = r.matrix.map(|row| row.map(i128::from));
                    let n = i128::from(r.n);
                    for i in 0..3 {
                        for j in 0..3 {
                            let dot: i128 = (0..3).map(|l| m[l][i] * m[l][j]).sum();
                            assert_eq!(dot, if i == j { n * n } else { 0 }, "{u:?} {k} {a}");
                        }
                    }
                    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
                    assert_eq!(det, n * n * n);
                    // It turns a vector across the axis by the quaternion's angle, about u.
                    let theta = Tau {
                        k: i128::from(k.abs()),
                        a: i128::from(a),
                    }
                    .angle(&axis)
                        * k.signum() as f64;
                    let w = axis.unit();
                    let x = if u[0] == 0 && u[1] == 0 {
                        [1.0, 0.0, 0.0]
                    } else {
                        let c = [-w[1], w[0], 0.0];
                        let l = (c[0] * c[0] + c[1] * c[1]).sqrt();
                        c.map(|v| v / l)
                    };
                    let y = [0, 1, 2].map(|i| {
                        (0..3).map(|j| r.matrix[i][j] as f64 * x[j]).sum::<f64>() / r.n as f64
                    });
                    let cross = [
                        x[1] * y[2] - x[2] * y[1],
                        x[2] * y[0] - x[0] * y[2],
                        x[0] * y[1] - x[1] * y[0],
                    ];
                    let sin = (0..3).map(|i| cross[i] * w[i]).sum::<f64>();
                    let cos = (0..3).map(|i| x[i] * y[i]).sum::<f64>();
                    let turned = sin.atan2(cos);
                    let diff = (turned - theta).rem_euclid(2.0 * PI);
                    assert!(
                        diff.min(2.0 * PI - diff) < 1e-9,
                        "{u:?} {k} {a}: {turned} vs {theta}"
                    );
                    seen += 1;
                }
            }
        }
        assert!(seen > 15_000, "{seen}");
    }

    #[test]
    fn simplest_fractions_lie_strictly_inside_and_are_simplest() {
        let frac = |k: i128, a: i128| Tau { k, a };
        let value = |t: &Tau| t.k as f64 / t.a as f64;
        for (lo, hi) in [
            (frac(0, 1), frac(1, 100)),
            (frac(1, 3), frac(1, 2)),
            (frac(2, 7), frac(3, 10)),
            (frac(5, 1), frac(16, 3)),
            (frac(1, 1), frac(2, 1)),
            (frac(355, 113), frac(22, 7)),
        ] {
            let s = simplest_between(lo, Some(hi));
            assert!(lo.less(&s) && s.less(&hi), "{lo:?} {s:?} {hi:?}");
            // No fraction with a smaller denominator lies inside.
            for a in 1..s.a {
                let k = (value(&lo) * a as f64).floor() as i128 + 1;
                assert!(!frac(k, a).less(&hi), "{k}/{a} inside ({lo:?}, {hi:?})");
            }
        }
        assert_eq!(
            simplest_between(frac(0, 1), Some(frac(1, 100))),
            frac(1, 101)
        );
        assert_eq!(simplest_between(frac(7, 3), None), frac(3, 1));
    }

    const SIZE: [u32; 3] = [40, 40, 8];

    /// Checker units per voxel of [`chronotope_mesh::glue::test_body`] (BITS, scale 2).
    const VOXEL: f64 = 16.0;

    /// A bar along x (voxels x 4..=35, y 18..=21, z 2..=5) and a square post (x 24..=27,
    /// y 20..=23, z 1..=6) through its upper half, both at rest over three frames, on
    /// their common lattice with the bar's result against the post.
    fn bar_and_post() -> (CommonLattice, Prepared, Prepared, PairResult) {
        let stamps = [0, 100_000_000, 200_000_000];
        let inside = |p: [usize; 3], lo: [usize; 3], hi: [usize; 3]| {
            (0..3).all(|k| (lo[k]..=hi[k]).contains(&p[k]))
        };
        let bar = chronotope_mesh::glue::test_body(SIZE, [0.0; 3], &stamps, |_, p| {
            inside(p, [4, 18, 2], [35, 21, 5])
        });
        let post = chronotope_mesh::glue::test_body(SIZE, [0.0; 3], &stamps, |_, p| {
            inside(p, [24, 20, 1], [27, 23, 6])
        });
        let lat = CommonLattice::of(&[("bar", &bar), ("post", &post)]).expect("one lattice");
        let a = lat.prepare("bar", &bar).expect("bar");
        let b = lat.prepare("post", &post).expect("post");
        let r = check_pair(&a, &b);
        assert!(r.interfering());
        (lat, a, b, r)
    }

    /// The exact smallest clockwise turn of the bar about the vertical axis through
    /// `pivot` (checker units) that clears the post as meshed: the bar's upper face is the
    /// plane y = pivot + 2 voxels, and the post clears it when every vertex v of its
    /// section, at (r cos α, r sin α) from the axis, is above it turned by φ:
    /// r·sin(α + φ) ≥ w, so φ* = max over v of asin(w/r) − α (the post's vertical sides are
    /// prisms over the bar's height, so its vertices there are its section's).
    fn exact_turn(post: &Prepared, pivot: [f64; 2]) -> f64 {
        let w = 2.0 * VOXEL;
        post.mesh
            .vertices
            .iter()
            .filter(|v| (1.5 * VOXEL..=5.5 * VOXEL).contains(&f64::from(v[2])))
            .map(|v| {
                let (x, y) = (f64::from(v[0]) - pivot[0], f64::from(v[1]) - pivot[1]);
                (w / x.hypot(y)).asin() - y.atan2(x)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// A bar turning away from a post about its end: the suggestion turns it clockwise,
    /// by no less than the exact smallest angle (every suggestion is verified exactly on
    /// the bodies as meshed) and by at most the search's tolerance more (an eighth of a
    /// voxel at the bar's far end), with the largest failing angle below the exact one.
    #[test]
    fn a_bar_turns_away_from_a_post_by_the_smallest_angle() {
        let (lat, a, b, r) = bar_and_post();
        let spec = RotationSpec {
            point_m: Some([0.04, 0.20, 0.04]),
            ..RotationSpec::default()
        };
        let rot = suggest_rotation(&a, &[&b], &[&r], &lat, &spec).expect("a rotation");
        assert_eq!(
            rot.point[..3],
            [56, 312, 56],
            "the bar's end, on the lattice"
        );
        assert_eq!(rot.axis.u, [0, 0, 1]);
        assert!(rot.verified_clear, "{rot:?}");
        assert!(rot.reason.is_none());
        let exact = exact_turn(&b, [3.5 * VOXEL, 19.5 * VOXEL]);
        assert!((0.09..0.11).contains(&exact), "{exact}");
        let found = -rot.angle_rad;
        assert!(found >= exact, "{found} below the exact {exact}");
        let tolerance = 1.0 / 8.0 / 32.0;
        assert!(found - exact <= tolerance, "{found} vs {exact}");
        let failing = -rot.failing_rad.expect("a failing angle below");
        assert!((0.0..exact).contains(&failing), "{failing} vs {exact}");
        // What the pipeline reports, in metres and radians.
        let res = crate::pipeline::resolve(&a, &[&b], &[&r], &lat, 1.0, &spec, 0, [0.0, 0.2]);
        let turn = res
            .iter()
            .find(|x| matches!(x, crate::report::Resolution::Rotate { .. }))
            .expect("a rotation reported");
        let crate::report::Resolution::Rotate {
            axis,
            point_m,
            angle_rad,
            verified_clear,
            lattice_refinement,
            ..
        } = turn
        else {
            unreachable!()
        };
        assert_eq!(*axis, [0.0, 0.0, 1.0]);
        assert!(point_m
            .iter()
            .zip([0.04, 0.20, 0.04])
            .all(|(x, y)| (x - y).abs() < 1e-12));
        assert_eq!((*angle_rad, *verified_clear), (rot.angle_rad, true));
        assert_eq!(*lattice_refinement, rot.n);
    }

    /// By default the axis goes through the bar's centroid at its first contact (the
    /// middle of the bar), and the turn is the exact smallest about it, within tolerance.
    #[test]
    fn by_default_the_bar_turns_about_its_centroid() {
        let (lat, a, b, r) = bar_and_post();
        let rot =
            suggest_rotation(&a, &[&b], &[&r], &lat, &RotationSpec::default()).expect("a rotation");
        assert_eq!(rot.point[..3], [312, 312, 56]);
        assert!(rot.verified_clear, "{rot:?}");
        let exact = exact_turn(&b, [19.5 * VOXEL, 19.5 * VOXEL]);
        let found = -rot.angle_rad;
        assert!(
            found >= exact && found - exact <= 1.0 / 8.0 / 16.0,
            "{found} vs {exact}"
        );
    }

    /// Within a limit below the exact smallest angle nothing clears: the suggestion says
    /// so, with the largest angle it tried.
    #[test]
    fn a_limit_below_the_smallest_clearing_angle_is_said() {
        let (lat, a, b, r) = bar_and_post();
        let spec = RotationSpec {
            point_m: Some([0.04, 0.20, 0.04]),
            max_rad: 0.05,
            ..RotationSpec::default()
        };
        let rot = suggest_rotation(&a, &[&b], &[&r], &lat, &spec).expect("a rotation");
        assert!(!rot.verified_clear);
        let why = rot.reason.clone().expect("a reason");
        assert!(
            why.contains("no angle tried up to 2.9° in either sense clears"),
            "{why}"
        );
        assert!(
            rot.angle_rad.abs() <= 0.05 && rot.angle_rad != 0.0,
            "{rot:?}"
        );
        // Nothing is asked for with a zero limit.
        let none = RotationSpec {
            max_rad: 0.0,
            ..spec
        };
        assert!(suggest_rotation(&a, &[&b], &[&r], &lat, &none).is_none());
    }

    /// The rotated body is closed and keeps its orientation: its hypervolume is n⁴ times
    /// the body's (Σ det of its tets, exactly), every mapped normal points the way the
    /// normal of the mapped tet does, and every box of the refitted tree holds its tet.
    #[test]
    fn the_rotated_body_is_closed_and_consistently_oriented() {
        let (_, a, _, _) = bar_and_post();
        let volume = |m: &chronotope_mesh::TetMesh| -> i128 {
            let o = m.vertices[0];
            m.tets
                .iter()
                .map(|t| {
                    let p = t.map(|v| m.vertices[v as usize]);
                    chronotope_kernel::orient4_i128([&o, &p[0], &p[1], &p[2], &p[3]])
                })
                .sum()
        };
        let v0 = volume(&a.mesh);
        assert!(v0 != 0);
        let mut placement = Placement::new(&a);
        for (u, k, q) in [([0, 0, 1], 1, 7), ([1, 2, 2], -3, 11), ([3, -1, 2], 5, 4)] {
            let rot = RationalRotation::of(u, k, q).expect("a rotation");
            let map = rot.about(&[312, 312, 56, 16]);
            let moved = placement.place_linear(&map).expect("fits");
            assert!(chronotope_mesh::validate::check_closed(&moved.mesh).is_closed());
            assert_eq!(volume(&moved.mesh), v0 * i128::from(rot.n).pow(4), "{u:?}");
            for (i, n) in moved.normals.iter().enumerate() {
                let t = tet_of(&moved.mesh, i as u32);
                let fresh = tet_normal(t);
                if *n == NO_NORMAL || fresh == NO_NORMAL {
                    continue;
                }
                let dot: i128 = (0..4)
                    .map(|k| i128::from(n[k]) * i128::from(fresh[k]))
                    .sum();
                let len = |x: &[i32; 4]| x.iter().map(|&c| (f64::from(c)).powi(2)).sum::<f64>();
                assert!(dot > 0, "normal {i} turned round");
                assert!(
                    (dot as f64).powi(2) >= 0.999_999 * len(n) * len(&fresh),
                    "normal {i} not parallel"
                );
            }
            let leaves = &moved.bvh;
            for slot in 0..leaves.len() {
                let item = leaves.order()[slot];
                let t = tet_of(&moved.mesh, item);
                assert!(t
                    .iter()
                    .all(|p| leaves.leaf_boxes()[slot].contains_point(p)));
            }
        }
    }

    /// The walk of the rotated body against the other as they are seen finds an
    /// interfering tet pair exactly when the checker's walk of the two placed on the finer
    /// lattice does, at angles that cross, touch and clear.
    #[test]
    fn interfering_pairs_seen_through_the_maps_are_the_placed_bodies_pairs() {
        let (_, a, b, _) = bar_and_post();
        let pivot = [56, 312, 56, 0];
        let (mut moved, mut other) = (Placement::new(&a), Placement::new(&b));
        let mut stack = Vec::new();
        let (mut crossing, mut not) = (0, 0);
        for (k, q) in [
            (0, 1),
            (-1, 40),
            (-1, 21),
            (-1, 20),
            (-1, 19),
            (-3, 58),
            (-1, 10),
            (1, 6),
            (2, 5),
            (-1, 2),
            (1, 1),
        ] {
            let rot = RationalRotation::of([0, 0, 1], k, q).expect("a rotation");
            let map = rot.about(&pivot);
            let n = rot.n;
            let seen_a = View::linear(&a, map).expect("fits");
            let seen_b = View::scaled(&b, n, &pivot).expect("fits");
            let placed_b = other
                .place([n; 4], pivot.map(|c| -i64::from(c) * n))
                .expect("fits");
            let placed_a = moved.place_linear(&map).expect("fits");
            let walked = walk(placed_a, placed_b, false).interfering_pairs > 0;
            assert_eq!(
                pair_interferes(&seen_a, &seen_b, &mut stack),
                walked,
                "{k}/{q}"
            );
            crossing += usize::from(walked);
            not += usize::from(!walked);
        }
        assert!(crossing >= 3 && not >= 3, "{crossing} {not}");
    }

    /// The full check of a turned body against the others scaled as they are read
    /// ([`clears_scaled`]) says what the check against copies placed scaled says
    /// ([`resolve::clears`](super::super::resolve::clears)), at angles that cross and
    /// clear, about two points.
    #[test]
    fn a_turn_checked_against_the_others_scaled_as_read_answers_as_placed_copies_do() {
        let (_, a, b, _) = bar_and_post();
        let mut moved = Placement::new(&a);
        let (mut clear, mut not) = (0, 0);
        for pivot in [[56, 312, 56, 0], [600, 330, 56, 8]] {
            for (k, q) in [
                (0, 1),
                (-1, 40),
                (-1, 20),
                (-1, 10),
                (1, 6),
                (-1, 2),
                (1, 1),
            ] {
                let rot = RationalRotation::of([0, 0, 1], k, q).expect("a rotation");
                let n = rot.n;
                let placed_b = b
                    .mapped([n; 4], pivot.map(|c| -i64::from(c) * n))
                    .expect("fits");
                let placed_a = moved.place_linear(&rot.about(&pivot)).expect("fits");
                let want = super::super::resolve::clears(placed_a, &[&placed_b]);
                assert_eq!(
                    clears_scaled(placed_a, &[&b], n, pivot),
                    Some(want),
                    "{k}/{q} about {pivot:?}"
                );
                clear += usize::from(want);
                not += usize::from(!want);
            }
        }
        assert!(clear >= 3 && not >= 3, "{clear} {not}");
    }

    /// Inclusion against a body seen scaled about a point answers as against a copy of it
    /// placed scaled.
    #[test]
    fn inclusion_in_a_scaled_view_is_inclusion_in_the_scaled_copy() {
        let (_, _, b, _) = bar_and_post();
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x0DDB_1A5E_5BAD_5EED);
        for (n, c) in [
            (1, [0, 0, 0, 0]),
            (5, [312, 312, 56, 16]),
            (29, [8, -16, 40, 0]),
        ] {
            let copy = b
                .mapped([n; 4], c.map(|x: i32| -i64::from(x) * n))
                .expect("fits");
            let mut placed = Inclusion::with_normals(&copy.mesh, &copy.bvh, &copy.normals);
            let mut seen = Inclusion::with_normals(&b.mesh, &b.bvh, &b.normals)
                .scaled(n, c)
                .expect("fits");
            let bb = copy.bvh.aabb();
            let (mut inside, mut outside) = (0, 0);
            for _ in 0..400 {
                let p = [0, 1, 2, 3].map(|k| {
                    let (lo, hi) = (i64::from(bb.min[k]), i64::from(bb.max[k]));
                    (lo - 8 + (rng.next() % (hi - lo + 17) as u64) as i64) as i32
                });
                let want = placed.contains(&p);
                assert_eq!(seen.contains(&p), want, "{p:?} at n = {n}");
                inside += usize::from(want == Some(true));
                outside += usize::from(want == Some(false));
            }
            assert!(inside > 20 && outside > 20, "{inside} {outside}");
        }
    }

    #[test]
    fn axes_are_approximated_by_small_integer_directions() {
        let a = IntegerAxis::near([0.0, 0.0, 2.5]).unwrap();
        assert_eq!((a.u, a.deviation_rad), ([0, 0, 1], 0.0));
        let a = IntegerAxis::near([1.0, -1.0, 0.0]).unwrap();
        assert_eq!(a.u, [1, -1, 0]);
        assert!(a.deviation_rad < 1e-12);
        let a = IntegerAxis::near([0.3, 0.2, 0.93]).unwrap();
        assert!(a.u.iter().all(|c| c.abs() <= MAX_AXIS_COMPONENT));
        assert!(a.deviation_rad < 0.05, "{a:?}");
        assert!(IntegerAxis::near([0.0; 3]).is_none());
        assert!(IntegerAxis::near([f64::NAN, 0.0, 1.0]).is_none());
    }
}
