//! The robot node, sans I/O: its URDF from a topic or a file, joint states merged and
//! interpolated to frame times, frames held until the joint states after them arrive, the
//! base pose from `/tf_static`, a plan turned into frames, and every kind of bad input
//! refused by name (or kept and counted, for positions beyond limits). Small lattices only.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use chronotope::msg::{
    Duration, Header, JointState, JointTrajectory, JointTrajectoryPoint, Point, Quaternion,
    RosString, TFMessage, Time, Transform, TransformStamped, Vector3, VoxelGrid,
};
use chronotope::node::launch::{LaunchConfig, NodeKind};
use chronotope::node::robot::RobotNode;
use chronotope::node::{Message, Node, Payload};
use chronotope_robot::{BasePose, Encoding, Lattice, LinkPoses, RasterOptions, Rasterizer};

const T0: i64 = 1_700_000_000_000_000_000;
const MS: i64 = 1_000_000;

/// Two links: a base box, and an arm box on a revolute joint `a` (about z) with a second
/// revolute joint `b` (about y) and a gripper finger mimicking `b`.
const TWO_JOINTS: &str = r#"<robot name="t">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0.15 0 0"/><geometry><box size="0.3 0.06 0.06"/></geometry></collision></link>
  <link name="hand"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="finger"><collision><geometry><box size="0.02 0.02 0.02"/></geometry></collision></link>
  <joint name="a" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>
  <joint name="b" type="revolute"><parent link="arm"/><child link="hand"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1"/></joint>
  <joint name="f" type="revolute"><parent link="hand"/><child link="finger"/><origin xyz="0.05 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1"/><mimic joint="b" multiplier="0.5"/></joint>
</robot>"#;

fn node(params: &str) -> Result<RobotNode, String> {
    let text = format!(
        "launch:\n- node: {{pkg: chronotope, exec: robot, name: robot, param: [{params}]}}\n"
    );
    let c = LaunchConfig::parse(&text, "test").map_err(|e| e.to_string())?;
    let spec = c.of_kind(NodeKind::Robot).next().unwrap();
    RobotNode::from_spec(spec).map_err(|e| e.to_string())
}

/// A node on a 16³ lattice of 5 cm over [-0.4, 0.4]² × [0, 0.8] at 10 Hz, standing at the origin.
fn grid_node(extra: &str) -> RobotNode {
    node(&format!(
        "{{name: origin, value: [-0.4, -0.4, 0.0]}}, {{name: resolution, value: 0.05}}, \
         {{name: size, value: [16, 16, 16]}}, {{name: rate_hz, value: 10}}, \
         {{name: base_pose, value: [0, 0, 0, 0, 0, 0]}}{extra}"
    ))
    .unwrap()
}

fn msg(topic: &str, stamp: i64, payload: Payload) -> Message {
    Message::new(topic, stamp, payload)
}

fn description(text: &str) -> Message {
    msg(
        "/robot_description",
        T0,
        Payload::Text(Arc::new(RosString { data: text.into() })),
    )
}

fn joints(stamp: i64, names: &[&str], q: &[f64]) -> Message {
    msg(
        "/joint_states",
        stamp,
        Payload::JointState(Arc::new(JointState {
            header: Header {
                stamp: Time::from_nanos(stamp),
                frame_id: String::new(),
            },
            name: names.iter().map(|n| (*n).to_owned()).collect(),
            position: q.to_vec(),
            ..JointState::default()
        })),
    )
}

fn feed(n: &mut RobotNode, m: Message) -> Vec<Message> {
    let mut out = Vec::new();
    n.on_message(&m, &mut out);
    out
}

fn frames(out: &[Message]) -> Vec<&VoxelGrid> {
    out.iter()
        .filter_map(|m| match &m.payload {
            Payload::VoxelGrid(g) => Some(g.as_ref()),
            _ => None,
        })
        .collect()
}

fn problems(n: &RobotNode) -> String {
    format!("{:?} {:?}", n.status().problems, n.status().messages)
}

