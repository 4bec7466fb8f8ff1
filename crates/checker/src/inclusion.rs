//! Is a point inside a closed, consistently oriented tet mesh? Exact signed crossing count
//! along a segment to a far point (docs/methods/interference.md#inclusion-test): each
//! crossed tet adds the sign of orient4(tet, q), +1 leaving and −1 entering, so the sum is
//! 1 inside and 0 outside. Any zero predicate on a candidate makes the answer undecided
//! ([`None`]) and the caller tries another far point or another point.

use chronotope_kernel::bvh::{Bvh, TraverseWorkspace};
use chronotope_kernel::{orient4_i128, tets_intersect, LatticePoint};
use chronotope_mesh::TetMesh;

/// Far points are the mesh box's max corner plus one of these (distinct, skew directions).
const FAR_OFFSETS: [[i32; 4]; 6] = [
    [7919, 6271, 5227, 4111],
    [6563, 7993, 4157, 5333],
    [4099, 5839, 7877, 6257],
    [5591, 4481, 6473, 7963],
    [7411, 4397, 5903, 6599],
    [4801, 7039, 6701, 4789],
];

/// Number of far points tried per point.
pub const FAR_POINTS: usize = FAR_OFFSETS.len();

/// Inclusion queries against one mesh.
#[derive(Debug)]
pub struct Inclusion<'a> {
    mesh: &'a TetMesh,
    bvh: &'a Bvh,
    /// A normal per tet (as [`Prepared::normals`](super::Prepared)), if known: the sides
    /// of a segment's ends from two dot products instead of two 5-point determinants.
    normals: Option<&'a [[i32; 4]]>,
    far: [LatticePoint; FAR_POINTS],
    ws: TraverseWorkspace,
    hits: Vec<u32>,
    /// The mesh seen scaled (see [`Inclusion::scaled`]), or as it is.
    scale: Option<Scale>,
}

/// A uniform scaling x → n·(x − centre) of a mesh, applied as its tets and tree boxes are
/// read.
#[derive(Debug, Clone, Copy)]
struct Scale {
    n: i64,
    centre: [i64; 4],
}

impl Scale {
    /// `p` scaled; the caller knows it fits (see [`Inclusion::scaled`]).
    #[inline]
    fn apply(&self, p: &LatticePoint) -> LatticePoint {
        [0, 1, 2, 3].map(|k| ((i64::from(p[k]) - self.centre[k]) * self.n) as i32)
    }
}

/// How a segment meets a tet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cross {
    No,
    Yes(i8),
    Degenerate,
}

/// sign orient4(t, x) from a normal `n` of `t`'s hyperplane (a positive multiple of the
/// signed minors of its edges, see `edge_minors`): orient4(t, x) = det[t1 − t0, t2 − t0,
/// t3 − t0, x − t0] = −n·(x − t0), expanded along its last row. Coordinates are `i32`, so
/// each term is below 2^31·2^32 = 2^63: `i64` products, an `i128` sum.
#[inline]
fn orient_by_normal(n: &[i32; 4], t0: &LatticePoint, x: &LatticePoint) -> i128 {
    let term = |k: usize| i64::from(n[k]) * (i64::from(x[k]) - i64::from(t0[k]));
    -(i128::from(term(0)) + i128::from(term(1)) + i128::from(term(2)) + i128::from(term(3)))
        .signum()
}

/// How segment p→q meets tet `t`, given sp = sign orient4(t, p) and sq = sign orient4(t, q).
fn segment_tet_sides(
    p: &LatticePoint,
    q: &LatticePoint,
    t: &[LatticePoint; 4],
    sp: i128,
    sq: i128,
) -> Cross {
    if sp == 0 || sq == 0 {
        // An end point on the tet's hyperplane: the count would be ambiguous if it were on
        // the tet itself; be safe and call it degenerate only if the segment can touch it.
        return if sp == sq {
            Cross::Degenerate
        } else {
            touch_or_no(p, q, t)
        };
    }
    if sp == sq {
        return Cross::No;
    }
    // The segment crosses the hyperplane once: inside the tet iff the four signs below
    // agree (docs/methods/interference.md#exact-predicates).
    let s = [
        orient4_i128([p, q, &t[1], &t[2], &t[3]]).signum(),
        -orient4_i128([p, q, &t[0], &t[2], &t[3]]).signum(),
        orient4_i128([p, q, &t[0], &t[1], &t[3]]).signum(),
        -orient4_i128([p, q, &t[0], &t[1], &t[2]]).signum(),
    ];
    if s.iter().all(|&v| v > 0) || s.iter().all(|&v| v < 0) {
        Cross::Yes(sq as i8)
    } else if s.iter().any(|&v| v > 0) && s.iter().any(|&v| v < 0) {
        Cross::No
    } else {
        Cross::Degenerate
    }
}

