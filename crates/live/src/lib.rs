//! The live transport: the suite's sans-I/O nodes on a real DDS wire (RustDDS, with
//! ros2-client for the ROS side of a node: its presence in the graph, its parameters, rosout).
//!
//! Nodes in one process pass messages in memory, on the same
//! [`Bus`](chronotope_node::bus::Bus) a replay uses; a topic goes on the wire when
//! something outside may want it. Mesh pieces, the one big message, cross the wire only
//! when a node that reads them runs in another process.
//!
//! Threads: RustDDS runs its own event loop; a small tokio runtime drives the readers and
//! the ros2-client spinners; every node runs on a thread of its own, fed through its own
//! bounded queue ([`executor`]: drops counted per node and topic, real-time nodes, faults
//! isolated). Every second the transport publishes a `diagnostic_msgs/DiagnosticArray` on
//! `/diagnostics` with each node's counters, problems and CPU use, and its own.
#![warn(missing_docs)]

pub mod executor;
pub mod graph;
pub mod wire;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime};

use futures::StreamExt;
use rustdds::no_key::{DataWriter, SimpleDataReader};
use rustdds::{
    DataWriterStatus, DomainParticipant, DomainParticipantBuilder, StatusEvented, TopicKind,
};
use serde::Serialize;

use chronotope_msg::{
    DiagnosticArray, DiagnosticStatus, Header, KeyValue, RosMessage, TetLabels, Time,
};
use chronotope_node::launch::{NodeSpec, ParamValue, MAX_QUEUE_MB};
use chronotope_node::{is_hidden_topic, Message, Node, NodeStatus, ParamError, TopicRef};
use executor::{Executor, Input, NodeRun, RawSample, UnitOptions, WireOut, DEFAULT_QUEUE_BYTES};
use graph::GraphAnnouncer;
use wire::{dds_topic_name, dds_type_name, RawCdr, RawCdrAdapter, TopicQos};

/// A writer of serialised messages.
pub type RawWriter = DataWriter<RawCdr, RawCdrAdapter>;

/// A writer of the wire, and whether writing to it is worth its cost.
pub struct WireWriter {
    raw: Mutex<RawWriter>,
    guid: rustdds::GUID,
    /// A volatile writer of a large type (VoxelGrid frames, mesh pieces; the large types
    /// kept for late readers, clouds, markers and labels, are transient local and always
    /// written): while no reader on the wire has matched it, nothing would receive or keep
    /// what it writes, so messages are neither encoded nor written (counted as `unread`).
    /// Copying a 128³ frame into CDR and into RustDDS's cache was two thirds of a robot
    /// node's time.
    skip_unread: bool,
    /// Readers on the wire it has matched, from its publication-matched events, drained by
    /// [`Demand::poll`] at every tick (at most 50 ms): a reader that appears receives from
    /// the next poll on, as if it had joined then.
    readers: AtomicI32,
}

impl WireWriter {
    fn new(raw: RawWriter, type_name: &str, qos: TopicQos) -> Arc<Self> {
        Arc::new(Self {
            guid: rustdds::RTPSEntity::guid(&raw),
            raw: Mutex::new(raw),
            skip_unread: is_bulk(type_name) && !qos.transient_local,
            readers: AtomicI32::new(0),
        })
    }

    fn lock(&self) -> MutexGuard<'_, RawWriter> {
        self.raw.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Whether a message written now would reach no reader nor be kept for one.
    fn unread(&self) -> bool {
        self.skip_unread && self.readers.load(Ordering::Relaxed) <= 0
    }

