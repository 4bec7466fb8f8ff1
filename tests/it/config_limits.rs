//! Hostile configuration inputs: launch configs and sampler scene files that are too big,
//! too deep, too many, contradictory or out of their domain are refused by name, quickly,
//! without echoing the user's text in full.

use std::io::Write;

use chronotope::node::carving::CarvingNode;
use chronotope::node::launch::{LaunchConfig, LaunchError, MAX_NODES};
use chronotope::node::mesher::MesherNode;
use chronotope::node::routes::{check_bag_types, check_topic_types, topic_uses};
use chronotope::node::Node;
use chronotope::sampler::scene_file::{SceneFile, SceneFileError};
use chronotope::yaml::CONFIG_LIMITS;

fn launch_err(text: &str) -> String {
    LaunchConfig::parse(text, "cfg.yaml")
        .expect_err("the config must be refused")
        .to_string()
}

/// No message quotes a long run of the user's text (a 300-digit literal, a huge name).
fn assert_short(msg: &str) {
    let longest = msg.split(' ').map(|w| w.chars().count()).max().unwrap_or(0);
    assert!(
        longest <= 60 && msg.len() < 600,
        "a message echoes user text in full: {msg}"
    );
    for dump in ["struct ", "enum ", "{ .. }", "Some(", "String(", "Double("] {
        assert!(!msg.contains(dump), "a Rust debug dump or type name: {msg}");
    }
}

const NODE: &str = "- node: {pkg: chronotope, exec: mesher}\n";

// Case: a 1 MB launch config of nested brackets (its parse grew quadratically) is refused
// by config_depth before any parsing.
#[test]
fn a_megabyte_of_nested_brackets_is_refused_by_depth() {
    let half = (1 << 20) / 2 - 64;
    let text = format!(
        "launch:\n- node: {{pkg: chronotope, exec: mesher, param: [{{name: bodies, value: {}{}}}]}}\n",
        "[".repeat(half),
        "]".repeat(half)
    );
    assert!(text.len() <= CONFIG_LIMITS.max_bytes);
    let e = launch_err(&text);
    assert!(
        e.contains("config_depth = 32") && e.contains("line 2"),
        "{e}"
    );
    assert_short(&e);
    // The same through a file; one byte over the size limit is refused by config_bytes.
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(text.as_bytes()).unwrap();
    let e = LaunchConfig::read(f.path()).unwrap_err().to_string();
    assert!(e.contains("config_depth"), "{e}");
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(format!("launch:\n{NODE}#{}\n", "x".repeat(1 << 20)).as_bytes())
        .unwrap();
    let e = LaunchConfig::read(f.path()).unwrap_err().to_string();
    assert!(e.contains("config_bytes = 1048576"), "{e}");
    // Block nesting counts too.
    let mut deep = String::from("launch:\n");
    for i in 1..40 {
        deep += &format!("{}k:\n", " ".repeat(i));
    }
    assert!(launch_err(&deep).contains("config_depth"));
}

