//! The live commands: `launch` and `node` run the suite's nodes on DDS, `play` puts a bag on
//! the wire with its recorded timing, `record` writes live topics to a rosbag2 MCAP.
//!
//! All four stop cleanly on Ctrl-C (SIGINT) or SIGTERM: the nodes finish what they have (a
//! stream cut short is closed and checked), the last messages are sent, and the DDS
//! participant says goodbye to its peers. A second signal aborts: what is still queued is
//! discarded (counted), each node finishes the handler it is in, and the writers are flushed.
//! A third exits at once (status 130).

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;
use futures::StreamExt;

use super::replay::write_json;
use crate::node::factory::build_nodes;
use super::CliError;
use crate::bag::{BagReader, BagWriter};
use crate::live::wire::{ros_topic_name, ros_type_name, RawCdr, TopicQos};
use crate::live::{
    domain_id_from_env, run_nodes, write_stamped, LiveError, LiveOptions, Participant, RawWriter,
    Shutdown,
};
use crate::msg::{Clock, RosMessage, Time};
use crate::node::launch::{LaunchConfig, NodeKind};
use crate::node::Payload;

impl From<LiveError> for CliError {
    fn from(e: LiveError) -> Self {
        CliError::Usage(e.to_string())
    }
}

/// Options shared by `launch` and `node`.
#[derive(Debug, Clone, Args)]
pub struct RunArgs {
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Received messages that may wait for the nodes; beyond it samples are dropped and
    /// counted.
    #[arg(long, default_value_t = 256)]
    pub queue: usize,
    /// Bytes (MiB) the messages waiting for one node may hold, all its topics together (a
    /// node's `queue_mb` parameter overrides it); beyond it samples are dropped and counted.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub queue_mb: u32,
    /// At exit, write what the nodes and the transport counted (JSON).
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Replace a summary path that holds a bag. Inputs are never replaced.
    #[arg(long)]
    pub overwrite: bool,
}

/// Options of `chronotope launch`.
#[derive(Debug, Clone, Args)]
pub struct LaunchArgs {
    /// Launch config (ROS 2 launch YAML): the nodes to run, in this one process.
    pub config: PathBuf,
    /// How long to run, the queue, the summary.
    #[command(flatten)]
    pub run: RunArgs,
}

/// Options of `chronotope node`.
#[derive(Debug, Clone, Args)]
pub struct NodeArgs {
    /// The node's name as the config gives it (`mesher`, or fully qualified `/ns/mesher`).
    pub name: String,
    /// The launch config that describes it (and the nodes it talks to).
    #[arg(long)]
    pub launch: PathBuf,
    /// How long to run, the queue, the summary.
    #[command(flatten)]
    pub run: RunArgs,
}

/// Options of `chronotope play`.
#[derive(Debug, Clone, Args)]
pub struct PlayArgs {
    /// Bag to publish: a rosbag2 directory, or an MCAP or SQLite (.db3) file.
    pub bag: PathBuf,
    /// Speed factor (2 plays twice as fast).
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Start again from the beginning when the bag ends, until Ctrl-C.
    #[arg(long = "loop")]
    pub looped: bool,
    /// Do not publish the bag's time on `/clock`.
    #[arg(long)]
    pub no_clock: bool,
    /// Wait this many seconds for subscribers to match before the first message.
    #[arg(long, default_value_t = 1.0)]
    pub wait: f64,
}

/// Options of `chronotope record`.
#[derive(Debug, Clone, Args)]
pub struct RecordArgs {
    /// Topics to record (their types are learnt from the publishers on the wire).
    pub topics: Vec<String>,
    /// Record what the nodes of this launch config publish (its recorder node's selection).
    #[arg(long)]
    pub launch: Option<PathBuf>,
    /// Output bag: an MCAP file, or a rosbag2 directory (with metadata.yaml) if the path
    /// ends with `/` or is a directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Seconds to wait for the publishers of TOPICS to be discovered.
    #[arg(long, default_value_t = 5.0)]
    pub discovery: f64,
    /// Replace an output path that holds a bag (a recording is never replaced otherwise).
    #[arg(long)]
    pub overwrite: bool,
}

