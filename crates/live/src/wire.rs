//! How the suite's messages go on a DDS wire the ROS 2 way: topic and type names, the QoS of
//! each kind of topic, and serialised messages passed through RustDDS untouched.
//!
//! Messages cross the wire as the CDR bytes the suite's own codec
//! ([`chronotope_msg::encode_cdr`], [`chronotope_msg::decode_cdr`]) writes and reads, the
//! same bytes a rosbag2 MCAP stores. RustDDS carries the 4-byte encapsulation header in its
//! own `SerializedPayload`, so [`RawCdr`] strips it on the way out and puts it back on the
//! way in. Nothing is decoded in the DDS threads: a sample that does not decode is found,
//! counted and logged by the transport that hands it to a node, like a bad bag message.

use std::convert::Infallible;

use rustdds::no_key::{Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{QosPolicies, QosPolicyBuilder, RepresentationIdentifier};

use chronotope_msg::{
    Clock, ContactEvent, DiagnosticArray, InterferenceReport, JointState, JointTrajectory, Marker,
    MarkerArray, MeshSlab, Octomap, PointCloud2, PoseStamped, ResolveSuggestions, RosMessage,
    RosString, TFMessage, TetLabels, VoxelGrid, WrenchStamped,
};

/// A serialised message: the 4-byte CDR encapsulation header, then the body.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawCdr(pub Vec<u8>);

/// Why a message cannot be written to the wire as it is.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RawCdrError {
    /// Shorter than the encapsulation header.
    #[error("a serialised message of {0} bytes has no 4-byte encapsulation header")]
    NoHeader(usize),
    /// Not little-endian plain CDR (the suite writes nothing else; a bag may hold others).
    #[error("encapsulation {0:02x} {1:02x} is not little-endian CDR (00 01): not sent")]
    NotCdrLe(u8, u8),
}

/// Serialises a [`RawCdr`] by handing its body to RustDDS (which writes the header itself).
pub struct RawCdrAdapter;

impl SerializerAdapter<RawCdr> for RawCdrAdapter {
    type Error = RawCdrError;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &RawCdr) -> Result<rustdds::bytes::Bytes, RawCdrError> {
        let v = &value.0;
        if v.len() < 4 {
            return Err(RawCdrError::NoHeader(v.len()));
        }
        if v[..2] != [0x00, 0x01] {
            return Err(RawCdrError::NotCdrLe(v[0], v[1]));
        }
        Ok(rustdds::bytes::Bytes::copy_from_slice(&v[4..]))
    }
}

/// Takes a received sample's bytes as they are, header restored.
#[derive(Clone, Copy)]
pub struct RawCdrDecoder;

impl Decode<'_, RawCdr> for RawCdrDecoder {
    type Error = Infallible;

    fn decode_bytes(
        self,
        input: &[u8],
        encoding: RepresentationIdentifier,
    ) -> Result<RawCdr, Infallible> {
        let kind = if encoding == RepresentationIdentifier::CDR_BE {
            0x00
        } else {
            0x01
        };
        let mut v = Vec::with_capacity(input.len() + 4);
        v.extend_from_slice(&[0x00, kind, 0x00, 0x00]);
        v.extend_from_slice(input);
        Ok(RawCdr(v))
    }
}

impl DeserializerAdapter<RawCdr> for RawCdrAdapter {
    type Error = Infallible;
    type Decoded = RawCdr;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::CDR_BE,
        ]
    }

    fn transform_decoded(decoded: RawCdr) -> RawCdr {
        decoded
    }
}

impl DefaultDecoder<RawCdr> for RawCdrAdapter {
    type Decoder = RawCdrDecoder;
    const DECODER: RawCdrDecoder = RawCdrDecoder;
}

/// The DDS topic of a ROS topic: `/a/b` is `rt/a/b`.
pub fn dds_topic_name(ros_topic: &str) -> String {
    format!("rt{}", ensure_absolute(ros_topic))
}

/// The ROS topic of a DDS topic (`rt/a/b` is `/a/b`); `None` for DDS topics that are not ROS
/// topics (services `rq/`, `rr/`, or plain DDS).
pub fn ros_topic_name(dds_topic: &str) -> Option<&str> {
    dds_topic.strip_prefix("rt").filter(|t| t.starts_with('/'))
}

fn ensure_absolute(t: &str) -> String {
    if t.starts_with('/') {
        t.to_owned()
    } else {
        format!("/{t}")
    }
}

