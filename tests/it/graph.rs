//! The suite in the ROS graph, as `ros2 node info` sees it: a Cyclone DDS participant
//! (tests/py/graph_peer.py) joins the domain after the nodes are up and reads what ROS 2's
//! middleware reads (`ros_discovery_info`, and the DDS builtin publications and
//! subscriptions). Every node must be listed once, with each topic it reads or writes on the
//! wire under it, of the right type and QoS, and nothing else (no hidden topic, no topic
//! passed only in memory) but ros2-client's `/rosout` and `/parameter_events`.
//!
//! Two layouts of the carving session: one `chronotope launch` (the carving node's force path
//! on a participant of its own, its display's clouds and the checker's labels and markers on
//! the bulk participant), and one process per node (the mesh pieces then on the wire).
//!
//! Needs the Python environment of `python3 tests/py/setup_env.py` (the README's test command). Without `cyclonedds` the tests are
//! skipped with a message, unless `CI` is set: then they fail.

use crate::pyenv;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use chronotope::live::graph::GID_LENGTH;
use chronotope::live::wire::TopicQos;
use chronotope::msg::{
    ContactEvent, DiagnosticArray, InterferenceReport, MeshSlab, PointCloud2, PoseStamped,
    RosMessage, TetLabels, VoxelGrid, WrenchStamped,
};
use serde_json::Value;

const CONFIG: &str = "launch_configs/carving_session.yaml";
/// What ros2-client makes for every node (and the suite does not declare).
const ROS2_CLIENT_OWN: [(&str, &str); 2] = [
    ("/rosout", "rcl_interfaces/msg/Log"),
    ("/parameter_events", "rcl_interfaces/msg/ParameterEvent"),
];

/// The reader each ros2-client node's spinner makes for simulated time; ros2-client does not
/// list it under its node, and does not say which it is.
const ROS2_CLIENT_CLOCK: &str = "reader /clock (builtin_interfaces/msg/Time)";

/// Kills (and reaps) a child process when dropped, so a failing assertion leaves nothing
/// running on the domain.
struct KillOnDrop(Option<Child>, String);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A domain id for test `k` (0-1), its own in this process (see [`crate::domains`]).
fn domain(k: u32) -> String {
    crate::domains::domain(4 + k)
}

/// `chronotope ARGS` on `domain` from the repository root (the config's cut-out images are
/// found from there), its log in `log`.
fn start(args: &[&str], domain: &str, log: &Path) -> KillOnDrop {
    let child = Command::new(env!("CARGO_BIN_EXE_chronotope"))
        .args(args)
        .current_dir(root())
        .env("ROS_DOMAIN_ID", domain)
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .expect("chronotope starts");
    KillOnDrop(Some(child), format!("chronotope {}", args.join(" ")))
}

