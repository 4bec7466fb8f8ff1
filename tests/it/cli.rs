//! The `chronotope` binary end to end: scene bags, `mesh --stats`, slices, bad bags and
//! bad frames in the middle of a stream.

use chronotope::bag::BagWriter;
use chronotope::msg::{Header, Point, Time, VoxelGrid};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_chronotope"))
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn run_ok(args: &[&str]) -> Output {
    let out = bin().args(args).output().expect("run chronotope");
    assert!(
        out.status.success(),
        "chronotope {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("tempdir")
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).to_string_lossy().into_owned()
}

fn read_json(path: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("stats file")).expect("valid JSON")
}

#[test]
fn scene_then_mesh_writes_contract_stats_and_closed_meshes() {
    let d = tmp();
    let bag = p(d.path(), "spheres.mcap");
    run_ok(&[
        "scene",
        "four-spheres",
        "--grid",
        "16",
        "--frames",
        "9",
        "--out",
        &bag,
    ]);
    let stats = p(d.path(), "stats.json");
    run_ok(&[
        "mesh",
        &bag,
        "--stats",
        &stats,
        "--slice",
        "t=0.5",
        "--slice",
        "x=0.5",
        "--ply-dir",
        &p(d.path(), "ply"),
    ]);
    let j = read_json(&stats);
    let bodies = j["bodies"].as_array().unwrap();
    assert_eq!(bodies.len(), 4);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.125f64.powi(3) * 1.0;
    for b in bodies {
        for key in [
            "id",
            "frames",
            "tets",
            "vertices",
            "closed",
            "hypervolume_m3s",
            "slab_ms_median",
            "slab_ms_p99",
        ] {
            assert!(b.get(key).is_some(), "missing {key} in {b}");
        }
        assert_eq!(b["frames"], 9);
        assert_eq!(b["closed"], true, "{b}");
        assert_eq!(b["skipped_frames"], 0);
        assert!(b["tets"].as_u64().unwrap() > 1000);
        let v = b["hypervolume_m3s"].as_f64().unwrap();
        assert!(
            (v - exact).abs() / exact < 0.2,
            "{}: {v} vs {exact}",
            b["id"]
        );
    }
    assert!(j["seconds_total"].as_f64().unwrap() > 0.0);
    assert!(j["peak_rss_mb"].as_f64().unwrap() > 0.0);
    // Slices as PLY files a person can open.
    let plys: Vec<PathBuf> = std::fs::read_dir(d.path().join("ply"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(plys.len(), 8, "{plys:?}");
    for f in plys {
        let bytes = std::fs::read(&f).unwrap();
        assert!(
            bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"),
            "{}",
            f.display()
        );
    }
}

#[test]
fn mesh_is_deterministic() {
    let d = tmp();
    let bag = p(d.path(), "mt.mcap");
    run_ok(&[
        "scene",
        "machine-tool",
        "--grid",
        "16",
        "--frames",
        "6",
        "--encoding",
        "percent",
        "--out",
        &bag,
    ]);
    let strip = |v: &mut Value| {
        v.as_object_mut().unwrap().remove("seconds_total");
        v.as_object_mut().unwrap().remove("peak_rss_mb");
        for b in v["bodies"].as_array_mut().unwrap() {
            b.as_object_mut().unwrap().remove("slab_ms_median");
            b.as_object_mut().unwrap().remove("slab_ms_p99");
        }
    };
    let mut runs = Vec::new();
    for i in 0..2 {
        let s = p(d.path(), &format!("s{i}.json"));
        run_ok(&["mesh", &bag, "--stats", &s]);
        let mut j = read_json(&s);
        strip(&mut j);
        runs.push(j);
    }
    assert_eq!(runs[0], runs[1]);
    assert_eq!(runs[0]["bodies"].as_array().unwrap().len(), 3);
}

fn grid(stamp_ns: i64, size: [u32; 3], data: Vec<u8>) -> VoxelGrid {
    VoxelGrid {
        header: Header {
            stamp: Time::from_nanos(stamp_ns),
            frame_id: "world".into(),
        },
        origin: Point {
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        resolution: 0.1,
        size_x: size[0],
        size_y: size[1],
        size_z: size[2],
        encoding: VoxelGrid::ENCODING_BITS,
        data,
    }
}

#[test]
fn bad_frames_mid_stream_are_skipped_and_counted() {
    let d = tmp();
    let bag = d.path().join("bad.mcap");
    let size = [4u32, 4, 4];
    let block = vec![
        0b0110_0000u8,
        0b0000_0110,
        0,
        0,
        0b0110_0000,
        0b0000_0110,
        0,
        0,
    ];
    let mut w = BagWriter::create(&bag).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    let mut frames = vec![
        grid(1_000, size, block.clone()),
        grid(2_000, size, block.clone()),
    ];
    frames.push(grid(3_000, size, block[..5].to_vec())); // data too short
    let mut nan = grid(3_500, size, block.clone());
    nan.resolution = f64::NAN;
    frames.push(nan);
    frames.push(grid(1_500, size, block.clone())); // stamp goes back
    frames.push(grid(4_000, size, block.clone()));
    for f in &frames {
        w.write("/a/occupancy", f.header.stamp.as_nanos() as u64, f)
            .unwrap();
    }
    w.finish().unwrap();
    let stats = p(d.path(), "s.json");
    let out = run_ok(&["mesh", bag.to_str().unwrap(), "--stats", &stats]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("/a/occupancy") && err.contains("data is 5 bytes"),
        "{err}"
    );
    assert!(err.contains("does not increase"), "{err}");
    assert!(
        err.contains("stamp_ns=3000") && err.contains("stamp_ns=1500"),
        "{err}"
    );
    let j = read_json(&stats);
    let b = &j["bodies"][0];
    // Accepted 1000, 2000 and 4000; the frame at 3000 was refused, so the gap from 2000 to
    // 4000 (two periods) is filled with one frame between those two accepted ones.
    assert_eq!(b["frames"], 4);
    assert_eq!(b["skipped_frames"], 3);
    assert!(err.contains("frames missing from 2000 to 4000 ns"), "{err}");
    assert_eq!(b["closed"], true);
    assert!(b["hypervolume_m3s"].as_f64().unwrap() > 0.0);
}

#[test]
fn bags_that_cannot_be_meshed_give_a_clear_error() {
    let d = tmp();
    // Not an MCAP file at all.
    let junk = d.path().join("junk.mcap");
    std::fs::write(&junk, b"this is not a bag").unwrap();
    // An empty bag (a topic, no messages).
    let empty = d.path().join("empty.mcap");
    let mut w = BagWriter::create(&empty).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    w.finish().unwrap();
    for (path, words) in [(&junk, "junk.mcap"), (&empty, "empty.mcap")] {
        let out = bin()
            .args(["mesh", path.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(!out.status.success(), "{path:?} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(words), "{err}");
    }
    let missing = bin()
        .args(["mesh", "/nonexistent/x.mcap"])
        .output()
        .unwrap();
    assert!(!missing.status.success());
}

#[test]
fn bad_command_lines_are_refused() {
    for args in [
        vec!["mesh", "x.mcap", "--slice", "w=1"],
        vec!["mesh", "x.mcap", "--slice", "t=nan"],
        vec!["scene", "no-such-scene", "--out", "/tmp/x.mcap"],
        vec![
            "scene",
            "four-spheres",
            "--grid",
            "1",
            "--out",
            "/tmp/x.mcap",
        ],
    ] {
        let out = bin().args(&args).output().unwrap();
        assert!(!out.status.success(), "{args:?} accepted");
    }
    // A bad option on a real bag names the option.
    let root = env!("CARGO_MANIFEST_DIR");
    let bag = format!("{root}/bags/four-spheres-32-bits.mcap");
    for (flag, value) in [
        ("--percent-scale", "3"),
        ("--percent-scale", "1024"),
        ("--iso-percent", "0"),
    ] {
        let out = bin().args(["mesh", &bag, flag, value]).output().unwrap();
        assert!(!out.status.success(), "{flag} {value} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&flag[2..].replace('-', "_")),
            "{flag} {value}: {err}"
        );
    }
}

#[test]
fn check_writes_the_contract_report() {
    let d = tmp();
    let root = env!("CARGO_MANIFEST_DIR");
    let report = p(d.path(), "out/report.json");
    let out = run_ok(&[
        "check",
        &format!("{root}/bags/four-spheres-32-bits.mcap"),
        "--report",
        &report,
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("COLLIDE /sphere_a/occupancy x /sphere_b/occupancy"),
        "{text}"
    );
    let j = read_json(&report);
    assert_eq!(j["schema"], "chronotope.report/1");
    assert_eq!(j["time_origin_ns"], 1_700_000_000_000_000_000i64);
    assert!(
        (j["time_scale_m_per_s"].as_f64().unwrap() - (1.0 / 32.0) / (1.0 / 16.0)).abs() < 1e-12
    );
    let bodies = j["bodies"].as_array().unwrap();
    assert_eq!(bodies.len(), 4);
    for b in bodies {
        for key in [
            "id",
            "frames",
            "tets",
            "vertices",
            "closed",
            "hypervolume_m3s",
        ] {
            assert!(b.get(key).is_some(), "missing {key}");
        }
        assert_eq!(b["closed"], true);
    }
    let pairs = j["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 6);
    for p in pairs {
        for key in [
            "a",
            "b",
            "interfering",
            "intervals_s",
            "first_contact_s",
            "overlap_hypervolume_m3s",
            "labels",
        ] {
            assert!(p.get(key).is_some(), "missing {key}");
        }
        for side in ["a", "b"] {
            for k in ["interference", "inside", "outside"] {
                assert!(p["labels"][side][k].is_u64());
            }
        }
        // Exactly the pairs with A overlap (B, C and D never meet).
        let with_a = p["a"] == "/sphere_a/occupancy";
        assert_eq!(p["interfering"], with_a, "{p}");
    }
    let res = j["resolutions"].as_array().unwrap();
    let translate = res
        .iter()
        .find(|r| r["kind"] == "translate")
        .expect("a translation");
    assert_eq!(translate["body"], "/sphere_a/occupancy");
    assert_eq!(translate["vector"].as_array().unwrap().len(), 4);
    assert_eq!(translate["verified_clear"], true);
    let v: Vec<f64> = translate["vector"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let c = j["time_scale_m_per_s"].as_f64().unwrap();
    let dist = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + (c * v[3]).powi(2)).sqrt();
    assert!((dist - translate["distance"].as_f64().unwrap()).abs() < 1e-9);
    let scale = res
        .iter()
        .find(|r| r["kind"] == "time_scale")
        .expect("a time scaling");
    assert!(
        scale["t0_s"].is_f64() && scale["scale"].is_f64() && scale["verified_clear"].is_boolean()
    );
    for k in ["mesh", "check", "resolve", "total"] {
        assert!(j["timings_ms"][k].as_f64().unwrap() >= 0.0);
    }
}

/// `check --rotation-axis/--rotation-point/--rotation-max-rad` reach the rotation
/// suggestion in the report (kind `rotate`, with the axis, point, angle, episode and whether
/// it was verified clear, or why nothing within the limit clears) and its line on stdout;
/// an axis without a direction and a limit beyond π are refused.
#[test]
fn check_takes_the_rotation_asked_for() {
    let d = tmp();
    let bag = format!("{}/bags/four-spheres-32-bits.mcap", root().display());
    let report = p(d.path(), "report.json");
    let out = run_ok(&[
        "check",
        &bag,
        "--report",
        &report,
        "--rotation-axis",
        "0,-1,0",
        "--rotation-point",
        "0.5,0.5,0.0",
        "--rotation-max-rad",
        "2",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("or turn /sphere_a/occupancy by"), "{text}");
    let j = read_json(&report);
    let turns: Vec<&Value> = j["resolutions"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["kind"] == "rotate")
        .collect();
    assert_eq!(turns.len(), 1, "{turns:?}");
    let r = turns[0];
    assert_eq!(r["body"], "/sphere_a/occupancy");
    assert_eq!(r["axis"], serde_json::json!([0.0, -1.0, 0.0]));
    let point: Vec<f64> = r["point_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    // Snapped to the checker lattice: an eighth of a 1/32 m voxel.
    for (got, want) in point.iter().zip([0.5, 0.5, 0.0]) {
        assert!((got - want).abs() <= 1.0 / 256.0, "{point:?}");
    }
    assert!(r["angle_rad"].as_f64().unwrap().abs() <= 2.0, "{r}");
    assert_eq!(r["episode_s"].as_array().unwrap().len(), 2);
    match r["verified_clear"].as_bool() {
        Some(true) => assert!(r.get("reason").is_none(), "{r}"),
        Some(false) => assert!(r["reason"].is_string(), "{r}"),
        None => panic!("verified_clear: {r}"),
    }
    // A zero limit asks for none.
    run_ok(&[
        "check",
        &bag,
        "--report",
        &report,
        "--overwrite",
        "--rotation-max-rad",
        "0",
    ]);
    let j = read_json(&report);
    assert!(
        !j["resolutions"]
            .as_array()
            .unwrap()
            .iter()
            .any(|r| r["kind"] == "rotate"),
        "{j}"
    );
    for (flag, value, said) in [
        ("--rotation-axis", "0,0,0", "needs a direction"),
        ("--rotation-axis", "1,0", "three"),
        ("--rotation-max-rad", "4", "[0, π]"),
    ] {
        let out = bin().args(["check", &bag, flag, value]).output().unwrap();
        assert!(!out.status.success(), "{flag} {value} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(said), "{flag} {value}: {err}");
    }
}

#[test]
fn topics_beyond_the_body_limit_are_refused_and_listed() {
    let d = tmp();
    let bag = d.path().join("many.mcap");
    let size = [2u32, 2, 2];
    let mut w = BagWriter::create(&bag).unwrap();
    let n = chronotope::cli::MAX_BODIES + 44;
    for b in 0..n {
        w.add_topic::<VoxelGrid>(&format!("/b{b:03}/occupancy"))
            .unwrap();
    }
    for k in 0..2i64 {
        for b in 0..n {
            let g = grid(1_000 * (k + 1), size, vec![0b0000_0001]);
            w.write(
                &format!("/b{b:03}/occupancy"),
                g.header.stamp.as_nanos() as u64,
                &g,
            )
            .unwrap();
        }
    }
    w.finish().unwrap();
    let stats = p(d.path(), "s.json");
    run_ok(&["mesh", bag.to_str().unwrap(), "--stats", &stats]);
    let j = read_json(&stats);
    assert_eq!(
        j["bodies"].as_array().unwrap().len(),
        chronotope::cli::MAX_BODIES
    );
    let errors = j["bag_errors"].as_array().unwrap();
    assert_eq!(errors.len(), 44);
    assert!(errors[0].as_str().unwrap().contains("not read"));
}

/// The live benchmark's config without markers is `launch_configs/machine_tool.yaml` with
/// only its markers line changed (a copy kept in step, so both measure the same cell).
#[test]
fn bench_config_without_markers_is_machine_tool_yaml_but_markers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lines = |rel: &str| -> Vec<String> {
        std::fs::read_to_string(root.join(rel))
            .expect(rel)
            .lines()
            .filter(|l| !l.trim_start().starts_with('#'))
            .map(str::to_owned)
            .collect()
    };
    let with = lines("launch_configs/machine_tool.yaml");
    let without = lines("bench/machine_tool_no_markers.yaml");
    let markers = |v: &str| format!("    - {{name: markers, value: {v}}}");
    let swapped: Vec<String> = with
        .iter()
        .map(|l| {
            if *l == markers("true") {
                markers("false")
            } else {
                l.clone()
            }
        })
        .collect();
    assert_ne!(
        swapped, with,
        "machine_tool.yaml has no `markers: true` line"
    );
    assert_eq!(swapped, without);
}

/// Every file under `dir` (recursively) with its bytes, to tell whether anything changed.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            let meta = std::fs::symlink_metadata(&path).unwrap();
            if meta.is_dir() {
                stack.push(path);
            } else if meta.is_file() {
                out.push((path.clone(), std::fs::read(&path).unwrap()));
            } else {
                out.push((path.clone(), Vec::new()));
            }
        }
    }
    out.sort();
    out
}

/// `chronotope ARGS` that must fail: its stderr.
fn run_refused(args: &[&str]) -> String {
    let out = bin().args(args).output().expect("run chronotope");
    assert!(!out.status.success(), "chronotope {args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn outputs_that_would_destroy_an_input_are_refused_and_nothing_changes() {
    let d = tmp();
    let bag = p(d.path(), "in.mcap");
    std::fs::copy(root().join("bags/four-spheres-32-bits.mcap"), &bag).unwrap();
    std::os::unix::fs::symlink(&bag, d.path().join("link.mcap")).unwrap();
    std::fs::hard_link(&bag, d.path().join("hard.mcap")).unwrap();
    let out = p(d.path(), "o.mcap");
    run_ok(&["replay", &bag, "--out", &out]);
    let rec = p(d.path(), "rec/");
    run_ok(&[
        "scene",
        "four-spheres",
        "--grid",
        "8",
        "--frames",
        "3",
        "--out",
        &rec,
    ]);
    let before = snapshot(d.path());
    let link = p(d.path(), "link.mcap");
    let hard = p(d.path(), "hard.mcap");
    let x = p(d.path(), "x");
    let rec_report = format!("{rec}r.json");
    let cases: Vec<Vec<&str>> = vec![
        vec!["replay", &bag, "--out", &bag],
        vec!["replay", &bag, "--report", &bag],
        vec!["replay", &bag, "--out", &link, "--overwrite"],
        vec!["replay", &bag, "--report", &hard, "--overwrite"],
        vec!["replay", &bag, "--report", &x, "--out", &x],
        vec!["replay", &rec, "--out", &rec, "--overwrite"],
        vec!["replay", &rec, "--report", &rec_report],
        vec!["check", &bag, "--report", &bag],
        vec!["mesh", &bag, "--stats", &link],
        vec!["render", &out, "--out", &out],
        vec!["scene", "four-spheres", "--out", &bag],
    ];
    for args in &cases {
        let err = run_refused(args);
        assert!(
            err.contains("--out") || err.contains("--report") || err.contains("--stats"),
            "{args:?}: {err}"
        );
        assert_eq!(snapshot(d.path()), before, "{args:?} changed a file");
    }
}

#[test]
fn the_readme_command_runs_twice_and_recordings_need_overwrite() {
    let d = tmp();
    let report = p(d.path(), "out/report.json");
    let out = p(d.path(), "out/replay.mcap");
    let bag = root().join("bags/machine-tool-32-bits.mcap");
    let launch = root().join("launch_configs/machine_tool.yaml");
    let args = [
        "replay",
        bag.to_str().unwrap(),
        "--launch",
        launch.to_str().unwrap(),
        "--report",
        &report,
        "--out",
        &out,
    ];
    run_ok(&args);
    let first = std::fs::read(&out).unwrap();
    run_ok(&args);
    assert_eq!(
        std::fs::read(&out).unwrap(),
        first,
        "the same run gives the same bag"
    );
    let mut names: Vec<String> = std::fs::read_dir(d.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["replay.mcap", "report.json"],
        "nothing else is left"
    );
    // A bag this program did not derive (the bundled bags predate the mark: as a recording)
    // is replaced only with --overwrite.
    let rec = p(d.path(), "recording.mcap");
    std::fs::copy(&bag, &rec).unwrap();
    let four = root().join("bags/four-spheres-32-bits.mcap");
    let err = run_refused(&["replay", four.to_str().unwrap(), "--out", &rec]);
    assert!(err.contains("--overwrite"), "{err}");
    assert_eq!(std::fs::read(&rec).unwrap(), std::fs::read(&bag).unwrap());
    run_ok(&[
        "replay",
        four.to_str().unwrap(),
        "--out",
        &rec,
        "--overwrite",
    ]);
    assert_ne!(std::fs::read(&rec).unwrap(), std::fs::read(&bag).unwrap());
}

#[test]
fn a_link_planted_at_an_output_is_replaced_never_written_through() {
    let d = tmp();
    let precious = d.path().join("precious.txt");
    std::fs::write(&precious, b"keep me").unwrap();
    std::fs::create_dir(d.path().join("out")).unwrap();
    let report = d.path().join("out/report.json");
    std::os::unix::fs::symlink(&precious, &report).unwrap();
    let bag = root().join("bags/four-spheres-32-bits.mcap");
    run_ok(&[
        "replay",
        bag.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(std::fs::read(&precious).unwrap(), b"keep me");
    assert!(read_json(report.to_str().unwrap())["pairs"].is_array());
}

#[test]
fn a_killed_replay_leaves_no_partial_output() {
    let d = tmp();
    let bag = p(d.path(), "mt.mcap");
    run_ok(&[
        "scene",
        "machine-tool",
        "--grid",
        "48",
        "--frames",
        "24",
        "--out",
        &bag,
    ]);
    let out_dir = d.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let tmp_dir = d.path().join("tmp");
    std::fs::create_dir(&tmp_dir).unwrap();
    // The bag compressed as a whole: read through a temporary copy in TMPDIR.
    let z = p(d.path(), "mt.mcap.zstd");
    std::fs::write(
        &z,
        zstd::encode_all(std::fs::File::open(&bag).unwrap(), 1).unwrap(),
    )
    .unwrap();
    for (i, wait_ms) in [50u64, 300, 800].into_iter().enumerate() {
        let out = out_dir.join(format!("o{i}.mcap"));
        let mut child = bin()
            .args(["replay", &z, "--out", out.to_str().unwrap()])
            .arg("--report")
            .arg(out_dir.join(format!("r{i}.json")))
            .env("TMPDIR", &tmp_dir)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(wait_ms));
        let _ = child.kill(); // SIGKILL: no handler runs.
        child.wait().unwrap();
        // Nothing half-made: no hidden staging file, and an output is there whole or not at all.
        let left: Vec<String> = std::fs::read_dir(&out_dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect();
        assert!(left.is_empty(), "killed after {wait_ms} ms: left {left:?}");
        assert!(
            std::fs::read_dir(&tmp_dir).unwrap().next().is_none(),
            "killed after {wait_ms} ms: TMPDIR not empty"
        );
        // What is there is whole: a complete bag or nothing.
        if out.exists() {
            assert!(chronotope::bag::BagReader::open(&out)
                .unwrap()
                .all(|m| m.is_ok()));
        }
    }
}