/// One end point lies on the tet's hyperplane: if the segment's crossing with the
/// hyperplane (that end point) could lie on the closed tet, the count is undecided.
fn touch_or_no(p: &LatticePoint, q: &LatticePoint, t: &[LatticePoint; 4]) -> Cross {
    let s = [
        orient4_i128([p, q, &t[1], &t[2], &t[3]]).signum(),
        -orient4_i128([p, q, &t[0], &t[2], &t[3]]).signum(),
        orient4_i128([p, q, &t[0], &t[1], &t[3]]).signum(),
        -orient4_i128([p, q, &t[0], &t[1], &t[2]]).signum(),
    ];
    if s.iter().any(|&v| v > 0) && s.iter().any(|&v| v < 0) {
        Cross::No
    } else {
        Cross::Degenerate
    }
}

/// Whether `p`, on the hyperplane of `t`, lies in the closed tet. Dropping a coordinate
/// in which the hyperplane's normal is non-zero (a non-zero 3D orientation of the dropped
/// tet) maps the hyperplane onto R^3 one to one, where p lies in the tet iff it is on the
/// inner side of, or on, each face: exact in `i128`. A flat tet takes the general test.
fn in_tet_on_hyperplane(p: &LatticePoint, t: &[LatticePoint; 4]) -> bool {
    for k in 0..4 {
        let drop = |x: &LatticePoint| {
            let mut out = [0i64; 3];
            for (o, j) in out.iter_mut().zip((0..4).filter(|&j| j != k)) {
                *o = i64::from(x[j]);
            }
            out
        };
        let q = t.map(|v| drop(&v));
        let o = orient3(&q);
        if o == 0 {
            continue;
        }
        let pk = drop(p);
        return (0..4).all(|i| {
            let mut r = q;
            r[i] = pk;
            orient3(&r) * o >= 0
        });
    }
    tets_intersect(&[*p; 4], t)
}

/// The sign of det[b − a, c − a, d − a] of a 3D tet with `i32` coordinates (exact).
fn orient3(t: &[[i64; 3]; 4]) -> i8 {
    let e = [1, 2, 3].map(|i| [0, 1, 2].map(|k| t[i][k] - t[0][k]));
    // Edges below 2^20 (every voxel-sized tet, and a point near it) keep each triple
    // product below 2^60 and the sum of six below 2^63: i64 is exact there. Longer edges
    // (below 2^32) take i128, whose products stay below 2^99.
    if e.iter().flatten().all(|c| c.unsigned_abs() < 1 << 20) {
        return det3(e).signum() as i8;
    }
    det3(e.map(|r| r.map(i128::from))).signum() as i8
}

fn det3<T>(e: [[T; 3]; 3]) -> T
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::Sub<Output = T> + std::ops::Add<Output = T>,
{
    e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1])
        - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
        + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0])
}

impl<'a> Inclusion<'a> {
    /// Queries against `mesh`, whose BVH over its tets is `bvh`.
    pub fn new(mesh: &'a TetMesh, bvh: &'a Bvh) -> Self {
        let b = bvh.aabb();
        let far = FAR_OFFSETS.map(|o| [0, 1, 2, 3].map(|k| b.max[k].saturating_add(o[k])));
        Self {
            mesh,
            bvh,
            normals: None,
            far,
            ws: TraverseWorkspace::new(),
            hits: Vec::new(),
            scale: None,
        }
    }

    /// The same queries against the mesh scaled by `n > 0` about `centre`
    /// (x → n·(x − centre)), with points given in the scaled coordinates, without scaling
    /// it: its tets and tree boxes are scaled as they are read. A uniform scaling keeps
    /// every normal's direction, so the normals serve as they are. The far points are
    /// placed beyond the scaled mesh's box. `None` if a scaled coordinate would leave
    /// ±2^30 (a far point must fit `i32`).
    #[must_use]
    pub fn scaled(mut self, n: i64, centre: LatticePoint) -> Option<Self> {
        let b = self.bvh.aabb();
        let centre = centre.map(i64::from);
        let fits = |k: usize, c: i32| {
            (i64::from(c) - centre[k])
                .checked_mul(n)
                .is_some_and(|v| v.abs() < 1 << 30)
        };
        if n <= 0 || (!b.is_empty() && !(0..4).all(|k| fits(k, b.min[k]) && fits(k, b.max[k]))) {
            return None;
        }
        let scale = Scale { n, centre };
        if !b.is_empty() {
            let top = scale.apply(&b.max);
            self.far = FAR_OFFSETS.map(|o| [0, 1, 2, 3].map(|k| top[k] + o[k]));
        }
        self.scale = Some(scale);
        Some(self)
    }

