//! Integration tests of chronotope-robot, linked once: URDF refusals, forward kinematics,
//! joint states, trajectories, mesh loading and package search, rasterisation.

mod common;
mod joint_state;
mod kinematics;
mod meshes;
mod raster;
mod trajectory;
mod urdf_errors;
