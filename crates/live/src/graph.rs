//! The suite in the ROS graph: which node owns which DDS endpoint, told the way ROS 2's
//! middleware tells it, so that `ros2 node info` lists every node's publishers and
//! subscriptions.
//!
//! ROS 2 does not learn a node's endpoints from DDS discovery (DDS knows participants, not
//! nodes): every participant publishes, on the DDS topic `ros_discovery_info`, an
//! `rmw_dds_common/ParticipantEntitiesInfo`: its GID and, per node, the GIDs of the node's
//! readers and writers. rmw_dds_common's graph cache keeps the latest of these per
//! participant GID (a new one replaces the old one whole), finds a node by name in the first
//! participant that lists it, and looks the node's GIDs up among all the endpoints DDS
//! discovered, whatever their participant: topic names, types and QoS come from there.
//!
//! ros2-client's `Context` publishes this for the endpoints made through its `Node` API
//! (parameter services, rosout, parameter events) only; the suite's readers and writers of
//! serialised messages are RustDDS's own, some in other participants of the process (the
//! bulk participant, a real-time node's participant), and ros2-client cannot be told about
//! them. So the transport publishes the whole story itself, for the main participant (the
//! one whose `Context` holds the ROS nodes): the `Context`'s own info with each node's raw
//! endpoints added ([`merge`]).
//!
//! The `Context`'s writer keeps its own (smaller) sample for the same participant GID, and a
//! reader that joins late gets both in no particular order. So the full info is published
//! again a moment after every new reader of `ros_discovery_info` matches (and after start,
//! once the `Context` has said its last word): the last one a reader takes is the full one.
//! See docs/live.md, "The ROS graph", for what this leaves out.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use rustdds::no_key::DataWriterCdr;
use rustdds::{DataWriterStatus, StatusEvented, TopicKind, GUID};
use serde::{Deserialize, Serialize};

use super::{dds_err, LiveError, Participant};

/// Bytes of a GID on the wire: 16 from ROS 2 Iron on (`char[16] data`), 24 before (Humble).
/// ros2-client decides it (its distribution feature; the suite builds it for Jazzy).
pub const GID_LENGTH: usize = ros2_client::gid::GID_LENGTH;

/// A DDS entity's GID as `rmw_dds_common/Gid` carries it: the 16-byte GUID, zero-padded.
pub type Gid = [u8; GID_LENGTH];

/// The GID of a DDS entity.
pub fn gid(guid: GUID) -> Gid {
    *ros2_client::Gid::from(guid).as_bytes()
}

/// `rmw_dds_common/msg/ParticipantEntitiesInfo`, field for field.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ParticipantEntities {
    /// The participant's GID.
    pub gid: Gid,
    /// The ROS nodes it holds.
    pub node_entities_info_seq: Vec<NodeEntities>,
}

/// `rmw_dds_common/msg/NodeEntitiesInfo`, field for field.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeEntities {
    /// `/` or `/ns`.
    pub node_namespace: String,
    /// The node's base name.
    pub node_name: String,
    /// Its readers.
    pub reader_gid_seq: Vec<Gid>,
    /// Its writers.
    pub writer_gid_seq: Vec<Gid>,
}

impl NodeEntities {
    /// `/ns/name`.
    pub fn fully_qualified_name(&self) -> String {
        match self.node_namespace.as_str() {
            "/" | "" => format!("/{}", self.node_name),
            ns => format!("{ns}/{}", self.node_name),
        }
    }
}

/// The DDS type of `ros_discovery_info`.
const TYPE_NAME: &str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";
const TOPIC_NAME: &str = "ros_discovery_info";

/// A node's own endpoints, besides those ros2-client made for it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NodeEndpoints {
    /// Its readers.
    pub readers: Vec<Gid>,
    /// Its writers.
    pub writers: Vec<Gid>,
}

/// `base` (what ros2-client says) with each node's `extra` endpoints added (once each); a
/// node `base` does not list is added.
pub fn merge(
    mut base: ParticipantEntities,
    extra: &BTreeMap<String, NodeEndpoints>,
) -> ParticipantEntities {
    fn add(seq: &mut Vec<Gid>, more: &[Gid]) {
        for g in more {
            if !seq.contains(g) {
                seq.push(*g);
            }
        }
    }
    for (fqn, e) in extra {
        let at = base
            .node_entities_info_seq
            .iter()
            .position(|n| n.fully_qualified_name() == *fqn);
        let node = match at {
            Some(i) => &mut base.node_entities_info_seq[i],
            None => {
                let (ns, name) = split_fqn(fqn);
                base.node_entities_info_seq.push(NodeEntities {
                    node_namespace: ns.to_owned(),
                    node_name: name.to_owned(),
                    reader_gid_seq: Vec::new(),
                    writer_gid_seq: Vec::new(),
                });
                base.node_entities_info_seq.last_mut().expect("just pushed")
            }
        };
        add(&mut node.reader_gid_seq, &e.readers);
        add(&mut node.writer_gid_seq, &e.writers);
    }
    base
}