    /// Tet `i` of the mesh, scaled if the queries are.
    #[inline]
    fn tet(&self, i: u32) -> [LatticePoint; 4] {
        let t = self.mesh.tets[i as usize].map(|v| self.mesh.vertices[v as usize]);
        match &self.scale {
            None => t,
            Some(s) => t.map(|p| s.apply(&p)),
        }
    }

    /// Fills `hits` with the tets whose boxes meet the closed segment `pq`.
    fn candidates(&mut self, p: &LatticePoint, q: &LatticePoint) {
        let (p, q) = (p.map(i64::from), q.map(i64::from));
        self.hits.clear();
        let hits = &mut self.hits;
        match &self.scale {
            None => self
                .bvh
                .segment_candidates(p, q, &mut self.ws, |i| hits.push(i)),
            Some(s) => self.bvh.segment_candidates_mapped(
                p,
                q,
                [s.n; 4],
                s.centre.map(|c| -c * s.n),
                &mut self.ws,
                |i| hits.push(i),
            ),
        }
    }

    /// As [`Inclusion::new`], with a normal of each tet's hyperplane (one per tet of
    /// `mesh`, positive multiples of the signed edge minors, [`NO_NORMAL`](crate::NO_NORMAL)
    /// where unknown): most candidate tets of a segment are then rejected by two dot
    /// products. Normals of the wrong length are not used.
    pub fn with_normals(mesh: &'a TetMesh, bvh: &'a Bvh, normals: &'a [[i32; 4]]) -> Self {
        let mut inc = Self::new(mesh, bvh);
        inc.normals = (normals.len() == mesh.tets.len()).then_some(normals);
        inc
    }

    /// Far points at times strictly between `t0` and `t1` (`t1 − t0` at least
    /// [`FAR_POINTS`] + 1), for points whose time lies in [t0, t1]: every segment to them
    /// stays in that band (its interior strictly inside), so it meets only the tets there.
    /// A mesh that is one slab of a body between two frame times (closed or not at the
    /// band's ends) then answers as the whole body does at those times.
    #[must_use]
    pub fn within_time(mut self, t0: i32, t1: i32) -> Self {
        let span = i64::from(t1) - i64::from(t0);
        for (k, f) in self.far.iter_mut().enumerate() {
            let t = i64::from(t0) + span * (k as i64 + 1) / (FAR_POINTS as i64 + 1);
            f[3] = t as i32;
        }
        self
    }

    /// Far points beyond the box `full` (spatial, holding the whole mesh the tests stand
    /// for, of which this one may be a part) on each axis's chosen side: below it where
    /// `low`, above it otherwise. The time coordinate is kept.
    #[must_use]
    pub fn far_beyond(mut self, full: ([i64; 3], [i64; 3]), low: [bool; 3]) -> Self {
        for (f, o) in self.far.iter_mut().zip(FAR_OFFSETS) {
            for k in 0..3 {
                let at = if low[k] {
                    full.0[k] - i64::from(o[k])
                } else {
                    full.1[k] + i64::from(o[k])
                };
                f[k] = at.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            }
        }
        self
    }

    /// `Some(true)` if `p` is inside, `Some(false)` outside, `None` if every far point met a
    /// degenerate configuration (p on or very near-aligned with the boundary).
    ///
    /// A point on the boundary is answered `None` at once: a segment from it crosses the
    /// hyperplane of a tet holding it at that very point, inside the closed tet, which is
    /// degenerate towards every far point (contact tets face to face with the other body
    /// have many such points, and each would otherwise cost six long segments).
    pub fn contains(&mut self, p: &LatticePoint) -> Option<bool> {
        if self.on_boundary(p) {
            return None;
        }
        (0..FAR_POINTS).find_map(|k| self.contains_towards(p, k))
    }

    /// Whether the closed tet `t` lies in one closed tet of the mesh, found through its
    /// point `p` (exact): then every point of `t` is on the boundary, and [`Self::contains`]
    /// answers `None` for each. Tets face to face with the other body mostly lie in one of
    /// its tets (both meshed on one lattice); this settles them with one point query
    /// rather than one per point tried.
    pub fn lies_in_boundary(&mut self, p: &LatticePoint, t: &[LatticePoint; 4]) -> bool {
        self.candidates(p, p);
        // A tet holding `t` holds its point `p` first: most candidates (tets sharing a
        // vertex or an edge with `t`) fail there, at one test rather than after several.
        self.hits
            .iter()
            .any(|&i| self.holds(i, p) && t.iter().all(|v| self.holds(i, v)))
    }

