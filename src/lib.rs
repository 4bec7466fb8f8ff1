//! chronotope: space-time (4D) interference checking for robot and machine-tool cells.
//!
//! This crate is the command line ([`cli`]) and the benchmarks it runs ([`bench`]) on the
//! layer crates, which it re-exports under their module paths. Bottom up (a crate never
//! imports one above it; ARCHITECTURE.md):
//! - [`kernel`]: exact integer lattice geometry in R^4 (points, predicates, BVH).
//! - [`mesh`]: 4D marching hypercubes, rolling slab mesher, caps, slicing, validation.
//! - [`checker`]: interference labels, intervals, verdicts and verified resolutions.
//! - [`yaml`]: bounded YAML loading for launch configs and scene files.
//! - [`carving`]: tool poses to material removed from a surfel workpiece and a force.
//! - [`sampler`]: stochastic sampling of implicit figures and 4D collision sets
//!   (docs/methods/sampling.md).
//! - [`msg`]: ROS 2 message types mirrored from `msgs/`, CDR encoding.
//! - [`scene`]: synthetic scenes (machine tool, four spheres, robot cell, person) as messages.
//! - [`bag`]: rosbag2 MCAP and SQLite reading, MCAP writing; [`fsio`], the file I/O under it.
//! - [`node`]: the sans-I/O nodes, launch configs, the node factory, the in-process bus.
//! - [`live`]: the nodes on DDS.
#![warn(missing_docs)]

pub use chronotope_bag as bag;
pub mod bench;
pub use chronotope_carving as carving;
pub use chronotope_checker as checker;
pub mod cli;
pub use chronotope_bag::fsio;
pub use chronotope_kernel as kernel;
pub use chronotope_live as live;
pub use chronotope_mesh as mesh;
pub use chronotope_msg as msg;
pub use chronotope_node as node;
pub use chronotope_sampler as sampler;
pub use chronotope_scene as scene;
pub use chronotope_yaml as yaml;

/// The message of a caught panic (the checker crate's, which catches them first).
pub use chronotope_checker::panic_text;
