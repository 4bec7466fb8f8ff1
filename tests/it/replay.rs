//! `chronotope replay` on bad input: every problem is counted in the report, nothing else is
//! lost, nothing panics.

use crate::common;

use std::path::{Path, PathBuf};

use chronotope::bag::{BagWriteOptions, BagWriter};
use chronotope::cli::replay::replay;
use chronotope::msg::{PoseStamped, Time, VoxelGrid};
use chronotope::node::launch::LaunchConfig;

/// The last report among a node's messages.
fn last_report(msgs: &[chronotope::node::Message]) -> Option<chronotope::msg::InterferenceReport> {
    msgs.iter().rev().find_map(|m| match &m.payload {
        chronotope::node::Payload::Report(r) => Some(r.as_ref().clone()),
        _ => None,
    })
}

/// A bundled bag and the text of a bundled launch config (`bags/BAG`,
/// `launch_configs/CONFIG`).
fn bundled(bag: &str, config: &str) -> (PathBuf, String) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("launch_configs").join(config)).unwrap();
    (root.join("bags").join(bag), text)
}

/// A mesher of /a and /b and a checker of the pair.
const PAIR_CONFIG: &str = "launch:\n\
    - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /b/occupancy]}]}\n\
    - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}]}\n";

/// Feeds `mesher` frame `k` of /a (moving into /b's place) and of /b (still), stamped `t_ns`.
fn feed_pair(
    mesher: &mut chronotope::node::mesher::MesherNode,
    t_ns: i64,
    k: u32,
    out: &mut Vec<chronotope::node::Message>,
) {
    use chronotope::node::{Message, Node, Payload};
    for (topic, mut g) in [("/a/occupancy", frame(0, k)), ("/b/occupancy", frame(6, 0))] {
        g.header.stamp = Time::from_nanos(t_ns);
        let m = Message::new(topic, t_ns, Payload::VoxelGrid(std::sync::Arc::new(g)));
        mesher.on_message(&m, out);
    }
}

/// A box moving +x one voxel per frame, frames at 0.1 s from 1 s.
fn frame(topic_x0: u32, k: u32) -> VoxelGrid {
    common::moving_box(topic_x0, k, 1_000_000_000)
}

