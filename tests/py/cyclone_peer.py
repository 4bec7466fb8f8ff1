#!/usr/bin/env python3
"""An independent DDS peer for the live nodes: Cyclone DDS (PyPI `cyclonedds`), no ROS.

Plays the VoxelGrid frames of a rosbag2 MCAP bag onto the wire with their recorded timing
(and its PointCloud2, octomap_msgs/Octomap and tf2_msgs/TFMessage messages, which occupancy
nodes read; static transforms and maps latched, as tf2 and octomap_server offer them) and
collects what the checker publishes (report, labels, optionally markers), then writes
it as JSON.  Used by tests/it/cyclone.rs; see docs/live.md.

    python3 tests/py/cyclone_peer.py --bag BAG --out OUT.json [--domain N] [--rate R]
                                     [--match-timeout S] [--timeout S]
                                     [--markers [--expect-markers N | --markers-quiet S]]

Domain: --domain, else ROS_DOMAIN_ID, else 0.  Discovery is loopback only (CYCLONEDDS_URI
set here unless the environment already sets it; see CYCLONE_XML).

Floats in the JSON are written as the hex of their IEEE-754 bit pattern (16 hex digits,
big-endian, as `struct.pack(">d")`), so that a reader can compare them exactly; NaN stays
NaN.  Exit status: 0 when the report, every label (two per reported pair) and, with
--expect-markers N, N marker arrays arrived;
1 (with the reason on stderr, and what did arrive still written) on timeout; 2 on bad use.
"""


import argparse
import bisect
import hashlib
import json
import os
import struct
import sys
import time
from dataclasses import dataclass

# Loopback-only discovery.  RustDDS sends its SPDP announcements to the multicast group and
# to the unicast discovery ports of participant indices on 127.0.0.1; Cyclone, with
# multicast off, listens on the unicast discovery port of its own (auto) participant index
# and sends its announcements to the ports of indices 0..MaxAutoParticipantIndex on each
# peer.  Bigger receive buffers: markers arrive as hundreds of fragments (docs/live.md).
CYCLONE_XML = """<CycloneDDS><Domain id="any">
  <General>
    <Interfaces><NetworkInterface name="lo"/></Interfaces>
    <AllowMulticast>false</AllowMulticast>
  </General>
  <Discovery>
    <Peers><Peer address="127.0.0.1"/></Peers>
    <ParticipantIndex>auto</ParticipantIndex>
    <MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>
  </Discovery>
  <Internal>
    <SocketReceiveBufferSize min="default" max="8MB"/>
  </Internal>
</Domain></CycloneDDS>"""

if "CYCLONEDDS_URI" not in os.environ:
    os.environ["CYCLONEDDS_URI"] = CYCLONE_XML

try:
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.internal import InvalidSample
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import float32, float64, int8, int32, sequence, uint8, uint32, uint64
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
except ImportError as e:  # pragma: no cover
    print(f"cyclone_peer: cannot import cyclonedds ({e}); python3 tests/py/setup_env.py makes target/py",
          file=sys.stderr)
    sys.exit(3)

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


# ---- the types, field for field as the .msg files (msgs/msg, msgs/deps) ----------------
# Default (final) IdlStruct: plain CDR (XCDR1), which RustDDS reads and writes.

@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class ColorRGBA(IdlStruct, typename="std_msgs::msg::dds_::ColorRGBA_"):
    r: float32
    g: float32
    b: float32
    a: float32


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header
    format: str
    data: sequence[uint8]


@dataclass
class UVCoordinate(IdlStruct, typename="visualization_msgs::msg::dds_::UVCoordinate_"):
    u: float32
    v: float32


@dataclass
class MeshFile(IdlStruct, typename="visualization_msgs::msg::dds_::MeshFile_"):
    filename: str
    data: sequence[uint8]


@dataclass
class Marker(IdlStruct, typename="visualization_msgs::msg::dds_::Marker_"):
    header: Header
    ns: str
    id: int32
    type: int32
    action: int32
    pose: Pose
    scale: Vector3
    color: ColorRGBA
    lifetime: Duration
    frame_locked: bool
    points: sequence[Point]
    colors: sequence[ColorRGBA]
    texture_resource: str
    texture: CompressedImage
    uv_coordinates: sequence[UVCoordinate]
    text: str
    mesh_resource: str
    mesh_file: MeshFile
    mesh_use_embedded_materials: bool


