//! The suite's ROS 2 nodes as sans-I/O state machines.
//!
//! A node is given messages ([`Message`]: a topic, a stamp and a typed payload shared by
//! reference count, so a big mesh is never copied between nodes) and pushes the messages it
//! publishes into a vector. It never reads a clock, a file or a socket: the transports do that
//! (the in-process [`bus::Bus`] for `chronotope replay` and the tests; DDS for live use). A
//! message a node cannot use is a counted, logged problem in its [`NodeStatus`], never a panic.
#![warn(missing_docs)]

mod ahead;
pub mod bus;
pub mod carving;
pub mod checker;
pub mod factory;
pub mod launch;
pub mod markers;
pub mod mesher;
pub mod names;
pub mod occupancy;
pub mod robot;
pub mod routes;

/// The message of a caught panic (the checker crate's, which catches them first); the
/// transports report a node's panic with it.
pub use chronotope_checker::panic_text;

use std::collections::BTreeMap;
use std::sync::Arc;

use chronotope_msg::{
    decode_cdr, encode_cdr, encode_cdr_into, CdrError, Clock, ContactEvent, DiagnosticArray,
    InterferenceReport, JointState, JointTrajectory, Marker, MarkerArray, MeshSlab, Octomap,
    PointCloud2, PoseStamped, ResolveSuggestions, RosMessage, RosString, TFMessage, TetLabels,
    VoxelGrid, WrenchStamped,
};

macro_rules! payloads {
    ($($variant:ident($ty:ty)),* $(,)?) => {
        /// A message of one of the types the suite speaks.
        #[derive(Debug, Clone)]
        pub enum Payload {
            $(
                #[doc = concat!("`", stringify!($ty), "`.")]
                $variant(Arc<$ty>),
            )*
        }

        impl Payload {
            /// The type's `pkg/msg/Type` name.
            pub fn type_name(&self) -> &'static str {
                match self {
                    $(Self::$variant(_) => <$ty as RosMessage>::TYPE_NAME,)*
                }
            }

            /// CDR with the encapsulation header.
            ///
            /// # Errors
            /// The message cannot be serialised (a field over CDR's `u32` limits).
            pub fn encode(&self) -> Result<Vec<u8>, CdrError> {
                match self {
                    $(Self::$variant(m) => encode_cdr(m.as_ref()),)*
                }
            }

            /// [`Self::encode`] into `out` (cleared first, its room reused).
            ///
            /// # Errors
            /// As [`Self::encode`].
            pub fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), CdrError> {
                match self {
                    $(Self::$variant(m) => encode_cdr_into(m.as_ref(), out),)*
                }
            }

            /// Decodes CDR bytes of the type named `type_name`.
            ///
            /// # Errors
            /// [`DecodeError::UnknownType`] for a type the suite does not speak,
            /// [`DecodeError::Cdr`] if the bytes do not decode as that type.
            pub fn decode(type_name: &str, bytes: &[u8]) -> Result<Self, DecodeError> {
                $(
                    if type_name == <$ty as RosMessage>::TYPE_NAME {
                        return decode_cdr::<$ty>(bytes)
                            .map(|m| Self::$variant(Arc::new(m)))
                            .map_err(DecodeError::Cdr);
                    }
                )*
                Err(DecodeError::UnknownType(type_name.to_owned()))
            }

            /// `(pkg/msg/Type, ros2msg schema)` of the type named `type_name`, if the suite
            /// speaks it.
            pub fn schema_of(type_name: &str) -> Option<(&'static str, String)> {
                $(
                    if type_name == <$ty as RosMessage>::TYPE_NAME {
                        return Some((
                            <$ty as RosMessage>::TYPE_NAME,
                            chronotope_msg::ros2msg_schema::<$ty>(),
                        ));
                    }
                )*
                None
            }

            /// `(pkg/msg/Type, ros2msg schema)` of the payload's type.
            pub fn schema(&self) -> (&'static str, String) {
                match self {
                    $(Self::$variant(_) => (
                        <$ty as RosMessage>::TYPE_NAME,
                        chronotope_msg::ros2msg_schema::<$ty>(),
                    ),)*
                }
            }
        }
    };
}