/// The DDS type of a ROS type: `pkg/msg/Type` is `pkg::msg::dds_::Type_`.
pub fn dds_type_name(ros_type: &str) -> String {
    let mut parts = ros_type.rsplitn(2, '/');
    let name = parts.next().unwrap_or_default();
    let pkg = parts.next().unwrap_or_default();
    format!("{}::dds_::{name}_", pkg.replace('/', "::"))
}

/// The ROS type of a DDS type (`pkg::msg::dds_::Type_` is `pkg/msg/Type`), if it is one.
pub fn ros_type_name(dds_type: &str) -> Option<String> {
    let (pkg, name) = dds_type.rsplit_once("::dds_::")?;
    let name = name.strip_suffix('_')?;
    Some(format!("{}/{name}", pkg.replace("::", "/")))
}

/// The QoS of one kind of topic, in ROS terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct TopicQos {
    /// Reliable (resent until acknowledged) or best effort.
    pub reliable: bool,
    /// Transient local: a late subscriber gets the last `depth` messages.
    pub transient_local: bool,
    /// Keep-last depth of the history.
    pub depth: i32,
}

impl TopicQos {
    /// Reliable, volatile, keep last `depth`: frames and meshes, where every message counts.
    pub const fn reliable(depth: i32) -> Self {
        Self {
            reliable: true,
            transient_local: false,
            depth,
        }
    }

    /// Reliable, transient local, keep last `depth`: results a late subscriber still wants.
    pub const fn latched(depth: i32) -> Self {
        Self {
            reliable: true,
            transient_local: true,
            depth,
        }
    }

    /// Best effort, volatile, keep last `depth`: high-rate streams where only the newest
    /// message matters (poses, forces, the clock).
    pub const fn best_effort(depth: i32) -> Self {
        Self {
            reliable: false,
            transient_local: false,
            depth,
        }
    }

    /// The suite's QoS for a topic of type `ros_type` (`pkg/msg/Type`); ROS's default
    /// (reliable, volatile, keep last 10) for types it does not know.
    pub fn for_type(ros_type: &str) -> Self {
        match ros_type {
            t if t == VoxelGrid::TYPE_NAME => Self::reliable(16),
            t if t == MeshSlab::TYPE_NAME => Self::reliable(64),
            t if t == InterferenceReport::TYPE_NAME || t == ResolveSuggestions::TYPE_NAME => {
                Self::latched(1)
            }
            // Two per checked pair and frame period: a late subscriber gets the latest
            // 64 (the history is not kept: a stream may run for hours).
            t if t == TetLabels::TYPE_NAME => Self::latched(64),
            // Every event counts; a late subscriber reads the report for what came before.
            t if t == ContactEvent::TYPE_NAME => Self::reliable(64),
            // One per body and frame period: a late subscriber gets the latest 32 (each
            // body's latest for up to 32 bodies). The writer keeps `depth` samples and what
            // came since RustDDS last cleaned its cache (every 6 s): a 128³ body's array is
            // ~7.6 MB, so 256 kept 1.4 GB (all 189 arrays of a 6 s run, still held after).
            t if t == MarkerArray::TYPE_NAME => Self::latched(32),
            t if t == Marker::TYPE_NAME => Self::best_effort(16),
            t if t == PointCloud2::TYPE_NAME => Self::latched(1),
            // Depth 16: a best-effort writer keeps at most `depth` samples not yet sent, the
            // newest evicting the oldest, so depth 1 lost wrenches written back to back
            // after a stall. A reader still takes the latest.
            t if t == PoseStamped::TYPE_NAME || t == WrenchStamped::TYPE_NAME => {
                Self::best_effort(16)
            }
            t if t == Clock::TYPE_NAME => Self::best_effort(1),
            t if t == DiagnosticArray::TYPE_NAME => Self::reliable(10),
            // A robot cell's: the robot description (robot_state_publisher) and `/tf_static`
            // (tf2's static broadcaster) are latched, keep last 1. Joint states are read best
            // effort as robot_state_publisher reads them (sensor data QoS), which matches
            // reliable and best-effort publishers alike; 100 deep for 1 kHz bursts. Plans go
            // reliable and volatile, as joint_trajectory_controller reads them.
            t if t == RosString::TYPE_NAME || t == TFMessage::TYPE_NAME => Self::latched(1),
            t if t == JointState::TYPE_NAME => Self::best_effort(100),
            t if t == JointTrajectory::TYPE_NAME => Self::reliable(10),
            _ => Self::reliable(10),
        }
    }

