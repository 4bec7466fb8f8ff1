//! One integer lattice for several bodies ([`CommonLattice`]): a common scale, integer origin
//! offsets and a common time lattice, so that every predicate between their tets is exact;
//! and how a body is placed on it ([`Placement`]).

use super::*;
use rayon::prelude::*;

/// A prepared body and one copy of it that is placed again and again by axis maps (the
/// candidate moves of a resolution search): each placement rewrites the copy's
/// coordinates, tree boxes and normals from the source in the copy's own buffers, so after
/// the first one nothing is allocated (fresh allocations of this size cost more in page
/// faults than the mapping itself). Tets, adjacency and leaf order are the source's.
#[derive(Debug)]
pub struct Placement<'a> {
    source: &'a Prepared,
    /// The smallest and largest coordinate of the source's vertices on each axis (`None`
    /// without vertices): a map that keeps them within ±2^30 keeps every vertex there.
    bounds: Option<[[i32; 2]; 4]>,
    pub(super) body: Prepared,
    /// The map the copy holds now (`None` before the first placement or after a failed
    /// one): placing it again by the same map does nothing.
    placed: Option<Placed>,
    /// The copy's normals are the source's (as after any map equal on every axis).
    normals_as_source: bool,
}

/// How a [`Placement`]'s copy is placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Placed {
    Axes([i64; 4], [i64; 4]),
    Linear(LinearMap),
}

impl<'a> Placement<'a> {
    /// A copy of `source` to place: its topology now, its coordinates, boxes and normals
    /// at the first placement.
    pub fn new(source: &'a Prepared) -> Self {
        let bounds = source.mesh.vertices.split_first().map(|(first, rest)| {
            let mut b = first.map(|c| [c, c]);
            for p in rest {
                for k in 0..4 {
                    b[k][0] = b[k][0].min(p[k]);
                    b[k][1] = b[k][1].max(p[k]);
                }
            }
            b
        });
        Self {
            source,
            bounds,
            body: Prepared {
                id: source.id.clone(),
                mesh: TetMesh {
                    vertices: Vec::new(),
                    tets: source.mesh.tets.clone(),
                },
                bvh: Bvh::new(),
                adjacency: source.adjacency.clone(),
                components: source.components.clone(),
                normals: Vec::new(),
                factor: source.factor,
                geometry: source.geometry,
                original: source.original.clone(),
            },
            placed: None,
            normals_as_source: false,
        }
    }

    /// The body as prepared, before any placement.
    pub fn source(&self) -> &'a Prepared {
        self.source
    }

    /// The source mapped by x_k → mul_k·x_k + add_k on each axis (every `mul_k > 0`): the
    /// tree's boxes are mapped, not rebuilt (an increasing map keeps every containment),
    /// and the normals follow the cofactor rule (N'_k = N_k · Π_{j≠k} mul_j). `None` if some
    /// `mul_k` is not positive or a coordinate would leave ±2^30 (the exact predicates'
    /// far points must fit), never clamped; the copy is then unusable until the next
    /// successful placement.
    pub fn place(&mut self, mul: [i64; 4], add: [i64; 4]) -> Option<&Prepared> {
        if mul.iter().any(|&m| m <= 0) {
            return None;
        }
        if self.placed == Some(Placed::Axes(mul, add)) {
            return Some(&self.body);
        }
        let (src, body) = (self.source, &mut self.body);
        // The map increases on each axis: if the extreme coordinates stay within ±2^30, so
        // does every one (and no product or sum below overflows).
        if let Some(b) = self.bounds {
            for (k, ends) in b.into_iter().enumerate() {
                if !ends
                    .iter()
                    .all(|&c| map_coordinate(c, mul[k], add[k]).is_some())
                {
                    return None;
                }
            }
        }
        self.placed = None;
        body.mesh.vertices.clear();
        body.mesh.vertices.extend(
            src.mesh
                .vertices
                .iter()
                .map(|p| [0, 1, 2, 3].map(|k| (i64::from(p[k]) * mul[k] + add[k]) as i32)),
        );
        if !body.bvh.map_axes_from(&src.bvh, mul, add) {
            return None;
        }
        // A map equal on every axis keeps every normal: the source's, written once.
        let uniform = mul.iter().all(|&m| m == mul[0]);
        if !(uniform && self.normals_as_source) {
            map_normals(&src.normals, mul, &mut body.normals);
        }
        self.normals_as_source = uniform;
        self.placed = Some(Placed::Axes(mul, add));
        Some(&self.body)
    }
}

