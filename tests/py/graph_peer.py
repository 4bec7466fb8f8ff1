#!/usr/bin/env python3
"""What `ros2 node info` would say about the nodes on a DDS domain, read the way ROS 2's
middleware reads it, by a Cyclone DDS participant (PyPI `cyclonedds`), no ROS.

It joins the domain (late: whatever is there already), reads for --listen seconds

- `ros_discovery_info` (rmw_dds_common/ParticipantEntitiesInfo: per participant GID, its
  nodes with their reader and writer GIDs), reliable, transient local, keep all, as rmw
  reads it; like rmw_dds_common's graph cache, the last sample of a participant GID
  replaces the ones before it;
- the DDS builtin topics DCPSPublication and DCPSSubscription: every endpoint's GUID, topic,
  type and QoS;

then writes, per node, the ROS topics (`rt/` stripped), types and QoS of its writers and
readers, and the endpoints on ROS topics that no node lists, as JSON.  Used by
tests/it/graph.rs.

    python3 tests/py/graph_peer.py --out OUT.json [--domain N] [--gid-size 16] [--listen S]

--gid-size: bytes of rmw_dds_common/Gid (16 from ROS 2 Iron on, 24 on Humble): what the
publisher writes.  Domain: --domain, else ROS_DOMAIN_ID, else 0.  Discovery is loopback
only (CYCLONEDDS_URI set here unless the environment sets it).

Exit status: 0 when the JSON is written; 2 on bad use; 3 without cyclonedds.
"""

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass

# Loopback-only discovery, as tests/py/cyclone_peer.py (which explains it).
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
</Domain></CycloneDDS>"""

if "CYCLONEDDS_URI" not in os.environ:
    os.environ["CYCLONEDDS_URI"] = CYCLONE_XML

try:
    from cyclonedds.builtin import (BuiltinDataReader, BuiltinTopicDcpsPublication,
                                    BuiltinTopicDcpsSubscription)
    from cyclonedds.core import (InstanceState, Policy, Qos, ReadCondition, SampleState,
                                 ViewState)
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import array, sequence, uint8
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
except ImportError as e:  # pragma: no cover
    print(f"graph_peer: cannot import cyclonedds ({e}); pip install -r tests/py/requirements.txt",
          file=sys.stderr)
    sys.exit(3)


def discovery_types(gid_size):
    """rmw_dds_common's messages, field for field, with a GID of `gid_size` bytes."""

    @dataclass
    class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
        data: array[uint8, gid_size]

    @dataclass
    class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
        node_namespace: str
        node_name: str
        reader_gid_seq: sequence[Gid]
        writer_gid_seq: sequence[Gid]

    @dataclass
    class ParticipantEntitiesInfo(IdlStruct,
                                  typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
        gid: Gid
        node_entities_info_seq: sequence[NodeEntitiesInfo]

    return ParticipantEntitiesInfo


def gid_hex(gid):
    """The first 16 bytes (the GUID) as hex; the rest is padding."""
    return bytes(gid.data[:16]).hex()


def fqn(node):
    ns = node.node_namespace
    return f"/{node.node_name}" if ns in ("", "/") else f"{ns}/{node.node_name}"


def ros_type(dds_type):
    """`pkg::msg::dds_::Type_` as `pkg/msg/Type` (other names as they are)."""
    if "::dds_::" in dds_type and dds_type.endswith("_"):
        pkg, name = dds_type.rsplit("::dds_::", 1)
        return pkg.replace("::", "/") + "/" + name[:-1]
    return dds_type


def endpoint(e):
    qos = e.qos
    rel = qos[Policy.Reliability] if qos is not None else None
    dur = qos[Policy.Durability] if qos is not None else None
    return {
        "dds_topic": e.topic_name,
        "topic": e.topic_name[2:] if e.topic_name.startswith("rt/") else None,
        "type": ros_type(e.type_name),
        # DDS defaults when not sent: a writer is reliable, a reader best effort; volatile.
        "reliable": isinstance(rel, Policy.Reliability.Reliable) if rel is not None else None,
        "transient_local": dur == Policy.Durability.TransientLocal if dur is not None else None,
        "participant": e.participant_key.bytes.hex(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID") or 0))
    ap.add_argument("--gid-size", type=int, default=16)
    ap.add_argument("--listen", type=float, default=5.0)
    a = ap.parse_args()
    if a.gid_size not in (16, 24) or not a.listen > 0:
        print("graph_peer: --gid-size is 16 or 24, --listen positive", file=sys.stderr)
        return 2

    dp = DomainParticipant(a.domain)
    info_type = discovery_types(a.gid_size)
    topic = Topic(dp, "ros_discovery_info", info_type)
    qos = Qos(Policy.Reliability.Reliable(max_blocking_time=0),
              Policy.Durability.TransientLocal, Policy.History.KeepAll)
    infos = DataReader(dp, topic, qos=qos)
    pubs = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    subs = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)

    last = {}  # participant GID -> the last info (the graph cache's view)
    history = {}  # participant GID -> every info received: when, from which writer, how big
    start = time.monotonic()
    while time.monotonic() - start < a.listen:
        for s in infos.take(N=256):
            if not hasattr(s, "gid"):
                continue  # an instance state change, no data
            g = gid_hex(s.gid)
            last[g] = s
            history.setdefault(g, []).append({
                "t": round(time.monotonic() - start, 3),
                "writer": s.sample_info.publication_handle,
                "nodes": len(s.node_entities_info_seq),
                "gids": sum(len(n.reader_gid_seq) + len(n.writer_gid_seq)
                            for n in s.node_entities_info_seq),
            })
        time.sleep(0.05)

    alive = SampleState.Any | ViewState.Any | InstanceState.Alive
    writers = {e.key.bytes.hex(): endpoint(e)
               for e in pubs.read(N=100000, condition=ReadCondition(pubs, alive))}
    readers = {e.key.bytes.hex(): endpoint(e)
               for e in subs.read(N=100000, condition=ReadCondition(subs, alive))}

    nodes = {}
    claimed = set()
    for g, info in last.items():
        for n in info.node_entities_info_seq:
            entry = nodes.setdefault(fqn(n), {
                "listed_by": [], "publishers": [], "subscribers": [],
                "unresolved_writers": 0, "unresolved_readers": 0, "other": [],
            })
            entry["listed_by"].append(g)
            for kind, seq, known in (("publishers", n.writer_gid_seq, writers),
                                     ("subscribers", n.reader_gid_seq, readers)):
                for gid in seq:
                    claimed.add(gid_hex(gid))
                    e = known.get(gid_hex(gid))
                    if e is None:
                        entry["unresolved_" + ("writers" if kind == "publishers" else "readers")] += 1
                    elif e["topic"] is None:
                        entry["other"].append(e["dds_topic"])  # services, ros_discovery_info
                    else:
                        entry[kind].append(e)

    out = {
        "gid_size": a.gid_size,
        "listened_s": round(time.monotonic() - start, 3),
        "participants": {g: {"samples": len(h), "writers": len({x["writer"] for x in h}),
                             "history": h,
                             "nodes": sorted(fqn(n) for n in last[g].node_entities_info_seq)}
                         for g, h in history.items()},
        "nodes": nodes,
        "endpoints": {"writers": len(writers), "readers": len(readers)},
        # Endpoints on ROS topics that no node lists (`ros2 topic info -v` cannot name a node).
        "unclaimed": sorted(f"{kind} {e['topic']} ({e['type']})"
                            for kind, known in (("writer", writers), ("reader", readers))
                            for k, e in known.items()
                            if e["topic"] is not None and k not in claimed),
    }
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1, sort_keys=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
