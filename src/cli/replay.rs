//! `chronotope replay BAG [--launch CFG] [--report FILE.json] [--out FILE.mcap]`: the nodes a
//! launch config names, in one process on the in-process bus, fed every message of a bag as
//! fast as they go; the report (docs/formats.md#report) and an output bag of everything
//! they published.
//!
//! Deterministic: the same bag and config give the same output bag, byte for byte, and the
//! same report (apart from `timings_ms`). Output messages are logged at their own stamps.

use std::collections::{BTreeMap, BTreeSet};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use serde::Serialize;

use super::CliError;
use crate::bag::{BagReader, BagWriter};
use crate::checker::report::Report;
use crate::node::bus::{Bus, Misrouted};
use crate::node::checker::CheckerNode;
use crate::node::factory::{build_nodes, Selection};
use crate::node::launch::{LaunchConfig, NodeKind, NodeSpec, Params};
use crate::node::mesher::MesherNode;
use crate::node::occupancy::InputKind;
use crate::node::{Message, Node, NodeStatus, Payload};

/// Options of `chronotope replay`.
#[derive(Debug, Clone, Args)]
pub struct ReplayArgs {
    /// Input bag: a rosbag2 directory, or an MCAP or SQLite (.db3) file, zstd-compressed or not.
    pub bag: PathBuf,
    /// Launch config (default: mesh every body, check every pair, resolutions for the body
    /// whose id sorts first).
    #[arg(long)]
    pub launch: Option<PathBuf>,
    /// Write the report (docs/formats.md#report, schema chronotope.report/1).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write every topic the nodes published (or the recorder node's selection) to this bag:
    /// an MCAP file, or a rosbag2 directory (with metadata.yaml) if the path ends with `/`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace an output path that holds a bag this command did not derive (a recording, a
    /// bag of another program). Inputs are never replaced.
    #[arg(long)]
    pub overwrite: bool,
}

pub use crate::cli::InputCounts;

/// The replay's report: the fields of docs/formats.md#report, then the input counts and
/// node statuses.
#[derive(Debug, Clone, Serialize)]
pub struct ReplayReport {
    /// The checker's report (empty bodies and pairs when the config has no checker).
    #[serde(flatten)]
    pub report: Report,
    /// What was read (extra field).
    pub input: InputCounts,
    /// Per node: counters and problems (extra field).
    pub nodes: BTreeMap<String, NodeStatus>,
    /// The output bag: topics and messages written (extra field).
    pub output: OutputCounts,
}

/// What went into the output bag.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct OutputCounts {
    /// Messages per topic.
    pub topics: BTreeMap<String, u64>,
}

/// The default config: a mesher of every body and a checker of every pair.
pub fn default_config() -> LaunchConfig {
    LaunchConfig::parse(
        "launch:\n- node: {pkg: chronotope, exec: mesher}\n- node: {pkg: chronotope, exec: checker}\n",
        "default config",
    )
    .expect("the default config parses")
}

/// A robot recorded the ROS way in a bag: its description and joint-state topics.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagRobot {
    /// The `std_msgs/String` topic `/robot_description`.
    pub description: String,
    /// The `sensor_msgs/JointState` topic (`/joint_states` if present, else the first).
    pub joint_states: String,
    /// Whether the bag has `/tf_static`.
    pub tf_static: bool,
}

/// The robot a bag holds, if any: `/robot_description` as `std_msgs/String` and a
/// `sensor_msgs/JointState` topic (from the channels the bag lists).
pub fn bag_robot(bag: &Path) -> Option<BagRobot> {
    use crate::msg::{JointState, RosMessage, RosString, TFMessage};
    let channels = BagReader::open(bag).ok()?.channels();
    let has = |topic: &str, ty: &str| {
        channels
            .iter()
            .any(|c| c.topic == topic && c.schema_name == ty)
    };
    if !has("/robot_description", RosString::TYPE_NAME) {
        return None;
    }
    let joint_states = if has("/joint_states", JointState::TYPE_NAME) {
        "/joint_states".to_owned()
    } else {
        channels
            .iter()
            .find(|c| c.schema_name == JointState::TYPE_NAME)?
            .topic
            .clone()
    };
    Some(BagRobot {
        description: "/robot_description".into(),
        joint_states,
        tf_static: has("/tf_static", TFMessage::TYPE_NAME),
    })
}

