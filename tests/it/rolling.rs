//! The rolling checker against the full check, and its stream behaviours.
//!
//! - On whole scenes (small grids), `replay` (mesher and checker nodes, frame period by frame
//!   period) gives the intervals, first contacts and their bounds, overlaps, label counts and
//!   body figures that `check` (every body meshed whole, then checked at once) gives.
//! - The periodic scene: every contact is found, each within its error bound, however long
//!   the stream; what the checker keeps does not grow with it.
//! - Streams that lag behind one another, stop while others go on, and restart.

use crate::common;

use std::path::{Path, PathBuf};

use chronotope::bag::BagWriter;
use chronotope::checker::report::Report;
use chronotope::cli::check::check_bag;
use chronotope::cli::replay::replay;
use chronotope::mesh::MesherOptions;
use chronotope::msg::{Time, VoxelGrid};
use chronotope::node::launch::LaunchConfig;
use chronotope::scene::{periodic_contacts, SceneName};
use common::scene_bag;

/// The answers both paths must agree on, digit for digit.
fn answers(r: &Report) -> String {
    let mut out = String::new();
    for b in &r.bodies {
        out += &format!(
            "body {} frames {} tets {} vertices {} closed {} hv {:e}\n",
            b.id, b.frames, b.tets, b.vertices, b.closed, b.hypervolume_m3s
        );
    }
    for p in &r.pairs {
        out += &format!(
            "pair {} {}: {} {:?} first {:?} ± {:?} speed {:?} bounds {:?} overlap {:?} ± {:?} labels {:?}\n",
            p.a,
            p.b,
            p.interfering,
            p.intervals_s,
            p.first_contact_s,
            p.first_contact_error_bound_s,
            p.closing_speed_mps,
            p.interval_error_bounds_s,
            p.overlap_hypervolume_m3s,
            p.overlap_hypervolume_error_bound_m3s,
            p.labels,
        );
    }
    out
}

/// Every pair checked, no resolution: the same plan for both paths.
fn all_pairs(topics: &[String]) -> LaunchConfig {
    let mut pairs = Vec::new();
    for i in 0..topics.len() {
        for j in i + 1..topics.len() {
            pairs.push(format!("'{} {}'", topics[i], topics[j]));
        }
    }
    LaunchConfig::parse(
        &format!(
            "launch:\n\
             - node: {{pkg: chronotope, exec: mesher}}\n\
             - node: {{pkg: chronotope, exec: checker, param: [{{name: pairs, value: [{}]}}]}}\n",
            pairs.join(", ")
        ),
        "test",
    )
    .unwrap()
}

#[test]
fn rolling_replay_answers_as_the_full_check_on_whole_scenes() {
    let d = tempfile::tempdir().unwrap();
    for (name, grid, frames) in [
        (SceneName::FourSpheres, 20, 9),
        (SceneName::MachineTool, 20, 10),
        (SceneName::Periodic, 16, 61),
    ] {
        let bag = scene_bag(d.path(), name, grid, frames);
        let full = check_bag(&bag, MesherOptions::default(), None).unwrap();
        let topics: Vec<String> = full.bodies.iter().map(|b| b.id.clone()).collect();
        let rolled = replay(&bag, Some(&all_pairs(&topics)), None, false).unwrap();
        assert_eq!(
            answers(&rolled.report),
            answers(&full),
            "{name} {grid}^3 x {frames}: rolling replay vs full check"
        );
        assert!(
            full.pairs.iter().any(|p| p.interfering),
            "{name}: the scene has a contact"
        );
    }
}

