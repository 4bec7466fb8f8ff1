//! chronotope-robot: a robot, described by its URDF and moved by joint states or a planned
//! joint trajectory, turned into voxel occupancy frames on a given lattice, in the two
//! encodings of `chronotope_msgs/VoxelGrid` (`bits`, conservative; `percent`, the volume
//! fraction).
//!
//! The pipeline, one module per step, bottom up:
//! - [`urdf`]: parse and check the URDF (typed errors naming the culprit and its line);
//! - [`mesh`]: resolve `package://`, `file://` and relative mesh URIs and load STL,
//!   COLLADA and OBJ within [`limits`];
//! - [`kinematics`]: forward kinematics of every link from joint positions and a base pose;
//! - [`joint_state`]: merge partial JointState messages into a bounded history and
//!   interpolate it to a frame time;
//! - [`trajectory`]: sample a JointTrajectory as ros2_control's joint_trajectory_controller
//!   does, and retime it;
//! - [`robot`]: the robot with its geometry prepared once, and bodies (sets of links);
//! - [`raster`]: rasterise a posed body onto a lattice.
//!
//! It relies on `nalgebra` (poses), `roxmltree` (XML), `mesh-loader` (mesh files) and
//! `thiserror`; it knows nothing of ROS transports, bags or threads, and allocates nothing
//! per frame once its buffers have grown.
//!
//! ```no_run
//! use chronotope_robot::{BasePose, Encoding, Lattice, LinkPoses, LoadOptions, RasterOptions, Rasterizer, Robot};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let robot = Robot::from_urdf_file("ur5.urdf".as_ref(), LoadOptions::new())?;
//! let body = robot.whole_body();
//! let q = vec![0.0; robot.kinematics().dof()];
//! let mut poses = LinkPoses::new();
//! robot.kinematics().forward(&q, &BasePose::IDENTITY, &mut poses);
//! let lattice = Lattice::cube([-1.0, -1.0, -1.0], 2.0, 128)?;
//! let mut raster = Rasterizer::new(lattice, Encoding::Bits, RasterOptions::default());
//! raster.rasterize(&robot, &body, &poses);
//! let data: &[u8] = raster.data(); // VoxelGrid `data`
//! # let _ = data; Ok(()) }
//! ```
#![warn(missing_docs)]

pub mod joint_state;
pub mod kinematics;
pub mod limits;
pub mod math;
pub mod mesh;
pub mod raster;
pub mod robot;
mod shape;
pub mod trajectory;
pub mod urdf;

pub use joint_state::{HistoryBounds, Interpolated, JointStateError, JointStateHistory, Stamp};
pub use kinematics::{Kinematics, LimitViolation, LinkPoses};
pub use limits::Limits;
pub use math::{BasePose, Pose};
pub use mesh::MeshError;
pub use raster::{Encoding, FrameStats, Lattice, LatticeError, RasterOptions, Rasterizer};
pub use robot::{Body, LoadOptions, LoadReport, Robot, RobotError};
pub use trajectory::{JointTrajectory, Sample, StartState, TrajectoryError, TrajectoryPoint};
pub use urdf::{UrdfError, UrdfModel};
