//! The interference checker (seed 000): two bodies' closed 4D meshes → per-tet labels, the
//! time intervals of interference, the first contact time and the overlap.
//!
//! Pipeline for a pair: both meshes are put on one integer lattice ([`Prepared`]: common
//! scale, integer origin offset, a common time lattice, coordinates ×8 so that several
//! interior points of every tet are lattice points); an AABB tree over each body's tets
//! gives candidate pairs; the exact predicate [`classify`] keeps the pairs whose boundaries
//! cross (or overlap in one hyperplane with the same orientation). Tets that touch the
//! other boundary without crossing it are *contact* tets, tested one by one; every other tet
//! is disjoint from the other boundary, and face-adjacent such tets lie on the same side, so
//! one exact inclusion test per region labels them all INSIDE or OUTSIDE (see [`labels`]).
//!
//! **Touching rule.** Bodies in adjacent voxels share facets and vertices: that is contact,
//! not interference. Exactly: two boundary tets interfere when their relative interiors
//! cross transversally (a polygon of positive area where the hyperplanes cut), or when they
//! lie in one hyperplane, overlap in a positive 3-volume, and face the same way (the two
//! interiors lie on the same side). Tets that only share vertices, edges or faces, meet
//! inside a face, or lie face to face with opposite orientation are not interference; a
//! region touching the other body only that way is OUTSIDE.

pub mod adjacency;
pub mod bounds;
pub mod contact;
pub mod inclusion;
pub mod labels;
pub mod oracle;
pub mod prep;
pub mod resolve;
pub mod rolling;
pub mod window;

use crate::kernel::bvh::{
    overlapping_pairs_under, top_pairs, Bvh, BvhError, NodePair, TraverseWorkspace,
};
use crate::kernel::intersect::{classify_if, TetPairRelation};
use crate::kernel::LatticePoint;
use crate::mesh::glue::BodyMesh;
use crate::mesh::{GridGeometry, TetMesh};
use inclusion::Inclusion;
use labels::{label_regions, LabelCounts, Labeling, Touch};
use prep::{BodyPrep, LocalPrep, PrepError};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Why two bodies cannot be checked against each other.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckError {
    /// A body has no mesh (fewer than two frames accepted).
    #[error("body {id}: no 4D mesh (needs at least two frames)")]
    EmptyBody {
        /// The body.
        id: String,
    },
    /// The spatial lattices differ (resolution, or an origin offset that is not a whole
    /// number of voxels).
    #[error("bodies {a} and {b} are not on one lattice: {reason}")]
    LatticeMismatch {
        /// First body.
        a: String,
        /// Second body.
        b: String,
        /// What differs.
        reason: String,
    },
    /// The frame stamps do not share one time lattice.
    #[error("{a}: its frames are not at the frame times of {b}: {reason}")]
    TimeMismatch {
        /// First body.
        a: String,
        /// Second body.
        b: String,
        /// What differs.
        reason: String,
    },
    /// The tree over a body's tets could not be built (too many tets, or a tet names a
    /// missing vertex).
    #[error("body {id}: {source}")]
    Bvh {
        /// The body.
        id: String,
        /// Why.
        source: BvhError,
    },
}

/// Checker lattice units per body lattice unit at the common scale: ×8 so that the points
/// (w·tet)/8 for the weights in [`INTERIOR_WEIGHTS`] are lattice points.
pub const CHECKER_FACTOR: i32 = 8;

/// Barycentric weights (sum 8, all positive) of the interior points tried per tet.
pub const INTERIOR_WEIGHTS: [[i64; 4]; 5] = [
    [2, 2, 2, 2],
    [3, 2, 2, 1],
    [1, 3, 2, 2],
    [2, 1, 3, 2],
    [2, 2, 1, 3],
];

/// One body ready for checking: lattice-aligned, ×8 coordinates, tree and adjacency.
#[derive(Debug)]
pub struct Prepared {
    /// Body id (topic).
    pub id: String,
    /// The mesh in checker coordinates, tets in the tree's leaf order (labels refer to
    /// these indices, not to the body's mesh).
    pub mesh: TetMesh,
    /// Tree over the tets.
    pub bvh: Bvh,
    /// Face adjacency (shared by the body's placed copies, see [`Placement`]).
    pub adjacency: std::sync::Arc<[[u32; 4]]>,
    /// A normal of each tet's hyperplane ([`NO_NORMAL`] if it does not fit `i32`): a cheap
    /// exact first test of candidate pairs.
    pub normals: Vec<[i32; 4]>,
    /// Checker lattice units per original lattice unit of this body.
    pub factor: i32,
    /// The body's lattice.
    pub geometry: GridGeometry,
    /// Frame stamps (ns) of the common time lattice: checker time `t` is at
    /// `stamps[t / (8·scale)]` plus the fraction within that frame period.
    pub stamps_ns: Vec<i64>,
    /// For each tet (in the order of `mesh.tets`), its index in the body's mesh as given to
    /// [`CommonLattice::prepare`].
    pub original: std::sync::Arc<[u32]>,
}