/// What Ctrl-C (SIGINT) or SIGTERM asks for: the first a stop, the second an abort, the
/// third an exit at once (status 130, as a shell reports an interrupted command).
fn stop_on_signal() -> Arc<Shutdown> {
    let shutdown = Arc::new(Shutdown::default());
    let flags = shutdown.clone();
    std::thread::spawn(move || {
        let Ok(rt) = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        else {
            return;
        };
        rt.block_on(async {
            use tokio::signal::unix::{signal, Signal, SignalKind};
            // Both streams live for the whole run, so a signal that comes while the one
            // before is being handled is not missed (two at once count as one).
            let mut int = signal(SignalKind::interrupt()).ok();
            let mut term = signal(SignalKind::terminate()).ok();
            async fn next(s: &mut Option<Signal>) {
                match s.as_mut() {
                    Some(s) => {
                        s.recv().await;
                    }
                    None => std::future::pending::<()>().await,
                }
            }
            for n in 1.. {
                tokio::select! {
                    () = next(&mut int) => {}
                    () = next(&mut term) => {}
                }
                match n {
                    1 => {
                        tracing::info!("signal: stopping (again to abort)");
                        flags.stop();
                    }
                    2 => {
                        tracing::warn!(
                            "second signal: aborting; what is queued is discarded (again to \
                             exit at once)"
                        );
                        flags.abort();
                    }
                    _ => {
                        tracing::error!("third signal: exiting at once");
                        std::process::exit(130);
                    }
                }
            }
        });
    });
    shutdown
}

fn seconds(what: &str, s: Option<f64>) -> Result<Option<Duration>, CliError> {
    match s {
        None => Ok(None),
        Some(v) if v.is_finite() && v > 0.0 && v < 1e9 => Ok(Some(Duration::from_secs_f64(v))),
        Some(v) => Err(CliError::Usage(format!(
            "--{what} {v}: not a positive number of seconds"
        ))),
    }
}

/// Runs the nodes of `config` named by `only` (all if `None`).
fn run_config(config: &LaunchConfig, only: Option<&str>, a: &RunArgs) -> Result<(), CliError> {
    let (nodes, _) = build_nodes(config, &[], false).map_err(|e| CliError::Usage(e.to_string()))?;
    let wanted = |fqn: &str| {
        only.is_none_or(|n| fqn == n || fqn.rsplit('/').next() == Some(n.trim_start_matches('/')))
    };
    let mut remote_subscribed = BTreeSet::new();
    let mut local = Vec::new();
    // A part of a node (the carving node's display, `<name>/display`) has no launch entry of
    // its own: it runs where its node runs.
    let owner = |fqn: &str| -> String {
        if config.nodes.iter().any(|s| s.fqn == fqn) {
            fqn.to_owned()
        } else {
            fqn.rsplit_once('/').map_or(fqn, |(p, _)| p).to_owned()
        }
    };
    for n in nodes {
        if wanted(&owner(n.name())) {
            local.push(n);
        } else {
            remote_subscribed.extend(n.subscriptions().into_iter().map(|s| s.topic));
        }
    }
    if local.is_empty() {
        let names: Vec<String> = config.nodes.iter().map(|n| n.fqn.clone()).collect();
        return Err(CliError::Usage(format!(
            "no node {} in the config (it has {})",
            only.unwrap_or("?"),
            names.join(", ")
        )));
    }
    let specs: Vec<_> = config
        .nodes
        .iter()
        .filter(|s| s.kind != NodeKind::Recorder && local.iter().any(|n| n.name() == s.fqn))
        .cloned()
        .collect();
    let opts = LiveOptions {
        domain_id: domain_id_from_env()?,
        queue_capacity: a.queue,
        queue_mb: a.queue_mb as usize,
        run_for: seconds("duration", a.duration)?,
        remote_subscribed,
        ..LiveOptions::default()
    };
    let summary = run_nodes(local, &specs, &opts, stop_on_signal())?;
    for (name, s) in &summary.nodes {
        eprintln!(
            "{name}: received {}, published {}, problems {}, dropped {}, CPU {:.2} s{}{}{}",
            s.status.received,
            s.status.published,
            s.status.problem_count(),
            s.dropped.values().sum::<u64>(),
            s.cpu_s,
            s.stopped
                .as_ref()
                .map(|w| format!(", STOPPED: {w}"))
                .unwrap_or_default(),
            match s.discarded.values().sum::<u64>() {
                0 => String::new(),
                n => format!(", discarded by the abort {n}"),
            },
            s.unfinished
                .as_ref()
                .map(|w| format!(", UNFINISHED: {w}"))
                .unwrap_or_default()
        );
    }
    let t = &summary.transport;
    eprintln!(
        "transport: received {}, sent {}, dropped {}, undecodable {}",
        t.received.values().sum::<u64>(),
        t.sent.values().sum::<u64>(),
        t.dropped.values().sum::<u64>(),
        t.undecodable.values().sum::<u64>()
    );
    if let Some(p) = &a.summary {
        write_json(p, &summary)?;
    }
    Ok(())
}

