//! The live transport: the suite's sans-I/O nodes on a real DDS wire (RustDDS, with
//! ros2-client for the ROS side of a node: its presence in the graph, its parameters, rosout).
//!
//! Nodes in one process pass messages in memory, on the same [`Bus`] a replay uses; a topic
//! goes on the wire when something outside may want it. Mesh pieces, the one big message,
//! cross the wire only when a node that reads them runs in another process.
//!
//! Threads: RustDDS runs its own event loop; a small tokio runtime drives the readers and
//! the ros2-client spinners; the nodes run on one thread of their own, fed through one
//! bounded queue. When the queue is full a new sample is dropped and counted on its topic
//! (a publisher faster than the checker costs messages, never unbounded memory). Every
//! second the transport publishes a `diagnostic_msgs/DiagnosticArray` on `/diagnostics`
//! with each node's counters and problems and its own.

pub mod wire;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

use futures::StreamExt;
use rustdds::no_key::{DataWriter, SimpleDataReader};
use rustdds::{DomainParticipant, DomainParticipantBuilder, TopicKind};
use serde::Serialize;

use crate::msg::{DiagnosticArray, DiagnosticStatus, Header, KeyValue, RosMessage, Time};
use crate::node::bus::Bus;
use crate::node::launch::{NodeSpec, ParamValue};
use crate::node::{Message, Node, NodeStatus, Payload, TopicRef};
use wire::{dds_topic_name, dds_type_name, RawCdr, RawCdrAdapter, TopicQos};

/// A writer of serialised messages.
pub type RawWriter = DataWriter<RawCdr, RawCdrAdapter>;
/// A reader of serialised messages.
pub type RawReader = SimpleDataReader<RawCdr, RawCdrAdapter>;

/// What stopped the live transport from starting or running.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// `ROS_DOMAIN_ID` is not a domain id.
    #[error("ROS_DOMAIN_ID={0:?} is not a domain id (an integer 0..=232)")]
    DomainId(String),
    /// RustDDS or ros2-client refused to create something.
    #[error("DDS: cannot create {what}: {reason}")]
    Dds {
        /// What.
        what: String,
        /// Why.
        reason: String,
    },
    /// The async runtime could not start.
    #[error("cannot start the runtime: {0}")]
    Runtime(#[from] std::io::Error),
    /// Nothing to run.
    #[error("{0}")]
    Nothing(String),
}

fn dds_err(what: impl Into<String>) -> impl FnOnce(String) -> LiveError {
    let what = what.into();
    move |reason| LiveError::Dds { what, reason }
}

/// The DDS domain: `ROS_DOMAIN_ID` if set (and not empty), else 0, as ROS 2 does.
///
/// # Errors
/// It is set to something that is not a domain id.
pub fn domain_id_from_env() -> Result<u16, LiveError> {
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(v) if v.trim().is_empty() => Ok(0),
        Ok(v) => v
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|d| *d <= 232)
            .ok_or(LiveError::DomainId(v)),
        Err(_) => Ok(0),
    }
}

/// One DDS participant: the process's presence on the wire.
pub struct Participant {
    ctx: ros2_client::Context,
    dp: DomainParticipant,
    publisher: rustdds::Publisher,
    subscriber: rustdds::Subscriber,
    topics: Mutex<HashMap<String, rustdds::Topic>>,
    /// The participant's GUID (its prefix is shared by all its writers).
    guid: rustdds::GUID,
}

impl Participant {
    /// Joins `domain_id`, asking the OS for large socket buffers (big reliable samples
    /// arrive as hundreds of fragments at once; the OS may clamp the request).
    ///
    /// # Errors
    /// RustDDS cannot open its sockets.
    pub fn new(domain_id: u16) -> Result<Self, LiveError> {
        let dp = DomainParticipantBuilder::new(domain_id)
            .socket_receive_buffer_size(32 << 20)
            .socket_send_buffer_size(32 << 20)
            .build()
            .map_err(|e| e.to_string())
            .map_err(dds_err("the domain participant"))?;
        let ctx = ros2_client::Context::from_domain_participant(dp.clone())
            .map_err(|e| e.to_string())
            .map_err(dds_err("the ROS context"))?;
        let qos = rustdds::QosPolicyBuilder::new().build();
        let publisher = dp
            .create_publisher(&qos)
            .map_err(|e| e.to_string())
            .map_err(dds_err("a publisher"))?;
        let subscriber = dp
            .create_subscriber(&qos)
            .map_err(|e| e.to_string())
            .map_err(dds_err("a subscriber"))?;
        let guid = rustdds::RTPSEntity::guid(&dp);
        Ok(Self {
            guid,
            ctx,
            dp,
            publisher,
            subscriber,
            topics: Mutex::new(HashMap::new()),
        })
    }