impl Prepared {
    /// Per-tet values in the order of the body's mesh as given to [`CommonLattice::prepare`]
    /// (undoing the tree's leaf order).
    pub fn in_original_order<T: Copy + Default>(&self, values: &[T]) -> Vec<T> {
        let mut out = vec![T::default(); self.original.len()];
        for (&o, &v) in self.original.iter().zip(values) {
            out[o as usize] = v;
        }
        out
    }

    /// Maps this body by x_k → mul_k·x_k + add_k on each axis (every `mul_k > 0`) in
    /// place, like [`Placement::place`]; `false`, with the body unchanged, if a
    /// coordinate would leave ±2^30.
    pub fn map_in_place(&mut self, mul: [i64; 4], add: [i64; 4]) -> bool {
        if mul.iter().any(|&m| m <= 0)
            || !self
                .mesh
                .vertices
                .iter()
                .all(|p| map_point(p, mul, add).is_some())
            || !self.bvh.map_axes(mul, add)
        {
            return false;
        }
        for p in &mut self.mesh.vertices {
            *p = map_point(p, mul, add).unwrap_or(*p);
        }
        if mul.iter().any(|&m| m != mul[0]) {
            let mut normals = Vec::new();
            map_normals(&self.normals, mul, &mut normals);
            self.normals = normals;
        }
        true
    }

    /// The same body mapped by x_k → mul_k·x_k + add_k on each axis (`mul_k > 0`: a
    /// translation, a refinement of the lattice, a time scaling); see [`Placement::place`].
    /// `None` if a coordinate would leave ±2^30, never clamped.
    pub fn mapped(&self, mul: [i64; 4], add: [i64; 4]) -> Option<Prepared> {
        let mut placement = Placement::new(self);
        placement.place(mul, add)?;
        Some(placement.body)
    }
}

/// A prepared body and one copy of it that is placed again and again by axis maps (the
/// candidate moves of a resolution search): each placement rewrites the copy's
/// coordinates, tree boxes and normals from the source in the copy's own buffers, so after
/// the first one nothing is allocated (fresh allocations of this size cost more in page
/// faults than the mapping itself). Tets, adjacency and leaf order are the source's.
#[derive(Debug)]
pub struct Placement<'a> {
    source: &'a Prepared,
    body: Prepared,
}

