//! The carving node's limits hold for the whole run: a pause in the pose stream costs one
//! pose's work, a short occupancy period cannot multiply the frames, the workpiece is
//! refused by its memory limit before anything is allocated, a pose's sweep work is
//! bounded, an unstable virtual coupling is refused at launch and no force is ever NaN, and
//! a cut-out path that is not a regular file is refused without opening it.

use chronotope::carving::cutout::{BinaryImage, ImageError};
use chronotope::carving::{
    CarveError, CutStats, ForceModel, ForceParams, ForceRenderer, Quat, Tool, ToolPose, Workpiece,
    COUPLING_STEP_S, MAX_POINTS,
};
use chronotope::msg::{Header, Point, Pose, PoseStamped, Quaternion, Time};
use chronotope::node::carving::{CarvingNode, MAX_FRAME_BYTES_PER_S};
use chronotope::node::launch::LaunchConfig;
use chronotope::node::{Message, Node, Payload};
use std::sync::Arc;

const T0: i64 = 1_000_000_000;

// The documented 256^3 workpiece still fits under the memory-derived limit.
const _: () = assert!(MAX_POINTS >= 256 * 256 * 256);
const ID: [f64; 4] = [0.0, 0.0, 0.0, 1.0];

fn config(params: &str) -> String {
    format!(
        "launch:\n- node:\n    pkg: chronotope\n    exec: carving\n    param:\n    - {{name: pose_topic, value: /haptic/pose}}\n{params}"
    )
}

fn try_node(params: &str) -> Result<CarvingNode, String> {
    let c = LaunchConfig::parse(&config(params), "test").unwrap();
    CarvingNode::from_spec(&c.nodes[0]).map_err(|e| e.to_string())
}

/// A 20 x 20 x 10 mm block at 1 mm with the given extra parameters.
fn node(extra: &str) -> CarvingNode {
    try_node(&format!(
        "    - {{name: workpiece_max, value: [0.02, 0.02, 0.01]}}\n    - {{name: spacing_m, value: 0.001}}\n{extra}"
    ))
    .unwrap()
}

fn pose_at(stamp: i64, p: [f64; 3]) -> Message {
    Message::new(
        "/haptic/pose",
        stamp,
        Payload::PoseStamped(Arc::new(PoseStamped {
            header: Header {
                stamp: Time::from_nanos(stamp),
                frame_id: "world".into(),
            },
            pose: Pose {
                position: Point {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                },
                orientation: Quaternion {
                    x: ID[0],
                    y: ID[1],
                    z: ID[2],
                    w: ID[3],
                },
            },
        })),
    )
}

fn count(out: &[Message], suffix: &str) -> usize {
    out.iter().filter(|m| m.topic.ends_with(suffix)).count()
}

#[test]
fn a_one_hour_pause_costs_one_pose_of_work() {
    let mut n = node("    - {name: occupancy_period_s, value: 0.001}\n");
    let hour = 3600 * 1_000_000_000i64;
    let stamps = [T0, T0 + 1_000_000, T0 + 1_000_000 + hour];
    let mut per_pose = Vec::new();
    for (k, &t) in stamps.iter().enumerate() {
        let mut out = Vec::new();
        n.on_message(
            &pose_at(t, [0.004 + 0.0005 * k as f64, 0.01, 0.009]),
            &mut out,
        );
        assert!(out[0].topic.ends_with("/wrench"), "the wrench goes first");
        per_pose.push((count(&out, "/wrench"), count(&out, "/occupancy")));
    }
    // One wrench and at most one frame per pose, whatever the pause.
    assert_eq!(per_pose, vec![(1, 1), (1, 1), (1, 1)]);
    assert_eq!(n.status().problems["pose_pause"], 1);
    // 3.6M periods of 1 ms passed without a pose; they are counted, not published.
    assert_eq!(n.skipped_periods(), 3_600_000 - 1);
    assert!(n.last_force().iter().all(|f| f.is_finite()));
    // The frame after the pause is on the period grid, at or before the pose.
    let mut out = Vec::new();
    n.finish(&mut out);
    assert_eq!(count(&out, "/occupancy"), 1);
    assert!(out[0].stamp_ns > stamps[2]);
}