payloads! {
    VoxelGrid(VoxelGrid),
    MeshSlab(MeshSlab),
    TetLabels(TetLabels),
    Report(InterferenceReport),
    Suggestions(ResolveSuggestions),
    Contact(ContactEvent),
    Marker(Marker),
    MarkerArray(MarkerArray),
    PoseStamped(PoseStamped),
    WrenchStamped(WrenchStamped),
    PointCloud2(PointCloud2),
    Octomap(Octomap),
    TFMessage(TFMessage),
    Diagnostics(DiagnosticArray),
    Clock(Clock),
    Text(RosString),
    JointState(JointState),
    JointTrajectory(JointTrajectory),
}

/// What a message counts against a queue's byte budget besides its arrays (its header,
/// names and small fields).
pub const MESSAGE_OVERHEAD_BYTES: usize = 256;

impl Payload {
    /// About how many bytes the message holds: its arrays, plus
    /// [`MESSAGE_OVERHEAD_BYTES`] for the rest. What a node's queue budget counts.
    pub fn queue_bytes(&self) -> usize {
        use std::mem::size_of_val;
        let marker = |m: &Marker| {
            size_of_val(m.points.as_slice())
                + size_of_val(m.colors.as_slice())
                + size_of_val(m.uv_coordinates.as_slice())
                + m.texture.data.len()
                + m.mesh_file.data.len()
                + m.text.len()
        };
        let arrays = match self {
            Self::VoxelGrid(m) => m.data.len(),
            Self::MeshSlab(m) => {
                size_of_val(m.mesh.vertices.as_slice()) + size_of_val(m.mesh.tets.as_slice())
            }
            Self::TetLabels(m) => m.labels.len(),
            Self::MarkerArray(m) => m
                .markers
                .iter()
                .map(|m| marker(m) + MESSAGE_OVERHEAD_BYTES)
                .sum(),
            Self::Marker(m) => marker(m),
            Self::PointCloud2(m) => m.data.len(),
            Self::Octomap(m) => m.data.len(),
            Self::Report(m) => {
                let intervals: usize = m
                    .pairs
                    .iter()
                    .map(|p| p.interval_start_s.len() + p.interval_end_s.len())
                    .sum();
                (m.pairs.len() + m.bodies.len()) * MESSAGE_OVERHEAD_BYTES
                    + intervals * std::mem::size_of::<f64>()
            }
            Self::Suggestions(m) => m.suggestions.len() * MESSAGE_OVERHEAD_BYTES,
            Self::TFMessage(m) => m.transforms.len() * MESSAGE_OVERHEAD_BYTES,
            Self::Diagnostics(m) => m.status.len() * MESSAGE_OVERHEAD_BYTES,
            Self::Contact(_) | Self::PoseStamped(_) | Self::WrenchStamped(_) | Self::Clock(_) => 0,
            Self::Text(m) => m.data.len(),
            Self::JointState(m) => {
                (m.position.len() + m.velocity.len() + m.effort.len()) * 8
                    + m.name.iter().map(|n| n.len() + 24).sum::<usize>()
            }
            Self::JointTrajectory(m) => m
                .points
                .iter()
                .map(|p| {
                    (p.positions.len()
                        + p.velocities.len()
                        + p.accelerations.len()
                        + p.effort.len())
                        * 8
                        + 64
                })
                .sum(),
        };
        arrays + MESSAGE_OVERHEAD_BYTES
    }
}

/// Why a serialised message could not be turned into a [`Payload`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// The type is not one the suite speaks.
    #[error("type {0} is not one the suite reads")]
    UnknownType(String),
    /// The bytes do not decode as the type.
    #[error(transparent)]
    Cdr(CdrError),
}