fn read_config(p: &std::path::Path) -> Result<LaunchConfig, CliError> {
    LaunchConfig::read(p).map_err(|e| CliError::Usage(e.to_string()))
}

/// `chronotope launch`.
///
/// # Errors
/// A bad config, or DDS cannot start.
pub fn launch(a: &LaunchArgs) -> Result<(), CliError> {
    let config = read_config(&a.config)?;
    summary_paths(&a.config, &config, &a.run)?;
    run_config(&config, None, &a.run)
}

/// Checks the summary path against the launch config and the files it reads, before the
/// nodes start.
fn summary_paths(
    path: &std::path::Path,
    config: &crate::node::launch::LaunchConfig,
    a: &RunArgs,
) -> Result<(), CliError> {
    super::paths::Paths::new(a.overwrite)
        .launch_config(path, Some(config))
        .output(
            "--summary",
            a.summary.as_deref(),
            super::paths::OutputKind::File,
        )
        .check()
}

/// `chronotope node`.
///
/// # Errors
/// A bad config, no such node, or DDS cannot start.
pub fn node(a: &NodeArgs) -> Result<(), CliError> {
    let config = read_config(&a.launch)?;
    summary_paths(&a.launch, &config, &a.run)?;
    run_config(&config, Some(&a.name), &a.run)
}

/// Longest `play` waits, once the bag is sent, for its reliable readers to acknowledge it.
const PLAY_ACK_WAIT: Duration = Duration::from_secs(10);