/// `/ns/name` as `(namespace, name)`, the namespace `/` at the root.
pub fn split_fqn(fqn: &str) -> (&str, &str) {
    match fqn.rsplit_once('/') {
        Some(("", n)) => ("/", n),
        Some((ns, n)) => (ns, n),
        None => ("/", fqn),
    }
}

/// ros2-client's info in the wire's own terms (its types keep the GID lists private; both
/// serialise the same fields, so one is read back as the other).
fn from_ros2_client(
    info: &ros2_client::entities_info::ParticipantEntitiesInfo,
) -> Result<ParticipantEntities, serde_json::Error> {
    serde_json::to_value(info).and_then(serde_json::from_value)
}

/// When the full info goes out again after a reader of `ros_discovery_info` matched: soon
/// (after the `Context`'s sample has reached it), and once more later in case that sample
/// needed a repair round.
const REPUBLISH_AFTER: [Duration; 2] = [Duration::from_millis(300), Duration::from_millis(1500)];

/// Publishes the process's ROS nodes with all their endpoints on `ros_discovery_info`.
pub struct GraphAnnouncer {
    ctx: ros2_client::Context,
    writer: DataWriterCdr<ParticipantEntities>,
    endpoints: BTreeMap<String, NodeEndpoints>,
    /// The next publications due (at most one per [`REPUBLISH_AFTER`] entry: bounded).
    due: [Option<Instant>; 2],
}

impl GraphAnnouncer {
    /// A writer of `ros_discovery_info` on `participant` (the one holding the ROS nodes),
    /// with the QoS ros2-client and rmw give it (reliable, transient local, keep last 1).
    ///
    /// # Errors
    /// RustDDS refuses the topic or the writer.
    pub fn new(participant: &Participant) -> Result<Self, LiveError> {
        let qos: &rustdds::QosPolicies = &ros2_client::builtin_topics::ros_discovery::QOS_PUB;
        let topic = participant
            .dp
            .create_topic(
                TOPIC_NAME.to_owned(),
                TYPE_NAME.to_owned(),
                qos,
                TopicKind::NoKey,
            )
            .map_err(|e| e.to_string())
            .map_err(dds_err("the topic ros_discovery_info"))?;
        let writer = participant
            .publisher
            .create_datawriter_no_key::<ParticipantEntities, _>(&topic, Some(qos.clone()))
            .map_err(|e| e.to_string())
            .map_err(dds_err("a writer on ros_discovery_info"))?;
        Ok(Self {
            ctx: participant.ctx.clone(),
            writer,
            endpoints: BTreeMap::new(),
            due: [None; 2],
        })
    }

    /// Counts `reader` as node `fqn`'s.
    pub fn add_reader(&mut self, fqn: &str, reader: GUID) {
        let e = self.endpoints.entry(fqn.to_owned()).or_default();
        let g = gid(reader);
        if !e.readers.contains(&g) {
            e.readers.push(g);
        }
    }

    /// Counts `writer` as node `fqn`'s.
    pub fn add_writer(&mut self, fqn: &str, writer: GUID) {
        let e = self.endpoints.entry(fqn.to_owned()).or_default();
        let g = gid(writer);
        if !e.writers.contains(&g) {
            e.writers.push(g);
        }
    }

    /// The full info: ros2-client's with the nodes' own endpoints.
    ///
    /// # Errors
    /// ros2-client's info does not read as `ParticipantEntitiesInfo` (it always does).
    pub fn info(&self) -> Result<ParticipantEntities, serde_json::Error> {
        Ok(merge(
            from_ros2_client(&self.ctx.participant_entities_info())?,
            &self.endpoints,
        ))
    }

    /// Publishes the full info now, and again a little later (after what ros2-client's
    /// `Context` said last).
    pub fn announce(&mut self, now: Instant) {
        self.publish();
        self.schedule(now);
    }

    /// Publishes what is due: a reader of `ros_discovery_info` that matched since the last
    /// call gets the full info again, after ros2-client's. Call it often (every tick).
    pub fn poll(&mut self, now: Instant) {
        let mut matched = false;
        while let Some(s) = self.writer.try_recv_status() {
            matched |= matches!(s, DataWriterStatus::PublicationMatched { .. });
        }
        if matched {
            self.schedule(now);
        }
        let mut go = false;
        for d in &mut self.due {
            if d.is_some_and(|t| t <= now) {
                *d = None;
                go = true;
            }
        }
        if go {
            self.publish();
        }
    }

