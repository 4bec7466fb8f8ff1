//! Bags as `ros2 bag record` leaves them: rosbag2 directories written by PyPI `rosbags` (an
//! independent writer), MCAP and SQLite storage, split into several files, compressed per file
//! or per message, Humble's and Jazzy's metadata. Each replays to the same report as the
//! single-file bag; damaged or missing split files are reported and the rest is read; a
//! directory written by `--out DIR/` is read back by `rosbags`.

use crate::pyenv;

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
        // SQLite keeps no checksums and rosbags writes MCAP chunks with CRC 0: said, not equal.
        rec.remove("integrity");
        rec.remove("unverified");
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

/// `chronotope ARGS`: (success, stdout + stderr).
fn run(args: &[&std::ffi::OsStr], env: &[(&str, &Path)]) -> (bool, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_chronotope"));
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    let o = c.output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.success(), text)
}

fn os(s: &str) -> &std::ffi::OsStr {
    std::ffi::OsStr::new(s)
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn metadata_that_disagrees_with_the_files_is_said_by_check_and_replay() {
    let d = tempfile::tempdir().unwrap();
    // Two split files; the metadata lists only the first but counts every message.
    let m = d.path().join("half");
    write_dir(&m, &["--storage", "mcap", "--splits", "2"]);
    let edit = "import sys; from ruamel.yaml import YAML; y = YAML(); p = sys.argv[1]; \
                d = y.load(open(p)); i = d['rosbag2_bagfile_information']; \
                i['relative_file_paths'] = i['relative_file_paths'][:1]; \
                i['files'] = i['files'][:1]; y.dump(d, open(p, 'w'))";
    let o = pyenv::python()
        .args(["-c", edit])
        .arg(m.join("metadata.yaml"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = d.path().join("r.json");
    let (ok, text) = run(
        &[
            os("replay"),
            m.as_os_str(),
            os("--report"),
            report.as_os_str(),
        ],
        &[],
    );
    assert!(ok, "{text}");
    assert!(
        text.contains("disagrees") && text.contains("half_1.mcap"),
        "{text}"
    );
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let losses = r["input"]["recovery"]["losses"].to_string();
    assert!(losses.contains("metadata_mismatch"), "{losses}");
    assert!(
        r["input"]["recovery"]["messages_lost"].as_u64() > Some(0),
        "{r}"
    );
    let (ok, text) = run(&[os("check"), m.as_os_str()], &[]);
    assert!(ok && text.contains("disagrees"), "{text}");
}

#[test]
fn formats_without_checksums_are_reported_unverified() {
    let d = tempfile::tempdir().unwrap();
    let integrity = |bag: &Path| -> Value {
        let report = d.path().join("i.json");
        replay(bag, &report, None)["input"]["recovery"].clone()
    };
    let ours = integrity(&root().join(SOURCE));
    assert_eq!(ours["integrity"], "verified", "{ours}");
    let s = d.path().join("sq");
    write_dir(&s, &["--storage", "sqlite3"]);
    let sq = integrity(&s);
    assert_eq!(sq["integrity"], "unverified", "{sq}");
    assert!(sq["unverified"].to_string().contains("SQLite"), "{sq}");
    let (_, text) = run(&[os("replay"), s.as_os_str()], &[]);
    assert!(text.contains("could not be verified"), "{text}");
    // rosbags writes MCAP chunks with CRC 0.
    let m = d.path().join("mc");
    write_dir(&m, &["--storage", "mcap"]);
    let mc = integrity(&m);
    assert_eq!(mc["integrity"], "unverified", "{mc}");
    assert!(mc["unverified"].to_string().contains("CRC 0"), "{mc}");
}

#[test]
fn sqlite_bags_are_read_without_creating_anything_beside_them() {
    let d = tempfile::tempdir().unwrap();
    let s = d.path().join("wal");
    write_dir(&s, &["--storage", "sqlite3"]);
    let db = s.join("wal_0.db3");
    // What rosbag2's resilient preset leaves: a database in WAL mode, closed properly.
    let o = pyenv::python()
        .args(["-c", "import sqlite3,sys; c=sqlite3.connect(sys.argv[1]); c.execute('pragma journal_mode=wal'); c.close()"])
        .arg(&db)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let before = names(&s);
    let r = replay(&s, &d.path().join("w.json"), None);
    assert_eq!(r["input"]["messages"], 68, "{}", r["input"]);
    assert_eq!(names(&s), before, "files were created beside the database");
    // A write-ahead log left by a writer that did not close: not read, and said.
    std::fs::write(s.join("wal_0.db3-wal"), vec![0u8; 4096]).unwrap();
    let before = names(&s);
    let (ok, text) = run(&[os("replay"), s.as_os_str()], &[]);
    assert!(ok, "{text}");
    assert!(
        text.contains("wal_0.db3-wal") && text.contains("not read"),
        "{text}"
    );
    assert_eq!(names(&s), before);
}

#[test]
fn special_files_and_links_out_of_the_bag_are_refused_by_name() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("pipe.mcap");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    // Refused at once (a FIFO's open would wait for a writer forever).
    let (ok, text) = run(&[os("info"), fifo.as_os_str()], &[]);
    assert!(!ok && text.contains("FIFO"), "{text}");
    // A FIFO listed as a split file, and a split file that is a link out of the directory.
    let m = d.path().join("links");
    write_dir(&m, &["--storage", "mcap", "--splits", "3"]);
    let outside = d.path().join("elsewhere.mcap");
    std::fs::rename(m.join("links_2.mcap"), &outside).unwrap();
    std::os::unix::fs::symlink(&outside, m.join("links_2.mcap")).unwrap();
    std::fs::remove_file(m.join("links_1.mcap")).unwrap();
    assert!(Command::new("mkfifo")
        .arg(m.join("links_1.mcap"))
        .status()
        .unwrap()
        .success());
    let report = d.path().join("l.json");
    let r = replay(&m, &report, None);
    let errors = r["input"]["bag_errors"].to_string();
    assert!(
        errors.contains("links_1.mcap") && errors.contains("FIFO"),
        "{errors}"
    );
    assert!(
        errors.contains("links_2.mcap") && errors.contains("outside the bag"),
        "{errors}"
    );
    assert_eq!(r["input"]["messages"], 23, "{}", r["input"]);
    // A metadata.yaml that is a link to a file outside the bag is not parsed.
    let e = d.path().join("etc");
    std::fs::create_dir(&e).unwrap();
    std::os::unix::fs::symlink("/etc/passwd", e.join("metadata.yaml")).unwrap();
    let (ok, text) = run(&[os("info"), e.as_os_str()], &[]);
    assert!(!ok && text.contains("outside the bag directory"), "{text}");
}

/// A zstd frame header declaring `size` bytes, then a block of zeros (enough for a reader
/// that looks at the header; decompression would fail later).
fn zstd_header_declaring(size: u64) -> Vec<u8> {
    let mut v = vec![0x28, 0xB5, 0x2F, 0xFD, 0xE0];
    v.extend_from_slice(&size.to_le_bytes());
    v.extend_from_slice(&[0u8; 64]);
    v
}

#[test]
fn compressed_bombs_are_refused_and_leave_nothing_in_tmpdir() {
    let d = tempfile::tempdir().unwrap();
    let tmp = d.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    // Declares 70 GiB: refused before anything is written.
    let declared = d.path().join("declared.mcap.zstd");
    std::fs::write(&declared, zstd_header_declaring(70 << 30)).unwrap();
    let (ok, text) = run(&[os("check"), declared.as_os_str()], &[("TMPDIR", &tmp)]);
    assert!(
        !ok && text.contains("declares") && text.contains("refused before writing"),
        "{text}"
    );
    assert!(names(&tmp).is_empty());
    // Declares nothing and decompresses past a 1 MiB cap: refused at the cap.
    let mut bomb = b"\x89MCAP0\r\n".to_vec();
    bomb.resize(8 << 20, 0);
    let undeclared = d.path().join("undeclared.mcap.zstd");
    let mut enc = zstd::stream::Encoder::new(Vec::new(), 1).unwrap();
    enc.include_contentsize(false).unwrap();
    std::io::Write::write_all(&mut enc, &bomb).unwrap();
    std::fs::write(&undeclared, enc.finish().unwrap()).unwrap();
    let cap = Path::new("0.001");
    let (ok, text) = run(
        &[os("info"), undeclared.as_os_str()],
        &[("TMPDIR", &tmp), ("CHRONOTOPE_MAX_DECOMPRESSED_GB", cap)],
    );
    assert!(!ok && text.contains("decompresses to more than"), "{text}");
    assert!(names(&tmp).is_empty());
}

#[test]
fn metadata_of_the_wrong_shape_is_refused_by_field() {
    let d = tempfile::tempdir().unwrap();
    let m = d.path().join("v");
    write_dir(&m, &["--storage", "mcap"]);
    let meta = std::fs::read_to_string(m.join("metadata.yaml")).unwrap();
    let with_version = |v: &str| {
        let text: String = meta
            .lines()
            .map(|l| {
                if l.trim_start().starts_with("version:") {
                    format!("  version: {v}\n")
                } else {
                    format!("{l}\n")
                }
            })
            .collect();
        std::fs::write(m.join("metadata.yaml"), text).unwrap();
        run(&[os("info"), m.as_os_str()], &[]).1
    };
    for (v, says) in [
        ("'9'", "the string \"9\""),
        ("-1", "negative"),
        ("18446744073709551616", "beyond 64 bits"),
        ("[9]", "is a list"),
    ] {
        let text = with_version(v);
        assert!(
            text.contains("version") && text.contains(says),
            "{v}: {text}"
        );
    }
    // Nesting deeper than the metadata limits: refused by the limit's name, at once.
    let deep = format!(
        "rosbag2_bagfile_information:\n  version: 9\n  x: {}{}\n",
        "[".repeat(5000),
        "]".repeat(5000)
    );
    std::fs::write(m.join("metadata.yaml"), deep).unwrap();
    let text = run(&[os("info"), m.as_os_str()], &[]).1;
    assert!(text.contains("config_depth"), "{text}");
}

#[test]
fn a_bag_without_readable_bodies_names_why() {
    let d = tempfile::tempdir().unwrap();
    let m = d.path().join("gone");
    write_dir(&m, &["--storage", "sqlite3", "--splits", "2"]);
    for f in ["gone_0.db3", "gone_1.db3"] {
        std::fs::remove_file(m.join(f)).unwrap();
    }
    let (ok, text) = run(&[os("replay"), m.as_os_str()], &[]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("gone_0.db3")
            && text.contains("does not exist")
            && text.contains("no bodies"),
        "{text}"
    );
    // A split file of a directory compressed per message, passed on its own: decompressed as
    // its metadata says, with a word to pass the directory.
    let c = d.path().join("perm");
    write_dir(
        &c,
        &[
            "--storage",
            "sqlite3",
            "--splits",
            "2",
            "--compression",
            "message",
        ],
    );
    let (ok, text) = run(&[os("replay"), c.join("perm_0.db3").as_os_str()], &[]);
    assert!(ok, "{text}");
    assert!(text.contains("pass the directory"), "{text}");
    assert!(!text.contains("encapsulation 28 b5"), "{text}");
}

#[test]
fn definitions_laid_out_by_other_writers_are_read_by_meaning() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("foreign");
    let o = pyenv::python()
        .arg(root().join("tests/py/write_foreign_defs.py"))
        .arg(root().join(SOURCE))
        .arg(root().join("msgs/msg"))
        .arg(&out)
        .output()
        .unwrap_or_else(|e| panic!("python runs ({}): {e}", pyenv::INSTALL_HINT));
    assert!(
        o.status.success(),
        "write_foreign_defs.py failed ({}):\n{}",
        pyenv::INSTALL_HINT,
        String::from_utf8_lossy(&o.stderr)
    );
    let reference = comparable(replay(&root().join(SOURCE), &d.path().join("ref.json"), None));
    for name in ["rosbags-mcap", "rosbags-sqlite", "mcap-ros2.mcap", "handmade.mcap"] {
        let r = replay(&out.join(name), &d.path().join(format!("{name}.json")), None);
        assert!(
            r["input"].get("refused_topics").is_none(),
            "{name}: {}",
            r["input"]
        );
        assert_eq!(comparable(r), reference, "{name}");
    }
}
