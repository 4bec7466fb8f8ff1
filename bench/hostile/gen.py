"""Case generation for the hostile-input campaign (bench/hostile/campaign.py).

A case is a dict: id, category, kind, dir (its work directory, where its inputs are written
and where the binary runs), runs [(name, argv)] with "BIN" for the binary, expect (what the
oracles know about the input), and optionally setup (things made just before a run, such as
a FIFO), out_checks (checks of an output bag) and timeout.
"""

import io
import json
import math
import os
import struct
import zlib
from pathlib import Path

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap.records import Message as McapMessage
from mcap.writer import CompressionType, Writer

import cdr

VOXEL = "chronotope_msgs/msg/VoxelGrid"
POSE = "geometry_msgs/msg/PoseStamped"
WRENCH = "geometry_msgs/msg/WrenchStamped"
T0 = 1_700_000_000_000_000_000
PERIOD = 100_000_000  # 0.1 s

# ----------------------------------------------------------------------------------------
# Bags: reading, writing in each form, damaging, and what Python's reader recovers.
# ----------------------------------------------------------------------------------------


def read_bag(path):
    """(profile, schemas {id: (name, encoding, data)}, channels {id: (topic, enc, schema_id,
    metadata)}, messages [(channel_id, log_time, publish_time, sequence, data)])."""
    with open(path, "rb") as f:
        r = make_reader(f)
        profile = r.get_header().profile
        s = r.get_summary()
        schemas = {k: (v.name, v.encoding, v.data) for k, v in s.schemas.items()}
        channels = {k: (v.topic, v.message_encoding, v.schema_id, dict(v.metadata))
                    for k, v in s.channels.items()}
        msgs = [(c.id, m.log_time, m.publish_time, m.sequence, m.data)
                for _, c, m in r.iter_messages(log_time_order=False)]
    return profile, schemas, channels, msgs


FORMS = {
    # form: Writer keyword arguments
    "zstd": dict(compression=CompressionType.ZSTD),
    "chunked": dict(compression=CompressionType.NONE, chunk_size=3000),
    "lz4": dict(compression=CompressionType.LZ4, chunk_size=3000),
    "unchunked": dict(compression=CompressionType.NONE, use_chunking=False),
}


def write_bag(path, bag, form="zstd"):
    profile, schemas, channels, msgs = bag
    with open(path, "wb") as f:
        w = Writer(f, **FORMS[form])
        w.start(profile=profile, library="hostile-campaign")
        sid = {}
        for k, (name, enc, data) in sorted(schemas.items()):
            sid[k] = w.register_schema(name, enc, data)
        cid = {}
        for k, (topic, enc, schema_id, meta) in sorted(channels.items()):
            cid[k] = w.register_channel(topic, enc, sid.get(schema_id, 0), meta)
        for ch, log, pub, seq, data in msgs:
            w.add_message(cid[ch], log, data, pub, seq)
        w.finish()


def records(data):
    """Top-level records [(offset, opcode, length)] up to the end or the first bad length."""
    out, pos = [], 8
    while pos + 9 <= len(data):
        op = data[pos]
        (n,) = struct.unpack_from("<Q", data, pos + 1)
        if pos + 9 + n > len(data):
            break
        out.append((pos, op, n))
        pos += 9 + n
        if op == 0x02:  # footer
            break
    return out


OP_CHUNK, OP_STATS, OP_FOOTER = 0x06, 0x0B, 0x02


def chunk_records_range(data, off):
    """(start, end, crc_offset) of a chunk record's records bytes."""
    pos = off + 9 + 8 + 8 + 8
    crc_at = pos
    pos += 4
    (n,) = struct.unpack_from("<I", data, pos)
    pos += 4 + n
    (rl,) = struct.unpack_from("<Q", data, pos)
    pos += 8
    return pos, pos + rl, crc_at


def python_recovery(path):
    """Messages the Python `mcap` reader recovers: the indexed (seeking) reader with CRC
    checks, falling back to a linear scan up to the first error; the better of the two.
    Returns (total, {topic: count})."""
    best = (0, {})
    for mode in ("indexed", "linear"):
        counts = {}
        try:
            with open(path, "rb") as f:
                if mode == "indexed":
                    it = make_reader(f, validate_crcs=True).iter_messages(log_time_order=False)
                    for _, c, _ in it:
                        counts[c.topic] = counts.get(c.topic, 0) + 1
                else:
                    chans = {}
                    for rec in StreamReader(f, skip_magic=False, validate_crcs=True).records:
                        if type(rec).__name__ == "Channel":
                            chans[rec.id] = rec.topic
                        elif isinstance(rec, McapMessage) and rec.channel_id in chans:
                            t = chans[rec.channel_id]
                            counts[t] = counts.get(t, 0) + 1
        except Exception:  # noqa: BLE001 - any failure ends that reader's count
            pass
        total = sum(counts.values())
        if total > best[0]:
            best = (total, counts)
    return best


# ----------------------------------------------------------------------------------------
# Case helpers.
# ----------------------------------------------------------------------------------------


class Cases:
    def __init__(self, root):
        self.root = Path(root)
        self.items = []

    def new(self, category, kind, **kw):
        cid = f"{category}-{kind}-{sum(1 for c in self.items if c['category'] == category):04d}"
        d = self.root / cid
        d.mkdir(parents=True, exist_ok=True)
        case = {"id": cid, "category": category, "kind": kind, "dir": str(d), "runs": [],
                "expect": {}}
        case.update(kw)
        self.items.append(case)
        return case, d


def bag_runs(mesh=False):
    runs = [("check", ["BIN", "check", "in.mcap", "--report", "check.json"]),
            ("replay", ["BIN", "replay", "in.mcap", "--report", "replay.json"])]
    if mesh:
        runs.append(("mesh", ["BIN", "mesh", "in.mcap", "--stats", "mesh.json"]))
    return runs


# ----------------------------------------------------------------------------------------
# Category 1: the bundled bags, damaged, in four forms.
# ----------------------------------------------------------------------------------------


