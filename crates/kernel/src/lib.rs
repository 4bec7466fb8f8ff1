//! The 4D geometry kernel: exact integer lattice points and predicates.
//!
//! Everything that decides *where* a surface is or *whether* two things touch works on
//! [`LatticePoint`]s (integers) with exact arithmetic; floats appear only when a result is
//! reported in metres and seconds (see [`stamp_time_s`] and [`float`]). Knows nothing of ROS, MCAP or tokio.

#![warn(missing_docs)]

pub mod float;
mod lattice;
mod predicates;

pub use lattice::{stamp_time_s, LatticePoint, SpaceTimePoint};
pub use predicates::{det4_i128, orient4_i128};

pub mod intersect;
pub use intersect::{classify, tets_cross, tets_intersect, TetPairRelation};

pub mod bvh;
pub use bvh::{
    overlapping_boxes_under, overlapping_pairs, overlapping_pairs_under, top_pairs,
    try_overlapping_pairs, Aabb4, Bvh, BvhError, Forest, NodePair, TraverseWorkspace,
};
