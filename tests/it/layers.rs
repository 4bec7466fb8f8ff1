//! The layer crates keep to ARCHITECTURE.md: each depends only on the layers under it, and
//! the kernel, the mesher and the checker build without ROS transport, bags or async
//! runtimes (tokio, RustDDS, ros2-client, rusqlite, mcap), directly or through anything they
//! pull in. A change that adds such a dependency fails here, naming the crate and the path.

use std::path::Path;
use std::process::Command;

/// The layer crates, the workspace crates each may use, in layer order.
const LAYERS: [(&str, &[&str]); 3] = [
    ("chronotope-kernel", &[]),
    ("chronotope-mesh", &["chronotope-kernel"]),
    (
        "chronotope-checker",
        &["chronotope-kernel", "chronotope-mesh"],
    ),
];

/// What none of the layer crates may build, even indirectly.
const FORBIDDEN: [&str; 9] = [
    "tokio",
    "rustdds",
    "ros2-client",
    "rusqlite",
    "mcap",
    "chronotope",
    "chronotope-robot",
    "chronotope-occupancy",
    "futures",
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
    let workspace: Vec<&str> = LAYERS.iter().map(|(name, _)| *name).collect();
    for (name, allowed) in LAYERS {
        let deps = tree(name);
        assert_eq!(deps.first().map(String::as_str), Some(name));
        for dep in &deps[1..] {
            assert!(
                !FORBIDDEN.contains(&dep.as_str()),
                "{name} builds {dep}, which ARCHITECTURE.md keeps out of the layer crates"
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