    /// Takes the writer's pending status events: how many readers it has matched.
    fn poll_readers(&self) {
        // A writer busy writing: its events wait for the next poll.
        if let Ok(raw) = self.raw.try_lock() {
            while let Some(st) = raw.try_recv_status() {
                if let DataWriterStatus::PublicationMatched { current, .. } = st {
                    self.readers.store(current.count(), Ordering::Relaxed);
                }
            }
        }
    }
}

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
        setter: Option<crossbeam_channel::Sender<Input>>,
    ) -> Result<ros2_client::Node, LiveError> {
        let (ns, name) = graph::split_fqn(fqn);
        let node_name = ros2_client::NodeName::new(ns, name)
            .map_err(|e| format!("{e:?}"))
            .map_err(dds_err(format!("ROS node {fqn}")))?;
        let mut opts = ros2_client::NodeOptions::new().enable_rosout(true);
        for (k, v) in params {
            opts = opts.declare_parameter(k, ros_param(v));
        }
        // The validator also sees the declarations; it asks the node only once it runs. It
        // answers as ros2-client takes it, in text (`SetParametersResult`): the node's
        // `ParamError` is turned into its message here.
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
                .try_send(Input::Param(ParamRequest {
                    node: node.clone(),
                    name: name.to_owned(),
                    value,
                    reply,
                }))
                .map_err(|_| format!("{name}: {node} is busy or stopping; try again"))?;
            let wait = || answer.recv_timeout(Duration::from_secs(5));
            // The spinner runs on the transport's runtime: let its other tasks (the readers)
            // go on while this waits for the node's thread.
            let answer = match tokio::runtime::Handle::try_current() {
                Ok(h) if h.runtime_flavor() == tokio::runtime::RuntimeFlavor::MultiThread => {
                    tokio::task::block_in_place(wait)
                }
                _ => wait(),
            };
            match answer {
                Ok(r) => r.map_err(|e| e.to_string()),
                Err(_) => Err(format!(
                    "{name}: {node} did not answer within 5 s (busy checking?); try again"
                )),
            }
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

/// A parameter change asked for over ROS, on its way to the node (the node's thread
/// answers on `reply`).
pub struct ParamRequest {
    /// The node's fully qualified name.
    pub node: String,
    /// The parameter.
    pub name: String,
    /// The new value.
    pub value: ParamValue,
    /// Where the node's answer goes.
    pub reply: SyncSender<Result<(), ParamError>>,
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
    /// Messages waiting for one node, all its topics together (unless its `queue_depth`
    /// says otherwise); beyond it new samples are dropped and counted.
    pub queue_capacity: usize,
    /// Bytes (MiB) the messages waiting for one node may hold (unless its `queue_mb` says
    /// otherwise); beyond it new samples are dropped and counted.
    pub queue_mb: usize,
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
            queue_mb: DEFAULT_QUEUE_BYTES >> 20,
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
    /// Samples dropped because a node's queue was full (summed over the nodes reading the
    /// topic; each node's own count is in its [`NodeRun`]).
    pub dropped: BTreeMap<String, u64>,
    /// Samples that did not decode as the topic's type (each node reading the topic decodes
    /// it; counted once).
    pub undecodable: BTreeMap<String, u64>,
    /// Messages written to the wire.
    pub sent: BTreeMap<String, u64>,
    /// Messages of large volatile topics not written because no reader on the wire had
    /// matched their writer (nothing would have received or kept them).
    pub unread: BTreeMap<String, u64>,
    /// Messages that could not be written (and why, the first few).
    pub send_errors: BTreeMap<String, u64>,
    /// Publishers seen on an input topic with another type (DDS does not match them, so
    /// nothing of theirs is read).
    pub wrong_type: BTreeMap<String, u64>,
    /// The first problems' texts.
    pub messages: Vec<String>,
    /// Per input topic: how long a sample took from the reader to the end of its handling
    /// (queue wait, decoding, the node's work, writing what it published); of the node
    /// reading it with the largest p99.
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
    /// Each node's counters and problems, CPU use, drops and lags.
    pub nodes: BTreeMap<String, NodeRun>,
    /// The transport's.
    pub transport: TransportStatus,
}

/// Types whose messages can be large (frames, clouds, meshes, markers, labels): they are
/// written through the process's bulk participant, and a real-time node hands them to a
/// writer thread instead of writing them itself.
fn is_bulk(type_name: &str) -> bool {
    [
        chronotope_msg::VoxelGrid::TYPE_NAME,
        chronotope_msg::PointCloud2::TYPE_NAME,
        chronotope_msg::MeshSlab::TYPE_NAME,
        chronotope_msg::MarkerArray::TYPE_NAME,
        TetLabels::TYPE_NAME,
    ]
    .contains(&type_name)
}

/// Why a message was not written to the wire.
#[derive(Debug, thiserror::Error)]
enum SendError {
    /// It does not encode as CDR.
    #[error(transparent)]
    Encode(#[from] chronotope_msg::CdrError),
    /// The writer refused it.
    #[error(transparent)]
    Write(#[from] rustdds::dds::WriteError<()>),
}

/// Writes a node's messages to DDS on the thread that publishes them.
struct DdsOut {
    writers: BTreeMap<String, Arc<WireWriter>>,
    status: Arc<Mutex<TransportStatus>>,
}

impl DdsOut {
    fn write(&self, m: &Message) {
        let Some(w) = self.writers.get(&*m.topic) else {
            return;
        };
        if w.unread() {
            let mut st = self.status.lock().unwrap_or_else(|p| p.into_inner());
            *st.unread.entry(m.topic.to_string()).or_default() += 1;
            return;
        }
        let r = m
            .payload
            .encode()
            .map_err(SendError::from)
            .and_then(|bytes| write_stamped(&w.lock(), bytes).map_err(SendError::from));
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
}

impl WireOut for DdsOut {
    fn send(&self, m: &Message) {
        self.write(m);
    }
}

/// A real-time node's wire: small messages written at once on its own participant, large
/// ones handed (never waiting: dropped and counted when the hand-off is full) to a writer
/// thread on the main participant.
struct RealtimeOut {
    own: DdsOut,
    /// Topics the writer thread writes (the main participants' writers).
    bulk_topics: BTreeSet<String>,
    bulk: crossbeam_channel::Sender<Message>,
    status: Arc<Mutex<TransportStatus>>,
}

impl WireOut for RealtimeOut {
    fn send(&self, m: &Message) {
        if self.own.writers.contains_key(&*m.topic) {
            self.own.write(m);
            return;
        }
        // Topics the writer thread has no writer for are not for the wire (a hidden topic,
        // mesh pieces no remote node reads).
        if !self.bulk_topics.contains(&*m.topic) {
            return;
        }
        if let Err(e) = self.bulk.try_send(m.clone()) {
            let mut st = self.status.lock().unwrap_or_else(|p| p.into_inner());
            let why = match e {
                crossbeam_channel::TrySendError::Full(_) => "the writer thread is behind",
                crossbeam_channel::TrySendError::Disconnected(_) => "the writer thread has ended",
            };
            st.problem(
                Fault::Dropped,
                &m.topic,
                format!(
                    "{}: not sent: {why} (a real-time node never waits)",
                    m.topic
                ),
            );
        }
    }
}

/// Messages a real-time node's large outputs may queue for the writer thread.
const BULK_QUEUE: usize = 8;

/// A real-time node's own participant: created on a SCHED_FIFO thread, so RustDDS's threads
/// inherit the policy; then that thread reads the node's input topics.
struct RealtimeIo {
    participant: Arc<Participant>,
    own: DdsOut,
    /// Its readers: topic and GUID (for the ROS graph).
    readers: Vec<(String, rustdds::GUID)>,
    start: crossbeam_channel::Sender<executor::Injector>,
    thread: std::thread::JoinHandle<()>,
}

fn start_realtime_io(
    domain_id: u16,
    index: usize,
    inputs: Vec<TopicRef>,
    outputs: Vec<TopicRef>,
    status: Arc<Mutex<TransportStatus>>,
    stop: Arc<AtomicBool>,
) -> Result<RealtimeIo, LiveError> {
    let (ready_tx, ready_rx) = crossbeam_channel::bounded(1);
    let (start_tx, start_rx) = crossbeam_channel::bounded::<executor::Injector>(1);
    let status_out = status.clone();
    let thread = std::thread::Builder::new()
        .name(format!("rt-io {index}"))
        .spawn(move || {
            if let Err(e) = executor::make_realtime(executor::REALTIME_PRIORITY) {
                tracing::warn!("real-time I/O: {e}");
            }
            let setup = (|| -> Result<_, LiveError> {
                let participant = Arc::new(Participant::new(domain_id)?);
                let mut writers = BTreeMap::new();
                for t in &outputs {
                    let qos = TopicQos::for_type(t.type_name);
                    let w = participant.writer(&t.topic, t.type_name, qos)?;
                    writers.insert(t.topic.clone(), WireWriter::new(w, t.type_name, qos));
                }
                let mut readers = Vec::new();
                for t in &inputs {
                    let qos = TopicQos::reader_for_type(t.type_name);
                    readers.push((t.clone(), participant.reader(&t.topic, t.type_name, qos)?));
                }
                Ok((participant, writers, readers))
            })();
            let (participant, writers, readers) = match setup {
                Ok(s) => s,
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                    return;
                }
            };
            let reader_ids = readers
                .iter()
                .map(|(t, r)| (t.topic.clone(), rustdds::RTPSEntity::guid(r)))
                .collect();
            let _ = ready_tx.send(Ok((participant.clone(), writers, reader_ids)));
            let Ok(injector) = start_rx.recv() else {
                return;
            };
            let Ok(rt) = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            else {
                tracing::error!("real-time I/O: cannot start its runtime");
                return;
            };
            rt.block_on(async move {
                for (t, reader) in readers {
                    tokio::spawn(read_into(
                        reader,
                        t,
                        participant.clone(),
                        status.clone(),
                        injector.clone(),
                        vec![index],
                    ));
                }
                while !stop.load(Ordering::Relaxed) {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            });
        })
        .map_err(LiveError::Runtime)?;
    match ready_rx.recv() {
        Ok(Ok((participant, writers, readers))) => Ok(RealtimeIo {
            participant,
            own: DdsOut {
                writers,
                status: status_out,
            },
            readers,
            start: start_tx,
            thread,
        }),
        Ok(Err(e)) => Err(e),
        Err(_) => Err(LiveError::Nothing("the real-time I/O thread ended".into())),
    }
}

/// Reads `topic` from DDS and hands each sample to the nodes `targets` (queued, or dropped
/// and counted per node when a queue is full).
async fn read_into(
    reader: RawReader,
    topic: TopicRef,
    participant: Arc<Participant>,
    status: Arc<Mutex<TransportStatus>>,
    injector: executor::Injector,
    targets: Vec<usize>,
) {
    let name: Arc<str> = topic.topic.as_str().into();
    let mut stream = std::pin::pin!(reader.as_async_stream());
    while let Some(r) = stream.next().await {
        let change = match r {
            Ok(c) => c,
            Err(e) => {
                let mut s = status.lock().unwrap_or_else(|p| p.into_inner());
                s.problem(
                    Fault::Undecodable,
                    &topic.topic,
                    format!("{}: a sample could not be read: {e}", topic.topic),
                );
                continue;
            }
        };
        if participant.is_own(change.writer_guid) {
            continue;
        }
        let at = Instant::now();
        {
            let mut s = status.lock().unwrap_or_else(|p| p.into_inner());
            *s.received.entry(topic.topic.clone()).or_default() += 1;
        }
        let bytes = Arc::new(change.sample.0);
        for &i in &targets {
            injector.inject_to(
                i,
                RawSample {
                    topic: name.clone(),
                    type_name: topic.type_name,
                    bytes: bytes.clone(),
                    at,
                },
            );
        }
    }
}

/// The ROS node (a launch spec's name) a node of the process shows under in the ROS graph:
/// the spec of its own name, else the one it is a part of (`/carving/display` is a part of
/// `/carving`: its topics are `/carving`'s, and it runs where `/carving` runs). `None` for a
/// node no spec names (it is not a ROS node).
fn ros_owner<'a>(name: &str, specs: &'a [NodeSpec]) -> Option<&'a str> {
    specs
        .iter()
        .map(|s| s.fqn.as_str())
        .filter(|f| name == *f || name.strip_prefix(f).is_some_and(|r| r.starts_with('/')))
        .max_by_key(|f| f.len())
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
            (p.type_name != chronotope_msg::MeshSlab::TYPE_NAME && !is_hidden_topic(&p.topic))
                || remote_subscribed.contains(&p.topic)
        })
        .collect();
    (inputs.into_iter().collect(), outputs)
}