    /// The domain joined.
    pub fn domain_id(&self) -> u16 {
        self.dp.domain_id()
    }

    fn topic(
        &self,
        ros_topic: &str,
        ros_type: &str,
        qos: TopicQos,
    ) -> Result<rustdds::Topic, LiveError> {
        let name = dds_topic_name(ros_topic);
        let mut topics = self.topics.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(t) = topics.get(&name) {
            return Ok(t.clone());
        }
        let t = self
            .dp
            .create_topic(
                name.clone(),
                dds_type_name(ros_type),
                &qos.policies(),
                TopicKind::NoKey,
            )
            .map_err(|e| e.to_string())
            .map_err(dds_err(format!("topic {ros_topic}")))?;
        topics.insert(name, t.clone());
        Ok(t)
    }

    /// A writer of `ros_type` messages on `ros_topic`.
    ///
    /// # Errors
    /// RustDDS refuses (e.g. the topic exists with another type).
    pub fn writer(
        &self,
        ros_topic: &str,
        ros_type: &str,
        qos: TopicQos,
    ) -> Result<RawWriter, LiveError> {
        let t = self.topic(ros_topic, ros_type, qos)?;
        self.publisher
            .create_datawriter_no_key::<RawCdr, RawCdrAdapter>(&t, Some(qos.policies()))
            .map_err(|e| e.to_string())
            .map_err(dds_err(format!("a writer on {ros_topic}")))
    }

    /// A reader of `ros_type` messages on `ros_topic`.
    ///
    /// # Errors
    /// RustDDS refuses.
    pub fn reader(
        &self,
        ros_topic: &str,
        ros_type: &str,
        qos: TopicQos,
    ) -> Result<RawReader, LiveError> {
        let t = self.topic(ros_topic, ros_type, qos)?;
        self.subscriber
            .create_simple_datareader_no_key::<RawCdr, RawCdrAdapter>(&t, Some(qos.policies()))
            .map_err(|e| e.to_string())
            .map_err(dds_err(format!("a reader on {ros_topic}")))
    }

    /// The topics discovered on the wire so far, as `(DDS topic, DDS type)`.
    pub fn discovered_topics(&self) -> Vec<(String, String)> {
        self.ctx
            .discovered_topics_raw()
            .into_iter()
            .map(|d| (d.topic_name().clone(), d.type_name().clone()))
            .collect()
    }

    /// Writers of other participants on the wire, as `(DDS topic, DDS type, writer GUID)`.
    pub fn foreign_writers(&self) -> Vec<(String, String, rustdds::GUID)> {
        self.ctx
            .domain_participant()
            .discovered_writers()
            .into_iter()
            .map(|w| w.publication_topic_data)
            .filter(|p| p.key.prefix != self.guid.prefix)
            .map(|p| (p.topic_name, p.type_name, p.key))
            .collect()
    }

    /// Whether a sample was written by this participant.
    pub fn is_own(&self, writer: rustdds::GUID) -> bool {
        writer.prefix == self.guid.prefix
    }

