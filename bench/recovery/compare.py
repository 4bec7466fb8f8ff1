#!/usr/bin/env python3
"""Messages recovered from damaged bags: chronotope's reader against the Python `mcap` readers.

Builds damaged variants of the bundled bags (bags/*.mcap) in three forms (small zstd chunks,
small lz4 chunks, unchunked), with byte flips, truncations, zeroed ranges, a duplicated chunk,
a corrupt first chunk and a bad record length, then counts on each:

- ours: `target/debug/examples/bag_count` (build it first: `cargo build --example bag_count`);
- python indexed: `mcap.reader.make_reader(f).iter_messages()` (uses the summary and chunk
  indexes; messages yielded before an exception count);
- python linear: `mcap.stream_reader.StreamReader` (messages before an exception count).

A message counts as recovered if it is one of the original bag's (topic, log time, data); a
delivered message that is not in the original is "invented", a second delivery a "duplicate".

    python3 bench/recovery/compare.py [--seed 17] [--per-kind 4] [--out /tmp/recovery]
"""

import argparse
import glob
import io
import json
import os
import random
import subprocess
import sys
from collections import Counter

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap.records import Message, Channel, Schema, Chunk
from mcap.writer import Writer, CompressionType

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OURS = os.path.join(ROOT, "target", "debug", "examples", "bag_count")


def fnv1a(data):
    h = 0xCBF29CE484222325
    for b in data:
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return "%016x" % h


def rewrite(src, compression, chunked):
    """The bag `src` rewritten with small chunks (or none)."""
    out = io.BytesIO()
    reader = make_reader(io.BytesIO(src))
    w = Writer(out, chunk_size=2048, compression=compression, use_chunking=chunked)
    w.start(profile="ros2", library="compare.py")
    schemas, channels = {}, {}
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        if schema is not None and schema.id not in schemas:
            schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
        if channel.id not in channels:
            channels[channel.id] = w.register_channel(
                channel.topic, channel.message_encoding,
                schemas.get(channel.schema_id, 0), channel.metadata)
        w.add_message(channels[channel.id], message.log_time, message.data,
                      message.publish_time, message.sequence)
    w.finish()
    return out.getvalue()


def records(data):
    """(offset, opcode, body length) of the top-level records of an intact file."""
    out, at = [], 8
    while at + 9 <= len(data) - 8:
        op = data[at]
        n = int.from_bytes(data[at + 1:at + 9], "little")
        out.append((at, op, n))
        if op == 0x02:
            break
        at += 9 + n
    return out


