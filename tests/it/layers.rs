//! The layer crates keep to ARCHITECTURE.md: each depends only on the layers under it, and
//! builds none of the crates its layer keeps out (tokio, RustDDS, ros2-client, rusqlite,
//! mcap, ...), directly or through anything it pulls in. A change that adds such a
//! dependency fails here, naming the crate and the dependency.

use std::path::Path;
use std::process::Command;

/// What no layer crate builds but the live transport: async runtimes and DDS.
const TRANSPORT: &[&str] = &["tokio", "rustdds", "ros2-client", "futures"];

/// What only the bags (and the crates above them that need bags) build: MCAP and SQLite.
const STORAGE: &[&str] = &["rusqlite", "mcap"];

/// A layer crate: its name, the workspace crates it may use (directly or not), and the
/// groups of crates it must not build.
type Layer = (
    &'static str,
    &'static [&'static str],
    &'static [&'static [&'static str]],
);

/// The layer crates, bottom up (ARCHITECTURE.md's table).
const LAYERS: [Layer; 14] = [
    ("chronotope-kernel", &[], &[TRANSPORT, STORAGE]),
    (
        "chronotope-mesh",
        &["chronotope-kernel"],
        &[TRANSPORT, STORAGE],
    ),
    (
        "chronotope-checker",
        &["chronotope-kernel", "chronotope-mesh"],
        &[TRANSPORT, STORAGE],
    ),
    ("chronotope-robot", &[], &[TRANSPORT, STORAGE]),
    ("chronotope-occupancy", &[], &[TRANSPORT, STORAGE]),
    ("chronotope-yaml", &[], &[TRANSPORT, STORAGE]),
    ("chronotope-carving", &[], &[TRANSPORT, STORAGE]),
    (
        "chronotope-sampler",
        &["chronotope-kernel", "chronotope-mesh", "chronotope-yaml"],
        &[TRANSPORT, STORAGE],
    ),
    (
        "chronotope-msg",
        &["chronotope-kernel", "chronotope-mesh"],
        &[TRANSPORT, STORAGE],
    ),
    (
        "chronotope-scene",
        &["chronotope-kernel", "chronotope-mesh", "chronotope-msg"],
        &[TRANSPORT, STORAGE],
    ),
    (
        "chronotope-bag",
        &[
            "chronotope-kernel",
            "chronotope-mesh",
            "chronotope-msg",
            "chronotope-yaml",
        ],
        &[TRANSPORT],
    ),
    (
        "chronotope-node",
        &[
            "chronotope-kernel",
            "chronotope-mesh",
            "chronotope-checker",
            "chronotope-robot",
            "chronotope-occupancy",
            "chronotope-yaml",
            "chronotope-carving",
            "chronotope-msg",
        ],
        &[TRANSPORT, STORAGE],
    ),
    (
        "chronotope-live",
        &[
            "chronotope-kernel",
            "chronotope-mesh",
            "chronotope-checker",
            "chronotope-robot",
            "chronotope-occupancy",
            "chronotope-yaml",
            "chronotope-carving",
            "chronotope-msg",
            "chronotope-node",
        ],
        &[STORAGE],
    ),
    // The command line: every layer, none above it.
    (
        "chronotope",
        &[
            "chronotope-kernel",
            "chronotope-mesh",
            "chronotope-checker",
            "chronotope-robot",
            "chronotope-occupancy",
            "chronotope-yaml",
            "chronotope-carving",
            "chronotope-sampler",
            "chronotope-msg",
            "chronotope-scene",
            "chronotope-bag",
            "chronotope-node",
            "chronotope-live",
        ],
        &[],
    ),
];

/// `cargo tree` of `package`'s normal (not dev) dependencies: one package name a line.
fn tree(package: &str) -> Vec<String> {
    let out = Command::new(env!("CARGO"))
        .args([
            "tree",
            "--offline",
            "-e",
            "normal",
            "--prefix",
            "none",
            "-p",
            package,
        ])
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")))
        .output()
        .expect("run cargo tree");
    assert!(
        out.status.success(),
        "cargo tree -p {package}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .expect("utf-8")
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .collect()
}

#[test]
fn layer_crates_depend_only_on_the_layers_under_them() {
    let workspace: Vec<&str> = LAYERS.iter().map(|(name, _, _)| *name).collect();
    for (name, allowed, forbidden) in LAYERS {
        let deps = tree(name);
        assert_eq!(deps.first().map(String::as_str), Some(name));
        for dep in &deps[1..] {
            assert!(
                !forbidden.iter().any(|group| group.contains(&dep.as_str())),
                "{name} builds {dep}, which ARCHITECTURE.md keeps out of its layer"
            );
            if workspace.contains(&dep.as_str()) {
                assert!(
                    allowed.contains(&dep.as_str()),
                    "{name} depends on {dep}: a layer uses only the layers under it \
                     (ARCHITECTURE.md)"
                );
            }
        }
    }
}

/// Every crate of the workspace is in [`LAYERS`]: a new crate gets a place in the table.
#[test]
fn every_workspace_crate_is_a_layer() {
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--offline",
            "--no-deps",
            "--format-version",
            "1",
        ])
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")))
        .output()
        .expect("run cargo metadata");
    assert!(out.status.success(), "cargo metadata failed");
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata JSON");
    let layers: Vec<&str> = LAYERS.iter().map(|(name, _, _)| *name).collect();
    for package in meta["packages"].as_array().expect("packages") {
        let name = package["name"].as_str().expect("a package name");
        assert!(
            layers.contains(&name),
            "{name} is a workspace crate without a place in LAYERS (ARCHITECTURE.md's table)"
        );
    }
}
