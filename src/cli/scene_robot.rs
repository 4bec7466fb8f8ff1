//! `chronotope scene robot-cell [--plan]`: the robot cell recorded the way `ros2 bag record`
//! records it (see [`crate::scene`]'s `robot_cell` items for the layout and the motion).

use std::path::Path;
use std::sync::Arc;

use super::CliError;
use crate::bag::{BagWriteOptions, BagWriter};
use crate::msg::{
    Duration, Header, JointState, JointTrajectory, JointTrajectoryPoint, Point, Quaternion,
    RosString, TFMessage, Time, Transform, TransformStamped, Vector3, VoxelEncoding, VoxelGrid,
};
use crate::scene::{
    robot_cell_lattice, robot_cell_positions, robot_cell_table, robot_cell_velocities, Rasterizer,
    ROBOT_CELL_BASE, ROBOT_CELL_DURATION_S, ROBOT_CELL_FIRST_MESSAGE_JOINTS,
    ROBOT_CELL_FRAME_PERIOD_NS, ROBOT_CELL_JOINTS, ROBOT_CELL_JOINT_PERIOD_NS,
    ROBOT_CELL_PLAN_SENT_U, ROBOT_CELL_PLAN_U, ROBOT_CELL_URDF, SCENE_FRAME_ID, SCENE_START_NS,
};

/// The topic the plan variant sends its plan on (joint_trajectory_controller's).
pub const PLAN_TOPIC: &str = "/arm_controller/joint_trajectory";

/// Points of the plan: one every 0.1 s over its span.
const PLAN_POINT_PERIOD_S: f64 = 0.1;

fn transform(parent: &str, child: &str, xyz: [f64; 3]) -> TransformStamped {
    TransformStamped {
        header: Header {
            stamp: Time::from_nanos(SCENE_START_NS),
            frame_id: parent.into(),
        },
        child_frame_id: child.into(),
        transform: Transform {
            translation: Vector3::new(xyz[0], xyz[1], xyz[2]),
            rotation: Quaternion::IDENTITY,
        },
    }
}

fn joint_state(stamp: i64, joints: &[&str], q: &[f64]) -> JointState {
    JointState {
        header: Header {
            stamp: Time::from_nanos(stamp),
            frame_id: String::new(),
        },
        name: joints.iter().map(|j| (*j).to_owned()).collect(),
        position: q.to_vec(),
        velocity: Vec::new(),
        effort: Vec::new(),
    }
}

/// The plan of the arm's dip: points every 0.1 s with positions and velocities (so the
/// controller's splines are cubic), starting at its header stamp.
pub fn robot_cell_plan() -> JointTrajectory {
    let d = ROBOT_CELL_DURATION_S;
    let (u0, u1) = ROBOT_CELL_PLAN_U;
    let n = ((u1 - u0) * d / PLAN_POINT_PERIOD_S).round() as usize;
    let start = SCENE_START_NS + (u0 * d * 1e9).round() as i64;
    JointTrajectory {
        header: Header {
            stamp: Time::from_nanos(start),
            frame_id: String::new(),
        },
        joint_names: ROBOT_CELL_JOINTS.iter().map(|j| (*j).to_owned()).collect(),
        points: (0..=n)
            .map(|k| {
                let tfs = k as f64 * PLAN_POINT_PERIOD_S;
                let u = u0 + tfs / d;
                JointTrajectoryPoint {
                    positions: robot_cell_positions(u).to_vec(),
                    velocities: robot_cell_velocities(u, d).to_vec(),
                    accelerations: Vec::new(),
                    effort: Vec::new(),
                    time_from_start: Duration::from_nanos((tfs * 1e9).round() as i64),
                }
            })
            .collect(),
    }
}

/// The robot cell's rates: the table's frames and the joint states.
#[derive(Debug, Clone, Copy)]
pub struct RobotCellTiming {
    /// Time between the table's frames (ns).
    pub frame_period_ns: i64,
    /// Time between joint-state instants (ns).
    pub joint_period_ns: i64,
}

impl Default for RobotCellTiming {
    /// The bundled bag's: the table at 10 Hz, joint states at 200 Hz.
    fn default() -> Self {
        Self {
            frame_period_ns: ROBOT_CELL_FRAME_PERIOD_NS,
            joint_period_ns: ROBOT_CELL_JOINT_PERIOD_NS,
        }
    }
}

