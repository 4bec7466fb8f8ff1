//! Bags written here are read, every message, by two readers nobody here wrote (PyPI
//! `rosbags` and `mcap-ros2-support`, installed by the README's test command / `.ci/run`).

use crate::pyenv;

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
    let out = pyenv::python()
        .arg(format!("{root}/tests/py/read_bags.py"))
        .args(&bags)
        .output()
        .unwrap_or_else(|e| panic!("python runs ({}): {e}", pyenv::INSTALL_HINT));
    assert!(
        out.status.success(),
        "python readers failed (is the environment of tests/py/setup_env.py made?)\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