/// The frame the library makes for `q` on the test lattice in `percent`.
fn expected(q: &[f64]) -> Vec<u8> {
    let robot =
        chronotope_robot::Robot::from_urdf_str(TWO_JOINTS, &chronotope_robot::LoadOptions::new())
            .unwrap();
    let mut poses = LinkPoses::new();
    robot
        .kinematics()
        .forward(q, &BasePose::IDENTITY, &mut poses);
    let lattice = Lattice::new([-0.4, -0.4, 0.0], 0.05, [16; 3]).unwrap();
    let mut r = Rasterizer::new(lattice, Encoding::Percent, RasterOptions::default());
    r.rasterize(&robot, &robot.whole_body(), &poses);
    r.data().to_vec()
}

#[test]
fn partial_joint_states_are_merged_by_name_and_a_frame_waits_for_the_samples_after_it() {
    let mut n = grid_node("");
    assert!(feed(&mut n, description(TWO_JOINTS)).is_empty());
    // Joint `a` at 0 ms and 150 ms, joint `b` at 0 ms and 150 ms, in separate messages.
    assert!(feed(&mut n, joints(T0, &["a"], &[0.0])).is_empty());
    assert!(feed(&mut n, joints(T0, &["b"], &[0.0])).is_empty());
    // The 100 ms frame needs a sample at or after 100 ms of both joints.
    assert!(frames(&feed(&mut n, joints(T0 + 150 * MS, &["a"], &[0.6]))).is_empty());
    let out = feed(&mut n, joints(T0 + 150 * MS, &["b"], &[-0.3]));
    let got = frames(&out);
    assert_eq!(got.len(), 1, "{}", problems(&n));
    let g = got[0];
    assert_eq!(g.header.stamp.as_nanos(), T0 + 100 * MS);
    assert_eq!(g.encoding, VoxelGrid::ENCODING_PERCENT);
    assert_eq!(&*out[0].topic, "/robot/occupancy");
    // Linear interpolation at 100 of 150 ms; the mimic joint follows `b`.
    assert_eq!(g.data, expected(&[0.4, -0.2]));
    assert_eq!(n.status().problem_count(), 0, "{}", problems(&n));
}

#[test]
fn frames_follow_the_stamps_and_lattice_of_another_body() {
    let mut n = node(
        "{name: lattice_from, value: /table/occupancy}, {name: encoding, value: bits}, \
         {name: base_pose, value: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]}",
    )
    .unwrap();
    let subs: Vec<String> = n.subscriptions().into_iter().map(|s| s.topic).collect();
    assert!(subs.contains(&"/table/occupancy".to_owned()), "{subs:?}");
    feed(&mut n, description(TWO_JOINTS));
    let table = |stamp: i64| {
        let g = VoxelGrid {
            header: Header {
                stamp: Time::from_nanos(stamp),
                frame_id: "cell".into(),
            },
            origin: Point {
                x: -0.4,
                y: -0.4,
                z: 0.0,
            },
            resolution: 0.05,
            size_x: 16,
            size_y: 16,
            size_z: 16,
            encoding: VoxelGrid::ENCODING_BITS,
            data: vec![0; 512],
        };
        msg("/table/occupancy", stamp, Payload::VoxelGrid(Arc::new(g)))
    };
    feed(&mut n, table(T0 + 33 * MS));
    feed(&mut n, joints(T0, &["a", "b"], &[0.0, 0.0]));
    let out = feed(&mut n, joints(T0 + 40 * MS, &["a", "b"], &[0.1, 0.1]));
    let got = frames(&out);
    assert_eq!(got.len(), 1, "{}", problems(&n));
    assert_eq!(got[0].header.stamp.as_nanos(), T0 + 33 * MS);
    assert_eq!(got[0].header.frame_id, "cell");
    assert_eq!(got[0].data.len(), 512);
}