    fn schedule(&mut self, now: Instant) {
        for (d, after) in self.due.iter_mut().zip(REPUBLISH_AFTER) {
            // A later match pushes a pending publication back: it must follow the Context's
            // sample to the new reader too.
            *d = Some(now + after);
        }
    }

    fn publish(&mut self) {
        match self.info() {
            Ok(info) => {
                if let Err(e) = self.writer.write(info, Some(rustdds::Timestamp::now())) {
                    tracing::warn!("ros_discovery_info not sent: {e}");
                }
            }
            Err(e) => tracing::warn!("ros_discovery_info: ros2-client's info does not read: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn g(b: u8) -> Gid {
        [b; GID_LENGTH]
    }

    #[test]
    fn a_gid_is_the_guid_padded() {
        let guid = GUID::from_bytes(std::array::from_fn(|i| i as u8 + 1));
        let id = gid(guid);
        assert_eq!(id[..16], guid.to_bytes()[..]);
        assert!(id[16..].iter().all(|&b| b == 0));
    }

    #[test]
    fn names_split_as_ros_does() {
        assert_eq!(split_fqn("/checker"), ("/", "checker"));
        assert_eq!(split_fqn("/cell/checker"), ("/cell", "checker"));
        let n = NodeEntities {
            node_namespace: "/cell".into(),
            node_name: "checker".into(),
            reader_gid_seq: vec![],
            writer_gid_seq: vec![],
        };
        assert_eq!(n.fully_qualified_name(), "/cell/checker");
    }

    #[test]
    fn merging_adds_each_node_s_endpoints_once_and_keeps_ros2_client_s() {
        let base = ParticipantEntities {
            gid: g(1),
            node_entities_info_seq: vec![
                NodeEntities {
                    node_namespace: "/".into(),
                    node_name: "checker".into(),
                    reader_gid_seq: vec![g(2)],
                    writer_gid_seq: vec![g(3)],
                },
                NodeEntities {
                    node_namespace: "/".into(),
                    node_name: "mesher".into(),
                    reader_gid_seq: vec![],
                    writer_gid_seq: vec![g(4)],
                },
            ],
        };
        let mut extra = BTreeMap::new();
        extra.insert(
            "/checker".to_owned(),
            NodeEndpoints {
                readers: vec![g(5)],
                writers: vec![g(3), g(6)],
            },
        );
        extra.insert(
            "/cell/carving".to_owned(),
            NodeEndpoints {
                readers: vec![],
                writers: vec![g(7)],
            },
        );
        let m = merge(base, &extra);
        assert_eq!(m.gid, g(1));
        let checker = &m.node_entities_info_seq[0];
        assert_eq!(checker.reader_gid_seq, vec![g(2), g(5)]);
        assert_eq!(checker.writer_gid_seq, vec![g(3), g(6)]);
        let mesher = &m.node_entities_info_seq[1];
        assert_eq!(mesher.writer_gid_seq, vec![g(4)]);
        let carving = &m.node_entities_info_seq[2];
        assert_eq!(
            (carving.node_namespace.as_str(), carving.node_name.as_str()),
            ("/cell", "carving")
        );
        assert_eq!(carving.writer_gid_seq, vec![g(7)]);
    }

    #[test]
    fn ros2_client_s_info_reads_as_the_wire_type() {
        let mut node = ros2_client::entities_info::NodeEntitiesInfo::new(
            ros2_client::NodeName::new("/cell", "checker").unwrap(),
        );
        node.add_reader(ros2_client::Gid::from([2u8; 16]));
        node.add_writer(ros2_client::Gid::from([3u8; 16]));
        let info = ros2_client::entities_info::ParticipantEntitiesInfo::new(
            ros2_client::Gid::from([1u8; 16]),
            vec![node],
        );
        let ours = from_ros2_client(&info).unwrap();
        let pad = |b: u8| -> Gid { std::array::from_fn(|i| if i < 16 { b } else { 0 }) };
        assert_eq!(
            ours,
            ParticipantEntities {
                gid: pad(1),
                node_entities_info_seq: vec![NodeEntities {
                    node_namespace: "/cell".into(),
                    node_name: "checker".into(),
                    reader_gid_seq: vec![pad(2)],
                    writer_gid_seq: vec![pad(3)],
                }],
            }
        );
    }
}
