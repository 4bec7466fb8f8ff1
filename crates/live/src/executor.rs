//! The live executor: every node on a thread of its own, fed through its own bounded queue.
//!
//! The model is rclcpp's multi-threaded executor with one mutually exclusive callback group
//! per node: a node's handlers never run concurrently with each other (the node is a plain
//! state machine), while different nodes run at once on different cores.
//!
//! - **Queues.** Each node has a bounded queue: at most `queue_depth` messages and
//!   `queue_bytes` bytes ([`Payload::queue_bytes`]), all its topics together, counted from
//!   when a message is queued until the node has handled it. A message larger than the whole
//!   budget is taken only into an empty queue. A sample from the wire that finds the queue
//!   full (either bound) is dropped and counted for that node and topic.
//!   A message from another node in the process waits for room (back-pressure: mesh pieces
//!   are not dropped between a mesher and a checker that is busy with earlier ones) for as
//!   long as the reading node is at work: in a handler, or itself waiting for a node that
//!   is. Once it has made no such progress for [`LOCAL_SEND_WAIT`] in all (it is stuck, or
//!   waits on the sender in a cycle), the message is dropped and counted. The publisher's own queue meanwhile fills, so a
//!   pipeline that cannot keep up loses samples at its entry, where they are counted and the
//!   mesher sees a gap, not pieces in the middle. A real-time node's messages never wait
//!   (dropped and counted when the queue is full).
//! - **Batches.** When a node takes a message, it takes what else is waiting in its queue
//!   too, one message per topic (at most [`MAX_BATCH`]), and handles them as one batch
//!   ([`Node::on_messages`]), so a node that can (the mesher's bodies) works on them in
//!   parallel. One per topic keeps what a batch publishes before it is routed to one
//!   message's worth per topic (a mesher behind by 30 frames of a big body would otherwise
//!   hold 30 mesh pieces at once).
//! - **Real-time nodes** (`realtime: true`) run at SCHED_FIFO priority where the system
//!   allows it (the result is reported in `/diagnostics` and the summary), on a thread
//!   nothing else uses, and their wire traffic goes through a DDS participant of their own,
//!   so a large message of another node never queues in front of theirs.
//! - **Faults.** A node whose handler panics is stopped: the panic is caught, counted and
//!   reported (`/diagnostics` ERROR, the summary's `stopped`), the messages sent to it after
//!   that are counted as dropped, and every other node goes on.
//! - **Finishing.** On stop, nodes finish in increasing [`Node::rank`]: a rank's nodes
//!   finish (each after the messages already in its queue) and what they publish reaches the
//!   next rank's queues before that rank is told to finish, as on the in-process bus.
//! - **Aborting** ([`Executor::aborter`], a second Ctrl-C): what waits in the queues, and
//!   whatever is sent or comes from the wire after, is discarded and counted per node and
//!   topic; each node finishes the handler it is in, then finishes (its last answers on what
//!   it handled). A node still busy [`ABORT_WAIT`] after the abort is not waited for.
//!
//! The executor knows nothing of DDS: the wire is behind [`WireOut`] (what a node publishes
//! that leaves the process) and [`Executor::inject`] (what comes in), so the tests run it
//! in memory.

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{
    bounded, Receiver, RecvTimeoutError, SendTimeoutError, Sender, TrySendError,
};
use serde::Serialize;

use super::{LagStats, ParamRequest};
use chronotope_node::{Message, Node, NodeStatus, ParamError, Payload};

/// Longest a message from one node waits for room in another node's queue, counting only
/// the time that node does no work, before it is dropped and counted (a non-real-time
/// publisher only).
pub const LOCAL_SEND_WAIT: Duration = Duration::from_secs(2);

/// How often a waiting publisher looks whether the reading node is still at work.
const LOCAL_SEND_POLL: Duration = Duration::from_millis(50);

/// How often a publisher waiting for room in a queue's byte budget looks again.
const BYTES_POLL: Duration = Duration::from_millis(2);

/// What a node is doing, as a publisher waiting for room in its queue sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum NodeState {
    /// In one of its handlers.
    Working,
    /// Between handlers.
    Idle,
    /// Waiting for room in node `n`'s queue (at work as long as `n` is).
    WaitingFor(usize),
}

/// A node's [`NodeState`], shared between threads in one atomic word.
struct StateCell(AtomicUsize);

impl StateCell {
    /// The word of `Working` and `Idle` (node indices are far below them).
    const WORKING: usize = usize::MAX - 1;
    const IDLE: usize = usize::MAX;

    fn new() -> Self {
        Self(AtomicUsize::new(Self::IDLE))
    }

    fn get(&self) -> NodeState {
        match self.0.load(Ordering::Relaxed) {
            Self::WORKING => NodeState::Working,
            Self::IDLE => NodeState::Idle,
            n => NodeState::WaitingFor(n),
        }
    }

    fn set(&self, state: NodeState) {
        let word = match state {
            NodeState::Working => Self::WORKING,
            NodeState::Idle => Self::IDLE,
            NodeState::WaitingFor(n) => n,
        };
        self.0.store(word, Ordering::Relaxed);
    }
}

/// Why a message from one node was not delivered to another.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
enum SendFailure {
    /// The run is aborted (the message is discarded and counted as such).
    #[error("the run is aborted")]
    Aborted,
    /// The reading node has ended.
    #[error("it has ended")]
    Ended,
    /// A real-time publisher found the queue full.
    #[error("its queue is full")]
    QueueFull,
    /// A real-time publisher found the queue holding its byte budget.
    #[error("its queue holds its queue_mb")]
    OverBudget,
    /// The queue stayed full while the reading node did no work.
    #[error("its queue stayed full while it did no work for LOCAL_SEND_WAIT")]
    StayedFull,
}

/// How long [`Executor::finish`] still waits for a node once the run is aborted.
pub const ABORT_WAIT: Duration = Duration::from_secs(2);

/// Most messages a node takes from its queue in one batch.
pub const MAX_BATCH: usize = 64;

/// SCHED_FIFO priority of real-time nodes' threads (1..=99; below the kernel's own
/// real-time threads at 99 and typical IRQ threads at 50).
pub const REALTIME_PRIORITY: i32 = 40;

/// Where a node's published messages go when they leave the process.
pub trait WireOut: Send + Sync {
    /// Writes `m` to the wire if its topic goes there (counted by the implementation).
    fn send(&self, m: &Message);
}

/// A wire that takes nothing (in-process runs and tests).
pub struct NoWire;

impl WireOut for NoWire {
    fn send(&self, _m: &Message) {}
}

/// A serialised sample from the wire, decoded on the node's thread.
pub struct RawSample {
    /// The topic.
    pub topic: Arc<str>,
    /// The type the node reads on it.
    pub type_name: &'static str,
    /// CDR bytes with the encapsulation header (shared by every node that reads the topic).
    pub bytes: Arc<Vec<u8>>,
    /// When the reader took it from DDS.
    pub at: Instant,
}

/// What a node's queue carries.
pub enum Input {
    /// A sample from the wire.
    Wire(RawSample),
    /// A message another node of the process published.
    Local(Message, Instant),
    /// A parameter change asked for over ROS.
    Param(ParamRequest),
    /// Whether anything reads one of the node's publications now ([`Node::set_demand`]).
    Demand(String, bool),
    /// The inputs have ended: finish, then acknowledge.
    Finish(Sender<()>),
    /// End the thread.
    Stop,
}