/// The default config for a bag with a robot and VoxelGrid bodies: a robot node on the
/// lattice and frame times of the first body (sorted by topic), then the default mesher and
/// checker.
pub fn default_robot_config(robot: &BagRobot, first_body: &str) -> LaunchConfig {
    let text = format!(
        "launch:\n- node: {{pkg: chronotope, exec: robot, param: [{{name: lattice_from, value: {}}}, {{name: joint_states_topic, value: {}}}]}}\n- node: {{pkg: chronotope, exec: mesher}}\n- node: {{pkg: chronotope, exec: checker}}\n",
        crate::yaml::quote(first_body),
        crate::yaml::quote(&robot.joint_states)
    );
    LaunchConfig::parse(&text, "default config").expect("the default robot config parses")
}

/// Messages handed to the output bag's thread and not yet written, at most (each holds its
/// payload by reference count; a few frame periods' messages: the writer keeps up, and a
/// slow disk holds the replay back instead of its memory growing).
const OUTPUT_QUEUE_MESSAGES: usize = 64;

/// The output bag, written on a thread of its own (serialising and compressing beside the
/// nodes), in the order the messages were recorded.
struct Output {
    selection: Selection,
    /// `None` once the writer has stopped (an error, found when it is joined).
    queue: Option<std::sync::mpsc::SyncSender<ToWrite>>,
    writer: std::thread::JoinHandle<Result<OutputCounts, crate::bag::BagError>>,
}

impl Output {
    /// An output bag at `path` of what `selection` takes.
    fn create(path: &Path, selection: Selection) -> Result<Self, crate::bag::BagError> {
        let mut bag = BagWriting {
            writer: BagWriter::create_with(
                path,
                crate::bag::BagWriteOptions::new().derived("replay"),
            )?,
            counts: OutputCounts::default(),
            bytes: Vec::new(),
        };
        let (queue, inbox) = std::sync::mpsc::sync_channel::<ToWrite>(OUTPUT_QUEUE_MESSAGES);
        let writer = std::thread::Builder::new()
            .name("output bag".into())
            .spawn(move || {
                for m in inbox {
                    match m {
                        ToWrite::Message(m) => bag.record(&m)?,
                        ToWrite::Finish => {
                            bag.writer.finish()?;
                            return Ok(bag.counts);
                        }
                    }
                }
                // The replay stopped on an error: the bag is left unfinished, as it was
                // before it had a thread of its own.
                Ok(bag.counts)
            })
            .map_err(|source| crate::bag::BagError::Io {
                path: path.to_path_buf(),
                action: "cannot start a thread to write",
                source,
            })?;
        Ok(Self {
            selection,
            queue: Some(queue),
            writer,
        })
    }

    /// Hands `m` to the writer if the selection takes it.
    fn record(&mut self, m: &Message) {
        if !self.selection.wants(&m.topic) {
            return;
        }
        if let Some(q) = &self.queue {
            if q.send(ToWrite::Message(m.clone())).is_err() {
                // The writer stopped on an error; it is reported when the bag is finished.
                self.queue = None;
            }
        }
    }

