//! The suite live on DDS: `chronotope launch`, `play` and `record` as separate processes on a
//! private ROS domain, talking over RustDDS the way they would on a robot's network.
//!
//! Each test has its own domain id, so tests running at once do not hear each other.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use chronotope::bag::{BagReader, BagWriter};
use chronotope::cli::replay::replay;
use chronotope::msg::{Clock, Time, VoxelGrid};
use chronotope::node::launch::LaunchConfig;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A domain id for test `k` (0-3), its own in this process (see [`crate::domains`]).
fn domain(k: u32) -> String {
    crate::domains::domain(k)
}

/// A child process killed if the test fails before it ends.
struct Proc(Option<Child>, &'static str);

impl Proc {
    fn start(what: &'static str, domain: &str, args: &[&str], log: &Path) -> Self {
        let err = std::fs::File::create(log).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_chronotope"))
            .args(args)
            .env("ROS_DOMAIN_ID", domain)
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(err)
            .spawn()
            .unwrap();
        Self(Some(child), what)
    }

    fn wait(mut self, log: &Path) {
        let status = self.0.take().unwrap().wait().unwrap();
        let text = std::fs::read_to_string(log).unwrap_or_default();
        assert!(status.success(), "{} failed ({status}):\n{text}", self.1);
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(c) = &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Every message of `topic` in `bag`, serialised.
fn messages(bag: &Path, topic: &str) -> Vec<Vec<u8>> {
    BagReader::open(bag)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.topic == topic)
        .map(|m| m.data)
        .collect()
}

/// Whether two serialised messages are the same but for the up to 3 zero bytes RTPS pads a
/// payload with (a received sample keeps them; the decoder accepts them).
fn same_but_padding(live: &[u8], offline: &[u8]) -> bool {
    live.len() >= offline.len()
        && live.len() - offline.len() <= 3
        && live[..offline.len()] == *offline
        && live[offline.len()..].iter().all(|&b| b == 0)
}

#[test]
fn a_bag_played_onto_the_wire_and_checked_live_gives_the_offline_results() {
    let d = tempfile::tempdir().unwrap();
    let dom = domain(0);
    // The bundled config without the rotation suggestion: its exact search takes seconds in
    // a debug build on a loaded machine, and the launch ends after a fixed duration; the
    // translation and time scaling are compared, and the rotation is tested offline. And
    // every slab's markers even when the markers part falls behind (by default it then draws
    // only each body's newest slab, which a loaded machine makes differ from the replay's).
    let bundled = std::fs::read_to_string(root().join("launch_configs/four_spheres.yaml")).unwrap();
    let movable = "    - {name: movable, value: [/sphere_a/occupancy]}\n";
    assert!(
        bundled.contains(movable),
        "four_spheres.yaml names its movable body"
    );
    let cfg_path = d.path().join("four_spheres.yaml");
    std::fs::write(
        &cfg_path,
        bundled.replace(
            movable,
            &format!(
                "{movable}    - {{name: rotation_max_rad, value: 0.0}}\n    - {{name: markers_every_slab, value: true}}\n"
            ),
        ),
    )
    .unwrap();
    let cfg = cfg_path.to_str().unwrap();
    let bag = root().join("bags/four-spheres-32-bits.mcap");
    let rec = d.path().join("recorded.mcap");
    let summary = d.path().join("summary.json");
    let (l_log, r_log, p_log) = (
        d.path().join("launch.log"),
        d.path().join("record.log"),
        d.path().join("play.log"),
    );
    let launch = Proc::start(
        "launch",
        &dom,
        &[
            "launch",
            cfg,
            "--duration",
            "16",
            "--summary",
            summary.to_str().unwrap(),
        ],
        &l_log,
    );
    let record = Proc::start(
        "record",
        &dom,
        &[
            "record",
            "--launch",
            cfg,
            "--out",
            rec.to_str().unwrap(),
            "--duration",
            "17",
        ],
        &r_log,
    );
    // The session's input too: the frames as they were on the wire.
    let rec_in = d.path().join("recorded-frames.mcap");
    let ri_log = d.path().join("record-frames.log");
    let record_frames = Proc::start(
        "record (frames)",
        &dom,
        &[
            "record",
            "/sphere_a/occupancy",
            "/sphere_b/occupancy",
            "/sphere_c/occupancy",
            "/sphere_d/occupancy",
            "--out",
            rec_in.to_str().unwrap(),
            "--duration",
            "17",
        ],
        &ri_log,
    );
    std::thread::sleep(Duration::from_secs(2));
    let play = Proc::start(
        "play",
        &dom,
        // Readers of a volatile topic get only what is written after they match: give both
        // recorders and the launch time to discover the player's writers (a loaded CI
        // machine needs more than 2 s, and once more than 4 s).
        &["play", bag.to_str().unwrap(), "--wait", "6"],
        &p_log,
    );
    play.wait(&p_log);
    launch.wait(&l_log);
    record.wait(&r_log);
    record_frames.wait(&ri_log);

    // The same nodes offline, on the same frames.
    let config = LaunchConfig::read(&cfg_path).unwrap();
    let offline = d.path().join("offline.mcap");
    replay(&bag, Some(&config), Some(&offline), false).unwrap();

    // The recorded session, replayed offline, gives the same report as the original bag.
    let again = d.path().join("replayed-recording.mcap");
    replay(&rec_in, Some(&config), Some(&again), false).unwrap();
    for topic in [
        "/sphere_a/occupancy",
        "/sphere_b/occupancy",
        "/sphere_c/occupancy",
        "/sphere_d/occupancy",
    ] {
        assert_eq!(
            messages(&rec_in, topic),
            messages(&bag, topic),
            "{topic}: recorded frames"
        );
    }
    // A recording holds the frames in the order they were received: the four bodies' frames
    // of one instant, published together, may come in another order than the bag's, and the
    // rolling checker answers in the order frames come. So the cumulative report must end the
    // same, and the labels and suggestions must be the same messages, in any order.
    let last = |b: &Path| messages(b, "/checker/report").pop();
    assert!(last(&offline).is_some(), "no report offline");
    assert_eq!(
        last(&again),
        last(&offline),
        "/checker/report: the recording replayed offline ends otherwise than the bag replayed offline"
    );
    for topic in ["/checker/labels", "/checker/suggestions"] {
        let sorted = |b: &Path| {
            let mut v = messages(b, topic);
            v.sort();
            v
        };
        assert_eq!(
            sorted(&again),
            sorted(&offline),
            "{topic}: the recording replayed offline differs from the bag replayed offline"
        );
    }

    let live_summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let received = &live_summary["transport"]["received"];
    for body in ["a", "b", "c", "d"] {
        assert_eq!(
            received[format!("/sphere_{body}/occupancy")],
            17,
            "{live_summary}"
        );
    }
    // All streams ending together is the end of the run, not a stopped stream.
    let mesher = &live_summary["nodes"]["/mesher"];
    assert!(
        mesher["problems"].get("stream_stopped").is_none(),
        "{live_summary}"
    );
    // Results published live are byte for byte those of the replay: the final report, and
    // every label, suggestion, marker and contact message (pairs and bodies interleave in
    // the order their frames arrived, so these are compared in a canonical order; the
    // reports in between are the answer so far at moments that differ).
    let last = |v: Vec<Vec<u8>>| v.last().cloned().expect("a report");
    assert!(same_but_padding(
        &last(messages(&rec, "/checker/report")),
        &last(messages(&offline, "/checker/report"))
    ));
    // The suggestions are cumulative too (every resolution so far), published with the
    // report when new ones have come: live, one message carries those the pool finished
    // between two reports, so how many messages there are follows the pool's speed (a
    // replay takes each result at a fixed point: docs/live.md). The last one is the same.
    assert!(same_but_padding(
        &last(messages(&rec, "/checker/suggestions")),
        &last(messages(&offline, "/checker/suggestions"))
    ));
    for topic in ["/checker/labels", "/checker/markers", "/checker/contacts"] {
        let mut live = messages(&rec, topic);
        let mut off = messages(&offline, topic);
        assert!(!off.is_empty(), "{topic}: nothing offline");
        assert_eq!(live.len(), off.len(), "{topic}: message count");
        // Sorted without trailing zeros (live CDR may carry up to 3 bytes of padding).
        let trim = |m: &Vec<u8>| m[..m.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1)].to_vec();
        live.sort_by_key(trim);
        off.sort_by_key(trim);
        for (i, (l, o)) in live.iter().zip(&off).enumerate() {
            assert!(same_but_padding(l, o), "{topic}: message {i} differs");
        }
    }
}

/// The four-spheres bag with faults: /sphere_d stops after 8 of its 17 frames, and one
/// /sphere_a message is truncated. (The test also plays a wrong-type publisher beside it.)
fn faulty_bag(dir: &Path) -> PathBuf {
    let path = dir.join("faulty.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    let mut seen: BTreeMap<String, u32> = BTreeMap::new();
    let src = root().join("bags/four-spheres-32-bits.mcap");
    for m in BagReader::open(&src).unwrap().map(Result::unwrap) {
        if !seen.contains_key(&m.topic) {
            w.add_topic::<VoxelGrid>(&m.topic).unwrap();
        }
        let k = seen.entry(m.topic.clone()).or_default();
        *k += 1;
        if m.topic == "/sphere_d/occupancy" && *k > 8 {
            continue;
        }
        let data = if m.topic == "/sphere_a/occupancy" && *k == 12 {
            m.data[..m.data.len() / 2].to_vec()
        } else {
            m.data
        };
        w.write_cdr(&m.topic, m.log_time_ns, &data).unwrap();
    }
    w.finish().unwrap();
    path
}

#[test]
fn a_stream_that_stops_and_undecodable_samples_are_counted_and_the_rest_is_checked() {
    let d = tempfile::tempdir().unwrap();
    let dom = domain(1);
    let bag = faulty_bag(d.path());
    let cfg = d.path().join("cfg.yaml");
    std::fs::write(
        &cfg,
        "launch:\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: idle_timeout_s, value: 1.0}, \
           {name: bodies, value: [/sphere_a/occupancy, /sphere_b/occupancy, /sphere_c/occupancy, /sphere_d/occupancy]}]}\n\
         - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: \
           ['/sphere_a/occupancy /sphere_b/occupancy', '/sphere_a/occupancy /sphere_d/occupancy']}, \
           {name: markers, value: true}]}\n",
    )
    .unwrap();
    let summary = d.path().join("summary.json");
    let (l_log, p_log) = (d.path().join("launch.log"), d.path().join("play.log"));
    let launch = Proc::start(
        "launch",
        &dom,
        &[
            "launch",
            cfg.to_str().unwrap(),
            // Room for a slow start on a busy host (the bag is sent 6 to 12 s in).
            "--duration",
            "20",
            "--summary",
            summary.to_str().unwrap(),
        ],
        &l_log,
    );
    // A peer publishing the wrong type on one of the nodes' topics.
    let wrong = d.path().join("wrong-type.mcap");
    let mut w = BagWriter::create(&wrong).unwrap();
    w.add_topic::<Clock>("/sphere_b/occupancy").unwrap();
    for k in 0..20u64 {
        let t = 1_000_000_000 + k * 50_000_000;
        let clock = Clock {
            clock: Time::from_nanos(t as i64),
        };
        w.write("/sphere_b/occupancy", t, &clock).unwrap();
    }
    w.finish().unwrap();
    let w_log = d.path().join("play-wrong.log");
    let play_wrong = Proc::start(
        "play (wrong type)",
        &dom,
        &["play", wrong.to_str().unwrap(), "--wait", "3", "--no-clock"],
        &w_log,
    );
    std::thread::sleep(Duration::from_secs(2));
    // A fifth of real time: frames about 0.3 s apart, so /sphere_d goes quiet for more than
    // the 1 s timeout while the others go on.
    let play = Proc::start(
        "play",
        &dom,
        &[
            "play",
            bag.to_str().unwrap(),
            // Time for the launch's readers to match, as above.
            "--wait",
            "4",
            "--rate",
            "0.2",
        ],
        &p_log,
    );
    play.wait(&p_log);
    play_wrong.wait(&w_log);
    launch.wait(&l_log);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(
        s["transport"]["undecodable"]["/sphere_a/occupancy"], 1,
        "{s}"
    );
    assert_eq!(
        s["transport"]["wrong_type"]["/sphere_b/occupancy"], 1,
        "{s}"
    );
    assert!(
        s["transport"]["messages"]
            .to_string()
            .contains("/sphere_b/occupancy: a publisher writes rosgraph_msgs/msg/Clock"),
        "{s}"
    );
    // The right publisher of that topic is still read.
    assert_eq!(s["transport"]["received"]["/sphere_b/occupancy"], 17, "{s}");
    let mesher = &s["nodes"]["/mesher"];
    assert_eq!(mesher["problems"]["stream_stopped"], 1, "{s}");
    let checker = &s["nodes"]["/checker"];
    assert!(checker["published"].as_u64().unwrap() >= 1, "{s}");
    let said = checker["messages"].to_string();
    assert!(said.contains("/sphere_d/occupancy: its frames end"), "{s}");
    // No reader of the markers or the labels on the wire: neither is built.
    assert_eq!(s["nodes"]["/checker/markers"]["published"], 0, "{s}");
    assert!(
        s["transport"]["sent"].get("/checker/labels").is_none(),
        "{s}"
    );
    assert!(
        s["transport"]["sent"]["/checker/report"].as_u64() >= Some(1),
        "{s}"
    );
}

/// `chronotope param` against a running launch: the ROS parameter services read the launch's
/// parameters; the mesher's `idle_timeout_s` changes while it runs; an out-of-range value and
/// a parameter taken at start are refused with the node's reason.
#[test]
fn parameters_are_read_and_set_over_the_ros_parameter_services() {
    let d = tempfile::tempdir().unwrap();
    let dom = domain(2);
    let cfg = root().join("launch_configs/four_spheres.yaml");
    let l_log = d.path().join("launch.log");
    // Stopped below once the answers are in (a loaded machine may take a while to start
    // the launch and each client).
    let launch = Proc::start(
        "launch",
        &dom,
        &["launch", cfg.to_str().unwrap(), "--duration", "120"],
        &l_log,
    );
    // Its parameter services are up once it is in the ROS graph.
    let deadline = Instant::now() + Duration::from_secs(60);
    while !std::fs::read_to_string(&l_log)
        .unwrap_or_default()
        .contains("announced in the ROS graph")
    {
        assert!(
            Instant::now() < deadline,
            "the launch did not start within 60 s:\n{}",
            std::fs::read_to_string(&l_log).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let param = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_chronotope"))
            .arg("param")
            .args(args)
            .args(["--timeout", "8"])
            .env("ROS_DOMAIN_ID", &dom)
            .env("RUST_LOG", "warn")
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        (out.status.success(), text)
    };
    let (ok, text) = param(&["get", "/mesher", "idle_timeout_s", "bodies"]);
    assert!(ok, "{text}");
    assert!(text.contains("idle_timeout_s: Double(2.0)"), "{text}");
    assert!(text.contains("/sphere_d/occupancy"), "{text}");
    let (ok, text) = param(&["set", "/mesher", "idle_timeout_s", "0.5"]);
    assert!(ok, "{text}");
    let (ok, text) = param(&["get", "/mesher", "idle_timeout_s"]);
    assert!(ok && text.contains("idle_timeout_s: Double(0.5)"), "{text}");
    let (ok, text) = param(&["set", "/mesher", "idle_timeout_s", "-1"]);
    assert!(
        !ok && text.contains("not a number of seconds in [0.001, 1e6]"),
        "{text}"
    );
    let (ok, text) = param(&["set", "/checker", "pairs", "[a b]"]);
    assert!(!ok && text.contains("takes it at start only"), "{text}");
    // Stopped as Ctrl-C would: it finishes and exits cleanly.
    let pid = launch.0.as_ref().map(|c| c.id()).unwrap();
    // SAFETY: a signal to our own child process.
    assert_eq!(unsafe { libc::kill(pid as i32, libc::SIGTERM) }, 0);
    launch.wait(&l_log);
}

/// A large volatile output nobody on the wire reads is neither encoded nor written (counted
/// as `unread`), and one a reader subscribes to is written whole: the robot cell's launch
/// publishes its arm's and its gripper's frames; only the gripper's are recorded.
#[test]
fn frames_nobody_reads_on_the_wire_are_not_written_and_frames_read_are() {
    let d = tempfile::tempdir().unwrap();
    let dom = domain(3);
    let cfg = root().join("launch_configs/robot_cell.yaml");
    let cfg = cfg.to_str().unwrap();
    let bag = root().join("bags/robot-cell-32.mcap");
    let rec = d.path().join("gripper.mcap");
    let summary = d.path().join("summary.json");
    let (l_log, r_log, p_log) = (
        d.path().join("launch.log"),
        d.path().join("record.log"),
        d.path().join("play.log"),
    );
    let launch = Proc::start(
        "launch",
        &dom,
        &[
            "launch",
            cfg,
            "--duration",
            "14",
            "--summary",
            summary.to_str().unwrap(),
        ],
        &l_log,
    );
    let gripper = "/robot/gripper/occupancy";
    let record = Proc::start(
        "record",
        &dom,
        &[
            "record",
            gripper,
            "--out",
            rec.to_str().unwrap(),
            "--duration",
            "15",
        ],
        &r_log,
    );
    std::thread::sleep(Duration::from_secs(2));
    // Time for the launch and the recorder to discover each other and the player.
    let play = Proc::start(
        "play",
        &dom,
        &["play", bag.to_str().unwrap(), "--wait", "6"],
        &p_log,
    );
    play.wait(&p_log);
    launch.wait(&l_log);
    record.wait(&r_log);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let t = &s["transport"];
    let arm = "/robot/arm/occupancy";
    assert!(t["sent"].get(arm).is_none(), "{s}");
    assert!(t["unread"][arm].as_u64() >= Some(30), "{s}");
    let sent = t["sent"][gripper].as_u64().unwrap_or(0);
    assert!(sent >= 30, "{s}");
    assert!(t["unread"].get(gripper).is_none(), "{s}");
    let recorded = messages(&rec, gripper).len() as u64;
    assert!(
        recorded >= 1 && recorded <= sent,
        "{recorded} recorded, {sent} sent: {s}"
    );
}