    /// The ROS node `fqn` (`/ns/name`) with `params` declared: visible to `ros2 node list`,
    /// its parameters listed and read by `ros2 param`. Once it runs, a `set_parameters`
    /// request goes to the node itself through `setter` (applied, or refused with the node's
    /// reason); without a setter every change is refused.
    ///
    /// # Errors
    /// The name is not a valid ROS node name, or ros2-client refuses.
    pub fn ros_node(
        &self,
        fqn: &str,
        params: &BTreeMap<String, ParamValue>,
        setter: Option<SyncSender<ParamRequest>>,
    ) -> Result<ros2_client::Node, LiveError> {
        let (ns, name) = match fqn.rsplit_once('/') {
            Some(("", n)) => ("/", n),
            Some((ns, n)) => (ns, n),
            None => ("/", fqn),
        };
        let node_name = ros2_client::NodeName::new(ns, name)
            .map_err(|e| format!("{e:?}"))
            .map_err(dds_err(format!("ROS node {fqn}")))?;
        let mut opts = ros2_client::NodeOptions::new().enable_rosout(true);
        for (k, v) in params {
            opts = opts.declare_parameter(k, ros_param(v));
        }
        // The validator also sees the declarations; it asks the node only once it runs.
        let running = Arc::new(AtomicBool::new(false));
        let flag = running.clone();
        let node = fqn.to_owned();
        let opts = opts.parameter_validator(Box::new(move |name: &str, value: &_| {
            if !flag.load(Ordering::Relaxed) {
                return Ok(());
            }
            let Some(setter) = &setter else {
                return Err(format!("{name}: {node} takes its parameters at start"));
            };
            let value = from_ros_param(value).ok_or_else(|| {
                format!("{name}: {value:?} is not a type the suite's parameters take")
            })?;
            let (reply, answer) = sync_channel(1);
            setter
                .try_send(ParamRequest {
                    node: node.clone(),
                    name: name.to_owned(),
                    value,
                    reply,
                })
                .map_err(|_| format!("{name}: {node} is busy or stopping; try again"))?;
            let wait = || answer.recv_timeout(Duration::from_secs(5));
            // The spinner runs on the transport's runtime: let its other tasks (the readers)
            // go on while this waits for the nodes' thread.
            let answer = match tokio::runtime::Handle::try_current() {
                Ok(h) if h.runtime_flavor() == tokio::runtime::RuntimeFlavor::MultiThread => {
                    tokio::task::block_in_place(wait)
                }
                _ => wait(),
            };
            answer.unwrap_or_else(|_| {
                Err(format!(
                    "{name}: {node} did not answer within 5 s (busy checking?); try again"
                ))
            })
        }));
        let node = self
            .ctx
            .new_node(node_name, opts)
            .map_err(|e| e.to_string())
            .map_err(dds_err(format!("ROS node {fqn}")))?;
        running.store(true, Ordering::Relaxed);
        Ok(node)
    }
}

/// A parameter change asked for over ROS, on its way to the node (the nodes' thread
/// answers on `reply`).
pub struct ParamRequest {
    /// The node's fully qualified name.
    pub node: String,
    /// The parameter.
    pub name: String,
    /// The new value.
    pub value: ParamValue,
    /// Where the node's answer goes.
    pub reply: SyncSender<Result<(), String>>,
}

fn from_ros_param(v: &ros2_client::ParameterValue) -> Option<ParamValue> {
    use ros2_client::ParameterValue as P;
    Some(match v.clone() {
        P::Boolean(b) => ParamValue::Bool(b),
        P::Integer(i) => ParamValue::Integer(i),
        P::Double(d) => ParamValue::Double(d),
        P::String(s) => ParamValue::String(s),
        P::BooleanArray(v) => ParamValue::BoolArray(v),
        P::IntegerArray(v) => ParamValue::IntegerArray(v),
        P::DoubleArray(v) => ParamValue::DoubleArray(v),
        P::StringArray(v) => ParamValue::StringArray(v),
        P::NotSet | P::ByteArray(_) => return None,
    })
}

/// A launch parameter value as ros2-client's.
pub fn ros_param(v: &ParamValue) -> ros2_client::ParameterValue {
    use ros2_client::ParameterValue as P;
    match v.clone() {
        ParamValue::Bool(b) => P::Boolean(b),
        ParamValue::Integer(i) => P::Integer(i),
        ParamValue::Double(d) => P::Double(d),
        ParamValue::String(s) => P::String(s),
        ParamValue::BoolArray(v) => P::BooleanArray(v),
        ParamValue::IntegerArray(v) => P::IntegerArray(v),
        ParamValue::DoubleArray(v) => P::DoubleArray(v),
        ParamValue::StringArray(v) => P::StringArray(v),
    }
}

