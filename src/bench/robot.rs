//! The robot node's benchmarks (`chronotope bench robot`):
//!
//! - **accuracy**: the robot cell's arm sweeping into the machine-tool table; the checker's
//!   first contact and contact interval (robot node → mesher → checker, as a replay runs
//!   them) against the exact contact times of the continuous geometry, per grid and
//!   encoding, with the report's error bounds and the run time;
//! - **speed**: the UR5 of example-robot-data (its STL collision meshes) in a robot node fed
//!   joint states at 500 Hz and making frames at 30 Hz on a 2 m lattice: the time of each
//!   frame inside the node (merging, interpolation, kinematics, rasterising, the message)
//!   and the process's resident memory over a long stream.
//!
//! The exact contact times come from parry3d's intersection test on the URDF's primitives
//! (boxes, cylinders, a sphere) posed by `chronotope-robot`'s kinematics, scanned at 1 ms and
//! bisected to 1 µs: independent of the rasteriser, the mesher and the checker, not of the
//! kinematics (which the library's own accuracy script checks against Pinocchio).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use chronotope_robot::urdf::Geometry;
use chronotope_robot::{BasePose, LinkPoses, Robot};
use parry3d::math::{Pose, Vector};
use parry3d::query::intersection_test;
use parry3d::shape::{Ball, Cuboid, Cylinder, SharedShape};

use super::BenchError;
use crate::msg::{Header, JointState, Time, VoxelEncoding};
use crate::node::launch::{LaunchConfig, NodeKind};
use crate::node::robot::RobotNode;
use crate::node::{Message, Node, Payload};
use crate::scene::{
    robot_cell_positions, robot_cell_table, ROBOT_CELL_BASE, ROBOT_CELL_DURATION_S,
    ROBOT_CELL_JOINTS, ROBOT_CELL_URDF,
};

/// The robot cell's arm (links `links`, all if empty) and table at time `t` (s): whether
/// their collision geometry intersects.
struct Cell {
    robot: Robot,
    links: Vec<usize>,
    q: Vec<f64>,
    poses: LinkPoses,
    table: crate::scene::BodySpec,
}

fn to_pose(p: &chronotope_robot::math::Pose) -> Pose {
    let t = p.translation.vector;
    let q = p.rotation.coords;
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        parry3d::math::Rotation::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32),
    )
}

impl Cell {
    fn new(links: &[&str]) -> Self {
        let robot = Robot::from_urdf_str(ROBOT_CELL_URDF, &chronotope_robot::LoadOptions::new())
            .expect("the robot cell's URDF loads");
        let links = if links.is_empty() {
            (0..robot.model().links.len()).collect()
        } else {
            links
                .iter()
                .map(|l| robot.model().link_index(l).expect("a link of arm6"))
                .collect()
        };
        Cell {
            q: vec![0.0; robot.kinematics().dof()],
            robot,
            links,
            poses: LinkPoses::new(),
            table: robot_cell_table(ROBOT_CELL_DURATION_S),
        }
    }

    fn touching(&mut self, t: f64) -> bool {
        let u = t / ROBOT_CELL_DURATION_S;
        let values = robot_cell_positions(u);
        let kin = self.robot.kinematics();
        for (name, v) in ROBOT_CELL_JOINTS.iter().zip(values) {
            if let Some(i) = kin.joint_index(name) {
                self.q[i] = v;
            }
        }
        let [x, y, z] = ROBOT_CELL_BASE;
        kin.forward(
            &self.q,
            &BasePose::from_array([x, y, z, 0.0, 0.0, 0.0]),
            &mut self.poses,
        );
        let [ox, oy, oz] = self.table.offset_at(t);
        let table = Cuboid::new(Vector::new(0.25, 0.25, 0.2));
        let table_pose =
            Pose::from_translation(Vector::new((0.8 + ox) as f32, oy as f32, (0.2 + oz) as f32));
        let model = self.robot.model();
        for &l in &self.links {
            for c in &model.links[l].collisions {
                let at = self.poses.get(l) * c.origin;
                let (shape, pose) = match &c.geometry {
                    Geometry::Box { size } => (
                        SharedShape::new(Cuboid::new(Vector::new(
                            (size[0] / 2.0) as f32,
                            (size[1] / 2.0) as f32,
                            (size[2] / 2.0) as f32,
                        ))),
                        to_pose(&at),
                    ),
                    Geometry::Sphere { radius } => {
                        (SharedShape::new(Ball::new(*radius as f32)), to_pose(&at))
                    }
                    Geometry::Cylinder { radius, length } => {
                        // parry's cylinders stand along y; URDF's along z.
                        let turn = chronotope_robot::math::pose_from_xyz_rpy(
                            [0.0; 3],
                            [std::f64::consts::FRAC_PI_2, 0.0, 0.0],
                        );
                        (
                            SharedShape::new(Cylinder::new((*length / 2.0) as f32, *radius as f32)),
                            to_pose(&(at * turn)),
                        )
                    }
                    Geometry::Mesh { .. } => continue,
                };
                if intersection_test(&pose, shape.as_ref(), &table_pose, &table)
                    .is_ok_and(|r| r.intersecting)
                {
                    return true;
                }
            }
        }
        false
    }
}