    /// Waits for the writer to write everything and finish the bag.
    fn finish(mut self) -> Result<OutputCounts, crate::bag::BagError> {
        if let Some(q) = self.queue.take() {
            // A writer that stopped on an error says so when joined.
            let _ = q.send(ToWrite::Finish);
        }
        match self.writer.join() {
            Ok(r) => r,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    }
}

/// What the output bag's thread is handed.
enum ToWrite {
    Message(Message),
    /// Every message is in: finish the bag.
    Finish,
}

/// The output bag's writer, on its thread.
struct BagWriting {
    writer: BagWriter,
    counts: OutputCounts,
    /// One serialisation buffer for every message (grown to the largest once).
    bytes: Vec<u8>,
}

impl BagWriting {
    fn record(&mut self, m: &Message) -> Result<(), crate::bag::BagError> {
        // A topic is added (its schema text built) once, at its first message.
        if !self.counts.topics.contains_key(&*m.topic) {
            let (ty, schema) = m.payload.schema();
            self.writer.add_topic_with_schema(&m.topic, ty, &schema)?;
        }
        m.payload
            .encode_into(&mut self.bytes)
            .map_err(|source| crate::bag::BagError::Cdr {
                path: self.writer.path().to_path_buf(),
                topic: m.topic.to_string(),
                source,
            })?;
        self.writer
            .write_cdr(&m.topic, m.stamp_ns.max(0) as u64, &self.bytes)?;
        *self.counts.topics.entry(m.topic.to_string()).or_default() += 1;
        Ok(())
    }
}

/// The bag's topics an occupancy node can read (`octomap_msgs/Octomap`,
/// `sensor_msgs/PointCloud2`), with their kinds; from the summary when there is one, else from
/// the messages. A bag that cannot be read has none (its errors come when it is replayed).
fn sensor_topics(bag: &Path) -> Vec<(String, InputKind)> {
    let Ok(mut reader) = BagReader::open(bag) else {
        return Vec::new();
    };
    let mut found = BTreeMap::new();
    if reader.recovery().summary_used {
        for c in reader.channels() {
            if let Some(k) = InputKind::of_type(&c.schema_name) {
                found.insert(c.topic, k);
            }
        }
    } else {
        for m in reader.by_ref() {
            match m {
                Ok(m) => {
                    if let Some(k) = InputKind::of_type(&m.schema_name) {
                        found.entry(m.topic).or_insert(k);
                    }
                }
                Err(e) if e.is_fatal() => break,
                Err(_) => {}
            }
        }
    }
    found.into_iter().collect()
}

/// `config` with what the bag says: an occupancy node without `input_type` reads its
/// `input_topic` as the bag's type for it; with the default config (`add_nodes`), each
/// OctoMap and point-cloud topic gets an occupancy node on the lattice and frame times of the
/// bag's first body (`/occupancy/<topic>`, publishing `/occupancy/<topic>/occupancy`).
fn with_bag_sensors(
    config: &LaunchConfig,
    sensors: &[(String, InputKind)],
    bag_bodies: &[String],
    add_nodes: bool,
) -> LaunchConfig {
    use crate::node::launch::ParamValue;
    let mut config = config.clone();
    for spec in config.nodes.iter_mut() {
        if spec.kind != NodeKind::Occupancy || spec.params.contains_key("input_type") {
            continue;
        }
        let p = Params::of(spec);
        let topic = match spec.params.get("input_topic") {
            Some(ParamValue::String(t)) => p.resolve("input_topic", t).ok(),
            _ => None,
        };
        if let Some((_, kind)) = sensors.iter().find(|(t, _)| Some(t) == topic.as_ref()) {
            spec.params.insert(
                "input_type".into(),
                ParamValue::String(kind.type_name().into()),
            );
        }
    }
    let Some(first) = bag_bodies.iter().min().filter(|_| add_nodes) else {
        return config;
    };
    for (topic, kind) in sensors {
        let mut name: String = topic
            .split('/')
            .filter(|t| !t.is_empty())
            .collect::<Vec<_>>()
            .join("_");
        if name.is_empty() || name.starts_with(|c: char| c.is_ascii_digit()) {
            name.insert(0, 'n');
        }
        let fqn = format!("/occupancy/{name}");
        if config.nodes.iter().any(|n| n.fqn == fqn) {
            continue;
        }
        let text = |v: &str| ParamValue::String(v.to_owned());
        config.nodes.push(NodeSpec {
            kind: NodeKind::Occupancy,
            fqn,
            params: [
                ("input_topic", text(topic)),
                ("input_type", text(kind.type_name())),
                ("lattice_from", text(first)),
                ("stamps_from", text(first)),
            ]
            .into_iter()
            .map(|(k, v)| (k.to_owned(), v))
            .collect(),
            remaps: BTreeMap::new(),
        });
    }
    config
}

/// How often a replay lets the nodes see the clock (bag log time), as the live transport's
/// tick.
const REPLAY_TICK_NS: i64 = 100_000_000;

/// Inputs read ahead of the one being delivered, at most (one frame of each body, up to
/// this many bodies): a node reading only the bag works on them meanwhile.
const AHEAD_INPUTS_MAX: usize = 16;

/// Replies of a node run behind awaited at once, at most: the messages published after the
/// oldest are held back until it comes.
const BEHIND_REPLIES_MAX: usize = 8;

/// Replays `bag` through the nodes of `config` (the default config if `None`).
///
/// # Errors
/// The bag cannot be opened, the config is invalid, or the output bag cannot be written.
pub fn replay(
    bag: &Path,
    config: Option<&LaunchConfig>,
    out: Option<&Path>,
    progress: bool,
) -> Result<ReplayReport, CliError> {
    let start = Instant::now();
    let bodies = bag_bodies(bag)?;
    let is_default = config.is_none();
    let (config, sensors) = replay_config(bag, config, &bodies.topics);
    let (nodes, selection) = replay_nodes(bag, &config, &bodies.topics, &sensors, is_default)?;
    let mut bus = Bus::new(nodes);
    let mut output = match out {
        Some(p) => Some(Output::create(p, selection)?),
        None => None,
    };
    // What neither a node nor the output bag reads is not built (markers without --out).
    bus.set_demand(|t| output.as_ref().is_some_and(|o| o.selection.wants(t)));
    // The mesher (any node reading only the bag) works a frame of each body ahead of the
    // checker, on a thread of its own; the output is the same message for message.
    bus.run_ahead(bodies.topics.len().clamp(1, AHEAD_INPUTS_MAX));
    // The markers part (any node whose outputs only the output bag reads, and that agrees)
    // draws behind the checker, on a thread of its own; again the same messages in order.
    bus.run_behind(BEHIND_REPLIES_MAX);
    let bar = progress_bar(progress);
    let (mut input, misrouted) = deliver_bag(bag, &mut bus, &mut output, &bar)?;
    let counts = finish(&mut bus, output, misrouted, &mut input, &bar)?;
    Ok(replay_report(&bus, input, counts, &bodies, start))
}

/// The bodies of a replayed bag.
struct BagBodies {
    /// Its VoxelGrid topics read, sorted.
    topics: Vec<String>,
    /// Its VoxelGrid topics beyond [`super::MAX_BODIES`], not read.
    over_limit: usize,
}

/// Open the bag: its bodies are its VoxelGrid topics (those of what can be read, in a
/// damaged bag), the first [`super::MAX_BODIES`] in sorted order.
fn bag_bodies(bag: &Path) -> Result<BagBodies, CliError> {
    let bag_bodies = match crate::bag::voxel_topics(bag) {
        Ok(t) => t,
        Err(crate::bag::BagError::NoVoxelTopics { .. }) => Vec::new(),
        // A damaged bag: the bodies are the VoxelGrid topics of what can be read.
        Err(e) if !matches!(e, crate::bag::BagError::EmptyBag { .. }) && bag.exists() => {
            tracing::error!("{e}; reading what can be read");
            let mut topics = BTreeSet::new();
            for m in BagReader::open(bag)? {
                match m {
                    Ok(m)
                        if m.schema_name
                            == <crate::msg::VoxelGrid as crate::msg::RosMessage>::TYPE_NAME =>
                    {
                        topics.insert(m.topic);
                    }
                    Ok(_) => {}
                    Err(e) if e.is_fatal() => break,
                    Err(_) => {}
                }
            }
            topics.into_iter().collect()
        }
        Err(e) => return Err(e.into()),
    };
    // As `check`: at most MAX_BODIES bodies (the first in sorted order); the rest are not read.
    let mut bag_bodies = bag_bodies;
    let over_limit = bag_bodies.len().saturating_sub(super::MAX_BODIES);
    if over_limit > 0 {
        tracing::warn!(
            "{over_limit} VoxelGrid topic(s) not read: more than {} in one bag",
            super::MAX_BODIES
        );
        bag_bodies.truncate(super::MAX_BODIES);
    }
    Ok(BagBodies {
        topics: bag_bodies,
        over_limit,
    })
}

/// Configure: `config`, or the default one (with a robot node when the bag holds a robot),
/// with what the bag's OctoMap and point-cloud topics need; and those topics.
fn replay_config(
    bag: &Path,
    config: Option<&LaunchConfig>,
    bag_bodies: &[String],
) -> (LaunchConfig, Vec<(String, InputKind)>) {
    // A robot recorded the ROS way becomes a body through a robot node: without a launch
    // config, one runs on the first body's lattice and frame times.
    let robot = if config.is_none() {
        bag_robot(bag)
    } else {
        None
    };
    let default = match (&robot, bag_bodies.first()) {
        (Some(r), Some(first)) => {
            tracing::info!(
                "the bag holds a robot ({}, {}): a robot node runs on the lattice of {first}; \
                 a launch config with `exec: robot` sets its base pose, lattice and bodies",
                r.description,
                r.joint_states
            );
            default_robot_config(r, first)
        }
        _ => default_config(),
    };
    if let (Some(r), None) = (&robot, bag_bodies.first()) {
        tracing::warn!(
            "the bag holds a robot ({}) but no VoxelGrid body to put it on a lattice with; \
             give a launch config with `exec: robot` and its lattice (origin, resolution, size)",
            r.description
        );
    }
    // The bag's OctoMap and point-cloud topics: read by the config's occupancy nodes as
    // their type, and by nodes of their own with the default config.
    let sensors = sensor_topics(bag);
    let is_default = config.is_none();
    let config = with_bag_sensors(config.unwrap_or(&default), &sensors, bag_bodies, is_default);
    (config, sensors)
}

/// Build the nodes: those `config` names (or why the bag has no body, when that is why they
/// cannot be built), refused if one reads a bag's body or sensor topic as another type.
fn replay_nodes(
    bag: &Path,
    config: &LaunchConfig,
    bag_bodies: &[String],
    sensors: &[(String, InputKind)],
    is_default: bool,
) -> Result<(Vec<Box<dyn Node>>, Selection), CliError> {
    let (nodes, selection) = match build_nodes(config, bag_bodies, is_default) {
        Ok(built) => built,
        // Nothing to mesh because the bag offers no body: say why the bag has none.
        Err(e) if bag_bodies.is_empty() => {
            let why = match crate::bag::voxel_frames(bag) {
                Err(why) => why.to_string(),
                Ok(_) => format!("{}: no VoxelGrid topic can be read", bag.display()),
            };
            return Err(CliError::NoBodies {
                why,
                config: e.to_string(),
            });
        }
        Err(e) => return Err(CliError::Usage(e.to_string())),
    };
    // The bag's bodies are VoxelGrid topics: a node that reads one as anything else is
    // refused (a carving `pose_topic` set to a body's topic, say); so are its sensor topics.
    let uses = crate::node::routes::topic_uses(config, &nodes);
    crate::node::routes::check_bag_types(
        &uses,
        bag_bodies
            .iter()
            .map(|t| {
                (
                    t.as_str(),
                    <crate::msg::VoxelGrid as crate::msg::RosMessage>::TYPE_NAME,
                )
            })
            .chain(sensors.iter().map(|(t, k)| (t.as_str(), k.type_name()))),
    )
    .map_err(|e| CliError::Usage(e.to_string()))?;
    Ok((nodes, selection))
}

/// A spinner of the messages read, on a terminal when `progress` asks for one.
fn progress_bar(progress: bool) -> indicatif::ProgressBar {
    if progress && std::io::stderr().is_terminal() {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {elapsed} {pos} messages {msg}")
                .expect("a valid template"),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    }
}

/// Run: every message of the bag read in order and put on the bus (the channel rules of
/// `check`, the types the nodes read), with the bag's log time as the nodes' clock; what the
/// nodes publish goes to `output`. Gives what was read and what the bus could not deliver.
fn deliver_bag(
    bag: &Path,
    bus: &mut Bus,
    output: &mut Option<Output>,
    bar: &indicatif::ProgressBar,
) -> Result<(InputCounts, Vec<Misrouted>), CliError> {
    let mut input = InputCounts::default();
    let mut sink = |m: &Message| {
        if let Some(o) = output.as_mut() {
            o.record(m);
        }
    };
    let mut misrouted = Vec::new();
    let mut last_tick: Option<i64> = None;
    let mut reader = BagReader::open(bag)?;
    let mut gate = Gate::default();
    for item in reader.by_ref() {
        let m = match item {
            Ok(m) => m,
            Err(e) => {
                let fatal = e.is_fatal();
                let then = if fatal {
                    "; using what was read before it"
                } else {
                    "; reading on"
                };
                tracing::error!("{e}{then}");
                input.bag_errors.push(e.to_string());
                if fatal {
                    break;
                }
                continue;
            }
        };
        input.messages += 1;
        bar.inc(1);
        let Some(payload) = gate.admit(&m, bus, &mut input) else {
            continue;
        };
        input.delivered += 1;
        let log_ns = m.log_time_ns.min(i64::MAX as u64) as i64;
        // The transport's clock, as live: the bag's log time, ticked every REPLAY_TICK_NS
        // (a mesher closes a stream whose frames stopped for its idle timeout).
        if last_tick.is_none_or(|t| log_ns.saturating_sub(t) >= REPLAY_TICK_NS) {
            last_tick = Some(log_ns);
            misrouted.extend(bus.put_tick(log_ns, &mut sink));
        }
        misrouted.extend(bus.put(Message::new(&m.topic, log_ns, payload), &mut sink));
    }
    input.refused_topics = gate.refused.into_values().collect();
    input.recovery = Some(reader.recovery().clone());
    Ok((input, misrouted))
}

/// What decides whether a message of the bag reaches the nodes: the channel rules of
/// `check` and the types the nodes read.
#[derive(Default)]
struct Gate {
    /// Each channel's verdict, decided at its first message (the schema text is compared
    /// once).
    verdicts: std::collections::HashMap<u16, Option<String>>,
    /// The VoxelGrid topics whose channel was refused.
    refused: BTreeMap<String, crate::bag::RefusedTopic>,
}

impl Gate {
    /// The payload of `m` for the nodes, or `None` if it is not delivered (counted in
    /// `input`: on a refused channel, on a topic no node reads, of another type than the
    /// node expects, or undecodable).
    fn admit(
        &mut self,
        m: &crate::bag::BagMessage,
        bus: &Bus,
        input: &mut InputCounts,
    ) -> Option<Payload> {
        // The channel rules of `check` (bag::voxel_frames): a VoxelGrid channel is read only
        // in CDR with our schema text.
        if m.schema.is_none()
            || m.schema_name == <crate::msg::VoxelGrid as crate::msg::RosMessage>::TYPE_NAME
        {
            let verdict = self.verdicts.entry(m.channel_id).or_insert_with(|| {
                crate::bag::voxel_channel_refusal(m.schema.as_deref(), &m.message_encoding)
            });
            if let Some(reason) = verdict {
                let first = crate::bag::RefusedTopic::count(
                    &mut self.refused,
                    &m.topic,
                    || reason.clone(),
                    m.log_time_ns,
                );
                if first {
                    tracing::error!(topic = %m.topic, "channel refused: {reason}");
                }
                return None;
            }
        }
        let Some(ty) = bus.expected_type(&m.topic) else {
            input.unused += 1;
            return None;
        };
        if m.schema_name != ty {
            tracing::warn!(topic = %m.topic, "a {} where a {ty} is read; skipped", m.schema_name);
            *input.wrong_type.entry(m.topic.clone()).or_default() += 1;
            return None;
        }
        match Payload::decode(ty, &m.data) {
            Ok(p) => Some(p),
            Err(e) => {
                tracing::warn!(topic = %m.topic, log_time_ns = m.log_time_ns, "skipping message: does not decode: {e}");
                *input.undecodable.entry(m.topic.clone()).or_default() += 1;
                None
            }
        }
    }
}

/// Finish: the nodes publish what they have left (closing meshes, the last check); what
/// the bus could not deliver is counted as of a wrong type; the output bag is completed.
fn finish(
    bus: &mut Bus,
    mut output: Option<Output>,
    mut misrouted: Vec<Misrouted>,
    input: &mut InputCounts,
    bar: &indicatif::ProgressBar,
) -> Result<OutputCounts, CliError> {
    let mut sink = |m: &Message| {
        if let Some(o) = output.as_mut() {
            o.record(m);
        }
    };
    bar.set_message("checking");
    misrouted.extend(bus.finish(&mut sink));
    bar.finish_and_clear();
    for m in misrouted {
        tracing::warn!(topic = %m.topic, "a {} published where a {} is read; not delivered", m.got, m.expected);
        *input.wrong_type.entry(m.topic).or_default() += 1;
    }
    let mut counts = OutputCounts::default();
    if let Some(o) = output {
        counts = o.finish()?;
    }
    Ok(counts)
}

/// Report: the checker's report (an empty one without a checker) with the frames the
/// meshers and the input lost, the bag's problems and the timings; what was read, each
/// node's status and what went into the output bag.
fn replay_report(
    bus: &Bus,
    input: InputCounts,
    output: OutputCounts,
    bodies: &BagBodies,
    start: Instant,
) -> ReplayReport {
    let mut report = bus
        .nodes()
        .iter()
        .find_map(|n| n.as_any().downcast_ref::<CheckerNode>())
        .and_then(|c| c.report().cloned())
        .unwrap_or_else(|| Report {
            schema: "chronotope.report/1",
            time_origin_ns: 0,
            time_scale_m_per_s: 0.0,
            bodies: Vec::new(),
            pairs: Vec::new(),
            resolutions: Vec::new(),
            timings_ms: Default::default(),
            problems: Vec::new(),
            unchecked_pairs: Vec::new(),
        });
    let origin = report.time_origin_ns;
    for b in &mut report.bodies {
        for n in bus.nodes() {
            if let Some(m) = n.as_any().downcast_ref::<MesherNode>() {
                if let Some(l) = m.losses(&b.id) {
                    b.skipped_frames += l.refused_frames;
                    b.filled_frames += l.filled_frames;
                    b.lost_spans
                        .extend(crate::checker::report::LostSpan::of(l, origin));
                }
            }
        }
        b.skipped_frames += input.undecodable.get(&b.id).copied().unwrap_or(0)
            + input.wrong_type.get(&b.id).copied().unwrap_or(0);
    }
    if bodies.over_limit > 0 {
        report.problems.push(format!(
            "{} VoxelGrid topic(s) not read: more than {} (MAX_BODIES) in one bag; \
             their messages are counted as unused",
            bodies.over_limit,
            super::MAX_BODIES
        ));
    }
    if bodies.topics.len() == 1 && report.pairs.is_empty() && report.unchecked_pairs.is_empty() {
        report.problems.push(format!(
            "the bag has one body ({}): no pair to check",
            bodies.topics[0]
        ));
    }
    let total = start.elapsed().as_secs_f64() * 1e3;
    report.timings_ms.total = total;
    report.timings_ms.mesh = (total - report.timings_ms.check - report.timings_ms.resolve).max(0.0);
    let nodes = bus
        .statuses()
        .into_iter()
        .map(|(n, s)| (n.to_owned(), s.clone()))
        .collect();
    ReplayReport {
        report,
        input,
        nodes,
        output,
    }
}

/// One line per resolution: what to do to clear each contact episode, and whether it was
/// verified clear.
pub(crate) fn fix_lines(resolutions: &[crate::checker::report::Resolution]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    for res in resolutions {
        let _ = match res {
            crate::checker::report::Resolution::Translate {
                body,
                vector,
                distance,
                verified_clear,
                episode_s,
                ..
            } => writeln!(
                s,
                "  FIX      {:.3}-{:.3} s: move {body} by ({:+.4}, {:+.4}, {:+.4}) m and {:+.3} s: {:.1} mm deep, {}",
                episode_s[0],
                episode_s[1],
                vector[0],
                vector[1],
                vector[2],
                vector[3],
                distance * 1e3,
                verdict_words(*verified_clear, res.unsure_s())
            ),
            crate::checker::report::Resolution::TimeScale {
                body,
                t0_s,
                scale,
                verified_clear,
                ..
            } => writeln!(
                s,
                "  FIX      or retime {body}: durations after {t0_s:.3} s ×{scale:.3}, {}",
                verdict_words(*verified_clear, res.unsure_s())
            ),
            crate::checker::report::Resolution::Rotate {
                body,
                axis,
                point_m,
                angle_rad,
                verified_clear,
                reason,
                ..
            } => writeln!(
                s,
                "  FIX      or turn {body} by {:+.2}° about ({:.3}, {:.3}, {:.3}) through ({:.4}, {:.4}, {:.4}) m: {}",
                angle_rad.to_degrees(),
                axis[0],
                axis[1],
                axis[2],
                point_m[0],
                point_m[1],
                point_m[2],
                match (verified_clear, reason) {
                    (true, _) => verdict_words(true, res.unsure_s()),
                    (false, Some(why)) => format!("NOT clear: {why}"),
                    (false, None) => "NOT clear when checked again".to_string(),
                }
            ),
        };
    }
    s
}

/// The short human summary: which bodies collide, when, how deep, what to do.
pub fn summary(r: &ReplayReport, bag: &Path) -> String {
    use std::fmt::Write;
    let rep = &r.report;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} messages, {} bodies, {} pairs checked in {:.2} s",
        bag.display(),
        r.input.messages,
        rep.bodies.len(),
        rep.pairs.len(),
        rep.timings_ms.total / 1e3
    );
    for p in &rep.pairs {
        if !p.interfering {
            match p.verdict {
                crate::checker::report::Verdict::Unsure => {
                    let _ = writeln!(
                        s,
                        "  UNSURE   {} x {}: no contact found, but cannot be called clear during {}",
                        p.a,
                        p.b,
                        p.unsure_line()
                    );
                }
                _ => {
                    let _ = writeln!(s, "  clear    {} x {}", p.a, p.b);
                }
            }
            continue;
        }
        let when: Vec<String> = p
            .intervals_s
            .iter()
            .map(|[a, b]| format!("{a:.3}-{b:.3} s"))
            .collect();
        let bound = p
            .first_contact_error_bound_s
            .map_or(String::new(), |e| format!(" (±{e:.3} s)"));
        let _ = writeln!(
            s,
            "  COLLIDE  {} x {}: first contact at {:.3} s{bound}, overlapping during {}; overlap {:.3e} m³·s, {} + {} tets interfere",
            p.a,
            p.b,
            p.first_contact_s.unwrap_or(f64::NAN),
            when.join(", "),
            p.overlap_hypervolume_m3s.unwrap_or(f64::NAN),
            p.labels.a.interference,
            p.labels.b.interference,
        );
    }
    s.push_str(&fix_lines(&rep.resolutions));
    let problems: u64 = r.nodes.values().map(NodeStatus::problem_count).sum::<u64>()
        + r.input.undecodable.values().sum::<u64>()
        + r.input.wrong_type.values().sum::<u64>()
        + r.input.bag_errors.len() as u64;
    if problems > 0 {
        let _ = writeln!(
            s,
            "  {problems} input problem(s): see the report's `input` and `nodes`"
        );
    }
    if let Some(line) = super::integrity_note(r.input.recovery.as_ref()) {
        let _ = writeln!(s, "  {line}");
    }
    s
}