/// How one node runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnitOptions {
    /// See [`chronotope_node::launch::ExecutorSpec::realtime`].
    pub realtime: bool,
    /// Its queue's capacity in messages.
    pub queue_depth: usize,
    /// Its queue's capacity in bytes ([`Payload::queue_bytes`]), from when a message is
    /// queued until it has been handled.
    pub queue_bytes: usize,
}

/// Default of [`UnitOptions::queue_bytes`]: 512 MiB.
pub const DEFAULT_QUEUE_BYTES: usize = 512 << 20;

/// What the executor reports of one node.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct NodeRun {
    /// The node's own counters and problems.
    #[serde(flatten)]
    pub status: NodeStatus,
    /// `"shared"` or `"realtime"`.
    pub thread: &'static str,
    /// For a real-time node: `SCHED_FIFO <priority>`, or why the system refused it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scheduling: Option<String>,
    /// CPU time of the node's thread (s): its handlers, decoding, and its writes.
    pub cpu_s: f64,
    /// Its share of one core over the last diagnostics period, in percent.
    pub cpu_percent: f64,
    /// Messages for it dropped because its queue was full (or it was stopped), per topic.
    pub dropped: BTreeMap<String, u64>,
    /// Messages for it that did not decode as the topic's type, per topic.
    pub undecodable: BTreeMap<String, u64>,
    /// Per input topic: from the reader (or the publishing node) to the end of its handling.
    pub lag: BTreeMap<String, LagStats>,
    /// Largest batch it took at once.
    pub max_batch: usize,
    /// Most bytes its queue held at once (queued or being handled, [`Payload::queue_bytes`]).
    pub queue_peak_bytes: usize,
    /// Why it was stopped (a panic's message), if it was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped: Option<String>,
    /// Messages for it discarded unhandled because the run was aborted, per topic.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub discarded: BTreeMap<String, u64>,
    /// Set when the run was aborted before the node finished (it was still in a handler
    /// [`ABORT_WAIT`] after the abort): its last answers were not published.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unfinished: Option<String>,
}

/// The recent lags of one topic (a bounded ring), from which [`LagStats`] are computed.
#[derive(Debug, Default, Clone)]
pub(crate) struct LagWindow {
    pub(crate) handled: u64,
    lag: Vec<f64>,
    busy: Vec<f64>,
    next: usize,
    max: f64,
    busy_total: f64,
}

impl LagWindow {
    pub(crate) fn add(&mut self, lag_s: f64, busy_s: f64) {
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

    pub(crate) fn stats(&self) -> LagStats {
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

/// A node's figures as its thread keeps them; the coordinator reads a copy.
struct Shared {
    run: NodeRun,
    lag: BTreeMap<String, LagWindow>,
    cpu_at_last: (Instant, f64),
}

struct UnitHandle {
    name: String,
    rank: u8,
    realtime: bool,
    tx: Sender<Input>,
    shared: Arc<Mutex<Shared>>,
    thread: Option<JoinHandle<()>>,
}

/// Routes between the nodes of the process: by topic, the queues of the nodes reading it.
struct Routes {
    by_topic: BTreeMap<String, Vec<(usize, &'static str)>>,
    queues: Vec<(Sender<Input>, Arc<Mutex<Shared>>)>,
    /// Per node: what it is doing.
    state: Vec<StateCell>,
    /// Per node: bytes of the messages queued for it or in its handler now, its budget, and
    /// the most it held.
    bytes: Vec<QueueBytes>,
    names: Vec<String>,
    /// Set once the run is aborted: queued and new messages are discarded.
    abort: AtomicBool,
}

/// Aborts a run ([`Executor::aborter`]).
#[derive(Clone)]
pub struct Aborter(Arc<Routes>);

impl Aborter {
    /// From now on, what waits in the nodes' queues and whatever comes is discarded
    /// (counted); [`Executor::finish`] waits at most [`ABORT_WAIT`] more for a node.
    pub fn abort(&self) {
        if !self.0.abort.swap(true, Ordering::AcqRel) {
            tracing::warn!("aborting: queued messages are discarded (counted)");
        }
    }
}

/// Nodes running on their threads.
pub struct Executor {
    units: Vec<UnitHandle>,
    routes: Arc<Routes>,
    start: Instant,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// CPU time of the calling thread (s).
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if r == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        0.0
    }
}

/// Why the system refused real-time scheduling ([`make_realtime`]).
#[derive(Debug, thiserror::Error)]
#[error(
    "SCHED_FIFO {priority} refused ({reason}): normal priority on its own thread; grant \
     CAP_SYS_NICE or an rtprio limit (ulimit -r) for real-time scheduling"
)]
pub struct RealtimeRefused {
    /// The priority asked for.
    pub priority: i32,
    /// The system's answer.
    #[source]
    pub reason: std::io::Error,
}

/// Puts the calling thread at SCHED_FIFO `priority`: `Ok("SCHED_FIFO 40")`, the scheduling
/// as diagnostics show it, or why not (without CAP_SYS_NICE or an rtprio limit the system
/// refuses; the node then runs at normal priority, still on its own thread). Threads it
/// starts afterwards inherit the policy.
///
/// # Errors
/// [`RealtimeRefused`] with the system's reason.
pub fn make_realtime(priority: i32) -> Result<String, RealtimeRefused> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: pthread_self is always valid; param is a valid sched_param.
    let r = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if r == 0 {
        Ok(format!("SCHED_FIFO {priority}"))
    } else {
        Err(RealtimeRefused {
            priority,
            reason: std::io::Error::from_raw_os_error(r),
        })
    }
}

/// One node's queue in bytes (see [`UnitOptions::queue_bytes`]).
struct QueueBytes {
    held: AtomicUsize,
    budget: usize,
    peak: AtomicUsize,
}

impl QueueBytes {
    fn new(budget: usize) -> Self {
        Self {
            held: AtomicUsize::new(0),
            budget,
            peak: AtomicUsize::new(0),
        }
    }

    /// Counts `n` more bytes if they fit the budget (or the queue holds nothing).
    fn reserve(&self, n: usize) -> bool {
        let r = self
            .held
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |held| {
                (held == 0 || held.saturating_add(n) <= self.budget).then(|| held.saturating_add(n))
            });
        match r {
            Ok(before) => {
                self.peak
                    .fetch_max(before.saturating_add(n), Ordering::Relaxed);
                true
            }
            Err(_) => false,
        }
    }

    fn release(&self, n: usize) {
        // Saturating: a release never takes more than was reserved for the same inputs.
        let _ = self
            .held
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |held| {
                Some(held.saturating_sub(n))
            });
    }
}

impl Input {
    /// The topic of a message (none for a control input).
    fn topic(&self) -> Option<&str> {
        match self {
            Input::Wire(s) => Some(&s.topic),
            Input::Local(m, _) => Some(&m.topic),
            Input::Param(_) | Input::Demand(..) | Input::Finish(_) | Input::Stop => None,
        }
    }