/// Why a parameter change asked for while a node runs ([`Node::set_parameter`]) is
/// refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// The node takes the parameter at start only: it shapes what was already built.
    #[error(
        "{name}: {node} takes it at start only{}; relaunch with the new value",
        changeable_note(*.changeable)
    )]
    StartOnly {
        /// The parameter.
        name: String,
        /// The node's fully qualified name.
        node: String,
        /// The parameter of the node that can change while it runs, if one can.
        changeable: Option<&'static str>,
    },
    /// The value is not one the parameter takes (a wrong type or out of its range).
    #[error("{name}: {value} is not {expected}")]
    BadValue {
        /// The parameter.
        name: &'static str,
        /// The value as the node shows it.
        value: String,
        /// What it takes (`a number of seconds in [0, 3600]`).
        expected: &'static str,
    },
    /// No node of that name runs on the transport asked.
    #[error("no node {node} here")]
    NoSuchNode {
        /// The name asked for.
        node: String,
    },
    /// The node was stopped after a fault (a live transport stops a node that panicked and
    /// runs the others on).
    #[error("{node}: stopped after a fault")]
    Stopped {
        /// The node's fully qualified name.
        node: String,
    },
}

/// The note a [`ParamError::StartOnly`] adds when another parameter of the node can change.
fn changeable_note(changeable: Option<&'static str>) -> String {
    changeable.map_or_else(String::new, |p| format!(" ({p} can change while it runs)"))
}

/// One message on a topic.
#[derive(Debug, Clone)]
pub struct Message {
    /// Fully qualified topic name (`/ns/name`).
    pub topic: Arc<str>,
    /// Time of the message (ns since the epoch): the stamp of its header.
    pub stamp_ns: i64,
    /// The message.
    pub payload: Payload,
}

impl Message {
    /// A message on `topic`.
    pub fn new(topic: &str, stamp_ns: i64, payload: Payload) -> Self {
        Self {
            topic: topic.into(),
            stamp_ns,
            payload,
        }
    }
}

/// A topic a node reads or writes, with the type carried on it.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct TopicRef {
    /// Fully qualified topic name.
    pub topic: String,
    /// `pkg/msg/Type`.
    pub type_name: &'static str,
}

/// What a node has done and what went wrong, by kind (e.g. `undecodable`, `stamp_order`).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct NodeStatus {
    /// Messages received.
    pub received: u64,
    /// Messages published.
    pub published: u64,
    /// Problems by kind: how many.
    pub problems: BTreeMap<String, u64>,
    /// The first problems' texts (at most [`NodeStatus::KEPT`]).
    pub messages: Vec<String>,
    /// What a node counts besides problems, by kind (e.g. an occupancy node's
    /// `points_nonfinite`); left out of the JSON when empty.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub counts: BTreeMap<String, u64>,
}

impl NodeStatus {
    /// Problem texts kept.
    pub const KEPT: usize = 32;

    /// Counts and logs a problem of `kind` in node `node`.
    pub fn problem(&mut self, node: &str, kind: &str, text: String) {
        tracing::warn!(node, kind, "{text}");
        *self.problems.entry(kind.to_owned()).or_default() += 1;
        if self.messages.len() < Self::KEPT {
            self.messages.push(text);
        }
    }

    /// Counts `n` problems of `kind`, logging (and keeping the text of) only the first one
    /// of that kind: for kinds that may recur at a message rate.
    pub fn count_quietly(&mut self, node: &str, kind: &str, n: u64, text: impl FnOnce() -> String) {
        if n == 0 {
            return;
        }
        if let Some(c) = self.problems.get_mut(kind) {
            *c += n;
        } else {
            self.problem(node, kind, text());
            if let Some(c) = self.problems.get_mut(kind) {
                *c += n - 1;
            }
        }
    }

    /// All problems counted.
    pub fn problem_count(&self) -> u64 {
        self.problems.values().sum()
    }
}

