//! chronotope: space-time (4D) interference checking for robot and machine-tool cells.
//!
//! Layers, bottom up (lower layers never import upper ones):
//! - [`kernel`]: exact integer lattice geometry in R^4 (points, predicates). No ROS, MCAP or tokio.
//! - [`mesh`]: 4D marching hypercubes, rolling slab mesher, caps, slicing, validation.
//! - [`scene`]: synthetic voxel scenes (machine tool, four spheres).
//! - [`sampler`]: stochastic sampling of implicit figures and 4D collision sets
//!   (docs/methods/sampling.md).
//! - [`msg`]: ROS 2 message types mirrored from `msgs/`, CDR encoding.
//! - [`bag`]: rosbag2 MCAP reading and writing.
//! - [`cli`]: the `chronotope` command line.
//! - [`yaml`]: bounded YAML loading for launch configs and scene files.
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