#[test]
fn frames_never_outnumber_poses_and_big_frames_are_throttled() {
    // A short period and poses 10 ms apart: one frame per pose, not ten.
    let mut n = node("    - {name: occupancy_period_s, value: 0.001}\n");
    let mut out = Vec::new();
    for k in 0..20 {
        n.on_message(
            &pose_at(
                T0 + k * 10_000_000,
                [0.004 + 0.0005 * k as f64, 0.01, 0.009],
            ),
            &mut out,
        );
    }
    assert_eq!(count(&out, "/occupancy"), 20);
    assert!(!n.status().problems.contains_key("occupancy_throttled"));
    assert_eq!(n.skipped_periods(), 19 * 9);

    // A 64^3 block's frame (~0.8 MB with the whole cloud every frame) takes longer than 1 ms
    // at the frame byte budget: frames every 2 ms, the periods left out counted.
    let mut n = try_node(
        "    - {name: workpiece_max, value: [0.064, 0.064, 0.064]}\n    - {name: spacing_m, value: 0.001}\n    - {name: occupancy_period_s, value: 0.001}\n    - {name: surfels_period_s, value: 0.001}\n",
    )
    .unwrap();
    let need_s = n.frame_bytes() as f64 / MAX_FRAME_BYTES_PER_S;
    assert!(need_s > 0.001 && need_s < 0.002, "{need_s}");
    let mut out = Vec::new();
    for k in 0..20 {
        n.on_message(
            &pose_at(T0 + k * 1_000_000, [0.004 + 0.0005 * k as f64, 0.03, 0.063]),
            &mut out,
        );
    }
    assert_eq!(count(&out, "/wrench"), 20);
    assert_eq!(count(&out, "/occupancy"), 10, "every other period");
    assert_eq!(n.status().problems["occupancy_throttled"], 10);
    // Logged once, counted every time.
    let texts = n
        .status()
        .messages
        .iter()
        .filter(|m| m.contains("MAX_FRAME_BYTES_PER_S"))
        .count();
    assert_eq!(texts, 1);
}

#[test]
fn a_workpiece_over_the_memory_limit_is_refused_by_name_before_allocating() {
    // 319^3 points at 1 mm: under the old 2^25, over the memory-derived limit.
    let t = std::time::Instant::now();
    let e = Workpiece::block([0.0; 3], [0.319; 3], 0.001).unwrap_err();
    let text = e.to_string();
    assert!(text.contains("319x319x319 = 32461759 points"), "{text}");
    assert!(text.contains(&MAX_POINTS.to_string()), "{text}");
    assert!(text.contains("MAX_POINTS"), "{text}");
    assert!(t.elapsed().as_millis() < 100, "refused before any work");
    // Through the node: the launch names the parameter.
    let e = try_node(
        "    - {name: workpiece_max, value: [0.638, 0.638, 0.638]}\n    - {name: spacing_m, value: 0.002}\n",
    )
    .err()
    .unwrap();
    assert!(
        e.contains("workpiece_max") && e.contains("MAX_POINTS"),
        "{e}"
    );
}

#[test]
fn a_pose_whose_sweep_is_too_much_work_is_refused_and_cuts_nothing() {
    // A 0.3 m knife (normal z) turning almost half a turn about x in one pose over a 64^3
    // grid at 0.5 mm: ~2600 rotation substeps, most sweeping the whole grid.
    let h = 0.0005;
    let mut w = Workpiece::block([0.0; 3], [0.032; 3], h).unwrap();
    let tool = Tool::knife(0.3, 0.3, 0.002, h).unwrap();
    let before = w.material_points();
    let from = ToolPose::at([0.016; 3]);
    let to = ToolPose {
        position: [0.016; 3],
        rotation: Quat::from_axis_angle([1.0, 0.0, 0.0], 3.1),
    };
    let t = std::time::Instant::now();
    let e = w.carve(&tool, &from, &to).unwrap_err();
    assert!(matches!(e, CarveError::TooMuchWork { .. }), "{e}");
    assert!(e.to_string().contains("per pose"), "{e}");
    assert!(t.elapsed().as_secs_f64() < 1.0);
    assert_eq!(w.material_points(), before);
    // Turning in small poses is fine.
    let mut prev = from;
    for k in 1..=10 {
        let next = ToolPose {
            position: [0.016; 3],
            rotation: Quat::from_axis_angle([1.0, 0.0, 0.0], 0.04 * k as f64),
        };
        w.carve(&tool, &prev, &next).unwrap();
        prev = next;
    }
    w.validate().unwrap();
}