/// How long a participant stays in the domain once its reliable readers have acknowledged
/// what it wrote, before it leaves. Acknowledged is not yet read: a RustDDS 0.15 reader (the
/// launch's, `record`'s) forgets a writer's reliable sequence marker when the writer leaves,
/// and with it every sample of that writer the application has not taken yet. A loaded CI
/// host lost the last frame of two of four topics that way, acknowledged by the launch and
/// left by the player a moment later. A reader takes a sample within milliseconds, or
/// within a few hundred on a host whose cores are all busy.
pub const LEAVE_GRACE: Duration = Duration::from_secs(1);

/// How often a live run hands the memory its threads have freed back to the system.
const TRIM_PERIOD: Duration = Duration::from_secs(5);

/// Blocks at least this large get pages of their own from the system (and give them back
/// when freed), in a live launch without a real-time node: 64 MiB, held fixed (see
/// [`keep_resident_memory_flat`]).
const MMAP_THRESHOLD: i32 = 64 * 1024 * 1024;

/// Keeps a long live run's resident memory at what is in use, without paying for it at
/// every frame. glibc raises its mmap threshold each time a mapped block is freed (up to
/// 32 MiB), so after the first few slabs the checker's blocks of a few MB come from the
/// arenas, where freed ones stay resident: a launch checking the 48³ periodic scene climbed
/// in steps from 171–187 MB in its first minute to 265–267 MB after 2.3 minutes. Setting
/// the threshold turns the raising off. At glibc's default, 128 KiB, every frame's blocks
/// of a few MB (a decoded grid, a robot's frame, a slab's mesh) were mapped, faulted in page
/// by page and unmapped again: a third of a 128³ robot launch's CPU went to page faults and
/// unmapping, and its contact latency doubled. At 64 MiB they are taken from the arenas
/// and used again, and the periodic trim ([`trim_heap`], every [`TRIM_PERIOD`]) gives the
/// system back what is free, so memory stays at what is in use over the last period. Left
/// to glibc when `MALLOC_MMAP_THRESHOLD_` is set, and beside a real-time node (not measured
/// there): mapping and unmapping takes the process's address-space lock, which the
/// real-time thread's page faults may have to wait for.
fn keep_resident_memory_flat() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if std::env::var_os("MALLOC_MMAP_THRESHOLD_").is_none() {
        // SAFETY: mallopt only sets a tunable of the allocator.
        let ok = unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD) };
        if ok != 1 {
            tracing::warn!("the allocator refused a fixed mmap threshold");
        }
    }
}

/// Hands the allocator's free pages back to the system (what the arenas hold free below
/// the mmap threshold). It takes 3-30 ms (48³ periodic scene), holding each arena's lock in
/// turn, so a process with a real-time node does not trim.
fn trim_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let t = Instant::now();
        // SAFETY: malloc_trim only returns free memory of the allocator's arenas to the
        // system; it takes each arena's lock in turn.
        unsafe {
            libc::malloc_trim(0);
        }
        tracing::trace!("malloc_trim: {:.2} ms", t.elapsed().as_secs_f64() * 1e3);
    }
}

/// How a live run is asked to end (set from signals by the commands: a first Ctrl-C stops,
/// a second aborts).
#[derive(Debug, Default)]
pub struct Shutdown {
    stop: AtomicBool,
    abort: AtomicBool,
}