/// How the live transport runs.
#[derive(Debug, Clone)]
pub struct LiveOptions {
    /// DDS domain.
    pub domain_id: u16,
    /// Received messages waiting for the nodes, all topics together; beyond it new samples
    /// are dropped and counted.
    pub queue_capacity: usize,
    /// How often the nodes see the clock (idle streams are closed on a tick).
    pub tick: Duration,
    /// How often `/diagnostics` is published.
    pub diagnostics_period: Duration,
    /// Stop after this long (tests, benchmarks); `None` runs until Ctrl-C.
    pub run_for: Option<Duration>,
    /// Topics read by nodes in other processes: mesh pieces on them go on the wire.
    pub remote_subscribed: BTreeSet<String>,
}

impl Default for LiveOptions {
    fn default() -> Self {
        Self {
            domain_id: 0,
            queue_capacity: 256,
            tick: Duration::from_millis(100),
            diagnostics_period: Duration::from_secs(1),
            run_for: None,
            remote_subscribed: BTreeSet::new(),
        }
    }
}

/// What the transport itself saw, per topic.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TransportStatus {
    /// Samples received from the wire.
    pub received: BTreeMap<String, u64>,
    /// Samples dropped because the nodes' queue was full.
    pub dropped: BTreeMap<String, u64>,
    /// Samples that did not decode as the topic's type.
    pub undecodable: BTreeMap<String, u64>,
    /// Messages written to the wire.
    pub sent: BTreeMap<String, u64>,
    /// Messages that could not be written (and why, the first few).
    pub send_errors: BTreeMap<String, u64>,
    /// Publishers seen on an input topic with another type (DDS does not match them, so
    /// nothing of theirs is read).
    pub wrong_type: BTreeMap<String, u64>,
    /// The first problems' texts.
    pub messages: Vec<String>,
    /// Per input topic: how long a sample took from the reader to the end of its handling
    /// (queue wait, decoding, the nodes' work, writing what they published).
    pub lag: BTreeMap<String, LagStats>,
}

/// Lag figures of one input topic, over its last [`LagStats::WINDOW`] samples (max over all).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LagStats {
    /// Samples handled.
    pub handled: u64,
    /// Median lag [ms] over the window.
    pub p50_ms: f64,
    /// 99th percentile lag [ms] over the window.
    pub p99_ms: f64,
    /// Largest lag [ms] of the run.
    pub max_ms: f64,
    /// Median time the nodes spent on one sample [ms] over the window (the rest is queueing).
    pub busy_p50_ms: f64,
    /// Time the nodes spent on samples of this topic [s], in all.
    pub busy_total_s: f64,
}

impl LagStats {
    /// Samples the percentiles are taken over (the latest ones).
    pub const WINDOW: usize = 1024;
}

/// The recent lags of one topic (a bounded ring), from which [`LagStats`] are computed.
#[derive(Debug, Default)]
struct LagWindow {
    handled: u64,
    lag: Vec<f64>,
    busy: Vec<f64>,
    next: usize,
    max: f64,
    busy_total: f64,
}

impl LagWindow {
    fn add(&mut self, lag_s: f64, busy_s: f64) {
        self.handled += 1;
        self.max = self.max.max(lag_s);
        self.busy_total += busy_s;
        if self.lag.len() < LagStats::WINDOW {
            self.lag.push(lag_s);
            self.busy.push(busy_s);
        } else {
            self.lag[self.next] = lag_s;
            self.busy[self.next] = busy_s;
            self.next = (self.next + 1) % LagStats::WINDOW;
        }
    }

    fn stats(&self) -> LagStats {
        let pct = |v: &[f64], q: f64| {
            let mut v = v.to_vec();
            v.sort_by(f64::total_cmp);
            v.get(((v.len() as f64 - 1.0) * q).round() as usize)
                .copied()
                .unwrap_or(0.0)
                * 1e3
        };
        LagStats {
            handled: self.handled,
            p50_ms: pct(&self.lag, 0.5),
            p99_ms: pct(&self.lag, 0.99),
            max_ms: self.max * 1e3,
            busy_p50_ms: pct(&self.busy, 0.5),
            busy_total_s: self.busy_total,
        }
    }
}