/// A node of the suite.
pub trait Node: Send + std::any::Any {
    /// For transports that need the concrete node (e.g. the replay reads the checker's report).
    fn as_any(&self) -> &dyn std::any::Any;
    /// Fully qualified node name (`/ns/name`).
    fn name(&self) -> &str;
    /// The topics it reads.
    fn subscriptions(&self) -> Vec<TopicRef>;
    /// The topics it may publish on.
    fn publications(&self) -> Vec<TopicRef>;
    /// Handles one message on a subscribed topic; pushes what it publishes.
    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>);
    /// Handles several messages that were waiting at once, in order, pushing what they
    /// publish in the order one-by-one handling would. A node whose messages are independent
    /// (a mesher's bodies) may handle them in parallel; the result must be the same as
    /// calling [`Node::on_message`] on each in turn. The default does exactly that.
    fn on_messages(&mut self, msgs: &[Message], out: &mut Vec<Message>) {
        for m in msgs {
            self.on_message(m, out);
        }
    }
    /// The inputs have ended (a replay's bag is read, or the node shuts down): publishes
    /// what it has left (the closing mesh caps, the final report).
    fn finish(&mut self, out: &mut Vec<Message>);
    /// Time has passed on the transport's clock: `now_ns` is a monotonic time (ns): the
    /// wall clock of a live transport, the bag's log time in a replay (ticked as live
    /// would, so that a stream that stops is closed after its idle timeout there too).
    /// The default does nothing.
    fn on_tick(&mut self, now_ns: i64, out: &mut Vec<Message>) {
        let _ = (now_ns, out);
    }
    /// Publishes work a node finished off its handler's thread (a live transport calls it
    /// with each tick; a replay never does, so that what it publishes, and when, does not
    /// depend on how fast that work ran). The default does nothing.
    fn poll(&mut self, out: &mut Vec<Message>) {
        let _ = out;
    }
    /// The parameters [`Node::set_parameter`] accepts, with their current values (declared
    /// to ROS even when the launch config does not set them). The default: none.
    fn runtime_parameters(&self) -> Vec<(String, launch::ParamValue)> {
        Vec::new()
    }
    /// Changes parameter `name` while the node runs (the ROS `set_parameters` service):
    /// applied, or refused with the reason. The default refuses: most parameters shape what
    /// was already built and are taken at start only.
    ///
    /// # Errors
    /// [`ParamError`]: why the value is refused.
    fn set_parameter(&mut self, name: &str, value: &launch::ParamValue) -> Result<(), ParamError> {
        let _ = value;
        Err(ParamError::StartOnly {
            name: name.to_owned(),
            node: self.name().to_owned(),
            changeable: None,
        })
    }
    /// Whether anything reads `topic`, one of its publications, now: a node in the
    /// process, a reader on the wire, or an output bag. A node may then skip building what
    /// nobody reads (markers, labels) until someone does. Every publication is read until
    /// the transport says otherwise; the default ignores this.
    fn set_demand(&mut self, topic: &str, read: bool) {
        let _ = (topic, read);
    }
    /// Asked once by the in-process bus, before the first input, of a node whose
    /// publications no other node of the bus reads: may it run on a thread of its own,
    /// behind the nodes it reads (handed each input in its turn, its outputs taken later
    /// and recorded where its turn put them; see
    /// [`Bus::run_behind`](bus::Bus::run_behind))? A node that shares state with another
    /// node says yes only once it has made that state safe to read late (the checker's
    /// markers part then takes, for each nudge, exactly the slabs of the checker step that
    /// sent it). The default says no.
    fn run_behind(&mut self) -> bool {
        false
    }
    /// Counters and problems.
    fn status(&self) -> &NodeStatus;
    /// Position in the pipeline: nodes finish in increasing rank, so what one publishes on
    /// finishing reaches the nodes after it before they finish.
    fn rank(&self) -> u8;
}

/// Whether a topic is hidden (a name token starting with `_`, as ROS 2 hides them): a topic
/// between the parts of one node, never written to the wire or to an output bag unless a
/// recorder names it.
pub fn is_hidden_topic(topic: &str) -> bool {
    topic.split('/').any(|t| t.starts_with('_'))
}