impl Shutdown {
    /// Stop: every node handles what is queued for it, then finishes.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Release);
    }

    /// Abort (implies stop): what is queued is discarded and counted, each node finishes
    /// the handler it is in and then finishes; a node still busy
    /// [`executor::ABORT_WAIT`] later is not waited for.
    pub fn abort(&self) {
        self.abort.store(true, Ordering::Release);
        self.stop();
    }

    /// Whether a stop (or an abort) was asked for.
    pub fn stopping(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }

    /// Whether an abort was asked for.
    pub fn aborting(&self) -> bool {
        self.abort.load(Ordering::Acquire)
    }
}

/// Runs `nodes` on the wire, each on its own thread ([`executor`]), until `shutdown` says
/// stop (Ctrl-C) or `opts.run_for` has passed, then finishes them in rank order (closing
/// meshes, a last check), publishes what that gives and waits for reliable readers to
/// acknowledge. An abort (a second Ctrl-C), before or while they finish, discards what is
/// still queued ([`Shutdown::abort`]).
///
/// `specs` are the nodes' launch specs (their ROS names, parameters and executor options).
///
/// # Errors
/// The participant, a reader or a writer cannot be created.
pub fn run_nodes(
    nodes: Vec<Box<dyn Node>>,
    specs: &[NodeSpec],
    opts: &LiveOptions,
    shutdown: Arc<Shutdown>,
) -> Result<LiveSummary, LiveError> {
    if nodes.is_empty() {
        return Err(LiveError::Nothing("no node to run".into()));
    }
    let transport = Transport::start(opts)?;
    let plan = Plan::of(&nodes, specs, opts);
    let writers = Writers::open(&transport, &plan, opts)?;
    let io = node_wires(&nodes, &transport, &plan, &writers, opts)?;
    let watched = watched_publications(&plan, &io.realtime, &writers.main);
    let exec = Executor::start(nodes, &plan.unit_options, io.wires, opts.tick)?;
    let mut demand = Demand::new(
        watched,
        writers
            .main
            .values()
            .chain(io.realtime.iter().flat_map(|r| r.own.writers.values()))
            .cloned(),
    );
    demand.poll(&exec);
    let injector = exec.injector();
    let ros_nodes = start_ros_nodes(&transport, specs, &plan, &exec)?;
    let main_readers = start_readers(&transport, &plan, &exec, &injector, &io.realtime)?;
    let graph = announce_graph(&transport, &plan, &writers, &io.realtime, &main_readers)?;
    tracing::info!(
        nodes = ros_nodes.len(),
        "announced in the ROS graph (ros_discovery_info)"
    );
    // The allocator's settings for a long run (a fixed mmap threshold, trims), not beside a
    // real-time node: a trim holds each arena's lock for up to tens of ms, and the
    // real-time thread may share one.
    let tune_allocator = !plan.unit_options.iter().any(|o| o.realtime);
    let Writers {
        bulk_participant,
        main: main_writers,
        diagnostics,
    } = writers;
    let coordinator = Coordinator {
        participants: std::iter::once(transport.participant.clone())
            .chain(bulk_participant.iter().cloned())
            .chain(io.realtime.iter().map(|io| io.participant.clone()))
            .collect(),
        inputs: plan.inputs,
        diagnostics,
        status: transport.status.clone(),
        wrong_writers: BTreeSet::new(),
        graph,
    };
    let mut running = Running {
        exec,
        demand,
        coordinator,
        ros_nodes,
        realtime: io.realtime,
        bulk_threads: io.bulk_threads,
        main_writers,
        bulk_participant,
        transport,
        tune_allocator,
    };
    running.run_until_stopped(opts, &shutdown);
    Ok(running.shut_down(&shutdown))
}

/// The transport's own parts: the async runtime of its readers and ROS spinners, the main
/// participant, the transport's counters, and the flag that stops the real-time I/O threads.
/// (Fields drop in order: the runtime, whose tasks hold the participant, goes last.)
struct Transport {
    io_stop: Arc<AtomicBool>,
    status: Arc<Mutex<TransportStatus>>,
    participant: Arc<Participant>,
    runtime: tokio::runtime::Runtime,
}

impl Transport {
    /// Runtime setup: starts the async runtime and joins the DDS domain.
    fn start(opts: &LiveOptions) -> Result<Self, LiveError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()?;
        let participant = Arc::new(Participant::new(opts.domain_id)?);
        tracing::info!(domain = participant.domain_id(), "joined the DDS domain");
        Ok(Self {
            io_stop: Arc::new(AtomicBool::new(false)),
            status: Arc::new(Mutex::new(TransportStatus::default())),
            participant,
            runtime,
        })
    }
}

/// What each node needs from the transport, decided from the nodes and their specs before
/// anything is created on the wire.
struct Plan {
    /// Each node's executor options, in node order.
    unit_options: Vec<UnitOptions>,
    /// The parameters each node can change while it runs, by node name.
    runtime_params: BTreeMap<String, Vec<(String, ParamValue)>>,
    /// Topics read from the wire.
    inputs: Vec<TopicRef>,
    /// Topics written to the wire.
    outputs: Vec<TopicRef>,
    /// Per node, in node order: the ROS node it shows under in the graph, what it writes and
    /// what it reads.
    graph: Vec<(Option<String>, Vec<TopicRef>, Vec<TopicRef>)>,
    /// Small outputs that only real-time nodes publish: written on their own participants.
    rt_small: BTreeSet<String>,
}

