//! The carving node: one wrench per accepted pose, published before the workpiece frames;
//! bad input refused and counted with the workpiece unchanged; cut-outs and the tool schedule.

use chronotope::msg::{Header, Point, Pose, PoseStamped, Quaternion, Time};
use chronotope::node::carving::CarvingNode;
use chronotope::node::launch::LaunchConfig;
use chronotope::node::{Message, Node, Payload};
use std::sync::Arc;

const T0: i64 = 1_000_000_000;

fn node(extra: &str) -> CarvingNode {
    let cfg = format!(
        "launch:\n- node:\n    pkg: chronotope\n    exec: carving\n    param:\n    - {{name: pose_topic, value: /haptic/pose}}\n    - {{name: workpiece_max, value: [0.02, 0.02, 0.01]}}\n    - {{name: spacing_m, value: 0.001}}\n    - {{name: occupancy_period_s, value: 0.01}}\n{extra}"
    );
    let c = LaunchConfig::parse(&cfg, "test").unwrap();
    CarvingNode::from_spec(&c.nodes[0]).unwrap()
}

fn pose_msg(t_ms: i64, p: [f64; 3], q: [f64; 4], frame: &str) -> Message {
    let stamp = T0 + t_ms * 1_000_000;
    Message::new(
        "/haptic/pose",
        stamp,
        Payload::PoseStamped(Arc::new(PoseStamped {
            header: Header {
                stamp: Time::from_nanos(stamp),
                frame_id: frame.into(),
            },
            pose: Pose {
                position: Point {
                    x: p[0],
                    y: p[1],
                    z: p[2],
                },
                orientation: Quaternion {
                    x: q[0],
                    y: q[1],
                    z: q[2],
                    w: q[3],
                },
            },
        })),
    )
}

const ID: [f64; 4] = [0.0, 0.0, 0.0, 1.0];

/// The knife (normal z) dragged along x, 2 mm into the top: 20 poses at 1 kHz.
fn stroke(n: &mut CarvingNode) -> Vec<Message> {
    let mut out = Vec::new();
    for k in 0..20 {
        n.on_message(
            &pose_msg(k, [0.004 + 0.0005 * k as f64, 0.01, 0.009], ID, "world"),
            &mut out,
        );
    }
    out
}

#[test]
fn every_pose_gets_a_wrench_before_any_frame_and_frames_follow_the_period() {
    let mut n = node("");
    let out = stroke(&mut n);
    let wrenches: Vec<&Message> = out
        .iter()
        .filter(|m| m.topic.ends_with("/wrench"))
        .collect();
    assert_eq!(wrenches.len(), 20);
    let frames = out
        .iter()
        .filter(|m| m.topic.ends_with("/occupancy"))
        .count();
    assert_eq!(
        frames, 2,
        "poses over 19 ms, a frame every 10 ms: at 0 and 10 ms"
    );
    // In each pose's output the wrench comes first.
    let first = out
        .iter()
        .position(|m| m.topic.ends_with("/wrench"))
        .unwrap();
    assert_eq!(first, 0);
    assert!(n.workpiece().material_points() < 20 * 20 * 10);
    assert!(n.status().problems.is_empty(), "{:?}", n.status().problems);
    // The force part publishes no cloud: the display does.
    assert!(!out.iter().any(|m| matches!(m.payload, Payload::PointCloud2(_))));
    // Cutting resists the motion along x.
    let f = n.last_force();
    assert!(f[0] < 0.0, "{f:?}");
}

#[test]
fn bad_poses_are_refused_counted_and_leave_the_workpiece_unchanged() {
    let mut n = node("");
    let mut out = Vec::new();
    stroke(&mut n);
    let before = n.workpiece().material_points();
    let surfels = n.workpiece().surfels().len();
    let deep = [0.01, 0.01, 0.005];
    for (m, kind) in [
        (
            pose_msg(30, [f64::NAN, 0.01, 0.005], ID, "world"),
            "bad_pose",
        ),
        (
            pose_msg(31, [0.01, f64::INFINITY, 0.005], ID, "world"),
            "bad_pose",
        ),
        (
            pose_msg(32, deep, [0.0, 0.0, 0.0, 0.0], "world"),
            "bad_pose",
        ),
        (
            pose_msg(33, deep, [f64::NAN, 0.0, 0.0, 1.0], "world"),
            "bad_pose",
        ),
        (pose_msg(5, deep, ID, "world"), "stamp_backwards"),
        (pose_msg(34, deep, ID, "tool0"), "unknown_frame"),
    ] {
        out.clear();
        n.on_message(&m, &mut out);
        assert!(out.is_empty(), "{kind}: published {}", out.len());
        assert!(n.status().problems.contains_key(kind), "{kind} not counted");
        assert_eq!(n.workpiece().material_points(), before, "{kind} cut");
        assert_eq!(n.workpiece().surfels().len(), surfels);
    }
    assert_eq!(n.status().problems["bad_pose"], 4);
    // A non-unit quaternion is normalised (and counted), and the node keeps cutting.
    out.clear();
    n.on_message(&pose_msg(40, deep, [0.0, 0.0, 0.0, 2.0], "world"), &mut out);
    assert_eq!(n.status().problems["non_unit_quaternion"], 1);
    assert!(n.workpiece().material_points() < before);
    n.workpiece().validate().unwrap();
}