/// An affine map x → L·x + b of checker coordinates with an integer matrix L of positive
/// determinant: a rotation made integer by scaling (see [`rotate`](super::rotate)), and
/// any axis map. It keeps lattice points lattice points and every tet's orientation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinearMap {
    /// L, row by row.
    pub matrix: [[i64; 4]; 4],
    /// b.
    pub shift: [i64; 4],
}

impl LinearMap {
    /// L·p + b in `i128` (exact for any `i64` matrix and `i32` point).
    #[inline]
    fn apply_wide(&self, p: &[i128; 4]) -> [i128; 4] {
        [0, 1, 2, 3].map(|k| {
            let row = &self.matrix[k];
            i128::from(self.shift[k]) + (0..4).map(|j| i128::from(row[j]) * p[j]).sum::<i128>()
        })
    }

    /// `p` mapped, or `None` if a coordinate would leave ±2^30.
    pub fn apply(&self, p: &LatticePoint) -> Option<LatticePoint> {
        let q = self.apply_wide(&p.map(i128::from));
        let mut out = [0; 4];
        for k in 0..4 {
            out[k] = i32::try_from(q[k])
                .ok()
                .filter(|c| c.unsigned_abs() < 1 << 30)?;
        }
        Some(out)
    }

    /// Whether every point of the box `b` (smallest and largest coordinate per axis) maps
    /// within ±2^30: an affine map takes its extremes at the box's corners.
    fn keeps_within(&self, b: &[[i32; 2]; 4]) -> bool {
        (0..16).all(|corner| {
            let p: [i128; 4] = [0, 1, 2, 3].map(|k| i128::from(b[k][(corner >> k) & 1]));
            self.apply_wide(&p).iter().all(|c| c.abs() < 1 << 30)
        })
    }

    /// The map of hyperplane normals: the cofactor matrix C = det(L)·L^{−T}, divided by
    /// the gcd of its entries (a positive factor: only a normal's direction matters). The
    /// edges of a tet map by L, so its normal maps by C (N'·x = det[L e1, L e2, L e3, x]
    /// = det(L)·N·L^{−1}x). `None` unless det L > 0.
    pub(super) fn normal_map(&self) -> Option<[[i128; 4]; 4]> {
        let l = self.matrix.map(|r| r.map(i128::from));
        let minor = |i: usize, j: usize| {
            let rows: Vec<usize> = (0..4).filter(|&r| r != i).collect();
            let cols: Vec<usize> = (0..4).filter(|&c| c != j).collect();
            let m = |r: usize, c: usize| l[rows[r]][cols[c]];
            m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
                - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
                + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0))
        };
        let mut c = [[0i128; 4]; 4];
        for (i, row) in c.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                let sign = if (i + j) % 2 == 0 { 1 } else { -1 };
                *x = sign * minor(i, j);
            }
        }
        let det: i128 = (0..4).map(|j| l[0][j] * c[0][j]).sum();
        if det <= 0 {
            return None;
        }
        let g = c
            .iter()
            .flatten()
            .fold(0u128, |g, &x| gcd(g, x.unsigned_abs()))
            .max(1) as i128;
        Some(c.map(|r| r.map(|x| x / g)))
    }
}