#[test]
fn every_periodic_contact_is_found_within_its_bound() {
    let d = tempfile::tempdir().unwrap();
    // 15 s at 20 Hz: eight contacts (the last cut by the end of the stream).
    let frames = 301;
    let bag = scene_bag(d.path(), SceneName::Periodic, 16, frames);
    let cfg = LaunchConfig::parse(
        &std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_configs/periodic.yaml"),
        )
        .unwrap(),
        "periodic",
    )
    .unwrap();
    let r = replay(&bag, Some(&cfg), None, false).unwrap().report;
    let want = periodic_contacts(15.0);
    assert_eq!(want.len(), 8);
    let p = &r.pairs[0];
    assert_eq!(p.intervals_s.len(), want.len(), "{:?}", p.intervals_s);
    // Voxelised spheres: each found interval lies within a frame period and a voxel's
    // travel (the swinger moves 0.25 m/s; voxels are 1/16 m) of the true one.
    let slack = 0.05 + (1.0 / 16.0) / 0.25;
    for (got, want) in p.intervals_s.iter().zip(&want) {
        assert!(
            (got[0] - want.0).abs() <= slack && (got[1] - want.1).abs() <= slack,
            "found {got:?}, true {want:?}"
        );
    }
    // Resolutions (translation, time scaling, rotation) per contact episode, each naming it.
    assert!(!r.resolutions.is_empty());
    assert!(r.problems.is_empty(), "{:?}", r.problems);
}

/// Bodies at rest, and one that steps by whole voxels between rests (the checker takes
/// such windows as earlier ones moved, not prepared again): the rolling replay answers as
/// the full check, through contact, rest in contact and separation.
#[test]
fn bodies_at_rest_and_stepping_are_checked_as_the_full_check_does() {
    let d = tempfile::tempdir().unwrap();
    let t0 = 1_000_000_000i64;
    // /a rests three frames at each voxel step along +x (into /b and through its near
    // face, resting there in contact), then back out; /b never moves.
    let xs = [0u32, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 2, 2, 2];
    let mut frames = Vec::new();
    for (k, &x) in xs.iter().enumerate() {
        let k = k as u32;
        let a = common::box_frame(x, 0, 4, k, t0);
        let b = common::box_frame(6, 0, 4, k, t0);
        let log = (t0 + i64::from(k) * 100_000_000) as u64;
        frames.push(("/a/occupancy", log, a));
        frames.push(("/b/occupancy", log, b));
    }
    let bag = bag_of(d.path(), "rest.mcap", &frames);
    let full = check_bag(&bag, MesherOptions::default(), None).unwrap();
    let rolled = replay(&bag, Some(&two_cubes()), None, false).unwrap();
    assert_eq!(answers(&rolled.report), answers(&full));
    assert!(full.pairs[0].interfering);
    assert!(
        rolled.report.problems.is_empty(),
        "{:?}",
        rolled.report.problems
    );
}

/// A box moving +x one voxel per frame (body /a) into a still box (/b), frames at 0.1 s
/// from `t0_ns`.
fn cube(x0: u32, k: u32, t0_ns: i64) -> VoxelGrid {
    common::moving_box(x0, k, t0_ns)
}

