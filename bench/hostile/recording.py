"""The "never lose a user's recording" categories of the hostile-input campaign: outputs that
must not destroy inputs or other bags, disk bombs, signals, hangs, silent wrong answers,
unclear errors, SQLite WAL files and symbolic links.

Unlike the other categories, a case here is run by `run_case` (called by campaign.py): its
inputs are built at run time from a spec (deterministic from `--seed` and the case id), each
run gets its own TMPDIR, a watcher samples the temporary bytes every 20 ms, runs can be sent
a signal, files that must survive are snapshotted before each run and compared after, and
big files are deleted once the case is judged. See bench/hostile/README.md for the classes.
"""

import hashlib
import json
import os
import random
import re
import resource
import shutil
import signal
import sqlite3
import stat
import struct
import subprocess
import threading
import time
from pathlib import Path

from mcap.reader import make_reader

import gen

CATEGORIES = ["outputs", "bombs", "signals", "hangs", "silent", "errors", "wal", "links"]
GiB = 1 << 30
MiB = 1 << 20
SLOW_S = 10.0  # an accepted input must be answered within this
BOMB_BYTES = 40 * GiB  # what a bomb decompresses to
WATCH_S = 0.02
FREE_RESERVE = 3 * GiB  # a run is killed if the disk gets this close to full
NOBODY = 65534
DISK_SLACK = 16 * MiB  # over the cap that still passes (a writer stops at cap + 1 byte)

FOUR = "four-spheres-32-bits.mcap"
MT = "machine-tool-32-bits.mcap"
CS = "carving-session.mcap"


# ----------------------------------------------------------------------------------------
# Matchers: what a message or a report must say. Tolerant of wording; one place to adjust.
# ----------------------------------------------------------------------------------------

SAYS = {
    # The metadata.yaml disagrees with the storage files.
    "metadata_disagrees": re.compile(
        r"metadata(\.yaml)?\W.{0,160}?\b(disagree|differ|mismatch|does ?n[o']t match|"
        r"inconsisten|not listed|unlisted|lists? only|says|claims|expected|declares?|"
        r"but (the )?(files?|bag|storage)|count)"
        r"|\b(disagree|differ|mismatch|inconsisten)\w*.{0,160}?metadata", re.I | re.S),
    # The bag's integrity could not be checked (no checksum in the format or the file).
    "integrity_unverified": re.compile(
        r"not (been )?verified|unverifi|(cannot|could not|couldn't|can't|can ?not) be "
        r"(verified|checked)|no (checksums?|crcs?)\b|without (a |any )?(checksums?|crcs?)|"
        r"crcs? (is |are |of )?(0|zero|absent|missing)|unchecked|integrity", re.I),
    # A symbolic link (or where it points) is named.
    "link": re.compile(r"symlink|symbolic|\blink(s|ed)?\b|points? (to|outside)|resolves? to|"
                       r"\b(outside|not inside|leaves?|escapes?)\b.{0,40}"
                       r"\b(bag|directory|folder)", re.I),
}


def report_mentions(obj, key_re, text_re):
    """Whether a JSON value has a key matching key_re, or a string matching text_re."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            if key_re and key_re.search(str(k)):
                return True
            if report_mentions(v, key_re, text_re):
                return True
    elif isinstance(obj, list):
        return any(report_mentions(v, key_re, text_re) for v in obj)
    elif isinstance(obj, str):
        return bool(text_re.search(obj))
    return False


def says(what, console, report, extra_words=()):
    """(console_says, report_says) for one of SAYS' statements. A report says it by a string
    matching it, or (integrity) by a key such as `integrity`/`verified`/`checksum`.
    `extra_words`: strings that count as saying it too (a path the link points to, the
    metadata's message count next to the word metadata)."""
    rx = SAYS[what]
    c = bool(rx.search(console)) or any(w and w in console for w in extra_words)
    r = False
    if report is not None:
        r = report_mentions(report, None, rx) or any(
            w and w in json.dumps(report) for w in extra_words)
        if what == "integrity_unverified" and isinstance(report, dict):
            # A field of its own: `integrity` at the top, or integrity/checksum/CRC/verified
            # fields of the report's `input` (not the checker's `verified_clear`).
            r = r or any(re.search(r"integrity", str(k), re.I) for k in report) or \
                report_mentions(report.get("input"),
                                re.compile(r"integrity|checksum|crc|verif", re.I), rx)
    return c, r


# ----------------------------------------------------------------------------------------
# Building inputs.
# ----------------------------------------------------------------------------------------


def zstd_bomb(prefix, total, declare=True, frames=1, window_log=17):
    """A zstd stream of `frames` frames decompressing to `total` bytes: `prefix` then zeros,
    built by hand from RLE blocks (4 bytes per 128 KiB), so tens of GiB take ~1 MB and no
    time. declare: True (each frame's content size in its header), None (no content size),
    or an int (the size every frame claims, whatever it holds)."""
    blk = 1 << 17
    per = total // frames
    out = bytearray()

    def hdr(last, typ, size):
        return struct.pack("<I", last | (typ << 1) | (size << 3))[:3]

    for k in range(frames):
        size = per if k < frames - 1 else total - per * (frames - 1)
        head = prefix if k == 0 else b""
        out += b"\x28\xb5\x2f\xfd"
        if declare is None:
            out.append(0)
        else:
            out.append(3 << 6)
        out.append((window_log - 10) << 3)
        if declare is not None:
            out += struct.pack("<Q", size if declare is True else declare)
        rest = size - len(head)
        nfull, tail = divmod(rest, blk)
        if head or not rest:
            out += hdr(0 if rest else 1, 0, len(head)) + head
        if nfull:
            out += (hdr(0, 1, blk) + b"\0") * (nfull - (0 if tail else 1))
            if not tail:
                out += hdr(1, 1, blk) + b"\0"
        if tail:
            out += hdr(1, 1, tail) + b"\0"
    return bytes(out)


MCAP_HEAD = b"\x89MCAP0\r\n" + bytes([0x01]) + struct.pack("<Q", 4 + 4 + 4 + 16) + \
    struct.pack("<I", 4) + b"ros2" + struct.pack("<I", 16) + b"hostile-campaign"
SQLITE_HEAD = b"SQLite format 3\x00"


def split_bag(bag, n):
    """The bag's messages cut into n consecutive runs, each a bag with every channel."""
    profile, schemas, channels, msgs = bag
    per = -(-len(msgs) // n)
    return [(profile, schemas, channels, msgs[k * per:(k + 1) * per]) for k in range(n)]


def topic_counts(bag):
    _, schemas, channels, msgs = bag
    counts = {}
    for ch, *_ in msgs:
        t = channels[ch][0]
        counts[t] = counts.get(t, 0) + 1
    types = {c[0]: schemas.get(c[2], ("",))[0] for c in channels.values()}
    return [(t, types[t], n) for t, n in sorted(counts.items())]


def metadata_yaml(files, topics, count=None, storage="mcap", version=9, mode="",
                  fmt="", start=1_700_000_000_000_000_000, duration=1_000_000_000,
                  version_text=None, paths_text=None, extra=""):
    """A rosbag2 metadata.yaml as rosbag2 writes it (block style)."""
    count = sum(n for _, _, n in topics) if count is None else count
    y = ["rosbag2_bagfile_information:",
         f"  version: {version if version_text is None else version_text}",
         f"  storage_identifier: {storage}",
         "  duration:", f"    nanoseconds: {duration}",
         "  starting_time:", f"    nanoseconds_since_epoch: {start}",
         f"  message_count: {count}"]
    if topics:
        y.append("  topics_with_message_count:")
        for name, typ, n in topics:
            y += ["    - topic_metadata:", f"        name: {name}", f"        type: {typ}",
                  "        serialization_format: cdr", '        offered_qos_profiles: ""',
                  f"      message_count: {n}"]
    else:
        y.append("  topics_with_message_count: []")
    y += [f'  compression_format: "{fmt}"', f'  compression_mode: "{mode}"']
    if paths_text is not None:
        y.append(f"  relative_file_paths: {paths_text}")
    else:
        y.append("  relative_file_paths:")
        y += [f"    - {f}" for f in files]
    y.append("  files: []")
    y.append(extra.rstrip("\n")) if extra else None
    return "\n".join(y) + "\n"


def write_db3(path, bag, wal=False, compress=False, wal_pending=False):
    """A rosbag2 SQLite file (Humble's tables). wal: journal_mode=WAL. wal_pending: the
    second half of the messages left in the `-wal` file, as a killed recorder leaves it
    (the main file and its -wal are copied while the writer is still open)."""
    import zstandard
    _, schemas, channels, msgs = bag
    path = Path(path)
    work = path.parent / f"_build-{path.name}"
    for p in (work, Path(f"{work}-wal"), Path(f"{work}-shm")):
        if p.exists():
            p.unlink()
    con = sqlite3.connect(work)
    if wal:
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("PRAGMA wal_autocheckpoint=0")
    con.executescript(
        "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);"
        "INSERT INTO schema VALUES (3, 'humble');"
        "CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,"
        " metadata TEXT NOT NULL);"
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,"
        " serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,"
        " timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
        "CREATE INDEX timestamp_idx ON messages (timestamp ASC);")
    for k, (topic, _enc, sid, _meta) in sorted(channels.items()):
        con.execute("INSERT INTO topics VALUES (?, ?, ?, 'cdr', '')",
                    (k, topic, schemas[sid][0]))
    half = len(msgs) // 2 if wal_pending else len(msgs)

    def insert(rows):
        for ch, log, _pub, _seq, data in rows:
            data = zstandard.ZstdCompressor().compress(data) if compress else data
            con.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)",
                        (ch, log, data))
        con.commit()

    insert(msgs[:half])
    if wal_pending:
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        insert(msgs[half:])
        shutil.copyfile(work, path)
        shutil.copyfile(f"{work}-wal", f"{path}-wal")
        con.close()
        for p in (work, Path(f"{work}-wal"), Path(f"{work}-shm")):
            if p.exists():
                p.unlink()
        return
    if wal:
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    con.close()
    os.replace(work, path)
    for p in (Path(f"{work}-wal"), Path(f"{work}-shm")):
        if p.exists():
            p.unlink()