/// What went wrong with a sample, for [`TransportStatus`].
#[derive(Debug, Clone, Copy)]
enum Fault {
    Dropped,
    Undecodable,
    NotSent,
    WrongType,
}

impl TransportStatus {
    fn problem(&mut self, kind: Fault, topic: &str, text: String) {
        tracing::warn!(?kind, topic, "{text}");
        let map = match kind {
            Fault::Dropped => &mut self.dropped,
            Fault::Undecodable => &mut self.undecodable,
            Fault::NotSent => &mut self.send_errors,
            Fault::WrongType => &mut self.wrong_type,
        };
        *map.entry(topic.to_owned()).or_default() += 1;
        if self.messages.len() < NodeStatus::KEPT {
            self.messages.push(text);
        }
    }
}

/// What a live run did, when it ends.
#[derive(Debug, Clone, Serialize)]
pub struct LiveSummary {
    /// Each node's counters and problems.
    pub nodes: BTreeMap<String, NodeStatus>,
    /// The transport's.
    pub transport: TransportStatus,
}

struct Sample {
    topic: usize,
    bytes: RawCdr,
    /// When the reader took it from DDS.
    at: Instant,
}

/// Runs `nodes` on the wire until `stop` is set (Ctrl-C) or `opts.run_for` has passed, then
/// finishes them (closing meshes, a last check) and publishes what that gives.
///
/// `specs` are the nodes' launch specs (for their ROS names and parameters).
///
/// # Errors
/// The participant, a reader or a writer cannot be created.
pub fn run_nodes(
    nodes: Vec<Box<dyn Node>>,
    specs: &[NodeSpec],
    opts: &LiveOptions,
    stop: Arc<AtomicBool>,
) -> Result<LiveSummary, LiveError> {
    if nodes.is_empty() {
        return Err(LiveError::Nothing("no node to run".into()));
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()?;
    let participant = Arc::new(Participant::new(opts.domain_id)?);
    tracing::info!(domain = participant.domain_id(), "joined the DDS domain");

    let mut ros_nodes = Vec::new();
    let (param_tx, param_rx) = sync_channel::<ParamRequest>(16);
    for spec in specs {
        // The launch's parameters, and those the node can change while it runs.
        let mut params = spec.params.clone();
        if let Some(node) = nodes.iter().find(|n| n.name() == spec.fqn) {
            for (k, v) in node.runtime_parameters() {
                params.entry(k).or_insert(v);
            }
        }
        let mut n = participant.ros_node(&spec.fqn, &params, Some(param_tx.clone()))?;
        let spinner = n
            .spinner()
            .map_err(|e| e.to_string())
            .map_err(dds_err(format!("the spinner of {}", spec.fqn)))?;
        runtime.spawn(async move {
            if let Err(e) = spinner.spin().await {
                tracing::warn!("a ROS node's spinner stopped: {e:?}");
            }
        });
        ros_nodes.push(n);
    }

    let (inputs, outputs) = wire_topics(&nodes, &opts.remote_subscribed);
    let status = Arc::new(Mutex::new(TransportStatus::default()));
    let (tx, rx) = sync_channel::<Sample>(opts.queue_capacity.max(1));
    for (i, t) in inputs.iter().enumerate() {
        let reader = participant.reader(&t.topic, t.type_name, TopicQos::for_type(t.type_name))?;
        tracing::info!(topic = t.topic, ty = t.type_name, "reading from the wire");
        runtime.spawn(read_topic(
            reader,
            i,
            t.topic.clone(),
            participant.clone(),
            tx.clone(),
            status.clone(),
        ));
    }
    drop(tx);
    let mut writers = BTreeMap::new();
    for t in &outputs {
        let w = participant.writer(&t.topic, t.type_name, TopicQos::for_type(t.type_name))?;
        tracing::info!(topic = t.topic, ty = t.type_name, "writing to the wire");
        writers.insert(t.topic.clone(), w);
    }
    let diagnostics = participant.writer(
        "/diagnostics",
        DiagnosticArray::TYPE_NAME,
        TopicQos::for_type(DiagnosticArray::TYPE_NAME),
    )?;

    let mut pump = Pump {
        bus: Bus::new(nodes),
        lag: inputs.iter().map(|_| LagWindow::default()).collect(),
        participant: participant.clone(),
        wrong_writers: BTreeSet::new(),
        param_rx,
        inputs,
        writers,
        diagnostics,
        status,
    };
    pump.run(rx, opts, &stop);
    let summary = pump.summary();
    drop(pump);
    drop(ros_nodes);
    runtime.shutdown_timeout(Duration::from_millis(500));
    Ok(summary)
}

/// Topics to read from the wire (what local nodes read and no local node writes) and to
/// write to it (everything local nodes write, but mesh pieces no remote node reads).
fn wire_topics(
    nodes: &[Box<dyn Node>],
    remote_subscribed: &BTreeSet<String>,
) -> (Vec<TopicRef>, Vec<TopicRef>) {
    let publications: BTreeSet<TopicRef> = nodes.iter().flat_map(|n| n.publications()).collect();
    let published: BTreeSet<&str> = publications.iter().map(|p| p.topic.as_str()).collect();
    let inputs: BTreeSet<TopicRef> = nodes
        .iter()
        .flat_map(|n| n.subscriptions())
        .filter(|s| !published.contains(s.topic.as_str()))
        .collect();
    let outputs = publications
        .into_iter()
        .filter(|p| {
            p.type_name != crate::msg::MeshSlab::TYPE_NAME || remote_subscribed.contains(&p.topic)
        })
        .collect();
    (inputs.into_iter().collect(), outputs)
}

async fn read_topic(
    reader: RawReader,
    index: usize,
    topic: String,
    participant: Arc<Participant>,
    tx: SyncSender<Sample>,
    status: Arc<Mutex<TransportStatus>>,
) {
    let mut stream = std::pin::pin!(reader.as_async_stream());
    while let Some(r) = stream.next().await {
        let change = match r {
            Ok(c) => c,
            Err(e) => {
                let mut s = status.lock().unwrap_or_else(|p| p.into_inner());
                s.problem(
                    Fault::Undecodable,
                    &topic,
                    format!("{topic}: a sample could not be read: {e}"),
                );
                continue;
            }
        };
        if participant.is_own(change.writer_guid) {
            continue;
        }
        let mut s = status.lock().unwrap_or_else(|p| p.into_inner());
        *s.received.entry(topic.clone()).or_default() += 1;
        match tx.try_send(Sample {
            topic: index,
            bytes: change.sample,
            at: Instant::now(),
        }) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => s.problem(
                Fault::Dropped,
                &topic,
                format!("{topic}: the nodes are behind (queue full): a sample was dropped"),
            ),
            Err(TrySendError::Disconnected(_)) => return,
        }
    }
}