impl Placement<'_> {
    /// The source mapped by `map` (see [`LinearMap`]): coordinates mapped, each box of the
    /// tree replaced by the box of its image (its nodes and leaf order kept: valid for any
    /// map, its boxes a little larger than the mapped tets' under a rotation, see
    /// [`Bvh::map_affine_from`]), normals mapped by the cofactor matrix. `None` if det L ≤ 0
    /// or a coordinate would leave ±2^30; the copy is then unusable until the next
    /// successful placement.
    pub fn place_linear(&mut self, map: &LinearMap) -> Option<&Prepared> {
        if self.placed == Some(Placed::Linear(*map)) {
            return Some(&self.body);
        }
        let normal_map = map.normal_map()?;
        if let Some(b) = &self.bounds {
            if !map.keeps_within(b) {
                return None;
            }
        }
        let (src, body) = (self.source, &mut self.body);
        self.placed = None;
        self.normals_as_source = false;
        body.mesh.vertices.clear();
        // Every vertex lies in the source's box, whose image fits: no conversion fails.
        // With matrix entries below 2^30 and shifts below 2^61, each term is below 2^60
        // and every sum fits i64.
        let small = map.matrix.iter().flatten().all(|c| c.abs() < 1 << 30)
            && map.shift.iter().all(|c| c.abs() < 1 << 61);
        let vertex = |p: &LatticePoint| -> LatticePoint {
            if small {
                [0, 1, 2, 3].map(|k| {
                    let row = &map.matrix[k];
                    (map.shift[k] + (0..4).map(|j| row[j] * i64::from(p[j])).sum::<i64>()) as i32
                })
            } else {
                map.apply_wide(&p.map(i128::from))
                    .map(|c| i32::try_from(c).unwrap_or_default())
            }
        };
        if src.mesh.vertices.len() >= PARALLEL_MAP {
            body.mesh
                .vertices
                .par_extend(src.mesh.vertices.par_iter().map(vertex));
        } else {
            body.mesh
                .vertices
                .extend(src.mesh.vertices.iter().map(vertex));
        }
        if !body.bvh.map_affine_from(&src.bvh, map.matrix, map.shift) {
            return None;
        }
        let mesh = &body.mesh;
        // Entries of the normal map below 2^30 keep every term below 2^61: i64 sums.
        let small = normal_map.iter().flatten().all(|c| c.abs() < 1 << 30);
        let narrow = normal_map.map(|r| r.map(|c| c as i64));
        let normal = |(i, n): (usize, &[i32; 4])| {
            if *n == NO_NORMAL {
                return tet_normal(tet_of(mesh, i as u32));
            }
            if small {
                let m = narrow.map(|row| (0..4).map(|j| row[j] * i64::from(n[j])).sum::<i64>());
                if let [Some(a), Some(b), Some(c), Some(d)] = m.map(|v| fit_i32(i128::from(v))) {
                    return [a, b, c, d];
                }
            }
            let n = n.map(i128::from);
            normal_in_i32(normal_map.map(|row| (0..4).map(|j| row[j] * n[j]).sum()))
        };
        body.normals.clear();
        if src.normals.len() >= PARALLEL_MAP {
            body.normals
                .par_extend(src.normals.par_iter().enumerate().map(normal));
        } else {
            body.normals
                .extend(src.normals.iter().enumerate().map(normal));
        }
        self.placed = Some(Placed::Linear(*map));
        Some(&self.body)
    }
}

/// Vertices or normals from which [`Placement::place_linear`] maps them on rayon's pool.
const PARALLEL_MAP: usize = 1 << 16;

/// `c` mapped by c → mul·c + add, or `None` if it would leave ±2^30.
fn map_coordinate(c: i32, mul: i64, add: i64) -> Option<i32> {
    let c = i64::from(c).checked_mul(mul)?.checked_add(add)?;
    (c.abs() < 1 << 30).then_some(c as i32)
}

