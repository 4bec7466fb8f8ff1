#!/usr/bin/env python3
"""Rewrites an MCAP bag as a rosbag2 directory, as `ros2 bag record` would, with PyPI
`rosbags`' rosbag2 writer: MCAP or SQLite storage, split into several files, compressed or not.

Usage:
    write_rosbag2.py SRC.mcap OUT_DIR --storage mcap|sqlite3 [--splits N]
                     [--compression none|file|message] [--version 8|9] [--humble]

Every message of SRC (read with the `mcap` package) is written with its log time and its
serialised bytes unchanged, on a connection with the schema text SRC holds. With --splits N
the messages are cut into N consecutive runs, each written by its own rosbags Writer; the
storage files are then gathered into OUT_DIR as `<name>_<k>.<ext>` with one metadata.yaml
listing them in order, as rosbag2 does for a split recording. --humble makes what Humble
records: metadata version 5, and (SQLite) no message_definitions table and no
type_description_hash column.
"""

from __future__ import annotations

import argparse
import shutil
import sqlite3
import sys
from pathlib import Path

from mcap.reader import make_reader
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
from ruamel.yaml import YAML


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("out")
    ap.add_argument("--storage", choices=["mcap", "sqlite3"], required=True)
    ap.add_argument("--splits", type=int, default=1)
    ap.add_argument("--compression", choices=["none", "file", "message"], default="none")
    ap.add_argument("--version", type=int, choices=[8, 9], default=9)
    ap.add_argument("--humble", action="store_true")
    a = ap.parse_args()

    with open(a.src, "rb") as f:
        rows = []
        topics = {}
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.topic not in topics:
                topics[channel.topic] = (schema.name, schema.data.decode())
            rows.append((channel.topic, message.log_time, bytes(message.data)))
    out = Path(a.out)
    name = out.name
    out.mkdir(parents=True)
    n = max(1, a.splits)
    per = -(-len(rows) // n)
    parts = [rows[k * per : (k + 1) * per] for k in range(n)]
    metas = []
    for k, part in enumerate(parts):
        tmp = out.parent / f"_{name}_part{k}"
        plugin = StoragePlugin.MCAP if a.storage == "mcap" else StoragePlugin.SQLITE3
        w = Writer(tmp, version=a.version, storage_plugin=plugin)
        if a.compression != "none":
            w.set_compression(
                CompressionMode[a.compression.upper()], CompressionFormat.ZSTD
            )
        w.open()
        conns = {}
        # Every topic in every split file, as rosbag2 does.
        for topic, (msgtype, text) in topics.items():
            conns[topic] = w.add_connection(topic, msgtype, msgdef=text, rihs01="RIHS01_" + "0" * 64)
        for topic, t, data in part:
            w.write(conns[topic], t, data)
        w.close()
        yaml = YAML(typ="safe")
        meta = yaml.load((tmp / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        [fname] = meta["relative_file_paths"]
        ext = fname.split(".", 1)[1]
        dst = f"{name}_{k}.{ext}"
        src_file = tmp / fname
        if a.humble and a.storage == "sqlite3":
            if a.compression == "file":
                raise SystemExit("--humble with file compression is not made by this script")
            humble_db3(src_file)
        shutil.move(str(src_file), str(out / dst))
        shutil.rmtree(tmp)
        meta["relative_file_paths"] = [dst]
        meta["files"][0]["path"] = dst
        metas.append(meta)
    merged = dict(metas[0])
    merged["relative_file_paths"] = [m["relative_file_paths"][0] for m in metas]
    merged["files"] = [m["files"][0] for m in metas]
    starts = [m["starting_time"]["nanoseconds_since_epoch"] for m in metas if m["message_count"]]
    ends = [
        m["starting_time"]["nanoseconds_since_epoch"] + m["duration"]["nanoseconds"]
        for m in metas
        if m["message_count"]
    ]
    merged["starting_time"] = {"nanoseconds_since_epoch": min(starts)}
    merged["duration"] = {"nanoseconds": max(ends) - min(starts)}
    merged["message_count"] = sum(m["message_count"] for m in metas)
    counts: dict[str, int] = {}
    for m in metas:
        for t in m["topics_with_message_count"]:
            counts[t["topic_metadata"]["name"]] = counts.get(t["topic_metadata"]["name"], 0) + t[
                "message_count"
            ]
    for t in merged["topics_with_message_count"]:
        t["message_count"] = counts[t["topic_metadata"]["name"]]
    if a.humble:
        merged["version"] = 5
        for key in ("custom_data", "ros_distro"):
            merged.pop(key, None)
        for t in merged["topics_with_message_count"]:
            t["topic_metadata"].pop("type_description_hash", None)
            qos = t["topic_metadata"].get("offered_qos_profiles")
            if not isinstance(qos, str):
                t["topic_metadata"]["offered_qos_profiles"] = ""
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    with open(out / "metadata.yaml", "w") as f:
        yaml.dump({"rosbag2_bagfile_information": merged}, f)
    print(f"{out}: {len(rows)} messages in {n} file(s)")
    return 0


def humble_db3(path: Path) -> None:
    """Makes a rosbags SQLite file look like Humble's: no message_definitions, no hash."""
    db = sqlite3.connect(path)
    db.executescript(
        """
        DROP TABLE IF EXISTS message_definitions;
        CREATE TABLE topics_h(
          id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
          serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
        INSERT INTO topics_h SELECT id, name, type, serialization_format, offered_qos_profiles
          FROM topics;
        DROP TABLE topics;
        ALTER TABLE topics_h RENAME TO topics;
        UPDATE schema SET schema_version = 3;
        """
    )
    db.commit()
    db.close()


if __name__ == "__main__":
    sys.exit(main())
