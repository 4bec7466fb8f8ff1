//! The live nodes against a DDS implementation nobody here wrote: Cyclone DDS (PyPI
//! `cyclonedds`, tests/py/cyclone_peer.py) plays the frames of a bag onto the wire to
//! `chronotope launch`, and what the checker sends back over DDS must equal what the
//! offline replay of the same bag computes: the report field by field (floats bit for bit),
//! every label array (length, counts, sha256) and the markers (ids, points, sha256 of the
//! points).
//!
//! Needs the Python environment of `python3 tests/py/setup_env.py` (the README's test command). Without `cyclonedds` the test is
//! skipped with a message, unless `CI` is set: then it fails.
//!
//! Markers (16 MarkerArray of ~1.1 MB, thousands of fragments each) are the slow part: lost
//! fragments are repaired in bursts several seconds apart, so the last one arrives
//! after the last frame (measured: 5-23 s; the peer waits 30 s). `CHRONOTOPE_CYCLONE_NO_MARKERS=1`
//! leaves them out (the test then takes ~10 s).

use crate::pyenv;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use chronotope::bag::BagReader;
use chronotope::msg::{decode_cdr, ContactEvent, InterferenceReport, MarkerArray, TetLabels};
use serde_json::Value;
use sha2::{Digest, Sha256};

const BAG: &str = "bags/four-spheres-32-bits.mcap";
const LAUNCH: &str = "launch_configs/four_spheres.yaml";

/// Kills (and reaps) a child process when dropped, so a failing assertion leaves nothing
/// running on the domain.
struct KillOnDrop(Option<Child>, &'static str);

impl KillOnDrop {
    /// Stops the child now; returns whether it was still running.
    fn stop(&mut self) -> bool {
        match self.0.take() {
            Some(mut c) => {
                let running = matches!(c.try_wait(), Ok(None));
                let _ = c.kill();
                let _ = c.wait();
                running
            }
            None => false,
        }
    }
}

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if self.stop() {
            eprintln!("cyclone test: killed {}", self.1);
        }
    }
}

/// A float the peer wrote as the hex of its bits.
/// `chronotope launch CONFIG` on `domain`, stopped when dropped.
fn launch_on(config: &Path, domain: &str, duration_s: &str) -> KillOnDrop {
    KillOnDrop(
        Some(
            Command::new(env!("CARGO_BIN_EXE_chronotope"))
                .arg("launch")
                .arg(config)
                .args(["--duration", duration_s])
                .env("ROS_DOMAIN_ID", domain)
                .env("RUST_LOG", "warn")
                .stdout(Stdio::null())
                .stderr(Stdio::inherit())
                .spawn()
                .expect("chronotope launch starts"),
        ),
        "chronotope launch",
    )
}

/// `python3 tests/py/cyclone_peer.py --bag BAG --out JSON` on `domain` (15 s to match,
/// 30 s for the results after the last frame); more arguments go after these.
fn peer_command(bag: &Path, json: &Path, domain: &str) -> Command {
    let mut c = pyenv::python();
    c.arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/py/cyclone_peer.py"))
        .arg("--bag")
        .arg(bag)
        .arg("--out")
        .arg(json)
        .args([
            "--domain",
            domain,
            "--match-timeout",
            "15",
            "--timeout",
            "30",
        ])
        .env("ROS_DOMAIN_ID", domain);
    c
}

fn f(v: &Value) -> f64 {
    let s = v
        .as_str()
        .unwrap_or_else(|| panic!("float as hex bits, got {v}"));
    f64::from_bits(u64::from_str_radix(s, 16).unwrap_or_else(|e| panic!("{s:?}: {e}")))
}

fn u(v: &Value) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("unsigned integer, got {v}"))
}

fn s(v: &Value) -> &str {
    v.as_str().unwrap_or_else(|| panic!("string, got {v}"))
}

/// Exactly equal, NaN equal to NaN.
fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

#[track_caller]
fn eq_f(what: &str, live: f64, offline: f64) {
    assert!(
        same(live, offline),
        "{what}: over Cyclone {live:e} ({:#018x}), offline {offline:e} ({:#018x})",
        live.to_bits(),
        offline.to_bits()
    );
}