/// The nodes' thread: takes samples, runs the nodes, writes what they publish.
struct Pump {
    bus: Bus,
    inputs: Vec<TopicRef>,
    writers: BTreeMap<String, RawWriter>,
    diagnostics: RawWriter,
    status: Arc<Mutex<TransportStatus>>,
    lag: Vec<LagWindow>,
    participant: Arc<Participant>,
    /// Writers already counted as publishing a wrong type.
    wrong_writers: BTreeSet<rustdds::GUID>,
    /// Parameter changes asked for over ROS.
    param_rx: Receiver<ParamRequest>,
}

impl Pump {
    fn run(&mut self, rx: Receiver<Sample>, opts: &LiveOptions, stop: &AtomicBool) {
        let start = Instant::now();
        let mut last_tick = start;
        let mut last_diag = start;
        loop {
            if stop.load(Ordering::Relaxed) || opts.run_for.is_some_and(|d| start.elapsed() >= d) {
                break;
            }
            match rx.recv_timeout(opts.tick) {
                Ok(s) => self.take(s),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => std::thread::sleep(opts.tick),
            }
            while let Ok(req) = self.param_rx.try_recv() {
                let r = self.bus.set_parameter(&req.node, &req.name, &req.value);
                match &r {
                    Ok(()) => tracing::info!(node = req.node, "parameter {} set", req.name),
                    Err(e) => tracing::warn!(node = req.node, "parameter refused: {e}"),
                }
                let _ = req.reply.send(r);
            }
            if last_tick.elapsed() >= opts.tick {
                last_tick = Instant::now();
                let now_ns = start.elapsed().as_nanos() as i64;
                let mut out = Vec::new();
                self.bus.tick(now_ns, &mut |m| out.push(m.clone()));
                for m in &out {
                    self.send(m);
                }
            }
            if last_diag.elapsed() >= opts.diagnostics_period {
                last_diag = Instant::now();
                self.check_foreign_types();
                self.publish_diagnostics();
            }
        }
        self.check_foreign_types();
        tracing::info!("stopping: the nodes finish what they have");
        let mut out = Vec::new();
        self.bus.finish(&mut |m| out.push(m.clone()));
        for m in &out {
            self.send(m);
        }
        self.publish_diagnostics();
        for w in self.writers.values() {
            // Reliable samples are resent until acknowledged; give readers a moment.
            let _ = w.wait_for_acknowledgments(Duration::from_secs(2));
        }
    }