    /// What the input counts against its node's byte budget.
    fn queue_bytes(&self) -> usize {
        match self {
            Input::Wire(s) => s.bytes.len() + chronotope_node::MESSAGE_OVERHEAD_BYTES,
            Input::Local(m, _) => m.payload.queue_bytes(),
            Input::Param(_) | Input::Demand(..) | Input::Finish(_) | Input::Stop => 0,
        }
    }
}

impl Routes {
    fn aborted(&self) -> bool {
        self.abort.load(Ordering::Acquire)
    }

    /// Counts a message for node `to` on `topic` discarded by the abort.
    fn discard(&self, to: usize, topic: &str) {
        let mut s = lock(&self.queues[to].1);
        *s.run.discarded.entry(topic.to_owned()).or_default() += 1;
    }

    /// Whether node `n` is at work: in a handler, or waiting for room at a node that is
    /// (followed along the chain; a cycle of waits is no work).
    fn at_work(&self, mut n: usize) -> bool {
        for _ in 0..self.state.len() {
            match self.state[n].get() {
                NodeState::Working => return true,
                NodeState::Idle => return false,
                NodeState::WaitingFor(next) => n = next,
            }
        }
        false
    }

    /// Sends `input` from node `from` to node `to`, waiting for room while `to` is at work
    /// (see the module doc); gives up once it has not been for [`LOCAL_SEND_WAIT`] in all.
    fn send_waiting(
        &self,
        from: usize,
        to: usize,
        tx: &Sender<Input>,
        mut input: Input,
    ) -> Result<(), SendFailure> {
        let bytes = input.queue_bytes();
        let budget = &self.bytes[to];
        let mut idle = Duration::ZERO;
        let r = loop {
            if self.aborted() {
                break Err(SendFailure::Aborted);
            }
            let waited = if budget.reserve(bytes) {
                match tx.send_timeout(input, LOCAL_SEND_POLL) {
                    Ok(()) => break Ok(()),
                    Err(SendTimeoutError::Disconnected(_)) => {
                        budget.release(bytes);
                        break Err(SendFailure::Ended);
                    }
                    Err(SendTimeoutError::Timeout(back)) => {
                        budget.release(bytes);
                        input = back;
                        LOCAL_SEND_POLL
                    }
                }
            } else {
                // Over the byte budget: wait for the node to finish what it holds.
                std::thread::sleep(BYTES_POLL);
                BYTES_POLL
            };
            self.state[from].set(NodeState::WaitingFor(to));
            if !self.at_work(to) {
                idle += waited;
                if idle >= LOCAL_SEND_WAIT {
                    break Err(SendFailure::StayedFull);
                }
            }
        };
        self.state[from].set(NodeState::Idle);
        r
    }

    /// Delivers `out` (published by node `from`) to the nodes reading each topic, then to
    /// the wire.
    fn route(&self, from: usize, realtime: bool, out: &mut Vec<Message>, wire: &dyn WireOut) {
        for m in out.drain(..) {
            if let Some(subs) = self.by_topic.get(&*m.topic) {
                for &(to, ty) in subs {
                    if to == from {
                        continue;
                    }
                    let (tx, shared) = &self.queues[to];
                    if ty != m.payload.type_name() {
                        let text = format!(
                            "{}: {} publishes {}, {} reads {ty}: not delivered",
                            m.topic,
                            self.names[from],
                            m.payload.type_name(),
                            self.names[to]
                        );
                        let mut s = lock(shared);
                        let name = self.names[to].clone();
                        s.run.status.problem(&name, "misrouted", text);
                        continue;
                    }
                    if self.aborted() {
                        self.discard(to, &m.topic);
                        continue;
                    }
                    let input = Input::Local(m.clone(), Instant::now());
                    let sent = if realtime {
                        let bytes = input.queue_bytes();
                        if self.bytes[to].reserve(bytes) {
                            let r = match tx.try_send(input) {
                                Ok(()) => Ok(()),
                                Err(TrySendError::Full(_)) => Err(SendFailure::QueueFull),
                                Err(TrySendError::Disconnected(_)) => Err(SendFailure::Ended),
                            };
                            if r.is_err() {
                                self.bytes[to].release(bytes);
                            }
                            r
                        } else {
                            Err(SendFailure::OverBudget)
                        }
                    } else {
                        self.send_waiting(from, to, tx, input)
                    };
                    if sent == Err(SendFailure::Aborted) {
                        self.discard(to, &m.topic);
                    } else if let Err(why) = sent {
                        let mut s = lock(shared);
                        *s.run.dropped.entry(m.topic.to_string()).or_default() += 1;
                        if s.run.dropped.values().sum::<u64>() == 1 {
                            tracing::warn!(
                                node = self.names[to],
                                topic = %m.topic,
                                "a message from {} was dropped: {why}",
                                self.names[from]
                            );
                        }
                    }
                }
            }
            wire.send(&m);
        }
    }
}

/// Everything one node's thread needs.
struct Unit {
    index: usize,
    name: String,
    node: Option<Box<dyn Node>>,
    rx: Receiver<Input>,
    shared: Arc<Mutex<Shared>>,
    routes: Arc<Routes>,
    wire: Arc<dyn WireOut>,
    realtime: bool,
    tick: Duration,
    start: Instant,
}