impl<'a> Placement<'a> {
    /// A copy of `source` to place: its topology now, its coordinates, boxes and normals
    /// at the first placement.
    pub fn new(source: &'a Prepared) -> Self {
        Self {
            source,
            body: Prepared {
                id: source.id.clone(),
                mesh: TetMesh {
                    vertices: Vec::new(),
                    tets: source.mesh.tets.clone(),
                },
                bvh: Bvh::new(),
                adjacency: source.adjacency.clone(),
                normals: Vec::new(),
                factor: source.factor,
                geometry: source.geometry,
                stamps_ns: source.stamps_ns.clone(),
                original: source.original.clone(),
            },
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
        let (src, body) = (self.source, &mut self.body);
        body.mesh.vertices.clear();
        for p in &src.mesh.vertices {
            body.mesh.vertices.push(map_point(p, mul, add)?);
        }
        if !body.bvh.map_axes_from(&src.bvh, mul, add) {
            return None;
        }
        map_normals(&src.normals, mul, &mut body.normals);
        Some(&self.body)
    }
}

/// `p` mapped by x_k → mul_k·x_k + add_k, or `None` if a coordinate would leave ±2^30.
fn map_point(p: &LatticePoint, mul: [i64; 4], add: [i64; 4]) -> Option<LatticePoint> {
    let mut out = [0; 4];
    for k in 0..4 {
        let c = i64::from(p[k]).checked_mul(mul[k])?.checked_add(add[k])?;
        if c.abs() >= 1 << 30 {
            return None;
        }
        out[k] = c as i32;
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
                        reason,
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

    /// The map (common factor over the body's own × [`CHECKER_FACTOR`], shift) of `b`
    /// onto this lattice.
    fn axis_map(&self, b: &BodyMesh) -> Result<(i64, [i64; 4]), String> {
        let g = b.geometry.ok_or("no lattice")?;
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
                reason,
            })?;
        let mut p = Prepared {
            id: id.to_string(),
            mesh: local.mesh,
            bvh: local.bvh,
            adjacency: local.adjacency.into(),
            normals: local.normals,
            factor: CHECKER_FACTOR * ratio as i32,
            geometry: g,
            stamps_ns: self.stamps_ns.clone(),
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
        crate::kernel::stamp_time_s(&self.stamps_ns, self.per_step() as f64, t, origin_ns)
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
fn prep_error(id: &str, e: PrepError) -> CheckError {
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

/// Whole-voxel offset from origin `a` to origin `b`, or why there is none.
pub(crate) fn origin_offset(a: &[f64; 3], b: &[f64; 3], res: f64) -> Result<[i64; 3], String> {
    let mut out = [0i64; 3];
    for k in 0..3 {
        let v = (b[k] - a[k]) / res;
        let r = v.round();
        if (v - r).abs() > 1e-6 || !r.is_finite() || r.abs() > 1e9 {
            return Err(format!(
                "origins differ by {v} voxels along axis {k}, not a whole number"
            ));
        }
        out[k] = r as i64;
    }
    Ok(out)
}

/// The result of checking one pair.
#[derive(Debug, Clone, Default)]
pub struct PairResult {
    /// Labels of the first body's tets.
    pub labels_a: Labeling,
    /// Labels of the second body's tets.
    pub labels_b: Labeling,
    /// Candidate tet pairs whose boxes overlap.
    pub candidate_pairs: u64,
    /// Pairs whose boundaries cross (or overlap coplanar with the same orientation).
    pub interfering_pairs: u64,
    /// Checker-time ranges where the bodies overlap, merged and sorted.
    pub intervals: Vec<(f64, f64)>,
    /// For each interval, how fast the boundaries approach at its start and recede at its
    /// end (voxels per frame period; see [`contact_speeds`]).
    pub interval_speeds: Vec<(Option<f64>, Option<f64>)>,
    /// Where the time went.
    pub timing: PairTiming,
}

/// Wall-clock seconds of the phases of [`check_pair`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairTiming {
    /// Tree traversal and exact tet-pair classification.
    pub detect_s: f64,
    /// Labels of both bodies (inclusion tests and propagation) and the intervals.
    pub label_s: f64,
}

impl PairResult {
    /// True if the bodies' interiors overlap somewhere in space-time.
    pub fn interfering(&self) -> bool {
        let (a, b) = (self.labels_a.counts(), self.labels_b.counts());
        a.interference + a.inside + b.interference + b.inside > 0
    }
    /// The same result with the two bodies' roles exchanged.
    pub fn swapped(mut self) -> Self {
        std::mem::swap(&mut self.labels_a, &mut self.labels_b);
        self
    }
    /// Label counts of both bodies.
    pub fn counts(&self) -> (LabelCounts, LabelCounts) {
        (self.labels_a.counts(), self.labels_b.counts())
    }
    /// The earliest checker time of overlap.
    pub fn first_contact(&self) -> Option<f64> {
        self.intervals.first().map(|r| r.0)
    }
}

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
fn tet_normals(m: &TetMesh) -> Vec<[i32; 4]> {
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
fn edge_minors<T>(e: [[T; 4]; 3]) -> [T; 4]
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
fn map_normals(normals: &[[i32; 4]], mul: [i64; 4], out: &mut Vec<[i32; 4]>) {
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
fn normal_in_i32(n: [i128; 4]) -> [i32; 4] {
    if let [Some(a), Some(b), Some(c), Some(d)] = n.map(fit_i32) {
        return [a, b, c, d];
    }
    reduced_normal(n)
}

/// `v` as `i32` unless it is out of range or `i32::MIN` (the [`NO_NORMAL`] marker).
#[inline]
fn fit_i32(v: i128) -> Option<i32> {
    i32::try_from(v).ok().filter(|&v| v != i32::MIN)
}

/// [`normal_in_i32`] for a normal that does not fit as it is (fine lattices).
#[cold]
fn reduced_normal(n: [i128; 4]) -> [i32; 4] {
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

fn gcd(mut a: u128, mut b: u128) -> u128 {
    // 64-bit remainders while both fit (128-bit division is a slow library call).
    while b != 0 {
        if let (Ok(x), Ok(y)) = (u64::try_from(a), u64::try_from(b)) {
            return u128::from(gcd64(x, y));
        }
        (a, b) = (b, a % b);
    }
    a
}

fn gcd64(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The sides (signs −1, 0, 1) of the vertices of tet `q` with respect to the hyperplane
/// of tet `p` (normal `n`), exactly; `None` when `n` is [`NO_NORMAL`]. All zero for a
/// flat `p` (zero normal).
#[inline]
fn sides(n: &[i32; 4], p: &[LatticePoint; 4], q: &[LatticePoint; 4]) -> Option<[i8; 4]> {
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

/// All vertices strictly on one side: the closed tets are disjoint.
fn strictly_one_side(s: &[i8; 4]) -> bool {
    s[0] != 0 && s[1] == s[0] && s[2] == s[0] && s[3] == s[0]
}

/// Vertices strictly on both sides.
fn straddles(s: &[i8; 4]) -> bool {
    let (hi, lo) = (
        s[0].max(s[1]).max(s[2].max(s[3])),
        s[0].min(s[1]).min(s[2].min(s[3])),
    );
    hi > 0 && lo < 0
}

/// One worker's share of a pair check.
#[derive(Debug, Default)]
struct Part {
    hit_a: Vec<Touch>,
    hit_b: Vec<Touch>,
    /// Time ranges of the interfering pairs, with the pair.
    ranges: Vec<(f64, f64, u32, u32)>,
    candidate_pairs: u64,
    interfering_pairs: u64,
}

/// How many node-pair levels the tree-against-tree walk is split at for the workers
/// (at most 4^6 independent sub-walks).
const SPLIT_DEPTH: u32 = 6;

/// Checks two prepared bodies: the tree walk and exact predicate on all cores, then the
/// two bodies' labels side by side. The result does not depend on the number of threads.
pub fn check_pair(a: &Prepared, b: &Prepared) -> PairResult {
    let start = std::time::Instant::now();
    let all = walk(a, b, false);
    finish_pair(a, b, all, start)
}

/// One tet pair whose boundaries cross: the checker-time range of their section, and the
/// two tets (indices in the leaf order of the bodies' meshes).
pub type CrossingPair = (f64, f64, u32, u32);

/// [`check_pair`], with every crossing tet pair it found (in no particular order).
pub fn check_pair_detailed(a: &Prepared, b: &Prepared) -> (PairResult, Vec<CrossingPair>) {
    let start = std::time::Instant::now();
    let all = walk(a, b, false);
    let crossings = all.ranges.clone();
    (finish_pair(a, b, all, start), crossings)
}

/// [`check_pair`] with the walk done as the bodies' pieces arrived (`walked`, over `a`
/// and `b` prepared from those same pieces and placed as they are): only the labels are
/// left. If `walked` did not see every tet of both bodies, the walk is done here.
pub fn check_pair_walked(a: &Prepared, b: &Prepared, walked: StreamWalk) -> PairResult {
    if walked.tets() != (a.mesh.tets.len(), b.mesh.tets.len()) {
        return check_pair(a, b);
    }
    finish_pair(a, b, walked.part, std::time::Instant::now())
}

/// The labels and the rest of a [`PairResult`] after the walk (`all`, started at `start`).
fn finish_pair(a: &Prepared, b: &Prepared, all: Part, start: std::time::Instant) -> PairResult {
    let mut r = PairResult {
        candidate_pairs: all.candidate_pairs,
        interfering_pairs: all.interfering_pairs,
        ..PairResult::default()
    };
    let mut ranges: Vec<(f64, f64)> = all.ranges.iter().map(|r| (r.0, r.1)).collect();
    r.timing.detect_s = start.elapsed().as_secs_f64();
    let start = std::time::Instant::now();
    let (la, lb) = rayon::join(
        || label_against(a, b, &all.hit_a),
        || label_against(b, a, &all.hit_b),
    );
    r.labels_a = la;
    r.labels_b = lb;
    for (p, labels) in [(a, &r.labels_a), (b, &r.labels_b)] {
        for (i, l) in labels.labels.iter().enumerate() {
            if *l == labels::Label::Inside {
                ranges.push(t_range(&tet_of(&p.mesh, i as u32)));
            }
        }
    }
    r.intervals = merge_ranges(ranges);
    r.interval_speeds = r
        .intervals
        .iter()
        .map(|&(s, e)| contact_speeds(a, b, &all.ranges, s, e))
        .collect();
    r.timing.label_s = start.elapsed().as_secs_f64();
    r
}

/// How fast the two boundaries approach at `start` and recede at `end` (voxels per frame
/// period), from the interfering pairs within one frame period of each end: each body's
/// boundary patch there moves along its spatial normal at −N_t/|N_s| (outward normals N
/// summed over the patch's tets, which smooths voxel staircases); the closing speed is
/// the sum for the two bodies, positive while they approach. `None` where no pair lies
/// near that end (an end made by a body starting or ending inside the other).
fn contact_speeds(
    a: &Prepared,
    b: &Prepared,
    pairs: &[(f64, f64, u32, u32)],
    start: f64,
    end: f64,
) -> (Option<f64>, Option<f64>) {
    let frame = (a.factor as f64) * f64::from(a.geometry.scale);
    let speed = |near: &dyn Fn(&(f64, f64, u32, u32)) -> bool| -> Option<f64> {
        let (mut ta, mut tb): (Vec<u32>, Vec<u32>) =
            pairs.iter().filter(|p| near(p)).map(|p| (p.2, p.3)).unzip();
        if ta.is_empty() {
            return None;
        }
        let surface = |tets: &mut Vec<u32>, m: &TetMesh| {
            tets.sort_unstable();
            tets.dedup();
            let mut n = [0.0f64; 4];
            for &t in tets.iter() {
                let v = crate::kernel::float::tet_normal(&tet_of(m, t));
                (0..4).for_each(|k| n[k] += v[k]);
            }
            let ns = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            (ns > 0.0).then(|| -n[3] / ns)
        };
        Some(surface(&mut ta, &a.mesh)? + surface(&mut tb, &b.mesh)?)
    };
    (
        speed(&|p| p.0 >= start && p.0 <= start + frame),
        speed(&|p| p.1 <= end && p.1 >= end - frame).map(|v| -v),
    )
}

/// Whether two bodies interfere, exactly as [`check_pair`] decides it, but stopping at
/// the first interfering tet pair; the labels are computed only when no pair crosses
/// (then only containment can make them interfere).
pub fn interferes(a: &Prepared, b: &Prepared) -> bool {
    let all = walk(a, b, true);
    if all.interfering_pairs > 0 {
        return true;
    }
    let inside = |p: &Prepared, other: &Prepared, hit: &[Touch]| {
        label_against(p, other, hit)
            .labels
            .contains(&labels::Label::Inside)
    };
    let (a_inside, b_inside) =
        rayon::join(|| inside(a, b, &all.hit_a), || inside(b, a, &all.hit_b));
    a_inside || b_inside
}

/// The tree-against-tree walk with the exact predicate, split over all cores; with
/// `stop_at_interference` every worker stops once any finds an interfering pair.
fn walk(a: &Prepared, b: &Prepared, stop_at_interference: bool) -> Part {
    let mut tops = Vec::new();
    top_pairs(&a.bvh, &b.bvh, SPLIT_DEPTH, &mut tops);
    let threads = rayon::current_num_threads()
        .clamp(1, 8)
        .min(tops.len().max(1));
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let work = || {
        let mut part = Part {
            hit_a: vec![Touch::Clear; a.mesh.tets.len()],
            hit_b: vec![Touch::Clear; b.mesh.tets.len()],
            ranges: Vec::new(),
            candidate_pairs: 0,
            interfering_pairs: 0,
        };
        let mut ws = TraverseWorkspace::new();
        while !stop.load(Ordering::Relaxed) {
            let k = next.fetch_add(1, Ordering::Relaxed);
            let Some(&top) = tops.get(k) else { break };
            let _ = overlapping_pairs_under(&a.bvh, &b.bvh, top, &mut ws, |i, j| {
                visit(Side::of(a), Side::of(b), i, j, &mut part);
                if stop_at_interference && part.interfering_pairs > 0 {
                    stop.store(true, Ordering::Relaxed);
                    return ControlFlow::Break(());
                }
                ControlFlow::Continue(())
            });
        }
        part
    };
    let parts: Vec<Part> = if threads == 1 {
        vec![work()]
    } else {
        // One part per worker (each holds a flag per tet of both bodies), the top pairs
        // taken in turn; the parts are merged with commutative operations.
        let done = std::sync::Mutex::new(Vec::with_capacity(threads));
        rayon::scope(|s| {
            for _ in 0..threads {
                s.spawn(|_| {
                    let part = work();
                    done.lock().unwrap_or_else(|e| e.into_inner()).push(part);
                });
            }
        });
        done.into_inner().unwrap_or_else(|e| e.into_inner())
    };
    let mut parts = parts.into_iter();
    let mut all = parts.next().expect("at least one worker");
    for p in parts {
        for (x, y) in all.hit_a.iter_mut().zip(&p.hit_a) {
            *x = (*x).max(*y);
        }
        for (x, y) in all.hit_b.iter_mut().zip(&p.hit_b) {
            *x = (*x).max(*y);
        }
        all.ranges.extend(p.ranges);
        all.candidate_pairs += p.candidate_pairs;
        all.interfering_pairs += p.interfering_pairs;
    }
    all
}

/// The instant k if the tets' time ranges meet only there, with at most one of the tets
/// lying in the time plane t = k (a cap tet). Then the pair can neither cross nor overlap
/// in a hyperplane, only touch, and A ∩ B = F_A ∩ F_B for the faces F of A and B spanned
/// by their vertices at t = k: A ∩ B lies in t = k, where each tet is that face (a linear
/// function is extreme on a convex set only on a face); the relative interior of a tet
/// that is not flat in time misses t = k, and a tet in t = k shares no hyperplane with one
/// that is not.
#[inline]
fn one_instant(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4]) -> Option<i32> {
    let range = |t: &[LatticePoint; 4]| {
        let lo = t[0][3].min(t[1][3]).min(t[2][3].min(t[3][3]));
        let hi = t[0][3].max(t[1][3]).max(t[2][3].max(t[3][3]));
        (lo, hi)
    };
    let ((alo, ahi), (blo, bhi)) = (range(ta), range(tb));
    if alo == ahi && blo == bhi {
        None
    } else if ahi == blo {
        Some(ahi)
    } else if bhi == alo {
        Some(alo)
    } else {
        None
    }
}

/// Whether the faces at t = `instant` of two tets (see [`one_instant`]) have disjoint
/// spatial boxes, so that the tets do not meet (exact).
#[inline]
fn faces_apart(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4], instant: i32) -> bool {
    let face_box = |t: &[LatticePoint; 4]| {
        let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
        for v in t.iter().filter(|v| v[3] == instant) {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        (lo, hi)
    };
    let ((alo, ahi), (blo, bhi)) = (face_box(ta), face_box(tb));
    (0..3).any(|k| ahi[k] < blo[k] || bhi[k] < alo[k])
}

/// What the walk reads of a body: its tets and their normals.
#[derive(Clone, Copy)]
struct Side<'a> {
    mesh: &'a TetMesh,
    normals: &'a [[i32; 4]],
}

impl<'a> Side<'a> {
    fn of(p: &'a Prepared) -> Self {
        Self {
            mesh: &p.mesh,
            normals: &p.normals,
        }
    }
}

/// The tree walk of one pair of bodies done as their pieces arrive (see [`prep`]): each
/// new piece of either body is walked against the pieces of the other that came before
/// it, so that every pair of pieces is walked once and, at the end of the stream, only
/// the labels are left ([`check_pair_walked`]).
///
/// Valid only if both bodies are already on the common lattice as prepared (same
/// lattice, same first frame: [`CommonLattice::places_as_is`]); otherwise the walk is
/// done again at the end.
#[derive(Debug, Default)]
pub struct StreamWalk {
    part: Part,
    /// Pieces of each body walked so far.
    seen: (usize, usize),
}

impl StreamWalk {
    /// Nothing walked yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Walks the pieces of `a` and `b` that came since the last call.
    pub fn advance(&mut self, a: &BodyPrep, b: &BodyPrep) {
        let (fa, fb) = (a.forest(), b.forest());
        let (na, nb) = (fa.pieces(), fb.pieces());
        let (sa, sb) = self.seen;
        if (na, nb) == (sa, sb) {
            return;
        }
        let part = &mut self.part;
        part.hit_a.resize(a.len(), Touch::Clear);
        part.hit_b.resize(b.len(), Touch::Clear);
        let (side_a, side_b) = (
            Side {
                mesh: a.mesh(),
                normals: a.normals(),
            },
            Side {
                mesh: b.mesh(),
                normals: b.normals(),
            },
        );
        let (ta, tb) = (fa.tree_so_far(), fb.tree_so_far());
        let mut ws = TraverseWorkspace::new();
        // New pieces of `a` against every piece of `b`, then old pieces of `a` against
        // the new ones of `b`.
        let pairs = (sa..na)
            .flat_map(|i| (0..nb).map(move |j| (i, j)))
            .chain((0..sa).flat_map(|i| (sb..nb).map(move |j| (i, j))));
        for (i, j) in pairs {
            let (Some((ra, ba)), Some((rb, bb))) = (fa.piece_root(i), fb.piece_root(j)) else {
                continue;
            };
            if !ba.overlaps(&bb) {
                continue;
            }
            let _ = overlapping_pairs_under(ta, tb, NodePair::new(ra, rb), &mut ws, |i, j| {
                visit(side_a, side_b, i, j, part);
                ControlFlow::<()>::Continue(())
            });
        }
        self.seen = (na, nb);
    }

    /// Tets of each body walked so far.
    pub fn tets(&self) -> (usize, usize) {
        (self.part.hit_a.len(), self.part.hit_b.len())
    }
}

/// One candidate pair: the exact relation, recorded in the worker's share.
#[inline]
fn visit(a: Side<'_>, b: Side<'_>, i: u32, j: u32, part: &mut Part) {
    part.candidate_pairs += 1;
    let (ta, tb) = (tet_of(&a.mesh, i), tet_of(&b.mesh, j));
    let (ha, hb) = (part.hit_a[i as usize], part.hit_b[j as usize]);
    // Whether the pair merely touches matters only to a tet not yet known to touch.
    let touching_matters = ha < Touch::Contact || hb < Touch::Contact;
    // Most candidates (about 60 % at the seed's scale) are tets of consecutive slabs whose
    // boxes meet only at the frame time between them: such a pair can only touch, and
    // only where their faces at that time meet (most of those are apart in space).
    if let Some(instant) = one_instant(&ta, &tb) {
        if !touching_matters || faces_apart(&ta, &tb, instant) {
            return;
        }
    }
    // Most other candidates lie strictly on one side of the other's hyperplane.
    let sides_of_b = sides(&a.normals[i as usize], &ta, &tb);
    if sides_of_b.is_some_and(|s| strictly_one_side(&s)) {
        return;
    }
    let sides_of_a = sides(&b.normals[j as usize], &tb, &ta);
    if sides_of_a.is_some_and(|s| strictly_one_side(&s)) {
        return;
    }
    // Unless both straddle the other's hyperplane (they may cross) or B lies in A's
    // hyperplane (coplanar, or A flat), the pair can at most touch: what classify_if
    // would call Disjoint when touching does not matter.
    if let (false, Some(sb), Some(sa)) = (touching_matters, sides_of_b, sides_of_a) {
        if sb != [0; 4] && !(straddles(&sb) && straddles(&sa)) {
            return;
        }
    }
    // Where the two tets meet in time: their section polygon for a crossing; for a
    // coplanar overlap, within both time ranges.
    let (range, touch) = match classify_if(&ta, &tb, touching_matters) {
        TetPairRelation::Crossing => (
            Some(contact::crossing_t_range(&ta, &tb).unwrap_or_else(|| overlap_t(&ta, &tb))),
            Touch::Interference,
        ),
        TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            same_orientation: true,
        } => (Some(overlap_t(&ta, &tb)), Touch::Interference),
        TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            same_orientation: false,
        } => (None, Touch::FaceToFace),
        TetPairRelation::Coplanar { .. } | TetPairRelation::Touching => (None, Touch::Contact),
        TetPairRelation::Disjoint => return,
    };
    if let Some(range) = range {
        part.interfering_pairs += 1;
        part.ranges.push((range.0, range.1, i, j));
    }
    part.hit_a[i as usize] = ha.max(touch);
    part.hit_b[j as usize] = hb.max(touch);
}

/// The common time range of two tets.
fn overlap_t(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4]) -> (f64, f64) {
    let (ra, rb) = (t_range(ta), t_range(tb));
    (ra.0.max(rb.0), ra.1.min(rb.1))
}

fn label_against(p: &Prepared, other: &Prepared, hit: &[Touch]) -> Labeling {
    let mut test = TetInside {
        mesh: &p.mesh,
        inc: Inclusion::with_normals(&other.mesh, &other.bvh, &other.normals),
    };
    label_regions(&p.adjacency, hit, &mut test)
}

/// Interior point (w·tet)/8 of a tet for weights `w` of [`INTERIOR_WEIGHTS`]: checker
/// coordinates are ×8 (and stay so under positive axis maps), so it is a lattice point.
fn interior_point(tet: &[LatticePoint; 4], w: &[i64; 4]) -> LatticePoint {
    [0, 1, 2, 3].map(|k| ((0..4).map(|v| w[v] * i64::from(tet[v][k])).sum::<i64>() / 8) as i32)
}

/// Inclusion tests of one body's tets against the other body.
struct TetInside<'a> {
    mesh: &'a TetMesh,
    inc: Inclusion<'a>,
}

impl TetInside<'_> {
    fn interior(&self, t: u32, w: &[i64; 4]) -> LatticePoint {
        interior_point(&tet_of(self.mesh, t), w)
    }
}

impl labels::InsideTest for TetInside<'_> {
    fn far(&mut self, t: u32, tries: usize) -> Option<(bool, LatticePoint)> {
        INTERIOR_WEIGHTS.iter().take(tries).find_map(|w| {
            let c = self.interior(t, w);
            self.inc.contains(&c).map(|inside| (inside, c))
        })
    }
    fn from_known(
        &mut self,
        t: u32,
        q: &LatticePoint,
        q_inside: bool,
    ) -> Option<(bool, LatticePoint)> {
        let c = self.interior(t, &INTERIOR_WEIGHTS[0]);
        self.inc
            .contains_from(&c, q, q_inside)
            .map(|inside| (inside, c))
    }
    fn point(&self, t: u32) -> LatticePoint {
        self.interior(t, &INTERIOR_WEIGHTS[0])
    }
}