/// Two bodies, /a (moving into /b's place) and /b (static), with the faults asked for.
fn faulty_bag(dir: &Path) -> PathBuf {
    let path = dir.join("faulty.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    w.add_topic::<VoxelGrid>("/b/occupancy").unwrap();
    w.add_topic::<PoseStamped>("/pose").unwrap();
    for k in 0..6u32 {
        let t = 1_000_000_000 + u64::from(k) * 100_000_000;
        // /b: frame 3 missing from the middle of the stream.
        if k != 3 {
            let mut b = frame(6, 0);
            b.header.stamp = Time::from_nanos(t as i64);
            w.write("/b/occupancy", t, &b).unwrap();
        }
        if k == 2 {
            // A truncated message on /a: does not decode.
            let bytes = chronotope::msg::encode_cdr(&frame(0, k)).unwrap();
            w.write_cdr("/a/occupancy", t, &bytes[..bytes.len() / 2])
                .unwrap();
        } else {
            w.write("/a/occupancy", t, &frame(0, k)).unwrap();
        }
        w.write("/pose", t, &PoseStamped::default()).unwrap();
    }
    w.finish().unwrap();
    path
}

#[test]
fn faults_are_counted_and_the_rest_is_checked() {
    let d = tempfile::tempdir().unwrap();
    let bag = faulty_bag(d.path());
    // The mesher is (wrongly) told /pose is a body: a topic of the wrong type.
    let cfg = LaunchConfig::parse(
        "launch:\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /b/occupancy, /pose]}]}\n\
         - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}]}\n",
        "test",
    )
    .unwrap();
    let out = d.path().join("out.mcap");
    let r = replay(&bag, Some(&cfg), Some(&out), false).unwrap();
    assert_eq!(
        r.input.undecodable.get("/a/occupancy"),
        Some(&1),
        "{:?}",
        r.input
    );
    // /pose is read by nobody once the checker's pairs leave it out: it is not meshed.
    assert_eq!(r.input.unused, 6, "{:?}", r.input);
    let mesher = &r.nodes["/mesher"];
    assert_eq!(
        mesher.problems.get("frames_missing"),
        Some(&2),
        "{mesher:?}"
    );
    // Both bodies checked: /a moves into /b.
    let p = &r.report.pairs[0];
    assert!(p.interfering, "{p:?}");
    let a = r
        .report
        .bodies
        .iter()
        .find(|b| b.id == "/a/occupancy")
        .unwrap();
    // 5 frames received, 1 undecodable, and the gap it leaves filled with one frame.
    assert_eq!((a.frames, a.skipped_frames), (6, 1));
    assert!(out.exists());
}

#[test]
fn a_frame_older_than_the_last_one_is_refused_counted_and_the_stream_goes_on() {
    let d = tempfile::tempdir().unwrap();
    let path = d.path().join("late.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    w.add_topic::<VoxelGrid>("/b/occupancy").unwrap();
    for k in 0..6u32 {
        let t = 1_000_000_000 + u64::from(k) * 100_000_000;
        w.write("/a/occupancy", t, &frame(0, k)).unwrap();
        let mut b = frame(6, 0);
        b.header.stamp = Time::from_nanos(t as i64);
        w.write("/b/occupancy", t, &b).unwrap();
        if k == 3 {
            // Frame 1 of /a again, arriving late (after frame 3).
            w.write("/a/occupancy", t + 1, &frame(0, 1)).unwrap();
        }
    }
    w.finish().unwrap();
    let cfg = LaunchConfig::parse(PAIR_CONFIG, "test").unwrap();
    let r = replay(&path, Some(&cfg), None, false).unwrap();
    let mesher = &r.nodes["/mesher"];
    assert_eq!(mesher.problems.get("frame_refused"), Some(&1), "{mesher:?}");
    assert!(
        mesher
            .messages
            .iter()
            .any(|m| m.contains("/a/occupancy: frame at 1.100 s (1100000000 ns) skipped")),
        "{mesher:?}"
    );
    assert_eq!(mesher.problems.get("frames_missing"), None, "{mesher:?}");
    let a = r
        .report
        .bodies
        .iter()
        .find(|b| b.id == "/a/occupancy")
        .unwrap();
    // Every frame in order is meshed; the late one is not.
    assert_eq!(a.frames, 6, "{a:?}");
    assert!(a.closed, "{a:?}");
    assert!(r.report.pairs[0].interfering);
}

#[test]
fn wrong_type_on_a_body_topic_is_counted() {
    let d = tempfile::tempdir().unwrap();
    let bag = faulty_bag(d.path());
    let cfg = LaunchConfig::parse(
        "launch:\n- node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /pose]}]}\n",
        "test",
    )
    .unwrap();
    let r = replay(&bag, Some(&cfg), None, false).unwrap();
    assert_eq!(r.input.wrong_type.get("/pose"), Some(&6), "{:?}", r.input);
    assert_eq!(r.nodes["/mesher"].problems.get("too_few_frames"), Some(&1));
}

#[test]
fn a_truncated_bag_replays_what_it_can_and_says_what_was_lost() {
    let d = tempfile::tempdir().unwrap();
    let whole = d.path().join("whole.mcap");
    let mut w = BagWriter::create_with(&whole, BagWriteOptions::new().chunk_size(1000)).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    w.add_topic::<VoxelGrid>("/b/occupancy").unwrap();
    for k in 0..6u32 {
        let t = 1_000_000_000 + u64::from(k) * 100_000_000;
        let mut b = frame(6, 0);
        b.header.stamp = Time::from_nanos(t as i64);
        w.write("/a/occupancy", t, &frame(0, k)).unwrap();
        w.write("/b/occupancy", t, &b).unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&whole).unwrap();
    let cut = d.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let r = replay(&cut, None, None, false).unwrap();
    assert!(!r.input.bag_errors.is_empty(), "{:?}", r.input);
    assert!(
        r.input.messages > 0 && r.input.messages <= 12,
        "{:?}",
        r.input
    );
    assert!(!r.report.bodies.is_empty());
}

#[test]
fn bad_launch_configs_are_refused_with_the_reason() {
    let d = tempfile::tempdir().unwrap();
    let bag = faulty_bag(d.path());
    for (cfg, what) in [
        (
            "launch:\n- node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}]}\n",
            "meshed by no mesher",
        ),
        (
            "launch:\n- node: {pkg: chronotope, exec: mesher}\n- node: {pkg: chronotope, exec: checker, param: [{name: movable, value: [/c]}]}\n",
            "in no checked pair",
        ),
        ("launch:\n- node: {pkg: chronotope, exec: carving}\n", "pose_topic"),
        (
            "launch:\n- node: {pkg: chronotope, exec: mesher, param: [{name: iso_percnt, value: 3}]}\n",
            "iso_percnt",
        ),
    ] {
        let c = LaunchConfig::parse(cfg, "t").unwrap();
        let e = replay(&bag, Some(&c), None, false).unwrap_err().to_string();
        assert!(e.contains(what), "{cfg}: {e}");
    }
}

/// Each body of a report: its id, frames, and whether its mesh is closed.
fn body_states(r: &chronotope::msg::InterferenceReport) -> Vec<(String, u64, bool)> {
    r.bodies
        .iter()
        .map(|b| (b.body_id.clone(), b.frames, b.closed))
        .collect()
}

/// A mesher of /a and /b (idle timeout 1 s) and a checker of the pair, as node state
/// machines driven by the test.
fn pair_nodes() -> (
    chronotope::node::mesher::MesherNode,
    chronotope::node::checker::CheckerNode,
) {
    let cfg = LaunchConfig::parse(
        "launch:\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: idle_timeout_s, value: 1.0}, {name: bodies, value: [/a/occupancy, /b/occupancy]}]}\n\
         - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}]}\n",
        "test",
    )
    .unwrap();
    let bodies = vec!["/a/occupancy".to_owned(), "/b/occupancy".to_owned()];
    (
        chronotope::node::mesher::MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap(),
        chronotope::node::checker::CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap(),
    )
}

/// A checker (re)started while the bodies' streams are under way: it says once per body that
/// it joined mid-stream, checks that stream from the first piece it sees (its mesh open
/// there), and the next one in full.
#[test]
fn a_checker_started_mid_stream_says_so_checks_from_there_and_the_next_stream_in_full() {
    use chronotope::node::mesher::MesherNode;
    use chronotope::node::{Message, Node, Payload};

    let (mut mesher, mut checker) = pair_nodes();
    // One stream of six frames per body, starting at `t0_ns`; returns what the mesher says.
    let stream = |mesher: &mut MesherNode, t0_ns: i64| {
        let mut out = Vec::new();
        for k in 0..6u32 {
            feed_pair(mesher, t0_ns + i64::from(k) * 100_000_000, k, &mut out);
            mesher.on_tick(i64::from(k) * 100_000_000, &mut out);
        }
        // Quiet for longer than the idle timeout: both streams close.
        mesher.on_tick(5 * 100_000_000 + 1_500_000_000, &mut out);
        out
    };
    let mut results = Vec::new();
    // The checker starts after the first stream's caps and first pieces went by.
    let first = stream(&mut mesher, 1_000_000_000);
    let slabs_a = |m: &Message| matches!(&m.payload, Payload::MeshSlab(_));
    let first: Vec<Message> = first.into_iter().filter(slabs_a).collect();
    assert!(first.len() > 8, "{}", first.len());
    // Pieces in order: both first caps and slabs 0, then slabs 1, 2, ... of a and b in turn.
    // Seen from b's slab 1: b from frame 1, a from frame 2.
    for m in &first[5..] {
        checker.on_message(m, &mut results);
    }
    let st = checker.status();
    assert_eq!(st.problems.get("joined_mid_stream"), Some(&2), "{st:?}");
    assert_eq!(st.problems.get("piece_out_of_order"), None, "{st:?}");
    let half = last_report(&results).expect("the half stream is checked");
    assert_eq!(
        body_states(&half),
        [
            ("/a/occupancy".to_owned(), 4, false),
            ("/b/occupancy".to_owned(), 5, false)
        ],
        "open where the pieces were missed"
    );
    results.clear();
    // The next stream is checked in full.
    let second = stream(&mut mesher, 10_000_000_000);
    for m in second.iter().filter(|m| slabs_a(m)) {
        checker.on_message(m, &mut results);
    }
    // The report is republished as the contact is found and when the streams end; the
    // last one is the answer of both streams: the contact of each (the same frames of each
    // stream meet), the frames of both runs, and open because the first run is.
    let last = &last_report(&results).expect("a report for the second stream");
    let pair = &last.pairs[0];
    assert!(pair.interfering);
    let intervals: Vec<(f64, f64)> = pair
        .interval_start_s
        .iter()
        .zip(&pair.interval_end_s)
        .map(|(a, b)| ((a * 1e3).round() / 1e3, (b * 1e3).round() / 1e3))
        .collect();
    assert_eq!(intervals, [(0.2, 0.4), (9.2, 9.4)], "{last:?}");
    let frames: Vec<(u64, bool)> = last.bodies.iter().map(|b| (b.frames, b.closed)).collect();
    assert_eq!(frames, [(4 + 6, false), (5 + 6, false)], "{last:?}");
    let st = checker.status();
    assert_eq!(st.problems.get("joined_mid_stream"), Some(&2), "{st:?}");
    assert_eq!(st.problems.get("check_failed"), None, "{st:?}");
}

/// Pieces lost between the mesher and the checker (a node that was behind): the checker says
/// which, checks the stream again from the next piece (the mesh open at the gap), and finds
/// the contact after it as with every piece.
#[test]
fn pieces_lost_inside_a_stream_are_said_and_the_stream_is_checked_again_after_them() {
    use chronotope::msg::MeshSlab;
    use chronotope::node::checker::CheckerNode;
    use chronotope::node::mesher::MesherNode;
    use chronotope::node::{Node, Payload};

    let cfg = LaunchConfig::parse(PAIR_CONFIG, "test").unwrap();
    let bodies = vec!["/a/occupancy".to_owned(), "/b/occupancy".to_owned()];
    let run = |lose: Option<u32>| {
        let mut mesher = MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap();
        let mut checker = CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap();
        let mut pieces = Vec::new();
        for k in 0..6u32 {
            feed_pair(
                &mut mesher,
                1_000_000_000 + i64::from(k) * 100_000_000,
                k,
                &mut pieces,
            );
        }
        mesher.finish(&mut pieces);
        let mut results = Vec::new();
        for m in &pieces {
            let lost = matches!(&m.payload, Payload::MeshSlab(p)
                if p.body_id == "/a/occupancy"
                    && p.kind == MeshSlab::KIND_LATERAL
                    && Some(p.index) == lose);
            if !lost {
                checker.on_message(m, &mut results);
            }
        }
        checker.finish(&mut results);
        let report = last_report(&results).expect("a report");
        (report, checker.status().clone())
    };
    let (all, st) = run(None);
    assert_eq!(st.problems.get("pieces_missing"), None, "{st:?}");
    let (lost, st) = run(Some(1));
    assert_eq!(st.problems.get("pieces_missing"), Some(&1), "{st:?}");
    assert!(
        st.messages
            .iter()
            .any(|m| m.contains("pieces 1 to 1 missing")),
        "{st:?}"
    );
    // The same contact, a mesh open at the gap, every frame counted (slab 1 is lost, not its
    // frames: frames 0-1 in the first run, 2-5 in the second).
    assert!(all.pairs[0].interfering);
    assert_eq!(
        lost.pairs[0].interval_start_s,
        all.pairs[0].interval_start_s
    );
    assert_eq!(lost.pairs[0].interval_end_s, all.pairs[0].interval_end_s);
    assert!(all.bodies[0].closed && !lost.bodies[0].closed, "{lost:?}");
    assert_eq!(lost.bodies[0].frames, 2 + 4);
    assert_eq!(lost.bodies[1], all.bodies[1]);
}

/// A body whose caps are over `max_slab_tets` but whose slabs are not (a solid block: its
/// caps fill its volume, its slabs only its surface): the caps go out without tets, the
/// mesher says so, and the checker checks the body from its first slab, reported open.
#[test]
fn caps_over_the_slab_budget_leave_the_mesh_open_and_the_body_checked() {
    use chronotope::msg::MeshSlab;
    use chronotope::node::checker::CheckerNode;
    use chronotope::node::mesher::MesherNode;
    use chronotope::node::{Message, Node, Payload};
    use std::sync::Arc;

    let block = |k: i64| {
        let data = common::bits_data([12; 3], |x, y, z| {
            (1..11).contains(&x) && (1..11).contains(&y) && (1..11).contains(&z)
        });
        common::cube_grid(12, 1_000_000_000 + k * 100_000_000, data)
    };
    let run = |max_slab_tets: Option<usize>| {
        let limit = max_slab_tets.map_or(String::new(), |n| {
            format!(", {{name: max_slab_tets, value: {n}}}")
        });
        let cfg = LaunchConfig::parse(
            &format!(
                "launch:\n\
                 - node: {{pkg: chronotope, exec: mesher, param: [{{name: bodies, value: [/a/occupancy]}}{limit}]}}\n\
                 - node: {{pkg: chronotope, exec: checker, param: [{{name: labels, value: false}}{limit}]}}\n"
            ),
            "test",
        )
        .unwrap();
        let bodies = vec!["/a/occupancy".to_owned()];
        let mut mesher = MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap();
        let mut checker = CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap();
        let mut pieces = Vec::new();
        for k in 0..4 {
            let m = Message::new("/a/occupancy", 0, Payload::VoxelGrid(Arc::new(block(k))));
            mesher.on_message(&m, &mut pieces);
        }
        mesher.finish(&mut pieces);
        let mut results = Vec::new();
        for m in &pieces {
            checker.on_message(m, &mut results);
        }
        checker.finish(&mut results);
        let tets: Vec<(u8, usize)> = pieces
            .iter()
            .filter_map(|m| match &m.payload {
                Payload::MeshSlab(p) => Some((p.kind, p.mesh.tets.len())),
                _ => None,
            })
            .collect();
        let report = last_report(&results).expect("a report");
        (tets, report, mesher.status().clone())
    };
    let (tets, all, _) = run(None);
    let lateral = |t: &[(u8, usize)]| -> Vec<usize> {
        t.iter()
            .filter(|p| p.0 == MeshSlab::KIND_LATERAL)
            .map(|p| p.1)
            .collect()
    };
    let widest = *lateral(&tets).iter().max().unwrap();
    let cap = tets[0].1;
    assert!(
        cap > widest,
        "cap {cap}, slabs {widest}: no budget between them"
    );
    assert!(all.bodies[0].closed && all.bodies[0].frames == 4);

    let (tets2, open, st) = run(Some(widest));
    assert_eq!(st.problems.get("cap_too_complex"), Some(&2), "{st:?}");
    let caps: Vec<(u8, usize)> = tets2
        .iter()
        .copied()
        .filter(|p| p.0 != MeshSlab::KIND_LATERAL)
        .collect();
    assert_eq!(
        caps,
        [(MeshSlab::KIND_CAP_START, 0), (MeshSlab::KIND_CAP_END, 0)]
    );
    assert_eq!(lateral(&tets2), lateral(&tets));
    let b = &open.bodies[0];
    assert_eq!((b.frames, b.closed), (4, false), "{open:?}");
    assert_eq!(
        b.tets as usize,
        lateral(&tets).iter().sum::<usize>(),
        "the slabs, no cap"
    );
}

/// The mesher's idle timeout changed while it runs takes effect at the next tick; other
/// parameters and bad values are refused with the reason.
#[test]
fn the_mesher_idle_timeout_changes_while_it_runs() {
    use chronotope::node::launch::ParamValue;
    use chronotope::node::mesher::MesherNode;
    use chronotope::node::{Message, Node, Payload};
    use std::sync::Arc;

    let cfg = LaunchConfig::parse(
        "launch:\n- node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy]}]}\n",
        "test",
    )
    .unwrap();
    let mut m = MesherNode::from_spec(&cfg.nodes[0], &["/a/occupancy".to_owned()]).unwrap();
    assert_eq!(
        m.runtime_parameters(),
        vec![("idle_timeout_s".to_owned(), ParamValue::Double(2.0))]
    );
    let mut out = Vec::new();
    for k in 0..3u32 {
        let g = frame(0, k);
        let t = g.header.stamp.as_nanos();
        m.on_message(
            &Message::new("/a/occupancy", t, Payload::VoxelGrid(Arc::new(g))),
            &mut out,
        );
        m.on_tick(i64::from(k) * 100_000_000, &mut out);
    }
    let caps = |out: &[Message]| {
        out.iter()
            .filter(|m| matches!(&m.payload, Payload::MeshSlab(s) if s.kind == chronotope::msg::MeshSlab::KIND_CAP_END))
            .count()
    };
    m.on_tick(1_000_000_000, &mut out);
    assert_eq!(caps(&out), 0, "0.8 s quiet < 2 s");
    assert!(m
        .set_parameter("idle_timeout_s", &ParamValue::Double(0.5))
        .is_ok());
    m.on_tick(1_100_000_000, &mut out);
    assert_eq!(caps(&out), 1, "0.9 s quiet > 0.5 s: closed");
    let e = m
        .set_parameter("idle_timeout_s", &ParamValue::Double(-1.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("[0.001, 1e6]"), "{e}");
    let e = m
        .set_parameter("bodies", &ParamValue::StringArray(vec![]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("at start only"), "{e}");
}

#[test]
fn a_pose_topic_routed_onto_a_body_topic_is_refused_with_the_reason() {
    let d = tempfile::tempdir().unwrap();
    let path = d.path().join("fixture.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    w.add_topic::<VoxelGrid>("/fixture/occupancy").unwrap();
    for k in 0..3u32 {
        let f = frame(0, k);
        w.write("/fixture/occupancy", f.header.stamp.as_nanos() as u64, &f)
            .unwrap();
    }
    w.finish().unwrap();
    let cfg = LaunchConfig::parse(
        "launch:\n\
         - node: {pkg: chronotope, exec: carving, param: [{name: pose_topic, value: /fixture/occupancy}]}\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/carving/occupancy, /fixture/occupancy]}]}\n\
         - node: {pkg: chronotope, exec: checker}\n",
        "test",
    )
    .unwrap();
    let e = replay(&path, Some(&cfg), None, false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("two message types") && e.contains("pose_topic"),
        "{e}"
    );
}

/// The report is republished when a body's stream ends, not only when a contact changes:
/// a live reader of `~/report` sees each body closed with all its frames while the launch
/// goes on (here nothing ever touches, so no contact would republish it).
#[test]
fn the_report_is_republished_when_the_streams_end_without_any_contact() {
    use chronotope::node::{Message, Node, Payload};

    let (mut mesher, mut checker) = pair_nodes();
    let t0 = 1_000_000_000;
    let mut pieces = Vec::new();
    for k in 0..6u32 {
        // /a moves along x at y 0..4; /b stays at y 8..12: never within a voxel of /a.
        for (topic, g) in [
            ("/a/occupancy", common::box_frame(0, 1, 0, k, t0)),
            ("/b/occupancy", common::box_frame(0, 0, 8, k, t0)),
        ] {
            let m = Message::new(
                topic,
                g.header.stamp.as_nanos(),
                Payload::VoxelGrid(std::sync::Arc::new(g)),
            );
            mesher.on_message(&m, &mut pieces);
        }
        mesher.on_tick(i64::from(k) * 100_000_000, &mut pieces);
    }
    // Quiet for longer than the idle timeout: the mesher closes both streams (their last
    // caps); the checker is never told to finish.
    mesher.on_tick(5 * 100_000_000 + 1_500_000_000, &mut pieces);
    let mut results = Vec::new();
    for m in pieces
        .iter()
        .filter(|m| matches!(m.payload, Payload::MeshSlab(_)))
    {
        checker.on_message(m, &mut results);
    }
    let last = last_report(&results).expect("a report once the streams have ended");
    assert_eq!(
        body_states(&last),
        [
            ("/a/occupancy".to_owned(), 6, true),
            ("/b/occupancy".to_owned(), 6, true)
        ],
        "{last:?}"
    );
    assert!(!last.pairs[0].interfering, "{last:?}");
}

/// What nothing reads is not built: without an output bag the checker makes neither its
/// markers nor its labels nor its reports on the way (only the last), and its answers are
/// those of the replay that records them; an output bag that leaves the markers out gets
/// the labels and no markers built.
#[test]
fn a_replay_builds_no_markers_or_labels_that_nothing_reads() {
    let d = tempfile::tempdir().unwrap();
    let (bag, cfg_text) = bundled("four-spheres-32-bits.mcap", "four_spheres.yaml");
    let cfg = LaunchConfig::parse(&cfg_text, "four_spheres.yaml").unwrap();
    let all = d.path().join("all.mcap");
    let recorded = replay(&bag, Some(&cfg), Some(&all), false).unwrap();
    let unread = replay(&bag, Some(&cfg), None, false).unwrap();
    let markers = |r: &chronotope::cli::replay::ReplayReport| r.nodes["/checker/markers"].published;
    assert!(
        recorded.output.topics["/checker/markers"] > 0,
        "{:?}",
        recorded.output
    );
    assert!(
        recorded.output.topics["/checker/labels"] > 0,
        "{:?}",
        recorded.output
    );
    assert_eq!(
        markers(&recorded),
        recorded.output.topics["/checker/markers"]
    );
    assert_eq!(markers(&unread), 0, "markers built for nobody");
    // The checker published its contacts and its last report only (with the suggestions,
    // if any): no labels, and no report on the way, which nothing read either.
    let suggested = recorded.output.topics.contains_key("/checker/suggestions");
    assert!(recorded.output.topics["/checker/report"] > 1);
    let contacts_and_answer =
        recorded.output.topics["/checker/contacts"] + 1 + u64::from(suggested);
    assert_eq!(unread.nodes["/checker"].published, contacts_and_answer);
    let answer = |r: &chronotope::cli::replay::ReplayReport| {
        serde_json::to_value((&r.report.bodies, &r.report.pairs, &r.report.resolutions)).unwrap()
    };
    assert_eq!(answer(&unread), answer(&recorded));

    // A recorder that leaves the markers out.
    let no_markers = LaunchConfig::parse(
        &format!(
            "{cfg_text}\n- node: {{pkg: chronotope, exec: recorder, param: [{{name: exclude, value: [/checker/markers]}}]}}\n"
        ),
        "four_spheres.yaml with a recorder",
    )
    .unwrap();
    let some = d.path().join("some.mcap");
    let partial = replay(&bag, Some(&no_markers), Some(&some), false).unwrap();
    assert_eq!(markers(&partial), 0, "markers built for nobody");
    assert!(!partial.output.topics.contains_key("/checker/markers"));
    assert_eq!(
        partial.output.topics["/checker/labels"],
        recorded.output.topics["/checker/labels"]
    );
    assert_eq!(answer(&partial), answer(&recorded));
}

/// What the checker's markers show of a body is the body at a frame it recorded: each id-0
/// triangle list (the body's slice, flat faces merged) encloses the volume of the frame at
/// its stamp, as the mesher's 3D marching of that frame (the cap it would close the stream
/// with there) has it, for the moving spindle and the table and fixture (at rest between
/// steps).
#[test]
fn the_markers_show_each_body_as_the_frame_at_their_stamp() {
    use chronotope::mesh::{CapSide, Mesher, MesherOptions};
    use chronotope::msg::{decode_cdr, Marker, MarkerArray};
    let d = tempfile::tempdir().unwrap();
    let (bag, cfg_text) = bundled("machine-tool-32-bits.mcap", "machine_tool.yaml");
    let cfg = LaunchConfig::parse(&cfg_text, "machine_tool.yaml").unwrap();
    let out = d.path().join("out.mcap");
    replay(&bag, Some(&cfg), Some(&out), false).unwrap();
    // Each body's frames by stamp, with the volume its 3D marching encloses (m³).
    let mut volume: std::collections::BTreeMap<(String, i64), f64> = Default::default();
    for m in chronotope::bag::BagReader::open(&bag).unwrap() {
        let m = m.unwrap();
        let Ok(g) = decode_cdr::<VoxelGrid>(&m.data) else {
            continue;
        };
        let mut mesher = Mesher::new(MesherOptions::default()).unwrap();
        mesher.push(&g.frame_ref()).unwrap();
        let step = mesher.geometry().unwrap().step_m();
        let cap = mesher
            .cap(mesher.last_frame().unwrap(), CapSide::High)
            .unwrap();
        let sixfold: i128 = cap
            .tets
            .iter()
            .map(|t| {
                let p = t.map(|v| cap.vertices[v as usize].map(i128::from));
                let e = |k: usize| [0, 1, 2].map(|c| p[k][c] - p[0][c]);
                let (a, b, c) = (e(1), e(2), e(3));
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    .abs()
            })
            .sum();
        let v = sixfold as f64 / 6.0 * step.powi(3);
        volume.insert((m.topic.clone(), g.header.stamp.as_nanos()), v);
    }
    let mut seen = std::collections::BTreeSet::new();
    for m in chronotope::bag::BagReader::open(&out).unwrap() {
        let m = m.unwrap();
        if m.topic != "/checker/markers" {
            continue;
        }
        let a: MarkerArray = decode_cdr(&m.data).unwrap();
        for mk in a.markers.iter().filter(|mk| mk.id == 0) {
            let key = (mk.ns.clone(), mk.header.stamp.as_nanos());
            let want = *volume
                .get(&key)
                .unwrap_or_else(|| panic!("{key:?}: no frame of that body at that stamp"));
            let got = if mk.action == Marker::DELETE {
                0.0
            } else {
                // Enclosed volume by the divergence theorem (the surface is closed).
                mk.points
                    .chunks_exact(3)
                    .map(|t| {
                        let (p, q, r) = (&t[0], &t[1], &t[2]);
                        p.x * (q.y * r.z - q.z * r.y) - p.y * (q.x * r.z - q.z * r.x)
                            + p.z * (q.x * r.y - q.y * r.x)
                    })
                    .sum::<f64>()
                    / 6.0
            };
            assert!(
                (got - want).abs() <= 1e-9 * want.max(1e-6),
                "{key:?}: the marker encloses {got} m³, the frame {want} m³"
            );
            seen.insert(mk.ns.clone());
        }
    }
    assert_eq!(seen.len(), 3, "every body drawn: {seen:?}");
}

/// `markers_period_s` is a display rate: a body's slab starting less than that after the
/// last one sliced gets no markers, decided on the stamps; labels, contacts and the report
/// are those of every slab.
#[test]
fn the_markers_period_slices_one_slab_in_so_many_per_body() {
    let d = tempfile::tempdir().unwrap();
    let (bag, cfg_text) = bundled("machine-tool-32-bits.mcap", "machine_tool.yaml");
    let every = LaunchConfig::parse(&cfg_text, "machine_tool.yaml").unwrap();
    let line = "    - {name: markers, value: true}\n";
    assert!(cfg_text.contains(line));
    // Frames are 0.1 s apart: 0.3 s slices slabs 0, 3, 6, … of each body; 0.25 s the same.
    let with = |period: &str| {
        let text = cfg_text.replace(
            line,
            &format!("{line}    - {{name: markers_period_s, value: {period}}}\n"),
        );
        LaunchConfig::parse(&text, "machine_tool.yaml with a markers period").unwrap()
    };
    let run = |cfg: &LaunchConfig, name: &str| {
        replay(&bag, Some(cfg), Some(&d.path().join(name)), false).unwrap()
    };
    let all = run(&every, "all.mcap");
    let slabs_per_body = all.report.bodies[0].frames - 1;
    let bodies = all.report.bodies.len() as u64;
    // Markers are kept until replaced: a body is drawn again only where its slice or its
    // labels changed, so at most one marker array per body and slab.
    let drawn = all.output.topics["/checker/markers"];
    assert!(drawn > 0 && drawn <= bodies * slabs_per_body, "{drawn}");
    // The slabs each marker array draws, by its stamp (the slab's later frame).
    let first_frame = all.report.time_origin_ns;
    let slabs_drawn = |name: &str| -> Vec<i64> {
        let mut ks = Vec::new();
        for m in chronotope::bag::BagReader::open(d.path().join(name)).unwrap() {
            let m = m.unwrap();
            if m.topic != "/checker/markers" {
                continue;
            }
            let a: chronotope::msg::MarkerArray = chronotope::msg::decode_cdr(&m.data).unwrap();
            for mk in a.markers {
                let t = mk.header.stamp.as_nanos() - first_frame - 100_000_000;
                assert_eq!(t % 100_000_000, 0, "a marker at a slab's later frame");
                ks.push(t / 100_000_000);
            }
        }
        ks
    };
    // The spindle moves all the time: drawn at every slab.
    assert_eq!(
        slabs_drawn("all.mcap")
            .iter()
            .copied()
            .collect::<std::collections::BTreeSet<_>>()
            .len() as u64,
        slabs_per_body
    );
    for period in ["0.3", "0.25"] {
        let some = run(&with(period), "some.mcap");
        let ks = slabs_drawn("some.mcap");
        assert!(!ks.is_empty());
        assert!(ks.iter().all(|k| k % 3 == 0), "{period} s: slabs {ks:?}");
        assert_eq!(
            some.output.topics["/checker/labels"],
            all.output.topics["/checker/labels"]
        );
        let answer = |r: &chronotope::cli::replay::ReplayReport| {
            serde_json::to_value((&r.report.bodies, &r.report.pairs, &r.report.resolutions))
                .unwrap()
        };
        assert_eq!(answer(&some), answer(&all));
    }
}

/// An unsure span that ends while the streams go on is said over by the period that finds it
/// over, stamped with that period's later frame (as a contact's end is): one frame after the
/// span's last. The bundled person cell's OctoMap, at half the cell's rate, gives such spans.
#[test]
fn an_unsure_span_s_end_is_stamped_with_the_period_that_found_it_over() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let d = tempfile::tempdir().unwrap();
    let config = LaunchConfig::read(&root.join("launch_configs/person_cell.yaml")).unwrap();
    let out = d.path().join("out.mcap");
    replay(
        &root.join("bags/person-cell-32.mcap"),
        Some(&config),
        Some(&out),
        false,
    )
    .unwrap();
    let ns = |t: &Time| i64::from(t.sec) * 1_000_000_000 + i64::from(t.nanosec);
    let since = |e: &chronotope::msg::ContactEvent| {
        (ns(&e.header.stamp) - ns(&e.time_origin)) as f64 * 1e-9
    };
    let (mut ended_early, mut last_s) = (0, f64::MIN);
    let mut events = Vec::new();
    for m in chronotope::bag::BagReader::open(&out).unwrap() {
        let m = m.unwrap();
        if m.topic == "/checker/contacts" {
            let e: chronotope::msg::ContactEvent = chronotope::msg::decode_cdr(&m.data).unwrap();
            last_s = last_s.max(since(&e));
            events.push(e);
        }
    }
    for e in &events {
        let at_s = since(e);
        assert!(at_s >= e.end_s - 1e-6, "{at_s} {e:?}");
        if e.event == chronotope::msg::ContactEvent::UNSURE_END && e.end_s < last_s - 1e-6 {
            assert!(
                at_s > e.end_s + 1e-6,
                "said at its last frame: {at_s} {e:?}"
            );
            ended_early += 1;
        }
    }
    assert!(
        ended_early > 0,
        "no span ended before the streams did: {events:?}"
    );
}

/// A 24³ bag at 1 cm voxels: `/arm/occupancy` is a resting base with a 1-voxel-thin blade that
/// jumps 6 voxels along x each frame (x = 1, 7, 13, 19, 1, ...: it vanishes between frames
/// and, from x = 13 to 19, passes through where `/post/occupancy`, a still plate at x = 16,
/// stands without touching it in any frame); `/far/occupancy` rests far from both. Frames at 10 Hz; with `gap`, `/far` misses
/// frames 3 to 5.
fn blade_bag(dir: &Path, gap: bool) -> PathBuf {
    let path = dir.join(if gap { "blade-gap.mcap" } else { "blade.mcap" });
    let mut w = BagWriter::create(&path).unwrap();
    for t in ["/arm/occupancy", "/post/occupancy", "/far/occupancy"] {
        w.add_topic::<VoxelGrid>(t).unwrap();
    }
    for k in 0..8u32 {
        let t = 1_000_000_000 + i64::from(k) * 100_000_000;
        let x = 1 + 6 * (k as usize % 4);
        let arm = common::bits_data([24; 3], |px, py, pz| {
            let base = px < 3 && py < 3 && pz < 3;
            let blade = px == x && (10..14).contains(&py) && (10..14).contains(&pz);
            base || blade
        });
        let post = common::bits_data([24; 3], |px, py, pz| {
            px == 16 && (10..14).contains(&py) && (10..14).contains(&pz)
        });
        let far = common::bits_data([24; 3], |px, py, pz| px > 20 && py > 20 && pz < 3);
        w.write("/arm/occupancy", t as u64, &common::cube_grid(24, t, arm))
            .unwrap();
        w.write("/post/occupancy", t as u64, &common::cube_grid(24, t, post))
            .unwrap();
        if !(gap && (3..6).contains(&k)) {
            w.write("/far/occupancy", t as u64, &common::cube_grid(24, t, far))
                .unwrap();
        }
    }
    w.finish().unwrap();
    path
}

#[test]
fn a_pair_is_called_clear_only_where_both_bodies_are_observed() {
    use chronotope::checker::report::Verdict;
    let d = tempfile::tempdir().unwrap();
    let bag = blade_bag(d.path(), false);
    let config = LaunchConfig::parse(
        "launch:\n- node: {pkg: chronotope, exec: mesher}\n- node: {pkg: chronotope, exec: checker}\n- node: {pkg: chronotope, exec: recorder}\n",
        "test",
    )
    .unwrap();
    let out = d.path().join("out.mcap");
    let r = replay(&bag, Some(&config), Some(&out), false).unwrap();
    let pair = |a: &str, b: &str| {
        r.report
            .pairs
            .iter()
            .find(|p| p.a == a && p.b == b)
            .unwrap_or_else(|| panic!("{a} x {b}"))
            .clone()
    };
    // The blade passes through the post between frames: no contact is seen, but the pair is
    // not clear.
    let ap = pair("/arm/occupancy", "/post/occupancy");
    assert!(!ap.interfering);
    assert_eq!(ap.verdict, Verdict::Unsure, "{:?}", ap.unsure_spans_s);
    let span = &ap.unsure_spans_s[0];
    assert_eq!(span.body, "/arm/occupancy");
    assert_eq!(span.code, "vanishes");
    assert!(span.resolve.contains("Hz"), "{}", span.resolve);
    assert!(
        span.span_s[0] <= 0.2 + 1e-9 && span.span_s[1] >= 0.3 - 1e-9,
        "{span:?}"
    );
    // The same verdict for every pair with the arm, and clear where both are observed.
    assert_eq!(
        pair("/arm/occupancy", "/far/occupancy").verdict,
        Verdict::Unsure
    );
    assert_eq!(
        pair("/far/occupancy", "/post/occupancy").verdict,
        Verdict::Clear
    );
    // `check` says the same.
    let c = chronotope::cli::check::check_bag(&bag, Default::default(), None).unwrap();
    for p in &c.report.pairs {
        let rp = pair(&p.a, &p.b);
        assert_eq!(p.verdict, rp.verdict, "{} x {}", p.a, p.b);
        assert_eq!(p.unsure_spans_s, rp.unsure_spans_s, "{} x {}", p.a, p.b);
    }
    // The contact events say when the unsure span begins and ends.
    let mut events = Vec::new();
    for m in chronotope::bag::BagReader::open(&out).unwrap() {
        let m = m.unwrap();
        if m.topic == "/checker/contacts" {
            let e: chronotope::msg::ContactEvent = chronotope::msg::decode_cdr(&m.data).unwrap();
            if e.body_a == "/arm/occupancy" && e.body_b == "/post/occupancy" {
                let stamp_s =
                    f64::from(e.header.stamp.sec) + f64::from(e.header.stamp.nanosec) * 1e-9;
                let origin_s =
                    f64::from(e.time_origin.sec) + f64::from(e.time_origin.nanosec) * 1e-9;
                // Stamped with the later frame of the period that found it: here the span
                // goes on to the streams' end (the last frame, 0.7 s).
                assert!((stamp_s - origin_s - e.end_s).abs() < 1e-6, "{e:?}");
                events.push((e.event, e.unsure_reason));
            }
        }
    }
    let kinds: Vec<u8> = events.iter().map(|e| e.0).collect();
    assert!(
        kinds.starts_with(&[
            chronotope::msg::ContactEvent::UNSURE_BEGIN,
            chronotope::msg::ContactEvent::UNSURE_END
        ]),
        "{events:?}"
    );
    assert!(
        events[0].1.contains("/arm/occupancy: vanishes"),
        "{events:?}"
    );
    // A summary that never says clear for such a pair.
    let text = chronotope::cli::replay::summary(&r, &bag);
    assert!(
        text.contains("UNSURE   /arm/occupancy x /post/occupancy"),
        "{text}"
    );
    assert!(!text.contains("clear    /arm/occupancy"), "{text}");

    // Missing frames of /far: pairs with it are unsure over the gap, even the still post.
    let bag = blade_bag(d.path(), true);
    let r = replay(&bag, None, None, false).unwrap();
    let fp = r
        .report
        .pairs
        .iter()
        .find(|p| p.a == "/far/occupancy" && p.b == "/post/occupancy")
        .unwrap();
    assert_eq!(fp.verdict, Verdict::Unsure, "{:?}", fp.unsure_spans_s);
    assert!(
        fp.unsure_spans_s.iter().any(|u| u.code == "frames_filled"),
        "{:?}",
        fp.unsure_spans_s
    );
}

/// The checker's `rotation_axis`, `rotation_point` and `rotation_max_rad` reach its
/// rotation suggestion: the spindle of the machine-tool cell turned about a horizontal axis
/// through its head swings its tool clear of the workpiece and the fixture, verified; within
/// a limit too small nothing clears and the report says so; an axis without a direction is
/// refused.
#[test]
fn the_rotation_parameters_reach_the_rotation_suggestion() {
    let d = tempfile::tempdir().unwrap();
    let (bag, cfg_text) = bundled("machine-tool-32-bits.mcap", "machine_tool.yaml");
    let line = "    - {name: markers, value: true}\n";
    assert!(cfg_text.contains(line));
    let with = |params: &str| {
        let text = cfg_text.replace(
            line,
            &format!("    - {{name: markers, value: false}}\n{params}"),
        );
        LaunchConfig::parse(&text, "machine_tool.yaml with a rotation").unwrap()
    };
    let axis = "    - {name: rotation_axis, value: [1.0, 0.0, 0.0]}\n    - {name: rotation_point, value: [0.44, 0.64, 1.0]}\n";
    let rotations = |cfg: &LaunchConfig| {
        let r = replay(&bag, Some(cfg), None, false).unwrap();
        let j = serde_json::to_value(&r.report.resolutions).unwrap();
        j.as_array()
            .unwrap()
            .iter()
            .filter(|x| x["kind"] == "rotate")
            .cloned()
            .collect::<Vec<_>>()
    };
    let found = rotations(&with(axis));
    assert_eq!(found.len(), 1, "{found:?}");
    let r = &found[0];
    assert_eq!(r["body"], "/spindle/occupancy");
    assert_eq!(r["axis"], serde_json::json!([1.0, 0.0, 0.0]));
    let point: Vec<f64> = r["point_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    // Snapped to the checker lattice (an eighth of a 0.04 m voxel).
    for (got, want) in point.iter().zip([0.44, 0.64, 1.0]) {
        assert!((got - want).abs() <= 0.0025, "{point:?}");
    }
    let angle = r["angle_rad"].as_f64().unwrap();
    assert!((0.1..1.2).contains(&angle.abs()), "{r}");
    assert_eq!(r["verified_clear"], true, "{r}");
    assert!(r.get("reason").is_none(), "{r}");
    assert_eq!(r["episode_s"].as_array().unwrap().len(), 2);
    // Within a tenth of a radian nothing clears: said, with the largest angle tried.
    let small = rotations(&with(&format!(
        "{axis}    - {{name: rotation_max_rad, value: 0.1}}\n"
    )));
    assert_eq!(small.len(), 1, "{small:?}");
    assert_eq!(small[0]["verified_clear"], false);
    assert!(small[0]["angle_rad"].as_f64().unwrap().abs() <= 0.1);
    let why = small[0]["reason"].as_str().unwrap();
    assert!(why.contains("no angle tried up to 5.7°"), "{why}");
    // A zero limit asks for no rotation.
    let none = rotations(&with(&format!(
        "{axis}    - {{name: rotation_max_rad, value: 0.0}}\n"
    )));
    assert!(none.is_empty(), "{none:?}");
    // An axis without a direction is refused, by name.
    let e = replay(
        &bag,
        Some(&with(
            "    - {name: rotation_axis, value: [0.0, 0.0, 0.0]}\n",
        )),
        Some(&d.path().join("never.mcap")),
        false,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("rotation_axis"), "{e}");
}

/// A 24³ bag at 1 cm voxels: `/ball/occupancy`, a 6-voxel cube, moves 4 voxels along x each
/// frame (no part vanishes: its frames overlap), passing 2 voxels beside `/post/occupancy`;
/// `/far/occupancy` rests 11 voxels from its path. Frames at 10 Hz.
fn pass_by_bag(dir: &Path) -> PathBuf {
    let path = dir.join("pass-by.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    for t in ["/ball/occupancy", "/post/occupancy", "/far/occupancy"] {
        w.add_topic::<VoxelGrid>(t).unwrap();
    }
    for k in 0..4u32 {
        let t = 1_000_000_000 + i64::from(k) * 100_000_000;
        let x0 = 1 + 4 * k as usize;
        let ball = common::bits_data([24; 3], |px, py, pz| {
            (x0..x0 + 6).contains(&px) && (2..8).contains(&py) && (8..14).contains(&pz)
        });
        let post = common::bits_data([24; 3], |px, py, pz| {
            (8..11).contains(&px) && (10..13).contains(&py) && (8..14).contains(&pz)
        });
        let far = common::bits_data([24; 3], |px, py, pz| {
            (8..11).contains(&px) && (18..23).contains(&py) && pz < 2
        });
        w.write("/ball/occupancy", t as u64, &common::cube_grid(24, t, ball))
            .unwrap();
        w.write("/post/occupancy", t as u64, &common::cube_grid(24, t, post))
            .unwrap();
        w.write("/far/occupancy", t as u64, &common::cube_grid(24, t, far))
            .unwrap();
    }
    w.finish().unwrap();
    path
}

#[test]
fn a_body_moving_more_than_two_voxels_a_frame_near_another_makes_the_pair_unsure() {
    use chronotope::checker::report::Verdict;
    let d = tempfile::tempdir().unwrap();
    let bag = pass_by_bag(d.path());
    let config = LaunchConfig::parse(
        "launch:\n- node: {pkg: chronotope, exec: mesher}\n- node: {pkg: chronotope, exec: checker}\n",
        "test",
    )
    .unwrap();
    let r = replay(&bag, Some(&config), None, false).unwrap();
    let pair = |a: &str, b: &str| {
        r.report
            .pairs
            .iter()
            .find(|p| p.a == a && p.b == b)
            .unwrap_or_else(|| panic!("{a} x {b}"))
            .clone()
    };
    // No frame shows the ball touching the post, and none of it vanishes; but it moves 4
    // voxels a frame 2 voxels from the post: what it passes is not seen.
    let bp = pair("/ball/occupancy", "/post/occupancy");
    assert!(!bp.interfering);
    assert_eq!(bp.verdict, Verdict::Unsure, "{:?}", bp.unsure_spans_s);
    assert!(bp
        .unsure_spans_s
        .iter()
        .all(|u| u.code == "moves_fast" && u.body == "/ball/occupancy"));
    let span = &bp.unsure_spans_s[0];
    assert!(
        span.span_s[0].abs() < 1e-9 && (span.span_s[1] - 0.3).abs() < 1e-9,
        "{span:?}"
    );
    assert!(span.resolve.contains("at least 20 Hz"), "{}", span.resolve);
    // Far from its path, the same ball leaves the pair clear; so do two bodies at rest.
    assert_eq!(
        pair("/ball/occupancy", "/far/occupancy").verdict,
        Verdict::Clear
    );
    assert_eq!(
        pair("/far/occupancy", "/post/occupancy").verdict,
        Verdict::Clear
    );
    // `check` says the same.
    let c = chronotope::cli::check::check_bag(&bag, Default::default(), None).unwrap();
    for p in &c.report.pairs {
        let rp = pair(&p.a, &p.b);
        assert_eq!(p.verdict, rp.verdict, "{} x {}", p.a, p.b);
        assert_eq!(p.unsure_spans_s, rp.unsure_spans_s, "{} x {}", p.a, p.b);
    }
}