def damage(data, kind, rng):
    b = bytearray(data)
    recs = records(data)
    chunks = [r for r in recs if r[1] == 0x06]
    msgs = [r for r in recs if r[1] == 0x05]
    data_recs = [r for r in recs if r[1] in (0x03, 0x04, 0x05, 0x06)]
    if kind == "flip":
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(8, len(b))
            b[i] ^= rng.randrange(1, 256)
    elif kind == "truncate":
        b = b[:rng.randrange(16, len(b))]
    elif kind == "zero":
        n = rng.randint(64, 4096)
        i = rng.randrange(8, max(9, len(b) - n))
        b[i:i + n] = bytes(min(n, len(b) - i))
    elif kind == "duplicate_chunk":
        unit = rng.choice(chunks or msgs)
        s, e = unit[0], unit[0] + 9 + unit[2]
        b = b[:e] + b[s:e] + b[e:]
    elif kind == "corrupt_first_chunk":
        unit = (chunks or msgs)[0]
        s, e = unit[0] + 9, unit[0] + 9 + unit[2]
        for _ in range(4):
            i = rng.randrange(s + (e - s) // 2, e)
            b[i] ^= 0x5A
    elif kind == "bad_length":
        unit = rng.choice(data_recs)
        b[unit[0] + 1:unit[0] + 9] = rng.randrange(1 << 20, 1 << 40).to_bytes(8, "little")
    return bytes(b)


def python_indexed(data):
    got = []
    try:
        for schema, channel, message in make_reader(io.BytesIO(data)).iter_messages(
                log_time_order=False):
            got.append((channel.topic, message.log_time, fnv1a(message.data)))
    except Exception:  # noqa: BLE001 - any failure ends the reading
        pass
    return got


def python_linear(data):
    got, channels = [], {}
    try:
        for record in StreamReader(io.BytesIO(data), skip_magic=False).records:
            if isinstance(record, Channel):
                channels[record.id] = record.topic
            elif isinstance(record, Message) and record.channel_id in channels:
                got.append((channels[record.channel_id], record.log_time, fnv1a(record.data)))
    except Exception:  # noqa: BLE001
        pass
    return got


def ours(path):
    out = subprocess.run([OURS, path], capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        return None, out.stderr[-300:]
    doc = json.loads(out.stdout)
    return [tuple(m) for m in doc["messages"]], doc


def score(got, truth):
    t = Counter(truth)
    g = Counter(got)
    recovered = sum(min(n, t[k]) for k, n in g.items())
    invented = sum(n for k, n in g.items() if k not in t)
    duplicates = sum(n - t[k] for k, n in g.items() if k in t and n > t[k])
    return recovered, invented, duplicates


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--per-kind", type=int, default=4)
    ap.add_argument("--out", default="/tmp/chronotope-recovery")
    args = ap.parse_args()
    if not os.path.exists(OURS):
        sys.exit("build it first: cargo build --example bag_count")
    os.makedirs(args.out, exist_ok=True)
    rng = random.Random(args.seed)
    kinds = ["flip", "truncate", "zero", "duplicate_chunk", "corrupt_first_chunk", "bad_length"]
    forms = {"zstd": (CompressionType.ZSTD, True), "lz4": (CompressionType.LZ4, True),
             "unchunked": (CompressionType.NONE, False)}
    totals = Counter()
    rows = []
    for bag in sorted(glob.glob(os.path.join(ROOT, "bags", "*.mcap"))):
        original = open(bag, "rb").read()
        for form, (compression, chunked) in forms.items():
            clean = rewrite(original, compression, chunked)
            truth = python_indexed(clean)
            for kind in kinds:
                for i in range(args.per_kind):
                    damaged = damage(clean, kind, rng)
                    name = "%s-%s-%s-%d.mcap" % (os.path.basename(bag)[:-5], form, kind, i)
                    path = os.path.join(args.out, name)
                    open(path, "wb").write(damaged)
                    o, doc = ours(path)
                    if o is None:
                        totals["ours_crashed"] += 1
                        print("CRASH", name, doc)
                        o = []
                    r = {"bag": name, "truth": len(truth)}
                    for who, got in (("ours", o), ("py_indexed", python_indexed(damaged)),
                                     ("py_linear", python_linear(damaged))):
                        rec, inv, dup = score(got, truth)
                        r[who] = rec
                        r[who + "_invented"] = inv
                        totals[who] += rec
                        totals[who + "_invented"] += inv
                        totals[who + "_duplicates"] += dup
                    totals["truth"] += len(truth)
                    totals["bags"] += 1
                    if r["ours"] < max(r["py_indexed"], r["py_linear"]):
                        totals["ours_behind"] += 1
                        print("BEHIND", json.dumps(r))
                    rows.append(r)
    json.dump(rows, open(os.path.join(args.out, "results.json"), "w"), indent=1)
    by_form = Counter()
    for r in rows:
        form = r["bag"].rsplit("-", 3)[0].rsplit("-", 1)[-1] if False else next(
            f for f in forms if "-%s-" % f in r["bag"])
        for who in ("ours", "py_indexed", "py_linear"):
            by_form[form + " " + who] += r[who]
            by_form[form + " " + who + "_invented"] += r[who + "_invented"]
        by_form[form + " truth"] += r["truth"]
    print(json.dumps(by_form, indent=1, sort_keys=True))
    print(json.dumps(totals, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()