    fn take(&mut self, s: Sample) {
        let Some(t) = self.inputs.get(s.topic) else {
            return;
        };
        let busy = Instant::now();
        match Payload::decode(t.type_name, &s.bytes.0) {
            Ok(payload) => {
                let msg = Message::new(&t.topic, wall_clock_ns(), payload);
                let mut out = Vec::new();
                self.bus.deliver(msg, &mut |m| out.push(m.clone()));
                for m in &out {
                    self.send(m);
                }
                if let Some(w) = self.lag.get_mut(s.topic) {
                    w.add(s.at.elapsed().as_secs_f64(), busy.elapsed().as_secs_f64());
                }
            }
            Err(e) => {
                let mut st = self.status.lock().unwrap_or_else(|p| p.into_inner());
                st.problem(
                    Fault::Undecodable,
                    &t.topic,
                    format!(
                        "{}: a sample does not decode as {}: {e}",
                        t.topic, t.type_name
                    ),
                );
            }
        }
    }

    /// Counts, once per writer, publishers on an input topic whose type is not the one the
    /// nodes read: DDS never matches them, so without this their data would vanish silently.
    fn check_foreign_types(&mut self) {
        let writers = self.participant.foreign_writers();
        for t in &self.inputs {
            let (topic, want) = (dds_topic_name(&t.topic), dds_type_name(t.type_name));
            for (_, ty, guid) in writers
                .iter()
                .filter(|(n, ty, _)| *n == topic && *ty != want)
            {
                if self.wrong_writers.insert(*guid) {
                    let mut st = self.status.lock().unwrap_or_else(|p| p.into_inner());
                    st.problem(
                        Fault::WrongType,
                        &t.topic,
                        format!(
                            "{}: a publisher writes {}, not {}: its samples are not read",
                            t.topic,
                            wire::ros_type_name(ty).unwrap_or_else(|| ty.clone()),
                            t.type_name
                        ),
                    );
                }
            }
        }
    }

    fn send(&self, m: &Message) {
        let Some(w) = self.writers.get(&*m.topic) else {
            return;
        };
        let r = m
            .payload
            .encode()
            .map_err(|e| e.to_string())
            .and_then(|bytes| write_stamped(w, bytes));
        let mut st = self.status.lock().unwrap_or_else(|p| p.into_inner());
        match r {
            Ok(()) => *st.sent.entry(m.topic.to_string()).or_default() += 1,
            Err(e) => st.problem(
                Fault::NotSent,
                &m.topic,
                format!("{}: not sent: {e}", m.topic),
            ),
        }
    }