/// Frame `k` of the two cubes (`/a` moving, `/b` still) through `mesher` and `checker`, as a
/// transport hands them (the checker reads the frames too, for the overlap): the two
/// frames, and what the checker published.
fn step_cubes(
    k: u32,
    t0: i64,
    mesher: &mut chronotope::node::mesher::MesherNode,
    checker: &mut chronotope::node::checker::CheckerNode,
) -> (
    [(&'static str, VoxelGrid); 2],
    Vec<chronotope::node::Message>,
) {
    use chronotope::node::{Message, Node, Payload};
    let (a, mut b) = (cube(0, k, t0), cube(6, 0, t0));
    b.header.stamp = a.header.stamp;
    let grids = [("/a/occupancy", a), ("/b/occupancy", b)];
    let mut inputs = Vec::new();
    let mut pieces = Vec::new();
    for (topic, g) in &grids {
        let t = g.header.stamp.as_nanos();
        let m = Message::new(
            *topic,
            t,
            Payload::VoxelGrid(std::sync::Arc::new(g.clone())),
        );
        mesher.on_message(&m, &mut pieces);
        inputs.push(m);
    }
    let mut out = Vec::new();
    for m in inputs.into_iter().chain(pieces) {
        checker.on_message(&m, &mut out);
    }
    (grids, out)
}

/// The two cubes' mesher and a live checker node of them (polled once, as a live transport
/// does at each tick; what that poll published) whose bookkeeping pool has one thread, held
/// until the sender returned is dropped: nothing the checker hands the pool runs there (the
/// checker runs it itself when it needs the outcome).
fn cubes_with_held_bookkeeping() -> (
    chronotope::node::mesher::MesherNode,
    chronotope::node::checker::CheckerNode,
    Vec<chronotope::node::Message>,
    std::sync::mpsc::Sender<()>,
) {
    use chronotope::node::Node;
    let held = std::sync::Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap(),
    );
    let (release, hold) = std::sync::mpsc::channel::<()>();
    held.spawn(move || {
        let _ = hold.recv();
    });
    let cfg = two_cubes();
    let bodies = vec!["/a/occupancy".to_owned(), "/b/occupancy".to_owned()];
    let mesher = chronotope::node::mesher::MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap();
    let mut checker =
        chronotope::node::checker::CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap();
    checker.set_bookkeeping_pool(Some(held));
    let mut out = Vec::new();
    checker.poll(&mut out);
    (mesher, checker, out, release)
}

fn two_cubes() -> LaunchConfig {
    LaunchConfig::parse(
        "launch:\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /b/occupancy]}]}\n\
         - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}]}\n",
        "test",
    )
    .unwrap()
}

/// Writes `frames` (topic, frame) with log times as given.
fn bag_of(dir: &Path, name: &str, frames: &[(&str, u64, VoxelGrid)]) -> PathBuf {
    let path = dir.join(name);
    let mut w = BagWriter::create(&path).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    w.add_topic::<VoxelGrid>("/b/occupancy").unwrap();
    for (t, log, g) in frames {
        w.write(t, *log, g).unwrap();
    }
    w.finish().unwrap();
    path
}

#[test]
fn a_body_whose_frames_come_late_is_checked_as_if_they_had_come_in_time() {
    let d = tempfile::tempdir().unwrap();
    let t0 = 1_000_000_000i64;
    let mut in_time = Vec::new();
    let mut late = Vec::new();
    for k in 0..8u32 {
        let log = (t0 + i64::from(k) * 100_000_000) as u64;
        in_time.push(("/a/occupancy", log, cube(0, k, t0)));
        in_time.push(("/b/occupancy", log, cube(6, 0, t0)));
        in_time.last_mut().unwrap().2.header.stamp = cube(0, k, t0).header.stamp;
    }
    // /b's frames arrive 5 periods after /a's (same stamps, later log times).
    for (t, log, g) in &in_time {
        let delay = if *t == "/b/occupancy" { 500_000_000 } else { 0 };
        late.push((*t, log + delay, g.clone()));
    }
    late.sort_by_key(|x| x.1);
    let a = replay(
        &bag_of(d.path(), "in_time.mcap", &in_time),
        Some(&two_cubes()),
        None,
        false,
    )
    .unwrap();
    let b = replay(
        &bag_of(d.path(), "late.mcap", &late),
        Some(&two_cubes()),
        None,
        false,
    )
    .unwrap();
    assert!(a.report.pairs[0].interfering);
    assert_eq!(answers(&a.report), answers(&b.report));
    assert!(b.report.problems.is_empty(), "{:?}", b.report.problems);
}

#[test]
fn a_stream_that_stops_and_restarts_is_checked_in_both_runs() {
    let d = tempfile::tempdir().unwrap();
    let t0 = 1_000_000_000i64;
    let gap = 3_000_000_000i64;
    let mut frames = Vec::new();
    // /b stands still throughout; /a moves in, stops for 3 s (its stream ends: the mesher's
    // idle timeout is 1 s), then comes back and moves in again.
    for k in 0..8u32 {
        for (x, start) in [(0u32, t0), (0u32, t0 + 800_000_000 + gap)] {
            let g = cube(x, k, start);
            let log = g.header.stamp.as_nanos() as u64;
            frames.push(("/a/occupancy", log, g));
        }
    }
    for k in 0..((8 + 30 + 8) as u32) {
        let mut g = cube(6, 0, t0);
        g.header.stamp = Time::from_nanos(t0 + i64::from(k) * 100_000_000);
        let log = g.header.stamp.as_nanos() as u64;
        frames.push(("/b/occupancy", log, g));
    }
    frames.sort_by_key(|x| x.1);
    let r = replay(
        &bag_of(d.path(), "restart.mcap", &frames),
        Some(&two_cubes()),
        None,
        false,
    )
    .unwrap();
    let p = &r.report.pairs[0];
    assert_eq!(
        p.intervals_s.len(),
        2,
        "one contact per run of /a: {:?}",
        p.intervals_s
    );
    let a = r
        .report
        .bodies
        .iter()
        .find(|b| b.id == "/a/occupancy")
        .unwrap();
    assert_eq!(a.frames, 16, "both runs' frames count");
    // Said, not silent: /a stopped while /b went on.
    let said = r.nodes["/checker"].messages.join("\n");
    assert!(said.contains("/a/occupancy: its frames end"), "{said}");
}

#[test]
fn a_stream_that_stalls_is_taken_as_ended_and_its_partner_goes_on() {
    use chronotope::msg::MeshSlab;
    use chronotope::node::checker::CheckerNode;
    use chronotope::node::mesher::MesherNode;
    use chronotope::node::{Message, Node, Payload};
    use std::sync::Arc;

    let cfg = LaunchConfig::parse(
        "launch:\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /b/occupancy]}]}\n\
         - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}, {name: max_lead_frames, value: 4}]}\n",
        "test",
    )
    .unwrap();
    let bodies = vec!["/a/occupancy".to_owned(), "/b/occupancy".to_owned()];
    let mut mesher = MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap();
    let mut checker = CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap();
    let t0 = 1_000_000_000i64;
    let mut results = Vec::new();
    for k in 0..9u32 {
        let mut out = Vec::new();
        for (topic, g) in [
            ("/a/occupancy", cube(0, k, t0)),
            ("/b/occupancy", {
                let mut g = cube(6, 0, t0);
                g.header.stamp = Time::from_nanos(t0 + i64::from(k) * 100_000_000);
                g
            }),
        ] {
            let t = g.header.stamp.as_nanos();
            mesher.on_message(
                &Message::new(topic, t, Payload::VoxelGrid(Arc::new(g))),
                &mut out,
            );
        }
        for m in &out {
            // /b's lateral pieces from 2 on are lost on the way: nothing follows its slab 1.
            // (A piece that does come after lost ones resumes the stream: `tests/it/replay.rs`.)
            if let Payload::MeshSlab(p) = &m.payload {
                if p.body_id == "/b/occupancy" && p.kind == MeshSlab::KIND_LATERAL && p.index >= 2 {
                    continue;
                }
            }
            checker.on_message(m, &mut results);
        }
    }
    let st = checker.status();
    assert_eq!(st.problems.get("stream_stalled"), Some(&1), "{st:?}");
    // /a's slabs were decided past the stall (not kept waiting): labels for /a beyond slab 2.
    let a_slabs = results
        .iter()
        .filter_map(|m| match &m.payload {
            Payload::TetLabels(l) if l.body_id == "/a/occupancy" => Some(l.index),
            _ => None,
        })
        .max();
    assert!(a_slabs.is_some_and(|i| i >= 3), "{a_slabs:?}");
}

/// A period's contact is said as soon as both bodies' slab of it is there, not one frame
/// later when what follows the slabs is known; the labels and what a cap adds where a
/// stream ends are settled after, and the answer is the full check's, with the bodies in
/// contact when their streams end (the caps at the last frame cross).
#[test]
fn a_contact_is_said_as_soon_as_both_slabs_of_its_period_are_there() {
    use chronotope::msg::ContactEvent;
    use chronotope::node::checker::CheckerNode;
    use chronotope::node::mesher::MesherNode;
    use chronotope::node::{Message, Node, Payload};

    let d = tempfile::tempdir().unwrap();
    let cfg = two_cubes();
    let bodies = vec!["/a/occupancy".to_owned(), "/b/occupancy".to_owned()];
    let mut mesher = MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap();
    let mut checker = CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap();
    let t0 = 1_000_000_000i64;
    let mut frames = Vec::new();
    let mut said: Vec<(u32, ContactEvent)> = Vec::new();
    let mut labels = 0usize;
    let events = |out: &[Message], k: u32, said: &mut Vec<(u32, ContactEvent)>| {
        for m in out {
            if let Payload::Contact(e) = &m.payload {
                said.push((k, (**e).clone()));
            }
        }
    };
    for k in 0..8u32 {
        let (grids, out) = step_cubes(k, t0, &mut mesher, &mut checker);
        for (topic, g) in grids {
            frames.push((topic, g.header.stamp.as_nanos() as u64, g));
        }
        labels += out
            .iter()
            .filter(|m| matches!(m.payload, Payload::TetLabels(_)))
            .count();
        events(&out, k, &mut said);
    }
    let (mut pieces, mut out) = (Vec::new(), Vec::new());
    mesher.finish(&mut pieces);
    for m in &pieces {
        checker.on_message(m, &mut out);
    }
    checker.finish(&mut out);
    labels += out
        .iter()
        .filter(|m| matches!(m.payload, Payload::TetLabels(_)))
        .count();
    events(&out, 8, &mut said);

    let begin = said
        .iter()
        .find(|(_, e)| e.event == ContactEvent::BEGIN)
        .expect("the boxes meet");
    let stamp_frame = (begin.1.header.stamp.as_nanos() - t0) / 100_000_000;
    assert_eq!(
        i64::from(begin.0),
        stamp_frame,
        "said while the frame of its stamp was handled, not with the next: {said:?}"
    );
    assert!(
        said.iter().any(|(_, e)| e.event == ContactEvent::END),
        "the contact ends with the streams: {said:?}"
    );
    // One labels message per body and slab, each as the full window gives it.
    assert_eq!(labels, 2 * 7);
    let full = check_bag(
        &bag_of(d.path(), "cubes.mcap", &frames),
        MesherOptions::default(),
        None,
    )
    .unwrap();
    let rolled = checker.report().expect("a report").clone();
    assert!(full.pairs[0].interfering);
    assert_eq!(answers(&rolled), answers(&full));
}

/// Live, a contact event goes out with its period's check: it waits neither for the
/// statistics of the pieces being added nor for the pair's overlap being measured (both
/// the bookkeeping's), and says the pair's overlap before its period, which the report had
/// after the period before; the report follows once the bookkeeping is through, at the
/// node's next tick. The bookkeeping's pool is held up for the whole test: what the checker
/// hands it stays queued until the checker needs it, and then it runs it itself.
#[test]
fn live_contact_events_wait_for_nothing_on_the_pool() {
    use chronotope::msg::ContactEvent;
    use chronotope::node::{Node, Payload};

    // The bookkeeping's pool held for the whole test.
    let (mut mesher, mut checker, out, release) = cubes_with_held_bookkeeping();
    {
        assert!(out.is_empty());
        let t0 = 1_000_000_000i64;
        // The pair's overlap in the latest report, after each step.
        let mut reported: Vec<f64> = Vec::new();
        let (mut contacts, mut steps_with_events, mut held_back) = (0, 0, 0);
        for k in 0..8u32 {
            let (_, out) = step_cubes(k, t0, &mut mesher, &mut checker);
            let events: Vec<&ContactEvent> = out
                .iter()
                .filter_map(|m| match &m.payload {
                    Payload::Contact(e) => Some(&**e),
                    _ => None,
                })
                .collect();
            let report_now = out.iter().any(|m| matches!(m.payload, Payload::Report(_)));
            for e in &events {
                contacts += 1;
                if e.event == ContactEvent::BEGIN {
                    assert!(e.first_contact_s.is_finite(), "{e:?}");
                }
                // The overlap before the event's period: the report's after the step
                // before (one period a step here).
                let before = reported.last().copied().unwrap_or(0.0);
                assert_eq!(
                    e.overlap_hypervolume_m3s.to_bits(),
                    before.to_bits(),
                    "step {k}: {e:?}"
                );
            }
            if !events.is_empty() {
                steps_with_events += 1;
                held_back += usize::from(!report_now);
            }
            // The tick: the report, waiting for the pool.
            let mut ticked = Vec::new();
            checker.poll(&mut ticked);
            let latest = out
                .iter()
                .chain(&ticked)
                .rev()
                .find_map(|m| match &m.payload {
                    Payload::Report(r) => Some(r.pairs[0].overlap_hypervolume_m3s),
                    _ => None,
                });
            if !events.is_empty() {
                assert!(latest.is_some(), "step {k}: a contact changes the report");
            }
            reported.push(latest.unwrap_or_else(|| reported.last().copied().unwrap_or(0.0)));
        }
        assert!(contacts >= 3, "{contacts} contact events");
        // Nothing ran the statistics or the overlap while the node handled the pieces:
        // every step's events went out before its report, which waited for them.
        assert!(
            steps_with_events >= 3,
            "{steps_with_events} steps with events"
        );
        assert_eq!(held_back, steps_with_events);
        assert!(
            reported.last().is_some_and(|&v| v > 0.0),
            "the boxes overlap: {reported:?}"
        );
    }
    drop(checker);
    drop(release);
}

/// A checker node whose report and suggestions nobody reads (a replay recording neither)
/// builds no report until its last, at the end, which is the report a node read all along
/// ends with (the overlap's bound, not worked out frame by frame then, the same); its
/// contact events go out as before, with the same overlaps. A reader that comes is sent the
/// report as it stands at the next step.
#[test]
fn an_unread_report_is_built_only_at_the_end() {
    use chronotope::msg::{InterferenceReport, ResolveSuggestions, RosMessage};
    use chronotope::node::{Message, Node, Payload};

    let t0 = 1_000_000_000i64;
    // The steps at which a report went out, the contact events, and the last report; the
    // report and suggestions unread from step `unread`, read again at step `reread`.
    let run = |unread: Option<u32>, reread: Option<u32>, movable: bool| {
        // The two cubes, /a movable (so that suggestions go out with the reports) or not.
        let cfg = if !movable {
            two_cubes()
        } else {
            LaunchConfig::parse(
            "launch:\n\
             - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /b/occupancy]}]}\n\
             - node: {pkg: chronotope, exec: checker, param: [{name: pairs, value: ['/a/occupancy /b/occupancy']}, {name: movable, value: [/a/occupancy]}]}\n",
            "test",
        )
        .unwrap()
        };
        let bodies = vec!["/a/occupancy".to_owned(), "/b/occupancy".to_owned()];
        let mut mesher =
            chronotope::node::mesher::MesherNode::from_spec(&cfg.nodes[0], &bodies).unwrap();
        let mut checker =
            chronotope::node::checker::CheckerNode::from_spec(&cfg.nodes[1], &bodies).unwrap();
        let told: Vec<String> = checker
            .publications()
            .into_iter()
            .filter(|p| {
                [InterferenceReport::TYPE_NAME, ResolveSuggestions::TYPE_NAME]
                    .contains(&p.type_name)
            })
            .map(|p| p.topic)
            .collect();
        assert_eq!(told.len(), 1 + usize::from(movable), "{told:?}");
        let (mut reported_at, mut events, mut last) = (Vec::new(), Vec::new(), None);
        let mut take = |k: u32, out: &[Message]| {
            for m in out {
                match &m.payload {
                    Payload::Report(r) => {
                        reported_at.push(k);
                        last = Some((**r).clone());
                    }
                    Payload::Contact(e) => events.push((
                        e.event,
                        e.contact_index,
                        e.header.stamp.as_nanos(),
                        e.overlap_hypervolume_m3s.to_bits(),
                    )),
                    _ => {}
                }
            }
        };
        for k in 0..8u32 {
            for t in &told {
                if Some(k) == unread {
                    checker.set_demand(t, false);
                }
                if Some(k) == reread {
                    checker.set_demand(t, true);
                }
            }
            let (_, out) = step_cubes(k, t0, &mut mesher, &mut checker);
            take(k, &out);
        }
        let (mut pieces, mut out) = (Vec::new(), Vec::new());
        mesher.finish(&mut pieces);
        for m in &pieces {
            checker.on_message(m, &mut out);
        }
        checker.finish(&mut out);
        take(8, &out);
        // Compared as printed: a bound not known is NaN, equal to itself there.
        let last = last.expect("a last report");
        (reported_at, events, format!("{last:?}"))
    };
    let (read, events, answer) = run(None, None, true);
    assert!(
        read.len() >= 4,
        "a report at each contact's change: {read:?}"
    );
    assert!(events.len() >= 3, "{events:?}");
    let (unread, unread_events, unread_answer) = run(Some(0), None, true);
    assert_eq!(unread, [8], "only the last report");
    assert_eq!(unread_events, events);
    assert_eq!(unread_answer, answer);
    // Read again from step 5: the report as it stands then, and on as before.
    // (The first message of that step brings the report owed, a later one of the step the
    // report it changes, as in a node read all along.)
    let (mut again, again_events, again_answer) = run(Some(0), Some(5), true);
    assert_eq!(again.first(), Some(&5), "{again:?}");
    let mut from_5: Vec<u32> = read.iter().copied().filter(|&k| k >= 5).collect();
    again.dedup();
    from_5.dedup();
    assert_eq!(again, from_5, "{read:?}");
    assert_eq!(again_events, events);
    assert_eq!(again_answer, answer);
    // No movable body, so no suggestions: the report unread is all it takes.
    let (read, events, answer) = run(None, None, false);
    assert!(read.len() >= 4, "{read:?}");
    let (unread, unread_events, unread_answer) = run(Some(0), None, false);
    assert_eq!(unread, [8], "only the last report");
    assert_eq!((unread_events, unread_answer), (events, answer));
}

/// A live checker node behind its input (no tick comes) with its bookkeeping held up: after
/// 16 steps its changed report goes out as it stands, nothing of the statistics still out
/// computed on its thread: every frame and tet its bodies have counted, their hypervolume
/// short of the complete one, which the tick that comes next publishes.
#[test]
fn a_live_report_behind_its_input_goes_out_as_it_stands() {
    use chronotope::msg::InterferenceReport;
    use chronotope::node::{Message, Node, Payload};

    let (mut mesher, mut checker, _, release) = cubes_with_held_bookkeeping();
    {
        let t0 = 1_000_000_000i64;
        let report = |out: &[Message]| -> Option<InterferenceReport> {
            out.iter().rev().find_map(|m| match &m.payload {
                Payload::Report(r) => Some((**r).clone()),
                _ => None,
            })
        };
        let figures = |r: &InterferenceReport| -> Vec<(String, u64, u64)> {
            r.bodies
                .iter()
                .map(|b| (b.body_id.clone(), b.frames, b.tets))
                .collect()
        };
        let hypervolume =
            |r: &InterferenceReport| -> f64 { r.bodies.iter().map(|b| b.hypervolume_m3s).sum() };
        // The cube of /a moves into /b's: a contact every period; no tick until a report
        // goes out.
        let mut forced = 0;
        for k in 0..10u32 {
            let (a, mut b) = (cube(0, k, t0), cube(6, 0, t0));
            b.header.stamp = a.header.stamp;
            let mut inputs = Vec::new();
            let mut pieces = Vec::new();
            for (topic, g) in [("/a/occupancy", a), ("/b/occupancy", b)] {
                let t = g.header.stamp.as_nanos();
                let m = Message::new(topic, t, Payload::VoxelGrid(std::sync::Arc::new(g)));
                mesher.on_message(&m, &mut pieces);
                inputs.push(m);
            }
            for m in inputs.into_iter().chain(pieces) {
                let mut out = Vec::new();
                checker.on_message(&m, &mut out);
                let Some(stands) = report(&out) else {
                    continue;
                };
                forced += 1;
                let mut ticked = Vec::new();
                checker.poll(&mut ticked);
                let complete = report(&ticked).expect("the complete report at the tick");
                assert_eq!(figures(&stands), figures(&complete), "step {k}");
                assert!(
                    hypervolume(&stands) < hypervolume(&complete),
                    "step {k}: {} against {}",
                    hypervolume(&stands),
                    hypervolume(&complete)
                );
            }
        }
        assert!(forced >= 1, "no report in 40 steps without a tick");
    }
    drop(checker);
    drop(release);
}