impl Unit {
    fn run(mut self) {
        if self.realtime {
            let r = make_realtime(REALTIME_PRIORITY);
            match &r {
                Ok(s) => tracing::info!(node = self.name, "real-time: {s}"),
                Err(e) => tracing::warn!(node = self.name, "real-time: {e}"),
            }
            lock(&self.shared).run.scheduling = Some(r.unwrap_or_else(|e| e.to_string()));
        }
        let mut next_tick = Instant::now() + self.tick;
        let mut next_report = Instant::now();
        let mut pending: Option<Input> = None;
        let mut out = Vec::new();
        loop {
            let first = match pending.take() {
                Some(i) => i,
                None => {
                    let wait = next_tick.saturating_duration_since(Instant::now());
                    match self.rx.recv_timeout(wait) {
                        Ok(i) => i,
                        Err(RecvTimeoutError::Timeout) => {
                            self.tick(&mut out);
                            next_tick = Instant::now() + self.tick;
                            self.report(&mut next_report);
                            continue;
                        }
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                }
            };
            match first {
                Input::Param(req) => {
                    let r = match self.node.as_mut() {
                        Some(n) => n.set_parameter(&req.name, &req.value),
                        None => Err(ParamError::Stopped {
                            node: req.node.clone(),
                        }),
                    };
                    match &r {
                        Ok(()) => tracing::info!(node = req.node, "parameter {} set", req.name),
                        Err(e) => tracing::warn!(node = req.node, "parameter refused: {e}"),
                    }
                    let _ = req.reply.send(r);
                }
                Input::Demand(topic, read) => {
                    tracing::debug!(node = self.name, topic, read, "demand");
                    self.guarded(&mut out, |n, _| n.set_demand(&topic, read));
                }
                Input::Stop => break,
                Input::Wire(_) | Input::Local(..) if self.routes.aborted() => {
                    let bytes = first.queue_bytes();
                    if let Some(topic) = first.topic() {
                        self.routes.discard(self.index, topic);
                    }
                    self.routes.bytes[self.index].release(bytes);
                }
                Input::Finish(ack) => {
                    self.guarded(&mut out, |n, out| n.finish(out));
                    self.routes
                        .route(self.index, self.realtime, &mut out, self.wire.as_ref());
                    self.report(&mut Instant::now());
                    let _ = ack.send(());
                }
                first => {
                    // What is waiting, one message per topic, up to a control input or a
                    // second message on a topic (handled in order next): the messages of
                    // different topics (a mesher's bodies) are handled at once, while what a
                    // batch publishes stays one message's worth per topic.
                    let mut batch = vec![first];
                    while batch.len() < MAX_BATCH {
                        match self.rx.try_recv() {
                            Ok(i @ (Input::Wire(_) | Input::Local(..))) => {
                                let topic = i.topic();
                                if batch.iter().any(|b| b.topic() == topic) {
                                    pending = Some(i);
                                    break;
                                }
                                batch.push(i);
                            }
                            Ok(other) => {
                                pending = Some(other);
                                break;
                            }
                            Err(_) => break,
                        }
                    }
                    self.handle(batch, &mut out);
                }
            }
            // The clock is seen only when the node has caught up: a node behind its queue
            // has input waiting, so none of its streams went quiet (a mesher must not close
            // a body whose frames wait in the queue).
            if Instant::now() >= next_tick && pending.is_none() && self.rx.is_empty() {
                self.tick(&mut out);
                next_tick = Instant::now() + self.tick;
            }
            self.report(&mut next_report);
        }
        self.report(&mut Instant::now());
    }

    /// Runs `f` on the node, catching a panic: the node is then stopped and reported.
    fn guarded(
        &mut self,
        out: &mut Vec<Message>,
        f: impl FnOnce(&mut dyn Node, &mut Vec<Message>),
    ) {
        let Some(node) = self.node.as_mut() else {
            return;
        };
        let before = out.len();
        let state = &self.routes.state[self.index];
        state.set(NodeState::Working);
        let r = catch_unwind(AssertUnwindSafe(|| f(node.as_mut(), out)));
        state.set(NodeState::Idle);
        if let Err(p) = r {
            let text = chronotope_node::panic_text(p.as_ref());
            tracing::error!(
                node = self.name,
                "the node panicked and is stopped (the other nodes go on): {text}"
            );
            out.truncate(before);
            let mut s = lock(&self.shared);
            s.run.stopped = Some(format!("panicked: {text}"));
            s.run.status = node.status().clone();
            self.node = None;
        }
    }

    fn handle(&mut self, batch: Vec<Input>, out: &mut Vec<Message>) {
        let bytes: usize = batch.iter().map(Input::queue_bytes).sum();
        self.handle_batch(batch, out);
        // What the batch held counts against the queue's budget until it has been handled.
        self.routes.bytes[self.index].release(bytes);
    }

    fn handle_batch(&mut self, batch: Vec<Input>, out: &mut Vec<Message>) {
        let mut msgs = Vec::with_capacity(batch.len());
        let mut arrivals = Vec::with_capacity(batch.len());
        for input in batch {
            match input {
                Input::Wire(s) => match Payload::decode(s.type_name, &s.bytes) {
                    Ok(payload) => {
                        msgs.push(Message::new(&s.topic, wall_clock_ns(), payload));
                        arrivals.push(s.at);
                    }
                    Err(e) => {
                        let mut sh = lock(&self.shared);
                        *sh.run.undecodable.entry(s.topic.to_string()).or_default() += 1;
                        let text = format!(
                            "{}: a sample does not decode as {}: {e}",
                            s.topic, s.type_name
                        );
                        tracing::warn!(node = self.name, "{text}");
                        if sh.run.status.messages.len() < NodeStatus::KEPT {
                            sh.run.status.messages.push(text);
                        }
                    }
                },
                Input::Local(m, at) => {
                    msgs.push(m);
                    arrivals.push(at);
                }
                Input::Param(_) | Input::Demand(..) | Input::Finish(_) | Input::Stop => {}
            }
        }
        if msgs.is_empty() {
            return;
        }
        if self.node.is_none() {
            let mut sh = lock(&self.shared);
            for m in &msgs {
                *sh.run.dropped.entry(m.topic.to_string()).or_default() += 1;
            }
            return;
        }
        let busy = Instant::now();
        self.guarded(out, |n, out| n.on_messages(&msgs, out));
        self.routes
            .route(self.index, self.realtime, out, self.wire.as_ref());
        let busy_s = busy.elapsed().as_secs_f64() / msgs.len() as f64;
        tracing::debug!(
            node = self.name,
            batch = msgs.len(),
            oldest_ms = arrivals
                .iter()
                .map(|a| a.elapsed().as_secs_f64() * 1e3)
                .fold(0.0, f64::max),
            busy_ms = busy_s * 1e3 * msgs.len() as f64,
            "batch handled"
        );
        let mut sh = lock(&self.shared);
        sh.run.max_batch = sh.run.max_batch.max(msgs.len());
        for (m, at) in msgs.iter().zip(arrivals) {
            sh.lag
                .entry(m.topic.to_string())
                .or_default()
                .add(at.elapsed().as_secs_f64(), busy_s);
        }
    }

    fn tick(&mut self, out: &mut Vec<Message>) {
        let now_ns = self.start.elapsed().as_nanos() as i64;
        self.guarded(out, |n, out| {
            n.on_tick(now_ns, out);
            n.poll(out);
        });
        self.routes
            .route(self.index, self.realtime, out, self.wire.as_ref());
    }

    /// Copies the node's status and CPU time for the coordinator (at most 5 times a second).
    fn report(&mut self, next: &mut Instant) {
        if Instant::now() < *next {
            return;
        }
        *next = Instant::now() + Duration::from_millis(200);
        let cpu = thread_cpu_s();
        let mut sh = lock(&self.shared);
        if let Some(n) = &self.node {
            let kept = std::mem::take(&mut sh.run.status.messages);
            sh.run.status = n.status().clone();
            // Decoding problems are the executor's, kept with the node's.
            for m in kept {
                if !sh.run.status.messages.contains(&m)
                    && sh.run.status.messages.len() < NodeStatus::KEPT
                {
                    sh.run.status.messages.push(m);
                }
            }
        }
        let (t0, c0) = sh.cpu_at_last;
        let dt = t0.elapsed().as_secs_f64();
        if dt >= 0.9 {
            sh.run.cpu_percent = 100.0 * (cpu - c0) / dt;
            sh.cpu_at_last = (Instant::now(), cpu);
        }
        sh.run.cpu_s = cpu;
    }
}

fn wall_clock_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64)
}

impl Drop for Executor {
    /// An executor dropped without [`Executor::finish`] (a transport that failed to start)
    /// still ends its threads.
    fn drop(&mut self) {
        for u in &self.units {
            let _ = u.tx.try_send(Input::Stop);
        }
    }
}

