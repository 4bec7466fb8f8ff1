//! Damaged frames in one body cost only that body's affected time span: a refused frame
//! changes no state (no gap is filled towards it), every other body and pair is checked and
//! reported in full, and `check` and `replay` agree.

use crate::common;

use std::path::{Path, PathBuf};

use chronotope::bag::BagWriter;
use chronotope::cli::check::check_bag;
use chronotope::cli::replay::replay;
use chronotope::mesh::MesherOptions;
use chronotope::msg::{Time, VoxelGrid};
use chronotope::checker::report::Report;

const T0: i64 = 1_000_000_000;
const PERIOD: i64 = 100_000_000;

/// A 3×4×4-voxel box in a 12³ BITS frame, x from `x0 + k·vx`, y from `y0`, at frame `k`.
fn boxf(x0: u32, vx: u32, y0: u32, k: u32) -> VoxelGrid {
    common::box_frame(x0, vx, y0, k, T0)
}

/// Writes `frames` (topic, frame) in order.
fn bag(dir: &Path, name: &str, frames: &[(&str, VoxelGrid)]) -> PathBuf {
    let path = dir.join(name);
    let mut w = BagWriter::create(&path).unwrap();
    let mut topics: Vec<&str> = frames.iter().map(|(t, _)| *t).collect();
    topics.sort_unstable();
    topics.dedup();
    for t in topics {
        w.add_topic::<VoxelGrid>(t).unwrap();
    }
    for (t, f) in frames {
        w.write(t, f.header.stamp.as_nanos() as u64, f).unwrap();
    }
    w.finish().unwrap();
    path
}