@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs::msg::dds_::MarkerArray_"):
    markers: sequence[Marker]


@dataclass
class VoxelGrid(IdlStruct, typename="chronotope_msgs::msg::dds_::VoxelGrid_"):
    header: Header
    origin: Point
    resolution: float64
    size_x: uint32
    size_y: uint32
    size_z: uint32
    encoding: uint8
    data: sequence[uint8]


@dataclass
class PointField(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
    name: str
    offset: uint32
    datatype: uint8
    count: uint32


@dataclass
class PointCloud2(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
    header: Header
    height: uint32
    width: uint32
    fields: sequence[PointField]
    is_bigendian: bool
    point_step: uint32
    row_step: uint32
    data: sequence[uint8]
    is_dense: bool


@dataclass
class Octomap(IdlStruct, typename="octomap_msgs::msg::dds_::Octomap_"):
    header: Header
    binary: bool
    id: str
    resolution: float64
    data: sequence[int8]


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped]


@dataclass
class RosString(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@dataclass
class BodySummary(IdlStruct, typename="chronotope_msgs::msg::dds_::BodySummary_"):
    body_id: str
    frames: uint64
    skipped_frames: uint64
    tets: uint64
    vertices: uint64
    closed: bool
    hypervolume_m3s: float64
    vanishing_slabs: uint64


@dataclass
class PairInterference(IdlStruct, typename="chronotope_msgs::msg::dds_::PairInterference_"):
    body_a: str
    body_b: str
    verdict: uint8
    unsure_start_s: sequence[float64]
    unsure_end_s: sequence[float64]
    unsure_reason: sequence[str]
    interfering: bool
    interval_start_s: sequence[float64]
    interval_end_s: sequence[float64]
    first_contact_s: float64
    first_contact_error_bound_s: float64
    closing_speed_mps: float64
    overlap_hypervolume_m3s: float64
    overlap_hypervolume_error_bound_m3s: float64
    a_interference: uint64
    a_inside: uint64
    a_outside: uint64
    b_interference: uint64
    b_inside: uint64
    b_outside: uint64


@dataclass
class InterferenceReport(IdlStruct, typename="chronotope_msgs::msg::dds_::InterferenceReport_"):
    header: Header
    time_origin: Time
    time_scale_m_per_s: float64
    voxel_size_m: float64
    bodies: sequence[BodySummary]
    pairs: sequence[PairInterference]


@dataclass
class TetLabels(IdlStruct, typename="chronotope_msgs::msg::dds_::TetLabels_"):
    header: Header
    body_id: str
    other_id: str
    index: uint32
    stamp_lo: Time
    stamp_hi: Time
    with_cap_start: bool
    with_cap_end: bool
    labels: sequence[uint8]
    interference: uint64
    inside: uint64
    outside: uint64


@dataclass
class ContactEvent(IdlStruct, typename="chronotope_msgs::msg::dds_::ContactEvent_"):
    header: Header
    body_a: str
    body_b: str
    event: uint8
    contact_index: uint64
    time_origin: Time
    start_s: float64
    end_s: float64
    start_error_bound_s: float64
    end_error_bound_s: float64
    first_contact_s: float64
    overlap_hypervolume_m3s: float64
    unsure_reason: str


# ---- helpers ----------------------------------------------------------------------------

def log(msg: str) -> None:
    print(f"cyclone_peer: {msg}", file=sys.stderr, flush=True)


def fbits(x: float) -> str:
    return struct.pack(">d", x).hex()


def time_json(t) -> dict:
    return {"sec": int(t.sec), "nanosec": int(t.nanosec)}


def report_json(r: InterferenceReport) -> dict:
    return {
        "header": {"stamp": time_json(r.header.stamp), "frame_id": r.header.frame_id},
        "time_origin": time_json(r.time_origin),
        "time_scale_m_per_s": fbits(r.time_scale_m_per_s),
        "voxel_size_m": fbits(r.voxel_size_m),
        "bodies": [
            {
                "body_id": b.body_id,
                "frames": int(b.frames),
                "skipped_frames": int(b.skipped_frames),
                "tets": int(b.tets),
                "vertices": int(b.vertices),
                "closed": bool(b.closed),
                "hypervolume_m3s": fbits(b.hypervolume_m3s),
                "vanishing_slabs": int(b.vanishing_slabs),
            }
            for b in r.bodies
        ],
        "pairs": [
            {
                "body_a": p.body_a,
                "body_b": p.body_b,
                "verdict": int(p.verdict),
                "unsure_start_s": [fbits(x) for x in p.unsure_start_s],
                "unsure_end_s": [fbits(x) for x in p.unsure_end_s],
                "unsure_reason": list(p.unsure_reason),
                "interfering": bool(p.interfering),
                "interval_start_s": [fbits(x) for x in p.interval_start_s],
                "interval_end_s": [fbits(x) for x in p.interval_end_s],
                "first_contact_s": fbits(p.first_contact_s),
                "first_contact_error_bound_s": fbits(p.first_contact_error_bound_s),
                "closing_speed_mps": fbits(p.closing_speed_mps),
                "overlap_hypervolume_m3s": fbits(p.overlap_hypervolume_m3s),
                "overlap_hypervolume_error_bound_m3s": fbits(p.overlap_hypervolume_error_bound_m3s),
                "a_interference": int(p.a_interference),
                "a_inside": int(p.a_inside),
                "a_outside": int(p.a_outside),
                "b_interference": int(p.b_interference),
                "b_inside": int(p.b_inside),
                "b_outside": int(p.b_outside),
            }
            for p in r.pairs
        ],
    }


def labels_json(l: TetLabels) -> dict:
    data = bytes(l.labels)
    return {
        "header": {"stamp": time_json(l.header.stamp), "frame_id": l.header.frame_id},
        "body_id": l.body_id,
        "other_id": l.other_id,
        "index": int(l.index),
        "stamp_lo": time_json(l.stamp_lo),
        "stamp_hi": time_json(l.stamp_hi),
        "with_cap_start": bool(l.with_cap_start),
        "with_cap_end": bool(l.with_cap_end),
        "len": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
        "interference": int(l.interference),
        "inside": int(l.inside),
        "outside": int(l.outside),
    }


def contact_json(c: ContactEvent) -> dict:
    return {
        "header": {"stamp": time_json(c.header.stamp), "frame_id": c.header.frame_id},
        "body_a": c.body_a,
        "body_b": c.body_b,
        "event": int(c.event),
        "contact_index": int(c.contact_index),
        "time_origin": time_json(c.time_origin),
        "start_s": fbits(c.start_s),
        "end_s": fbits(c.end_s),
        "start_error_bound_s": fbits(c.start_error_bound_s),
        "end_error_bound_s": fbits(c.end_error_bound_s),
        "first_contact_s": fbits(c.first_contact_s),
        "overlap_hypervolume_m3s": fbits(c.overlap_hypervolume_m3s),
    }


def markers_json(m: MarkerArray) -> dict:
    """Marker count, [ns, id, type, action] of each, the points and a sha256 over every
    point's x, y, z as little-endian float64, all markers in order."""
    h = hashlib.sha256()
    for k in m.markers:
        for p in k.points:
            h.update(struct.pack("<3d", p.x, p.y, p.z))
    return {
        "markers": len(m.markers),
        "ids": [[k.ns, int(k.id), int(k.type), int(k.action)] for k in m.markers],
        "points": sum(len(k.points) for k in m.markers),
        "points_sha256": h.hexdigest(),
    }


def header_of(h) -> Header:
    return Header(stamp=Time(sec=h.stamp.sec, nanosec=h.stamp.nanosec), frame_id=h.frame_id)


def voxel_grid(m) -> VoxelGrid:
    return VoxelGrid(
        header=header_of(m.header),
        origin=Point(x=m.origin.x, y=m.origin.y, z=m.origin.z),
        resolution=m.resolution,
        size_x=m.size_x,
        size_y=m.size_y,
        size_z=m.size_z,
        encoding=m.encoding,
        data=bytes(m.data),
    )


def point_cloud(m) -> PointCloud2:
    return PointCloud2(
        header=header_of(m.header), height=m.height, width=m.width,
        fields=[PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count) for f in m.fields],
        is_bigendian=m.is_bigendian, point_step=m.point_step, row_step=m.row_step,
        data=bytes(m.data), is_dense=m.is_dense)


def octomap(m) -> Octomap:
    # int8[]: as signed values, whether the decoder gives bytes (0..255) or ints.
    data = [int(v) - 256 if int(v) > 127 else int(v) for v in m.data]
    return Octomap(header=header_of(m.header), binary=m.binary, id=m.id, resolution=m.resolution, data=data)


def tf_message(m) -> TFMessage:
    return TFMessage(transforms=[
        TransformStamped(
            header=header_of(t.header), child_frame_id=t.child_frame_id,
            transform=Transform(
                translation=Vector3(x=t.transform.translation.x, y=t.transform.translation.y,
                                    z=t.transform.translation.z),
                rotation=Quaternion(x=t.transform.rotation.x, y=t.transform.rotation.y,
                                    z=t.transform.rotation.z, w=t.transform.rotation.w)))
        for t in m.transforms])


def ros_string(m) -> RosString:
    return RosString(data=m.data)


def joint_state(m) -> JointState:
    return JointState(header=header_of(m.header), name=list(m.name), position=list(m.position),
                      velocity=list(m.velocity), effort=list(m.effort))


def bytes_whole(cls, field: str) -> None:
    """Writes `cls`'s `sequence[uint8]` field from a `bytes` value, and reads it as `bytes`,
    in one copy: the same bytes on the wire (a 4-byte length, then the bytes), without
    Cyclone's element-by-element packing of a 2 MB frame or a 5 MB cloud, or unpacking of a
    slab's labels (either takes longer than a frame period)."""
    from cyclonedds.idl._machinery import BytesMachine
    cls.__idl__.populate()
    for machine in (cls.__idl__.v1_machine, cls.__idl__.v2_machine):
        machine.members_machines[field] = BytesMachine()


bytes_whole(VoxelGrid, "data")
bytes_whole(PointCloud2, "data")
bytes_whole(TetLabels, "labels")


# What the peer plays: the type's Cyclone class and how a decoded message becomes one.
PLAYED = {
    "chronotope_msgs/msg/VoxelGrid": (VoxelGrid, voxel_grid),
    "sensor_msgs/msg/PointCloud2": (PointCloud2, point_cloud),
    "octomap_msgs/msg/Octomap": (Octomap, octomap),
    "tf2_msgs/msg/TFMessage": (TFMessage, tf_message),
    "std_msgs/msg/String": (RosString, ros_string),
    "sensor_msgs/msg/JointState": (JointState, joint_state),
}

# Offered latched (reliable, transient local, depth 1), as tf2's static broadcaster,
# octomap_server and robot_state_publisher offer them; the rest as a stream of frames.
LATCHED = ("tf2_msgs/msg/TFMessage", "octomap_msgs/msg/Octomap", "std_msgs/msg/String")

# Sent once, not again when the recording is played in loops.
ONCE = ("tf2_msgs/msg/TFMessage", "std_msgs/msg/String")


def iter_frames(bag: str):
    """(log time ns, ROS topic, sample) of every message of a played type (VoxelGrid frames,
    and the point clouds, OctoMaps and static transforms occupancy nodes read), in log-time
    order, read as they are played (a recording of any length streams in constant memory)."""
    with open(bag, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, m in reader.iter_decoded_messages(log_time_order=True):
            if schema is None or schema.name not in PLAYED:
                continue
            yield message.log_time, channel.topic, PLAYED[schema.name][1](m)


def frame_index(bag: str) -> list[tuple[int, str, str]]:
    """(log time ns, ROS topic, type) of every message of a played type, in log-time order
    (no data)."""
    out = []
    with open(bag, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if schema is not None and schema.name in PLAYED:
                out.append((message.log_time, channel.topic, schema.name))
    return out


def dds_topic(ros_topic: str) -> str:
    return "rt/" + ros_topic.lstrip("/")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bag", required=True, help="rosbag2 MCAP with VoxelGrid topics")
    ap.add_argument("--out", required=True, help="JSON file to write what was received")
    ap.add_argument("--domain", type=int, default=None, help="DDS domain (default ROS_DOMAIN_ID or 0)")
    ap.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1)")
    ap.add_argument("--loops", type=int, default=1,
                    help="play the recording this many times, header stamps shifted by the "
                         "recording's span plus --gap each time (static transforms and the "
                         "robot description sent once)")
    ap.add_argument("--gap", type=float, default=3.5,
                    help="seconds between loops (longer than the mesher's idle timeout: each "
                         "loop is a stream of its own)")
    ap.add_argument("--latency-from", default=None,
                    help="comma-separated input topics whose messages complete a contact's slab "
                         "(default: the VoxelGrid topics); a contact's latency is measured from "
                         "writing the last of these, each the first at or after the contact's "
                         "stamp, to taking its event")
    ap.add_argument("--match-timeout", type=float, default=15.0,
                    help="seconds to wait for the nodes' readers and writers to match")
    ap.add_argument("--timeout", type=float, default=30.0,
                    help="seconds to wait, after the last frame, for the report and labels")
    ap.add_argument("--expect-labels", type=int, default=None,
                    help="wait (within --timeout) for this many TetLabels messages")
    ap.add_argument("--no-labels", action="store_true",
                    help="do not subscribe to /checker/labels (as a user who watches contacts and "
                         "reports; the checker then builds no labels): done when the report came "
                         "and every body closed")
    ap.add_argument("--markers", action="store_true",
                    help="also subscribe to /checker/markers (MarkerArray, ~1 MB each: slow in Python)")
    ap.add_argument("--markers-quiet", type=float, default=3.0,
                    help="with --markers: after the results, take markers until none came for this long")
    ap.add_argument("--expect-markers", type=int, default=None,
                    help="with --markers: wait (within --timeout) for this many MarkerArray messages")
    a = ap.parse_args()
    if a.rate <= 0:
        ap.error("--rate must be > 0")
    if not (1 <= a.loops <= 1000 and 0 <= a.gap <= 600):
        ap.error("--loops in 1..1000, --gap in 0..600 s")
    domain = a.domain if a.domain is not None else int(os.environ.get("ROS_DOMAIN_ID") or 0)
    t_start = time.monotonic()

    frames = frame_index(a.bag)
    if not frames:
        log(f"no VoxelGrid messages in {a.bag}")
        return 2
    in_topics = sorted({(t, ty) for _, t, ty in frames})
    if a.latency_from:
        latency_from = [t for t in a.latency_from.split(",") if t]
        unknown = [t for t in latency_from if t not in {t for t, _ in in_topics}]
        if unknown:
            log(f"--latency-from: {unknown} not in {a.bag}")
            return 2
    else:
        latency_from = sorted({t for t, ty in in_topics if ty == "chronotope_msgs/msg/VoxelGrid"})
    log(f"domain {domain}; {len(frames)} messages on {len(in_topics)} topics from {a.bag}")

    dp = DomainParticipant(domain)
    frame_qos = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                    Policy.Durability.Volatile,
                    Policy.History.KeepLast(16))
    # Static transforms and maps as tf2 and octomap_server offer them (latched); the rest as
    # frames.
    latched_qos = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                      Policy.Durability.TransientLocal,
                      Policy.History.KeepLast(1))
    writers = {t: DataWriter(dp, Topic(dp, dds_topic(t), PLAYED[ty][0]),
                             qos=latched_qos if ty in LATCHED else frame_qos)
               for t, ty in in_topics}
    once = {t for t, ty in in_topics if ty in ONCE}

    def latched_reader(topic: str, cls, depth: int) -> DataReader:
        # The writers offer reliable + transient local; ask for the same (a late joiner
        # still gets their last sample) with a reader history deep enough not to lose any.
        qos = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                  Policy.Durability.TransientLocal,
                  Policy.History.KeepLast(depth))
        return DataReader(dp, Topic(dp, topic, cls), qos=qos)

    readers = {
        "report": latched_reader("rt/checker/report", InterferenceReport, 8),
        "contacts": DataReader(dp, Topic(dp, "rt/checker/contacts", ContactEvent),
                               qos=Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                                       Policy.Durability.Volatile,
                                       Policy.History.KeepLast(1024))),
    }
    if not a.no_labels:
        readers["labels"] = latched_reader("rt/checker/labels", TetLabels, 1024)
    if a.markers:
        readers["markers"] = latched_reader("rt/checker/markers", MarkerArray, 256)

    # Wait for the nodes: every frame writer has a matched reader and every result reader a
    # matched writer (so that no frame and no result is published before the other side
    # listens; the results are latched with depth 1, a late labels reader would see one).
    deadline = time.monotonic() + a.match_timeout
    while True:
        missing = [f"reader of {t}" for t, w in writers.items() if not w.get_matched_subscriptions()]
        missing += [f"writer of {n}" for n, r in readers.items() if not r.get_matched_publications()]
        if not missing:
            break
        if time.monotonic() > deadline:
            log(f"TIMEOUT after {a.match_timeout:.0f} s waiting for discovery/matching in domain "
                f"{domain}: no {', '.join(missing)} (is `chronotope launch` running on this domain?)")
            return 1
        time.sleep(0.05)
    t_matched = time.monotonic()
    log(f"matched after {t_matched - t_start:.2f} s")
    # The launch builds labels and markers only once it has seen a reader of them (at its
    # next tick after matching ours, which may come a little after we saw the match).
    time.sleep(1.0)

    got_report: list = []
    got_labels: list = []
    got_markers: list = []
    got_contacts: list = []
    # Per input topic, the header stamps written (ns, increasing) and when each was written.
    written: dict = {t: ([], []) for t in latency_from}
    playing = [True]

    def slab_complete_at(stamp_ns: int):
        # When the last of the latency topics had its first message at or after `stamp_ns`
        # written (None if one has not).
        last = None
        for stamps, walls in written.values():
            i = bisect.bisect_left(stamps, stamp_ns)
            if i == len(stamps):
                return None
            last = walls[i] if last is None else max(last, walls[i])
        return last

    def take(reader, n: int) -> list:
        # Samples only: a writer that goes away (the launch ending first) leaves
        # "invalid samples" that carry an instance state, not data.
        return [s for s in reader.take(N=n) if not isinstance(s, InvalidSample)]

    def drain() -> None:
        for r in take(readers["report"], 64):
            got_report.append(r)
        if "labels" in readers:
            for l in take(readers["labels"], 256):
                got_labels.append(l)
        for c in take(readers["contacts"], 256):
            taken = time.monotonic()
            got_contacts.append(contact_json(c))
            # Taken while frames were still being played: published while streaming.
            got_contacts[-1]["while_streaming"] = playing[0]
            # From writing the last input of the period that found it (the frame that
            # completes the contact's slab) to taking the event.
            w = slab_complete_at(int(c.header.stamp.sec) * 10**9 + int(c.header.stamp.nanosec))
            got_contacts[-1]["latency_s"] = None if w is None else round(taken - w, 6)
        if "markers" in readers:
            for m in take(readers["markers"], 64):
                got_markers.append(markers_json(m))
                got_markers[-1]["taken_s"] = round(time.monotonic() - t0, 3)

    # Play with the recorded timing (log times), scaled by --rate; each loop later by the
    # recording's span and the gap, in log time and in header stamps alike.
    t0_log = frames[0][0]
    shift_ns = frames[-1][0] - t0_log + int(a.gap * 1e9 * a.rate)
    t0 = time.monotonic()
    published = 0
    loop_last: dict = {}  # loop -> the last stamp written on the latency topics
    for loop in range(a.loops):
        dns = loop * shift_ns
        for log_ns, topic, msg in iter_frames(a.bag):
            if loop > 0 and topic in once:
                continue
            if dns and hasattr(msg, "header"):
                ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec + dns
                msg.header.stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
            due = t0 + (log_ns + dns - t0_log) / 1e9 / a.rate
            while True:
                now = time.monotonic()
                if now >= due:
                    break
                time.sleep(min(due - now, 0.005))
                drain()
            writers[topic].write(msg)
            published += 1
            if topic in written and hasattr(msg, "header"):
                stamps, walls = written[topic]
                stamps.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
                walls.append(time.monotonic())
                loop_last[loop] = max(loop_last.get(loop, 0), stamps[-1])
            drain()
    drain()
    playing[0] = False
    t_played = time.monotonic()
    log(f"published {published} messages ({a.loops} loop(s)) in {t_played - t0:.2f} s")

    def complete() -> bool:
        if not got_report:
            return False
        want = {(p.body_a, p.body_b) for p in got_report[-1].pairs}
        want |= {(b, a_) for a_, b in want}
        have = {(l.body_id, l.other_id) for l in got_labels} if "labels" in readers else want
        if a.expect_markers is not None and len(got_markers) < a.expect_markers:
            return False
        if a.expect_labels is not None and len(got_labels) < a.expect_labels:
            return False
        return want <= have

    deadline = time.monotonic() + a.timeout
    while not complete() and time.monotonic() < deadline:
        drain()
        time.sleep(0.02)
    ok = complete()
    t_done = time.monotonic()
    if ok:
        # The streams ended: the answer is final once the checker has closed every body (the
        # mesher closes a stream after its idle timeout, which can take a while on a loaded
        # machine). Wait for that within the same deadline.
        def all_closed() -> bool:
            return bool(got_report) and all(b.closed for b in got_report[-1].bodies)
        while not all_closed() and time.monotonic() < deadline:
            drain()
            time.sleep(0.02)
    if ok:
        # Contact events and reports travel on their own topics, and the report is
        # republished as answers change: take what is still on its way, until nothing new
        # came for a second.
        quiet = time.monotonic()
        while time.monotonic() - quiet < 1.0:
            n = (len(got_contacts), len(got_report))
            drain()
            if (len(got_contacts), len(got_report)) != n:
                quiet = time.monotonic()
            time.sleep(0.02)
    if ok and "markers" in readers and a.expect_markers is None:
        # Markers precede the report; take what is still queued.
        quiet = time.monotonic()
        while time.monotonic() - quiet < a.markers_quiet:
            n = len(got_markers)
            drain()
            if len(got_markers) != n:
                quiet = time.monotonic()
            time.sleep(0.02)

    # A contact event stamped at a loop's last frame closes with the stream: it comes after
    # the mesher's idle timeout, not with a frame.
    lasts = sorted(loop_last.values())
    for c in got_contacts:
        st = c["header"]["stamp"]
        ns = st["sec"] * 10**9 + st["nanosec"]
        i = bisect.bisect_left(lasts, ns)
        c["at_stream_end"] = i < len(lasts) and ns == lasts[i]

    out = {
        "domain": domain,
        "float_encoding": "hex of IEEE-754 binary64 bits, big-endian",
        "frames_published": published,
        "latency_from": latency_from,
        "timing_s": {
            "matched": round(t_matched - t_start, 3),
            "played": round(t_played - t0, 3),
            "results_after_last_frame": round(t_done - t_played, 3),
        },
        "reports": [report_json(r) for r in got_report],
        "report": report_json(got_report[-1]) if got_report else None,
        "labels": [labels_json(l) for l in got_labels],
        "contacts": got_contacts,
    }
    if "markers" in readers:
        out["markers"] = got_markers
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    if not ok:
        have = sorted({(l.body_id, l.other_id) for l in got_labels})
        log(f"TIMEOUT after {a.timeout:.0f} s waiting for the results: "
            f"{len(got_report)} report(s), labels for {have}"
            + (f", {len(got_markers)} marker arrays" if "markers" in readers else "")
            + f"; wrote what arrived to {a.out}")
        return 1
    log(f"got {len(got_report)} report(s), {len(got_labels)} labels, {len(got_contacts)} contact events"
        + (f", {len(got_markers)} marker arrays" if "markers" in readers else "")
        + f" {t_done - t_played:.2f} s after the last frame; wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