    fn publish_diagnostics(&self) {
        let now = wall_clock_ns();
        let mut status: Vec<DiagnosticStatus> = self
            .bus
            .statuses()
            .into_iter()
            .map(|(name, s)| node_diagnostic(name, s))
            .collect();
        status.push(transport_diagnostic(&self.transport()));
        let msg = DiagnosticArray {
            header: Header {
                stamp: Time::from_nanos(now),
                frame_id: String::new(),
            },
            status,
        };
        match crate::msg::encode_cdr(&msg) {
            Ok(bytes) => {
                if let Err(e) = write_stamped(&self.diagnostics, bytes) {
                    tracing::warn!("/diagnostics not sent: {e}");
                }
            }
            Err(e) => tracing::warn!("/diagnostics not encoded: {e}"),
        }
    }

    /// The transport's counters, with the lag figures so far.
    fn transport(&self) -> TransportStatus {
        let mut transport = self
            .status
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
        transport.lag = self
            .inputs
            .iter()
            .zip(&self.lag)
            .filter(|(_, w)| w.handled > 0)
            .map(|(t, w)| (t.topic.clone(), w.stats()))
            .collect();
        transport
    }

    fn summary(&self) -> LiveSummary {
        LiveSummary {
            nodes: self
                .bus
                .statuses()
                .into_iter()
                .map(|(n, s)| (n.to_owned(), s.clone()))
                .collect(),
            transport: self.transport(),
        }
    }
}

/// Writes one sample with its source timestamp (now), as ROS 2's middleware does: readers
/// (`ros2 topic delay`, a peer's `SampleInfo`) see when it was published.
///
/// # Errors
/// The writer's error, as text.
pub fn write_stamped(w: &RawWriter, bytes: Vec<u8>) -> Result<(), String> {
    w.write(RawCdr(bytes), Some(rustdds::Timestamp::now()))
        .map_err(|e| e.to_string())
}

fn wall_clock_ns() -> i64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64)
}

fn kv(key: impl Into<String>, value: impl ToString) -> KeyValue {
    KeyValue {
        key: key.into(),
        value: value.to_string(),
    }
}

/// A diagnostic status: OK, or WARN with `summary` once `problems` were counted.
fn diagnostic(name: &str, problems: u64, summary: &str, values: Vec<KeyValue>) -> DiagnosticStatus {
    let (level, message) = if problems == 0 {
        (DiagnosticStatus::OK, "ok".to_owned())
    } else {
        (DiagnosticStatus::WARN, format!("{problems} {summary}"))
    };
    DiagnosticStatus {
        level,
        name: name.to_owned(),
        message,
        hardware_id: String::new(),
        values,
    }
}

/// A node's status as ROS diagnostics: WARN once it has counted a problem.
pub fn node_diagnostic(name: &str, s: &NodeStatus) -> DiagnosticStatus {
    let mut values = vec![kv("received", s.received), kv("published", s.published)];
    values.extend(
        s.problems
            .iter()
            .map(|(k, n)| kv(format!("problem.{k}"), n)),
    );
    values.extend(s.messages.last().map(|m| kv("last_problem", m)));
    diagnostic(
        name,
        s.problem_count(),
        "problem(s), counted and skipped",
        values,
    )
}

fn transport_diagnostic(t: &TransportStatus) -> DiagnosticStatus {
    let mut values = Vec::new();
    for (kind, map) in [
        ("received", &t.received),
        ("dropped", &t.dropped),
        ("undecodable", &t.undecodable),
        ("sent", &t.sent),
        ("send_errors", &t.send_errors),
        ("wrong_type", &t.wrong_type),
    ] {
        values.extend(
            map.iter()
                .map(|(topic, n)| kv(format!("{kind}.{topic}"), n)),
        );
    }
    for (topic, l) in &t.lag {
        values.push(kv(
            format!("lag_p99_ms.{topic}"),
            format!("{:.3}", l.p99_ms),
        ));
        values.push(kv(
            format!("lag_max_ms.{topic}"),
            format!("{:.3}", l.max_ms),
        ));
    }
    let problems: u64 = [&t.dropped, &t.undecodable, &t.send_errors, &t.wrong_type]
        .iter()
        .flat_map(|m| m.values())
        .sum();
    values.extend(t.messages.last().map(|m| kv("last_problem", m)));
    diagnostic(
        "chronotope/transport",
        problems,
        "sample(s) dropped, undecodable or not sent, or publisher(s) of a wrong type",
        values,
    )
}