impl Plan {
    /// Plan: each node's executor options and runtime parameters, the topics read from and
    /// written to the wire, and which outputs real-time nodes write themselves.
    fn of(nodes: &[Box<dyn Node>], specs: &[NodeSpec], opts: &LiveOptions) -> Self {
        // Each node's executor options, from its spec (nodes a spec makes more than one of,
        // such as the carving node's display, share nothing but the spec's name prefix:
        // defaults).
        let unit_options: Vec<UnitOptions> = nodes
            .iter()
            .map(|n| {
                let e = specs
                    .iter()
                    .find(|s| s.fqn == n.name())
                    .and_then(|s| s.executor().ok());
                UnitOptions {
                    realtime: e.is_some_and(|e| e.realtime),
                    queue_depth: e
                        .and_then(|e| e.queue_depth)
                        .unwrap_or(opts.queue_capacity)
                        .max(1),
                    queue_bytes: e
                        .and_then(|e| e.queue_mb)
                        .unwrap_or(opts.queue_mb)
                        .clamp(1, MAX_QUEUE_MB as usize)
                        << 20,
                }
            })
            .collect();
        let runtime_params = nodes
            .iter()
            .map(|n| (n.name().to_owned(), n.runtime_parameters()))
            .collect();
        let (inputs, outputs) = wire_topics(nodes, &opts.remote_subscribed);
        // What each node reads and writes, and the ROS node it shows under in the graph.
        let graph = nodes
            .iter()
            .map(|n| {
                (
                    ros_owner(n.name(), specs).map(str::to_owned),
                    n.publications(),
                    n.subscriptions(),
                )
            })
            .collect();
        // A real-time node writes its small outputs on its own participant: the main one has
        // no writer for them (unless another node publishes the topic too).
        let rt_small = {
            let small = |realtime: bool| -> BTreeSet<String> {
                nodes
                    .iter()
                    .zip(&unit_options)
                    .filter(|(_, o)| o.realtime == realtime)
                    .flat_map(|(n, _)| n.publications())
                    .filter(|p| !is_bulk(p.type_name) && outputs.contains(p))
                    .map(|p| p.topic)
                    .collect()
            };
            let shared = small(false);
            small(true)
                .into_iter()
                .filter(|t| !shared.contains(t))
                .collect()
        };
        Self {
            unit_options,
            runtime_params,
            inputs,
            outputs,
            graph,
            rt_small,
        }
    }
}

/// The writers on the shared participants: every output but those real-time nodes write
/// themselves, and `/diagnostics`. (Fields drop in order: the writers before the participant.)
struct Writers {
    /// The writer of `/diagnostics`, on the main participant.
    diagnostics: RawWriter,
    /// The writers of the outputs, by topic.
    main: BTreeMap<String, Arc<WireWriter>>,
    /// The participant of the large outputs, if there are any.
    bulk_participant: Option<Arc<Participant>>,
}

impl Writers {
    /// Participants and writers: a writer per output on the main participant, or on the bulk
    /// participant for a large type, and the `/diagnostics` writer.
    fn open(transport: &Transport, plan: &Plan, opts: &LiveOptions) -> Result<Self, LiveError> {
        // Large outputs (frames, clouds, meshes, markers, labels) go through a participant of
        // their own: resending their fragments to a slow reader keeps a RustDDS event loop
        // busy for seconds, and the inputs must not wait behind that.
        let bulk_participant = if plan.outputs.iter().any(|t| is_bulk(t.type_name)) {
            Some(Arc::new(Participant::new(opts.domain_id)?))
        } else {
            None
        };
        let main = plan
            .outputs
            .iter()
            .filter(|t| !plan.rt_small.contains(&t.topic))
            .map(|t| {
                let p = match &bulk_participant {
                    Some(b) if is_bulk(t.type_name) => b,
                    _ => &transport.participant,
                };
                let qos = TopicQos::for_type(t.type_name);
                let w = p.writer(&t.topic, t.type_name, qos)?;
                tracing::info!(topic = t.topic, ty = t.type_name, "writing to the wire");
                Ok((t.topic.clone(), WireWriter::new(w, t.type_name, qos)))
            })
            .collect::<Result<_, LiveError>>()?;
        let diagnostics = transport.participant.writer(
            "/diagnostics",
            DiagnosticArray::TYPE_NAME,
            TopicQos::for_type(DiagnosticArray::TYPE_NAME),
        )?;
        Ok(Self {
            diagnostics,
            main,
            bulk_participant,
        })
    }
}

/// How each node's outputs reach the wire, and the threads of the real-time nodes.
struct NodeWires {
    /// Each node's wire, in node order.
    wires: Vec<Arc<dyn WireOut>>,
    /// The real-time nodes' own participants and I/O threads, in node order.
    realtime: Vec<RealtimeIo>,
    /// The real-time nodes' writer threads for their large outputs.
    bulk_threads: Vec<std::thread::JoinHandle<()>>,
}

/// Node wires: a node writes through the shared writers; a real-time node gets its own
/// participant and I/O thread for its inputs and small outputs, and a writer thread on the
/// main participant for its large outputs.
fn node_wires(
    nodes: &[Box<dyn Node>],
    transport: &Transport,
    plan: &Plan,
    writers: &Writers,
    opts: &LiveOptions,
) -> Result<NodeWires, LiveError> {
    let mut wires: Vec<Arc<dyn WireOut>> = Vec::new();
    let mut realtime = Vec::new();
    let mut bulk_threads = Vec::new();
    for (i, n) in nodes.iter().enumerate() {
        let shared_out = || DdsOut {
            writers: writers.main.clone(),
            status: transport.status.clone(),
        };
        if !plan.unit_options[i].realtime {
            wires.push(Arc::new(shared_out()));
            continue;
        }
        let my_inputs: Vec<TopicRef> = n
            .subscriptions()
            .into_iter()
            .filter(|s| plan.inputs.contains(s))
            .collect();
        let small: Vec<TopicRef> = n
            .publications()
            .into_iter()
            .filter(|p| !is_bulk(p.type_name) && plan.outputs.contains(p))
            .collect();
        let io = start_realtime_io(
            opts.domain_id,
            i,
            my_inputs,
            small,
            transport.status.clone(),
            transport.io_stop.clone(),
        )?;
        let (bulk_tx, bulk_rx) = crossbeam_channel::bounded::<Message>(BULK_QUEUE);
        let bulk = shared_out();
        bulk_threads.push(
            std::thread::Builder::new()
                .name(format!("bulk writer {}", n.name()))
                .spawn(move || {
                    for m in bulk_rx {
                        bulk.write(&m);
                    }
                })
                .map_err(LiveError::Runtime)?,
        );
        wires.push(Arc::new(RealtimeOut {
            own: DdsOut {
                writers: io.own.writers.clone(),
                status: transport.status.clone(),
            },
            bulk_topics: writers.main.keys().cloned().collect(),
            bulk: bulk_tx,
            status: transport.status.clone(),
        }));
        tracing::info!(node = n.name(), "real-time: own thread and DDS participant");
        realtime.push(io);
    }
    Ok(NodeWires {
        wires,
        realtime,
        bulk_threads,
    })
}

