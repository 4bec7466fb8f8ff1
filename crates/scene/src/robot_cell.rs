//! The `robot-cell` scene: a six-axis arm with a gripper (the project's own URDF,
//! `scenes/robot-cell/arm6.urdf`, collision geometry as primitives) beside a machine-tool
//! table that shuttles out from under it, recorded the way `ros2 bag record` records a cell: the
//! robot description, joint states at 200 Hz in two partial messages per instant (the arm's
//! controller and the wrist-and-gripper controller), `/tf_static`, and the table as VoxelGrid
//! frames at 10 Hz. The arm dips towards the table before the table has left: they collide.
//!
//! Pure: the URDF text, the joint positions at any run fraction and the table body; the
//! command line writes the bag (`chronotope scene robot-cell`). Layout and times:
//! docs/scenes.md.

use super::{BodySpec, Keyframe, Motion, Shape, VoxelLattice};

/// The arm's URDF (`scenes/robot-cell/arm6.urdf`).
pub const ROBOT_CELL_URDF: &str = include_str!("../../../scenes/robot-cell/arm6.urdf");

/// The URDF root link's place in `world` (published on `/tf_static`): x, y, z (m).
pub const ROBOT_CELL_BASE: [f64; 3] = [0.1, 0.0, 0.0];

/// Length of the recording (s).
pub const ROBOT_CELL_DURATION_S: f64 = 4.0;

/// Time between the table's frames (ns): 10 Hz.
pub const ROBOT_CELL_FRAME_PERIOD_NS: i64 = 100_000_000;

/// Time between joint states (ns): 200 Hz.
pub const ROBOT_CELL_JOINT_PERIOD_NS: i64 = 5_000_000;

/// The independent joints, in the URDF's order; the first three come in one message (the
/// arm controller's), the rest in another (the wrist and gripper's).
pub const ROBOT_CELL_JOINTS: [&str; 7] = [
    "joint1",
    "joint2",
    "joint3",
    "joint4",
    "joint5",
    "joint6",
    "finger_left_joint",
];

/// Joints of the first partial JointState message of each instant.
pub const ROBOT_CELL_FIRST_MESSAGE_JOINTS: usize = 3;

/// Edge of the cubic domain (m); the domain is `[-0.4, 1.2] × [-0.8, 0.8] × [0, 1.6]`.
pub const ROBOT_CELL_DOMAIN_EDGE: f64 = 1.6;

/// Minimum corner of the domain (m).
pub const ROBOT_CELL_DOMAIN_ORIGIN: [f64; 3] = [-0.4, -0.8, 0.0];

/// The plan's span in run fractions: the dip, as a JointTrajectory, in the plan variant.
pub const ROBOT_CELL_PLAN_U: (f64, f64) = (0.2, 0.8);

/// When the plan is published, as a run fraction (it starts at [`ROBOT_CELL_PLAN_U`]`.0`).
pub const ROBOT_CELL_PLAN_SENT_U: f64 = 0.125;

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// 0 before `a`, rising to 1 at `b`, falling back to 0 at `c` (smoothly).
fn bump(u: f64, a: f64, b: f64, c: f64) -> f64 {
    smoothstep((u - a) / (b - a)) - smoothstep((u - b) / (c - b))
}

/// The joint positions (rad, m) of [`ROBOT_CELL_JOINTS`] at run fraction `u` (0..=1): the
/// arm upright, dipping towards the table between u = 0.25 and 0.75 (deepest at 0.5),
/// the wrist turning, the gripper closing during the dip.
pub fn robot_cell_positions(u: f64) -> [f64; 7] {
    let dip = bump(u, 0.25, 0.5, 0.75);
    [
        0.0,
        1.2 * dip,
        1.0 * dip,
        0.0,
        0.5 * dip,
        1.5 * u,
        0.03 * (1.0 - bump(u, 0.35, 0.5, 0.65)),
    ]
}

/// The joint velocities (rad/s, m/s) at `u`, by central differences of the positions over a
/// recording of `duration_s` (for the plan's points).
pub fn robot_cell_velocities(u: f64, duration_s: f64) -> [f64; 7] {
    let h = 1e-6;
    let (a, b) = (robot_cell_positions(u - h), robot_cell_positions(u + h));
    let mut v = [0.0; 7];
    for k in 0..7 {
        v[k] = (b[k] - a[k]) / (2.0 * h * duration_s);
    }
    v
}

/// The machine-tool table: 0.5 × 0.5 × 0.4 m, beside the robot along x, under the arm's
/// reach at first, shuttling out along -y between u = 0.45 and 0.65 and staying there.
pub fn robot_cell_table(duration_s: f64) -> BodySpec {
    let key = |u: f64, offset: [f64; 3]| Keyframe {
        t: u * duration_s,
        offset,
    };
    BodySpec::new(
        "/table/occupancy",
        "machine-tool table (0.5 x 0.5 x 0.4 m) shuttling out along -y from under the arm",
        vec![Shape::cuboid([0.55, -0.25, 0.0], [1.05, 0.25, 0.4])],
        Motion::keyframes(vec![
            key(0.0, [0.0, 0.0, 0.0]),
            key(0.45, [0.0, 0.0, 0.0]),
            key(0.65, [0.0, -0.5, 0.0]),
            key(1.0, [0.0, -0.5, 0.0]),
        ]),
    )
}

/// The scene's lattice at `grid` voxels per edge.
pub fn robot_cell_lattice(grid: u32) -> VoxelLattice {
    VoxelLattice::cube(ROBOT_CELL_DOMAIN_ORIGIN, ROBOT_CELL_DOMAIN_EDGE, grid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_arm_rests_upright_dips_once_and_stays_within_its_limits() {
        let rest = robot_cell_positions(0.0);
        assert_eq!(&rest[..6], &[0.0; 6]);
        let deep = robot_cell_positions(0.5);
        assert!((deep[1] - 1.2).abs() < 1e-12 && (deep[2] - 1.0).abs() < 1e-12);
        assert!(
            deep[6].abs() < 1e-12,
            "the gripper is closed at the deepest point"
        );
        for k in 0..=400 {
            let q = robot_cell_positions(f64::from(k) / 400.0);
            assert!(q[1] <= 2.0 && q[2] <= 2.5 && q[4] <= 2.0);
            assert!((0.0..=0.04).contains(&q[6]));
        }
        assert!(ROBOT_CELL_URDF.contains("<robot name=\"arm6\">"));
    }
}
