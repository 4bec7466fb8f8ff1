//! Bags written here are read, every message, by two readers nobody here wrote (PyPI
//! `rosbags` and `mcap-ros2-support`, installed by the README's test command / `.ci/run`).

use std::process::Command;

#[test]
fn committed_and_generated_bags_read_with_independent_readers() {
    let root = env!("CARGO_MANIFEST_DIR");
    let d = tempfile::tempdir().unwrap();
    let fresh = d.path().join("fresh.mcap");
    let status = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .args([
            "scene",
            "machine-tool",
            "--grid",
            "12",
            "--frames",
            "3",
            "--encoding",
            "percent",
            "--out",
        ])
        .arg(&fresh)
        .status()
        .unwrap();
    assert!(status.success());
    let mut bags: Vec<std::path::PathBuf> = std::fs::read_dir(format!("{root}/bags"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    assert!(bags.len() >= 4, "committed bags missing: {bags:?}");
    bags.push(fresh);
    let out = Command::new("python3")
        .arg(format!("{root}/tests/py/read_bags.py"))
        .args(&bags)
        .output()
        .expect("python3 runs (install: pip install -r tests/py/requirements.txt)");
    assert!(
        out.status.success(),
        "python readers failed (are tests/py/requirements.txt installed?)\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