/// Demand: each node's publications no node of the process reads, with the writer whose
/// readers on the wire decide whether anything does (none: nothing ever reads it).
fn watched_publications(
    plan: &Plan,
    realtime: &[RealtimeIo],
    main_writers: &BTreeMap<String, Arc<WireWriter>>,
) -> Vec<Watched> {
    let local_read: BTreeSet<&str> = plan
        .graph
        .iter()
        .flat_map(|(_, _, subs)| subs.iter().map(|s| s.topic.as_str()))
        .collect();
    let mut rt_of = realtime.iter();
    let mut watched = Vec::new();
    for (i, (_, pubs, _)) in plan.graph.iter().enumerate() {
        let own = if plan.unit_options[i].realtime {
            rt_of.next().map(|io| &io.own.writers)
        } else {
            None
        };
        for p in pubs
            .iter()
            .filter(|p| !local_read.contains(p.topic.as_str()))
        {
            let writer = own
                .and_then(|w| w.get(&p.topic))
                .or_else(|| main_writers.get(&p.topic))
                .cloned();
            watched.push(Watched {
                node: i,
                topic: p.topic.clone(),
                writer,
                said: true,
            });
        }
    }
    watched
}

/// ROS nodes: one per launch spec, declaring the launch's parameters and those its node can
/// change while it runs, spun on the transport's runtime.
fn start_ros_nodes(
    transport: &Transport,
    specs: &[NodeSpec],
    plan: &Plan,
    exec: &Executor,
) -> Result<Vec<ros2_client::Node>, LiveError> {
    let mut ros_nodes = Vec::new();
    for spec in specs {
        // The launch's parameters, and those the node can change while it runs.
        let mut params = spec.params.clone();
        for (k, v) in plan.runtime_params.get(&spec.fqn).into_iter().flatten() {
            params.entry(k.clone()).or_insert_with(|| v.clone());
        }
        let mut n =
            transport
                .participant
                .ros_node(&spec.fqn, &params, exec.param_sender(&spec.fqn))?;
        let spinner = n
            .spinner()
            .map_err(|e| e.to_string())
            .map_err(dds_err(format!("the spinner of {}", spec.fqn)))?;
        transport.runtime.spawn(async move {
            if let Err(e) = spinner.spin().await {
                tracing::warn!("a ROS node's spinner stopped: {e:?}");
            }
        });
        ros_nodes.push(n);
    }
    Ok(ros_nodes)
}

/// A reader on the main participant: its topic, its GUID and the nodes it feeds.
type MainReader = (String, rustdds::GUID, Vec<usize>);

/// Readers: one on the main participant per input topic that a node not real-time reads,
/// feeding the executor; then the real-time nodes' own readers start.
fn start_readers(
    transport: &Transport,
    plan: &Plan,
    exec: &Executor,
    injector: &executor::Injector,
    realtime: &[RealtimeIo],
) -> Result<Vec<MainReader>, LiveError> {
    let mut main_readers = Vec::new();
    for t in &plan.inputs {
        let targets: Vec<usize> = exec
            .readers_of(&t.topic)
            .into_iter()
            .filter(|&(_, rt, ty)| !rt && ty == t.type_name)
            .map(|(i, _, _)| i)
            .collect();
        if targets.is_empty() {
            continue;
        }
        let reader = transport.participant.reader(
            &t.topic,
            t.type_name,
            TopicQos::reader_for_type(t.type_name),
        )?;
        tracing::info!(topic = t.topic, ty = t.type_name, "reading from the wire");
        main_readers.push((
            t.topic.clone(),
            rustdds::RTPSEntity::guid(&reader),
            targets.clone(),
        ));
        transport.runtime.spawn(read_into(
            reader,
            t.clone(),
            transport.participant.clone(),
            transport.status.clone(),
            injector.clone(),
            targets,
        ));
    }
    for io in realtime {
        let _ = io.start.send(injector.clone());
    }
    Ok(main_readers)
}

/// Graph: every endpoint (writers, readers, `/diagnostics`) announced under the ROS node it
/// serves, on `ros_discovery_info`.
fn announce_graph(
    transport: &Transport,
    plan: &Plan,
    writers: &Writers,
    realtime: &[RealtimeIo],
    main_readers: &[MainReader],
) -> Result<GraphAnnouncer, LiveError> {
    let mut graph = GraphAnnouncer::new(&transport.participant)?;
    let diagnostics_id = rustdds::RTPSEntity::guid(&writers.diagnostics);
    let mut rt_ios = realtime.iter();
    for (i, (owner, pubs, subs)) in plan.graph.iter().enumerate() {
        let rt = if plan.unit_options[i].realtime {
            rt_ios.next()
        } else {
            None
        };
        let Some(owner) = owner else {
            continue;
        };
        graph.add_writer(owner, diagnostics_id);
        for p in pubs {
            let own = rt.and_then(|io| io.own.writers.get(&p.topic));
            if let Some(w) = own.or_else(|| writers.main.get(&p.topic)) {
                graph.add_writer(owner, w.guid);
            }
        }
        for s in subs {
            let own = rt.and_then(|io| io.readers.iter().find(|(t, _)| *t == s.topic));
            if let Some((_, id)) = own {
                graph.add_reader(owner, *id);
            }
            for (_, id, _) in main_readers
                .iter()
                .filter(|(t, _, targets)| *t == s.topic && targets.contains(&i))
            {
                graph.add_reader(owner, *id);
            }
        }
    }
    graph.announce(Instant::now());
    Ok(graph)
}

/// A live run once everything has started: what the main loop polls, and what shutting
/// down stops.
struct Running {
    exec: Executor,
    demand: Demand,
    coordinator: Coordinator,
    /// The ROS nodes, in the graph until the nodes have finished.
    ros_nodes: Vec<ros2_client::Node>,
    realtime: Vec<RealtimeIo>,
    bulk_threads: Vec<std::thread::JoinHandle<()>>,
    main_writers: BTreeMap<String, Arc<WireWriter>>,
    bulk_participant: Option<Arc<Participant>>,
    transport: Transport,
    /// Whether the allocator is tuned for a long run (not beside a real-time node).
    tune_allocator: bool,
}

impl Running {
    /// Main loop: until a stop is asked for or `opts.run_for` has passed, polls the ROS
    /// graph and the demand for the nodes' outputs, trims the heap, checks for publishers of
    /// wrong types and publishes `/diagnostics`.
    fn run_until_stopped(&mut self, opts: &LiveOptions, shutdown: &Shutdown) {
        let start = Instant::now();
        let mut last_diag = start;
        let mut last_trim = start;
        if self.tune_allocator {
            keep_resident_memory_flat();
        }
        while !(shutdown.stopping() || opts.run_for.is_some_and(|d| start.elapsed() >= d)) {
            std::thread::sleep(opts.tick.min(Duration::from_millis(50)));
            self.coordinator.graph.poll(Instant::now());
            self.demand.poll(&self.exec);
            if self.tune_allocator && last_trim.elapsed() >= TRIM_PERIOD {
                last_trim = Instant::now();
                trim_heap();
            }
            if last_diag.elapsed() >= opts.diagnostics_period {
                last_diag = Instant::now();
                self.coordinator.check_foreign_types();
                self.coordinator.publish_diagnostics(&self.exec.runs());
            }
        }
    }