def damage(data, kind, rng):
    """A damaged copy of `data` and a short description."""
    d = bytearray(data)
    recs = records(data)
    chunks = [r for r in recs if r[1] == OP_CHUNK]
    n = len(d)
    if kind == "flip1":
        i = rng.randrange(8, n)
        d[i] ^= 1 << rng.randrange(8)
        return bytes(d), f"bit flip at {i}"
    if kind == "flips":
        for _ in range(rng.randrange(2, 20)):
            d[rng.randrange(8, n)] ^= rng.randrange(1, 256)
        return bytes(d), "several byte flips"
    if kind == "truncate":
        i = rng.randrange(8, n)
        return bytes(d[:i]), f"truncated at {i} of {n}"
    if kind == "truncate-tail":
        i = n - rng.randrange(1, min(n - 8, 400))
        return bytes(d[:i]), f"truncated at {i} of {n}"
    if kind == "zero":
        i = rng.randrange(8, n)
        ln = rng.choice([8, 64, 512, 4096])
        d[i:i + ln] = bytes(len(d[i:i + ln]))
        return bytes(d), f"zeroed {ln} bytes at {i}"
    if kind == "dup-chunk" and chunks:
        off, _, ln = rng.choice(chunks)
        piece = data[off:off + 9 + ln]
        at = rng.choice([off, off + 9 + ln])
        return bytes(d[:at] + piece + d[at:]), f"chunk at {off} duplicated"
    if kind == "corrupt-first-chunk" and chunks:
        off, _, ln = chunks[0]
        i = off + 9 + rng.randrange(40, ln)
        d[i] ^= 0xFF
        return bytes(d), f"byte {i} of the first chunk flipped"
    if kind == "bad-length" and recs:
        off, op, ln = rng.choice(recs[1:] or recs)
        new = rng.choice([ln + 1, max(ln - 1, 0), ln * 2, 1 << 40, 0xFFFFFFFFFFFFFFFF,
                          rng.randrange(0, 1 << 20)])
        d[off + 1:off + 9] = struct.pack("<Q", new)
        return bytes(d), f"record at {off} (op {op:#x}) length {ln} -> {new}"
    if kind == "zero-stats":
        st = [r for r in recs if r[1] == OP_STATS]
        if st:
            off, _, ln = st[0]
            d[off + 9:off + 9 + ln] = bytes(ln)
            foot = [r for r in recs if r[1] == OP_FOOTER]
            if foot:  # summary CRC 0 = not checked: the file stays intact otherwise
                fo = foot[0][0]
                d[fo + 9 + 16:fo + 9 + 20] = bytes(4)
            return bytes(d), "statistics zeroed"
    if kind == "zero-chunk" and chunks:
        off, _, _ = rng.choice(chunks)
        try:
            s, e, crc_at = chunk_records_range(data, off)
        except struct.error:
            return bytes(d), "no chunk"
        d[s:e] = bytes(e - s)
        d[crc_at:crc_at + 4] = bytes(4)
        return bytes(d), f"chunk at {off} zero-filled (CRC 0)"
    # Fallback when the form has no such record.
    i = rng.randrange(8, n)
    d[i] ^= 0x55
    return bytes(d), f"byte flip at {i} (no record for {kind})"


DAMAGE_KINDS = ["flip1", "flips", "truncate", "truncate-tail", "zero", "dup-chunk",
                "corrupt-first-chunk", "bad-length", "zero-stats", "zero-chunk"]


def gen_bag_damage(cases, repo, rng, per_form):
    bags = sorted((repo / "bags").glob("*.mcap"))
    for bag_path in bags:
        bag = read_bag(bag_path)
        voxel_channels = {k for k, c in bag[2].items()
                          if bag[1].get(c[2], ("",))[0] == VOXEL}
        frames = {}
        for ch, *_ in bag[3]:
            if ch in voxel_channels:
                t = bag[2][ch][0]
                frames[t] = frames.get(t, 0) + 1
        for form in FORMS:
            tmp = cases.root / f"_base-{bag_path.stem}-{form}.mcap"
            write_bag(tmp, bag, form)
            base = tmp.read_bytes()
            for i in range(per_form):
                kind = DAMAGE_KINDS[i % len(DAMAGE_KINDS)]
                data, what = damage(base, kind, rng)
                case, d = cases.new("bag-damage", f"{form}-{kind}")
                (d / "in.mcap").write_bytes(data)
                total, per_topic = python_recovery(d / "in.mcap")
                case["what"] = f"{bag_path.name} ({form}): {what}"
                case["runs"] = bag_runs(mesh=kind in ("zero-stats", "zero-chunk"))
                case["expect"] = {
                    "py_messages": total, "orig_messages": len(bag[3]),
                    "py_frames": {t: c for t, c in per_topic.items() if t in frames},
                    "crc_protected": form != "unchunked",
                    "has_messages": True,
                }
                if kind == "zero-stats":
                    case["expect"]["must_succeed"] = True


# ----------------------------------------------------------------------------------------
# Category 2: hostile VoxelGrid bags, written from scratch.
# ----------------------------------------------------------------------------------------

RES = 0.05
SIZE = (24, 24, 8)