/// Writes the robot cell at `grid` voxels per edge: `/robot_description`, `/tf_static`
/// (world → base_link, as a static broadcaster; link6 → tool0, as robot_state_publisher
/// publishes the URDF's fixed joints), `/joint_states` (200 Hz by default) in two partial
/// messages per instant, and `/table/occupancy` (10 Hz by default), each table frame written
/// before the joint states of its instant; with `plan`, the dip as a plan sent at 0.5 s and
/// joint states only until then.
///
/// # Errors
/// A grid out of range or a bag that cannot be written.
pub fn robot_cell(
    out: &Path,
    grid: u32,
    encoding: VoxelEncoding,
    plan: bool,
    timing: RobotCellTiming,
) -> Result<(), CliError> {
    if !(crate::scene::MIN_GRID..=crate::scene::MAX_GRID).contains(&grid) {
        return Err(crate::scene::SceneError::GridOutOfRange { grid }.into());
    }
    let d = ROBOT_CELL_DURATION_S;
    let lattice = robot_cell_lattice(grid);
    let table = robot_cell_table(d);
    let mut w = BagWriter::create_with(out, BagWriteOptions::new().derived("scene"))?;
    w.add_topic::<RosString>("/robot_description")?;
    w.add_topic::<TFMessage>("/tf_static")?;
    w.add_topic::<JointState>("/joint_states")?;
    w.add_topic::<VoxelGrid>("/table/occupancy")?;
    if plan {
        w.add_topic::<JointTrajectory>(PLAN_TOPIC)?;
    }
    let t0 = SCENE_START_NS;
    w.write(
        "/robot_description",
        t0 as u64,
        &RosString {
            data: ROBOT_CELL_URDF.to_owned(),
        },
    )?;
    w.write(
        "/tf_static",
        t0 as u64,
        &TFMessage {
            transforms: vec![transform(SCENE_FRAME_ID, "base_link", ROBOT_CELL_BASE)],
        },
    )?;
    w.write(
        "/tf_static",
        t0 as u64,
        &TFMessage {
            transforms: vec![transform("link6", "tool0", [0.0, 0.0, 0.04])],
        },
    )?;
    let span_ns = (d * 1e9) as i64;
    let steps = span_ns / timing.joint_period_ns;
    // On a joint-state instant (the last at or before the plan's sending time).
    let sent =
        (ROBOT_CELL_PLAN_SENT_U * d * 1e9) as i64 / timing.joint_period_ns * timing.joint_period_ns;
    let mut raster = Rasterizer::new();
    let mut g = VoxelGrid {
        origin: Point {
            x: lattice.origin[0],
            y: lattice.origin[1],
            z: lattice.origin[2],
        },
        resolution: lattice.resolution,
        size_x: lattice.size[0],
        size_y: lattice.size[1],
        size_z: lattice.size[2],
        encoding: encoding.code(),
        ..VoxelGrid::default()
    };
    let (arm, wrist) = ROBOT_CELL_JOINTS.split_at(ROBOT_CELL_FIRST_MESSAGE_JOINTS);
    // The table's frames up to `until` (ns after the start), in time order.
    let mut next_frame = 0i64;
    let mut table_until = |until: i64, w: &mut BagWriter| -> Result<(), CliError> {
        while next_frame * timing.frame_period_ns <= until.min(span_ns) {
            let dt = next_frame * timing.frame_period_ns;
            raster.rasterize(
                &table.shapes,
                table.offset_at(dt as f64 * 1e-9),
                &lattice,
                encoding,
                &mut g.data,
            );
            g.header = Header {
                stamp: Time::from_nanos(t0 + dt),
                frame_id: SCENE_FRAME_ID.into(),
            };
            w.write("/table/occupancy", (t0 + dt) as u64, &g)?;
            next_frame += 1;
        }
        Ok(())
    };
    for k in 0..=steps {
        let dt = k * timing.joint_period_ns;
        let stamp = t0 + dt;
        let u = dt as f64 * 1e-9 / d;
        table_until(dt, &mut w)?;
        if plan && dt > sent {
            continue;
        }
        let q = if plan {
            robot_cell_positions(0.0)
        } else {
            robot_cell_positions(u)
        };
        let (qa, qb) = q.split_at(ROBOT_CELL_FIRST_MESSAGE_JOINTS);
        w.write("/joint_states", stamp as u64, &joint_state(stamp, arm, qa))?;
        w.write(
            "/joint_states",
            stamp as u64,
            &joint_state(stamp, wrist, qb),
        )?;
        if plan && dt == sent {
            let p = Arc::new(robot_cell_plan());
            w.write(PLAN_TOPIC, stamp as u64, p.as_ref())?;
        }
    }
    table_until(span_ns, &mut w)?;
    w.finish()?;
    tracing::info!(
        "wrote {} (robot cell, {grid}^3 voxels, {encoding:?}{})",
        out.display(),
        if plan { ", plan" } else { "" }
    );
    Ok(())
}