/// Both reports, after checking `check` and `replay` give the same verdicts and frame counts.
fn both(
    bag: &Path,
) -> (
    chronotope::cli::check::CheckReport,
    chronotope::cli::replay::ReplayReport,
) {
    let c = check_bag(bag, MesherOptions::default(), None).expect("check reports");
    let r = replay(bag, None, None, false).expect("replay reports");
    let verdicts = |rep: &Report| {
        rep.pairs
            .iter()
            .map(|p| {
                (
                    p.a.clone(),
                    p.b.clone(),
                    p.interfering,
                    p.intervals_s.clone(),
                )
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(verdicts(&c), verdicts(&r.report), "check vs replay pairs");
    let frames = |rep: &Report| {
        rep.bodies
            .iter()
            .map(|b| (b.id.clone(), b.frames, b.skipped_frames))
            .collect::<Vec<_>>()
    };
    assert_eq!(frames(&c), frames(&r.report), "check vs replay bodies");
    (c, r)
}

fn pair<'a>(r: &'a Report, a: &str, b: &str) -> &'a chronotope::checker::report::PairReport {
    r.pairs
        .iter()
        .find(|p| p.a == a && p.b == b)
        .unwrap_or_else(|| panic!("pair {a} x {b} in {:?}", r.pairs))
}

#[test]
fn refused_frames_after_the_last_valid_one_invent_nothing() {
    let d = tempfile::tempdir().unwrap();
    let mut frames = Vec::new();
    for k in 0..12 {
        // /a: static at x 0..3; its frames 6..12 on another resolution (refused).
        let mut a = boxf(0, 0, 4, k);
        if k >= 6 {
            a.resolution = 0.02;
        }
        frames.push(("/a/occupancy", a));
        // /b: comes towards /a's place only after /a's last valid frame.
        frames.push((
            "/b/occupancy",
            boxf(9, 0, 4, k).tap_x(if k >= 7 { 0 } else { 9 }),
        ));
    }
    let (c, r) = both(&bag(d.path(), "refused.mcap", &frames));
    for rep in [&c, &r.report] {
        let p = pair(rep, "/a/occupancy", "/b/occupancy");
        assert!(!p.interfering, "/a has no valid frame after 0.5 s: {p:?}");
        let a = rep.bodies.iter().find(|b| b.id == "/a/occupancy").unwrap();
        assert_eq!((a.frames, a.skipped_frames), (6, 6), "{a:?}");
    }
}

trait TapX {
    fn tap_x(self, x0: u32) -> Self;
}
impl TapX for VoxelGrid {
    /// The same frame with the box at x `x0..x0+3`.
    fn tap_x(self, x0: u32) -> Self {
        let size = self.size_x;
        let data = common::bits_data([size; 3], |x, y, z| {
            (4..8).contains(&z) && (4..8).contains(&y) && (x0..x0 + 3).contains(&(x as u32))
        });
        Self { data, ..self }
    }
}

/// Three bodies: /a moves into /b; /c stays clear of both.
fn three(k: u32) -> [(&'static str, VoxelGrid); 3] {
    [
        ("/a/occupancy", boxf(0, 1, 0, k)),
        ("/b/occupancy", boxf(7, 0, 0, k)),
        ("/c/occupancy", boxf(0, 0, 7, k)),
    ]
}

fn scene(edit: impl Fn(&str, u32, &mut VoxelGrid) -> bool) -> Vec<(&'static str, VoxelGrid)> {
    let mut v = Vec::new();
    for k in 0..8 {
        for (t, mut f) in three(k) {
            if edit(t, k, &mut f) {
                v.push((t, f));
            }
        }
    }
    v
}

fn clean_verdicts() -> Vec<(String, String, bool)> {
    vec![
        ("/a/occupancy".into(), "/b/occupancy".into(), true),
        ("/a/occupancy".into(), "/c/occupancy".into(), false),
        ("/b/occupancy".into(), "/c/occupancy".into(), false),
    ]
}

fn verdicts(r: &Report) -> Vec<(String, String, bool)> {
    r.pairs
        .iter()
        .map(|p| (p.a.clone(), p.b.clone(), p.interfering))
        .collect()
}

#[test]
fn the_clean_three_body_scene() {
    let d = tempfile::tempdir().unwrap();
    let (c, _) = both(&bag(d.path(), "clean.mcap", &scene(|_, _, _| true)));
    assert_eq!(verdicts(&c), clean_verdicts());
}

#[test]
fn one_skipped_frame_costs_only_its_body() {
    let d = tempfile::tempdir().unwrap();
    let b = bag(
        d.path(),
        "skip.mcap",
        &scene(|t, k, _| !(t == "/c/occupancy" && k == 3)),
    );
    let (c, _) = both(&b);
    assert_eq!(verdicts(&c), clean_verdicts());
}

#[test]
fn a_body_that_cannot_be_compared_costs_only_its_pairs() {
    let d = tempfile::tempdir().unwrap();
    for (name, edit) in [
        ("half-voxel", 0),
        ("resolution", 1),
        ("stamps", 2),
        ("frame-id", 3),
    ] {
        let b = bag(
            d.path(),
            &format!("{name}.mcap"),
            &scene(|t, _, f| {
                if t == "/c/occupancy" {
                    match edit {
                        0 => f.origin.x = 0.005,
                        1 => f.resolution = 0.02,
                        2 => {
                            f.header.stamp =
                                Time::from_nanos(f.header.stamp.as_nanos() + PERIOD / 2)
                        }
                        _ => f.header.frame_id = "tool".into(),
                    }
                }
                true
            }),
        );
        let (c, r) = both(&b);
        for rep in [&c, &r.report] {
            assert_eq!(
                verdicts(rep),
                clean_verdicts()[..1].to_vec(),
                "{name}: /a x /b checked, the pairs of /c not"
            );
            let unchecked: Vec<(&str, &str)> = rep
                .unchecked_pairs
                .iter()
                .map(|p| (p.a.as_str(), p.b.as_str()))
                .collect();
            assert_eq!(
                unchecked,
                [
                    ("/a/occupancy", "/c/occupancy"),
                    ("/b/occupancy", "/c/occupancy")
                ],
                "{name}: {:?}",
                rep.unchecked_pairs
            );
            for p in &rep.unchecked_pairs {
                assert!(
                    !p.reason.contains("{ ") && !p.reason.is_empty(),
                    "{name}: {}",
                    p.reason
                );
                // One body named twice is no explanation.
                assert!(
                    !p.reason.contains(&format!("{0} and {0}", p.a)),
                    "{}",
                    p.reason
                );
            }
            assert!(
                rep.bodies.iter().all(|b| b.frames == 8),
                "{name}: {:?}",
                rep.bodies
            );
        }
    }
}

#[test]
fn several_bad_frames_in_one_body_are_filled_between_accepted_ones_and_said() {
    let d = tempfile::tempdir().unwrap();
    let b = bag(
        d.path(),
        "several.mcap",
        &scene(|t, k, f| {
            if t == "/c/occupancy" && k % 2 == 1 {
                f.data.truncate(3);
            }
            true
        }),
    );
    let (c, r) = both(&b);
    for rep in [&c, &r.report] {
        assert_eq!(verdicts(rep), clean_verdicts());
        let body = rep.bodies.iter().find(|b| b.id == "/c/occupancy").unwrap();
        // Frames 1, 3, 5 filled between accepted ones; frame 7, the last, is refused and
        // nothing follows it, so nothing is filled towards it.
        assert_eq!(
            (body.frames, body.skipped_frames, body.filled_frames),
            (7, 4, 3),
            "{body:?}"
        );
        let filled: Vec<[f64; 2]> = body
            .lost_spans
            .iter()
            .filter(|s| format!("{:?}", s.kind) == "Filled")
            .map(|s| s.span_s.expect("known stamps"))
            .collect();
        assert_eq!(filled.len(), 3, "{:?}", body.lost_spans);
        assert!(
            (filled[0][0] - 0.0).abs() < 1e-9 && (filled[0][1] - 0.2).abs() < 1e-9,
            "{filled:?}"
        );
    }
}

#[test]
fn out_of_domain_fields_are_refused_or_clamped_by_name() {
    let d = tempfile::tempdir().unwrap();
    let b = bag(
        d.path(),
        "fields.mcap",
        &scene(|t, k, f| {
            if t == "/c/occupancy" {
                // /c in PERCENT; at frame 4 its occupied voxels say 150 (outside 0..=100).
                let bits = f.data.clone();
                let on = if k == 4 { 150 } else { 100 };
                f.encoding = VoxelGrid::ENCODING_PERCENT;
                f.data = (0..12 * 12 * 12)
                    .map(|i| {
                        if bits[i / 8] >> (i % 8) & 1 == 1 {
                            on
                        } else {
                            0
                        }
                    })
                    .collect();
                if k == 2 {
                    f.header.stamp.nanosec = 1_500_000_000;
                }
            }
            true
        }),
    );
    let (c, r) = both(&b);
    assert_eq!(verdicts(&c), clean_verdicts());
    let body = c.bodies.iter().find(|b| b.id == "/c/occupancy").unwrap();
    // Frame 2 refused (its stamp) and filled between 1 and 3; frame 4 accepted, counted.
    assert_eq!(
        (body.frames, body.skipped_frames, body.filled_frames),
        (8, 1, 1),
        "{body:?}"
    );
    let codes: Vec<&str> = body.lost_spans.iter().map(|s| s.code).collect();
    assert_eq!(
        codes,
        ["bad_stamp", "frames_missing", "percent_out_of_range"],
        "{body:?}"
    );
    // A stamp out of its domain is no time: that span has none.
    assert_eq!(body.lost_spans[0].span_s, None, "{body:?}");
    assert!(body.lost_spans[1].span_s.is_some(), "{body:?}");
    let problems = format!("{:?}", r.nodes);
    assert!(problems.contains("nanosec 1500000000"), "{problems}");
    assert!(
        problems.contains("PERCENT voxel(s) hold values outside 0..=100"),
        "{problems}"
    );
    // The resolution has a domain: 10^-300 m is refused by name, in a short number.
    let e = chronotope::mesh::MeshError::BadResolution { resolution: 1e-300 }.to_string();
    assert!(e.contains("1e-300") && e.len() < 120, "{e}");
}

/// The overlap of /a x /b in a report.
fn overlap(r: &Report) -> Option<f64> {
    pair(r, "/a/occupancy", "/b/occupancy").overlap_hypervolume_m3s
}

#[test]
fn the_overlap_is_measured_across_whole_voxel_offsets_mixed_encodings_and_gaps() {
    let d = tempfile::tempdir().unwrap();
    let (clean, _) = both(&bag(d.path(), "clean.mcap", &scene(|_, _, _| true)));
    let want = overlap(&clean).expect("the clean overlap is measured");
    assert!(want > 0.0);
    for (name, edit) in [("offset", 0), ("percent", 1), ("skip", 2)] {
        let b = bag(
            d.path(),
            &format!("ov-{name}.mcap"),
            &scene(|t, k, f| {
                if t != "/b/occupancy" {
                    return true;
                }
                match edit {
                    0 => {
                        // The same box on a grid one voxel further along x.
                        f.origin.x = 0.01;
                        *f = boxf(6, 0, 0, k).with_origin_x(0.01);
                        true
                    }
                    1 => {
                        let bits = f.data.clone();
                        f.encoding = VoxelGrid::ENCODING_PERCENT;
                        f.data = (0..12 * 12 * 12)
                            .map(|i| {
                                if bits[i / 8] >> (i % 8) & 1 == 1 {
                                    100
                                } else {
                                    0
                                }
                            })
                            .collect();
                        true
                    }
                    _ => k != 3,
                }
            }),
        );
        let (c, r) = both(&b);
        for rep in [&c, &r.report] {
            let got = overlap(rep).unwrap_or_else(|| panic!("{name}: overlap measured"));
            assert!(got.is_finite() && got > 0.0, "{name}: {got}");
            if edit != 2 {
                assert!((got - want).abs() <= 1e-9 * want, "{name}: {got} vs {want}");
            }
        }
    }
}

trait WithOrigin {
    fn with_origin_x(self, x: f64) -> Self;
}
impl WithOrigin for VoxelGrid {
    fn with_origin_x(mut self, x: f64) -> Self {
        self.origin.x = x;
        self
    }
}

#[test]
fn a_refused_channel_is_named_in_the_input_by_check_and_replay() {
    use chronotope::msg::RosMessage;
    let d = tempfile::tempdir().unwrap();
    let path = d.path().join("schema.mcap");
    let mut w = BagWriter::create(&path).unwrap();
    w.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    w.add_topic::<VoxelGrid>("/b/occupancy").unwrap();
    // /c: recorded with a schema text that is not ours (a field of another type).
    let ours = chronotope::msg::ros2msg_schema::<VoxelGrid>();
    let schema = ours.replacen("float64 resolution", "float32 resolution", 1);
    assert_ne!(schema, ours);
    w.add_topic_with_schema("/c/occupancy", VoxelGrid::TYPE_NAME, &schema)
        .unwrap();
    for (t, f) in scene(|_, _, _| true) {
        let bytes = chronotope::msg::encode_cdr(&f).unwrap();
        w.write_cdr(t, f.header.stamp.as_nanos() as u64, &bytes)
            .unwrap();
    }
    w.finish().unwrap();
    let (c, r) = both(&path);
    assert_eq!(verdicts(&c), clean_verdicts()[..1].to_vec());
    for input in [&c.input, &r.input] {
        let refused: Vec<(&str, u64)> = input
            .refused_topics
            .iter()
            .map(|t| (t.topic.as_str(), t.messages))
            .collect();
        assert_eq!(refused, [("/c/occupancy", 8)], "{input:?}");
        assert!(
            input.refused_topics[0].reason.contains("resolution"),
            "{input:?}"
        );
    }
}

#[test]
fn a_one_body_bag_replays_with_the_default_config_and_reports_its_body() {
    let d = tempfile::tempdir().unwrap();
    let frames: Vec<_> = (0..5)
        .map(|k| ("/fixture/occupancy", boxf(0, 1, 0, k)))
        .collect();
    let (c, r) = both(&bag(d.path(), "one.mcap", &frames));
    for rep in [&c, &r.report] {
        assert!(rep.pairs.is_empty());
        let b = &rep.bodies[0];
        assert_eq!(
            (b.id.as_str(), b.frames, b.closed),
            ("/fixture/occupancy", 5, true)
        );
    }
    assert_eq!(c.bodies[0].tets, r.report.bodies[0].tets);
}