#[test]
fn an_unstable_coupling_is_refused_at_launch_with_its_condition() {
    let e = node_err("    - {name: proxy_mass_kg, value: 0.0001}\n");
    assert!(e.contains("proxy_mass_kg"), "{e}");
    assert!(e.contains("k·h²/m + 2·b·h/m"), "{e}");
    assert!(e.contains("unstable"), "{e}");
    // The defaults pass, and so does a light proxy without damping.
    node("");
    node("    - {name: proxy_mass_kg, value: 0.0001}\n    - {name: coupling_damping_ns_per_m, value: 0.0}\n");
    // The bound: m ≥ (k h² + 2 b h)/2.
    let p = ForceParams::default();
    let h = COUPLING_STEP_S;
    let m_min = (p.coupling_stiffness * h * h + 2.0 * p.coupling_damping * h) / 2.0;
    assert!(ForceParams {
        proxy_mass: m_min * 1.01,
        ..p
    }
    .validate()
    .is_ok());
    assert!(ForceParams {
        proxy_mass: m_min * 0.99,
        ..p
    }
    .validate()
    .is_err());
}

fn node_err(extra: &str) -> String {
    try_node(&format!(
        "    - {{name: workpiece_max, value: [0.02, 0.02, 0.01]}}\n    - {{name: spacing_m, value: 0.001}}\n{extra}"
    ))
    .err()
    .expect("refused")
}

/// 1500 poses at 1 kHz of a constant 0.5 N cut; the rendered forces.
fn render(p: ForceParams) -> (Vec<[f64; 3]>, u64) {
    let mut f = ForceRenderer::new(ForceParams {
        model: ForceModel::Count,
        newtons_per_point: 0.05,
        ..p
    });
    let cut = CutStats {
        removed: 10,
        normal_sum: [1.0, 0.0, 0.0],
        ..CutStats::default()
    };
    let out = (0..1500)
        .map(|_| f.step(&cut, 1e-3, [-1e-4, 0.0, 0.0], 1e-3))
        .collect();
    (out, f.non_finite_steps())
}

#[test]
fn forces_are_never_nan_and_the_accepted_couplings_converge() {
    // Refused at launch, but a library caller may still build it: the forces are replaced,
    // clamped and counted, never NaN.
    let wild = ForceParams {
        proxy_mass: 1e-6,
        ..ForceParams::default()
    };
    assert!(wild.validate().is_err());
    let (out, bad) = render(wild);
    assert!(bad > 0, "this coupling diverges");
    for f in &out {
        assert!(f.iter().all(|v| v.is_finite()), "{f:?}");
        let m = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        assert!(m <= wild.max_force * (1.0 + 1e-12), "{m}");
    }
    // Accepted: the defaults and a proxy at the limit settle on the cut force, 0.5 N.
    let h = COUPLING_STEP_S;
    let p = ForceParams::default();
    let m_min = (p.coupling_stiffness * h * h + 2.0 * p.coupling_damping * h) / 2.0;
    for q in [
        p,
        ForceParams {
            proxy_mass: m_min,
            ..p
        },
    ] {
        q.validate().unwrap();
        let (out, bad) = render(q);
        assert_eq!(bad, 0);
        let last = out.last().unwrap();
        assert!((last[0] - 0.5).abs() < 1e-6, "{last:?} with {q:?}");
    }
    // A NaN parameter is refused by name.
    let e = ForceParams {
        max_force: f64::NAN,
        ..p
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(e.contains("max_force_n NaN"), "{e}");
}

#[test]
fn a_cutout_path_that_is_not_a_regular_file_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("outline.pgm");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    assert!(made, "mkfifo is needed for this test");
    // Loaded on another thread: a blocked open fails the test instead of hanging it.
    let (tx, rx) = std::sync::mpsc::channel();
    let p = fifo.clone();
    std::thread::spawn(move || {
        let _ = tx.send(BinaryImage::load(&p).map(|_| ()));
    });
    let r = rx
        .recv_timeout(std::time::Duration::from_secs(5))
        .expect("loading a FIFO blocked");
    let e = r.unwrap_err();
    assert!(matches!(e, ImageError::NotAFile { .. }), "{e}");
    assert!(e.to_string().contains("a FIFO"), "{e}");
    // A directory too.
    let e = BinaryImage::load(dir.path()).unwrap_err();
    assert!(e.to_string().contains("a directory"), "{e}");
    // Through the node: a counted bad image, and the node runs.
    let (tx, rx) = std::sync::mpsc::channel();
    let entry = format!(
        "    - {{name: cutouts, value: [\"z {}\"]}}\n",
        fifo.display()
    );
    std::thread::spawn(move || {
        let n = node(&entry);
        let _ = tx.send(n.status().problems.get("bad_image").copied());
    });
    let counted = rx
        .recv_timeout(std::time::Duration::from_secs(5))
        .expect("the node blocked on the FIFO");
    assert_eq!(counted, Some(1));
}