/// `p` mapped by x_k → mul_k·x_k + add_k, or `None` if a coordinate would leave ±2^30.
pub(super) fn map_point(p: &LatticePoint, mul: [i64; 4], add: [i64; 4]) -> Option<LatticePoint> {
    let mut out = [0; 4];
    for k in 0..4 {
        out[k] = map_coordinate(p[k], mul[k], add[k])?;
    }
    Some(out)
}

/// Whether tet `t` of `a`, mapped by x_k → mul_k·x_k + add_k, has its first interior
/// point strictly inside the body that `other` tests against (a decided crossing count,
/// exact). Then `a` so mapped interferes with that body: a boundary point of one body in
/// the other's interior makes their interiors overlap, and [`interferes`] finds it (that
/// tet is labelled INSIDE or INTERFERENCE; should every point of its region be undecided
/// there, the witness is the truer of the two). A cheap exact proof that a candidate move
/// fails, needing neither the moved body's tree nor a walk.
pub fn mapped_tet_inside(
    a: &Prepared,
    t: u32,
    mul: [i64; 4],
    add: [i64; 4],
    other: &mut Inclusion,
) -> bool {
    let mut tet = tet_of(&a.mesh, t);
    for p in &mut tet {
        match map_point(p, mul, add) {
            Some(q) => *p = q,
            None => return false,
        }
    }
    other.contains(&interior_point(&tet, &INTERIOR_WEIGHTS[0])) == Some(true)
}

/// The common lattice of a set of bodies.
#[derive(Debug, Clone)]
pub struct CommonLattice {
    /// Largest lattice scale among the bodies (all are powers of two).
    pub scale: i32,
    /// Reference voxel-(0,0,0) centre (m).
    pub voxel0_centre: [f64; 3],
    /// Voxel edge (m).
    pub resolution: f64,
    /// Frame stamps of the union time lattice (ns).
    pub stamps_ns: Vec<i64>,
}

impl CommonLattice {
    /// The lattice shared by `bodies`.
    ///
    /// # Errors
    /// Empty bodies, different resolutions or non-integer origin offsets, or frames that do
    /// not lie on one time lattice (each body's frames must be a contiguous run of the
    /// union of all stamps).
    pub fn of(bodies: &[(&str, &BodyMesh)]) -> Result<Self, CheckError> {
        let mut first: Option<(&str, GridGeometry)> = None;
        let mut scale = 2;
        let mut stamps: Vec<i64> = Vec::new();
        for (id, b) in bodies {
            let g = b
                .geometry
                .ok_or_else(|| CheckError::EmptyBody { id: id.to_string() })?;
            if b.stamps_ns.len() < 2 {
                return Err(CheckError::EmptyBody { id: id.to_string() });
            }
            if let Some((fid, f)) = &first {
                if (g.resolution - f.resolution).abs() > 1e-9 * f.resolution {
                    return Err(CheckError::LatticeMismatch {
                        a: fid.to_string(),
                        b: id.to_string(),
                        reason: format!("resolution {} vs {}", f.resolution, g.resolution),
                    });
                }
                origin_offset(&f.origin, &g.origin, f.resolution).map_err(|reason| {
                    CheckError::LatticeMismatch {
                        a: fid.to_string(),
                        b: id.to_string(),
                        reason: reason.to_string(),
                    }
                })?;
            } else {
                first = Some((id, g));
            }
            scale = scale.max(g.scale);
            stamps.extend_from_slice(&b.stamps_ns);
        }
        stamps.sort_unstable();
        stamps.dedup();
        for (id, b) in bodies {
            let start = stamps.binary_search(&b.stamps_ns[0]).unwrap_or(0);
            let run = &stamps[start..(start + b.stamps_ns.len()).min(stamps.len())];
            if run != b.stamps_ns.as_slice() {
                let others: Vec<&str> =
                    bodies.iter().map(|(o, _)| *o).filter(|o| o != id).collect();
                return Err(CheckError::TimeMismatch {
                    a: id.to_string(),
                    b: others.join(", "),
                    reason: format!(
                        "its {} frames from {:.3} s are not a contiguous run of the common frame \
                         times (different frame rates or phases are not resampled)",
                        b.stamps_ns.len(),
                        b.stamps_ns[0] as f64 * 1e-9
                    ),
                });
            }
        }
        let (_, g) = first.expect("at least one body");
        Ok(Self {
            scale,
            voxel0_centre: g.voxel0_centre(),
            resolution: g.resolution,
            stamps_ns: stamps,
        })
    }