#[test]
fn the_base_pose_comes_from_tf_static_when_not_given() {
    let mut n = node(
        "{name: origin, value: [-0.4, -0.4, 0.0]}, {name: resolution, value: 0.05}, \
         {name: size, value: [16, 16, 16]}, {name: rate_hz, value: 10}, {name: frame_id, value: world}",
    )
    .unwrap();
    feed(&mut n, description(TWO_JOINTS));
    feed(&mut n, joints(T0, &["a", "b"], &[0.0, 0.0]));
    // Without /tf_static the frame waits.
    assert!(frames(&feed(
        &mut n,
        joints(T0 + 120 * MS, &["a", "b"], &[0.0, 0.0])
    ))
    .is_empty());
    let tf = TFMessage {
        transforms: vec![TransformStamped {
            header: Header {
                stamp: Time::from_nanos(T0),
                frame_id: "world".into(),
            },
            child_frame_id: "base".into(),
            transform: Transform {
                translation: Vector3::new(0.0, 0.0, 0.0),
                rotation: Quaternion::IDENTITY,
            },
        }],
    };
    let out = feed(
        &mut n,
        msg("/tf_static", T0, Payload::TFMessage(Arc::new(tf))),
    );
    assert_eq!(frames(&out).len(), 1, "{}", problems(&n));
    assert_eq!(frames(&out)[0].data, expected(&[0.0, 0.0]));
}

#[test]
fn a_robot_without_its_base_pose_says_how_to_give_it() {
    let mut n = node(
        "{name: origin, value: [0, 0, 0]}, {name: resolution, value: 0.05}, {name: size, value: [8, 8, 8]}",
    )
    .unwrap();
    feed(&mut n, description(TWO_JOINTS));
    feed(&mut n, joints(T0, &["a", "b"], &[0.0, 0.0]));
    feed(&mut n, joints(T0 + 200 * MS, &["a", "b"], &[0.0, 0.0]));
    let mut out = Vec::new();
    n.finish(&mut out);
    assert!(frames(&out).is_empty());
    let p = problems(&n);
    assert!(p.contains("no_base_pose") && p.contains("base_pose"), "{p}");
}

/// Feeds a description and returns the node's problem texts.
fn refused_description(text: &str) -> String {
    let mut n = grid_node("");
    feed(&mut n, description(text));
    assert!(n.robot().is_none());
    problems(&n)
}

#[test]
fn bad_robot_descriptions_are_refused_with_what_was_wrong() {
    let p = refused_description("<robot name=\"x\"><link name=\"a\"></robot>");
    assert!(
        p.contains("bad_robot_description") && p.contains("malformed XML"),
        "{p}"
    );
    let p = refused_description(
        r#"<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="l" value="1"/><link name="a"/></robot>"#,
    );
    assert!(p.contains("xacro") && p.contains("run xacro first"), "{p}");
    let p = refused_description(
        r#"<robot name="x"><link name="a"/><link name="b"/>
        <joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>
        <joint name="j2" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#,
    );
    assert!(
        p.contains("loop") || p.contains("two parents") || p.contains("no link"),
        "{p}"
    );
    let p = refused_description(
        r#"<robot name="x"><link name="a"><collision><geometry><mesh filename="file:///nonexistent/arm.stl" scale="0 1 1"/></geometry></collision></link></robot>"#,
    );
    assert!(p.contains("scale"), "{p}");
    let p = refused_description(
        r#"<robot name="x"><link name="a"><collision><geometry><mesh filename="package://no_such_pkg/meshes/arm.stl"/></geometry></collision></link></robot>"#,
    );
    assert!(
        p.contains("no_such_pkg/meshes/arm.stl") && p.contains("tried"),
        "{p}"
    );
    let p = refused_description(
        r#"<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="floating"><parent link="a"/><child link="b"/></joint></robot>"#,
    );
    assert!(p.contains("floating"), "{p}");
}

