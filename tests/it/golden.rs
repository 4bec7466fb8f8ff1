//! Golden replays: every bag under `bags/` replays, with its scene's launch config, to the
//! committed report (`tests/golden/<bag>.report.json`, timings left out) and output bag
//! (`tests/golden/<bag>.mcap.sha256`). A change in either fails the test. After an intended
//! change, re-bless with
//!
//! ```text
//! CHRONOTOPE_BLESS=1 cargo test --test it golden::
//! ```
//!
//! and review the diff of `tests/golden/`. Output bags of every replay are also read by the
//! independent Python readers, and a second replay must give the same bytes.

use crate::pyenv;

use std::path::{Path, PathBuf};
use std::process::Command;

use sha2::{Digest, Sha256};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The launch config of a bag's scene.
fn config_for(bag: &Path) -> PathBuf {
    let stem = bag.file_stem().unwrap().to_str().unwrap();
    let name = if stem.starts_with("machine-tool") {
        "machine_tool"
    } else if stem.starts_with("four-spheres") {
        "four_spheres"
    } else if stem.starts_with("carving-session") {
        "carving_session"
    } else if stem.starts_with("robot-cell") {
        "robot_cell"
    } else if stem.starts_with("person-cell") {
        "person_cell"
    } else {
        panic!("{stem}: which launch config replays it? add it to config_for")
    };
    root().join("launch_configs").join(format!("{name}.yaml"))
}

fn replay(
    bag: &Path,
    config: &Path,
    dir: &Path,
    tag: &str,
    threads: usize,
) -> (serde_json::Value, Vec<u8>, PathBuf) {
    let report = dir.join(format!("{tag}.json"));
    let out = dir.join(format!("{tag}.mcap"));
    let o = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .env("RAYON_NUM_THREADS", threads.to_string())
        .arg("replay")
        .arg(bag)
        .arg("--launch")
        .arg(config)
        .arg("--report")
        .arg(&report)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "replay of {} failed:\n{}",
        bag.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let mut r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    r.as_object_mut().unwrap().remove("timings_ms");
    (r, std::fs::read(&out).unwrap(), out)
}

fn sha256(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn every_bag_replays_to_its_golden_report_and_bag() {
    let bless = std::env::var_os("CHRONOTOPE_BLESS").is_some();
    let golden = root().join("tests/golden");
    std::fs::create_dir_all(&golden).unwrap();
    let mut bags: Vec<PathBuf> = std::fs::read_dir(root().join("bags"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    bags.sort();
    assert!(bags.len() >= 5, "bags missing: {bags:?}");
    let dir = tempfile::tempdir().unwrap();
    let mut outputs = Vec::new();
    let mut failures = Vec::new();
    for bag in &bags {
        let stem = bag.file_stem().unwrap().to_str().unwrap().to_owned();
        // On two threads, then on one: the same bytes whatever the thread count.
        let (report, bytes, out) = replay(bag, &config_for(bag), dir.path(), &stem, 2);
        let (_, again, _) = replay(bag, &config_for(bag), dir.path(), &format!("{stem}-1"), 1);
        assert!(
            bytes == again,
            "{stem}: replays on 2 and 1 threads wrote different output bags"
        );
        outputs.push(out);
        let report_path = golden.join(format!("{stem}.report.json"));
        let digest_path = golden.join(format!("{stem}.mcap.sha256"));
        let digest = sha256(&bytes);
        let text = serde_json::to_string_pretty(&report).unwrap() + "\n";
        if bless {
            std::fs::write(&report_path, &text).unwrap();
            std::fs::write(&digest_path, format!("{digest}\n")).unwrap();
            continue;
        }
        let want = std::fs::read_to_string(&report_path).unwrap_or_default();
        let want_json: serde_json::Value = serde_json::from_str(&want).unwrap_or_default();
        if want_json != report {
            failures.push(format!(
                "{stem}: the report differs from {} (re-bless with CHRONOTOPE_BLESS=1 cargo test --test it golden:: if intended)\n{text}",
                report_path.display()
            ));
        }
        let want_digest = std::fs::read_to_string(&digest_path).unwrap_or_default();
        if want_digest.trim() != digest {
            failures.push(format!(
                "{stem}: the output bag's sha256 {digest} is not {} (re-bless if intended)",
                want_digest.trim()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // Every output bag, every message, read by two readers nobody here wrote.
    let o = pyenv::python()
        .arg(root().join("tests/py/read_bags.py"))
        .args(&outputs)
        .output()
        .unwrap_or_else(|e| panic!("python runs ({}): {e}", pyenv::INSTALL_HINT));
    assert!(
        o.status.success(),
        "python readers failed on output bags\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}