#[track_caller]
fn eq_fs(what: &str, live: &Value, offline: &[f64]) {
    let live: Vec<f64> = live.as_array().expect("array").iter().map(f).collect();
    assert_eq!(
        live.len(),
        offline.len(),
        "{what}: lengths {live:?} vs {offline:?}"
    );
    for (i, (a, b)) in live.iter().zip(offline).enumerate() {
        eq_f(&format!("{what}[{i}]"), *a, *b);
    }
}

/// What the offline replay published on the checker's result topics.
struct Offline {
    reports: Vec<InterferenceReport>,
    labels: Vec<TetLabels>,
    markers: Vec<MarkerArray>,
    contacts: Vec<ContactEvent>,
}

fn offline(out: &Path) -> Offline {
    let mut o = Offline {
        reports: Vec::new(),
        labels: Vec::new(),
        markers: Vec::new(),
        contacts: Vec::new(),
    };
    for m in BagReader::open(out).expect("the replay's output bag opens") {
        let m = m.expect("the replay's output bag reads");
        match m.topic.as_str() {
            "/checker/report" => o.reports.push(decode_cdr(&m.data).expect("a report")),
            "/checker/labels" => o.labels.push(decode_cdr(&m.data).expect("labels")),
            "/checker/markers" => o.markers.push(decode_cdr(&m.data).expect("markers")),
            "/checker/contacts" => o.contacts.push(decode_cdr(&m.data).expect("a contact")),
            _ => {}
        }
    }
    o
}