/// `chronotope play`.
///
/// # Errors
/// The bag cannot be opened, bad options, or DDS cannot start.
pub fn play(a: &PlayArgs) -> Result<(), CliError> {
    if !(a.rate.is_finite() && a.rate > 0.0) {
        return Err(CliError::Usage(format!(
            "--rate {}: not a positive factor",
            a.rate
        )));
    }
    let stop = stop_on_signal();
    let participant = Participant::new(domain_id_from_env()?)?;
    let mut writers: BTreeMap<String, Option<RawWriter>> = BTreeMap::new();
    let clock = if a.no_clock {
        None
    } else {
        Some(participant.writer(
            "/clock",
            Clock::TYPE_NAME,
            TopicQos::for_type(Clock::TYPE_NAME),
        )?)
    };
    // Writers are made from the bag's channels before the first message, so that readers
    // can match during the wait.
    let mut first_pass = BagReader::open(&a.bag)?;
    for m in first_pass.by_ref().flatten() {
        if !writers.contains_key(&m.topic) {
            let w = make_writer(&participant, &m.topic, &m.schema_name, &m.message_encoding);
            writers.insert(m.topic.clone(), w);
        }
    }
    drop(first_pass);
    std::thread::sleep(Duration::from_secs_f64(a.wait.clamp(0.0, 60.0)));
    let (mut sent, mut failed) = (0u64, 0u64);
    'plays: loop {
        let start = Instant::now();
        let mut t0 = None;
        let mut last_clock = None;
        for item in BagReader::open(&a.bag)? {
            if stop.stopping() {
                break 'plays;
            }
            let m = match item {
                Ok(m) => m,
                Err(e) => {
                    tracing::warn!("{e}");
                    if e.is_fatal() {
                        break;
                    }
                    continue;
                }
            };
            let t = m.log_time_ns;
            let first = *t0.get_or_insert(t);
            let due = Duration::from_secs_f64(t.saturating_sub(first) as f64 * 1e-9 / a.rate);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
            if let Some(c) = &clock {
                if last_clock.is_none_or(|l: u64| t >= l + 10_000_000) {
                    last_clock = Some(t);
                    let msg = Clock {
                        clock: Time::from_nanos(t.min(i64::MAX as u64) as i64),
                    };
                    if let Ok(bytes) = crate::msg::encode_cdr(&msg) {
                        let _ = write_stamped(c, bytes);
                    }
                }
            }
            let Some(Some(w)) = writers.get(&m.topic) else {
                continue;
            };
            match write_stamped(w, m.data) {
                Ok(()) => sent += 1,
                Err(e) => {
                    failed += 1;
                    tracing::warn!(topic = m.topic, "not sent: {e}");
                }
            }
        }
        if !a.looped {
            break;
        }
    }
    // Reliable samples are resent until each matched reader acknowledges them: the player
    // stays until all are (a lost packet on a busy host takes a few heartbeats), for at
    // most `PLAY_ACK_WAIT` in all, and names the topics that were not; then it stays
    // `LEAVE_GRACE` longer, for the readers to take what they acknowledged.
    let deadline = Instant::now() + PLAY_ACK_WAIT;
    for (topic, w) in writers.iter().filter_map(|(t, w)| Some((t, w.as_ref()?))) {
        let left = deadline.saturating_duration_since(Instant::now());
        if !matches!(w.wait_for_acknowledgments(left), Ok(true)) {
            tracing::warn!(
                topic,
                "not acknowledged by every reliable reader within {} s of the end",
                PLAY_ACK_WAIT.as_secs()
            );
        }
    }
    if sent > 0 {
        std::thread::sleep(crate::live::LEAVE_GRACE);
    }
    eprintln!("play: {sent} message(s) sent, {failed} not sent");
    Ok(())
}

/// A DDS timestamp (seconds and 2^-32 fractions since the Unix epoch) in nanoseconds; `None`
/// for the invalid and infinite markers.
fn timestamp_ns(t: rustdds::Timestamp) -> Option<u64> {
    let ticks = t.to_ticks();
    let seconds = ticks >> 32;
    if seconds == 0xFFFF_FFFF {
        return None;
    }
    Some(seconds * 1_000_000_000 + (((ticks & 0xFFFF_FFFF) * 1_000_000_000) >> 32))
}

fn make_writer(p: &Participant, topic: &str, ty: &str, encoding: &str) -> Option<RawWriter> {
    if encoding != "cdr" || ty.is_empty() {
        tracing::warn!(
            topic,
            "not played: encoding {encoding:?}, type {ty:?} (needs cdr with a type)"
        );
        return None;
    }
    match p.writer(topic, ty, TopicQos::for_type(ty)) {
        Ok(w) => Some(w),
        Err(e) => {
            tracing::warn!(topic, "not played: {e}");
            None
        }
    }
}

