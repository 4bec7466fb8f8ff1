//! Replay is deterministic whatever the thread count: the bundled bags of several bodies,
//! replayed through their launch configs in a rayon pool of one thread and of several, give
//! byte-identical output bags and the same report (timings aside). With several threads the
//! mesher marches slabs in chunks and the checker checks several pairs' windows at once, so
//! these runs take the parallel paths.

use crate::common;

use std::path::{Path, PathBuf};

use chronotope::cli::replay::{replay, ReplayReport};
use chronotope::node::launch::LaunchConfig;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Replays `bag` through `config` on `threads` threads; the output bag's bytes and the report.
fn run(bag: &str, config: &str, threads: usize, dir: &Path) -> (Vec<u8>, ReplayReport) {
    let text = std::fs::read_to_string(repo(config)).unwrap();
    run_text(&repo(bag), &text, threads, dir)
}

/// [`run`] with the launch config's text.
fn run_text(bag: &Path, text: &str, threads: usize, dir: &Path) -> (Vec<u8>, ReplayReport) {
    let cfg = LaunchConfig::parse(text, "test").unwrap();
    let out = dir.join(format!("out-{threads}.mcap"));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let report = pool.install(|| {
        assert_eq!(rayon::current_num_threads(), threads);
        replay(bag, Some(&cfg), Some(&out), false).unwrap()
    });
    (std::fs::read(&out).unwrap(), report)
}

/// The report as JSON without its wall-clock timings.
fn answer(r: &ReplayReport) -> serde_json::Value {
    let mut v = serde_json::to_value(r).unwrap();
    v.as_object_mut().unwrap().remove("timings_ms");
    v
}

fn same_whatever_the_threads(bag: &str, config: &str) {
    let d = tempfile::tempdir().unwrap();
    let (one, r1) = run(bag, config, 1, d.path());
    assert!(
        r1.output.topics.values().sum::<u64>() > 0,
        "{bag}: nothing published"
    );
    assert!(
        r1.report.pairs.iter().any(|p| p.interfering),
        "{bag}: no pair interferes, the checker's work is not exercised"
    );
    for threads in [2, 3] {
        let (many, r) = run(bag, config, threads, d.path());
        assert_eq!(
            many.len(),
            one.len(),
            "{bag}: {threads} threads, bag length"
        );
        assert!(
            many == one,
            "{bag}: {threads} threads: the output bags differ"
        );
        assert_eq!(
            answer(&r),
            answer(&r1),
            "{bag}: {threads} threads: reports differ"
        );
    }
}

#[test]
fn machine_tool_replays_byte_identical_on_one_thread_and_several() {
    same_whatever_the_threads(
        "bags/machine-tool-32-bits.mcap",
        "launch_configs/machine_tool.yaml",
    );
}

#[test]
fn machine_tool_percent_replays_byte_identical_on_one_thread_and_several() {
    same_whatever_the_threads(
        "bags/machine-tool-32-percent.mcap",
        "launch_configs/machine_tool.yaml",
    );
}

#[test]
fn four_spheres_replays_byte_identical_on_one_thread_and_several() {
    same_whatever_the_threads(
        "bags/four-spheres-32-bits.mcap",
        "launch_configs/four_spheres.yaml",
    );
}

/// Resolutions run on their own pool while the windows go on; a replay takes their results
/// at points that depend only on the stream (when the next episode is handed over, and at
/// the end), so the output bag is the same on any thread count, and the answers are those
/// of resolutions run in turn on the checker's thread.
#[test]
fn resolutions_beside_the_windows_leave_a_replay_deterministic() {
    let d = tempfile::tempdir().unwrap();
    // 15 s of the periodic scene at 16³: eight contact episodes of the movable swinger.
    let bag = common::scene_bag(d.path(), chronotope::scene::SceneName::Periodic, 16, 301);
    let text = std::fs::read_to_string(repo("launch_configs/periodic.yaml")).unwrap();
    let (one, r1) = run_text(&bag, &text, 1, d.path());
    let (two, r2) = run_text(&bag, &text, 2, d.path());
    assert!(one == two, "1 and 2 threads: the output bags differ");
    assert_eq!(answer(&r1), answer(&r2), "1 and 2 threads: reports differ");
    assert!(
        r1.report.resolutions.len() >= 14,
        "{:?}",
        r1.report.resolutions
    );
    // Suggestions go out while the stream goes on, not all at its end.
    let published = r1.output.topics["/checker/suggestions"];
    assert!(published >= 4, "suggestions published {published} times");
    // The same answers as resolutions run in turn.
    let in_turn = text.replace(
        "- {name: resolve_horizon_s, value: 0.5}",
        "- {name: resolve_horizon_s, value: 0.5}\n    - {name: resolve_in_flight, value: 0}",
    );
    assert_ne!(in_turn, text);
    let (_, r0) = run_text(&bag, &in_turn, 2, d.path());
    assert_eq!(
        serde_json::to_value(&r0.report.resolutions).unwrap(),
        serde_json::to_value(&r1.report.resolutions).unwrap()
    );
    assert_eq!(
        serde_json::to_value(&r0.report.pairs).unwrap(),
        serde_json::to_value(&r1.report.pairs).unwrap()
    );
}