/// How a resolution's verification reads on the console.
fn verdict_words(verified_clear: bool, unsure_s: &[[f64; 2]]) -> String {
    let base = if verified_clear {
        "verified clear"
    } else {
        "NOT clear when checked again"
    };
    if unsure_s.is_empty() {
        return base.to_owned();
    }
    let spans: Vec<String> = unsure_s
        .iter()
        .map(|[a, b]| format!("{a:.3}-{b:.3} s"))
        .collect();
    format!(
        "{base} where observed; not verifiable during {} (a body not observed well enough)",
        spans.join(", ")
    )
}

/// Runs `chronotope replay`.
///
/// # Errors
/// See [`replay`]; also a report that cannot be written.
pub fn run(a: &ReplayArgs) -> Result<(), CliError> {
    let config = a
        .launch
        .as_ref()
        .map(|p| LaunchConfig::read(p))
        .transpose()
        .map_err(|e| CliError::Usage(e.to_string()))?;
    let mut paths = super::paths::Paths::new(a.overwrite).bag(&a.bag);
    if let Some(l) = &a.launch {
        paths = paths.launch_config(l, config.as_ref());
    }
    paths
        .output(
            "--out",
            a.out.as_deref(),
            super::paths::OutputKind::Bag { derived: true },
        )
        .output(
            "--report",
            a.report.as_deref(),
            super::paths::OutputKind::File,
        )
        .check()?;
    let r = replay(&a.bag, config.as_ref(), a.out.as_deref(), true)?;
    print!("{}", summary(&r, &a.bag));
    if let Some(p) = &a.report {
        write_json(p, &r)?;
        println!("  report   {}", p.display());
    }
    if let Some(p) = &a.out {
        let n: u64 = r.output.topics.values().sum();
        println!(
            "  bag      {} ({n} messages on {} topics)",
            p.display(),
            r.output.topics.len()
        );
    }
    Ok(())
}

