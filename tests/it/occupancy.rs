//! The occupancy node against producers nobody here wrote: OctoMap streams written by the
//! OctoMap library itself (PyPI `pyoctomap`) and point clouds serialised by PyPI `rosbags`,
//! in rosbag2 bags `rosbags` writes (MCAP and SQLite), replayed by `chronotope replay` and
//! compared voxel for voxel with the producers' own answers (`tests/py/occupancy_bags.py`
//! says how); and the bundled person-cell bag, replayed without a launch config, checks the
//! sensed person against the cell.
//!
//! Needs the Python environment of `python3 tests/py/setup_env.py`; without `pyoctomap` the
//! interop test is skipped with a message, unless `CI` is set: then it fails.

use crate::pyenv;

use std::path::Path;
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn run_interop(storage: &str) {
    let out = pyenv::python()
        .arg(root().join("tests/py/occupancy_bags.py"))
        .arg(env!("CARGO_BIN_EXE_chronotope"))
        .args(["--storage", storage])
        .output()
        .unwrap_or_else(|e| panic!("python runs ({}): {e}", pyenv::INSTALL_HINT));
    let stdout = String::from_utf8_lossy(&out.stdout);
    if out.status.code() == Some(3) {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set and pyoctomap is missing: {}",
            pyenv::INSTALL_HINT
        );
        eprintln!("SKIPPED: {stdout}");
        return;
    }
    assert!(
        out.status.success(),
        "occupancy frames differ from the producers' ({storage}):\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{stdout}");
}

#[test]
fn pyoctomap_trees_and_rosbags_clouds_in_an_mcap_bag_become_the_producers_voxels() {
    run_interop("mcap");
}

#[test]
fn pyoctomap_trees_and_rosbags_clouds_in_a_sqlite_bag_become_the_producers_voxels() {
    run_interop("sqlite3");
}

/// Without a launch config, a replay gives each OctoMap and point-cloud topic a node of its
/// own on the lattice and frame times of the bag's first body, and the checker sees them.
#[test]
fn the_person_cell_bag_replays_without_a_config_with_its_sensors_as_bodies() {
    let d = tempfile::tempdir().unwrap();
    let report = d.path().join("r.json");
    let out = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .arg("replay")
        .arg(root().join("bags/person-cell-32.mcap"))
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let bodies: Vec<&str> = r["bodies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["id"].as_str().unwrap())
        .collect();
    for b in [
        "/occupancy/camera_points/occupancy",
        "/occupancy/octomap_binary/occupancy",
        "/spindle/occupancy",
    ] {
        assert!(bodies.contains(&b), "{b} in {bodies:?}");
    }
    // The spindle, not a sensed body, is the default movable one.
    let moved: Vec<&str> = r["resolutions"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|x| x["body"].as_str())
        .collect();
    assert!(
        moved.iter().all(|b| !b.starts_with("/occupancy/")),
        "{moved:?}"
    );
    let node = &r["nodes"]["/occupancy/camera_points"];
    assert_eq!(node["problems"], serde_json::json!({}), "{node}");
    assert!(node["counts"]["points_nonfinite"].as_u64().unwrap() > 0);
    // The person reaches into the spindle's path: seen by the camera and in the map.
    let collide = |a: &str| {
        r["pairs"].as_array().unwrap().iter().any(|p| {
            (p["a"] == a || p["b"] == a)
                && (p["a"] == "/spindle/occupancy" || p["b"] == "/spindle/occupancy")
                && p["interfering"] == true
        })
    };
    assert!(collide("/occupancy/camera_points/occupancy"));
    assert!(collide("/occupancy/octomap_binary/occupancy"));
}