    /// Puts a body on this lattice (coordinates ×[`CHECKER_FACTOR`]), preparing it one
    /// piece at a time as [`BodyMesh::pieces`] says it arrived (see [`prep`]).
    ///
    /// # Errors
    /// The tree cannot be built (too many tets, a missing vertex) or the coordinates do
    /// not fit the checker lattice.
    pub fn prepare(&self, id: &str, b: &BodyMesh) -> Result<Prepared, CheckError> {
        let local = BodyPrep::of(&b.mesh, &b.pieces).map_err(|e| prep_error(id, e))?;
        self.place(id, b, local)
    }

    /// [`place`](Self::place) for a body fed to `prep` piece by piece as it was welded
    /// (prepared again at once if `prep` did not see all of `b`'s tets).
    ///
    /// # Errors
    /// As [`prepare`](Self::prepare).
    pub fn place_prep(
        &self,
        id: &str,
        b: &BodyMesh,
        prep: BodyPrep,
    ) -> Result<Prepared, CheckError> {
        if prep.len() != b.mesh.tets.len() {
            return self.prepare(id, b);
        }
        let local = prep.finish().map_err(|e| prep_error(id, e))?;
        self.place(id, b, local)
    }

    /// Whether `b`, prepared in its own lattice, is already on this one (same scale, origin
    /// and first frame): then [`place`](Self::place) leaves it as it is, and walks done
    /// as its pieces arrived ([`StreamWalk`]) hold.
    pub fn places_as_is(&self, b: &BodyMesh) -> bool {
        matches!(self.axis_map(b), Ok((1, [0, 0, 0, 0])))
    }

    /// Where `b` goes on this lattice: the map [`place`](Self::place) applies to it (a
    /// body's preparation depends only on its mesh, its lattice and this), or `None` if it
    /// cannot be placed.
    pub fn placement_of(&self, b: &BodyMesh) -> Option<(i64, [i64; 4])> {
        self.axis_map(b).ok()
    }

    /// The map (common factor over the body's own × [`CHECKER_FACTOR`], shift) of `b`
    /// onto this lattice.
    fn axis_map(&self, b: &BodyMesh) -> Result<(i64, [i64; 4]), LatticeMismatch> {
        let g = b.geometry.ok_or(LatticeMismatch::NoLattice)?;
        let ratio = i64::from(self.scale / g.scale.max(1)).max(1);
        let voxels = origin_offset(
            &self.voxel0_centre.map(|c| c - 0.5 * self.resolution),
            &g.origin,
            self.resolution,
        )?;
        let frame0 =
            b.stamps_ns
                .first()
                .map_or(0, |s| self.stamps_ns.binary_search(s).unwrap_or(0)) as i64;
        let step = self.per_step();
        let shift = [voxels[0], voxels[1], voxels[2], frame0].map(|v| v.saturating_mul(step));
        Ok((ratio, shift))
    }