#[test]
fn a_mesh_over_the_limits_is_refused_naming_the_file_and_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("huge.stl");
    // A sparse file: its size is refused from the metadata before anything is read.
    std::fs::File::create(&stl)
        .unwrap()
        .set_len(chronotope_robot::limits::MAX_MESH_FILE_BYTES + 1)
        .unwrap();
    let p = refused_description(&format!(
        r#"<robot name="x"><link name="a"><collision><geometry><mesh filename="file://{}"/></geometry></collision></link></robot>"#,
        stl.display()
    ));
    assert!(
        p.contains("huge.stl") && p.contains("MAX_MESH_FILE_BYTES"),
        "{p}"
    );
    // An OBJ of more triangles than MAX_MESH_TRIANGLES (8 bytes a face: 17 MB).
    let big = dir.path().join("many.obj");
    let faces = chronotope_robot::limits::MAX_MESH_TRIANGLES + 1;
    let mut text = String::with_capacity(faces * 8 + 64);
    text.push_str("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for _ in 0..faces {
        text.push_str("f 1 2 3\n");
    }
    std::fs::write(&big, text).unwrap();
    let p = refused_description(&format!(
        r#"<robot name="x"><link name="a"><collision><geometry><mesh filename="file://{}"/></geometry></collision></link></robot>"#,
        big.display()
    ));
    assert!(
        p.contains("many.obj") && p.contains("MAX_MESH_TRIANGLES"),
        "{p}"
    );
}

#[test]
fn a_urdf_file_that_does_not_load_is_refused_at_launch() {
    let e = node(
        "{name: urdf_file, value: /nonexistent/robot.urdf}, {name: lattice_from, value: /t/occupancy}",
    )
    .err()
    .unwrap();
    assert!(
        e.contains("urdf_file") && e.contains("/nonexistent/robot.urdf"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("arm.urdf.xacro");
    std::fs::write(
        &f,
        r#"<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="${prefix}a"/></robot>"#,
    )
    .unwrap();
    let e = node(&format!(
        "{{name: urdf_file, value: {}}}, {{name: lattice_from, value: /t/occupancy}}",
        f.display()
    ))
    .err()
    .unwrap();
    assert!(e.contains("xacro"), "{e}");
    for (params, what) in [
        ("{name: rate_hz, value: 10}", "no lattice"),
        (
            "{name: lattice_from, value: /t/occupancy}, {name: size, value: [4, 4, 4]}",
            "not both",
        ),
        (
            "{name: lattice_from, value: /t/occupancy}, {name: encoding, value: octree}",
            "one of percent, bits",
        ),
        (
            "{name: lattice_from, value: /t/occupancy}, {name: bodies, value: [\"a: x\", \"b: x\"]}",
            "is in bodies",
        ),
        (
            "{name: origin, value: [0, 0, 0]}, {name: resolution, value: 0.1}, {name: size, value: [4.5, 4, 4]}",
            "whole number",
        ),
    ] {
        let e = node(params).err().unwrap();
        assert!(e.contains(what), "{params}: {e}");
    }
}

#[test]
fn bad_joint_states_are_refused_whole_and_counted_and_beyond_limits_is_kept() {
    let mut n = grid_node("");
    feed(&mut n, description(TWO_JOINTS));
    feed(&mut n, joints(T0, &["a", "b"], &[0.0, 0.0]));
    // A name not in the URDF.
    feed(&mut n, joints(T0 + 10 * MS, &["a", "elbow"], &[0.1, 0.2]));
    // Arrays of different lengths.
    feed(&mut n, joints(T0 + 20 * MS, &["a", "b"], &[0.1]));
    let mut m = JointState {
        header: Header {
            stamp: Time::from_nanos(T0 + 25 * MS),
            frame_id: String::new(),
        },
        name: vec!["a".into(), "b".into()],
        position: vec![0.0, 0.0],
        velocity: vec![1.0],
        effort: Vec::new(),
    };
    feed(
        &mut n,
        msg(
            "/joint_states",
            T0,
            Payload::JointState(Arc::new(m.clone())),
        ),
    );
    // Non-finite positions: refused, each counted.
    m.velocity.clear();
    m.position = vec![f64::NAN, f64::INFINITY];
    m.header.stamp = Time::from_nanos(T0 + 30 * MS);
    feed(
        &mut n,
        msg("/joint_states", T0, Payload::JointState(Arc::new(m))),
    );
    // Beyond the limits: kept (the frame shows it), warned, counted.
    let out = feed(&mut n, joints(T0 + 100 * MS, &["a", "b"], &[1.5, 0.0]));
    let s = n.status();
    assert_eq!(
        s.problems.get("joint_state_refused"),
        Some(&3),
        "{}",
        problems(&n)
    );
    assert_eq!(
        s.problems.get("non_finite_position"),
        Some(&2),
        "{}",
        problems(&n)
    );
    assert_eq!(
        s.problems.get("beyond_limits"),
        Some(&1),
        "{}",
        problems(&n)
    );
    let p = problems(&n);
    assert!(
        p.contains("elbow") && p.contains("1 positions") && p.contains("velocity"),
        "{p}"
    );
    assert!(p.contains("beyond its limits") && p.contains("kept"), "{p}");
    let got = frames(&out);
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].data, expected(&[1.5, 0.0]));
}

