//! Bags as `ros2 bag record` leaves them: rosbag2 directories written by PyPI `rosbags` (an
//! independent writer), MCAP and SQLite storage, split into several files, compressed per file
//! or per message, Humble's and Jazzy's metadata. Each replays to the same report as the
//! single-file bag; damaged or missing split files are reported and the rest is read; a
//! directory written by `--out DIR/` is read back by `rosbags`.

mod pyenv;

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

const SOURCE: &str = "bags/four-spheres-32-bits.mcap";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Writes SOURCE as a rosbag2 directory with `rosbags` (tests/py/write_rosbag2.py).
fn write_dir(out: &Path, args: &[&str]) {
    let o = pyenv::python()
        .arg(root().join("tests/py/write_rosbag2.py"))
        .arg(root().join(SOURCE))
        .arg(out)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("python runs ({}): {e}", pyenv::INSTALL_HINT));
    assert!(
        o.status.success(),
        "write_rosbag2.py {args:?} failed ({}):\n{}",
        pyenv::INSTALL_HINT,
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `chronotope replay BAG --report R [--out OUT]`: the report.
fn replay(bag: &Path, report: &Path, out: Option<&Path>) -> Value {
    let mut c = Command::new(env!("CARGO_BIN_EXE_chronotope"));
    c.arg("replay").arg(bag).arg("--report").arg(report);
    if let Some(o) = out {
        c.arg("--out").arg(o);
    }
    let o = c.output().unwrap();
    assert!(
        o.status.success(),
        "replay {} failed:\n{}",
        bag.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap()
}

/// A report without what legitimately differs between storages: timings, and how the bag's
/// structure was used (chunk indexes, summaries).
fn comparable(mut r: Value) -> Value {
    let o = r.as_object_mut().unwrap();
    o.remove("timings_ms");
    if let Some(rec) = o
        .get_mut("input")
        .and_then(|i| i.get_mut("recovery"))
        .and_then(Value::as_object_mut)
    {
        rec.remove("indexed_chunks");
        rec.remove("summary_used");
        rec.remove("statistics_message_count");
    }
    r
}

#[test]
fn rosbag2_directories_replay_to_the_single_file_report() {
    let d = tempfile::tempdir().unwrap();
    let reference = comparable(replay(
        &root().join(SOURCE),
        &d.path().join("ref.json"),
        None,
    ));
    let variants: [(&str, &[&str]); 6] = [
        ("mcap1", &["--storage", "mcap"]),
        (
            "mcap3_file",
            &[
                "--storage",
                "mcap",
                "--splits",
                "3",
                "--compression",
                "file",
            ],
        ),
        (
            "mcap2_msg",
            &[
                "--storage",
                "mcap",
                "--splits",
                "2",
                "--compression",
                "message",
            ],
        ),
        ("db2", &["--storage", "sqlite3", "--splits", "2"]),
        (
            "db3_msg_v8",
            &[
                "--storage",
                "sqlite3",
                "--splits",
                "3",
                "--compression",
                "message",
                "--version",
                "8",
            ],
        ),
        (
            "db2_humble",
            &["--storage", "sqlite3", "--splits", "2", "--humble"],
        ),
    ];
    for (name, args) in variants {
        let dir = d.path().join(name);
        write_dir(&dir, args);
        let r = comparable(replay(&dir, &d.path().join(format!("{name}.json")), None));
        assert_eq!(
            r, reference,
            "{name}: report differs from the single-file bag's"
        );
    }
    // The split file given alone (an MCAP file) and the metadata.yaml path both work too.
    let alone = d.path().join("db2").join("db2_0.db3");
    let r = replay(&alone, &d.path().join("alone.json"), None);
    assert_eq!(r["input"]["messages"], 34, "{}", r["input"]);
    let r = comparable(replay(
        &d.path().join("mcap1").join("metadata.yaml"),
        &d.path().join("meta.json"),
        None,
    ));
    assert_eq!(r, reference);
    // A directory whose metadata.yaml is lost (recording cut) is read from its files.
    std::fs::remove_file(d.path().join("db2").join("metadata.yaml")).unwrap();
    let r = comparable(replay(
        &d.path().join("db2"),
        &d.path().join("nometa.json"),
        None,
    ));
    assert_eq!(r, reference, "without metadata.yaml");
}

#[test]
fn damaged_and_missing_split_files_are_reported_and_the_rest_is_read() {
    let d = tempfile::tempdir().unwrap();
    // Three MCAP split files of 23, 23 and 22 messages; the middle one is cut in half.
    let m = d.path().join("cut");
    write_dir(&m, &["--storage", "mcap", "--splits", "3"]);
    let middle = m.join("cut_1.mcap");
    let bytes = std::fs::read(&middle).unwrap();
    std::fs::write(&middle, &bytes[..bytes.len() / 2]).unwrap();
    let r = replay(&m, &d.path().join("cut.json"), None);
    let input = &r["input"];
    let read = input["messages"].as_u64().unwrap();
    assert!(read > 45 && read < 68, "{input}");
    let errors = input["bag_errors"].to_string();
    assert!(errors.contains("cut_1.mcap"), "{errors}");
    assert!(errors.contains("reading the next split file"), "{errors}");
    // Pairs are still checked over the frames read.
    assert_eq!(r["pairs"].as_array().unwrap().len(), 6, "{r}");

    // SQLite: the middle file is missing, the last one is not a database at all.
    let s = d.path().join("gone");
    write_dir(&s, &["--storage", "sqlite3", "--splits", "3"]);
    std::fs::remove_file(s.join("gone_1.db3")).unwrap();
    std::fs::write(s.join("gone_2.db3"), b"SQLite format 3\0 and then garbage").unwrap();
    let r = replay(&s, &d.path().join("gone.json"), None);
    let input = &r["input"];
    assert_eq!(input["messages"], 23, "{input}");
    let errors = input["bag_errors"].to_string();
    assert!(
        errors.contains("gone_1.db3") && errors.contains("does not exist"),
        "{errors}"
    );
    assert!(errors.contains("gone_2.db3"), "{errors}");
    let losses = input["recovery"]["losses"].to_string();
    assert!(losses.contains("split_file"), "{losses}");

    // An unusable metadata.yaml is refused by name.
    let bad = d.path().join("bad");
    std::fs::create_dir(&bad).unwrap();
    std::fs::write(bad.join("metadata.yaml"), "rosbag2_bagfile_information: [").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .arg("replay")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("metadata.yaml") && err.contains("not valid YAML"),
        "{err}"
    );
}

#[test]
fn output_directories_are_read_by_rosbags_and_info() {
    let d = tempfile::tempdir().unwrap();
    let single = d.path().join("out.mcap");
    let dir = d.path().join("outdir/");
    replay(
        &root().join(SOURCE),
        &d.path().join("a.json"),
        Some(&single),
    );
    replay(&root().join(SOURCE), &d.path().join("b.json"), Some(&dir));
    assert!(dir.join("metadata.yaml").is_file());
    // rosbags' rosbag2 reader: the metadata's counts, and every message read.
    let script = r#"
import json, sys
from rosbags.rosbag2 import Reader
with Reader(sys.argv[1]) as r:
    counts = {c.topic: c.msgcount for c in r.connections}
    read = {}
    for c, t, data in r.messages():
        read[c.topic] = read.get(c.topic, 0) + 1
    print(json.dumps({"metadata": counts, "read": read, "total": r.message_count,
                      "types": {c.topic: c.msgtype for c in r.connections}}))
"#;
    let o = pyenv::python()
        .arg("-c")
        .arg(script)
        .arg(&dir)
        .output()
        .unwrap_or_else(|e| panic!("python runs ({}): {e}", pyenv::INSTALL_HINT));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(got["metadata"], got["read"], "{got}");
    // The same topics and counts as the single-file output.
    let info = |p: &Path| -> Value {
        let o = Command::new(env!("CARGO_BIN_EXE_chronotope"))
            .arg("info")
            .arg(p)
            .arg("--json")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let a = info(&single);
    let b = info(&dir);
    assert_eq!(b["kind"], "rosbag2 directory");
    assert_eq!(b["metadata_version"], 9);
    assert_eq!(a["messages"], b["messages"]);
    assert_eq!(b["messages"], got["total"]);
    let counts = |v: &Value| -> Vec<(String, u64)> {
        v["topics"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                (
                    t["topic"].as_str().unwrap().to_owned(),
                    t["messages"].as_u64().unwrap(),
                )
            })
            .collect()
    };
    assert_eq!(counts(&a), counts(&b));
    for (topic, n) in counts(&b) {
        assert_eq!(got["read"][&topic], n, "{topic}");
    }
}

#[test]
fn info_names_the_bodies_and_their_timing() {
    let o = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .arg("info")
        .arg(root().join(SOURCE))
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let i: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(i["kind"], "mcap");
    assert_eq!(i["messages"], 68);
    let bodies = i["bodies"].as_array().unwrap();
    assert_eq!(bodies.len(), 4);
    for b in bodies {
        assert_eq!(b["frames"], 17);
        assert_eq!(b["sizes"], serde_json::json!([[32, 32, 32]]));
        assert_eq!(b["encodings"]["bits"], 17);
        assert_eq!(b["gaps"], 0);
        let p = b["period_s"].as_f64().unwrap();
        assert!((p - 0.0625).abs() < 1e-9, "{p}");
    }
    assert!((i["duration_s"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    // The text form says the same.
    let o = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .arg("info")
        .arg(root().join(SOURCE))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("Bodies (VoxelGrid topics the suite reads): 4"),
        "{text}"
    );
    assert!(text.contains("16.00 Hz"), "{text}");
}