    /// Puts a body prepared in its own lattice (by [`BodyPrep`], as its stream arrived) on
    /// this lattice: nothing to do when the body's lattice is the reference one, otherwise
    /// an increasing axis map of its coordinates and tree boxes.
    ///
    /// # Errors
    /// The body has no lattice, its origin is not a whole number of voxels from the
    /// reference, or its coordinates would not fit the checker lattice.
    pub fn place(&self, id: &str, b: &BodyMesh, local: LocalPrep) -> Result<Prepared, CheckError> {
        let g = b
            .geometry
            .ok_or_else(|| CheckError::EmptyBody { id: id.to_string() })?;
        let (ratio, shift) = self
            .axis_map(b)
            .map_err(|reason| CheckError::LatticeMismatch {
                a: "reference".into(),
                b: id.to_string(),
                reason: reason.to_string(),
            })?;
        let mut p = Prepared {
            id: id.to_string(),
            mesh: local.mesh,
            bvh: local.bvh,
            adjacency: local.adjacency.into(),
            components: Default::default(),
            normals: local.normals,
            factor: CHECKER_FACTOR * ratio as i32,
            geometry: g,
            original: local.original.into(),
        };
        let mul = [ratio; 4];
        if (mul != [1; 4] || shift != [0; 4]) && !p.map_in_place(mul, shift) {
            // Checker coordinates must fit in i32 with room for far points (2^30): bodies
            // far apart on a fine lattice are refused, never wrapped.
            return Err(CheckError::LatticeMismatch {
                a: "reference".into(),
                b: id.to_string(),
                reason: "checker lattice coordinates would overflow (bodies too far apart, or \
                         grids too large for a common fine lattice)"
                    .into(),
            });
        }
        Ok(p)
    }

    /// Checker lattice units per voxel and per frame period.
    pub fn per_step(&self) -> i64 {
        i64::from(self.scale) * i64::from(CHECKER_FACTOR)
    }

    /// Seconds since `origin_ns` of checker time `t` (piecewise linear between frames).
    pub fn time_s(&self, t: f64, origin_ns: i64) -> f64 {
        chronotope_kernel::stamp_time_s(&self.stamps_ns, self.per_step() as f64, t, origin_ns)
    }

    /// Length of one frame period containing checker time `t` (s).
    pub fn period_s(&self, t: f64) -> f64 {
        let per = self.per_step() as f64;
        let n = self.stamps_ns.len() as i64;
        let k = ((t / per).floor() as i64).clamp(0, n - 2) as usize;
        (self.stamps_ns[k + 1] - self.stamps_ns[k]) as f64 * 1e-9
    }
}

/// A body's preparation error, named.
pub(super) fn prep_error(id: &str, e: PrepError) -> CheckError {
    match e {
        PrepError::Tree(source) => CheckError::Bvh {
            id: id.to_string(),
            source,
        },
        PrepError::Overflow { .. } => CheckError::LatticeMismatch {
            a: "reference".into(),
            b: id.to_string(),
            reason: e.to_string(),
        },
    }
}

/// Why two bodies' lattices cannot be put on one.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LatticeMismatch {
    /// A body has no lattice yet (no frame was meshed).
    #[error("no lattice")]
    NoLattice,
    /// The voxel edges differ.
    #[error("voxel edges of {a} m and {b} m")]
    Resolution {
        /// One body's voxel edge (m).
        a: f64,
        /// The other's (m).
        b: f64,
    },
    /// The origins are not a whole number of voxels apart.
    #[error("origins differ by {voxels} voxels along axis {axis}, not a whole number")]
    Origins {
        /// The axis (0 = x, 1 = y, 2 = z).
        axis: usize,
        /// The difference in voxels.
        voxels: f64,
    },
}

/// Whole-voxel offset from origin `a` to origin `b`, or why there is none.
pub(crate) fn origin_offset(
    a: &[f64; 3],
    b: &[f64; 3],
    res: f64,
) -> Result<[i64; 3], LatticeMismatch> {
    let mut out = [0i64; 3];
    for k in 0..3 {
        let v = (b[k] - a[k]) / res;
        let r = v.round();
        if (v - r).abs() > 1e-6 || !r.is_finite() || r.abs() > 1e9 {
            return Err(LatticeMismatch::Origins { axis: k, voxels: v });
        }
        out[k] = r as i64;
    }
    Ok(out)
}