// Case: a 400 KB scene file of nested brackets hung `sample` the same way.
#[test]
fn a_400_kb_nested_scene_file_is_refused_by_depth() {
    let n = 200_000;
    let text = format!(
        "dim: 3\nbodies:\n  - name: a\n    shape: {{kind: sphere, centre: {}0{}, radius: 1}}\nsample: [a]\n",
        "[".repeat(n),
        "]".repeat(n)
    );
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(text.as_bytes()).unwrap();
    let e = SceneFile::read(f.path()).unwrap_err();
    assert!(matches!(e, SceneFileError::Yaml(_)), "{e}");
    let e = e.to_string();
    assert!(
        e.contains("config_depth = 32") && e.contains("line 4"),
        "{e}"
    );
    // Aliases, which could expand a small file into a huge one, are refused by name.
    let e = SceneFile::parse("dim: 3\nbodies: &b []\nsample: *b\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("alias *b") && e.contains("line 3"), "{e}");
}

// Case: 10,000 nodes in a config aborted; the config is refused by nodes_per_launch.
#[test]
fn ten_thousand_nodes_are_refused_by_name() {
    let mut text = String::from("launch:\n");
    for i in 0..10_000 {
        text += &format!("- node: {{pkg: chronotope, exec: mesher, name: m{i}}}\n");
    }
    let e = launch_err(&text);
    assert!(
        e.contains("10000 nodes") && e.contains(&format!("nodes_per_launch = {MAX_NODES}")),
        "{e}"
    );
    // The limit itself is accepted.
    let mut ok = String::from("launch:\n");
    for i in 0..MAX_NODES {
        ok += &format!("- node: {{pkg: chronotope, exec: mesher, name: m{i}}}\n");
    }
    assert_eq!(
        LaunchConfig::parse(&ok, "t").unwrap().nodes.len(),
        MAX_NODES
    );
}

fn carving_and_mesher(pose_topic: &str, bodies: &str) -> (LaunchConfig, Vec<Box<dyn Node>>) {
    let text = format!(
        "launch:\n- node:\n    pkg: chronotope\n    exec: carving\n    param:\n    - {{name: pose_topic, value: {pose_topic}}}\n- node:\n    pkg: chronotope\n    exec: mesher\n    param:\n    - {{name: bodies, value: {bodies}}}\n"
    );
    let cfg = LaunchConfig::parse(&text, "t").unwrap();
    let carving = CarvingNode::from_spec(&cfg.nodes[0]).unwrap();
    let mesher = MesherNode::from_spec(&cfg.nodes[1], &[]).unwrap();
    (cfg, vec![Box::new(carving), Box::new(mesher)])
}

// Case: a carving node's pose_topic set to a body's VoxelGrid topic silently took the
// body's frames; one topic with two meanings is refused, both uses named.
#[test]
fn one_topic_with_two_meanings_is_refused() {
    let (cfg, nodes) = carving_and_mesher(
        "/fixture/occupancy",
        "[/carving/occupancy, /fixture/occupancy]",
    );
    let uses = topic_uses(&cfg, &nodes);
    let pose = uses
        .iter()
        .find(|u| u.node == "/carving" && !u.publishes)
        .unwrap();
    assert_eq!(pose.topic, "/fixture/occupancy");
    assert_eq!(pose.source, "parameter pose_topic");
    let e = check_topic_types(&uses).unwrap_err();
    assert!(matches!(e, LaunchError::TopicTypes { .. }));
    let e = e.to_string();
    for part in [
        "topic /fixture/occupancy",
        "/carving reads it as geometry_msgs/msg/PoseStamped (parameter pose_topic)",
        "/mesher reads it as chronotope_msgs/msg/VoxelGrid (parameter bodies)",
    ] {
        assert!(e.contains(part), "{part:?} not in: {e}");
    }
    // The intended routing passes, and the carving's own occupancy is named as such.
    let (cfg, nodes) =
        carving_and_mesher("/haptic/pose", "[/carving/occupancy, /fixture/occupancy]");
    let uses = topic_uses(&cfg, &nodes);
    check_topic_types(&uses).unwrap();
    let occ = uses
        .iter()
        .find(|u| u.node == "/carving" && u.topic == "/carving/occupancy")
        .unwrap();
    assert!(occ.publishes && occ.source == "its fixed name", "{occ:?}");
    // A bag whose pose topic carries VoxelGrids is refused against the nodes' uses.
    let (cfg, nodes) = carving_and_mesher("/fixture/occupancy", "[/carving/occupancy]");
    let uses = topic_uses(&cfg, &nodes);
    check_topic_types(&uses).unwrap();
    let e = check_bag_types(
        &uses,
        [("/fixture/occupancy", "chronotope_msgs/msg/VoxelGrid")],
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("the bag carries chronotope_msgs/msg/VoxelGrid")
            && e.contains("parameter pose_topic"),
        "{e}"
    );
    check_bag_types(
        &uses,
        [("/fixture/occupancy", "geometry_msgs/msg/PoseStamped")],
    )
    .unwrap();
}

// Case: an empty `launch:` exited 0 silently.
#[test]
fn a_config_that_launches_nothing_is_refused() {
    for text in ["launch:\n", "launch: []\n", "launch: ~\n"] {
        let e = launch_err(text);
        assert!(e.contains("launches no node"), "{text:?}: {e}");
    }
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(b"launch:\n").unwrap();
    let e = LaunchConfig::read(f.path()).unwrap_err().to_string();
    assert!(e.contains("launches no node"), "{e}");
}

// Case: 300-digit number literals were echoed in messages; every message quoting a user's
// value shortens it and names the field.
#[test]
fn long_literals_are_never_echoed_in_full() {
    let digits = "9".repeat(300);
    let node =
        |extra: &str| format!("launch:\n- node: {{pkg: chronotope, exec: mesher, {extra}}}\n");
    let cases = [
        (
            node(&format!(
                "param: [{{name: idle_timeout_s, value: {digits}}}]"
            )),
            "idle_timeout_s",
        ),
        (
            node(&format!(
                "param: [{{name: idle_timeout_s, value: -{digits}.5}}]"
            )),
            "idle_timeout_s",
        ),
        (
            node(&format!(
                "param: [{{name: slice_markers, value: {digits}}}]"
            )),
            "slice_markers",
        ),
        (
            node(&format!(
                "param: [{{name: slice_markers, value: \"{digits}\"}}]"
            )),
            "slice_markers",
        ),
        (
            node(&format!("param: [{{name: p{digits}, value: 1}}]")),
            "parameter p999",
        ),
        (node(&format!("name: n{digits}")), "node name"),
        (node(&format!("namespace: {digits}")), "namespace"),
        (
            format!("launch:\n- node: {{pkg: chronotope, exec: \"{digits}\"}}\n"),
            "exec",
        ),
        (
            format!("launch:\n- node: {{pkg: \"{digits}\", exec: mesher}}\n"),
            "pkg",
        ),
        (
            format!("launch:\n- node: {{pkg: chronotope, exec: mesher, {digits}: 1}}\n"),
            "not text",
        ),
        (
            format!("launch:\n- node: {{pkg: chronotope, exec: mesher, a{digits}: 1}}\n"),
            "unknown field",
        ),
        (format!("launch: {digits}\n"), "launch"),
    ];
    for (text, field) in &cases {
        let e = match LaunchConfig::parse(text, "cfg.yaml") {
            Ok(c) => {
                // Typed on use: the mesher's own parameter check.
                MesherNode::from_spec(&c.nodes[0], &[])
                    .err()
                    .unwrap_or_else(|| panic!("accepted: {text}"))
                    .to_string()
            }
            Err(e) => e.to_string(),
        };
        assert!(e.contains(field), "{field:?} not named: {e}");
        assert_short(&e);
    }
    for text in [
        format!("dim: {digits}\nbodies: []\nsample: []\n"),
        format!("dim: 3\nbodies: []\nsample: [\"{digits}\"]\n"),
        format!("dim: 4\nbodies: []\nsample: []\ntime: [0, {digits}]\n"),
    ] {
        let e = match SceneFile::parse(&text) {
            Ok(s) => s.build().unwrap_err().to_string(),
            Err(e) => e.to_string(),
        };
        assert_short(&e);
    }
}

// Case: other fields outside their domain in a launch config or a scene file.
#[test]
fn out_of_domain_fields_are_named() {
    let mesher = |param: &str| {
        let text = format!(
            "launch:\n- node: {{pkg: chronotope, exec: mesher, param: [{{name: {param}}}]}}\n"
        );
        let c = LaunchConfig::parse(&text, "t").unwrap();
        MesherNode::from_spec(&c.nodes[0], &[])
            .err()
            .map(|e| e.to_string())
    };
    for (param, want) in [
        (
            "idle_timeout_s, value: .nan",
            "idle_timeout_s: .nan is not in",
        ),
        ("idle_timeout_s, value: .inf", "a finite number is needed"),
        (
            "idle_timeout_s, value: -1.0",
            "idle_timeout_s: -1 is not in",
        ),
        (
            "slice_markers, value: [1, 2]",
            "expected a bool, got integer array [1, 2]",
        ),
    ] {
        let e = mesher(param).unwrap_or_else(|| panic!("{param} accepted"));
        assert!(e.contains(want), "{param}: {e}");
    }
    for (text, want) in [
        (
            format!("launch:\n{NODE}{NODE}"),
            "two nodes are named /mesher",
        ),
        (
            "launch:\n- node: {pkg: chronotope, exec: mesher, pkg: chronotope}\n".into(),
            "duplicate",
        ),
        (format!("launch:\n{NODE}launch: []\n"), "duplicate"),
        (
            "launch:\n- node: {pkg: chronotope, exec: mesher, remap: [{from: a, to: b}, {from: a, to: c}]}\n".into(),
            "/a is remapped twice (to /b and to /c)",
        ),
        (
            "launch:\n- node: {pkg: chronotope, exec: mesher, colour: red}\n".into(),
            "unknown field `colour`",
        ),
        (format!("launch:\n{NODE}extra: 1\n"), "unknown field `extra`"),
        ("launch:\n- 3: {pkg: chronotope}\n".into(), "not text"),
    ] {
        let e = launch_err(&text);
        assert!(e.contains(want), "{text:?}: {e}");
    }
    // A config that is not a regular file (a FIFO would block) is refused.
    let e = LaunchConfig::read(std::path::Path::new("/dev/null"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a regular file"), "{e}");

    let scene = |body: &str, rest: &str| {
        let text = format!("dim: 4\nbodies:\n  - {{name: a, shape: {{kind: sphere, centre: [0, 0, 0], radius: 1}}{body}}}\nsample: [a]\ntime: [0, 1]\n{rest}");
        match SceneFile::parse(&text) {
            Ok(s) => s.build().err().map(|e| e.to_string()),
            Err(e) => Some(e.to_string()),
        }
    };
    assert!(scene("", "").is_none(), "the base scene builds");
    for (body, rest, want) in [
        (", velocity: [.nan, 0, 0]", "", "velocity (m/s) is .nan"),
        (", t_ref: -.inf", "", "t_ref (s) is -.inf"),
        (
            "",
            "walls: [{kind: box, min: [0, 0, 0], max: [1, -1, 1]}]\n",
            "wall 1: box min 0 ≥ max -1 m on y",
        ),
        (
            "",
            "walls: [{kind: shell, centre: [0, 0, 0], inner: 2, outer: 1}]\n",
            "need 0 ≤ inner < outer",
        ),
        (
            "",
            "walls: [{kind: box, min: [.nan, 0, 0], max: [1, 1, 1]}]\n",
            "must be finite",
        ),
        ("", "sampler: {dt: -0.5}\n", "sampler.dt is -0.5"),
        ("", "sampler: {dt: 0.1, dt: 0.2}\n", "duplicate"),
        ("", "colour: red\n", "unknown field `colour`"),
    ] {
        let e = scene(body, rest).unwrap_or_else(|| panic!("accepted: {body} {rest}"));
        assert!(e.contains(want), "{body} {rest}: {e}");
    }
    let e = SceneFile::parse("dim: 4\nbodies:\n  - {name: a, shape: {kind: sphere, centre: [0, 0, 0], radius: 1}}\nsample: [a]\ntime: [1, .nan]\n")
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("time: [1, .nan] s"), "{e}");
}

// The bundled configs and scenes pass the limits with room to spare.
#[test]
fn the_bundled_configs_and_scenes_are_well_inside_the_limits() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for dir in ["launch_configs", "scenes/implicit"] {
        for f in std::fs::read_dir(root.join(dir)).unwrap() {
            let path = f.unwrap().path();
            let text = std::fs::read_to_string(&path).unwrap();
            let s = chronotope::yaml::prescan(&text, &CONFIG_LIMITS).unwrap();
            assert!(s.depth <= 8 && s.entries < 200, "{}: {s:?}", path.display());
            if dir == "launch_configs" {
                LaunchConfig::read(&path).unwrap();
            } else {
                SceneFile::read(&path).unwrap().build().unwrap();
            }
        }
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

    // Any text made of YAML's structural characters is refused or accepted, never a panic,
    // and every refusal is short.
    #[test]
    fn yaml_shaped_noise_never_panics(text in "[\\[\\]{}:,\\- \n'\"*&#|>a-c0-9.]{0,400}") {
        for t in [format!("launch:\n{text}"), text.clone()] {
            if let Err(e) = LaunchConfig::parse(&t, "t") {
                assert_short(&e.to_string());
            }
            if let Err(e) = SceneFile::parse(&t) {
                assert_short(&e.to_string());
            }
        }
    }
}