    /// Whether the closed tet `i` of the mesh holds `p` (exact).
    #[inline]
    fn holds(&self, i: u32, p: &LatticePoint) -> bool {
        let t = self.tet(i);
        let side = match self.normals.map(|n| n[i as usize]) {
            Some(n) if n != super::NO_NORMAL => orient_by_normal(&n, &t[0], p),
            _ => orient4_i128([&t[0], &t[1], &t[2], &t[3], p]),
        };
        side == 0 && in_tet_on_hyperplane(p, &t)
    }

    /// Whether `p` lies in a closed tet of the mesh (exact).
    fn on_boundary(&mut self, p: &LatticePoint) -> bool {
        self.candidates(p, p);
        self.hits.iter().any(|&i| self.holds(i, p))
    }

    /// The signed count towards far point `k`, or `None` if degenerate.
    pub fn contains_towards(&mut self, p: &LatticePoint, k: usize) -> Option<bool> {
        let q = self.far[k % FAR_POINTS];
        self.contains_from(p, &q, false)
    }

    /// Whether `p` is inside, given a point `q` off the boundary whose answer is
    /// `q_inside`: each crossing of the segment p→q adds +1 leaving and −1 entering, so the
    /// sum is in(p) − in(q). `None` if a crossing is degenerate (or the sum is impossible).
    pub fn contains_from(
        &mut self,
        p: &LatticePoint,
        q: &LatticePoint,
        q_inside: bool,
    ) -> Option<bool> {
        self.candidates(p, q);
        let mut sum = i32::from(q_inside);
        for &i in &self.hits {
            let t = self.tet(i);
            let (sp, sq) = match self.normals.map(|n| n[i as usize]) {
                Some(n) if n != super::NO_NORMAL => (
                    orient_by_normal(&n, &t[0], p),
                    orient_by_normal(&n, &t[0], q),
                ),
                _ => (
                    orient4_i128([&t[0], &t[1], &t[2], &t[3], p]).signum(),
                    orient4_i128([&t[0], &t[1], &t[2], &t[3], q]).signum(),
                ),
            };
            match segment_tet_sides(p, q, &t, sp, sq) {
                Cross::No => {}
                Cross::Yes(s) => sum += i32::from(s),
                Cross::Degenerate => return None,
            }
        }
        match sum {
            0 => Some(false),
            1 => Some(true),
            // A closed, consistently oriented mesh never gives anything else; treat as undecided.
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use chronotope_kernel::intersect::test_rng::Rng;

    /// A tet lies in the boundary exactly when some one tet of the mesh holds its four
    /// vertices (brute force over all tets), and then no point of it is decided.
    #[test]
    fn a_tet_lies_in_the_boundary_exactly_when_one_tet_holds_it() {
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        let mut mesh = TetMesh::default();
        // Overlapping tets with coordinates ×32 (so that the sub-tets below have coordinates
        // ×8, and interior points are lattice points, as in the checker), in a few
        // hyperplanes (x or y constant) and off them, so that sub-tets of one often touch
        // or straddle others.
        for k in 0..200u32 {
            let at = [0; 4].map(|_| (rng.next() % 9) as i32 * 32);
            for j in 0..4 {
                let mut v = at.map(|x| x + (rng.next() % 5) as i32 * 32);
                match k % 3 {
                    0 => v[0] = at[0],
                    1 => v[1] = at[1],
                    _ => v[j] += 32,
                }
                mesh.vertices.push(v);
            }
            mesh.tets.push([0, 1, 2, 3].map(|j| 4 * k + j));
        }
        let bvh = Bvh::from_tets(&mesh.vertices, &mesh.tets).expect("a tree");
        let normals = super::super::tet_normals(&mesh);
        let mut inc = Inclusion::with_normals(&mesh, &bvh, &normals);
        let holds = |t: &[LatticePoint; 4], v: &LatticePoint| tets_intersect(&[*v; 4], t);
        let (mut inside, mut not) = (0, 0);
        for k in 0..2000 {
            let m = super::super::tet_of(&mesh, (k % mesh.tets.len()) as u32);
            // A tet of points (w·m)/4 with weights summing to 4: inside m; or one vertex
            // moved a step (8), often out of it.
            let mut t = [0; 4].map(|_| {
                let mut w = [0i64; 4];
                for _ in 0..4 {
                    w[(rng.next() % 4) as usize] += 1;
                }
                [0, 1, 2, 3]
                    .map(|c| ((0..4).map(|v| w[v] * i64::from(m[v][c])).sum::<i64>() / 4) as i32)
            });
            if k % 2 == 1 {
                t[(rng.next() % 4) as usize][(rng.next() % 4) as usize] += 8;
            }
            let p = super::super::walk::interior_point(&t, &super::super::INTERIOR_WEIGHTS[0]);
            let expected = mesh.tets.iter().any(|x| {
                let x = x.map(|v| mesh.vertices[v as usize]);
                t.iter().all(|v| holds(&x, v))
            });
            assert_eq!(inc.lies_in_boundary(&p, &t), expected, "tet {t:?}");
            if expected {
                inside += 1;
                for w in &super::super::INTERIOR_WEIGHTS {
                    let q = super::super::walk::interior_point(&t, w);
                    assert_eq!(inc.contains(&q), None, "a point of {t:?} on the boundary");
                }
            } else {
                not += 1;
            }
        }
        assert!(inside > 500 && not > 300, "{inside} in, {not} not");
    }

    /// The 3D orientation's i64 shortcut against i128 throughout, for tets of every size
    /// up to the checker's range (the shortcut is taken below 2^20 per edge).
    #[test]
    fn orient3_is_exact_for_small_and_large_tets() {
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        let mut signs = [0usize; 3];
        for size in [3i64, 1 << 10, (1 << 20) - 1, 1 << 20, 1 << 30] {
            for _ in 0..2000 {
                let at = [0; 3].map(|_| (rng.next() % (1 << 30)) as i64 - (1 << 29));
                let mut t = [0; 4].map(|_| at.map(|x| x + (rng.next() % (size as u64 + 1)) as i64));
                if rng.next() % 3 == 0 {
                    // Flat: the fourth point on the plane of the first three.
                    t[3] = [0, 1, 2].map(|k| t[1][k] + t[2][k] - t[0][k]);
                }
                let e = [1, 2, 3].map(|i| [0, 1, 2].map(|k| i128::from(t[i][k] - t[0][k])));
                let expected = det3(e).signum() as i8;
                assert_eq!(orient3(&t), expected, "{t:?}");
                signs[(expected + 1) as usize] += 1;
            }
        }
        assert!(signs.iter().all(|&n| n > 1000), "{signs:?}");
    }

    /// The normal-based side is the sign of orient4 for every tet and point, including
    /// normals reduced by their gcd on coarse-to-fine lattices and far points.
    #[test]
    fn sides_from_normals_are_the_orientation_signs() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for scale in [4u64, 1 << 12, 1 << 20, 1 << 29] {
            let mut mesh = TetMesh::default();
            for _ in 0..300 {
                let c = |r: &mut Rng| (r.next() % (2 * scale)) as i64 - scale as i64;
                let base = mesh.vertices.len() as u32;
                // Voxel-sized tets anywhere (edges up to 64 lattice units).
                let at = [0; 4].map(|_| c(&mut rng));
                for _ in 0..4 {
                    let v = at.map(|x| x + (rng.next() % 129) as i64 - 64);
                    mesh.vertices.push(v.map(|x| x as i32));
                }
                mesh.tets.push([base, base + 1, base + 2, base + 3]);
            }
            // Flat tets too: their normal is zero, every side 0.
            mesh.vertices
                .extend([[0, 0, 0, 0], [1, 0, 0, 0], [2, 0, 0, 0], [0, 1, 0, 0]]);
            let n = mesh.vertices.len() as u32;
            mesh.tets.push([n - 4, n - 3, n - 2, n - 1]);
            let normals = super::super::tet_normals(&mesh);
            let usable = normals
                .iter()
                .filter(|n| **n != super::super::NO_NORMAL)
                .count();
            assert!(usable > 250, "{usable} normals at scale {scale}");
            for (t, normal) in mesh.tets.iter().zip(&normals) {
                if *normal == super::super::NO_NORMAL {
                    continue;
                }
                let v = t.map(|i| mesh.vertices[i as usize]);
                for _ in 0..20 {
                    let x = [0; 4].map(|_| (rng.next() as i64 % (2 * scale as i64)) as i32);
                    let expect = orient4_i128([&v[0], &v[1], &v[2], &v[3], &x]).signum();
                    assert_eq!(orient_by_normal(normal, &v[0], &x), expect, "{v:?} {x:?}");
                }
                // Points on the hyperplane: the vertices themselves.
                for x in &v {
                    assert_eq!(orient_by_normal(normal, &v[0], x), 0);
                }
            }
        }
    }
}