fn point(q: [f64; 2], t_ms: i64) -> JointTrajectoryPoint {
    JointTrajectoryPoint {
        positions: q.to_vec(),
        time_from_start: Duration::from_nanos(t_ms * MS),
        ..JointTrajectoryPoint::default()
    }
}

fn plan(points: Vec<JointTrajectoryPoint>, names: &[&str]) -> Message {
    msg(
        "/arm/joint_trajectory",
        T0 + 50 * MS,
        Payload::JointTrajectory(Arc::new(JointTrajectory {
            header: Header::default(),
            joint_names: names.iter().map(|n| (*n).to_owned()).collect(),
            points,
        })),
    )
}

#[test]
fn a_plan_becomes_frames_over_its_time_from_its_arrival_when_its_stamp_is_zero() {
    let mut n = grid_node(", {name: trajectory_topic, value: /arm/joint_trajectory}");
    feed(&mut n, description(TWO_JOINTS));
    feed(&mut n, joints(T0, &["a", "b"], &[0.0, 0.0]));
    // Arrives at 50 ms with a zero stamp: starts then; linear to 0.5 at +250 ms (300 ms).
    let mut out = feed(
        &mut n,
        plan(
            vec![point([0.0, 0.0], 0), point([0.5, 0.5], 250)],
            &["a", "b"],
        ),
    );
    n.finish(&mut out);
    let got = frames(&out);
    let stamps: Vec<i64> = got
        .iter()
        .map(|g| (g.header.stamp.as_nanos() - T0) / MS)
        .collect();
    assert_eq!(stamps, [100, 200, 300], "{}", problems(&n));
    // At 200 ms: 150 of 250 ms into the segment.
    assert_eq!(got[1].data, expected(&[0.3, 0.3]));
    assert_eq!(got[2].data, expected(&[0.5, 0.5]));
}

#[test]
fn bad_plans_are_refused_by_name() {
    let mut n = grid_node(", {name: trajectory_topic, value: /arm/joint_trajectory}");
    feed(&mut n, description(TWO_JOINTS));
    feed(&mut n, joints(T0, &["a", "b"], &[0.0, 0.0]));
    feed(
        &mut n,
        plan(
            vec![point([0.0, 0.0], 100), point([0.5, 0.5], 100)],
            &["a", "b"],
        ),
    );
    feed(&mut n, plan(vec![point([0.0, 0.0], 100)], &["a", "wrist"]));
    let p = problems(&n);
    assert!(p.contains("does not strictly increase"), "{p}");
    assert!(
        p.contains("wrist") && p.contains("not movable joints"),
        "{p}"
    );
    assert_eq!(n.status().problems.get("plan_refused"), Some(&2));
}

