//! Integration tests of chronotope-occupancy, in one binary (one link).

// References are written index by index, as the definitions read.
#![allow(clippy::needless_range_loop, clippy::identity_op)]

#[path = "../support/octree_writer.rs"]
mod octree_writer;

mod cloud;
mod cloud_errors;
mod fuzz;
mod octomap;
mod octomap_errors;