    /// The QoS the suite's readers ask for on a topic of type `ros_type`: [`Self::for_type`],
    /// except for sensor input. Point clouds and OctoMaps come from drivers and mappers that
    /// offer anything from best effort and volatile (the sensor-data profile of camera and
    /// lidar drivers) to reliable and transient local (octomap_server): a reader asking for
    /// best effort and volatile matches them all (DDS matches a reader only to writers
    /// offering at least what it asks), and takes the newest.
    pub fn reader_for_type(ros_type: &str) -> Self {
        match ros_type {
            t if t == PointCloud2::TYPE_NAME || t == Octomap::TYPE_NAME => Self::best_effort(4),
            t => Self::for_type(t),
        }
    }

    /// As RustDDS policies. Reliable writers block at most 100 ms on a full history. The
    /// resource limit of `depth` samples bounds what a reliable writer keeps for readers that
    /// have not acknowledged (RustDDS keeps every unacknowledged sample of a transient-local
    /// writer otherwise, up to 8192: gigabytes of clouds and markers with a slow reader or
    /// none); it is applied at RustDDS's cache cleaning, every 6 s.
    pub fn policies(&self) -> QosPolicies {
        let b = QosPolicyBuilder::new()
            .history(History::KeepLast { depth: self.depth })
            .resource_limits(rustdds::policy::ResourceLimits {
                max_samples: self.depth,
                max_instances: 1,
                max_samples_per_instance: self.depth,
            })
            .durability(if self.transient_local {
                Durability::TransientLocal
            } else {
                Durability::Volatile
            });
        let b = if self.reliable {
            b.reliability(Reliability::Reliable {
                max_blocking_time: rustdds::Duration::from_millis(100),
            })
        } else {
            b.reliability(Reliability::BestEffort)
        };
        b.build()
    }

    /// The `offered_qos_profiles` YAML rosbag2 stores with a channel recorded at this QoS.
    pub fn rosbag2_yaml(&self) -> String {
        format!(
            "- history: 1\n  depth: {}\n  reliability: {}\n  durability: {}\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n",
            self.depth,
            if self.reliable { 1 } else { 2 },
            if self.transient_local { 1 } else { 2 },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_map_both_ways() {
        assert_eq!(dds_topic_name("/a/b"), "rt/a/b");
        assert_eq!(dds_topic_name("chatter"), "rt/chatter");
        assert_eq!(ros_topic_name("rt/a/b"), Some("/a/b"));
        assert_eq!(ros_topic_name("rq/a/bRequest"), None);
        assert_eq!(
            dds_type_name("chronotope_msgs/msg/VoxelGrid"),
            "chronotope_msgs::msg::dds_::VoxelGrid_"
        );
        assert_eq!(
            ros_type_name("visualization_msgs::msg::dds_::MarkerArray_").as_deref(),
            Some("visualization_msgs/msg/MarkerArray")
        );
        assert_eq!(ros_type_name("SomeDdsType"), None);
    }

    #[test]
    fn raw_cdr_round_trips_through_the_adapters() {
        let msg = RawCdr(vec![0, 1, 0, 0, 7, 0, 0, 0, 42]);
        let body = <RawCdrAdapter as SerializerAdapter<RawCdr>>::to_bytes(&msg).unwrap();
        assert_eq!(&body[..], &[7, 0, 0, 0, 42]);
        let back = RawCdrDecoder
            .decode_bytes(&body, RepresentationIdentifier::CDR_LE)
            .unwrap();
        assert_eq!(back, msg);
        let big_endian = RawCdr(vec![0, 0, 0, 0, 1]);
        assert_eq!(
            <RawCdrAdapter as SerializerAdapter<RawCdr>>::to_bytes(&big_endian),
            Err(RawCdrError::NotCdrLe(0, 0))
        );
        assert_eq!(
            <RawCdrAdapter as SerializerAdapter<RawCdr>>::to_bytes(&RawCdr(vec![0, 1])),
            Err(RawCdrError::NoHeader(2))
        );
    }

    #[test]
    fn qos_follows_the_kind_of_topic() {
        assert!(TopicQos::for_type(VoxelGrid::TYPE_NAME).reliable);
        assert!(TopicQos::for_type(InterferenceReport::TYPE_NAME).transient_local);
        assert!(!TopicQos::for_type(PoseStamped::TYPE_NAME).reliable);
        assert_eq!(TopicQos::for_type("x/msg/Unknown"), TopicQos::reliable(10));
        // Sensor input is read as best effort, volatile: it matches every writer.
        let cloud = TopicQos::reader_for_type(PointCloud2::TYPE_NAME);
        assert!(!cloud.reliable && !cloud.transient_local);
        assert_eq!(
            TopicQos::reader_for_type(VoxelGrid::TYPE_NAME),
            TopicQos::for_type(VoxelGrid::TYPE_NAME)
        );
    }
}
