//! A plan checked before it runs: the robot cell's dip sent as a JointTrajectory
//! (`chronotope scene robot-cell --plan`) is replayed with `launch_configs/robot_cell_plan.yaml`;
//! the checker finds the contact with the table and a verified time scaling; the robot node
//! publishes the plan retimed; and the retimed plan, put in the bag in place of the original
//! and replayed again, is clear of the table over its whole time.

use std::path::{Path, PathBuf};
use std::process::Command;

use chronotope::bag::{BagReader, BagWriteOptions, BagWriter};
use chronotope::msg::{decode_cdr, JointTrajectory};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn chronotope(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "chronotope {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn replay(bag: &Path, dir: &Path, tag: &str) -> (serde_json::Value, PathBuf) {
    let report = dir.join(format!("{tag}.json"));
    let out = dir.join(format!("{tag}-out.mcap"));
    let config = root().join("launch_configs/robot_cell_plan.yaml");
    chronotope(&[
        "replay",
        bag.to_str().unwrap(),
        "--launch",
        config.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let r = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    (r, out)
}

/// The messages of `topic` in a bag, decoded.
fn messages_of(bag: &Path, topic: &str) -> Vec<(u64, JointTrajectory)> {
    BagReader::open(bag)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.topic == topic)
        .map(|m| (m.log_time_ns, decode_cdr(&m.data).unwrap()))
        .collect()
}

#[test]
fn a_plan_into_the_table_is_caught_before_it_runs_and_its_retimed_plan_is_clear() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("plan.mcap");
    chronotope(&[
        "scene",
        "robot-cell",
        "--plan",
        "--out",
        bag.to_str().unwrap(),
    ]);
    let (report, out) = replay(&bag, dir.path(), "plan");
    let pair = &report["pairs"][0];
    assert_eq!(pair["verdict"], "collide", "{pair}");
    let scaling = report["resolutions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["kind"] == "time_scale")
        .unwrap_or_else(|| panic!("no time scaling in {}", report["resolutions"]))
        .clone();
    assert_eq!(scaling["verified_clear"], true, "{scaling}");
    let robot = &report["nodes"]["/robot"];
    assert_eq!(robot["problems"], serde_json::json!({}), "{robot}");

    // The retimed plan: the original under t' = t0 + s (t - t0).
    let retimed = messages_of(&out, "/robot/retimed_trajectory");
    assert_eq!(retimed.len(), 1, "one retimed plan");
    let (_, retimed) = &retimed[0];
    let (sent, original) = messages_of(&bag, "/arm_controller/joint_trajectory")
        .pop()
        .unwrap();
    let origin = report["time_origin_ns"].as_i64().unwrap();
    let t0 = origin + (scaling["t0_s"].as_f64().unwrap() * 1e9).round() as i64;
    let s = scaling["scale"].as_f64().unwrap();
    let start = original.header.stamp.as_nanos();
    let mapped = t0 + ((start - t0) as f64 * s).round() as i64;
    assert!((retimed.header.stamp.as_nanos() - mapped).abs() <= 1);
    assert!(
        retimed.header.stamp.as_nanos() >= sent as i64,
        "the retimed plan starts after the original was sent, so it can be sent as it is"
    );
    assert_eq!(retimed.joint_names, original.joint_names);
    for (a, b) in original.points.iter().zip(&retimed.points) {
        assert_eq!(a.positions, b.positions);
        let (ta, tb) = (
            a.time_from_start.as_nanos() as f64,
            b.time_from_start.as_nanos() as f64,
        );
        assert!((tb - ta * s).abs() <= 1.0, "{ta} {tb} {s}");
        for (va, vb) in a.velocities.iter().zip(&b.velocities) {
            assert!((vb - va / s).abs() <= 1e-12 * va.abs().max(1.0));
        }
    }

    // The same cell with the retimed plan sent instead: clear.
    let again = dir.path().join("retimed.mcap");
    let mut w = BagWriter::create_with(&again, BagWriteOptions::new()).unwrap();
    let mut added = std::collections::BTreeSet::new();
    for m in BagReader::open(&bag).unwrap().map(Result::unwrap) {
        if added.insert(m.topic.clone()) {
            let (ty, schema) = chronotope::node::Payload::schema_of(&m.schema_name).unwrap();
            w.add_topic_with_schema(&m.topic, ty, &schema).unwrap();
        }
        if m.topic == "/arm_controller/joint_trajectory" {
            w.write(&m.topic, m.log_time_ns, retimed).unwrap();
        } else {
            w.write_cdr(&m.topic, m.log_time_ns, &m.data).unwrap();
        }
    }
    w.finish().unwrap();
    let (report, _) = replay(&again, dir.path(), "retimed");
    let pair = &report["pairs"][0];
    // No contact; where the arm sweeps more than two voxels a frame past the table the pair
    // is unsure rather than clear (what it passes between frames is not seen).
    assert_eq!(pair["interfering"], false, "{pair}");
    assert_ne!(pair["verdict"], "collide", "{pair}");
    for u in pair["unsure_spans_s"].as_array().unwrap() {
        assert_eq!(u["code"], "moves_fast", "{pair}");
    }
}

/// `info` lists the bundled cell's robot as a body source, and `replay` without a launch
/// config runs a robot node on the table's lattice and checks the two.
#[test]
fn info_lists_the_robot_and_replay_without_a_config_checks_it() {
    let bag = root().join("bags/robot-cell-32.mcap");
    let text = chronotope(&["info", bag.to_str().unwrap()]);
    assert!(
        text.contains("robot: arm6 (/robot_description), 10 links, 7 joints")
            && text.contains("joint states at 200.0 Hz on /joint_states")
            && text.contains("2.0 messages per instant")
            && text.contains("exec: robot"),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&chronotope(&["info", bag.to_str().unwrap(), "--json"])).unwrap();
    assert_eq!(json["robots"][0]["name"], "arm6");
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let out = chronotope(&[
        "replay",
        bag.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(out.contains("2 bodies, 1 pairs checked"), "{out}");
    assert!(
        out.contains("COLLIDE  /robot/occupancy x /table/occupancy"),
        "{out}"
    );
}

/// The robot sweeping into the table: the checker's first contact and the end of the contact
/// interval lie within the report's stated bounds of the exact times (from the continuous
/// geometry, independent of the rasteriser, mesher and checker), in both encodings.
#[test]
fn first_contact_and_interval_are_within_the_reported_bounds_of_the_exact_times() {
    use chronotope::bench::robot::{accuracy_row, exact_contacts};
    use chronotope::msg::VoxelEncoding;
    let exact = exact_contacts(&[]);
    assert_eq!(exact.len(), 1, "{exact:?}");
    let [e0, e1] = exact[0];
    assert!(e0 > 1.0 && e1 < 3.0, "{exact:?}");
    let dir = tempfile::tempdir().unwrap();
    for encoding in [VoxelEncoding::Bits, VoxelEncoding::Percent] {
        let row = accuracy_row(32, encoding, dir.path()).unwrap();
        let (first, bound) = row.first_contact.expect("a contact");
        assert!(
            (first - e0).abs() <= bound,
            "{encoding:?}: first contact {first} ± {bound}, exact {e0}"
        );
        let (interval, bounds) = row.interval.expect("an interval");
        assert!(
            (interval[1] - e1).abs() <= bounds[1],
            "{encoding:?}: end {} ± {}, exact {e1}",
            interval[1],
            bounds[1]
        );
    }
}
