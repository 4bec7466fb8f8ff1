//! The interference checker (the interference paper: docs/methods/interference.md): two
//! bodies' closed 4D meshes → per-tet labels, the time intervals of interference, the first
//! contact time and the overlap.
//!
//! Pipeline for a pair: both meshes are put on one integer lattice ([`Prepared`]: common
//! scale, integer origin offset, a common time lattice, coordinates ×8 so that several
//! interior points of every tet are lattice points); an AABB tree over each body's tets
//! gives candidate pairs; the exact predicate [`classify`](chronotope_kernel::classify) keeps the pairs whose boundaries
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
//!
//! # Start here
//!
//! Mesh each body's voxel frames with the mesher's [`BodyAssembler`](chronotope_mesh::glue::BodyAssembler),
//! then check the bodies with [`pipeline::check_bodies`]: the report gives each pair's
//! verdict (collide, clear or unsure), its contact intervals with error bounds, its first
//! contact, and the verified resolutions. A cube sliding into a post:
//!
//! ```
//! use std::collections::BTreeMap;
//! use chronotope_checker::pipeline::{check_bodies, CheckPlan};
//! use chronotope_mesh::glue::BodyAssembler;
//! use chronotope_mesh::{Encoding, FrameRef, MesherOptions};
//!
//! const N: usize = 12;
//! // BITS data of an N³ grid: voxel (x, y, z) occupied where `f` says.
//! let bits = |f: &dyn Fn(usize, usize, usize) -> bool| {
//!     let mut d = vec![0u8; (N * N * N).div_ceil(8)];
//!     for i in (0..N * N * N).filter(|i| f(i % N, i / N % N, i / (N * N))) {
//!         d[i / 8] |= 1 << (i % 8);
//!     }
//!     d
//! };
//! let opts = MesherOptions::default();
//! let (mut cube, mut post) = (BodyAssembler::new(opts)?, BodyAssembler::new(opts)?);
//! for k in 0..6usize {
//!     let frames = [
//!         (&mut cube, bits(&|x, y, z| (k..k + 3).contains(&x) && (4..7).contains(&y) && (4..7).contains(&z))),
//!         (&mut post, bits(&|x, y, z| (7..9).contains(&x) && (3..8).contains(&y) && (2..10).contains(&z))),
//!     ];
//!     for (body, data) in frames {
//!         body.push(&FrameRef {
//!             stamp_ns: k as i64 * 100_000_000, // 10 Hz
//!             origin: [0.0; 3],
//!             resolution: 0.01, // 1 cm voxels
//!             size: [N as u32; 3],
//!             encoding: Encoding::Bits.code(),
//!             data: &data,
//!         })?;
//!     }
//! }
//! let bodies = BTreeMap::from([("/cube".to_owned(), cube.finish()), ("/post".to_owned(), post.finish())]);
//! let plan = CheckPlan::all_pairs_first_movable(&["/cube", "/post"], None);
//! let report = check_bodies(&bodies, &plan, opts)?.report;
//! let pair = &report.pairs[0];
//! assert_eq!(pair.verdict.as_str(), "collide");
//! // The cube's front face (x = k + 3 voxels) reaches the post (x = 7) between frames 3 and 5.
//! let [from, _to] = pair.intervals_s[0];
//! assert!((0.3..=0.5).contains(&from), "{from}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![warn(missing_docs)]

// The API: checking bodies at once or as they stream, the report, the resolutions.
pub mod labels;
pub mod pipeline;
pub mod report;
pub mod resolve;
pub mod rolling;
pub mod rotate;

// The pipeline's parts.
mod adjacency;
mod contact;
mod inclusion;
mod lattice;
mod normals;
mod period;
mod walk;

// Parts this workspace's benchmarks and tests reach into: public for them, with no promise
// to anyone else (hidden from these docs).
#[doc(hidden)]
pub mod bounds;
#[doc(hidden)]
pub mod oracle;
#[doc(hidden)]
pub mod prep;

// The parts of the pair check, visible to every module of the checker.
#[allow(unused_imports)]
use {lattice::*, normals::*, walk::*};

pub(crate) use lattice::origin_offset;
pub use lattice::{mapped_tet_inside, CommonLattice, LatticeMismatch, LinearMap, Placement};
pub(crate) use normals::{t_range, tet_normal, tet_of};
pub use normals::NO_NORMAL;
pub use walk::{
    check_pair, check_pair_detailed, check_pair_walked, interferes, merge_ranges, CrossingPair,
    PairResult, PairTiming, StreamWalk,
};

use chronotope_kernel::bvh::{
    overlapping_boxes_under, top_pairs, Aabb4, Bvh, BvhError, NodePair, TraverseWorkspace,
};
use chronotope_kernel::intersect::{classify_if, TetPairRelation};
use chronotope_kernel::LatticePoint;
use chronotope_mesh::glue::BodyMesh;
use chronotope_mesh::{GridGeometry, TetMesh};
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
    /// Its connected components, computed when first needed (shared like the adjacency).
    pub components: std::sync::Arc<std::sync::OnceLock<labels::Components>>,
    /// A normal of each tet's hyperplane ([`NO_NORMAL`] if it does not fit `i32`): a cheap
    /// exact first test of candidate pairs.
    pub normals: Vec<[i32; 4]>,
    /// Checker lattice units per original lattice unit of this body.
    pub factor: i32,
    /// The body's lattice.
    pub geometry: GridGeometry,
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

    /// Its connected components under face adjacency (computed at the first call, and
    /// shared with its placed copies).
    pub fn components(&self) -> &labels::Components {
        self.components
            .get_or_init(|| labels::Components::of(&self.adjacency))
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

/// The message of a caught panic (its payload), for the places that catch one and say so:
/// the checker's resolver pool, and the live executor's node threads above it.
pub fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}