impl Executor {
    /// Starts every node on its thread. `wires[i]` takes what node `i` publishes to the
    /// wire; `tick` is how often the nodes see the clock.
    ///
    /// # Errors
    /// The OS refuses a thread.
    pub fn start(
        nodes: Vec<Box<dyn Node>>,
        options: &[UnitOptions],
        wires: Vec<Arc<dyn WireOut>>,
        tick: Duration,
    ) -> std::io::Result<Self> {
        let start = Instant::now();
        let mut by_topic: BTreeMap<String, Vec<(usize, &'static str)>> = BTreeMap::new();
        for (i, n) in nodes.iter().enumerate() {
            for s in n.subscriptions() {
                by_topic.entry(s.topic).or_default().push((i, s.type_name));
            }
        }
        let mut channels = Vec::new();
        let mut shared = Vec::new();
        for (i, n) in nodes.iter().enumerate() {
            let o = options.get(i).copied().unwrap_or(UnitOptions {
                realtime: false,
                queue_depth: 256,
                queue_bytes: DEFAULT_QUEUE_BYTES,
            });
            channels.push(bounded::<Input>(o.queue_depth.max(1)));
            let sh = Shared {
                run: NodeRun {
                    status: n.status().clone(),
                    thread: if o.realtime { "realtime" } else { "shared" },
                    ..NodeRun::default()
                },
                lag: BTreeMap::new(),
                cpu_at_last: (start, 0.0),
            };
            shared.push(Arc::new(Mutex::new(sh)));
        }
        let routes = Arc::new(Routes {
            by_topic,
            queues: channels
                .iter()
                .zip(&shared)
                .map(|((tx, _), sh)| (tx.clone(), sh.clone()))
                .collect(),
            state: nodes.iter().map(|_| StateCell::new()).collect(),
            bytes: (0..nodes.len())
                .map(|i| {
                    QueueBytes::new(
                        options
                            .get(i)
                            .map_or(DEFAULT_QUEUE_BYTES, |o| o.queue_bytes),
                    )
                })
                .collect(),
            names: nodes.iter().map(|n| n.name().to_owned()).collect(),
            abort: AtomicBool::new(false),
        });
        let mut units = Vec::new();
        let mut wires = wires.into_iter();
        for (i, ((node, (tx, rx)), sh)) in nodes.into_iter().zip(channels).zip(shared).enumerate() {
            let realtime = options.get(i).is_some_and(|o| o.realtime);
            let name = node.name().to_owned();
            let rank = node.rank();
            let unit = Unit {
                index: i,
                name: name.clone(),
                node: Some(node),
                rx,
                shared: sh.clone(),
                routes: routes.clone(),
                wire: wires.next().unwrap_or_else(|| Arc::new(NoWire)),
                realtime,
                tick,
                start,
            };
            let thread = std::thread::Builder::new()
                .name(format!("node {name}"))
                .spawn(move || unit.run())?;
            units.push(UnitHandle {
                name,
                rank,
                realtime,
                tx,
                shared: sh,
                thread: Some(thread),
            });
        }
        Ok(Self {
            units,
            routes,
            start,
        })
    }

    /// When the executor started.
    pub fn started(&self) -> Instant {
        self.start
    }

    /// What the readers hand wire samples to.
    pub fn injector(&self) -> Injector {
        Injector(self.routes.clone())
    }

    /// Hands a sample from the wire to every node reading `sample.topic` (queued, or
    /// dropped and counted for a node whose queue is full). How many nodes took it.
    pub fn inject(&self, sample: &RawSample) -> usize {
        let subs = self.readers_of(&sample.topic);
        let injector = self.injector();
        subs.into_iter()
            .filter(|&(i, _, _)| {
                injector.inject_to(
                    i,
                    RawSample {
                        topic: sample.topic.clone(),
                        type_name: sample.type_name,
                        bytes: sample.bytes.clone(),
                        at: sample.at,
                    },
                )
            })
            .count()
    }

    /// Nodes reading `topic` from the wire, by index: `(index, realtime, type)`.
    pub fn readers_of(&self, topic: &str) -> Vec<(usize, bool, &'static str)> {
        self.routes
            .by_topic
            .get(topic)
            .map(|subs| {
                subs.iter()
                    .map(|&(i, ty)| (i, self.units[i].realtime, ty))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Tells node `index` whether anything reads `topic` now; false if its queue has no
    /// room for it now (to be said again).
    pub fn demand(&self, index: usize, topic: &str, read: bool) -> bool {
        self.units
            .get(index)
            .is_some_and(|u| u.tx.try_send(Input::Demand(topic.to_owned(), read)).is_ok())
    }

    /// The queue of the node named `node`, for parameter requests.
    pub fn param_sender(&self, node: &str) -> Option<Sender<Input>> {
        self.units
            .iter()
            .find(|u| u.name == node)
            .map(|u| u.tx.clone())
    }

    /// Every node's figures now.
    pub fn runs(&self) -> BTreeMap<String, NodeRun> {
        self.units
            .iter()
            .enumerate()
            .map(|(i, u)| {
                let sh = lock(&u.shared);
                let mut run = sh.run.clone();
                run.queue_peak_bytes = self.routes.bytes[i].peak.load(Ordering::Relaxed);
                run.lag = sh
                    .lag
                    .iter()
                    .filter(|(_, w)| w.handled > 0)
                    .map(|(t, w)| (t.clone(), w.stats()))
                    .collect();
                (u.name.clone(), run)
            })
            .collect()
    }

    /// What aborts the run (while it runs or while it finishes).
    pub fn aborter(&self) -> Aborter {
        Aborter(self.routes.clone())
    }

    /// Finishes the nodes in increasing rank (each after what is in its queue), waiting at
    /// most `wait` per rank, then ends their threads.
    ///
    /// Once the run is aborted ([`Aborter`]) the queues are discarded, and a node that has
    /// not finished [`ABORT_WAIT`] later (it is still in a handler) is left: its thread is
    /// not joined and its run says `unfinished`.
    pub fn finish(mut self, wait: Duration) -> BTreeMap<String, NodeRun> {
        let mut ranks: Vec<u8> = self.units.iter().map(|u| u.rank).collect();
        ranks.sort_unstable();
        ranks.dedup();
        let mut aborted_at: Option<Instant> = None;
        let mut finished = vec![false; self.units.len()];
        for r in ranks {
            let rank_start = Instant::now();
            let acks: Vec<_> = self
                .units
                .iter()
                .enumerate()
                .filter(|(_, u)| u.rank == r)
                .map(|(i, u)| {
                    let (tx, rx) = bounded(1);
                    self.send_control(&u.tx, Input::Finish(tx), rank_start, wait, &mut aborted_at);
                    (i, rx)
                })
                .collect();
            for (i, rx) in acks {
                loop {
                    let until = self.until(rank_start, wait, &mut aborted_at);
                    let slice = until
                        .saturating_duration_since(Instant::now())
                        .min(LOCAL_SEND_POLL);
                    match rx.recv_timeout(slice) {
                        Ok(()) => {
                            finished[i] = true;
                            break;
                        }
                        Err(RecvTimeoutError::Disconnected) => break,
                        Err(RecvTimeoutError::Timeout) if Instant::now() < until => {}
                        Err(RecvTimeoutError::Timeout) => {
                            let name = &self.units[i].name;
                            if aborted_at.is_some() {
                                tracing::warn!(
                                    node = name,
                                    "aborted: still in a handler; not waited for"
                                );
                                lock(&self.units[i].shared).run.unfinished = Some(format!(
                                    "the run was aborted while it was still in a handler \
                                     ({ABORT_WAIT:?} later): its last answers were not published"
                                ));
                            } else {
                                tracing::warn!(node = name, "did not finish within {wait:?}");
                            }
                            break;
                        }
                    }
                }
            }
        }
        let units = std::mem::take(&mut self.units);
        for (u, &done) in units.iter().zip(&finished) {
            if done || aborted_at.is_none() {
                self.send_control(&u.tx, Input::Stop, Instant::now(), wait, &mut aborted_at);
            } else {
                let _ = u.tx.try_send(Input::Stop);
            }
        }
        for (mut u, done) in units.into_iter().zip(finished) {
            // A node left in a handler after an abort is not joined: its thread ends with
            // the process.
            if done || aborted_at.is_none() {
                if let Some(t) = u.thread.take() {
                    let _ = t.join();
                }
            }
            self.units.push(u);
        }
        self.runs()
    }

    /// Until when [`Executor::finish`] waits for what it began at `from`: `wait` later, or
    /// [`ABORT_WAIT`] after the abort (or after `from`, if the abort came first).
    fn until(&self, from: Instant, wait: Duration, aborted_at: &mut Option<Instant>) -> Instant {
        if self.routes.aborted() {
            aborted_at.get_or_insert_with(Instant::now);
        }
        let deadline = from + wait;
        aborted_at.map_or(deadline, |a| deadline.min(a.max(from) + ABORT_WAIT))
    }

    /// Sends a control input to a node, waiting for room until [`Executor::until`].
    fn send_control(
        &self,
        tx: &Sender<Input>,
        mut input: Input,
        from: Instant,
        wait: Duration,
        aborted_at: &mut Option<Instant>,
    ) {
        loop {
            let until = self.until(from, wait, aborted_at);
            let slice = until
                .saturating_duration_since(Instant::now())
                .min(LOCAL_SEND_POLL);
            match tx.send_timeout(input, slice) {
                Ok(()) | Err(SendTimeoutError::Disconnected(_)) => return,
                Err(SendTimeoutError::Timeout(back)) if Instant::now() < until => input = back,
                Err(SendTimeoutError::Timeout(_)) => return,
            }
        }
    }
}

/// Hands wire samples to the nodes' queues (held by the readers).
#[derive(Clone)]
pub struct Injector(Arc<Routes>);

impl Injector {
    /// Hands `sample` to node `index`: queued, or dropped and counted for that node and
    /// topic if its queue is full. Whether it was queued.
    pub fn inject_to(&self, index: usize, sample: RawSample) -> bool {
        let Some((tx, shared)) = self.0.queues.get(index) else {
            return false;
        };
        if self.0.aborted() {
            self.0.discard(index, &sample.topic);
            return false;
        }
        let topic = sample.topic.clone();
        let input = Input::Wire(sample);
        let bytes = input.queue_bytes();
        let budget = &self.0.bytes[index];
        let why = if budget.reserve(bytes) {
            match tx.try_send(input) {
                Ok(()) => return true,
                Err(_) => {
                    budget.release(bytes);
                    "queue_depth"
                }
            }
        } else {
            "queue_mb"
        };
        let mut sh = lock(shared);
        let first = sh.run.dropped.is_empty();
        *sh.run.dropped.entry(topic.to_string()).or_default() += 1;
        if first {
            tracing::warn!(
                node = self.0.names[index],
                topic = %topic,
                "the node is behind (its queue holds its {why}): a sample was dropped (counted)"
            );
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronotope_msg::{Header, PoseStamped, RosMessage, Time};
    use chronotope_node::TopicRef;

    /// Reads `input`, republishes every pose on `output`; panics on a pose at `panic_at`.
    struct Relay {
        name: String,
        input: String,
        /// A second topic it reads, if any.
        input2: Option<String>,
        output: String,
        rank: u8,
        panic_at: Option<f64>,
        sleep: Duration,
        /// Sleeps this long on the pose at x instead.
        sleep_at: Option<(f64, Duration)>,
        seen: Arc<Mutex<Vec<f64>>>,
        /// How many times its `finish` ran.
        finishes: Arc<AtomicUsize>,
        /// How many times it was ticked and polled.
        ticks: Arc<AtomicUsize>,
        polls: Arc<AtomicUsize>,
        status: NodeStatus,
    }

    fn relay(name: &str, input: &str, output: &str, rank: u8) -> (Relay, Arc<Mutex<Vec<f64>>>) {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let r = Relay {
            name: name.into(),
            input: input.into(),
            input2: None,
            output: output.into(),
            rank,
            panic_at: None,
            sleep: Duration::ZERO,
            sleep_at: None,
            seen: seen.clone(),
            finishes: Arc::new(AtomicUsize::new(0)),
            ticks: Arc::new(AtomicUsize::new(0)),
            polls: Arc::new(AtomicUsize::new(0)),
            status: NodeStatus::default(),
        };
        (r, seen)
    }

    fn pose(x: f64) -> Payload {
        let mut p = PoseStamped {
            header: Header {
                stamp: Time::from_nanos(1),
                frame_id: "world".into(),
            },
            ..PoseStamped::default()
        };
        p.pose.position.x = x;
        Payload::PoseStamped(Arc::new(p))
    }

    impl Node for Relay {
        fn as_any(&self) -> &dyn std::any::Any {
            self
        }
        fn name(&self) -> &str {
            &self.name
        }
        fn subscriptions(&self) -> Vec<TopicRef> {
            std::iter::once(&self.input)
                .chain(&self.input2)
                .map(|t| TopicRef {
                    topic: t.clone(),
                    type_name: PoseStamped::TYPE_NAME,
                })
                .collect()
        }
        fn publications(&self) -> Vec<TopicRef> {
            vec![TopicRef {
                topic: self.output.clone(),
                type_name: PoseStamped::TYPE_NAME,
            }]
        }
        fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
            self.status.received += 1;
            let Payload::PoseStamped(p) = &msg.payload else {
                return;
            };
            let x = p.pose.position.x;
            assert!(self.panic_at != Some(x), "unlucky pose {x}");
            match self.sleep_at {
                Some((at, long)) if at == x => std::thread::sleep(long),
                _ => std::thread::sleep(self.sleep),
            }
            lock(&self.seen).push(x);
            out.push(Message::new(
                &self.output,
                msg.stamp_ns,
                msg.payload.clone(),
            ));
        }
        fn finish(&mut self, out: &mut Vec<Message>) {
            self.finishes.fetch_add(1, Ordering::Relaxed);
            out.push(Message::new(&self.output, 0, pose(-1.0)));
        }
        fn on_tick(&mut self, _now_ns: i64, _out: &mut Vec<Message>) {
            self.ticks.fetch_add(1, Ordering::Relaxed);
        }
        fn poll(&mut self, _out: &mut Vec<Message>) {
            self.polls.fetch_add(1, Ordering::Relaxed);
        }
        fn status(&self) -> &NodeStatus {
            &self.status
        }
        fn rank(&self) -> u8 {
            self.rank
        }
    }

    fn sample(topic: &str, x: f64) -> RawSample {
        RawSample {
            topic: topic.into(),
            type_name: PoseStamped::TYPE_NAME,
            bytes: Arc::new(pose(x).encode().unwrap()),
            at: Instant::now(),
        }
    }

    fn opts(depth: usize) -> UnitOptions {
        UnitOptions {
            realtime: false,
            queue_depth: depth,
            queue_bytes: DEFAULT_QUEUE_BYTES,
        }
    }

    fn opts_bytes(depth: usize, bytes: usize) -> UnitOptions {
        UnitOptions {
            queue_bytes: bytes,
            ..opts(depth)
        }
    }

    fn start(nodes: Vec<Box<dyn Node>>, options: &[UnitOptions]) -> Executor {
        Executor::start(nodes, options, Vec::new(), Duration::from_millis(20)).unwrap()
    }

    #[test]
    fn a_panicking_node_is_stopped_and_reported_while_the_others_go_on() {
        let (mut a, seen_a) = relay("/a", "/in", "/mid", 0);
        a.panic_at = Some(13.0);
        let (b, seen_b) = relay("/b", "/mid", "/out", 1);
        let (c, seen_c) = relay("/c", "/in", "/other", 0);
        let exec = start(vec![Box::new(a), Box::new(b), Box::new(c)], &[opts(64); 3]);
        for x in [1.0, 2.0, 13.0, 4.0, 5.0] {
            assert_eq!(exec.inject(&sample("/in", x)), 2);
            std::thread::sleep(Duration::from_millis(5));
        }
        let runs = exec.finish(Duration::from_secs(5));
        // /a panicked at 13: stopped, what came after is dropped and counted.
        let a = &runs["/a"];
        assert!(
            a.stopped.as_deref().unwrap().contains("unlucky pose 13"),
            "{a:?}"
        );
        assert_eq!(*lock(&seen_a), vec![1.0, 2.0]);
        assert_eq!(a.dropped.get("/in"), Some(&2), "{a:?}");
        // /b got what /a relayed before it stopped (and nothing from a finish /a never had).
        assert_eq!(*lock(&seen_b), vec![1.0, 2.0]);
        assert!(runs["/b"].stopped.is_none());
        // /c, reading the same topic, saw everything.
        assert_eq!(*lock(&seen_c), vec![1.0, 2.0, 13.0, 4.0, 5.0]);
        assert!(runs["/c"].stopped.is_none());
    }

    /// A live node is polled with each tick (for work finished off its thread); a replay's
    /// bus ticks its nodes with the bag's time but never polls them, so that what they
    /// publish does not depend on how fast that work ran.
    #[test]
    fn live_ticks_poll_the_nodes_and_a_replays_do_not() {
        let (a, _) = relay("/a", "/in", "/out", 0);
        let (ticks, polls) = (a.ticks.clone(), a.polls.clone());
        let exec = start(vec![Box::new(a)], &[opts(64)]);
        std::thread::sleep(Duration::from_millis(200));
        exec.finish(Duration::from_secs(5));
        let (t, p) = (ticks.load(Ordering::Relaxed), polls.load(Ordering::Relaxed));
        assert!(t >= 2 && p == t, "live: {t} ticks, {p} polls");
        let (b, _) = relay("/b", "/in", "/out", 0);
        let (ticks, polls) = (b.ticks.clone(), b.polls.clone());
        let mut bus = chronotope_node::bus::Bus::new(vec![Box::new(b)]);
        for k in 0..5 {
            bus.tick(k * 100_000_000, &mut |_| {});
        }
        bus.finish(&mut |_| {});
        assert_eq!(ticks.load(Ordering::Relaxed), 5);
        assert_eq!(polls.load(Ordering::Relaxed), 0, "a replay never polls");
    }

    #[test]
    fn a_slow_node_drops_wire_samples_counted_for_itself_only() {
        let (mut slow, seen_slow) = relay("/slow", "/in", "/s", 0);
        slow.sleep = Duration::from_millis(30);
        let (fast, seen_fast) = relay("/fast", "/in", "/f", 0);
        let exec = start(vec![Box::new(slow), Box::new(fast)], &[opts(2), opts(64)]);
        for x in 0..20 {
            exec.inject(&sample("/in", f64::from(x)));
        }
        let runs = exec.finish(Duration::from_secs(10));
        let slow = &runs["/slow"];
        let dropped = slow.dropped.get("/in").copied().unwrap_or(0);
        assert!(dropped >= 10, "{slow:?}");
        assert_eq!(lock(&seen_slow).len() as u64 + dropped, 20);
        assert_eq!(lock(&seen_fast).len(), 20);
        assert!(runs["/fast"].dropped.is_empty());
        assert_eq!(runs["/slow"].lag["/in"].handled + dropped, 20);
    }

    #[test]
    fn nodes_finish_in_rank_order_so_the_last_messages_reach_the_next_rank() {
        let (a, _) = relay("/a", "/in", "/mid", 0);
        let (mut b, seen_b) = relay("/b", "/mid", "/out", 1);
        // A slow reader: the finishing message must still reach it before it finishes.
        b.sleep = Duration::from_millis(20);
        let exec = start(vec![Box::new(b), Box::new(a)], &[opts(1), opts(64)]);
        for x in 0..5 {
            exec.inject(&sample("/in", f64::from(x)));
        }
        let runs = exec.finish(Duration::from_secs(10));
        // Back-pressure between nodes: nothing dropped on /mid although /b's queue holds one.
        assert!(runs["/b"].dropped.is_empty(), "{:?}", runs["/b"]);
        assert_eq!(*lock(&seen_b), vec![0.0, 1.0, 2.0, 3.0, 4.0, -1.0]);
    }

    #[test]
    fn a_publisher_waits_as_long_as_the_nodes_after_it_work() {
        // /a -> /b -> /c, one message per queue; /c works 2.5 s on the first pose, longer
        // than LOCAL_SEND_WAIT. /b waits for /c meanwhile, and /a for /b: both wait for a
        // node at work, so nothing is dropped in the middle of the chain.
        let (a, _) = relay("/a", "/in", "/mid", 0);
        let (b, _) = relay("/b", "/mid", "/out", 1);
        let (mut c, seen_c) = relay("/c", "/out", "/end", 2);
        c.sleep_at = Some((0.0, LOCAL_SEND_WAIT + Duration::from_millis(500)));
        let exec = start(
            vec![Box::new(a), Box::new(b), Box::new(c)],
            &[opts(64), opts(1), opts(1)],
        );
        for x in 0..6 {
            exec.inject(&sample("/in", f64::from(x)));
        }
        let runs = exec.finish(Duration::from_secs(10));
        for n in ["/b", "/c"] {
            assert!(runs[n].dropped.is_empty(), "{n}: {:?}", runs[n]);
        }
        // And the two finishing poses, of /a (relayed by /b) and of /b.
        assert_eq!(
            *lock(&seen_c),
            vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, -1.0, -1.0]
        );
    }

    #[test]
    fn wire_samples_over_the_byte_budget_are_dropped_until_the_node_has_handled_what_it_holds() {
        let each = sample("/in", 0.0).bytes.len() + chronotope_node::MESSAGE_OVERHEAD_BYTES;
        // Room for three samples, counted until handled: the first is in the handler for
        // 300 ms, two more wait, the rest find the budget full.
        let (mut slow, seen) = relay("/slow", "/in", "/s", 0);
        slow.sleep_at = Some((0.0, Duration::from_millis(300)));
        // A budget smaller than one sample: taken into an empty queue only.
        let (mut tiny, seen_tiny) = relay("/tiny", "/in2", "/t", 0);
        tiny.sleep_at = Some((0.0, Duration::from_millis(300)));
        let exec = start(
            vec![Box::new(slow), Box::new(tiny)],
            &[opts_bytes(64, 3 * each), opts_bytes(64, 1)],
        );
        let taken: Vec<usize> = (0..10)
            .map(|x| exec.inject(&sample("/in", f64::from(x))))
            .collect();
        assert_eq!(taken, [1, 1, 1, 0, 0, 0, 0, 0, 0, 0]);
        let taken: Vec<usize> = (0..2)
            .map(|x| exec.inject(&sample("/in2", f64::from(x))))
            .collect();
        assert_eq!(taken, [1, 0]);
        // Once handled, the bytes are given back.
        std::thread::sleep(Duration::from_millis(700));
        for x in 10..13 {
            assert_eq!(exec.inject(&sample("/in", f64::from(x))), 1);
        }
        assert_eq!(exec.inject(&sample("/in2", 2.0)), 1);
        let runs = exec.finish(Duration::from_secs(10));
        assert_eq!(*lock(&seen), vec![0.0, 1.0, 2.0, 10.0, 11.0, 12.0]);
        assert_eq!(*lock(&seen_tiny), vec![0.0, 2.0]);
        assert_eq!(runs["/slow"].dropped["/in"], 7);
        assert_eq!(runs["/slow"].queue_peak_bytes, 3 * each);
        assert_eq!(runs["/tiny"].dropped["/in2"], 1);
    }

    #[test]
    fn a_publisher_waits_for_room_in_the_byte_budget_of_a_node_at_work() {
        // /b has room for two messages in bytes (and 64 by count) and works 30 ms on each;
        // /a publishes faster, so it waits, and nothing is dropped.
        let (a, _) = relay("/a", "/in", "/mid", 0);
        let (mut b, seen_b) = relay("/b", "/mid", "/out", 1);
        b.sleep = Duration::from_millis(30);
        let budget = 2 * pose(0.0).queue_bytes();
        let exec = start(
            vec![Box::new(a), Box::new(b)],
            &[opts(64), opts_bytes(64, budget)],
        );
        for x in 0..10 {
            exec.inject(&sample("/in", f64::from(x)));
        }
        let runs = exec.finish(Duration::from_secs(10));
        assert!(runs["/b"].dropped.is_empty(), "{:?}", runs["/b"]);
        let want: Vec<f64> = (0..10).map(f64::from).chain([-1.0]).collect();
        assert_eq!(*lock(&seen_b), want);
        assert_eq!(runs["/b"].queue_peak_bytes, budget);
    }

    #[test]
    fn a_batch_is_what_was_waiting_one_message_per_topic() {
        let (mut a, seen) = relay("/a", "/in", "/mid", 0);
        a.input2 = Some("/in2".into());
        a.sleep = Duration::from_millis(50);
        let (mut b, seen_b) = relay("/b", "/in", "/mid2", 0);
        b.sleep = Duration::from_millis(50);
        let exec = start(vec![Box::new(a), Box::new(b)], &[opts(64), opts(64)]);
        for x in 0..10 {
            exec.inject(&sample("/in", f64::from(x)));
            exec.inject(&sample("/in2", f64::from(x)));
        }
        let runs = exec.finish(Duration::from_secs(10));
        assert_eq!(lock(&seen).len(), 20);
        // Both topics at once, never two of one: each topic's messages in order.
        assert_eq!(runs["/a"].max_batch, 2, "{:?}", runs["/a"]);
        assert_eq!(runs["/b"].max_batch, 1, "{:?}", runs["/b"]);
        let want: Vec<f64> = (0..10).map(f64::from).collect();
        assert_eq!(*lock(&seen_b), want);
        assert!(runs["/a"].cpu_s >= 0.0);
    }

    #[test]
    fn an_abort_discards_what_is_queued_counts_it_and_still_finishes_the_nodes() {
        // /a works 100 ms per pose and has 20 waiting; /b reads what /a publishes.
        let (mut a, seen_a) = relay("/a", "/in", "/mid", 0);
        a.sleep = Duration::from_millis(100);
        let (b, seen_b) = relay("/b", "/mid", "/out", 1);
        let (fa, fb) = (a.finishes.clone(), b.finishes.clone());
        let exec = start(vec![Box::new(a), Box::new(b)], &[opts(64), opts(64)]);
        for x in 0..20 {
            assert_eq!(exec.inject(&sample("/in", f64::from(x))), 1);
        }
        std::thread::sleep(Duration::from_millis(150));
        let routes = exec.routes.clone();
        exec.aborter().abort();
        // Wire samples after the abort are discarded at once.
        assert_eq!(exec.inject(&sample("/in", 99.0)), 0);
        let t = Instant::now();
        let runs = exec.finish(Duration::from_secs(30));
        assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
        let handled = lock(&seen_a).len() as u64;
        assert!((1..=4).contains(&handled), "{handled}");
        // Every pose is either handled or discarded and counted, none dropped.
        assert_eq!(runs["/a"].discarded["/in"], 21 - handled);
        assert!(runs["/a"].dropped.is_empty(), "{:?}", runs["/a"]);
        // What /a published after the abort (its finish's pose included) is discarded at /b.
        let at_b = lock(&seen_b).len() as u64;
        assert_eq!(at_b + runs["/b"].discarded["/mid"], handled + 1);
        // Both still finished, and neither is unfinished.
        assert_eq!(
            (fa.load(Ordering::Relaxed), fb.load(Ordering::Relaxed)),
            (1, 1)
        );
        assert!(runs["/a"].unfinished.is_none() && runs["/b"].unfinished.is_none());
        // What was discarded gave its bytes back.
        assert!(routes
            .bytes
            .iter()
            .all(|b| b.held.load(Ordering::Relaxed) == 0));
    }

    #[test]
    fn an_abort_while_finishing_leaves_a_node_stuck_in_its_handler_after_abort_wait() {
        // /a is in a 20 s handler; a stop would wait for it (up to its 30 s per rank). An
        // abort 300 ms into the finish ends the wait ABORT_WAIT later.
        let (mut a, _) = relay("/a", "/in", "/mid", 0);
        a.sleep_at = Some((1.0, Duration::from_secs(20)));
        let (b, _) = relay("/b", "/mid", "/out", 1);
        let (fa, fb) = (a.finishes.clone(), b.finishes.clone());
        let exec = start(vec![Box::new(a), Box::new(b)], &[opts(64), opts(64)]);
        for x in [1.0, 2.0, 3.0] {
            exec.inject(&sample("/in", x));
        }
        std::thread::sleep(Duration::from_millis(100));
        let aborter = exec.aborter();
        let t = Instant::now();
        let later = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            aborter.abort();
        });
        let runs = exec.finish(Duration::from_secs(30));
        later.join().unwrap();
        let took = t.elapsed();
        assert!(
            took >= ABORT_WAIT && took < ABORT_WAIT + Duration::from_millis(1500),
            "{took:?}"
        );
        assert!(runs["/a"].unfinished.is_some(), "{:?}", runs["/a"]);
        assert_eq!(fa.load(Ordering::Relaxed), 0);
        // /b was idle: it finished.
        assert!(runs["/b"].unfinished.is_none());
        assert_eq!(fb.load(Ordering::Relaxed), 1);
    }
}