/// Waits until every process has announced its nodes in the ROS graph.
fn wait_announced(procs: &mut [(KillOnDrop, PathBuf)]) {
    let deadline = Instant::now() + Duration::from_secs(60);
    for (p, log) in procs.iter_mut() {
        loop {
            let text = std::fs::read_to_string(&*log).unwrap_or_default();
            if text.contains("announced in the ROS graph") {
                break;
            }
            if let Some(st) = p.0.as_mut().unwrap().try_wait().unwrap() {
                panic!("{} ended ({st}) before it was up:\n{text}", p.1);
            }
            assert!(
                Instant::now() < deadline,
                "{} not up after 60 s:\n{text}",
                p.1
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// The graph as the Cyclone peer read it, joining `domain` now.
fn read_graph(domain: &str, out: &Path) -> Value {
    let status = pyenv::python()
        .arg(root().join("tests/py/graph_peer.py"))
        .arg("--out")
        .arg(out)
        .args([
            "--domain",
            domain,
            "--gid-size",
            &GID_LENGTH.to_string(),
            "--listen",
            "5",
        ])
        .status()
        .expect("the test Python runs");
    assert!(status.success(), "graph_peer.py failed ({status})");
    serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap()
}

/// What one node reads and writes on the wire: `(topic, type)`.
struct Expect {
    node: &'static str,
    publishes: Vec<(&'static str, &'static str)>,
    subscribes: Vec<(&'static str, &'static str)>,
}

fn topics(endpoints: &Value) -> BTreeSet<(String, String)> {
    endpoints
        .as_array()
        .expect("a list of endpoints")
        .iter()
        .map(|e| {
            (
                e["topic"].as_str().unwrap().to_owned(),
                e["type"].as_str().unwrap().to_owned(),
            )
        })
        .collect()
}

fn set(v: &[(&str, &str)]) -> BTreeSet<(String, String)> {
    v.iter()
        .map(|(t, ty)| ((*t).to_owned(), (*ty).to_owned()))
        .collect()
}

/// Each node of `expect` is in `graph` once, with exactly its topics (and ros2-client's own),
/// each endpoint of the suite's QoS for its type; the graph has no other node, and no endpoint
/// on a ROS topic that no node lists.
fn check(graph: &Value, expect: &[Expect]) {
    let nodes = graph["nodes"].as_object().expect("nodes");
    let names: BTreeSet<&str> = nodes.keys().map(String::as_str).collect();
    let want: BTreeSet<&str> = expect.iter().map(|e| e.node).collect();
    assert_eq!(names, want, "the nodes in the graph\n{graph:#}");
    let unclaimed: Vec<&str> = graph["unclaimed"]
        .as_array()
        .expect("unclaimed endpoints")
        .iter()
        .filter_map(Value::as_str)
        .filter(|e| *e != ROS2_CLIENT_CLOCK)
        .collect();
    assert!(
        unclaimed.is_empty(),
        "endpoints on ROS topics no node lists: {unclaimed:?}"
    );
    for e in expect {
        let n = &nodes[e.node];
        let why = || format!("{}: {n:#}", e.node);
        assert_eq!(
            n["listed_by"].as_array().map(Vec::len),
            Some(1),
            "listed by one participant; {}",
            why()
        );
        assert_eq!(
            (
                n["unresolved_writers"].as_u64(),
                n["unresolved_readers"].as_u64()
            ),
            (Some(0), Some(0)),
            "every GID listed is an endpoint on the wire; {}",
            why()
        );
        let own = set(&ROS2_CLIENT_OWN);
        let publishes = topics(&n["publishers"]);
        assert!(
            own.is_subset(&publishes),
            "ros2-client's own publishers are kept; {}",
            why()
        );
        let suite: BTreeSet<_> = publishes.difference(&own).cloned().collect();
        assert_eq!(suite, set(&e.publishes), "publishers; {}", why());
        assert_eq!(
            topics(&n["subscribers"]),
            set(&e.subscribes),
            "subscribers; {}",
            why()
        );
        for ep in n["publishers"]
            .as_array()
            .unwrap()
            .iter()
            .chain(n["subscribers"].as_array().unwrap())
        {
            let ty = ep["type"].as_str().unwrap();
            if own.iter().any(|(_, t)| t == ty) {
                continue;
            }
            let q = TopicQos::for_type(ty);
            assert_eq!(
                (ep["reliable"].as_bool(), ep["transient_local"].as_bool()),
                (Some(q.reliable), Some(q.transient_local)),
                "QoS of {ep}; {}",
                why()
            );
        }
    }
}

/// One line per participant: how many infos it sent and from how many writers.
fn say(what: &str, graph: &Value) {
    for (gid, p) in graph["participants"].as_object().unwrap() {
        eprintln!(
            "graph test ({what}): participant {gid}: {} sample(s) from {} writer(s), nodes {}",
            p["samples"], p["writers"], p["nodes"]
        );
    }
}

fn carving() -> Expect {
    Expect {
        node: "/carving",
        publishes: vec![
            ("/carving/wrench", WrenchStamped::TYPE_NAME),
            ("/carving/occupancy", VoxelGrid::TYPE_NAME),
            ("/carving/surfels", PointCloud2::TYPE_NAME),
            ("/carving/surfels_changed", PointCloud2::TYPE_NAME),
            ("/diagnostics", DiagnosticArray::TYPE_NAME),
        ],
        subscribes: vec![("/haptic/pose", PoseStamped::TYPE_NAME)],
    }
}

fn checker_publishes() -> Vec<(&'static str, &'static str)> {
    vec![
        ("/checker/report", InterferenceReport::TYPE_NAME),
        ("/checker/contacts", ContactEvent::TYPE_NAME),
        ("/checker/labels", TetLabels::TYPE_NAME),
        ("/diagnostics", DiagnosticArray::TYPE_NAME),
    ]
}

/// One `chronotope launch`: the carving node (real-time: its pose and wrench on a participant
/// of its own) with its display part (clouds and occupancy through the bulk participant), the
/// mesher and the checker. The occupancy and the mesh pieces pass in memory: no endpoint.
#[test]
fn every_node_of_a_launch_lists_its_topics_in_the_ros_graph() {
    if !pyenv::cyclone_or_skip("every_node_of_a_launch_lists_its_topics_in_the_ros_graph") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let dom = domain(0);
    let log = dir.path().join("launch.log");
    let mut procs = vec![(
        start(&["launch", CONFIG, "--duration", "60"], &dom, &log),
        log,
    )];
    wait_announced(&mut procs);
    // A late joiner: ros2-client's own info for the participant is already there, and the
    // full one must win.
    std::thread::sleep(Duration::from_secs(1));
    let graph = read_graph(&dom, &dir.path().join("graph.json"));
    say("launch", &graph);
    check(
        &graph,
        &[
            carving(),
            Expect {
                node: "/mesher",
                publishes: vec![("/diagnostics", DiagnosticArray::TYPE_NAME)],
                subscribes: vec![("/fixture/occupancy", VoxelGrid::TYPE_NAME)],
            },
            Expect {
                node: "/checker",
                publishes: checker_publishes(),
                subscribes: vec![("/fixture/occupancy", VoxelGrid::TYPE_NAME)],
            },
        ],
    );
}

/// The same nodes, one process each (`chronotope node NAME`): the mesher writes its mesh
/// pieces on the wire and the checker reads them; both read the carving node's occupancy.
#[test]
fn nodes_in_separate_processes_list_the_topics_between_them() {
    if !pyenv::cyclone_or_skip("nodes_in_separate_processes_list_the_topics_between_them") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let dom = domain(1);
    let mut procs: Vec<(KillOnDrop, PathBuf)> = ["carving", "mesher", "checker"]
        .iter()
        .map(|name| {
            let log = dir.path().join(format!("{name}.log"));
            let args = ["node", name, "--launch", CONFIG, "--duration", "60"];
            (start(&args, &dom, &log), log)
        })
        .collect();
    wait_announced(&mut procs);
    std::thread::sleep(Duration::from_secs(1));
    let graph = read_graph(&dom, &dir.path().join("graph.json"));
    say("node per process", &graph);
    let bodies = [
        ("/carving/occupancy", VoxelGrid::TYPE_NAME),
        ("/fixture/occupancy", VoxelGrid::TYPE_NAME),
    ];
    let mut checker_reads = vec![("/mesher/mesh_slabs", MeshSlab::TYPE_NAME)];
    checker_reads.extend(bodies);
    check(
        &graph,
        &[
            carving(),
            Expect {
                node: "/mesher",
                publishes: vec![
                    ("/mesher/mesh_slabs", MeshSlab::TYPE_NAME),
                    ("/diagnostics", DiagnosticArray::TYPE_NAME),
                ],
                subscribes: bodies.to_vec(),
            },
            Expect {
                node: "/checker",
                publishes: checker_publishes(),
                subscribes: checker_reads,
            },
        ],
    );
}
