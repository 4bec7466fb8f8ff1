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
pub mod contact;
pub mod inclusion;
pub mod labels;
pub mod oracle;
pub mod resolve;

use crate::kernel::bvh::{overlapping_pairs, Bvh, BvhError, TraverseWorkspace};
use crate::kernel::intersect::{classify, TetPairRelation};
use crate::kernel::LatticePoint;
use crate::mesh::glue::BodyMesh;
use crate::mesh::{GridGeometry, TetMesh};
use adjacency::face_adjacency;
use inclusion::Inclusion;
use labels::{label_regions, LabelCounts, Labeling, Touch};

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
    #[error("bodies {a} and {b} have frames at different times: {reason}")]
    TimeMismatch {
        /// First body.
        a: String,
        /// Second body.
        b: String,
        /// What differs.
        reason: String,
    },
    /// The tree over a body's tets could not be built.
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
    /// The mesh in checker coordinates.
    pub mesh: TetMesh,
    /// Tree over the tets.
    pub bvh: Bvh,
    /// Face adjacency.
    pub adjacency: Vec<[u32; 4]>,
    /// Checker lattice units per original lattice unit of this body.
    pub factor: i32,
    /// The body's lattice.
    pub geometry: GridGeometry,
    /// Frame stamps (ns) of the common time lattice: checker time `t` is at
    /// `stamps[t / (8·scale)]` plus the fraction within that frame period.
    pub stamps_ns: Vec<i64>,
}