fn compare_report(live: &Value, r: &InterferenceReport) {
    let stamp = &live["header"]["stamp"];
    assert_eq!(
        (u(&stamp["sec"]) as i64, u(&stamp["nanosec"]) as i64),
        (
            i64::from(r.header.stamp.sec),
            i64::from(r.header.stamp.nanosec)
        ),
        "report header.stamp"
    );
    assert_eq!(
        s(&live["header"]["frame_id"]),
        r.header.frame_id,
        "report header.frame_id"
    );
    let origin = &live["time_origin"];
    assert_eq!(
        (u(&origin["sec"]) as i64, u(&origin["nanosec"]) as i64),
        (
            i64::from(r.time_origin.sec),
            i64::from(r.time_origin.nanosec)
        ),
        "report time_origin"
    );
    eq_f(
        "time_scale_m_per_s",
        f(&live["time_scale_m_per_s"]),
        r.time_scale_m_per_s,
    );
    eq_f("voxel_size_m", f(&live["voxel_size_m"]), r.voxel_size_m);

    let bodies = live["bodies"].as_array().expect("bodies");
    let ids: Vec<&str> = bodies.iter().map(|b| s(&b["body_id"])).collect();
    let off_ids: Vec<&str> = r.bodies.iter().map(|b| b.body_id.as_str()).collect();
    assert_eq!(ids, off_ids, "report bodies");
    for (l, b) in bodies.iter().zip(&r.bodies) {
        let w = |field: &str| format!("bodies[{}].{field}", b.body_id);
        assert_eq!(u(&l["frames"]), b.frames, "{}", w("frames"));
        assert_eq!(
            u(&l["skipped_frames"]),
            b.skipped_frames,
            "{}",
            w("skipped_frames")
        );
        assert_eq!(u(&l["tets"]), b.tets, "{}", w("tets"));
        assert_eq!(u(&l["vertices"]), b.vertices, "{}", w("vertices"));
        assert_eq!(l["closed"].as_bool(), Some(b.closed), "{}", w("closed"));
        eq_f(
            &w("hypervolume_m3s"),
            f(&l["hypervolume_m3s"]),
            b.hypervolume_m3s,
        );
        assert_eq!(
            u(&l["vanishing_slabs"]),
            b.vanishing_slabs,
            "{}",
            w("vanishing_slabs")
        );
    }

    let pairs = live["pairs"].as_array().expect("pairs");
    let names: Vec<(&str, &str)> = pairs
        .iter()
        .map(|p| (s(&p["body_a"]), s(&p["body_b"])))
        .collect();
    let off_names: Vec<(&str, &str)> = r
        .pairs
        .iter()
        .map(|p| (p.body_a.as_str(), p.body_b.as_str()))
        .collect();
    assert_eq!(names, off_names, "report pairs");
    for (l, p) in pairs.iter().zip(&r.pairs) {
        let w = |field: &str| format!("pairs[{} x {}].{field}", p.body_a, p.body_b);
        assert_eq!(
            l["interfering"].as_bool(),
            Some(p.interfering),
            "{}",
            w("interfering")
        );
        assert_eq!(u(&l["verdict"]), u64::from(p.verdict), "{}", w("verdict"));
        eq_fs(
            &w("unsure_start_s"),
            &l["unsure_start_s"],
            &p.unsure_start_s,
        );
        eq_fs(&w("unsure_end_s"), &l["unsure_end_s"], &p.unsure_end_s);
        eq_fs(
            &w("interval_start_s"),
            &l["interval_start_s"],
            &p.interval_start_s,
        );
        eq_fs(
            &w("interval_end_s"),
            &l["interval_end_s"],
            &p.interval_end_s,
        );
        eq_f(
            &w("first_contact_s"),
            f(&l["first_contact_s"]),
            p.first_contact_s,
        );
        eq_f(
            &w("first_contact_error_bound_s"),
            f(&l["first_contact_error_bound_s"]),
            p.first_contact_error_bound_s,
        );
        eq_f(
            &w("closing_speed_mps"),
            f(&l["closing_speed_mps"]),
            p.closing_speed_mps,
        );
        eq_f(
            &w("overlap_hypervolume_m3s"),
            f(&l["overlap_hypervolume_m3s"]),
            p.overlap_hypervolume_m3s,
        );
        eq_f(
            &w("overlap_hypervolume_error_bound_m3s"),
            f(&l["overlap_hypervolume_error_bound_m3s"]),
            p.overlap_hypervolume_error_bound_m3s,
        );
        assert_eq!(
            u(&l["a_interference"]),
            p.a_interference,
            "{}",
            w("a_interference")
        );
        assert_eq!(u(&l["a_inside"]), p.a_inside, "{}", w("a_inside"));
        assert_eq!(u(&l["a_outside"]), p.a_outside, "{}", w("a_outside"));
        assert_eq!(
            u(&l["b_interference"]),
            p.b_interference,
            "{}",
            w("b_interference")
        );
        assert_eq!(u(&l["b_inside"]), p.b_inside, "{}", w("b_inside"));
        assert_eq!(u(&l["b_outside"]), p.b_outside, "{}", w("b_outside"));
    }
}

fn compare_labels(live: &Value, offline: &[TetLabels]) {
    // Keyed by (body, other, slab): the live order is the order of arrival.
    let live: BTreeMap<(String, String, u64), &Value> = live
        .as_array()
        .expect("labels")
        .iter()
        .map(|l| {
            (
                (
                    s(&l["body_id"]).to_owned(),
                    s(&l["other_id"]).to_owned(),
                    u(&l["index"]),
                ),
                l,
            )
        })
        .collect();
    let off: BTreeMap<(String, String, u64), &TetLabels> = offline
        .iter()
        .map(|l| {
            (
                (l.body_id.clone(), l.other_id.clone(), u64::from(l.index)),
                l,
            )
        })
        .collect();
    assert_eq!(
        live.len(),
        offline.len(),
        "labels: one message per body, pair and slab"
    );
    assert_eq!(
        live.keys().collect::<Vec<_>>(),
        off.keys().collect::<Vec<_>>(),
        "labels: (body_id, other_id, index) received over Cyclone vs offline"
    );
    for (k, l) in &live {
        let o = off[k];
        let w = format!("labels {} vs {} slab {}", k.0, k.1, k.2);
        assert_eq!(
            (l["with_cap_start"].as_bool(), l["with_cap_end"].as_bool()),
            (Some(o.with_cap_start), Some(o.with_cap_end)),
            "{w}: caps"
        );
        assert_eq!(u(&l["len"]), o.labels.len() as u64, "{w}: number of labels");
        assert_eq!(u(&l["interference"]), o.interference, "{w}: interference");
        assert_eq!(u(&l["inside"]), o.inside, "{w}: inside");
        assert_eq!(u(&l["outside"]), o.outside, "{w}: outside");
        assert_eq!(
            s(&l["sha256"]),
            hex(&Sha256::digest(&o.labels)),
            "{w}: sha256 of the labels"
        );
        let stamp = &l["header"]["stamp"];
        assert_eq!(
            (u(&stamp["sec"]) as i64, u(&stamp["nanosec"]) as i64),
            (
                i64::from(o.header.stamp.sec),
                i64::from(o.header.stamp.nanosec)
            ),
            "{w}: header.stamp"
        );
    }
}

