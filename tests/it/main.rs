//! The integration tests, one binary: each module is what was a test binary of its own
//! (one link of the crate instead of one per file). Run one module's tests with
//! `cargo test --test it golden::` (and so on).

mod common;
mod domains;
mod pyenv;

mod bag_recovery;
mod bag_roundtrip;
mod bvh;
mod carving;
mod carving_limits;
mod carving_model;
mod carving_node;
mod cdr_vs_cdr_encoding;
mod checker;
mod cli;
mod config_limits;
mod cyclone;
mod damaged_frames;
mod determinism;
mod fuzz;
mod golden;
mod graph;
mod layers;
mod live;
mod mesh_closed;
mod mesh_values;
mod mesher_parallel;
mod msg_definitions;
mod occupancy;
mod python_readers;
mod render;
mod replay;
mod robot_node;
mod robot_plan;
mod rolling;
mod rosbag2;
mod sampler;
mod sampler_checker;
mod sampler_limits;
mod scenes;
mod table;
mod tet_tet;
