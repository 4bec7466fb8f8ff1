#!/usr/bin/env python3
"""Rewrites the VoxelGrid topics of an MCAP bag with message definitions laid out by other
writers, so that the suite can be checked to read them by meaning.

Usage:
    write_foreign_defs.py SRC.mcap MSG_DIR OUT_DIR

MSG_DIR is the interface package's msg/ directory (our VoxelGrid.msg). Writes into OUT_DIR:

- rosbags-mcap/ and rosbags-sqlite/: rosbag2 directories written by PyPI `rosbags`, the
  VoxelGrid type registered from our .msg text in its type store; rosbags then writes the
  definition it generates itself (constants first, `pkg/msg/Type` names).
- mcap-ros2.mcap: written by PyPI `mcap-ros2-support`, which serialises each message itself
  from the decoded values, under a definition whose dependency sections come in another
  order and carry no comments.
- handmade.mcap: the raw messages under a definition laid out by hand (constants last,
  spacing and comments changed, an unused dependency section added).

Every message keeps its topic and log time.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mcap.reader import make_reader
from mcap.writer import Writer as McapWriter
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TYPE = "chronotope_msgs/msg/VoxelGrid"
SEP = "=" * 80

POINT = "float64 x\nfloat64 y\nfloat64 z\n"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
TIME = "int32 sec\nuint32 nanosec\n"


def messages(src: Path):
    """(topic, log_time, raw CDR bytes, schema text) of every VoxelGrid message."""
    with open(src, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if schema is not None and schema.name == TYPE:
                yield channel.topic, message.log_time, message.data, schema.data.decode()


def with_rosbags(src: Path, msg_text: str, out: Path, plugin: StoragePlugin) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(msg_text, TYPE))
    conns = {}
    with Writer(out, version=9, storage_plugin=plugin) as w:
        for topic, t, data, _ in messages(src):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, TYPE, typestore=store)
            w.write(conns[topic], t, data)


def reordered_definition() -> str:
    """Our type with the dependency sections reversed and no comments."""
    main = (
        "std_msgs/Header header\ngeometry_msgs/Point origin\nfloat64 resolution\n"
        "uint32 size_x\nuint32 size_y\nuint32 size_z\nuint8 ENCODING_BITS=0\n"
        "uint8 ENCODING_PERCENT=1\nuint8 encoding\nuint8[] data\n"
    )
    return (
        f"{main}{SEP}\nMSG: builtin_interfaces/Time\n{TIME}{SEP}\nMSG: std_msgs/Header\n"
        f"{HEADER}{SEP}\nMSG: geometry_msgs/Point\n{POINT}"
    )


def handmade_definition() -> str:
    """Our type laid out by hand: constants last, odd spacing, comments, an unused section."""
    main = (
        "# a frame\n\nstd_msgs/Header   header   # stamp\n"
        "geometry_msgs/msg/Point\torigin\n"
        "float64 resolution  0.05   # a default value never reaches the wire\n"
        "uint32 size_x\nuint32 size_y\nuint32 size_z\nuint8 encoding\nuint8[] data\n"
        "uint8 ENCODING_PERCENT = 1\nuint8 ENCODING_BITS=0\n"
    )
    return (
        f"{main}\n{SEP}\nMSG: geometry_msgs/msg/Point\n{POINT}\n{SEP}\nMSG: nobody_uses/This\n"
        f"int8 x\n\n{SEP}\nMSG: std_msgs/msg/Header\n{HEADER}\n{SEP}\n"
        f"MSG: builtin_interfaces/msg/Time\n{TIME}"
    )


def with_mcap_ros2(src: Path, out: Path) -> None:
    decoders = DecoderFactory()
    with open(out, "wb") as f:
        w = Ros2Writer(f)
        schema = w.register_msgdef(TYPE, reordered_definition())
        with open(src, "rb") as s:
            reader = make_reader(s, decoder_factories=[decoders])
            for sch, channel, message, decoded in reader.iter_decoded_messages():
                if sch is None or sch.name != TYPE:
                    continue
                w.write_message(channel.topic, schema, decoded, log_time=message.log_time,
                                publish_time=message.log_time)
        w.finish()


def handmade(src: Path, out: Path) -> None:
    with open(out, "wb") as f:
        w = McapWriter(f)
        w.start(profile="ros2", library="handmade")
        sid = w.register_schema(TYPE, "ros2msg", handmade_definition().encode())
        chans = {}
        for topic, t, data, _ in messages(src):
            if topic not in chans:
                chans[topic] = w.register_channel(topic, "cdr", sid)
            w.add_message(chans[topic], t, data, t)
        w.finish()


def main() -> int:
    src, msg_dir, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
    out.mkdir(parents=True, exist_ok=True)
    msg_text = (msg_dir / "VoxelGrid.msg").read_text()
    with_rosbags(src, msg_text, out / "rosbags-mcap", StoragePlugin.MCAP)
    with_rosbags(src, msg_text, out / "rosbags-sqlite", StoragePlugin.SQLITE3)
    with_mcap_ros2(src, out / "mcap-ros2.mcap")
    handmade(src, out / "handmade.mcap")
    return 0


if __name__ == "__main__":
    sys.exit(main())