/// Sorts closed ranges and merges those that overlap or touch.
pub fn merge_ranges(mut v: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    v.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (s, e) in v {
        match out.last_mut() {
            Some(last) if s <= last.1 => last.1 = last.1.max(e),
            _ => out.push((s, e)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::intersect::test_rng::Rng;
    use crate::kernel::tets_intersect;

    /// The shortcut of the walk against the exact classifier: a pair whose time ranges
    /// meet in one instant never crosses or overlaps in a hyperplane, and faces apart at
    /// that instant mean the closed tets are disjoint. Vertices at t ∈ {0, 1, 2} (a third
    /// of the tets caps at one instant) on a small spatial lattice make such pairs common
    /// and touching ones too.
    #[test]
    fn pairs_meeting_in_one_instant_only_touch_where_their_faces_meet() {
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        let (mut instants, mut touching, mut apart) = (0, 0, 0);
        let tet = |rng: &mut Rng, t: [i32; 4]| -> [LatticePoint; 4] {
            t.map(|t| {
                [0, 0, 0]
                    .map(|_| rng.range(0, 3) as i32)
                    .into_iter()
                    .chain([t])
                    .collect::<Vec<_>>()
                    .try_into()
                    .expect("4")
            })
        };
        let times = [
            [0, 0, 1, 1],
            [0, 1, 1, 1],
            [1, 1, 1, 2],
            [1, 2, 2, 2],
            [1, 1, 1, 1],
            [0, 0, 0, 1],
        ];
        for _ in 0..20_000 {
            let ka = rng.range(0, 5) as usize;
            let ta = tet(&mut rng, times[ka]);
            let kb = rng.range(0, 5) as usize;
            let tb = tet(&mut rng, times[kb]);
            let Some(k) = one_instant(&ta, &tb) else {
                continue;
            };
            instants += 1;
            let relation = crate::kernel::classify(&ta, &tb);
            assert!(
                matches!(
                    relation,
                    TetPairRelation::Touching | TetPairRelation::Disjoint
                ),
                "{ta:?} {tb:?} at {k}: {relation:?}"
            );
            let meet = tets_intersect(&ta, &tb);
            touching += usize::from(meet);
            if faces_apart(&ta, &tb, k) {
                apart += 1;
                assert!(
                    !meet,
                    "{ta:?} {tb:?} meet though their faces at {k} are apart"
                );
            }
        }
        assert!(
            instants > 5000 && touching > 500 && apart > 500,
            "{instants} {touching} {apart}"
        );
    }
}