def immutable_count(path):
    """Messages Python's sqlite3 reads with `immutable=1` (no -wal/-shm read or made)."""
    try:
        con = sqlite3.connect(f"file:{path}?immutable=1", uri=True)
        n = con.execute("SELECT count(*) FROM messages").fetchone()[0]
        con.close()
        return n
    except sqlite3.Error:
        return 0


def flip_db3_blob(path, rng):
    """Flips one bit in the occupancy bytes of one VoxelGrid message (it still decodes)."""
    con = sqlite3.connect(path)
    rows = con.execute("SELECT m.id, length(m.data) FROM messages m JOIN topics t "
                       "ON m.topic_id = t.id WHERE t.type = ?", (gen.VOXEL,)).fetchall()
    mid, n = rows[rng.randrange(len(rows))]
    data = bytearray(con.execute("SELECT data FROM messages WHERE id = ?",
                                 (mid,)).fetchone()[0])
    i = n - 1 - rng.randrange(min(n // 2, 2048))
    data[i] ^= 1 << rng.randrange(8)
    con.execute("UPDATE messages SET data = ? WHERE id = ?", (bytes(data), mid))
    con.commit()
    con.close()
    return f"message {mid} byte {i}"


def flip_in_message(path, bag, rng):
    """Flips one bit in the last bytes (occupancy) of one VoxelGrid message in an MCAP file
    whose messages are stored uncompressed."""
    data = bytearray(Path(path).read_bytes())
    vox = [m for m in bag[3] if bag[1].get(bag[2][m[0]][2], ("",))[0] == gen.VOXEL]
    m = vox[rng.randrange(len(vox))]
    at = bytes(data).find(m[4])
    assert at >= 0, "message not stored uncompressed"
    i = at + len(m[4]) - 1 - rng.randrange(min(len(m[4]) // 2, 2048))
    data[i] ^= 1 << rng.randrange(8)
    Path(path).write_bytes(bytes(data))
    return f"byte {i}"


def write_rosbags_mcap(dst, bag):
    """An MCAP file as PyPI rosbags' rosbag2 writer makes it: uncompressed chunks whose CRC
    is 0 (not checked)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    _, schemas, channels, msgs = bag
    tmp = Path(dst).parent / f"_rosbags-{Path(dst).stem}"
    if tmp.exists():
        shutil.rmtree(tmp)
    w = Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP)
    w.open()
    conns = {}
    for k, (topic, _enc, sid, _meta) in sorted(channels.items()):
        name, _senc, text = schemas[sid]
        conns[k] = w.add_connection(topic, name, msgdef=text.decode(),
                                    rihs01="RIHS01_" + "0" * 64)
    for ch, log, _pub, _seq, data in msgs:
        w.write(conns[ch], log, data)
    w.close()
    [f] = [p for p in tmp.iterdir() if p.suffix == ".mcap"]
    shutil.move(str(f), dst)
    shutil.rmtree(tmp)


def pose_bag(repo, stamp):
    """A one-message bag on /haptic/pose (a topic no default node reads)."""
    schema = (gen.POSE, "ros2msg", gen.schema_text(repo, gen.POSE))
    return ("ros2", {1: schema}, {1: ("/haptic/pose", "cdr", 1, {})},
            [(1, stamp, stamp, 0, gen.cdr.pose_stamped(stamp, [0, 0, 0], [0, 0, 0, 1]))])


def rosbag2_dir(d, bag, n=1, storage="mcap", **meta):
    """A rosbag2 directory `d` holding `bag` in n split files, with its metadata.yaml."""
    d = Path(d)
    d.mkdir(parents=True, exist_ok=True)
    names = []
    for k, part in enumerate(split_bag(bag, n)):
        name = f"{d.name}_{k}.{'mcap' if storage == 'mcap' else 'db3'}"
        if storage == "mcap":
            gen.write_bag(d / name, part, "zstd")
        else:
            write_db3(d / name, part)
        names.append(name)
    (d / "metadata.yaml").write_text(metadata_yaml(
        meta.pop("files", names), meta.pop("topics", topic_counts(bag)), storage=storage,
        **meta))
    return names


# ----------------------------------------------------------------------------------------
# Shared artefacts (made once per campaign output directory, with the binary under test).
# ----------------------------------------------------------------------------------------

_shared_lock = threading.Lock()


def shared(ctx, name):
    """Path of a shared artefact, made on first use: `replayed.mcap` (an output bag of
    `replay` with the machine-tool config: markers for `render`), `mt64.mcap.zstd` (the
    64^3 machine-tool scene, 192 frames, compressed as a whole: a replay of ~3 s)."""
    sd = Path(ctx["shared"])
    p = sd / name
    with _shared_lock:
        if p.exists():
            return p
        sd.mkdir(parents=True, exist_ok=True)
        repo, b = Path(ctx["repo"]), ctx["binary"]
        if name == "replayed.mcap":
            subprocess.run([b, "replay", str(repo / "bags" / MT), "--launch",
                            str(repo / "launch_configs/machine_tool.yaml"),
                            "--out", str(sd / "_replayed.mcap")], cwd=sd, check=True,
                           capture_output=True, timeout=300)
            os.replace(sd / "_replayed.mcap", p)
        elif name == "mt64.mcap.zstd":
            import zstandard
            subprocess.run([b, "scene", "machine-tool", "--grid", "64", "--frames", "192",
                            "--out", str(sd / "_mt64.mcap")], cwd=sd, check=True,
                           capture_output=True, timeout=300)
            data = (sd / "_mt64.mcap").read_bytes()
            (sd / "_mt64.zst").write_bytes(zstandard.ZstdCompressor(level=3).compress(data))
            (sd / "_mt64.mcap").unlink()
            os.replace(sd / "_mt64.zst", p)
        else:
            raise KeyError(name)
    return p


# ----------------------------------------------------------------------------------------
# Case specs.
# ----------------------------------------------------------------------------------------


class Specs:
    def __init__(self, root, quick, limits=None):
        self.root = Path(root)
        self.quick = quick
        self.items = []
        self.limits = limits or {}

    def add(self, category, kind, build, runs, what, quick=False, **kw):
        n = sum(1 for c in self.items if c["category"] == category)
        cid = f"{category}-{kind}-{n:04d}"
        case = {"id": cid, "category": category, "kind": kind, "dir": str(self.root / cid),
                "build": build, "runs": runs, "what": what, "expect": kw.pop("expect", {}),
                "quick": quick}
        case.update(kw)
        self.items.append(case)
        return case


def R(name, *argv, **kw):
    """One run: name, argv ("BIN" for the binary, paths relative to the case directory)."""
    return dict(name=name, argv=["BIN", *argv], **kw)


def gen_outputs(s):
    c = "outputs"
    four = {"fn": "copy", "files": {"in.mcap": ("bag", FOUR)}}
    s.add(c, "replay-out-is-input", four, [R("replay", "replay", "in.mcap", "--out", "in.mcap")],
          "replay in.mcap --out in.mcap", quick=True)
    s.add(c, "replay-report-is-input", four,
          [R("replay", "replay", "in.mcap", "--report", "in.mcap")],
          "replay in.mcap --report in.mcap", quick=True)
    s.add(c, "replay-out-is-input-metadata", {"fn": "rec", "name": "rec"},
          [R("replay", "replay", "rec/metadata.yaml", "--out", "rec/rec_0.mcap")],
          "replay rec/metadata.yaml --out rec/rec_0.mcap (the directory's own split file)")
    s.add(c, "render-out-is-input", {"fn": "copy", "files": {"o.mcap": ("shared", "replayed.mcap")}},
          [R("render", "render", "o.mcap", "--out", "o.mcap")],
          "render o.mcap --out o.mcap (o.mcap an output bag of replay)", quick=True)
    s.add(c, "report-is-out-new", four,
          [R("replay", "replay", "in.mcap", "--report", "x", "--out", "x")],
          "replay in.mcap --report x --out x (x new): one of the two outputs is lost")
    s.add(c, "report-is-out-user-bag",
          {"fn": "copy", "files": {"in.mcap": ("bag", FOUR), "x.mcap": ("bag", MT)}},
          [R("replay", "replay", "in.mcap", "--report", "x.mcap", "--out", "x.mcap")],
          "replay in.mcap --report x.mcap --out x.mcap, x.mcap an existing recording")
    for slash in ("/", ""):
        nm = "slash" if slash else "noslash"
        s.add(c, f"out-is-input-dir-{nm}", {"fn": "rec", "name": "rec"},
              [R("replay", "replay", "rec", "--out", "rec" + slash)],
              f"replay rec --out rec{slash} (rec an existing rosbag2 directory, the input)",
              quick=True)
        s.add(c, f"out-is-input-dir-db3-{nm}", {"fn": "rec", "name": "rec",
                                                "storage": "sqlite3"},
              [R("replay", "replay", "rec", "--out", "rec" + slash)],
              f"replay rec --out rec{slash} (rec an existing rosbag2 directory of .db3 files, "
              "the input)")
        s.add(c, f"out-into-other-rosbag2-dir-{nm}",
              {"fn": "rec", "name": "other", "input": FOUR, "bag": MT},
              [R("replay", "replay", "in.mcap", "--out", "other" + slash)],
              f"replay in.mcap --out other{slash} (other an existing rosbag2 directory)")
    s.add(c, "out-into-other-rosbag2-dir-db3",
          {"fn": "rec", "name": "other", "input": FOUR, "bag": MT, "storage": "sqlite3"},
          [R("replay", "replay", "in.mcap", "--out", "other/")],
          "replay in.mcap --out other/ (other an existing rosbag2 directory of .db3 files)")
    s.add(c, "out-hardlink-to-input", {"fn": "copy", "files": {"in.mcap": ("bag", FOUR)},
                                       "hardlink": {"hl.mcap": "in.mcap"}},
          [R("replay", "replay", "in.mcap", "--out", "hl.mcap")],
          "replay in.mcap --out hl.mcap, hl.mcap a hard link to in.mcap", quick=True)
    s.add(c, "out-symlink-to-input", {"fn": "copy", "files": {"in.mcap": ("bag", FOUR)},
                                      "symlink": {"sl.mcap": "in.mcap"}},
          [R("replay", "replay", "in.mcap", "--out", "sl.mcap")],
          "replay in.mcap --out sl.mcap, sl.mcap a symbolic link to in.mcap", quick=True)
    s.add(c, "out-symlink-to-input-dir", {"fn": "rec", "name": "rec",
                                          "symlink": {"view": "rec"}},
          [R("replay", "replay", "rec", "--out", "view/")],
          "replay rec --out view/, view a symbolic link to the input directory rec")
    # A symbolic link planted at the output path, to a file outside the output directory.
    victim = {"outside/victim.txt": "a file that is not the output\n"}
    for argv, name, kind, q in [
            (["replay", "in.mcap", "--out", "out/o.mcap"], "out/o.mcap", "replay-out", True),
            (["replay", "in.mcap", "--report", "out/r.json"], "out/r.json", "replay-report",
             False),
            (["check", "in.mcap", "--report", "out/r.json"], "out/r.json", "check-report", False),
            (["scene", "four-spheres", "--out", "out/o.mcap"], "out/o.mcap", "scene-out", False),
            (["render", "in.mcap", "--out", "out/p.png"], "out/p.png", "render-out", False)]:
        src = ("shared", "replayed.mcap") if kind == "render-out" else ("bag", FOUR)
        for ow in ([], ["--overwrite"]):
            s.add(c, f"planted-link-at-{kind}{'-overwrite' if ow else ''}",
                  {"fn": "copy", "files": {"in.mcap": src}, "text": victim,
                   "symlink": {name: "../outside/victim.txt"}, "mkdir": ["out"]},
                  [R(kind.split("-")[0], *argv, *ow)],
                  f"{' '.join(argv + ow)}, {name} a planted link to outside/victim.txt",
                  protect_always=["outside/victim.txt"], quick=q and not ow)
    # Links planted at names a writer might use for its temporary file.
    temp_names = lambda base: [f".{base}.tmp", f"{base}.tmp", f".{base}.part",  # noqa: E731
                               f"{base}.part", f".{base}.partial", f"{base}~",
                               f".{base}.swp", f".{base}.new", f"{base}.new"]
    for kind, argv, names in [
            ("replay-file", ["replay", "in.mcap", "--out", "out/o.mcap", "--report",
                             "out/r.json"],
             [f"out/{n}" for n in temp_names("o.mcap") + temp_names("r.json")]),
            ("replay-dir", ["replay", "in.mcap", "--out", "out/rec/"],
             [f"out/rec/{n}" for n in temp_names("metadata.yaml") + temp_names("rec_0.mcap")]
             + [f"out/{n}" for n in temp_names("rec")]),
            ("scene-file", ["scene", "four-spheres", "--out", "out/o.mcap"],
             [f"out/{n}" for n in temp_names("o.mcap")])]:
        links = {n: f"{'../' * (n.count('/'))}outside/v{i}.txt" for i, n in enumerate(names)}
        texts = {f"outside/v{i}.txt": f"victim {i}\n" for i in range(len(names))}
        s.add(c, f"planted-links-at-temp-names-{kind}",
              {"fn": "copy", "files": {"in.mcap": ("bag", FOUR)}, "text": texts,
               "symlink": links, "mkdir": ["out", "out/rec"] if "dir" in kind else ["out"]},
              [R(argv[0], *argv)],
              f"{' '.join(argv)}, with links to files outside planted at {len(names)} likely "
              "temporary names", protect_always=list(texts), quick=kind == "replay-dir")
    s.add(c, "mesh-stats-is-input", four, [R("mesh", "mesh", "in.mcap", "--stats", "in.mcap")],
          "mesh in.mcap --stats in.mcap", quick=True)
    s.add(c, "check-report-is-input", four,
          [R("check", "check", "in.mcap", "--report", "in.mcap")],
          "check in.mcap --report in.mcap", quick=True)
    s.add(c, "check-report-is-input-dir", {"fn": "rec", "name": "rec"},
          [R("check", "check", "rec", "--report", "rec/metadata.yaml")],
          "check rec --report rec/metadata.yaml")
    user = {"fn": "copy", "files": {"in.mcap": ("bag", FOUR), "rec.mcap": ("bag", CS)}}
    s.add(c, "scene-out-existing-recording", user,
          [R("scene", "scene", "four-spheres", "--out", "rec.mcap")],
          "scene four-spheres --out rec.mcap (a recording not written by scene)", quick=True)
    s.add(c, "replay-out-existing-recording", user,
          [R("replay", "replay", "in.mcap", "--out", "rec.mcap")],
          "replay in.mcap --out rec.mcap (a recording not written by replay)")
    s.add(c, "sample-out-existing-recording",
          {"fn": "copy", "files": {"rec.mcap": ("bag", CS), "scene.yaml": ("scene", None)}},
          [R("sample", "sample", "scene.yaml", "--out", "rec.mcap", "--samples", "200")],
          "sample scene.yaml --out rec.mcap (an existing recording)")
    s.add(c, "replay-out-existing-db3",
          {"fn": "copy", "files": {"in.mcap": ("bag", FOUR)}, "db3": {"rec.db3": MT}},
          [R("replay", "replay", "in.mcap", "--out", "rec.db3")],
          "replay in.mcap --out rec.db3 (an existing SQLite recording)")
    s.add(c, "sample-out-is-scene", {"fn": "copy", "files": {"scene.yaml": ("scene", None)}},
          [R("sample", "sample", "scene.yaml", "--out", "scene.yaml", "--samples", "200")],
          "sample scene.yaml --out scene.yaml", quick=True)
    s.add(c, "launch-summary-is-config", {"fn": "copy", "files": {
        "cfg.yaml": ("repo", "launch_configs/machine_tool.yaml")}, "needs_dds": True},
          [R("launch", "launch", "cfg.yaml", "--summary", "cfg.yaml", "--duration", "1")],
          "launch cfg.yaml --summary cfg.yaml --duration 1 (skipped if DDS is unavailable)")
    # --overwrite on an existing bag that is not an input: the new output, complete.
    for argv, what in [(["replay", "in.mcap", "--out", "rec.mcap", "--overwrite"],
                        "replay in.mcap --out rec.mcap --overwrite"),
                       (["scene", "four-spheres", "--out", "rec.mcap", "--overwrite"],
                        "scene four-spheres --out rec.mcap --overwrite"),
                       (["replay", "in.mcap", "--report", "r.json", "--out", "other/",
                         "--overwrite"], "replay in.mcap --out other/ --overwrite (other an "
                        "existing rosbag2 directory)")]:
        build = dict(user) if "other/" not in argv else \
            {"fn": "rec", "name": "other", "input": FOUR, "bag": CS}
        s.add(c, f"overwrite-{argv[0]}-{'dir' if 'other/' in argv else 'file'}", build,
              [R(argv[0], *argv)], what + ": expected exit 0 and a complete new bag",
              expect={"must_succeed": True}, quick=argv[0] == "replay" and "rec.mcap" in argv)
    # A bag replay wrote is replaced by the next replay without --overwrite.
    s.add(c, "replay-out-replaces-own-output",
          {"fn": "copy", "files": {"in.mcap": ("bag", FOUR)},
           "prerun": [["replay", "in.mcap", "--out", "o.mcap"]]},
          [R("replay", "replay", "in.mcap", "--out", "o.mcap")],
          "replay in.mcap --out o.mcap, o.mcap written by the same command before: replaced",
          replaceable=["o.mcap"], expect={"must_succeed": True})
    readme = ["replay", "bags/machine-tool-32-bits.mcap", "--launch",
              "launch_configs/machine_tool.yaml", "--report", "out/report.json", "--out",
              "out/replay.mcap"]
    s.add(c, "readme-command-twice", {"fn": "copy", "files": {
        f"bags/{MT}": ("bag", MT),
        "launch_configs/machine_tool.yaml": ("repo", "launch_configs/machine_tool.yaml")}},
          [R("first", *readme), R("second", *readme)],
          "the README's main command, run twice", replaceable=["out/replay.mcap"],
          expect={"must_succeed": True}, quick=True)


def gen_bombs(s):
    c = "bombs"
    for kind, build, q in [
            ("mcap-zstd-declared", {"name": "bomb.mcap.zstd", "declare": True}, True),
            ("mcap-zstd-undeclared", {"name": "bomb.mcap.zstd", "declare": None}, False),
            ("mcap-zstd-1024-frames", {"name": "bomb.mcap.zstd", "declare": True,
                                       "frames": 1024}, False),
            ("zstd-magic-named-mcap", {"name": "bomb.mcap", "declare": True}, False),
            ("db3-zstd-declared", {"name": "bomb.db3.zstd", "declare": True,
                                   "prefix": "sqlite"}, False),
            ("rosbag2-file-compression", {"name": "rec/rec_0.mcap.zstd", "declare": True,
                                          "dir": True}, True),
            ("declares-1-PiB-holds-1-MiB", {"name": "bomb.mcap.zstd", "declare": 1 << 50,
                                            "total": MiB}, False),
            ("declares-1-MiB-holds-40-GiB", {"name": "bomb.mcap.zstd", "declare": MiB},
             False)]:
        bag = "rec" if build.get("dir") else build["name"]
        build = {"fn": "bomb", **build}
        s.add(c, kind, build, [
            R("info", "info", bag, watch=True),
            R("check", "check", bag, "--report", "out/check.json", watch=True),
            R("replay", "replay", bag, "--report", "out/replay.json", "--out", "out/o.mcap",
              watch=True)],
            f"{build['name']}: {build.get('total', BOMB_BYTES) >> 20} MiB of zeros after a "
            f"{'SQLite' if build.get('prefix') else 'MCAP'} header, content size "
            f"{'declared' if build['declare'] is True else build['declare']}, "
            f"{build.get('frames', 1)} frame(s)", big=[build["name"]], quick=q)


def gen_signals(s):
    c = "signals"
    variants = [
        ("replay-new-out", {"fn": "copy", "files": {"in.mcap.zstd": ("shared",
                                                                     "mt64.mcap.zstd")},
                            "mkdir": ["out"]},
         ["replay", "in.mcap.zstd", "--report", "out/r.json", "--out", "out/o.mcap"], {}),
        ("replay-existing-out", {"fn": "copy", "files": {
            "in.mcap.zstd": ("shared", "mt64.mcap.zstd"),
            "out/o.mcap": ("shared", "replayed.mcap")}},
         ["replay", "in.mcap.zstd", "--report", "out/r.json", "--out", "out/o.mcap"],
         {"replaceable": ["out/o.mcap"]}),
        ("replay-dir-out", {"fn": "copy", "files": {"in.mcap.zstd": ("shared",
                                                                     "mt64.mcap.zstd")},
                            "mkdir": ["out"]},
         ["replay", "in.mcap.zstd", "--report", "out/r.json", "--out", "out/rec/"], {}),
        ("info-bomb", {"fn": "bomb", "name": "bomb.mcap.zstd", "declare": True},
         ["info", "bomb.mcap.zstd"], {"big": ["bomb.mcap.zstd"]}),
    ]
    for kind, build, argv, kw in variants:
        for sig in ("SIGINT", "SIGTERM", "SIGKILL"):
            for at in (0.3, 1.0, 2.0):
                s.add(c, f"{kind}-{sig}-{at}s", build,
                      [R(argv[0], *argv, watch=True, signal=[sig, at])],
                      f"{' '.join(argv)}; {sig} at {at} s", quick=at == 1.0 and (
                          sig == "SIGKILL" or kind == "replay-new-out"), **kw)


def gen_hangs(s):
    c = "hangs"
    runs = lambda bag: [R("info", "info", bag), R("replay", "replay", bag, "--report",  # noqa
                                                  "out/r.json")]
    for kb in (52, 102, 202, 402):
        s.add(c, f"metadata-nested-brackets-{kb}k", {"fn": "hang", "what": "brackets", "kb": kb},
              runs("rec"), f"metadata.yaml with {kb} kB of nested brackets",
              quick=kb == 402, timeout=30)
        s.add(c, f"metadata-nested-mappings-{kb}k", {"fn": "hang", "what": "mappings", "kb": kb},
              runs("rec"), f"metadata.yaml with {kb} kB of nested mappings inside "
              "rosbag2_bagfile_information", timeout=30)
    for n in (20_000, 100_000):
        for exist in (True, False):
            s.add(c, f"split-files-{n}-{'present' if exist else 'missing'}",
                  {"fn": "hang", "what": "splits", "n": n, "exist": exist}, runs("rec"),
                  f"metadata.yaml listing {n} split files "
                  f"({'tiny valid MCAP files' if exist else 'all but the first missing'})",
                  quick=n == 20_000 and exist, timeout=60, big=["rec"])
    # At the documented maxima (docs/limits.md, read at campaign time): must be answered
    # within 10 s if accepted.
    n = s.limits.get("MAX_SPLIT_FILES")
    if n and n not in (20_000, 100_000):
        s.add(c, f"split-files-{n}-present-documented-max",
              {"fn": "hang", "what": "splits", "n": n, "exist": True}, runs("rec"),
              f"metadata.yaml listing {n} split files (MAX_SPLIT_FILES as docs/limits.md "
              "documents it; tiny valid MCAP files)", quick=True, timeout=60, big=["rec"])
    mb = s.limits.get("MAX_METADATA_BYTES") or 16 * MiB
    s.add(c, f"metadata-{mb >> 20}-MiB-documented-max", {"fn": "hang", "what": "maxmeta",
                                                         "bytes": mb}, runs("rec"),
          f"metadata.yaml of {mb >> 20} MiB less 4 KiB (MAX_METADATA_BYTES as docs/limits.md "
          "documents it), padded with topics", timeout=60)
    for kind, what in [("fifo-as-bag", "a FIFO given as the bag (fifo.mcap)"),
                       ("fifo-as-split-file", "a FIFO listed as split file rec_1.mcap"),
                       ("fifo-as-metadata", "a FIFO as rec/metadata.yaml (the directory given)"),
                       ("fifo-as-metadata-path", "a FIFO as rec/metadata.yaml, given as the "
                                                 "path"),
                       ("dev-zero-as-split-file", "/dev/zero listed as split file rec_1.mcap "
                                                  "(a symbolic link)"),
                       ("dev-zero-as-bag", "a link zero.mcap -> /dev/zero given as the bag"),
                       ("dev-zero-as-metadata", "rec/metadata.yaml a link to /dev/zero")]:
        bag = {"fifo-as-bag": "fifo.mcap", "dev-zero-as-bag": "zero.mcap",
               "fifo-as-metadata-path": "rec/metadata.yaml"}.get(kind, "rec")
        s.add(c, kind, {"fn": "hang", "what": kind}, runs(bag), what,
              quick=kind in ("fifo-as-bag", "fifo-as-split-file"), timeout=30)


def gen_silent(s):
    c = "silent"
    three = lambda bag: [R("info", "info", bag),  # noqa: E731
                         R("check", "check", bag, "--report", "out/check.json"),
                         R("replay", "replay", bag, "--report", "out/replay.json")]
    for kind, what, q in [
            ("metadata-lists-1-of-2-counts-all", "metadata.yaml lists rec_0.mcap of rec_0 and "
             "rec_1, but counts the messages of both", True),
            ("metadata-counts-double", "metadata.yaml lists both split files and counts every "
             "message twice", False),
            ("metadata-topic-counts-swapped", "metadata.yaml's total is right but two topics' "
             "counts are wrong", False),
            ("metadata-lists-2-of-3-db3", "metadata.yaml (sqlite3) lists 2 of the 3 split "
             "files and counts all", False)]:
        s.add(c, kind, {"fn": "silent", "what": kind}, three("rec"), what, quick=q,
              expect={"must_say": "metadata_disagrees"})
    for kind, bag, what, q in [
            ("db3-bit-flip", "rec.db3", "one bit flipped in a VoxelGrid blob of a .db3 file",
             True),
            ("db3-dir-bit-flip", "rec", "one bit flipped in a VoxelGrid blob of a .db3 split "
             "file", False),
            ("db3-intact", "rec.db3", "an intact .db3 file (SQLite stores no checksum)", False),
            ("rosbags-mcap-crc0-bit-flip", "rec.mcap", "one bit flipped in a message of an "
             "MCAP file written by PyPI rosbags (chunk CRC 0)", True),
            ("rosbags-mcap-crc0-intact", "rec.mcap", "an intact MCAP file written by PyPI "
             "rosbags (chunk CRC 0)", False),
            ("unchunked-mcap-bit-flip", "rec.mcap", "one bit flipped in a message of an "
             "unchunked MCAP file (no CRC)", False)]:
        s.add(c, kind, {"fn": "silent", "what": kind}, three(bag), what, quick=q,
              expect={"must_say": "integrity_unverified"})


# A version that is there but unusable: the message must say what is wrong with it, and must
# not say it is absent (nor hand over the YAML parser's "expected any YAML value").
VERSION_CAUSE = (r"version\b.{0,160}(invalid|not (a|an)\b|must be|out of range|too (large|big|"
                 r"high)|unsupported|not supported|negative|integer|number|string|newer|"
                 r"unknown|exceeds|wrong type)")
VERSION_FALSE = r"has no version|expected any YAML value"


def gen_errors(s):
    c = "errors"
    two = lambda bag: [R("info", "info", bag), R("replay", "replay", bag,  # noqa: E731
                                                 "--report", "out/r.json")]
    cases = [
        ("only-split-file-missing", "rec", ["rec_0.mcap"],
         r"missing|not found|no such file|does ?n[o']t exist|absent|cannot (be )?(open|find)",
         None, "the directory's only split file is missing", False),
        ("compression-mode-bogus", "rec", ["metadata.yaml"], r"compression", None,
         "compression_mode: ZIP in metadata.yaml", False),
        ("compression-message-but-plain", "rec", ["rec_0.mcap", "metadata.yaml", "rec"],
         r"compress|zstd", None, "compression_mode MESSAGE, but the messages are not "
         "compressed", True),
        ("compression-none-but-messages-compressed", "rec", ["rec_0.db3", "metadata.yaml", "rec"],
         r"compress|zstd", None, "compression_mode empty, but each message is a zstd frame",
         True),
        ("all-schemas-refused", "in.mcap", ["in.mcap", "/a/occupancy", "/b/occupancy"],
         r"schema|refused", None, "every VoxelGrid channel has another schema text", False),
        ("all-json-encoding", "in.mcap", ["in.mcap", "/a/occupancy", "/b/occupancy"],
         r"encoding|json|refused", None, "every VoxelGrid channel in message encoding json",
         False),
        ("message-compressed-db3-alone", "rec/rec_0.db3", ["rec_0.db3"],
         r"compress|zstd|metadata", None, "a per-message-compressed .db3 passed on its own, "
         "not its directory", True),
        ("metadata-version-2^64+1", "rec", ["metadata.yaml", "rec"], VERSION_CAUSE,
         VERSION_FALSE, "version: 18446744073709551617", True),
        ("metadata-version-string-9", "rec", ["metadata.yaml", "rec"], VERSION_CAUSE,
         VERSION_FALSE, "version: '9'", True),
        ("metadata-version-minus-1", "rec", ["metadata.yaml", "rec"], VERSION_CAUSE,
         VERSION_FALSE, "version: -1", False),
        ("metadata-version-1.5", "rec", ["metadata.yaml", "rec"], VERSION_CAUSE,
         VERSION_FALSE, "version: 1.5", False),
    ]
    for kind, bag, names, cause, forbid, what, q in cases:
        s.add(c, kind, {"fn": "errors", "what": kind}, two(bag), what, quick=q,
              expect={"names": names, "cause": cause, "forbid": forbid,
                      "say_on_success": kind.startswith(("compression-message",
                                                         "compression-none",
                                                         "message-compressed",
                                                         "all-"))})


def gen_wal(s):
    c = "wal"
    for pending in (False, True):
        for form in ("file", "dir"):
            for ro in (False, True):
                kind = (f"{'wal-pending' if pending else 'wal-checkpointed'}-{form}-"
                        f"{'readonly' if ro else 'writable'}")
                bag = "in/rec_0.db3" if form == "file" else "in"
                s.add(c, kind, {"fn": "wal", "pending": pending, "form": form, "ro": ro},
                      [R("info", "info", bag, "--json", user=ro),
                       R("replay", "replay", bag, "--report", "out/r.json", user=ro)],
                      f"a rosbag2 .db3 in WAL mode{' with its -wal file' if pending else ''}, "
                      f"given as {'the file' if form == 'file' else 'its directory'}, in a "
                      f"{'read-only' if ro else 'writable'} directory",
                      quick=not pending and not ro or pending and ro and form == "file",
                      expect={"no_new_files_in": "in"})


def gen_links(s):
    c = "links"
    two = lambda bag: [R("info", "info", bag), R("replay", "replay", bag,  # noqa: E731
                                                 "--report", "out/r.json")]
    for kind, what, words, q in [
            ("split-file-link-outside", "split file rec_1.mcap a link to ../other/other.mcap "
             "(another recording)", ["other/other.mcap", "other.mcap"], True),
            ("metadata-link-etc-passwd", "rec/metadata.yaml a link to /etc/passwd",
             ["/etc/passwd"], True),
            ("metadata-link-other-bag", "rec/metadata.yaml a link to ../other/metadata.yaml "
             "(another recording's, listing the same file names)", ["other/metadata.yaml"],
             False),
            ("dir-link-outside", "rec/rec_0.mcap a link to a file in ../other/ that is a "
             "recording of other topics, metadata.yaml describing rec's own", ["other/"],
             False)]:
        s.add(c, kind, {"fn": "links", "what": kind}, two("rec"), what, quick=q,
              expect={"must_say": "link", "words": words})
    s.add(c, "split-file-link-inside", {"fn": "links", "what": "split-file-link-inside"},
          two("rec"), "split file rec_1.mcap a link to rec/data/rec_1.mcap inside the "
          "directory (control: nothing to say)")


def generate(root, seed, quick=False, only=(), repo=None):
    s = Specs(root, quick, documented_limits(repo) if repo else {})
    want = lambda c: not only or c in only  # noqa: E731
    for name, fn in [("outputs", gen_outputs), ("bombs", gen_bombs), ("signals", gen_signals),
                     ("hangs", gen_hangs), ("silent", gen_silent), ("errors", gen_errors),
                     ("wal", gen_wal), ("links", gen_links)]:
        if want(name):
            fn(s)
    items = s.items
    for it in items:
        it["seed"] = seed
    if quick:
        items = [c for c in items if c["quick"]]
    return items


# ----------------------------------------------------------------------------------------
# Builders (run at run time, into the case directory).
# ----------------------------------------------------------------------------------------

SCENE = gen.SPHERE_BOX.replace("CENTRE", "[0.65, 0.5, 0.5]").replace("RADIUS", "0.2") \
    .replace("VELOCITY", "[0.6, 0, 0]")


def build(case, ctx):
    d = Path(case["dir"])
    b = case["build"]
    rng = random.Random(f"{case['seed']}-{case['id']}")
    repo = Path(ctx["repo"])
    bags = repo / "bags"
    for p in b.get("mkdir", []):
        (d / p).mkdir(parents=True, exist_ok=True)
    fn = b["fn"]
    if fn in ("copy", "bomb"):
        for dst, (kind, src) in b.get("files", {}).items():
            (d / dst).parent.mkdir(parents=True, exist_ok=True)
            if kind == "bag":
                shutil.copyfile(bags / src, d / dst)
            elif kind == "repo":
                shutil.copyfile(repo / src, d / dst)
            elif kind == "shared":
                shutil.copyfile(shared(ctx, src), d / dst)
            elif kind == "scene":
                (d / dst).write_text(SCENE)
        for dst, src in b.get("db3", {}).items():
            write_db3(d / dst, gen.read_bag(bags / src))
    if fn == "bomb":
        total = b.get("total", BOMB_BYTES)
        prefix = SQLITE_HEAD if b.get("prefix") == "sqlite" else MCAP_HEAD
        p = d / b["name"]
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(zstd_bomb(prefix, total, b["declare"], b.get("frames", 1)))
        if b.get("dir"):
            (d / "rec/metadata.yaml").write_text(metadata_yaml(
                ["rec_0.mcap.zstd"], [("/a/occupancy", gen.VOXEL, 12)], mode="FILE",
                fmt="zstd"))
        (d / "out").mkdir(exist_ok=True)
    elif fn == "rec":
        if "input" in b:
            shutil.copyfile(bags / b["input"], d / "in.mcap")
        rosbag2_dir(d / b["name"], gen.read_bag(bags / b.get("bag", FOUR)), n=2,
                    storage=b.get("storage", "mcap"))
    elif fn == "hang":
        build_hang(d, b, ctx, rng)
    elif fn == "silent":
        build_silent(d, b, rng, case)
    elif fn == "errors":
        build_errors(d, b, bags)
    elif fn == "wal":
        build_wal(d, b, bags, case)
    elif fn == "links":
        build_links(d, b, bags)
    for argv in b.get("prerun", []):
        # Made by the binary under test, as a user would have made it (not judged).
        tmp = d / "tmp-prerun"
        tmp.mkdir(exist_ok=True)
        subprocess.run([ctx["binary"], *argv], cwd=d, capture_output=True, timeout=300,
                       env=dict(os.environ, TMPDIR=str(tmp)))
        shutil.rmtree(tmp, ignore_errors=True)
    for name, text in b.get("text", {}).items():
        (d / name).parent.mkdir(parents=True, exist_ok=True)
        (d / name).write_text(text)
    for name, target in b.get("symlink", {}).items():
        (d / name).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(target, d / name)
    for name, target in b.get("hardlink", {}).items():
        os.link(d / target, d / name)
    (d / "out").mkdir(exist_ok=True)


def build_hang(d, b, ctx, rng):
    w = b["what"]
    rec = d / "rec"
    rec.mkdir(exist_ok=True)
    four = gen.read_bag(Path(ctx["repo"]) / "bags" / FOUR)
    if w in ("brackets", "mappings"):
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        size = b["kb"] * 1000
        if w == "brackets":
            depth = (size - 400) // 2
            meta = metadata_yaml([], topic_counts(four),
                                 paths_text="[" * depth + "rec_0.mcap" + "]" * depth)
        else:
            depth = (size - 400) // 5
            meta = metadata_yaml(["rec_0.mcap"], topic_counts(four),
                                 extra="  custom_data: " + "{a: " * depth + "1" + "}" * depth)
        (rec / "metadata.yaml").write_text(meta)
    elif w == "splits":
        n = b["n"]
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        names = [f"rec_{i}.mcap" for i in range(n)]
        if b["exist"]:
            # Hard links of one tiny file (a new one every 50 000: a file system's link limit).
            tiny = rec / "_pose.mcap"
            for i, nm in enumerate(names[1:]):
                if i % 50_000 == 0:
                    if tiny.exists():
                        tiny.unlink()
                    gen.write_bag(tiny, pose_bag(Path(ctx["repo"]), gen.T0 + 500_000_000),
                                  "unchunked")
                os.link(tiny, rec / nm)
            tiny.unlink()
        topics = topic_counts(four) + [("/haptic/pose", gen.POSE, n - 1 if b["exist"] else 0)]
        (rec / "metadata.yaml").write_text(metadata_yaml(names, topics))
    elif w == "maxmeta":
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        topics = topic_counts(four)
        head = metadata_yaml(["rec_0.mcap"], topics)
        entry = ("    - topic_metadata:\n        name: /pad/t{:06d}\n        type: "
                 "std_msgs/msg/Empty\n        serialization_format: cdr\n"
                 "        offered_qos_profiles: \"\"\n      message_count: 0\n")
        budget = b.get("bytes", 16 * MiB) - 4096 - len(head)
        pads, used, i = [], 0, 0
        while used + len(entry.format(i)) <= budget and i < 10**6:
            e = entry.format(i)
            pads.append(e)
            used += len(e)
            i += 1
        # Insert the padding topics after the real ones.
        marker = "  compression_format:"
        head = head.replace(marker, "".join(pads) + marker, 1)
        (rec / "metadata.yaml").write_text(head)
    elif w.startswith(("fifo", "dev-zero")):
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        names = ["rec_0.mcap", "rec_1.mcap"] if "split" in w else ["rec_0.mcap"]
        meta = metadata_yaml(names, topic_counts(four))
        if w == "fifo-as-bag":
            os.mkfifo(d / "fifo.mcap")
        elif w == "fifo-as-split-file":
            os.mkfifo(rec / "rec_1.mcap")
        elif w in ("fifo-as-metadata", "fifo-as-metadata-path"):
            os.mkfifo(rec / "metadata.yaml")
            meta = None
        elif w == "dev-zero-as-split-file":
            os.symlink("/dev/zero", rec / "rec_1.mcap")
        elif w == "dev-zero-as-bag":
            os.symlink("/dev/zero", d / "zero.mcap")
        elif w == "dev-zero-as-metadata":
            os.symlink("/dev/zero", rec / "metadata.yaml")
            meta = None
        if meta is not None:
            (rec / "metadata.yaml").write_text(meta)


def build_silent(d, b, rng, case):
    w = b["what"]
    bags = Path(__file__).resolve().parents[2] / "bags"
    four = gen.read_bag(bags / FOUR)
    rec = d / "rec"
    if w.startswith("metadata-"):
        rec.mkdir()
        topics = topic_counts(four)
        if w == "metadata-lists-2-of-3-db3":
            parts = split_bag(four, 3)
            names = [f"rec_{k}.db3" for k in range(3)]
            for nm, part in zip(names, parts):
                write_db3(rec / nm, part)
            meta = metadata_yaml(names[:2], topics, storage="sqlite3")
        else:
            parts = split_bag(four, 2)
            names = ["rec_0.mcap", "rec_1.mcap"]
            for nm, part in zip(names, parts):
                gen.write_bag(rec / nm, part, "zstd")
            if w == "metadata-lists-1-of-2-counts-all":
                meta = metadata_yaml(names[:1], topics)
            elif w == "metadata-counts-double":
                meta = metadata_yaml(names, [(t, ty, 2 * n) for t, ty, n in topics])
            else:
                t2 = [list(t) for t in topics]
                t2[0][2] += 5
                t2[1][2] -= 5
                meta = metadata_yaml(names, [tuple(t) for t in t2])
        (rec / "metadata.yaml").write_text(meta)
        case["expect"]["words"] = []
        return
    if w.startswith("db3"):
        if "dir" in w:
            rec.mkdir()
            write_db3(rec / "rec_0.db3", four)
            (rec / "metadata.yaml").write_text(metadata_yaml(["rec_0.db3"], topic_counts(four),
                                                             storage="sqlite3"))
            target = rec / "rec_0.db3"
        else:
            write_db3(d / "rec.db3", four)
            target = d / "rec.db3"
        if "flip" in w:
            case["what"] += f" ({flip_db3_blob(target, rng)})"
        return
    if w.startswith("rosbags"):
        write_rosbags_mcap(d / "rec.mcap", four)
    else:
        gen.write_bag(d / "rec.mcap", four, "unchunked")
    if "flip" in w:
        case["what"] += f" ({flip_in_message(d / 'rec.mcap', four, rng)})"


def build_errors(d, b, bags):
    w = b["what"]
    four = gen.read_bag(bags / FOUR)
    rec = d / "rec"
    topics = topic_counts(four)
    if w == "only-split-file-missing":
        rec.mkdir()
        (rec / "metadata.yaml").write_text(metadata_yaml(["rec_0.mcap"], topics))
    elif w == "compression-mode-bogus":
        rosbag2_dir(rec, four, mode="ZIP", fmt="zstd")
    elif w == "compression-message-but-plain":
        rosbag2_dir(rec, four, mode="MESSAGE", fmt="zstd")
    elif w in ("compression-none-but-messages-compressed", "message-compressed-db3-alone"):
        rec.mkdir()
        write_db3(rec / "rec_0.db3", four, compress=True)
        mode = "MESSAGE" if w == "message-compressed-db3-alone" else ""
        (rec / "metadata.yaml").write_text(metadata_yaml(
            ["rec_0.db3"], topics, storage="sqlite3", mode=mode, fmt="zstd" if mode else ""))
    elif w in ("all-schemas-refused", "all-json-encoding"):
        b2 = gen.base_scene()
        over = {"encoding": "json"} if "json" in w else {"schema": "mismatch"}
        bag = gen.scene_bag(Path(__file__).resolve().parents[2], b2,
                            channel_over={t: over for t in b2})
        gen.write_bag(d / "in.mcap", bag, "zstd")
    elif w.startswith("metadata-version"):
        text = {"metadata-version-2^64+1": "18446744073709551617",
                "metadata-version-string-9": "'9'", "metadata-version-minus-1": "-1",
                "metadata-version-1.5": "1.5"}[w]
        rosbag2_dir(rec, four, version_text=text)


def build_wal(d, b, bags, case):
    four = gen.read_bag(bags / FOUR)
    inn = d / "in"
    inn.mkdir()
    write_db3(inn / "rec_0.db3", four, wal=True, wal_pending=b["pending"])
    if b["form"] == "dir":
        (inn / "metadata.yaml").write_text(metadata_yaml(["rec_0.db3"], topic_counts(four),
                                                         storage="sqlite3"))
    case["expect"]["immutable_messages"] = immutable_count(inn / "rec_0.db3")
    case["expect"]["all_messages"] = len(four[3])


def build_links(d, b, bags):
    w = b["what"]
    four, mt = gen.read_bag(bags / FOUR), gen.read_bag(bags / MT)
    rec, other = d / "rec", d / "other"
    rec.mkdir()
    other.mkdir()
    if w == "split-file-link-outside":
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        gen.write_bag(other / "other.mcap", mt, "zstd")
        os.symlink("../other/other.mcap", rec / "rec_1.mcap")
        (rec / "metadata.yaml").write_text(metadata_yaml(["rec_0.mcap", "rec_1.mcap"],
                                                         topic_counts(four)))
    elif w == "metadata-link-etc-passwd":
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        os.symlink("/etc/passwd", rec / "metadata.yaml")
    elif w == "metadata-link-other-bag":
        gen.write_bag(rec / "rec_0.mcap", four, "zstd")
        gen.write_bag(other / "rec_0.mcap", mt, "zstd")
        (other / "metadata.yaml").write_text(metadata_yaml(["rec_0.mcap"], topic_counts(mt)))
        os.symlink("../other/metadata.yaml", rec / "metadata.yaml")
    elif w == "dir-link-outside":
        gen.write_bag(other / "data.mcap", mt, "zstd")
        os.symlink("../other/data.mcap", rec / "rec_0.mcap")
        (rec / "metadata.yaml").write_text(metadata_yaml(["rec_0.mcap"], topic_counts(four)))
    elif w == "split-file-link-inside":
        parts = split_bag(four, 2)
        gen.write_bag(rec / "rec_0.mcap", parts[0], "zstd")
        (rec / "data").mkdir()
        gen.write_bag(rec / "data/rec_1.mcap", parts[1], "zstd")
        os.symlink("data/rec_1.mcap", rec / "rec_1.mcap")
        (rec / "metadata.yaml").write_text(metadata_yaml(["rec_0.mcap", "rec_1.mcap"],
                                                         topic_counts(four)))


# ----------------------------------------------------------------------------------------
# Watching a run: snapshots, temporary bytes, validity of outputs.
# ----------------------------------------------------------------------------------------

OUT_FLAGS = {"--out", "--report", "--stats", "--summary", "--ply"}


def outputs_of(argv):
    """[(flag, path)] of the run's output arguments."""
    out = []
    for i, a in enumerate(argv[:-1]):
        if a in OUT_FLAGS:
            out.append((a, argv[i + 1]))
    return out


def inputs_of(argv):
    """The positional input (the argument after the subcommand), except for `scene`."""
    if len(argv) > 2 and argv[1] not in ("scene",) and not argv[2].startswith("-"):
        return [argv[2]]
    return []


def is_bag(p):
    """An MCAP or SQLite file (zstd-compressed or not), or a rosbag2 directory."""
    try:
        st = os.lstat(p)
    except OSError:
        return False
    if stat.S_ISLNK(st.st_mode):
        return False
    if stat.S_ISDIR(st.st_mode):
        return (Path(p) / "metadata.yaml").exists() or any(
            gen_storage(x.name) for x in Path(p).iterdir())
    if not stat.S_ISREG(st.st_mode):
        return False
    with open(p, "rb") as f:
        head = f.read(16)
    return head.startswith((b"\x89MCAP", SQLITE_HEAD, b"\x28\xb5\x2f\xfd"))


def gen_storage(name):
    n = name[:-5] if name.endswith(".zstd") else name
    return n.endswith((".mcap", ".db3"))


def snapshot(p):
    """What must not change about a path: for a file its inode and bytes, for a link its
    target, for a directory (recursively) its listing and each entry's snapshot."""
    p = Path(p)
    try:
        st = os.lstat(p)
    except OSError:
        return None
    if stat.S_ISLNK(st.st_mode):
        return ("link", os.readlink(p), st.st_ino)
    if stat.S_ISDIR(st.st_mode):
        return ("dir", st.st_ino, tuple(sorted((x.name, snapshot(x)) for x in p.iterdir())))
    if stat.S_ISREG(st.st_mode):
        h = hashlib.sha256()
        with open(p, "rb") as f:
            for blk in iter(lambda: f.read(1 << 20), b""):
                h.update(blk)
        return ("file", st.st_ino, st.st_size, h.hexdigest())
    return ("other", st.st_mode, st.st_ino)


SIDE_FILES = re.compile(r"-(wal|shm|journal)$")


def without_side_files(snap):
    """A directory snapshot without SQLite's -wal/-shm/-journal files (the `wal` category
    judges those as `created`)."""
    if not snap or snap[0] != "dir":
        return snap
    return ("dir", snap[1], tuple((n, without_side_files(x)) for n, x in snap[2]
                                  if not SIDE_FILES.search(n)))


def describe_change(before, after):
    if after is None:
        return "deleted"
    if before[0] != after[0]:
        return f"a {before[0]} became a {after[0]}"
    if before[0] == "file":
        if before[1] != after[1]:
            return f"replaced by another file ({after[2]} bytes)"
        return f"rewritten ({before[2]} -> {after[2]} bytes)"
    if before[0] == "link":
        return f"link changed ({before[1]} -> {after[1]})"
    if before[0] == "dir":
        b, a = dict(before[2]), dict(after[2])
        added = sorted(set(a) - set(b))
        gone = sorted(set(b) - set(a))
        changed = sorted(k for k in set(a) & set(b) if a[k] != b[k])
        bits = []
        if added:
            bits.append("added " + ", ".join(added[:4]))
        if gone:
            bits.append("removed " + ", ".join(gone[:4]))
        if changed:
            bits.append("changed " + ", ".join(changed[:4]))
        return "; ".join(bits) or "inode changed"
    return "changed"


def complete(kind, p):
    """'' if the output at p is complete, else why not. kind: mcap (file or rosbag2 dir by
    what is there), json, png."""
    p = Path(p)
    try:
        if kind == "mcap":
            if p.is_dir():
                meta = p / "metadata.yaml"
                if not meta.is_file():
                    return "a directory without metadata.yaml"
                m = re.search(r"relative_file_paths:[ \t]*\n((?:[ \t]+-[^\n]*\n?)+)",
                              meta.read_text())
                if not m:
                    return "metadata.yaml lists no split file"
                for f in re.findall(r"-\s*['\"]?([^'\"\n]+?)['\"]?\s*$", m.group(1), re.M):
                    why = complete("mcap", p / Path(f).name)
                    if why:
                        return f"{f}: {why}"
                return ""
            with open(p, "rb") as f:
                data_head = f.read(8)
                if data_head != b"\x89MCAP0\r\n":
                    return f"not an MCAP file (starts {data_head[:8]!r})"
                f.seek(-8, 2)
                if f.read(8) != b"\x89MCAP0\r\n":
                    return "no closing MCAP magic (cut short)"
                f.seek(0)
                if make_reader(f).get_summary() is None:
                    return "no summary"
            return ""
        if kind == "json":
            json.loads(p.read_text())
            return ""
        if kind == "png":
            data = p.read_bytes()
            if not data.startswith(b"\x89PNG\r\n\x1a\n") or b"IEND" not in data[-16:]:
                return "not a complete PNG"
            return ""
    except Exception as e:  # noqa: BLE001
        return f"unreadable: {type(e).__name__}: {str(e)[:100]}"
    return ""


def out_kind(argv, flag, path):
    if flag == "--out" and argv[1] == "render":
        return "png"
    if flag == "--out":
        return "mcap"
    if flag == "--ply":
        return None
    return "json"


def usage(paths, pid, baseline):
    """Bytes written since the run started: files under `paths` (their growth over
    `baseline` {(dev, ino): blocks}) and files the process has open for writing anywhere,
    deleted or not."""
    seen = {}
    for root in paths:
        for dp, dns, fns in os.walk(root):
            for n in fns:
                try:
                    st = os.lstat(os.path.join(dp, n))
                except OSError:
                    continue
                if stat.S_ISREG(st.st_mode):
                    seen[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        fds = []
    for fd in fds:
        try:
            with open(f"/proc/{pid}/fdinfo/{fd}") as f:
                flags = int(re.search(r"flags:\s+([0-7]+)", f.read()).group(1), 8)
            if flags & 3 == 0:
                continue
            st = os.stat(f"/proc/{pid}/fd/{fd}")
        except (OSError, AttributeError):
            continue
        if stat.S_ISREG(st.st_mode):
            seen[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    return sum(max(0, b - baseline.get(k, 0)) for k, b in seen.items())


def blocks_under(paths):
    base = {}
    for root in paths:
        for dp, dns, fns in os.walk(root):
            for n in fns:
                try:
                    st = os.lstat(os.path.join(dp, n))
                except OSError:
                    continue
                if stat.S_ISREG(st.st_mode):
                    base[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    return base


def tree_bytes(root):
    files, total = [], 0
    for dp, dns, fns in os.walk(root):
        for n in fns:
            p = os.path.join(dp, n)
            try:
                st = os.lstat(p)
            except OSError:
                continue
            total += st.st_size
            files.append(os.path.relpath(p, root))
    return files, total


def listing(d):
    try:
        return set(os.listdir(d))
    except OSError:
        return set()


TEMPISH = re.compile(r"^\.|\.tmp|\.part|~$|\.new$|\.swp$")
SIGNALS = {"SIGINT": signal.SIGINT, "SIGTERM": signal.SIGTERM, "SIGKILL": signal.SIGKILL}


def execute(run, case, ctx):
    """Runs one command under the watcher; returns the run record."""
    d = Path(case["dir"])
    tmp = d / "tmp"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    argv = [ctx["binary"] if a == "BIN" else a for a in run["argv"]]
    as_user = run.get("user") and os.geteuid() == 0
    if as_user:
        os.chmod(tmp, 0o777)
        for p in (d / "out",):
            p.mkdir(exist_ok=True)
            os.chmod(p, 0o777)
    outs = outputs_of(run["argv"])
    out_dirs = sorted({str((d / p).parent) for _, p in outs} | {str(tmp)})
    for od in out_dirs:
        Path(od).mkdir(parents=True, exist_ok=True)
    baseline = blocks_under(out_dirs)
    mem = int(ctx["mem_gb"] * GiB)
    env = dict(os.environ, TMPDIR=str(tmp), RUST_BACKTRACE="0")

    def pre():
        # Signals the campaign may have inherited as ignored (started with nohup or `&`)
        # would be ignored by the binary too.
        for sg in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
            signal.signal(sg, signal.SIG_DFL)
        resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
        os.setsid()
        if as_user:
            os.setgroups([])
            os.setgid(NOBODY)
            os.setuid(NOBODY)

    timeout = min(case.get("timeout", ctx["timeout"]), ctx["timeout"])
    sig = run.get("signal")
    start = time.monotonic()
    p = subprocess.Popen(argv, cwd=d, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         stdin=subprocess.DEVNULL, preexec_fn=pre, env=env)
    state = {"peak": 0, "killed_for": None, "signal_sent": None, "stopped_after_signal": None}
    outbuf = {}

    def reader(name, stream):
        outbuf[name] = stream.read()

    threads = [threading.Thread(target=reader, args=(n, s), daemon=True)
               for n, s in (("stdout", p.stdout), ("stderr", p.stderr))]
    for t in threads:
        t.start()
    watch = run.get("watch")
    timed_out = False
    while p.poll() is None:
        now = time.monotonic() - start
        if watch:
            u = usage(out_dirs, p.pid, baseline)
            state["peak"] = max(state["peak"], u)
            if u > ctx["kill_bytes"] and not state["killed_for"]:
                state["killed_for"] = f"temporary bytes passed {ctx['kill_bytes'] / GiB:.1f} GiB"
                _killpg(p)
            fs = os.statvfs(d)
            if fs.f_bavail * fs.f_frsize < FREE_RESERVE and not state["killed_for"]:
                state["killed_for"] = "the disk was nearly full"
                _killpg(p)
        if sig and state["signal_sent"] is None and now >= sig[1]:
            try:
                os.kill(p.pid, SIGNALS[sig[0]])
                state["signal_sent"] = round(now, 3)
            except ProcessLookupError:
                pass
        if state["signal_sent"] is not None and now > state["signal_sent"] + 15:
            state["stopped_after_signal"] = False
            _killpg(p)
        if now > timeout:
            timed_out = True
            _killpg(p)
        time.sleep(WATCH_S)
    rc = p.wait()
    # Anything else of its process group (none expected) goes too.
    _killpg(p)
    for t in threads:
        t.join(5)
    secs = round(time.monotonic() - start, 3)
    if state["signal_sent"] is not None and state["stopped_after_signal"] is None:
        state["stopped_after_signal"] = True
    return {"cmd": [str(a) for a in argv], "rc": rc, "seconds": secs, "timed_out": timed_out,
            "stdout": (outbuf.get("stdout") or b"").decode(errors="replace")[-20000:],
            "stderr": (outbuf.get("stderr") or b"").decode(errors="replace")[-20000:],
            "peak_temp_bytes": state["peak"] if watch else None,
            "killed_for": state["killed_for"], "signal": sig,
            "signal_sent_at": state["signal_sent"],
            "stopped_after_signal": state["stopped_after_signal"], "as_nobody": bool(as_user)}


def _killpg(p):
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


# ----------------------------------------------------------------------------------------
# Judging.
# ----------------------------------------------------------------------------------------


def load_json_text(text):
    try:
        return json.loads(text)
    except ValueError:
        return None


def run_case(case, ctx):
    """Builds, runs and judges one case; returns the result row."""
    d = Path(case["dir"])
    if d.exists():
        _rmtree(d)
    d.mkdir(parents=True)
    rank, bump_state = ctx["rank"], {"worst": "ok"}
    reasons = []

    def bump(cls, why):
        if rank[cls] > rank[bump_state["worst"]]:
            bump_state["worst"] = cls
        reasons.append(f"{cls}: {why}")

    if case["build"].get("needs_dds") and not ctx["dds"]():
        return {"id": case["id"], "category": case["category"], "kind": case["kind"],
                "class": "ok", "reasons": ["skipped: DDS unavailable"], "runs": {},
                "what": case["what"], "skipped": True}
    try:
        build(case, ctx)
    except Exception as e:  # noqa: BLE001
        _cleanup(case)
        return {"id": case["id"], "category": case["category"], "kind": case["kind"],
                "class": "ok", "reasons": [f"skipped: could not build: {e!r}"[:300]],
                "runs": {}, "what": case["what"], "skipped": True}
    if case["build"].get("ro") and case["category"] == "wal":
        os.chmod(d / "in", 0o555)
        if os.geteuid() != 0:
            pass
    runs = {}
    expect = case.get("expect", {})
    in_dir = expect.get("no_new_files_in")
    pristine = listing(d / in_dir) if in_dir else None
    for run in case["runs"]:
        name = run["name"]
        argv = run["argv"]
        if in_dir:
            # Each run starts from the input as built: side files an earlier run made go.
            for x in listing(d / in_dir) - pristine:
                os.unlink(d / in_dir / x)
        overwrite = "--overwrite" in argv
        # What must not change: the input, pre-existing bags among the outputs (unless
        # replaceable), and the files the case protects always.
        replaceable = set(case.get("replaceable", []))
        protect = {}
        for p in inputs_of(argv):
            if (d / p).exists() or os.path.islink(d / p):
                protect[p] = "input"
        for _, p in outputs_of(argv):
            if p not in replaceable and is_bag(d / p.rstrip("/")):
                protect.setdefault(p.rstrip("/"), "existing bag")
        always = set(case.get("protect_always", []))
        snaps = {p: snapshot(d / p) for p in set(protect) | always}
        outs = outputs_of(argv)
        out_before = {p: snapshot(d / p.rstrip("/")) for _, p in outs}
        parents = {str((d / p.rstrip("/")).parent) for _, p in outs}
        parents |= {str(d / p.rstrip("/")) for _, p in outs if p.endswith("/")}
        before_lists = {q: listing(q) for q in parents}
        in_before = listing(d / in_dir) if in_dir else None
        r = execute(run, case, ctx)
        runs[name] = r
        console = r["stdout"] + "\n" + r["stderr"]
        err = console
        # 1. The process itself.
        if r["killed_for"]:
            bump("disk", f"{name}: killed by the campaign: {r['killed_for']} "
                         f"(peak {r['peak_temp_bytes'] / GiB:.2f} GiB)")
        elif r["timed_out"]:
            bump("hang", f"{name}: no answer within the timeout ({r['seconds']} s)")
        elif r["stopped_after_signal"] is False:
            bump("hang", f"{name}: still running 15 s after {r['signal'][0]}")
        elif r["rc"] == 101 or "panicked at" in err:
            bump("panic", f"{name}: {err.strip().splitlines()[-1][:160] if err.strip() else ''}")
        elif r["rc"] is not None and r["rc"] < 0 and r["signal_sent_at"] is None:
            bump("memory", f"{name}: killed by signal {-r['rc']}")
        elif "memory allocation of" in err:
            bump("memory", f"{name}: allocation failed")
        if r["peak_temp_bytes"] is not None and not r["killed_for"] and \
                r["peak_temp_bytes"] > ctx["cap_bytes"] + DISK_SLACK:
            bump("disk", f"{name}: peak temporary bytes {r['peak_temp_bytes'] / GiB:.2f} GiB "
                         f"over the cap of {ctx['cap_bytes'] / GiB:.1f} GiB")
        # 2. What must not change.
        for p, snap in snaps.items():
            now = snapshot(d / p)
            if in_dir is not None:
                now, snap = without_side_files(now), without_side_files(snap)
            if now != snap and (p in always or not overwrite):
                why = "a file outside the output directory" if p in always else protect[p]
                bump("destroyed", f"{name}: {p} ({why}) {describe_change(snap, now)}"
                                  f"{'' if overwrite else ' without --overwrite'}")
        # 3. Temporary bytes left.
        left, left_bytes = tree_bytes(d / "tmp")
        if left:
            bump("temp_left", f"{name}: {len(left)} file(s), {left_bytes} bytes left in TMPDIR "
                              f"({', '.join(left[:3])})"
                              f"{' after the campaign killed it' if r['killed_for'] else ''}")
        for q, before in before_lists.items():
            new = sorted(x for x in listing(q) - before if TEMPISH.search(x))
            if new:
                rel = os.path.relpath(q, d)
                bump("temp_left", f"{name}: stray file(s) beside the output in {rel}: "
                                  f"{', '.join(new[:4])}")
        ok_exit = r["rc"] == 0 and not r["timed_out"] and not r["killed_for"]
        for flag, p in outs:
            kind = out_kind(argv, flag, p)
            target = d / p.rstrip("/")
            if kind is None:
                continue
            if snapshot(target) == out_before[p]:
                if ok_exit and overwrite and out_before[p] is not None and \
                        expect.get("must_succeed"):
                    bump("lost", f"{name}: exit 0 with --overwrite, but {p} was not replaced")
                continue
            if p.rstrip("/") in snaps and snaps[p.rstrip("/")] is not None and not overwrite:
                continue  # already judged as destroyed
            if not (target.exists() or target.is_symlink()):
                continue
            why = complete(kind, target)
            if why:
                if ok_exit:
                    bump("lost", f"{name}: exit 0 but its {flag} {p} is not a complete "
                                 f"{kind}: {why}")
                else:
                    bump("temp_left", f"{name}: partial output left at {p}: {why}")
        # 4. Speed on accepted input.
        if ok_exit and r["seconds"] > SLOW_S:
            bump("slow", f"{name}: accepted, but took {r['seconds']} s (over {SLOW_S:.0f} s)")
        # 5. Category oracles.
        report = None
        for flag, p in outs:
            if flag == "--report" and (d / p).is_file():
                report = ctx["load_json"](d / p)
        if report is None and "--json" in argv:
            report = load_json_text(r["stdout"])
        if expect.get("must_succeed") and not ok_exit and not r["killed_for"]:
            tail = (r["stderr"].strip().splitlines() or [""])[-1][:140]
            bump("lost", f"{name}: refused a run that must succeed (exit {r['rc']}: {tail})")
        what = expect.get("must_say")
        if what == "metadata_disagrees" and ok_exit:
            c, rep = says(what, console, report)
            if not c or (report is not None and not rep) or (
                    "--report" in argv and report is None):
                miss = [x for x, ok in (("console", c), ("report", rep or report is None))
                        if not ok]
                bump("silent", f"{name}: exit 0, the metadata's disagreement with the files "
                               f"not said ({' nor '.join(miss)})")
        if what == "integrity_unverified" and ok_exit and "--report" in argv:
            c, rep = says(what, console, report)
            if not rep:
                bump("silent", f"{name}: the report says nothing of the bag's integrity "
                               "(the format has no checksum)")
        if what == "link":
            c, rep = says(what, console, report, expect.get("words", []))
            if not (c or rep):
                bump("silent", f"{name}: exit {r['rc']}, the link is followed without a word "
                               "naming it")
        if "names" in expect and (not ok_exit or expect.get("say_on_success")):
            probs = []
            if not any(n in console for n in expect["names"]):
                probs.append(f"names none of {', '.join(expect['names'])}")
            if not re.search(expect["cause"], console, re.I):
                probs.append(f"no word of the cause (/{expect['cause']}/)")
            if expect.get("forbid") and re.search(expect["forbid"], console, re.I):
                probs.append(f"says /{expect['forbid']}/, which is false")
            if probs and not (r["timed_out"] or r["killed_for"]):
                line = _last_line(r["stderr"] or r["stdout"])
                bump("unclear", f"{name}: exit {r['rc']}: {'; '.join(probs)} ({line})")
        if in_dir is not None:
            new = sorted(listing(d / in_dir) - in_before)
            if new:
                bump("created", f"{name}: created {', '.join(new)} beside the input")
            want = expect.get("immutable_messages")
            got = None
            if isinstance(report, dict):
                got = (report.get("input") or {}).get("messages", report.get("messages"))
            if want is not None and (got is None or got < want):
                bump("created", f"{name}: read {got if got is not None else 'no'} messages; "
                                f"Python's sqlite3 (immutable=1) reads {want}")
        # 6. Otherwise the general outcome.
        if not any(x.startswith(("hang", "panic", "memory", "disk", "unclear"))
                   and x.split(": ", 2)[1] == name for x in reasons):
            if r["rc"] != 0 and r["signal_sent_at"] is None:
                probs = ctx["message_problems"](r["stderr"] or r["stdout"], case)
                if probs:
                    bump("unclear", f"{name}: " + "; ".join(probs))
                else:
                    bump("clean_error", f"{name}: {_last_line(r['stderr'])}")
            elif r["rc"] == 0 and (re.search(r"\b(WARN|ERROR)\b", r["stderr"])
                                   or ctx["counted"](r, report)):
                bump("counted", f"{name}: counted")
        # Between runs: the TMPDIR is emptied (what was left is already judged).
        shutil.rmtree(d / "tmp", ignore_errors=True)
    _cleanup(case)
    return {
        "id": case["id"], "category": case["category"], "kind": case["kind"],
        "class": bump_state["worst"], "reasons": reasons, "what": case["what"],
        "runs": {n: {k: r[k] for k in ("cmd", "rc", "seconds", "timed_out", "peak_temp_bytes",
                                       "killed_for", "signal", "signal_sent_at", "as_nobody")}
                 | {"stderr_tail": r["stderr"][-400:], "stdout_tail": r["stdout"][-200:]}
                 for n, r in runs.items()},
    }


def _last_line(text):
    lines = [l for l in text.strip().splitlines() if l.strip()]
    return lines[-1][:200] if lines else "(no message)"


def _rmtree(d):
    for dp, dns, fns in os.walk(d):
        for n in dns:
            try:
                os.chmod(os.path.join(dp, n), 0o755, follow_symlinks=False)
            except (OSError, NotImplementedError):
                pass
    try:
        os.chmod(d, 0o755)
    except OSError:
        pass
    shutil.rmtree(d, ignore_errors=True)


def _cleanup(case):
    """Deletes the case's big files (bombs, thousands of split files, large outputs) once it
    is judged; keeps the small ones for reading."""
    d = Path(case["dir"])
    for dp, dns, fns in os.walk(d):
        for n in dns:
            try:
                os.chmod(os.path.join(dp, n), 0o755, follow_symlinks=False)
            except (OSError, NotImplementedError):
                pass
    for p in case.get("big", []):
        q = d / p
        if q.is_dir() and not q.is_symlink():
            shutil.rmtree(q, ignore_errors=True)
        elif q.exists() or q.is_symlink():
            q.unlink()
    shutil.rmtree(d / "tmp", ignore_errors=True)
    for dp, dns, fns in os.walk(d):
        for n in fns:
            p = os.path.join(dp, n)
            try:
                st = os.lstat(p)
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode) and st.st_size > 8 * MiB:
                os.unlink(p)


def documented_limits(repo):
    """{name: value} of the limits table of docs/limits.md: each row's backticked names are
    paired in order with its value cell's comma-separated values ("16 MiB", "100 000")."""
    try:
        text = (Path(repo) / "docs/limits.md").read_text()
    except OSError:
        return {}
    out = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2:
            continue
        names = re.findall(r"`([A-Za-z_]+)`", cells[0])
        values = [v.strip() for v in re.split(r",\s*(?=\d)", cells[1])]
        for name, v in zip(names, values):
            m = re.match(r"([\d][\d ]*(?:\.\d+)?)\s*([KMGT]i?B)?", v)
            if not m:
                continue
            num = float(m.group(1).replace(" ", ""))
            unit = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}[m.group(2)[0]] \
                if m.group(2) else 1
            out[name] = int(num * unit)
    return out


def documented_cap(repo):
    """`max_decompressed_file_bytes` from docs/limits.md, in bytes (None if not found)."""
    try:
        text = (Path(repo) / "docs/limits.md").read_text()
    except OSError:
        return None
    m = re.search(r"`max_decompressed_file_bytes`\s*\|\s*([\d.]+)\s*([KMGT]i?B)", text)
    if not m:
        return None
    unit = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}[m.group(2)[0]]
    return int(float(m.group(1)) * unit)


_dds = {}


def dds_available(binary, root):
    """Whether `launch --duration 1` runs here (once per campaign)."""
    with _shared_lock:
        if "ok" not in _dds:
            d = Path(root) / "_dds-probe"
            d.mkdir(parents=True, exist_ok=True)
            (d / "cfg.yaml").write_text("launch:\n- node: {pkg: chronotope, exec: mesher, "
                                        "param: [{name: bodies, value: [/a/occupancy]}]}\n")
            try:
                p = subprocess.run([binary, "launch", "cfg.yaml", "--duration", "1",
                                    "--summary", "s.json"], cwd=d, capture_output=True,
                                   timeout=30)
                _dds["ok"] = p.returncode == 0 and (d / "s.json").exists()
            except subprocess.TimeoutExpired:
                _dds["ok"] = False
    return _dds["ok"]
