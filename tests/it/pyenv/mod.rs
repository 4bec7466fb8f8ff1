//! The Python interpreter of the interop tests: `$CHRONOTOPE_PYTHON`, else the environment
//! `python3 tests/py/setup_env.py` makes under the target directory (`target/py`), else
//! `python3` from the PATH.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// The interpreter's path.
pub fn python_path() -> PathBuf {
    if let Some(p) = std::env::var_os("CHRONOTOPE_PYTHON") {
        return PathBuf::from(p);
    }
    // CARGO_TARGET_TMPDIR is `<target>/tmp` for integration tests.
    let venv = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .map(|t| t.join("py").join("bin").join("python"));
    match venv {
        Some(p) if p.exists() => p,
        _ => PathBuf::from("python3"),
    }
}

/// A command running the interpreter.
pub fn python() -> Command {
    Command::new(python_path())
}

/// What to do when the interpreter or a package is missing.
pub const INSTALL_HINT: &str =
    "run `python3 tests/py/setup_env.py` (the README's test command does)";

/// Whether the test Python can import cyclonedds.
pub fn cyclonedds_available() -> bool {
    python()
        .args(["-c", "import cyclonedds"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Whether a test that needs a Cyclone DDS peer can run: `false` (said) where the test
/// Python cannot import cyclonedds, which fails the test under CI.
pub fn cyclone_or_skip(test: &str) -> bool {
    if cyclonedds_available() {
        return true;
    }
    let why = "the test Python cannot import cyclonedds (run `python3 tests/py/setup_env.py`)";
    assert!(std::env::var_os("CI").is_none(), "CI is set and {why}");
    eprintln!("SKIPPED {test}: {why}");
    false
}