    /// Shutdown: the nodes finish in rank order (an abort asked for meanwhile reaches them),
    /// the last diagnostics go out, the I/O threads stop, reliable readers get a moment to
    /// acknowledge, and the participants leave the domain.
    fn shut_down(self, shutdown: &Arc<Shutdown>) -> LiveSummary {
        let Running {
            exec,
            demand,
            mut coordinator,
            ros_nodes,
            realtime,
            bulk_threads,
            main_writers,
            bulk_participant,
            transport,
            tune_allocator: _,
        } = self;
        coordinator.check_foreign_types();
        tracing::info!("stopping: the nodes finish what they have (a second Ctrl-C aborts)");
        let runs = finish_nodes(exec, shutdown);
        coordinator.publish_diagnostics(&runs);
        transport.io_stop.store(true, Ordering::Relaxed);
        for t in bulk_threads {
            let _ = t.join();
        }
        for w in main_writers
            .values()
            .chain(realtime.iter().flat_map(|io| io.own.writers.values()))
        {
            // Reliable samples are resent until acknowledged; give readers a moment.
            let _ = w.lock().wait_for_acknowledgments(Duration::from_secs(2));
        }
        let summary = LiveSummary {
            transport: coordinator.transport(&runs),
            nodes: runs,
        };
        if summary.transport.sent.values().any(|&n| n > 0) {
            std::thread::sleep(LEAVE_GRACE);
        }
        drop(coordinator);
        drop(ros_nodes);
        for io in realtime {
            let _ = io.thread.join();
        }
        let Transport {
            runtime,
            participant,
            ..
        } = transport;
        runtime.shutdown_timeout(Duration::from_millis(500));
        // The writers go before their participants, in the order they always went.
        drop(demand);
        drop(main_writers);
        drop(bulk_participant);
        drop(participant);
        summary
    }
}