#[test]
fn bad_images_and_unknown_tools_are_counted_at_start_and_the_node_runs() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("disc.pgm");
    let mut img = String::from("P2 8 8 1\n");
    for r in 0..8 {
        for c in 0..8 {
            let (x, y) = (c as f64 - 3.5, r as f64 - 3.5);
            img.push_str(if x * x + y * y < 9.0 { "0 " } else { "1 " });
        }
    }
    std::fs::write(&good, img).unwrap();
    let extra = format!(
        "    - {{name: cutouts, value: [\"z {}\", \"y /nonexistent.png\", \"w {}\"]}}\n    - {{name: tool_schedule, value: [\"0.005 chisel\", \"0.01 gouge\"]}}\n",
        good.display(),
        good.display()
    );
    let mut n = node(&extra);
    assert_eq!(n.status().problems["bad_image"], 2);
    assert_eq!(n.status().problems["unknown_tool"], 1);
    let cut = n.workpiece().material_points();
    assert!(cut < 20 * 20 * 10, "the good cut-out applied");
    n.workpiece().validate().unwrap();
    let out = stroke(&mut n);
    assert_eq!(
        out.iter().filter(|m| m.topic.ends_with("/wrench")).count(),
        20
    );
    assert!(n.workpiece().material_points() < cut);
}

#[test]
fn launch_parameters_are_checked() {
    let bad = |extra: &str, what: &str| {
        let cfg = format!(
            "launch:\n- node:\n    pkg: chronotope\n    exec: carving\n    param:\n    - {{name: pose_topic, value: /p}}\n{extra}"
        );
        let c = LaunchConfig::parse(&cfg, "test").unwrap();
        let e = CarvingNode::from_spec(&c.nodes[0])
            .err()
            .expect(what)
            .to_string();
        assert!(e.contains(what), "{e}");
    };
    bad("    - {name: tool, value: gouge}\n", "gouge");
    bad("    - {name: spacing_m, value: 0.0}\n", "spacing_m");
    bad("    - {name: spacing_m, value: 0.00002}\n", "workpiece");
    bad("    - {name: force_model, value: springy}\n", "springy");
    bad(
        "    - {name: knife_length_m, value: -1.0}\n",
        "knife_length_m",
    );
    bad(
        "    - {name: tool_radius_m, value: 0.004}\n",
        "tool_radius_m",
    );
}

#[test]
fn a_thin_blade_is_reported() {
    let n = node("    - {name: knife_thickness_m, value: 0.0002}\n");
    assert_eq!(n.status().problems["thin_blade"], 1);
}

/// Every PointCloud2 the display publishes, by topic suffix.
fn clouds<'a>(out: &'a [Message], suffix: &str) -> Vec<&'a chronotope::msg::PointCloud2> {
    out.iter()
        .filter(|m| m.topic.ends_with(suffix))
        .filter_map(|m| match &m.payload {
            Payload::PointCloud2(c) => Some(c.as_ref()),
            _ => None,
        })
        .collect()
}

/// A zigzag of knife moves through the block, going deeper: `n` poses at 1 kHz from `t0` ms.
fn zigzag(t0: i64, n: i64) -> Vec<Message> {
    (0..n)
        .map(|k| {
            let t = (t0 + k) as f64 * 1e-3;
            let x = 0.002 + 0.016 * (0.5 + 0.5 * (t * 40.0).sin());
            let y = 0.004 + 0.012 * (0.5 + 0.5 * (t * 13.0).cos());
            let z = 0.0095 - 0.004 * (t / 0.3).min(1.0);
            pose_msg(t0 + k, [x, y, z], ID, "world")
        })
        .collect()
}

#[test]
fn the_display_copy_of_the_surfels_follows_the_workpiece_exactly_even_when_frames_are_missed() {
    for missed_every in [0usize, 2, 3] {
        let mut n = node("");
        let mut d = n.display().unwrap();
        let mut frames = 0usize;
        let mut shown = Vec::new();
        for m in zigzag(0, 300) {
            let mut out = Vec::new();
            n.on_message(&m, &mut out);
            for f in out.iter().filter(|m| m.topic.ends_with("/_frame")) {
                frames += 1;
                // Frames the display's queue dropped: it never sees them.
                if missed_every > 0 && frames % missed_every == 0 {
                    continue;
                }
                d.on_message(f, &mut shown);
            }
        }
        let mut out = Vec::new();
        n.finish(&mut out);
        for f in &out {
            d.on_message(f, &mut shown);
        }
        d.finish(&mut shown);
        assert!(frames > 20, "{frames} frames");
        let full = clouds(&shown, "/surfels");
        let last = full.last().expect("a whole cloud at the end");
        assert_eq!(last.data, n.workpiece().surfel_bytes(), "missed every {missed_every}");
        assert_eq!(last.width as usize, n.workpiece().surfels().len());
        // The occupancy frames come from the display too, built from its own copy.
        let grids: Vec<_> = shown
            .iter()
            .filter(|m| m.topic.ends_with("/occupancy"))
            .filter_map(|m| match &m.payload {
                Payload::VoxelGrid(g) => Some(g.clone()),
                _ => None,
            })
            .collect();
        assert!(!grids.is_empty());
        assert_eq!(
            grids.last().unwrap().data,
            n.workpiece().occupancy_bits(),
            "missed every {missed_every}"
        );
        assert!(!out.iter().any(|m| matches!(m.payload, Payload::VoxelGrid(_))));
        let changed = clouds(&shown, "/surfels_changed");
        assert!(!changed.is_empty());
        for c in &changed {
            assert_eq!(c.data.len(), c.width as usize * 32);
            assert_eq!(c.point_step, 32);
        }
        // Changed clouds are far smaller than the whole one.
        let mean = changed.iter().map(|c| c.data.len()).sum::<usize>() / changed.len();
        assert!(mean < last.data.len(), "{mean} vs {}", last.data.len());
        if missed_every > 0 {
            assert!(n.status().problems.get("display_behind").is_some_and(|&c| c > 0));
        }
    }
}