/// `chronotope record`.
///
/// # Errors
/// Bad options, a topic of a type the suite has no definition for, DDS cannot start, or the
/// bag cannot be written.
pub fn record(a: &RecordArgs) -> Result<(), CliError> {
    let mut paths = super::paths::Paths::new(a.overwrite);
    if let Some(l) = &a.launch {
        paths = paths.input("the launch config", l);
    }
    paths
        .output(
            "--out",
            Some(&a.out),
            super::paths::OutputKind::Bag { derived: false },
        )
        .check()?;
    let stop = stop_on_signal();
    let participant = Participant::new(domain_id_from_env()?)?;
    let mut topics: BTreeMap<String, &'static str> = BTreeMap::new();
    if let Some(cfg) = &a.launch {
        let config = read_config(cfg)?;
        let (nodes, selection) =
            build_nodes(&config, &[], false).map_err(|e| CliError::Usage(e.to_string()))?;
        for n in &nodes {
            for p in n.publications() {
                if selection.wants(&p.topic) {
                    topics.insert(p.topic, p.type_name);
                }
            }
        }
    }
    if !a.topics.is_empty() {
        let deadline = Instant::now() + Duration::from_secs_f64(a.discovery.clamp(0.0, 600.0));
        let mut missing: BTreeSet<String> = a.topics.iter().cloned().collect();
        while !missing.is_empty() && Instant::now() < deadline {
            for d in participant.discovered_topics() {
                let Some(t) = ros_topic_name(&d.0) else {
                    continue;
                };
                if !missing.contains(t) {
                    continue;
                }
                let Some(ty) = ros_type_name(&d.1) else {
                    continue;
                };
                let Some((known, _)) = Payload::schema_of(&ty) else {
                    return Err(CliError::Usage(format!(
                        "{t}: type {ty} is not one whose definition the suite has; cannot record it"
                    )));
                };
                topics.insert(t.to_owned(), known);
                missing.remove(t);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        if !missing.is_empty() {
            return Err(CliError::Usage(format!(
                "no publisher seen for {} within {} s",
                missing.into_iter().collect::<Vec<_>>().join(", "),
                a.discovery
            )));
        }
    }
    if topics.is_empty() {
        return Err(CliError::Usage(
            "nothing to record: name topics or --launch".into(),
        ));
    }
    // A recording is written where it stays while it grows, so that what was recorded
    // survives a crash (an existing bag it replaces, with --overwrite, is replaced at the end).
    let mut writer =
        BagWriter::create_with(&a.out, crate::bag::BagWriteOptions::new().visible(true))?;
    let (tx, rx) = std::sync::mpsc::sync_channel::<(usize, u64, u64, RawCdr)>(1024);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(LiveError::Runtime)?;
    let names: Vec<(String, &'static str)> = topics.into_iter().collect();
    for (i, (topic, ty)) in names.iter().enumerate() {
        let (_, schema) = Payload::schema_of(ty).expect("only known types are recorded");
        writer.add_topic_with_schema(topic, ty, &schema)?;
        let reader = participant.reader(topic, ty, TopicQos::reader_for_type(ty))?;
        let tx = tx.clone();
        runtime.spawn(async move {
            let mut stream = std::pin::pin!(reader.as_async_stream());
            while let Some(r) = stream.next().await {
                if let Ok(c) = r {
                    let now = std::time::SystemTime::now()
                        .duration_since(std::time::UNIX_EPOCH)
                        .map_or(0, |d| d.as_nanos() as u64);
                    let published = c
                        .write_options
                        .source_timestamp()
                        .and_then(timestamp_ns)
                        .unwrap_or(now);
                    if tx.send((i, now, published, c.sample)).is_err() {
                        return;
                    }
                }
            }
        });
        tracing::info!(topic, ty, "recording");
    }
    drop(tx);
    let start = Instant::now();
    let limit = seconds("duration", a.duration)?;
    let mut counts: BTreeMap<&str, u64> = BTreeMap::new();
    while !stop.stopping() && limit.is_none_or(|l| start.elapsed() < l) {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok((i, t, published, bytes)) => {
                let topic = &names[i].0;
                writer.write_cdr_published(topic, t, published, &bytes.0)?;
                *counts.entry(topic).or_default() += 1;
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
        }
    }
    writer.finish()?;
    runtime.shutdown_timeout(Duration::from_millis(200));
    for (t, n) in &counts {
        eprintln!("record: {t}: {n} message(s)");
    }
    eprintln!("record: wrote {}", a.out.display());
    Ok(())
}