/// The same contact events, in the same order, and at least one taken by the peer while it
/// was still playing frames: contacts are published while the streams go on.
fn compare_contacts(live: &Value, offline: &[ContactEvent]) {
    let live = live.as_array().expect("contacts");
    // Per pair in order (pairs interleave in the order their frames arrived).
    let mut live: Vec<&Value> = live.iter().collect();
    live.sort_by_key(|l| (s(&l["body_a"]).to_owned(), s(&l["body_b"]).to_owned()));
    let mut offline: Vec<&ContactEvent> = offline.iter().collect();
    offline.sort_by_key(|o| (o.body_a.clone(), o.body_b.clone()));
    let brief_live: Vec<String> = live
        .iter()
        .map(|l| {
            format!(
                "{} {} {}#{}",
                s(&l["body_a"]),
                s(&l["body_b"]),
                u(&l["event"]),
                u(&l["contact_index"])
            )
        })
        .collect();
    let brief_off: Vec<String> = offline
        .iter()
        .map(|o| format!("{} {} {}#{}", o.body_a, o.body_b, o.event, o.contact_index))
        .collect();
    assert_eq!(
        brief_live, brief_off,
        "contact events over Cyclone vs offline"
    );
    for (i, (l, o)) in live.iter().zip(offline).enumerate() {
        let w = format!("contacts[{i}]");
        assert_eq!(s(&l["body_a"]), o.body_a, "{w}: body_a");
        assert_eq!(s(&l["body_b"]), o.body_b, "{w}: body_b");
        assert_eq!(u(&l["event"]), u64::from(o.event), "{w}: event");
        assert_eq!(
            u(&l["contact_index"]),
            o.contact_index,
            "{w}: contact_index"
        );
        eq_f(&format!("{w}.start_s"), f(&l["start_s"]), o.start_s);
        eq_f(&format!("{w}.end_s"), f(&l["end_s"]), o.end_s);
        eq_f(
            &format!("{w}.start_error_bound_s"),
            f(&l["start_error_bound_s"]),
            o.start_error_bound_s,
        );
        eq_f(
            &format!("{w}.overlap_hypervolume_m3s"),
            f(&l["overlap_hypervolume_m3s"]),
            o.overlap_hypervolume_m3s,
        );
    }
    let streaming = live
        .iter()
        .filter(|l| l["while_streaming"].as_bool() == Some(true))
        .count();
    assert!(
        streaming > 0,
        "no contact event arrived while the frames were being played ({} in all)",
        live.len()
    );
}