/// The exact contact intervals (s from the recording's start) of the robot cell's links
/// `links` (every link if empty) with the table: scanned every millisecond, each change
/// bisected to a microsecond.
pub fn exact_contacts(links: &[&str]) -> Vec<[f64; 2]> {
    let mut cell = Cell::new(links);
    let step = 1e-3;
    let n = (ROBOT_CELL_DURATION_S / step).round() as usize;
    let mut out = Vec::new();
    let mut was = cell.touching(0.0);
    let mut start = was.then_some(0.0);
    for k in 1..=n {
        let t = k as f64 * step;
        let now = cell.touching(t);
        if now != was {
            let (mut lo, mut hi) = (t - step, t);
            while hi - lo > 1e-6 {
                let mid = 0.5 * (lo + hi);
                if cell.touching(mid) == was {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let at = 0.5 * (lo + hi);
            match start.take() {
                Some(s) => out.push([s, at]),
                None => start = Some(at),
            }
            was = now;
        }
    }
    if let Some(s) = start {
        out.push([s, ROBOT_CELL_DURATION_S]);
    }
    out
}

/// One row of the accuracy table.
#[derive(Debug, Clone)]
pub struct AccuracyRow {
    /// Voxels per edge.
    pub grid: u32,
    /// Encoding of the robot's and the table's frames.
    pub encoding: VoxelEncoding,
    /// The checker's first contact and its bound (s).
    pub first_contact: Option<(f64, f64)>,
    /// The checker's interval and the bounds of its ends (s).
    pub interval: Option<([f64; 2], [f64; 2])>,
    /// The replay's wall time (s).
    pub run_s: f64,
}

/// Replays the robot cell at `grid` in `encoding` (the robot in one body, as the default
/// replay makes it) and reads the robot-table pair's first contact and interval.
///
/// # Errors
/// The bag cannot be written or replayed.
pub fn accuracy_row(
    grid: u32,
    encoding: VoxelEncoding,
    dir: &Path,
) -> Result<AccuracyRow, BenchError> {
    let bag = dir.join(format!("robot-cell-{grid}-{encoding:?}.mcap"));
    crate::cli::scene_robot::robot_cell(
        &bag,
        grid,
        encoding,
        false,
        crate::cli::scene_robot::RobotCellTiming::default(),
    )
    .map_err(|e| BenchError::Usage(e.to_string()))?;
    let enc = match encoding {
        VoxelEncoding::Bits => "bits",
        VoxelEncoding::Percent => "percent",
    };
    let config = LaunchConfig::parse(
        &format!(
            "launch:\n- node: {{pkg: chronotope, exec: robot, param: [{{name: lattice_from, value: /table/occupancy}}, {{name: encoding, value: {enc}}}]}}\n- node: {{pkg: chronotope, exec: mesher}}\n- node: {{pkg: chronotope, exec: checker}}\n"
        ),
        "bench",
    )
    .map_err(|e| BenchError::Usage(e.to_string()))?;
    let t = Instant::now();
    let r = crate::cli::replay::replay(&bag, Some(&config), None, false)
        .map_err(|e| BenchError::Usage(e.to_string()))?;
    let run_s = t.elapsed().as_secs_f64();
    let pair = r.report.pairs.first();
    Ok(AccuracyRow {
        grid,
        encoding,
        first_contact: pair.and_then(|p| {
            p.first_contact_s
                .map(|f| (f, p.first_contact_error_bound_s.unwrap_or(f64::NAN)))
        }),
        interval: pair.and_then(|p| {
            let i = p.intervals_s.first()?;
            let b = p
                .interval_error_bounds_s
                .first()
                .copied()
                .unwrap_or([None; 2])
                .map(|b| b.unwrap_or(f64::NAN));
            Some((*i, b))
        }),
        run_s,
    })
}

/// `chronotope bench robot --accuracy`: prints the table of docs/accuracy.md.
///
/// # Errors
/// A replay that fails.
pub fn accuracy(grids: &[u32], encodings: &[VoxelEncoding]) -> Result<(), BenchError> {
    let exact = exact_contacts(&[]);
    println!("exact contact intervals of the whole robot with the table: {exact:?}");
    let Some(&[e0, e1]) = exact.first() else {
        return Err(BenchError::Usage("no exact contact".into()));
    };
    let dir = tempfile::tempdir().map_err(|source| BenchError::Io {
        path: std::env::temp_dir(),
        source,
    })?;
    println!("| grid | encoding | first contact (bound) | error | within | interval end (bound) | error | within | replay s |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for &g in grids {
        for &enc in encodings {
            let row = accuracy_row(g, enc, dir.path())?;
            let (f, fb) = row.first_contact.unwrap_or((f64::NAN, f64::NAN));
            let (i, ib) = row.interval.unwrap_or(([f64::NAN; 2], [f64::NAN; 2]));
            println!(
                "| {g}³ | {enc:?} | {f:.4} s (±{fb:.4}) | {:+.4} s | {} | {:.4} s (±{:.4}) | {:+.4} s | {} | {:.2} |",
                f - e0,
                if (f - e0).abs() <= fb { "yes" } else { "NO" },
                i[1],
                ib[1],
                i[1] - e1,
                if (i[1] - e1).abs() <= ib[1] { "yes" } else { "NO" },
                row.run_s
            );
        }
    }
    Ok(())
}

/// Resident memory now (MB) (Linux: VmRSS), 0 if unknown.
fn rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

/// `chronotope bench robot`: the UR5 (from `share`, the directory holding
/// `example-robot-data/`) in a robot node, joint states at 500 Hz for `seconds` of stream,
/// frames at 30 Hz on `grid`³ over 2 m in `encoding`. Prints the frame times inside the
/// node (median, p90, p99, max) and the resident memory every minute of stream.
///
/// # Errors
/// The UR5 does not load.
pub fn speed(
    share: &Path,
    grid: u32,
    encoding: VoxelEncoding,
    seconds: f64,
) -> Result<(), BenchError> {
    let urdf: PathBuf = share.join("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf");
    let enc = match encoding {
        VoxelEncoding::Bits => "bits",
        VoxelEncoding::Percent => "percent",
    };
    let config = LaunchConfig::parse(
        &format!(
            "launch:\n- node: {{pkg: chronotope, exec: robot, param: [{{name: urdf_file, value: {}}}, {{name: package_path, value: [{}]}}, {{name: origin, value: [-1.0, -1.0, -1.0]}}, {{name: resolution, value: {}}}, {{name: size, value: [{grid}, {grid}, {grid}]}}, {{name: base_pose, value: [0, 0, 0, 0, 0, 0]}}, {{name: rate_hz, value: 30}}, {{name: encoding, value: {enc}}}]}}\n",
            yaml_string(&urdf.display().to_string()),
            yaml_string(&share.display().to_string()),
            2.0 / f64::from(grid)
        ),
        "bench",
    )
    .map_err(|e| BenchError::Usage(e.to_string()))?;
    let spec = config
        .of_kind(NodeKind::Robot)
        .next()
        .expect("one robot node");
    let mut node = RobotNode::from_spec(spec).map_err(|e| BenchError::Usage(e.to_string()))?;
    let names: Vec<String> = node
        .robot()
        .map(|r| r.kinematics().joint_names().to_vec())
        .unwrap_or_default();
    let t0: i64 = 1_700_000_000_000_000_000;
    let period = 2_000_000; // 500 Hz
    let steps = (seconds * 500.0) as i64;
    let mut frame_ms = Vec::new();
    let mut out = Vec::new();
    let rss0 = rss_mb();
    let mut rss = vec![(0.0, rss0)];
    for k in 0..=steps {
        let t = k as f64 * 0.002;
        // Every joint swinging over ±π at its own frequency: every frame a new pose.
        let q: Vec<f64> = (0..names.len())
            .map(|j| std::f64::consts::PI * (t * (0.3 + 0.11 * j as f64)).sin())
            .collect();
        let m = JointState {
            header: Header {
                stamp: Time::from_nanos(t0 + k * period),
                frame_id: String::new(),
            },
            name: names.clone(),
            position: q,
            ..JointState::default()
        };
        let msg = Message::new(
            "/joint_states",
            t0 + k * period,
            Payload::JointState(Arc::new(m)),
        );
        let start = Instant::now();
        node.on_message(&msg, &mut out);
        let took = start.elapsed().as_secs_f64() * 1e3;
        if !out.is_empty() {
            frame_ms.push(took / out.len() as f64);
            out.clear();
        }
        if k % 30_000 == 0 && k > 0 {
            rss.push((t, rss_mb()));
        }
    }
    frame_ms.sort_by(f64::total_cmp);
    let q = |p: f64| frame_ms[((frame_ms.len() - 1) as f64 * p) as usize];
    println!(
        "UR5, {grid}³ over 2 m, {enc}: {} frames in {seconds} s of stream; frame in the node: median {:.3} ms, p90 {:.3}, p99 {:.3}, max {:.3}; problems {}",
        frame_ms.len(),
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0),
        node.status().problem_count()
    );
    let line: Vec<String> = rss
        .iter()
        .map(|(t, m)| format!("{:.0} s: {m:.1} MB", t))
        .collect();
    println!("  resident memory: {}", line.join(", "));
    Ok(())
}

/// `s` as a double-quoted YAML scalar (every byte kept; `yaml::quote` shortens for messages).
fn yaml_string(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}