def block_bits(size, box):
    """BITS data of a grid with the voxels of box ((x0,x1),(y0,y1),(z0,z1)) set."""
    sx, sy, sz = size
    out = bytearray((sx * sy * sz + 7) // 8)
    (x0, x1), (y0, y1), (z0, z1) = box
    for z in range(max(z0, 0), min(z1, sz)):
        for y in range(max(y0, 0), min(y1, sy)):
            for x in range(max(x0, 0), min(x1, sx)):
                i = x + sx * (y + sy * z)
                out[i >> 3] |= 1 << (i & 7)
    return bytes(out)


def block_percent(size, box, value=100):
    sx, sy, sz = size
    out = bytearray(sx * sy * sz)
    (x0, x1), (y0, y1), (z0, z1) = box
    for z in range(max(z0, 0), min(z1, sz)):
        for y in range(max(y0, 0), min(y1, sy)):
            for x in range(max(x0, 0), min(x1, sx)):
                out[x + sx * (y + sy * z)] = value
    return bytes(out)


def base_scene(frames=12):
    """Four bodies on one lattice. A moves along +x; B comes down -y through the place A
    leaves at frame 5 (so if A were extended past frame 5, they would meet from frame 9);
    C and D overlap all the time. Truth: only C x D collides."""
    bodies = {}
    for name, box_of in [
        ("/a/occupancy", lambda i: ((i, i + 4), (2, 6), (2, 6))),
        ("/b/occupancy", lambda i: ((4, 7), (22 - 2 * i, 26 - 2 * i), (2, 6))),
        ("/c/occupancy", lambda i: ((14, 18), (14, 18), (2, 6))),
        ("/d/occupancy", lambda i: ((15, 19), (15, 19), (2, 6))),
    ]:
        bodies[name] = [dict(stamp=T0 + i * PERIOD, origin=[0.0, 0.0, 0.0], res=RES,
                             size=list(SIZE), enc=0, box=box_of(i))
                        for i in range(frames)]
    return bodies


TRUTH = {"/a/occupancy /b/occupancy": False, "/a/occupancy /c/occupancy": False,
         "/a/occupancy /d/occupancy": False, "/b/occupancy /c/occupancy": False,
         "/b/occupancy /d/occupancy": False, "/c/occupancy /d/occupancy": True}
NOT_A = ["/b/occupancy /c/occupancy", "/b/occupancy /d/occupancy",
         "/c/occupancy /d/occupancy"]


def encode_frame(f):
    if "raw" in f:
        return f["raw"]
    data = f.get("data")
    if data is None:
        if f["enc"] == 1:
            data = block_percent(f["size"], f["box"], f.get("value", 100))
        else:
            data = block_bits(f["size"], f["box"])
    return cdr.voxel_grid(f["stamp"], f["origin"], f["res"], f["size"], f["enc"], data,
                          frame_id=f.get("frame_id", "world"), nanosec=f.get("nanosec"),
                          declared_len=f.get("declared_len"))


_SCHEMAS = {}


def schema_text(repo, name):
    if not _SCHEMAS:
        for p in ["bags/carving-session.mcap"]:
            _, schemas, _, _ = read_bag(repo / p)
            for n, _, data in schemas.values():
                _SCHEMAS[n] = data
    return _SCHEMAS[name]


QOS = ("- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: "
       "9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n"
       "  liveliness: 1\n  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: "
       "854775807\n  avoid_ros_namespace_conventions: false")


def scene_bag(repo, bodies, channel_over=None, extra=None):
    """A bag (read_bag's tuple) of VoxelGrid bodies; channel_over: {topic: dict(encoding=,
    schema=name|None|'mismatch')}; extra: [(topic, type, [(log_time, bytes)])]."""
    channel_over = channel_over or {}
    schemas = {1: (VOXEL, "ros2msg", schema_text(repo, VOXEL))}
    channels, msgs = {}, []
    for i, (topic, frames) in enumerate(sorted(bodies.items()), 1):
        over = channel_over.get(topic, {})
        sid = 1
        if "schema" in over:
            if over["schema"] is None:
                sid = 0
            else:
                sid = 100 + i
                text = schema_text(repo, VOXEL)
                if over["schema"] == "mismatch":
                    text = text.replace(b"float64 resolution", b"float32 resolution") \
                        .replace(b"uint32 size_x", b"uint16 size_x")
                schemas[sid] = (VOXEL, over.get("schema_encoding", "ros2msg"), text)
        channels[i] = (topic, over.get("encoding", "cdr"), sid,
                       {"offered_qos_profiles": QOS})
        for seq, f in enumerate(frames):
            msgs.append((f.get("log", f["stamp"]), i, seq, encode_frame(f)))
    for j, (topic, typ, items) in enumerate(extra or [], 1000):
        sid = 500 + j
        schemas[sid] = (typ, "ros2msg", schema_text(repo, typ))
        channels[j] = (topic, "cdr", sid, {"offered_qos_profiles": QOS})
        for seq, (log, data) in enumerate(items):
            msgs.append((log, j, seq, data))
    msgs.sort(key=lambda m: m[0])
    return ("ros2", schemas, channels,
            [(ch, log, log, seq, data) for log, ch, seq, data in msgs])


def gen_voxelgrid(cases, repo, rng):
    def add(kind, bodies, expect=None, channel_over=None, form="zstd", mesh=False,
            post=None, runs=None, extra=None):
        case, d = cases.new("voxelgrid", kind)
        bag = scene_bag(repo, bodies, channel_over, extra)
        write_bag(d / "in.mcap", bag, form)
        if post:
            post(d / "in.mcap")
        case["runs"] = runs or bag_runs(mesh)
        e = {"truth": dict(TRUTH)}
        e.update(expect or {})
        case["expect"] = e
        return case

    A = "/a/occupancy"
    full = {t: 12 for t in ("/a/occupancy", "/b/occupancy", "/c/occupancy", "/d/occupancy")}

    def vf(**kw):
        v = dict(full)
        v.update(kw)
        return v

    # Refused frames must not invent a collision: A valid for k frames, then another lattice.
    for k in range(2, 11):
        for change in ("resolution", "half-voxel-origin"):
            b = base_scene()
            for f in b[A][k:]:
                if change == "resolution":
                    f["res"] = RES * 2
                else:
                    f["origin"] = [RES / 2, 0.0, 0.0]
            add(f"{change}-change-after-{k}", b,
                {"valid_frames": vf(**{A: k}), "intact_pairs": NOT_A, "must_count":
                 "frames on another lattice"})
    # Another body on a half-voxel offset lattice, and whole-voxel offsets (supported).
    for axis in range(3):
        b = base_scene()
        for f in b["/b/occupancy"]:
            f["origin"][axis] = RES / 2
        add(f"half-voxel-body-offset-{'xyz'[axis]}", b,
            {"valid_frames": full, "must_count": "bodies on different lattices",
             "truth": {}})
        for n in (1, 3):
            b = base_scene()
            for f in b["/c/occupancy"]:
                f["origin"][axis] = n * RES
                (x0, x1), (y0, y1), (z0, z1) = f["box"]
                sh = [[x0, x1], [y0, y1], [z0, z1]]
                sh[axis] = [sh[axis][0] - n, sh[axis][1] - n]
                f["box"] = tuple(map(tuple, sh))
            add(f"whole-voxel-body-offset-{'xyz'[axis]}{n}", b,
                {"valid_frames": full, "truth_exact": True})
    # Percent values outside 0..=100 and 255.
    for v in (101, 120, 150, 200, 254):
        for where in ("one", "all"):
            b = base_scene()
            for i, f in enumerate(b[A]):
                f["enc"] = 1
                if where == "all" or i == 5:
                    f["value"] = v
            add(f"percent-{v}-{where}-frames", b,
                {"valid_frames": full, "must_count": f"PERCENT value {v}"})
    # nanosec >= 1e9.
    for ns in (1_000_000_000, 1_500_000_000, 0xFFFFFFFF):
        for where in (0, 6):
            b = base_scene()
            b[A][where]["nanosec"] = ns
            add(f"nanosec-{ns}-frame{where}", b,
                {"valid_frames": vf(**{A: 11}), "must_count": f"nanosec {ns}"})
    # Non-finite or non-positive resolution and origin in one frame.
    for name, val in [("nan", math.nan), ("inf", math.inf), ("neg", -RES), ("zero", 0.0),
                      ("tiny", 1e-300)]:
        for where in (0, 6):
            b = base_scene()
            b[A][where]["res"] = val
            add(f"resolution-{name}-frame{where}", b,
                {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A,
                 "must_count": "bad resolution", "nan_input": name == "nan"})
    for name, val in [("nan", math.nan), ("inf", -math.inf), ("huge", 1e300)]:
        for axis in range(3):
            b = base_scene()
            b[A][6]["origin"][axis] = val
            add(f"origin-{name}-{'xyz'[axis]}", b,
                {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A,
                 "must_count": "bad origin", "nan_input": name == "nan"})
    # Stamps backwards and duplicated.
    for where in (1, 6, 11):
        b = base_scene()
        b[A][where]["stamp"] = b[A][where - 1]["stamp"] - PERIOD // 2
        add(f"stamp-backwards-frame{where}", b,
            {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A, "must_count": "backwards"})
        b = base_scene()
        b[A][where]["stamp"] = b[A][where - 1]["stamp"]
        add(f"stamp-duplicate-frame{where}", b,
            {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A, "must_count": "duplicate"})
    # Data of the wrong length, declared or real.
    for name, over in [("short", dict(cut=1)), ("long", dict(extra=7)),
                       ("declared-huge", dict(declared_len=0xFFFFFFF0)),
                       ("declared-short", dict(declared_len=10))]:
        for where in (0, 6):
            b = base_scene()
            f = b[A][where]
            data = block_bits(f["size"], f["box"])
            if "cut" in over:
                data = data[:-over["cut"]]
            if "extra" in over:
                data = data + bytes(over["extra"])
            f["data"] = data
            if "declared_len" in over:
                f["declared_len"] = over["declared_len"]
            add(f"data-{name}-frame{where}", b,
                {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A, "must_count": "length"})
    # Mixed encodings.
    b = base_scene()
    for f in b[A] + b["/c/occupancy"]:
        f["enc"] = 1
    add("mixed-encodings-bodies", b, {"valid_frames": full, "truth_exact": True})
    b = base_scene()
    for f in b["/c/occupancy"]:
        f["enc"] = 1
    add("mixed-encodings-c-percent", b, {"valid_frames": full, "truth_exact": True})
    b = base_scene()
    for f in b[A][6:]:
        f["enc"] = 1
    add("encoding-switch-mid-stream", b,
        {"valid_frames": vf(**{A: 6}), "intact_pairs": NOT_A, "must_count": "encoding switch"})
    # One skipped frame (does not decode), and several in one body.
    for where in range(1, 11):
        b = base_scene()
        raw = encode_frame(b[A][where])
        b[A][where]["raw"] = raw[:rng.randrange(5, 60)]
        add(f"one-skipped-frame-{where}", b,
            {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A, "must_count": "undecodable"})
    for bad in ((2, 5), (3, 4, 8), (1, 4, 7, 9), (2, 3, 4, 5, 6), (5, 6)):
        b = base_scene()
        for j, where in enumerate(bad):
            f = b[A][where]
            kind = j % 3
            if kind == 0:
                f["raw"] = encode_frame(f)[:20]
            elif kind == 1:
                f["res"] = math.nan
            else:
                f["res"] = RES * 2
        add(f"several-bad-frames-{len(bad)}", b,
            {"valid_frames": vf(**{A: 12 - len(bad)}), "intact_pairs": NOT_A,
             "must_count": "bad frames"})
    # Bodies in different frame_ids.
    for which in (["/b/occupancy"], ["/c/occupancy"], list(full)):
        b = base_scene()
        for t in which:
            for f in b[t]:
                f["frame_id"] = "robot_base" + t.replace("/", "_")
        add(f"frame-id-{len(which)}-bodies", b,
            {"valid_frames": full, "must_count": "different frame_id", "truth": {}})
    # Stamps offset between bodies.
    for off in (1_000_000, 50_000_000, 30 * PERIOD):
        b = base_scene()
        for f in b["/b/occupancy"]:
            f["stamp"] += off
        add(f"stamps-offset-{off // 1_000_000}ms", b, {"valid_frames": full, "truth": {}})
    # Many tiny bodies.
    for n in (100, 257, 300):
        b = {}
        for i in range(n):
            b[f"/body{i:03d}/occupancy"] = [
                dict(stamp=T0 + j * PERIOD, origin=[0.0, 0.0, 0.0], res=RES, size=[4, 4, 4],
                     enc=0, box=((i % 2, i % 2 + 2), (1, 3), (1, 3))) for j in range(2)]
        add(f"tiny-bodies-{n}", b, {"must_count": "over 256 topics" if n > 256 else None,
                                    "truth": {}} if n > 256 else {"truth": {}})
    # Channel-level problems.
    for kind, over in [("json-encoding", {"encoding": "json"}),
                       ("schema-mismatch", {"schema": "mismatch"}),
                       ("no-schema", {"schema": None}),
                       ("schema-encoding-other", {"schema": "same",
                                                  "schema_encoding": "ros2idl"})]:
        for t in ("/b/occupancy", "/c/occupancy"):
            add(f"{kind}-{t.split('/')[1]}", base_scene(), {"must_count": kind, "truth": {}},
                channel_over={t: over})
    # A zero-filled chunk (one chunk for the whole bag, or one of several).
    def zero_chunk(which):
        def post(p):
            data = bytearray(p.read_bytes())
            chunks = [r for r in records(bytes(data)) if r[1] == OP_CHUNK]
            off = chunks[which if which < len(chunks) else 0][0]
            s, e, crc_at = chunk_records_range(bytes(data), off)
            data[s:e] = bytes(e - s)
            data[crc_at:crc_at + 4] = bytes(4)
            p.write_bytes(bytes(data))
        return post
    for form, which in (("chunked", 0), ("chunked", 3)):
        add(f"zero-filled-chunk-{which}", base_scene(), {"must_count": "zero-filled chunk",
                                                        "has_messages": True, "truth": {}},
            form=form, post=zero_chunk(which), mesh=True)
    one = scene_bag(repo, base_scene())
    case, d = cases.new("voxelgrid", "zero-filled-single-chunk")
    write_bag(d / "in.mcap", one, "zstd")
    with open(d / "in.mcap", "wb") as f:
        w = Writer(f, compression=CompressionType.NONE, chunk_size=1 << 30)
        prof, schemas, channels, msgs = one
        w.start(profile=prof)
        sid = {k: w.register_schema(*v) for k, v in schemas.items()}
        cid = {k: w.register_channel(c[0], c[1], sid[c[2]], c[3]) for k, c in channels.items()}
        for ch, log, pub, seq, data in msgs:
            w.add_message(cid[ch], log, data, pub, seq)
        w.finish()
    zero_chunk(0)(d / "in.mcap")
    case["runs"] = bag_runs(mesh=True)
    case["expect"] = {"must_count": "zero-filled chunk", "has_messages": True}
    # The only chunk fails its CRC.
    for flip in (40, 400):
        case, d = cases.new("voxelgrid", f"only-chunk-bad-crc-{flip}")
        with open(d / "in.mcap", "wb") as f:
            w = Writer(f, compression=CompressionType.NONE, chunk_size=1 << 30)
            prof, schemas, channels, msgs = one
            w.start(profile=prof)
            sid = {k: w.register_schema(*v) for k, v in schemas.items()}
            cid = {k: w.register_channel(c[0], c[1], sid[c[2]], c[3])
                   for k, c in channels.items()}
            for ch, log, pub, seq, data in msgs:
                w.add_message(cid[ch], log, data, pub, seq)
            w.finish()
        data = bytearray((d / "in.mcap").read_bytes())
        off = [r for r in records(bytes(data)) if r[1] == OP_CHUNK][0][0]
        s, e, _ = chunk_records_range(bytes(data), off)
        data[s + flip] ^= 0xFF
        (d / "in.mcap").write_bytes(bytes(data))
        case["runs"] = bag_runs()
        case["expect"] = {"has_messages": True}
    # Huge frames: within the per-frame limits (8 x 16384 x 8192 bits: 128 MiB of data, zstd
    # compressed to a few KB) and beyond them.
    for name, size, n in [("8x16384x8192-bits-2", [8, 16384, 8192], 2),
                          ("2048x2048x256-bits-2", [2048, 2048, 256], 2),
                          ("1x32768x32768-bits-1", [1, 32768, 32768], 1),
                          ("2048x2048x2048-bits-1", [2048, 2048, 2048], 1)]:
        case, d = cases.new("voxelgrid", f"huge-{name}")
        vox = size[0] * size[1] * size[2]
        frames = []
        for j in range(n):
            data = bytes((vox + 7) // 8) if vox <= (1 << 31) else bytes(16)
            frames.append(dict(stamp=T0 + j * PERIOD, origin=[0.0, 0.0, 0.0], res=0.001,
                               size=size, enc=0, data=data))
            del data
        bag = scene_bag(repo, {"/huge/occupancy": frames})
        write_bag(d / "in.mcap", bag, "zstd")
        del bag, frames
        case["runs"] = bag_runs(mesh=True)
        case["expect"] = {}
    # A one-body bag under the default replay config.
    for nbody in ("/a/occupancy", "/c/occupancy"):
        b = {nbody: base_scene()[nbody]}
        add(f"one-body-{nbody.split('/')[1]}", b, {"must_succeed": True, "truth": {}})
    # A bag without VoxelGrid messages (only poses), and one whose frames all fail.
    pose_items = [(T0 + i * 1_000_000, cdr.pose_stamped(T0 + i * 1_000_000, [0, 0, 0],
                                                        [0, 0, 0, 1])) for i in range(5)]
    add("no-voxel-topics", {}, {"truth": {}}, extra=[("/haptic/pose", POSE, pose_items)])
    b = base_scene()
    for frames in b.values():
        for f in frames:
            f["raw"] = encode_frame(f)[:30]
    add("every-frame-undecodable", b, {"truth": {}, "has_messages": True})
    # Empty and single-frame bodies.
    b = base_scene()
    for f in b["/b/occupancy"]:
        f["box"] = ((0, 0), (0, 0), (0, 0))
    add("empty-body", b, {"valid_frames": full, "truth": {}})
    b = base_scene()
    b["/b/occupancy"] = b["/b/occupancy"][:1]
    add("single-frame-body", b, {"truth": {}})
    # The same damage in PERCENT bodies and in body B (added last: case ids stay stable).
    for where in (2, 5, 8):
        b = base_scene()
        for f in b[A]:
            f["enc"] = 1
        b[A][where]["raw"] = encode_frame(b[A][where])[:40]
        add(f"percent-one-skipped-frame-{where}", b,
            {"valid_frames": vf(**{A: 11}), "intact_pairs": NOT_A, "must_count": "undecodable"})
    for where in (3, 7):
        b = base_scene()
        b["/b/occupancy"][where]["res"] = RES * 2
        add(f"b-resolution-change-frame{where}", b,
            {"valid_frames": vf(**{"/b/occupancy": 11}),
             "intact_pairs": ["/a/occupancy /c/occupancy", "/a/occupancy /d/occupancy",
                              "/c/occupancy /d/occupancy"],
             "must_count": "frame on another lattice"})


# ----------------------------------------------------------------------------------------
# Category 3: launch configs.
# ----------------------------------------------------------------------------------------

NODE_PARAMS = {
    "mesher": {"iso_percent": "int", "percent_scale": "int", "max_slab_tets": "int",
               "idle_timeout_s": "float", "unknown_occupied": "bool"},
    "checker": {"time_scale_m_per_s": "float", "max_lead_frames": "int",
                "resolve_horizon_s": "float", "max_episode_s": "float",
                "resolve_max_tets": "int", "iso_percent": "int", "percent_scale": "int"},
    "carving": {"spacing_m": "float", "knife_length_m": "float", "knife_width_m": "float",
                "knife_thickness_m": "float", "chisel_width_m": "float",
                "chisel_height_m": "float", "chisel_thickness_m": "float",
                "newtons_per_point": "float", "cutting_pressure_n_per_m2": "float",
                "filter_cutoff_hz": "float", "coupling_stiffness_n_per_m": "float",
                "coupling_damping_ns_per_m": "float", "proxy_mass_kg": "float",
                "max_force_n": "float", "occupancy_period_s": "float"},
}

MT_BODIES = ["/spindle/occupancy", "/table/occupancy", "/fixture/occupancy"]


def carving_config(repo, over=None, extra_nodes=""):
    p = {"pose_topic": "/haptic/pose", "frame_id": "world",
         "workpiece_min": "[0.0, 0.0, 0.0]", "workpiece_max": "[0.06, 0.06, 0.03]",
         "spacing_m": "0.002",
         "cutouts": f'["z {repo}/bags/carving-outline-z.pgm", "y {repo}/bags/carving-outline-y.pgm"]',
         "tool": "knife", "tool_schedule": '["1.5 chisel"]', "occupancy_period_s": "0.1"}
    p.update(over or {})
    params = "\n".join(f"    - {{name: {k}, value: {v}}}" for k, v in p.items() if v is not None)
    return (f"launch:\n- node:\n    pkg: chronotope\n    exec: carving\n    param:\n{params}\n"
            "- node:\n    pkg: chronotope\n    exec: mesher\n    param:\n"
            "    - {name: bodies, value: [/carving/occupancy, /fixture/occupancy]}\n"
            "- node:\n    pkg: chronotope\n    exec: checker\n    param:\n"
            "    - {name: pairs, value: [\"/carving/occupancy /fixture/occupancy\"]}\n"
            + extra_nodes)


def mt_config(node, name, value):
    mesher = "    - {name: bodies, value: [/spindle/occupancy, /table/occupancy, /fixture/occupancy]}"
    checker = ('    - {name: pairs, value: ["/spindle/occupancy /table/occupancy", '
               '"/spindle/occupancy /fixture/occupancy"]}\n'
               "    - {name: movable, value: [/spindle/occupancy]}")
    extra = f"    - {{name: {name}, value: {value}}}"
    # A parameter the base config already sets is replaced, not given twice.
    mesher = "\n".join(l for l in mesher.split("\n") if f"name: {name}," not in l)
    checker = "\n".join(l for l in checker.split("\n") if f"name: {name}," not in l)
    if node == "mesher":
        mesher += "\n" + extra
    else:
        checker += "\n" + extra
    return (f"launch:\n- node:\n    pkg: chronotope\n    exec: mesher\n    param:\n{mesher}\n"
            f"- node:\n    pkg: chronotope\n    exec: checker\n    param:\n{checker}\n")


def replay_runs(bag, out=False):
    argv = ["BIN", "replay", str(bag), "--launch", "cfg.yaml", "--report", "replay.json"]
    if out:
        argv += ["--out", "out.mcap"]
    return [("replay", argv)]


def gen_launch(cases, repo, rng, mutated):
    mt = repo / "bags/machine-tool-32-bits.mcap"
    cs = repo / "bags/carving-session.mcap"

    def add(kind, text, bag=mt, expect=None, out=False, setup=None, timeout=None):
        case, d = cases.new("launch", kind)
        (d / "cfg.yaml").write_text(text) if isinstance(text, str) else \
            (d / "cfg.yaml").write_bytes(text)
        case["runs"] = replay_runs(bag, out)
        case["expect"] = expect or {}
        if out:
            case["out_checks"] = ["wrench_finite", "output_finite"]
        if setup:
            case["setup"] = setup
        if timeout:
            case["timeout"] = timeout
        return case

    for size in (100_000, 500_000, 1_000_000):
        depth = (size - 8) // 2
        add(f"nested-brackets-{size // 1000}k", "launch: " + "[" * depth + "]" * depth + "\n")
    add("nested-mappings-200k", "launch: " + "{a: " * 40_000 + "1" + "}" * 40_000 + "\n")
    for n in (2_000, 10_000, 19_000):
        nodes = "".join(f"- node: {{pkg: chronotope, exec: recorder, name: r{i}}}\n"
                        for i in range(n))
        add(f"nodes-{n}", "launch:\n" + nodes)
    for kind, text in [("empty-launch", "launch:\n"), ("empty-list", "launch: []\n"),
                       ("empty-file", ""), ("empty-mapping", "{}\n"),
                       ("only-comment", "# nothing\n")]:
        add(kind, text, expect={"must_count": "nothing to run"})
    add("alias-bomb", "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a]\n"
        "c: &c [*b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c]\n"
        "e: &e [*d, *d, *d, *d, *d, *d, *d, *d]\nf: &f [*e, *e, *e, *e, *e, *e, *e, *e]\n"
        "launch: [*f]\n")
    big = "9" * 300
    for node, params in NODE_PARAMS.items():
        for name, typ in params.items():
            values = {"300-digit": big, "neg-300-digit": "-" + big, "nan": ".nan",
                      "inf": ".inf", "neg": "-1", "zero": "0", "huge": "1e308",
                      "string": "'x'"}
            if typ == "bool":
                values = {"300-digit": big, "string": "'yes please'"}
            for vname, v in values.items():
                e = {}
                if vname in ("nan", "inf") and typ == "float":
                    e["must_count"] = f"{name} {vname}"
                if node == "carving":
                    add(f"{node}-{name}-{vname}", carving_config(repo, {name: v}), bag=cs,
                        expect=e, out=True)
                else:
                    add(f"{node}-{name}-{vname}", mt_config(node, name, v), expect=e)
    for m in ("1e-4", "5e-5", "1e-5", "1e-6", "1e-9"):
        add(f"proxy-mass-{m}", carving_config(repo, {"proxy_mass_kg": m}), bag=cs, out=True)
    for period in ("0.001", "0.0005", "0.002"):
        add(f"occupancy-period-{period}", carving_config(repo, {"occupancy_period_s": period}),
            bag=cs, out=False)
    for n, spacing in ((319, 0.001), (400, 0.001), (4096, 0.0001)):
        top = n * spacing
        add(f"workpiece-{n}-cubed", carving_config(repo, {
            "workpiece_max": f"[{top}, {top}, {top}]" if n < 4096 else f"[{top}, {top}, 0.0002]",
            "spacing_m": str(spacing)}), bag=cs)
    add("pose-topic-is-voxelgrid", carving_config(repo, {"pose_topic": "/fixture/occupancy"}),
        bag=cs, expect={"must_count": "pose_topic on a VoxelGrid topic"})
    add("cutout-fifo", carving_config(repo, {"cutouts": '["z fifo.pgm"]'}), bag=cs,
        setup=["fifo.pgm"])
    for name, path in (("dev-zero", "/dev/zero"), ("directory", "/tmp"),
                       ("missing", "/nonexistent/x.pgm")):
        add(f"cutout-{name}", carving_config(repo, {"cutouts": f'["z {path}"]'}), bag=cs)
    structural = {
        "unknown-exec": "launch:\n- node: {pkg: chronotope, exec: teleporter}\n",
        "other-pkg": "launch:\n- node: {pkg: rviz2, exec: rviz2}\n",
        "duplicate-names": "launch:\n- node: {pkg: chronotope, exec: mesher}\n"
                           "- node: {pkg: chronotope, exec: mesher}\n",
        "bad-namespace": "launch:\n- node: {pkg: chronotope, exec: mesher, namespace: '//x y'}\n",
        "misspelt-param": mt_config("checker", "marker", "true"),
        "pair-same-body": mt_config("checker", "pairs",
                                    '["/spindle/occupancy /spindle/occupancy"]'),
        "pair-unknown-body": mt_config("checker", "pairs", '["/x/occupancy /y/occupancy"]'),
        "pair-one-name": mt_config("checker", "pairs", '["/spindle/occupancy"]'),
        "movable-not-in-pair": mt_config("checker", "movable", "[/table/occupancy]"),
        "bodies-empty": "launch:\n- node: {pkg: chronotope, exec: mesher, param: "
                        "[{name: bodies, value: []}]}\n",
        "remap-loop": "launch:\n- node: {pkg: chronotope, exec: mesher, remap: "
                      "[{from: /a, to: /b}, {from: /b, to: /a}]}\n",
        "remap-to-input": "launch:\n- node: {pkg: chronotope, exec: mesher, remap: "
                          "[{from: ~/mesh_slabs, to: /spindle/occupancy}]}\n"
                          "- node: {pkg: chronotope, exec: checker}\n",
        "two-checkers": "launch:\n- node: {pkg: chronotope, exec: mesher}\n"
                        "- node: {pkg: chronotope, exec: checker, name: c1}\n"
                        "- node: {pkg: chronotope, exec: checker, name: c2}\n",
        "checker-without-mesher": "launch:\n- node: {pkg: chronotope, exec: checker}\n",
        "not-yaml": "launch: [\n",
        "binary": bytes(range(256)) * 4,
        "param-list-of-maps": mt_config("checker", "pairs", "[{a: 1}]"),
        "param-given-twice": mt_config("checker", "markers", "true").replace(
            "    - {name: markers, value: true}",
            "    - {name: markers, value: true}\n    - {name: markers, value: false}"),
    }
    for kind, text in structural.items():
        add(kind, text)
    # Bundled configs with random edits (hostile values, deleted or repeated lines).
    seeds = sorted((repo / "launch_configs").glob("*.yaml"))
    texts = [(p.stem, p.read_text().replace("bags/", f"{repo}/bags/")) for p in seeds]
    for i in range(mutated):
        stem, text = texts[i % len(texts)]
        bag = {"machine_tool": mt, "four_spheres": repo / "bags/four-spheres-32-bits.mcap",
               "carving_session": cs, "periodic": mt}[stem]
        add(f"mutated-{stem}", edit_text(text, rng), bag=bag)


HOSTILE = [".nan", "-.inf", ".inf", "-1", "0", "1e-9", "1e308", "-0.0", "9" * 300, "''", "[]",
           "{}", "~", "[.nan, .nan, .nan]", "[1, 2]", "/", "/fixture/occupancy", "x y z",
           "[[[[[[[[[[]]]]]]]]]]", "&a [*a]", "1e6", "100000000", "4294967296"]


def edit_text(text, rng):
    lines = text.splitlines()
    for _ in range(rng.randrange(1, 4)):
        if not lines:
            break
        op = rng.randrange(4)
        i = rng.randrange(len(lines))
        if op <= 1:
            spots = [(j, m.start()) for j, l in enumerate(lines) for m in re.finditer(": ", l)]
            if spots:
                j, k = rng.choice(spots)
                line = lines[j]
                end = min([p for p in (line.find(",", k + 2), line.find("}", k + 2)) if p >= 0]
                          or [len(line)])
                lines[j] = line[:k + 2] + rng.choice(HOSTILE) + line[end:]
        elif op == 2:
            del lines[i]
        else:
            lines[i:i] = [lines[i]] * rng.randrange(1, 50)
    return "\n".join(lines) + "\n"


import re  # noqa: E402  (used by edit_text)


# ----------------------------------------------------------------------------------------
# Category 4: sampler scene files and options.
# ----------------------------------------------------------------------------------------

SPHERE_BOX = """dim: 4
bodies:
  - name: sphere
    shape: {kind: sphere, centre: CENTRE, radius: RADIUS}
  - name: box
    shape: {kind: box, centre: [0.2, 0.5, 0.55], half: [0.15, 0.15, 0.15], rounding: 0.0}
    velocity: VELOCITY
sample: [sphere, box]
walls:
  - {kind: box, min: [0, 0, 0], max: [1, 1, 1]}
time: [0.0, 1.0]
sampler: {scheme: metropolis, dt: 0.0001, samples: 2000, walkers: 8}
"""


def gen_sampler(cases, repo, rng, mutated):
    def add(kind, text, opts=(), expect=None):
        case, d = cases.new("sampler", kind)
        (d / "scene.yaml").write_text(text)
        case["runs"] = [("sample", ["BIN", "sample", "scene.yaml", "--out", "s.mcap",
                                    *opts])]
        case["expect"] = expect or {}
        return case

    for size in (100_000, 400_000, 1_000_000):
        depth = (size - 10) // 2
        add(f"nested-{size // 1000}k", "bodies: " + "[" * depth + "]" * depth + "\n")
    base = dict(CENTRE="[0.65, 0.5, 0.5]", RADIUS="0.2", VELOCITY="[0.6, 0, 0]")
    for field, vals in {"CENTRE": ["[.nan, 0.5, 0.5]", "[0.65, .inf, 0.5]", "[1e308, 0, 0]",
                                   "[0.65, 0.5]", "[" + "9" * 300 + ", 0, 0]"],
                        "RADIUS": [".nan", ".inf", "-0.2", "0", "1e-300", "1e308", "9" * 300],
                        "VELOCITY": ["[.nan, 0, 0]", "[1e308, 0, 0]", "[-.inf, 0, 0]",
                                     "[0.6, 0]"]}.items():
        for v in vals:
            t = SPHERE_BOX
            for k, bv in base.items():
                t = t.replace(k, v if k == field else bv)
            add(f"{field.lower()}-{v[:12]}", t, expect={"nan_input": "nan" in v})
    good = SPHERE_BOX
    for k, bv in base.items():
        good = good.replace(k, bv)
    for opts in (["--samples", "100000000"], ["--samples", "10000000"],
                 ["--burn-in", "100000000"], ["--thin", "1000000"], ["--walkers", "1000000"],
                 ["--walkers", "0"], ["--samples", "0"], ["--dt", "NaN"], ["--dt", "0"],
                 ["--dt", "-1"], ["--dt", "1e308"], ["--lambda", "NaN"],
                 ["--scheme", "explicit", "--lambda", "5"], ["--seed", "18446744073709551615"],
                 ["--samples", "1e8"], ["--thin", "0"]):
        add("option" + "".join(opts).replace("--", "-"), good, opts)
    seeds = sorted((repo / "scenes/implicit").glob("*.yaml"))
    texts = [p.read_text() for p in seeds]
    for i in range(mutated):
        text = edit_text(texts[i % len(texts)], rng)
        text = text.replace("samples: 20000", "samples: 2000")
        add("mutated-scene", text, ["--samples", "2000"])


# ----------------------------------------------------------------------------------------
# Category 5: hostile pose streams into the carving node.
# ----------------------------------------------------------------------------------------


def gen_poses(cases, repo, rng):
    session = read_bag(repo / "bags/carving-session.mcap")
    _, schemas, channels, msgs = session
    pose_ch = next(k for k, c in channels.items() if c[0] == "/haptic/pose")
    poses = [m for m in msgs if m[0] == pose_ch]
    others = [m for m in msgs if m[0] != pose_ch]

    def parse_pose(data):
        body = data[4:]
        sec, ns = struct.unpack_from("<iI", body, 0)
        (n,) = struct.unpack_from("<I", body, 8)
        pos = (12 + n + 7) // 8 * 8
        vals = struct.unpack_from("<7d", body, pos)
        return sec * 1_000_000_000 + ns, list(vals[:3]), list(vals[3:])

    base = [parse_pose(m[4]) for m in poses]

    def add(kind, items, cfg_over=None, expect=None, frame_id="world"):
        case, d = cases.new("poses", kind)
        new = [(pose_ch, t, t, i, cdr.pose_stamped(t, p, q, frame_id if i % 7 == 3 else "world"))
               for i, (t, p, q) in enumerate(items)]
        bag = (session[0], schemas, channels, sorted(new + others, key=lambda m: m[1]))
        write_bag(d / "in.mcap", bag, "zstd")
        (d / "cfg.yaml").write_text(carving_config(repo, cfg_over))
        case["runs"] = [("replay", ["BIN", "replay", "in.mcap", "--launch", "cfg.yaml",
                                    "--report", "replay.json", "--out", "out.mcap"])]
        case["out_checks"] = ["wrench_finite", "output_finite"]
        case["expect"] = expect or {}
        return case

    def edited(fn, every):
        out = []
        for i, (t, p, q) in enumerate(base):
            if i % every == every - 1:
                t, p, q = fn(t, list(p), list(q))
            out.append((t, p, q))
        return out

    nan, inf = math.nan, math.inf
    for every in (3, 50, 400):
        add(f"nan-quaternion-every-{every}", edited(lambda t, p, q: (t, p, [nan, 0, 0, 1]), every),
            expect={"must_count": "NaN quaternion"})
        add(f"zero-quaternion-every-{every}", edited(lambda t, p, q: (t, p, [0, 0, 0, 0]), every),
            expect={"must_count": "zero quaternion"})
        add(f"nan-position-every-{every}", edited(lambda t, p, q: (t, [nan, p[1], p[2]], q), every),
            expect={"must_count": "NaN position"})
        add(f"inf-position-every-{every}", edited(lambda t, p, q: (t, [p[0], inf, p[2]], q), every),
            expect={"must_count": "inf position"})
        add(f"huge-position-every-{every}", edited(lambda t, p, q: (t, [1e300, p[1], p[2]], q),
                                                    every))
        add(f"huge-quaternion-every-{every}", edited(lambda t, p, q: (t, p, [1e300, 0, 0, 1e300]),
                                                      every))
        add(f"stamp-backwards-every-{every}", edited(
            lambda t, p, q: (t - 10_000_000, p, q), every), expect={"must_count": "backwards"})
        if every == 3:
            add("other-frame-every-7th", base, expect={"must_count": "other frame"},
                frame_id="tool0")
    # Pauses: three poses with an hour (or a day) between them; and a pause mid-stroke.
    for pause_s in (3600, 86400):
        t0, p, q = base[0]
        three = [(t0, p, q), (t0 + pause_s * 1_000_000_000, base[500][1], base[500][2]),
                 (t0 + 2 * pause_s * 1_000_000_000, base[900][1], base[900][2])]
        add(f"three-poses-pause-{pause_s}s", three)
        mid = [(t + (pause_s * 1_000_000_000 if i >= 700 else 0), p, q)
               for i, (t, p, q) in enumerate(base)]
        add(f"pause-{pause_s}s-mid-stroke", mid)
    # A large workpiece with the bundled poses.
    for n, spacing in ((319, 0.0002), (256, 0.0002)):
        top = n * spacing
        add(f"workpiece-{n}-cubed", base, {"workpiece_max": f"[{top}, {top}, {top}]",
                                           "spacing_m": str(spacing)})
    # Random garbage poses.
    for k in range(6):
        items = []
        t = base[0][0]
        for _ in range(300):
            t += rng.choice([1_000_000, 0, -1_000_000, 10 ** rng.randrange(3, 13)])
            p = [rng.choice([0.03, nan, 1e10, -0.01, 0.0]) for _ in range(3)]
            q = [rng.choice([0.0, 1.0, nan, 1e-300, -1.0]) for _ in range(4)]
            items.append((t, p, q))
        add(f"random-poses-{k}", items)


# ----------------------------------------------------------------------------------------
# Output checks and setup steps used by campaign.py.
# ----------------------------------------------------------------------------------------


def check_output(name, workdir):
    """A problem with the run's output bag (empty string if none)."""
    path = Path(workdir) / "out.mcap"
    if not path.exists():
        return ""
    try:
        with open(path, "rb") as f:
            bad = 0
            for schema, channel, m in make_reader(f).iter_messages(log_time_order=False):
                if name == "wrench_finite" and schema and schema.name == WRENCH:
                    v = cdr.wrench_values(m.data)
                    if v is None or not cdr.all_finite(v):
                        bad += 1
            if bad:
                return f"{bad} wrenches with NaN or infinite values"
    except Exception as e:  # noqa: BLE001
        return f"output bag unreadable: {e}"
    return ""


def setup(name, workdir):
    p = Path(workdir) / name
    if not p.exists():
        os.mkfifo(p)


# ----------------------------------------------------------------------------------------


def generate(repo, root, rng, quick=False, only=()):
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    cases = Cases(root)
    want = lambda c: not only or c in only  # noqa: E731
    if want("voxelgrid"):
        gen_voxelgrid(cases, repo, rng)
    if want("launch"):
        gen_launch(cases, repo, rng, mutated=10 if quick else 150)
    if want("sampler"):
        gen_sampler(cases, repo, rng, mutated=5 if quick else 100)
    if want("poses"):
        gen_poses(cases, repo, rng)
    # The damaged bundled bags last: the most numerous and the least varied, so that a
    # partial run (--limit, or stopped and --resume'd) covers every other category first.
    if want("bag-damage"):
        gen_bag_damage(cases, repo, rng, per_form=2 if quick else 80)
    items = cases.items
    if quick:
        # About 100 cases: every bag-damage case generated, a spread of the others.
        picked = [c for c in items if c["category"] == "bag-damage"]
        rest = [c for c in items if c["category"] != "bag-damage"]
        step = max(1, len(rest) // max(1, 100 - len(picked)))
        picked += rest[::step]
        items = picked
    (root / "cases.json").write_text(json.dumps(
        [{k: c[k] for k in ("id", "category", "kind", "runs", "expect")} | {"what": c.get("what")}
         for c in items], indent=1, default=str))
    return items