/// Finishes the nodes in rank order (at most 30 s a rank) and gives what each did.
fn finish_nodes(exec: Executor, shutdown: &Arc<Shutdown>) -> BTreeMap<String, NodeRun> {
    // An abort asked for while the nodes finish reaches the executor through this watcher.
    let finished = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (aborter, shutdown, finished) = (exec.aborter(), shutdown.clone(), finished.clone());
        std::thread::Builder::new()
            .name("abort watcher".into())
            .spawn(move || {
                while !finished.load(Ordering::Acquire) {
                    if shutdown.aborting() {
                        aborter.abort();
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
            })
            .ok()
    };
    let runs = exec.finish(Duration::from_secs(30));
    finished.store(true, Ordering::Release);
    if let Some(w) = watcher {
        let _ = w.join();
    }
    runs
}

/// A publication no node of the process reads: whether a reader on the wire does.
struct Watched {
    node: usize,
    topic: String,
    writer: Option<Arc<WireWriter>>,
    /// What the node was last told (every publication is read until it is told otherwise).
    said: bool,
}

/// Tells each node which of its publications are read ([`Node::set_demand`]), from the
/// readers its writers have matched, so that nothing builds markers or labels nobody
/// reads. A reader that appears is seen at the next poll (every tick, at most 50 ms).
/// RustDDS has no matched-readers query (`get_matched_subscriptions` is a placeholder that
/// panics): the count comes from each writer's publication-matched events, drained here.
struct Demand {
    watched: Vec<Watched>,
    /// Every writer of the wire, each once (nodes publishing one topic share it).
    writers: Vec<Arc<WireWriter>>,
}

impl Demand {
    fn new(watched: Vec<Watched>, writers: impl IntoIterator<Item = Arc<WireWriter>>) -> Self {
        let mut seen = BTreeSet::new();
        let writers = writers
            .into_iter()
            .filter(|w| seen.insert(w.guid))
            .collect();
        Demand { watched, writers }
    }

    fn poll(&mut self, exec: &Executor) {
        for w in &self.writers {
            w.poll_readers();
        }
        for w in &mut self.watched {
            let read = w
                .writer
                .as_ref()
                .is_some_and(|wr| wr.readers.load(Ordering::Relaxed) > 0);
            if read != w.said && exec.demand(w.node, &w.topic, read) {
                tracing::info!(topic = w.topic, read, "readers on the wire");
                w.said = read;
            }
        }
    }
}

/// The coordinating thread: `/diagnostics`, publishers of wrong types.
struct Coordinator {
    participants: Vec<Arc<Participant>>,
    inputs: Vec<TopicRef>,
    diagnostics: RawWriter,
    status: Arc<Mutex<TransportStatus>>,
    /// Writers already counted as publishing a wrong type.
    wrong_writers: BTreeSet<rustdds::GUID>,
    /// The process's nodes in the ROS graph.
    graph: GraphAnnouncer,
}

impl Coordinator {
    /// Counts, once per writer, publishers on an input topic whose type is not the one the
    /// nodes read: DDS never matches them, so without this their data would vanish silently.
    fn check_foreign_types(&mut self) {
        let Some(main) = self.participants.first() else {
            return;
        };
        let writers: Vec<_> = main
            .foreign_writers()
            .into_iter()
            .filter(|(_, _, g)| !self.participants.iter().any(|p| p.is_own(*g)))
            .collect();
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

    fn publish_diagnostics(&self, runs: &BTreeMap<String, NodeRun>) {
        let now = wall_clock_ns();
        let mut status: Vec<DiagnosticStatus> = runs
            .iter()
            .map(|(name, r)| node_diagnostic(name, r))
            .collect();
        status.push(transport_diagnostic(&self.transport(runs)));
        let msg = DiagnosticArray {
            header: Header {
                stamp: Time::from_nanos(now),
                frame_id: String::new(),
            },
            status,
        };
        match chronotope_msg::encode_cdr(&msg) {
            Ok(bytes) => {
                if let Err(e) = write_stamped(&self.diagnostics, bytes) {
                    tracing::warn!("/diagnostics not sent: {e}");
                }
            }
            Err(e) => tracing::warn!("/diagnostics not encoded: {e}"),
        }
    }

    /// The transport's counters, with the nodes' drops, undecodable samples and lags of the
    /// wire's topics (per topic, the worst node reading it).
    fn transport(&self, runs: &BTreeMap<String, NodeRun>) -> TransportStatus {
        let mut t = self
            .status
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
        for r in runs.values() {
            for (topic, n) in &r.dropped {
                if self.inputs.iter().any(|i| &i.topic == topic) {
                    *t.dropped.entry(topic.clone()).or_default() += n;
                }
            }
            // Every node reading a topic decodes the same samples: a sample counts once.
            for (topic, n) in &r.undecodable {
                let e = t.undecodable.entry(topic.clone()).or_default();
                *e = (*e).max(*n);
            }
            for (topic, l) in &r.lag {
                if !self.inputs.iter().any(|i| &i.topic == topic) {
                    continue;
                }
                let worse = t.lag.get(topic).is_none_or(|old| l.p99_ms > old.p99_ms);
                if worse {
                    t.lag.insert(topic.clone(), l.clone());
                }
            }
        }
        for r in runs.values() {
            for m in &r.status.messages {
                if m.contains("does not decode")
                    && !t.messages.contains(m)
                    && t.messages.len() < NodeStatus::KEPT
                {
                    t.messages.push(m.clone());
                }
            }
        }
        t
    }
}
/// Writes one sample with its source timestamp (now), as ROS 2's middleware does: readers
/// (`ros2 topic delay`, a peer's `SampleInfo`) see when it was published.
///
/// # Errors
/// The writer's error, without the sample it gives back.
pub fn write_stamped(w: &RawWriter, bytes: Vec<u8>) -> Result<(), rustdds::dds::WriteError<()>> {
    w.write(RawCdr(bytes), Some(rustdds::Timestamp::now()))
        .map_err(rustdds::dds::WriteError::forget_data)
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

/// A node's status as ROS diagnostics: WARN once it has counted a problem or dropped a
/// message, ERROR once it is stopped after a fault; with its CPU use.
pub fn node_diagnostic(name: &str, r: &NodeRun) -> DiagnosticStatus {
    let s = &r.status;
    let mut values = vec![
        kv("received", s.received),
        kv("published", s.published),
        kv("thread", r.thread),
        kv("cpu_s", format!("{:.3}", r.cpu_s)),
        kv("cpu_percent", format!("{:.1}", r.cpu_percent)),
        kv("max_batch", r.max_batch),
        kv(
            "queue_peak_mb",
            format!("{:.1}", r.queue_peak_bytes as f64 / f64::from(1 << 20)),
        ),
    ];
    values.extend(r.scheduling.as_ref().map(|s| kv("scheduling", s)));
    values.extend(r.dropped.iter().map(|(t, n)| kv(format!("dropped.{t}"), n)));
    values.extend(
        r.undecodable
            .iter()
            .map(|(t, n)| kv(format!("undecodable.{t}"), n)),
    );
    values.extend(
        r.discarded
            .iter()
            .map(|(t, n)| kv(format!("discarded.{t}"), n)),
    );
    values.extend(r.unfinished.as_ref().map(|w| kv("unfinished", w)));
    for (topic, l) in &r.lag {
        values.push(kv(
            format!("lag_p99_ms.{topic}"),
            format!("{:.3}", l.p99_ms),
        ));
    }
    values.extend(
        s.problems
            .iter()
            .map(|(k, n)| kv(format!("problem.{k}"), n)),
    );
    values.extend(s.messages.last().map(|m| kv("last_problem", m)));
    if let Some(why) = &r.stopped {
        values.push(kv("stopped", why));
        return DiagnosticStatus {
            level: DiagnosticStatus::ERROR,
            name: name.to_owned(),
            message: format!("stopped after a fault ({why}); the other nodes go on"),
            hardware_id: String::new(),
            values,
        };
    }
    let dropped: u64 = r.dropped.values().sum();
    diagnostic(
        name,
        s.problem_count() + dropped,
        "problem(s) or dropped message(s), counted and skipped",
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_s_diagnostics_carry_its_cpu_and_drops_and_turn_error_when_stopped() {
        let mut r = NodeRun {
            thread: "realtime",
            scheduling: Some("SCHED_FIFO 40".into()),
            cpu_s: 1.25,
            cpu_percent: 12.5,
            ..NodeRun::default()
        };
        let d = node_diagnostic("/carving", &r);
        assert_eq!(d.level, DiagnosticStatus::OK);
        let value = |d: &DiagnosticStatus, k: &str| {
            d.values
                .iter()
                .find(|v| v.key == k)
                .map(|v| v.value.clone())
        };
        assert_eq!(value(&d, "cpu_s").as_deref(), Some("1.250"));
        assert_eq!(value(&d, "cpu_percent").as_deref(), Some("12.5"));
        assert_eq!(value(&d, "scheduling").as_deref(), Some("SCHED_FIFO 40"));
        r.dropped.insert("/haptic/pose".into(), 3);
        let d = node_diagnostic("/carving", &r);
        assert_eq!(d.level, DiagnosticStatus::WARN);
        assert_eq!(value(&d, "dropped./haptic/pose").as_deref(), Some("3"));
        r.stopped = Some("panicked: boom".into());
        let d = node_diagnostic("/carving", &r);
        assert_eq!(d.level, DiagnosticStatus::ERROR);
        assert!(d.message.contains("boom"), "{}", d.message);
    }

    #[test]
    fn a_part_of_a_node_shows_under_its_node() {
        let spec = |fqn: &str| NodeSpec {
            kind: chronotope_node::launch::NodeKind::Checker,
            fqn: fqn.to_owned(),
            params: BTreeMap::new(),
            remaps: BTreeMap::new(),
        };
        let specs = [spec("/carving"), spec("/cell/carving"), spec("/checker")];
        assert_eq!(ros_owner("/carving", &specs), Some("/carving"));
        assert_eq!(ros_owner("/carving/display", &specs), Some("/carving"));
        assert_eq!(
            ros_owner("/cell/carving/display", &specs),
            Some("/cell/carving")
        );
        assert_eq!(ros_owner("/carvingx", &specs), None);
        assert_eq!(ros_owner("/mesher", &specs), None);
    }

    #[test]
    fn large_types_are_the_bulk_ones() {
        assert!(is_bulk(chronotope_msg::VoxelGrid::TYPE_NAME));
        assert!(is_bulk(chronotope_msg::PointCloud2::TYPE_NAME));
        assert!(is_bulk(chronotope_msg::MarkerArray::TYPE_NAME));
        assert!(!is_bulk(chronotope_msg::WrenchStamped::TYPE_NAME));
        assert!(!is_bulk(chronotope_msg::InterferenceReport::TYPE_NAME));
    }
}