/// The directory holding `example-robot-data/` (the package) in the tests' Python
/// environment, or `None` with the reason.
fn example_robot_data() -> Result<PathBuf, String> {
    let python = std::env::var_os("CHRONOTOPE_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let target = std::env::var_os("CARGO_TARGET_DIR")
                .map(PathBuf::from)
                .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
            target.join("py/bin/python")
        });
    let o = std::process::Command::new(&python)
        .args([
            "-c",
            "import example_robot_data, os; print(os.path.dirname(os.path.dirname(example_robot_data.getModelPath('ur5_robot.urdf'))))",
        ])
        .output()
        .map_err(|e| format!("{}: {e}", python.display()))?;
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).trim().to_owned());
    }
    let share = PathBuf::from(String::from_utf8_lossy(&o.stdout).trim());
    share
        .join("example-robot-data")
        .is_dir()
        .then_some(share.clone())
        .ok_or_else(|| format!("{} has no example-robot-data/", share.display()))
}

#[test]
fn the_ur5_and_the_panda_of_example_robot_data_load_and_make_frames() {
    let share = match example_robot_data() {
        Ok(s) => s,
        Err(why) => {
            eprintln!(
                "SKIPPED: example-robot-data is not in the tests' Python environment \
                 (run `python3 tests/py/setup_env.py`): {why}"
            );
            return;
        }
    };
    let robots = share.join("example-robot-data/robots");
    for (urdf, joint) in [
        ("ur_description/urdf/ur5_robot.urdf", "shoulder_lift_joint"),
        ("panda_description/urdf/panda.urdf", "panda_joint2"),
    ] {
        let mut n = node(&format!(
            "{{name: urdf_file, value: {}}}, {{name: package_path, value: [{}]}}, \
             {{name: origin, value: [-1.0, -1.0, -1.0]}}, {{name: resolution, value: 0.0625}}, \
             {{name: size, value: [32, 32, 32]}}, {{name: base_pose, value: [0, 0, 0, 0, 0, 0]}}, \
             {{name: rate_hz, value: 10}}",
            robots.join(urdf).display(),
            share.display()
        ))
        .unwrap_or_else(|e| panic!("{urdf}: {e}"));
        let robot = n.robot().expect("loaded at launch");
        let meshes = robot.load_report().meshes.len();
        assert!(meshes >= 5, "{urdf}: {meshes} meshes");
        let names: Vec<String> = robot.kinematics().joint_names().to_vec();
        let zeros = vec![0.0; names.len()];
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        feed(&mut n, joints(T0, &refs, &zeros));
        let mut q = zeros.clone();
        q[names.iter().position(|j| j == joint).unwrap()] = -0.5;
        let out = feed(&mut n, joints(T0 + 100 * MS, &refs, &q));
        let got = frames(&out);
        assert_eq!(got.len(), 1, "{urdf}: {}", problems(&n));
        let occupied = got[0].data.iter().filter(|&&v| v > 0).count();
        assert!(occupied > 30, "{urdf}: {occupied} voxels");
        assert_eq!(n.status().problem_count(), 0, "{urdf}: {}", problems(&n));
    }
}

/// A joint state stamped far past the last (a clock jump, a bad stamp) does not make the node
/// visit every grid time in between: the oldest are skipped, counted, and the node answers at
/// once.
#[test]
fn a_stamp_far_ahead_skips_the_grid_times_between_at_once() {
    let mut n = grid_node("");
    feed(&mut n, description(TWO_JOINTS));
    let names = ["a", "b"];
    feed(&mut n, joints(T0, &names, &[0.0, 0.0]));
    let start = std::time::Instant::now();
    // 4·10^17 ns (12 years) later: 4·10^9 grid times at 10 Hz.
    feed(
        &mut n,
        joints(T0 + 400_000_000_000_000_000, &names, &[0.0, 0.0]),
    );
    let mut out = Vec::new();
    n.on_tick(i64::MAX, &mut out);
    n.finish(&mut out);
    // Not a speed test: visiting the 10^10 grid times would take hours.
    assert!(
        start.elapsed() < std::time::Duration::from_secs(60),
        "{:?}",
        start.elapsed()
    );
    assert!(problems(&n).contains("frames_dropped"), "{}", problems(&n));
    // And at the very end of time, nothing overflows.
    feed(&mut n, joints(i64::MAX, &names, &[0.0, 0.0]));
}