fn compare_markers(live: &Value, offline: &[MarkerArray]) {
    let live = live.as_array().expect("markers");
    assert_eq!(live.len(), offline.len(), "number of MarkerArray messages");
    // Per body in order (one array per body and slab; bodies interleave in the order their
    // frames arrived).
    let mut live: Vec<&Value> = live.iter().collect();
    live.sort_by_key(|l| s(&l["ids"][0][0]).to_owned());
    let mut offline: Vec<&MarkerArray> = offline.iter().collect();
    offline.sort_by_key(|o| o.markers.first().map(|k| k.ns.clone()));
    for (i, (l, o)) in live.iter().zip(offline).enumerate() {
        assert_eq!(
            u(&l["markers"]),
            o.markers.len() as u64,
            "markers[{i}]: markers"
        );
        let ids: Vec<(String, i64, i64, i64)> = l["ids"]
            .as_array()
            .expect("ids")
            .iter()
            .map(|k| {
                (
                    s(&k[0]).to_owned(),
                    k[1].as_i64().expect("id"),
                    k[2].as_i64().expect("type"),
                    k[3].as_i64().expect("action"),
                )
            })
            .collect();
        let off_ids: Vec<(String, i64, i64, i64)> = o
            .markers
            .iter()
            .map(|k| (k.ns.clone(), k.id.into(), k.r#type.into(), k.action.into()))
            .collect();
        assert_eq!(ids, off_ids, "markers[{i}]: ns, id, type, action");
        let mut h = Sha256::new();
        let mut points = 0u64;
        for k in &o.markers {
            for p in &k.points {
                h.update(p.x.to_le_bytes());
                h.update(p.y.to_le_bytes());
                h.update(p.z.to_le_bytes());
                points += 1;
            }
        }
        assert_eq!(u(&l["points"]), points, "markers[{i}]: points");
        assert_eq!(
            s(&l["points_sha256"]),
            hex(&h.finalize()),
            "markers[{i}]: sha256 of the points"
        );
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn live_nodes_answer_a_cyclone_peer_as_the_offline_replay_does() {
    if !pyenv::cyclone_or_skip("live_nodes_answer_a_cyclone_peer_as_the_offline_replay_does") {
        return;
    }
    let root = env!("CARGO_MANIFEST_DIR");
    let exe = env!("CARGO_BIN_EXE_chronotope");
    let bag = Path::new(root).join(BAG);
    let dir = tempfile::tempdir().unwrap();
    // The bundled config with a longer idle timeout: the Python peer decodes the markers
    // it takes while it plays (about half a second each), and a frame written more than
    // `idle_timeout_s` (2 s) after the one before would look like a stream that stopped
    // and started again. The offline replay has no clock, so the answers are the same.
    let text = std::fs::read_to_string(Path::new(root).join(LAUNCH)).unwrap();
    let bodies_line = "    - {name: bodies, value: [/sphere_a/occupancy, /sphere_b/occupancy, /sphere_c/occupancy, /sphere_d/occupancy]}\n";
    assert!(
        text.contains(bodies_line),
        "{LAUNCH} names the mesher's bodies as expected"
    );
    // And every slab's markers even when the markers part falls behind (by default it then
    // draws only each body's newest slab, which a loaded machine makes differ from the
    // offline replay's).
    let markers_line = "    - {name: markers, value: true}\n";
    assert!(text.contains(markers_line), "{LAUNCH} draws markers");
    let launch = dir.path().join("four_spheres.yaml");
    std::fs::write(
        &launch,
        text.replace(
            bodies_line,
            &format!("{bodies_line}    - {{name: idle_timeout_s, value: 10.0}}\n"),
        )
        .replace(
            markers_line,
            &format!("{markers_line}    - {{name: markers_every_slab, value: true}}\n"),
        ),
    )
    .unwrap();
    let t = Instant::now();

    // Offline first: the reference.
    let offline_bag = dir.path().join("offline.mcap");
    let out = Command::new(exe)
        .arg("replay")
        .arg(&bag)
        .arg("--launch")
        .arg(&launch)
        .arg("--out")
        .arg(&offline_bag)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "chronotope replay failed\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let off = offline(&offline_bag);
    assert!(
        !off.reports.is_empty(),
        "the offline replay publishes a report"
    );
    assert!(
        !off.contacts.is_empty(),
        "the offline replay publishes contact events"
    );
    assert!(
        !off.labels.is_empty(),
        "the offline replay publishes labels"
    );
    let t_offline = t.elapsed();

    // A domain of our own, so that parallel runs and other tests do not meet.
    let domain = crate::domains::domain(6);
    let mut launch_child = launch_on(&launch, &domain, "45");

    let json = dir.path().join("cyclone.json");
    let markers = std::env::var_os("CHRONOTOPE_CYCLONE_NO_MARKERS").is_none();
    let mut peer = peer_command(&bag, &json, &domain);
    peer.args(["--expect-labels", &off.labels.len().to_string()])
        .stdout(Stdio::inherit())
        .stderr(Stdio::inherit());
    if markers {
        // Markers (~1.1 MB each, hundreds of fragments) come last: wait for all of them.
        peer.args([
            "--markers",
            "--expect-markers",
            &off.markers.len().to_string(),
        ]);
    }
    let mut peer = KillOnDrop(
        Some(peer.spawn().expect("the test Python runs")),
        "cyclone_peer.py",
    );
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        let c = peer.0.as_mut().unwrap();
        if let Some(st) = c.try_wait().unwrap() {
            break st;
        }
        assert!(
            Instant::now() < deadline,
            "cyclone_peer.py still running after 60 s"
        );
        if let Some(st) = launch_child.0.as_mut().unwrap().try_wait().unwrap() {
            panic!("chronotope launch exited early ({st}) while the peer was running");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    peer.0 = None;
    let t_live = t.elapsed() - t_offline;
    // The nodes have answered (or not): no need to wait for --duration.
    launch_child.stop();
    assert!(
        status.success(),
        "cyclone_peer.py failed ({status}); see its message above"
    );

    let live: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(
        live["reports"].as_array().is_some_and(|r| !r.is_empty()),
        "a report over Cyclone"
    );
    // The last report is the whole answer; the ones before it are the answer so far.
    compare_report(&live["report"], off.reports.last().unwrap());
    compare_contacts(&live["contacts"], &off.contacts);
    compare_labels(&live["labels"], &off.labels);
    if markers {
        compare_markers(&live["markers"], &off.markers);
    }
    eprintln!(
        "cyclone test: domain {domain}; offline replay {:.1} s, live run {:.1} s (peer timing {}); \
         report, {} labels{} equal",
        t_offline.as_secs_f64(),
        t_live.as_secs_f64(),
        live["timing_s"],
        off.labels.len(),
        if markers {
            format!(", {} marker arrays", off.markers.len())
        } else {
            String::new()
        }
    );
}

/// The person-cell bag's point cloud, OctoMap and static transform, played with the cell's
/// frames by the Cyclone peer into `chronotope launch launch_configs/person_cell.yaml`: the
/// occupancy nodes read them from a DDS implementation nobody here wrote, and the checker's
/// final report over DDS is the offline replay's, field by field.
#[test]
fn occupancy_nodes_read_a_cyclone_peers_cloud_and_octomap_as_the_replay_does() {
    if !pyenv::cyclone_or_skip(
        "occupancy_nodes_read_a_cyclone_peers_cloud_and_octomap_as_the_replay_does",
    ) {
        return;
    }
    let root = env!("CARGO_MANIFEST_DIR");
    let exe = env!("CARGO_BIN_EXE_chronotope");
    let bag = Path::new(root).join("bags/person-cell-32.mcap");
    let dir = tempfile::tempdir().unwrap();
    // A longer idle timeout, as above: a loaded machine must not split a stream.
    let text =
        std::fs::read_to_string(Path::new(root).join("launch_configs/person_cell.yaml")).unwrap();
    let bodies = "/camera/occupancy, /map/occupancy]}\n";
    assert!(
        text.contains(bodies),
        "person_cell.yaml lists the mesher's bodies"
    );
    let launch = dir.path().join("person_cell.yaml");
    std::fs::write(
        &launch,
        text.replace(
            bodies,
            &format!("{bodies}    - {{name: idle_timeout_s, value: 10.0}}\n"),
        ),
    )
    .unwrap();
    let offline_bag = dir.path().join("offline.mcap");
    let out = Command::new(exe)
        .arg("replay")
        .arg(&bag)
        .arg("--launch")
        .arg(&launch)
        .arg("--out")
        .arg(&offline_bag)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "chronotope replay failed\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let off = offline(&offline_bag);
    let domain = crate::domains::domain(7);
    let mut launch_child = launch_on(&launch, &domain, "60");
    let json = dir.path().join("cyclone.json");
    let mut peer = peer_command(&bag, &json, &domain);
    peer.args(["--expect-labels", &off.labels.len().to_string()])
        .stdout(Stdio::inherit())
        .stderr(Stdio::inherit());
    let mut peer = KillOnDrop(
        Some(peer.spawn().expect("the test Python runs")),
        "cyclone_peer.py",
    );
    let deadline = Instant::now() + Duration::from_secs(90);
    let status = loop {
        if let Some(st) = peer.0.as_mut().unwrap().try_wait().unwrap() {
            break st;
        }
        assert!(
            Instant::now() < deadline,
            "cyclone_peer.py still running after 90 s"
        );
        if let Some(st) = launch_child.0.as_mut().unwrap().try_wait().unwrap() {
            panic!("chronotope launch exited early ({st}) while the peer was running");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    peer.0 = None;
    launch_child.stop();
    assert!(
        status.success(),
        "cyclone_peer.py failed ({status}); see its message above"
    );
    let live: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    compare_report(&live["report"], off.reports.last().unwrap());
    let pairs = live["report"]["pairs"].as_array().unwrap();
    assert!(
        pairs
            .iter()
            .any(|p| s(&p["body_a"]) == "/camera/occupancy"
                || s(&p["body_b"]) == "/camera/occupancy"),
        "the camera's person is checked live"
    );
}

/// The periodic scene (24³, 20 s at 20 Hz, a contact every 2 s) streamed by the Cyclone
/// peer with its recorded timing into `chronotope launch`: every contact begins on
/// `/checker/contacts` while the frames are still being played, and the final report holds
/// all of them. The latency from the frame that completes a contact's slab to its event is
/// printed (speed is a benchmark figure, not asserted here).
#[test]
fn periodic_contacts_are_published_while_the_stream_goes_on() {
    if !pyenv::cyclone_or_skip("periodic_contacts_are_published_while_the_stream_goes_on") {
        return;
    }
    let root = env!("CARGO_MANIFEST_DIR");
    let exe = env!("CARGO_BIN_EXE_chronotope");
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("periodic.mcap");
    let duration = 20.0;
    let out = Command::new(exe)
        .args([
            "scene",
            "periodic",
            "--grid",
            "24",
            "--duration",
            "20",
            "--out",
        ])
        .arg(&bag)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let domain = crate::domains::domain(8);
    let config = Path::new(root).join("launch_configs/periodic.yaml");
    let mut launch = launch_on(&config, &domain, "90");
    let json = dir.path().join("periodic.json");
    let status = peer_command(&bag, &json, &domain)
        .status()
        .expect("the test Python runs");
    launch.stop();
    assert!(status.success(), "cyclone_peer.py failed ({status})");
    let live: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let want = chronotope::scene::periodic_contacts(duration);
    // The final report: every contact.
    let pair = &live["report"]["pairs"][0];
    assert_eq!(
        pair["interval_start_s"].as_array().map(Vec::len),
        Some(want.len()),
        "{pair}"
    );
    // Each contact began while the stream went on (the last one may be found only after the
    // last frame, if it begins in the caps that close the streams).
    let contacts = live["contacts"].as_array().expect("contacts");
    let begun_streaming = contacts
        .iter()
        .filter(|c| u(&c["event"]) == 0 && c["while_streaming"].as_bool() == Some(true))
        .count();
    assert!(
        begun_streaming + 1 >= want.len(),
        "{begun_streaming} of {} contacts began while streaming",
        want.len()
    );
    let mut lat: Vec<f64> = contacts
        .iter()
        .filter_map(|c| c["latency_s"].as_f64())
        .collect();
    lat.sort_by(f64::total_cmp);
    if !lat.is_empty() {
        let p = |q: f64| lat[((lat.len() - 1) as f64 * q).round() as usize];
        eprintln!(
            "periodic live: {} contact events; latency from the completing frame p50 {:.3} s, \
             p99 {:.3} s, max {:.3} s (frame period 0.05 s)",
            lat.len(),
            p(0.5),
            p(0.99),
            lat[lat.len() - 1]
        );
    }
}