impl Prepared {
    /// The same body with another mesh on the same tets (moved or re-timed): the tree is
    /// rebuilt, the adjacency kept.
    ///
    /// # Errors
    /// The tree cannot be built.
    pub fn with_mesh(&self, mesh: TetMesh) -> Result<Prepared, CheckError> {
        let bvh = Bvh::from_tets(&mesh.vertices, &mesh.tets).map_err(|source| CheckError::Bvh {
            id: self.id.clone(),
            source,
        })?;
        Ok(Prepared {
            id: self.id.clone(),
            mesh,
            bvh,
            adjacency: self.adjacency.clone(),
            factor: self.factor,
            geometry: self.geometry,
            stamps_ns: self.stamps_ns.clone(),
        })
    }
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
                return Err(CheckError::TimeMismatch {
                    a: bodies[0].0.to_string(),
                    b: id.to_string(),
                    reason: "a body's frames are not a contiguous run of the common frame times \
                             (different frame rates or phases are not resampled yet)"
                        .into(),
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

    /// Puts a body on this lattice (coordinates ×[`CHECKER_FACTOR`]).
    ///
    /// # Errors
    /// The tree cannot be built (too many tets).
    pub fn prepare(&self, id: &str, b: &BodyMesh) -> Result<Prepared, CheckError> {
        let g = b
            .geometry
            .ok_or_else(|| CheckError::EmptyBody { id: id.to_string() })?;
        let factor = CHECKER_FACTOR * (self.scale / g.scale);
        let voxels = origin_offset(
            &self.voxel0_centre.map(|c| c - 0.5 * self.resolution),
            &g.origin,
            self.resolution,
        )
        .map_err(|reason| CheckError::LatticeMismatch {
            a: "reference".into(),
            b: id.to_string(),
            reason,
        })?;
        let frame0 = self.stamps_ns.binary_search(&b.stamps_ns[0]).unwrap_or(0) as i64;
        // Checker coordinates must fit in i32 with room for far points (2^30): bodies far
        // apart on a fine lattice are refused, never wrapped.
        let too_far = || {
            CheckError::LatticeMismatch {
            a: "reference".into(),
            b: id.to_string(),
            reason: "checker lattice coordinates would overflow (bodies too far apart, or grids too large \
                     for a common fine lattice)"
                .into(),
        }
        };
        const LIMIT: i64 = 1 << 30;
        let fit = |v: i64| {
            if v.abs() < LIMIT {
                Ok(v)
            } else {
                Err(too_far())
            }
        };
        let step = self.per_step();
        let shift = [
            fit(voxels[0].saturating_mul(step))?,
            fit(voxels[1].saturating_mul(step))?,
            fit(voxels[2].saturating_mul(step))?,
            fit(frame0.saturating_mul(step))?,
        ];
        let mut mesh = b.mesh.clone();
        for p in &mut mesh.vertices {
            for k in 0..4 {
                p[k] = fit(i64::from(p[k]) * i64::from(factor) + shift[k])? as i32;
            }
        }
        let bvh = Bvh::from_tets(&mesh.vertices, &mesh.tets).map_err(|source| CheckError::Bvh {
            id: id.to_string(),
            source,
        })?;
        let adjacency = face_adjacency(&mesh);
        Ok(Prepared {
            id: id.to_string(),
            mesh,
            bvh,
            adjacency,
            factor,
            geometry: g,
            stamps_ns: self.stamps_ns.clone(),
        })
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

/// Whole-voxel offset from origin `a` to origin `b`, or why there is none.
fn origin_offset(a: &[f64; 3], b: &[f64; 3], res: f64) -> Result<[i64; 3], String> {
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
}

impl PairResult {
    /// True if the bodies' interiors overlap somewhere in space-time.
    pub fn interfering(&self) -> bool {
        let (a, b) = (self.labels_a.counts(), self.labels_b.counts());
        a.interference + a.inside + b.interference + b.inside > 0
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

fn tet_of(m: &TetMesh, i: u32) -> [LatticePoint; 4] {
    m.tets[i as usize].map(|v| m.vertices[v as usize])
}

fn t_range(t: &[LatticePoint; 4]) -> (f64, f64) {
    let ts = t.map(|p| p[3]);
    (
        f64::from(*ts.iter().min().expect("4")),
        f64::from(*ts.iter().max().expect("4")),
    )
}

/// Checks two prepared bodies.
pub fn check_pair(a: &Prepared, b: &Prepared) -> PairResult {
    let mut ws = TraverseWorkspace::new();
    let mut hit_a = vec![Touch::Clear; a.mesh.tets.len()];
    let mut hit_b = vec![Touch::Clear; b.mesh.tets.len()];
    let mut ranges: Vec<(f64, f64)> = Vec::new();
    let mut r = PairResult::default();
    overlapping_pairs(&a.bvh, &b.bvh, &mut ws, |i, j| {
        r.candidate_pairs += 1;
        let (ta, tb) = (tet_of(&a.mesh, i), tet_of(&b.mesh, j));
        let (ra, rb) = (t_range(&ta), t_range(&tb));
        let overlap = (ra.0.max(rb.0), ra.1.min(rb.1));
        // Where the two tets meet in time: their section polygon for a crossing; for a
        // coplanar overlap, within both time ranges.
        let (range, touch) = match classify(&ta, &tb) {
            TetPairRelation::Crossing => (
                Some(contact::crossing_t_range(&ta, &tb).unwrap_or(overlap)),
                Touch::Interference,
            ),
            TetPairRelation::Coplanar {
                overlap_volume_positive: true,
                same_orientation: true,
            } => (Some(overlap), Touch::Interference),
            TetPairRelation::Coplanar {
                overlap_volume_positive: true,
                same_orientation: false,
            } => (None, Touch::FaceToFace),
            TetPairRelation::Coplanar { .. } | TetPairRelation::Touching => (None, Touch::Contact),
            TetPairRelation::Disjoint => (None, Touch::Clear),
        };
        if let Some(range) = range {
            r.interfering_pairs += 1;
            ranges.push(range);
        }
        hit_a[i as usize] = hit_a[i as usize].max(touch);
        hit_b[j as usize] = hit_b[j as usize].max(touch);
    });
    r.labels_a = label_against(a, b, &hit_a);
    r.labels_b = label_against(b, a, &hit_b);
    for (p, labels) in [(a, &r.labels_a), (b, &r.labels_b)] {
        for (i, l) in labels.labels.iter().enumerate() {
            if *l == labels::Label::Inside {
                ranges.push(t_range(&tet_of(&p.mesh, i as u32)));
            }
        }
    }
    r.intervals = merge_ranges(ranges);
    r
}

fn label_against(p: &Prepared, other: &Prepared, hit: &[Touch]) -> Labeling {
    let mut inc = Inclusion::new(&other.mesh, &other.bvh);
    label_regions(&p.adjacency, hit, |t, tries| {
        let tet = tet_of(&p.mesh, t);
        // Interior points: coordinates are ×8, so (w·tet)/8 is a lattice point.
        INTERIOR_WEIGHTS.iter().take(tries).find_map(|w| {
            let c = [0, 1, 2, 3]
                .map(|k| ((0..4).map(|v| w[v] * i64::from(tet[v][k])).sum::<i64>() / 8) as i32);
            inc.contains(&c)
        })
    })
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
