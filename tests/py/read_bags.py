#!/usr/bin/env python3
"""Reads rosbag2 MCAP files with two independent Python readers and decodes every message.

Usage:
    python3 tests/py/read_bags.py BAG.mcap [BAG.mcap ...]

Needs rosbags and mcap-ros2-support (`python3 tests/py/setup_env.py` installs them under target/py) (checked with rosbags 0.11.9,
mcap-ros2-support 0.6.0, mcap 1.6.0). A bag to try it on:

    CHRONOTOPE_SAMPLE_BAG=/tmp/sample.mcap cargo test --test bag_roundtrip sample_bag
    python3 tests/py/read_bags.py /tmp/sample.mcap

For each bag, every message is decoded by
  - rosbags: its MCAP storage reader, with the message types registered in a fresh typestore
    from the `ros2msg` definitions embedded in the bag (nothing comes from a ROS install);
  - mcap_ros2 (mcap-ros2-support): `read_ros2_messages`, which parses the same definitions
    with its own code.
Both must decode every message, agree on every message's topic, log time and fields, and every
chronotope_msgs/msg/VoxelGrid must have the data length its sizes and encoding call for
(docs/formats.md#input-message). Exit status 0 if all bags pass, 1 otherwise (2 for bad usage).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

VOXEL_GRID = "chronotope_msgs/msg/VoxelGrid"
ENCODING_BITS = 0
ENCODING_PERCENT = 1


def plain(value):
    """Turns a decoded message (either reader's objects) into comparable Python values.

    Byte strings and numeric arrays (numpy or lists) all become lists of numbers, and NaN
    becomes the string "NaN" (NaN != NaN would fail every comparison of a report with no
    contact)."""
    if isinstance(value, float):
        return "NaN" if math.isnan(value) else value
    if isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, (bytes, bytearray, memoryview)):
        return list(bytes(value))
    if hasattr(value, "tolist"):  # numpy arrays and scalars (rosbags)
        return plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    fields = getattr(value, "__slots__", None) or getattr(value, "__dataclass_fields__", None)
    if fields is None:
        fields = [k for k in vars(value) if not k.startswith("_")]
    # ROS 2 field names are lower case and constants upper case; only fields are compared.
    return {
        name: plain(getattr(value, name))
        for name in fields
        if not name.startswith("_") and not name.isupper()
    }


def short(value, limit: int = 400) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + f"... ({len(text)} characters)"


def check_voxel_grid(fields: dict, where: str) -> None:
    voxels = fields["size_x"] * fields["size_y"] * fields["size_z"]
    encoding = fields["encoding"]
    if encoding == ENCODING_BITS:
        expected = (voxels + 7) // 8
    elif encoding == ENCODING_PERCENT:
        expected = voxels
    else:
        raise ValueError(f"{where}: unknown encoding {encoding}")
    if len(fields["data"]) != expected:
        raise ValueError(
            f"{where}: data has {len(fields['data'])} bytes, sizes and encoding call for {expected}"
        )


def read_with_rosbags(path: Path) -> list[tuple[str, int, dict]]:
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    reader = McapReader(path)
    reader.open()
    try:
        typestore = get_typestore(Stores.EMPTY)
        types = {}
        for connection in reader.connections:
            if connection.ext.serialization_format != "cdr":
                raise ValueError(f"{connection.topic}: message encoding is not cdr")
            types.update(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        typestore.register(types)
        out = []
        for connection, timestamp, raw in reader.messages(reader.connections):
            message = typestore.deserialize_cdr(raw, connection.msgtype)
            out.append((connection.topic, timestamp, connection.msgtype, plain(message)))
        return sorted(out, key=lambda m: (m[1], m[0], repr(m[3])))
    finally:
        reader.close()


def read_with_mcap_ros2(path: Path) -> list[tuple[str, int, dict]]:
    from mcap_ros2.reader import read_ros2_messages

    out = []
    for message in read_ros2_messages(str(path), log_time_order=False):
        out.append(
            (message.channel.topic, message.log_time_ns, message.schema.name, plain(message.ros_msg))
        )
    return sorted(out, key=lambda m: (m[1], m[0], repr(m[3])))


def check_bag(path: Path) -> bool:
    try:
        by_rosbags = read_with_rosbags(path)
        by_mcap_ros2 = read_with_mcap_ros2(path)
    except Exception as err:  # any failure of either reader fails the bag
        print(f"FAIL {path}: {type(err).__name__}: {err}")
        return False
    if len(by_rosbags) != len(by_mcap_ros2):
        print(f"FAIL {path}: rosbags read {len(by_rosbags)} messages, mcap_ros2 {len(by_mcap_ros2)}")
        return False
    voxel_grids = 0
    for (topic, t, typ, fields), (topic2, t2, typ2, fields2) in zip(by_rosbags, by_mcap_ros2):
        where = f"{path}: {topic} at {t} ns"
        if (topic, t, typ) != (topic2, t2, typ2):
            print(f"FAIL {where}: mcap_ros2 has {topic2} at {t2} ns of type {typ2} instead")
            return False
        if fields != fields2:
            print(f"FAIL {where}: the readers disagree:\n  rosbags:    {short(fields)}\n  mcap_ros2: {short(fields2)}")
            return False
        if typ == VOXEL_GRID:
            try:
                check_voxel_grid(fields, where)
            except (KeyError, ValueError) as err:
                print(f"FAIL {err}")
                return False
            voxel_grids += 1
    topics = sorted({m[0] for m in by_rosbags})
    print(
        f"ok   {path}: {len(by_rosbags)} messages ({voxel_grids} VoxelGrid) on {len(topics)} topics "
        f"{', '.join(topics)}; rosbags and mcap_ros2 agree"
    )
    return True


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 2
    results = [check_bag(Path(arg)) for arg in argv[1:]]
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