/// Writes `value` as pretty JSON, creating the directory (complete or not at all; a link at
/// the path is replaced, not followed: [`crate::fsio::write_atomic`]).
///
/// # Errors
/// The file cannot be written.
pub fn write_json(p: &Path, value: &impl Serialize) -> Result<(), CliError> {
    let text = serde_json::to_string_pretty(value).expect("plain data serialises");
    super::write_output(p, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The checker's markers of the four-spheres bag through the bus; with `read_from`,
    /// nothing is read until that input message, then the markers are.
    fn markers(read_from: Option<usize>) -> Vec<Vec<u8>> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let bag = root.join("bags/four-spheres-32-bits.mcap");
        let config = LaunchConfig::read(&root.join("launch_configs/four_spheres.yaml"))
            .expect("the bundled config");
        let bodies = crate::bag::voxel_topics(&bag).expect("the bundled bag");
        let (nodes, _) = build_nodes(&config, &bodies, false).expect("its nodes");
        let mut bus = Bus::new(nodes);
        let mut got = Vec::new();
        let mut sink = |m: &Message| {
            if &*m.topic == "/checker/markers" {
                got.push(m.payload.encode().expect("markers encode"));
            }
        };
        if read_from.is_some() {
            bus.set_demand(|_| false);
        }
        for (i, m) in BagReader::open(&bag).expect("the bag").enumerate() {
            let m = m.expect("a whole bag");
            if read_from == Some(i) {
                bus.set_demand(|t| t == "/checker/markers");
            }
            let Some(ty) = bus.expected_type(&m.topic) else {
                continue;
            };
            let payload = Payload::decode(ty, &m.data).expect("frames decode");
            bus.deliver(
                Message::new(&m.topic, m.log_time_ns as i64, payload),
                &mut sink,
            );
        }
        bus.finish(&mut sink);
        got
    }

    /// Markers asked for while the streams go on come for the slabs from then on, each the
    /// same message as when they were read from the start: no slab seen by some pairs'
    /// checks only is sliced.
    #[test]
    fn markers_read_from_mid_stream_are_the_full_ones_from_there() {
        let full = markers(None);
        let none = markers(Some(usize::MAX));
        assert!(none.is_empty(), "{} built for nobody", none.len());
        let from_mid = markers(Some(30));
        assert!(
            !from_mid.is_empty() && from_mid.len() < full.len(),
            "{} of {}",
            from_mid.len(),
            full.len()
        );
        for (i, m) in from_mid.iter().enumerate() {
            assert!(
                full.contains(m),
                "marker array {i} is not one of the full run's"
            );
        }
        // The last slabs' markers are all there.
        assert_eq!(full.last(), from_mid.last());
    }
}
