#!/usr/bin/env python3
"""Occupancy nodes on bags written by others, compared voxel for voxel with the producers'
own answers.

OctoMap streams are written by the OctoMap library itself (PyPI `pyoctomap`, which bundles
OctoMap 1.10: `insertPointCloud` ray casting with pruning, `write()` for the full stream,
`writeBinary()` for the binary one, the file header stripped to what `octomap_msgs` puts in
`Octomap.data`); point clouds are laid out with numpy and serialised by PyPI `rosbags`
(`sensor_msgs/msg/PointCloud2`, little- and big-endian values, float32 and float64, odd
offsets and steps, organised with row padding, NaN and far points). `rosbags` writes the bag
(rosbag2 MCAP, or SQLite with --storage sqlite3), `chronotope replay` runs occupancy nodes on
it, and the frames they publish are read back from the output bag with `rosbags` and
compared with:

- octrees: OctoMap's own `search()` and `isNodeOccupied()` at the centre of every finest cell
  in each voxel (lattices aligned with the tree, 1 and 2 tree cells a voxel), bits and percent,
  as the node's rules say (tests/py/occupancy/compare.py holds the reference);
- clouds: numpy's `floor((p - origin) / resolution)` of every finite point.

Usage:
    python tests/py/occupancy_bags.py CHRONOTOPE_BINARY [--storage mcap|sqlite3] [--keep DIR]

Exit status 0 when every frame matches, 1 on a mismatch, 3 when pyoctomap is missing.
"""

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

try:
    import pyoctomap  # noqa: F401
except ImportError:
    print("SKIPPED: pyoctomap is not installed (python3 tests/py/setup_env.py installs it)")
    sys.exit(3)

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

sys.path.insert(0, str(Path(__file__).resolve().parent / "occupancy"))
import compare  # noqa: E402  (the octree reference: cell states and voxel rules)

OCTOMAP_MSG = (Path(__file__).resolve().parents[2] / "msgs/deps/octomap_msgs/msg/Octomap.msg").read_text()
T0 = 1_700_000_000 * 10**9
FAILED = []


def say(case, ok, text):
    print(f"| {case} | {'ok' if ok else '**MISMATCH**'} | {text} |")
    if not ok:
        FAILED.append(case)


def header(ts, stamp_ns, frame):
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    return Header(stamp=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=frame)


def cloud_msg(ts, stamp_ns, points, layout):
    """A PointCloud2 of `points` (N x 3, may hold NaN) in a numpy layout:
    (names, formats, offsets, itemsize, big_endian, height, row_padding)."""
    PointCloud2 = ts.types["sensor_msgs/msg/PointCloud2"]
    PointField = ts.types["sensor_msgs/msg/PointField"]
    names, formats, offsets, itemsize, big, height, pad = layout
    order = ">" if big else "<"
    dt = np.dtype({"names": names, "formats": [order + f for f in formats], "offsets": offsets, "itemsize": itemsize})
    n = len(points)
    width = n // height
    arr = np.zeros(n, dtype=dt)
    for i, a in enumerate("xyz"):
        arr[a] = points[:, i]
    for extra in [nm for nm in names if nm not in ("x", "y", "z")]:
        arr[extra] = np.arange(n) % 7
    rows = arr.reshape(height, width).view(np.uint8).reshape(height, width * itemsize)
    data = np.concatenate([rows, np.full((height, pad), 0xAB, np.uint8)], axis=1).reshape(-1)
    code = {"f4": 7, "f8": 8, "u1": 2, "i2": 3, "u4": 6}
    fields = [PointField(name=nm, offset=off, datatype=code[f], count=1) for nm, f, off in zip(names, formats, offsets)]
    return PointCloud2(
        header=header(ts, stamp_ns, "world"),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=big,
        point_step=itemsize,
        row_step=width * itemsize + pad,
        data=data,
        is_dense=False,
    )


def octomap_msg(ts, stamp_ns, data, binary, kind, res):
    Octomap = ts.types["octomap_msgs/msg/Octomap"]
    return Octomap(
        header=header(ts, stamp_ns, "world"),
        binary=binary,
        id=kind,
        resolution=res,
        data=np.frombuffer(data, dtype=np.int8),
    )


def cloud_points(seed, n):
    rng = np.random.default_rng(seed)
    p = rng.uniform([-0.3, -0.3, -0.1], [1.5, 1.3, 0.9], size=(n, 3))
    p[::37] = np.nan                                 # invalid pixels
    p[5::53, 1] = np.inf
    p[7::61] = [40.0, -3.0, 0.5]                     # far outside the lattice
    return p


LATTICES = {
    # name: (origin, resolution, size); origins on the 0.05 m tree's grid.
    "fine": ([-0.5, -0.5, -0.2], 0.05, [40, 36, 24]),
    "coarse": ([-0.5, -0.5, -0.2], 0.10, [20, 18, 12]),
}

CLOUD_LAYOUTS = {
    # topic: layout
    "/cloud_f32": (["x", "y", "z", "intensity"], ["f4", "f4", "f4", "f4"], [0, 4, 8, 12], 16, False, 1, 0),
    "/cloud_f64_be": (["z", "x", "ring", "y"], ["f8", "f8", "u1", "f8"], [3, 14, 0, 27], 40, True, 8, 12),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("chronotope")
    ap.add_argument("--storage", default="mcap", choices=["mcap", "sqlite3"])
    ap.add_argument("--keep")
    args = ap.parse_args()

    ts = get_typestore(Stores.ROS2_HUMBLE)
    ts.register(get_types_from_msg(OCTOMAP_MSG, "octomap_msgs/msg/Octomap"))
    res = 0.05
    tree = compare.build_tree("OcTree", res)
    full = compare.strip_header(tree.write())
    binary = compare.strip_header(tree.writeBinary())  # max-likelihood and pruned by OctoMap
    # Every finest cell of the compared box, as OctoMap itself answers (after writeBinary,
    # which changed the tree, the binary stream's states; the full stream's are taken first).
    work = Path(args.keep or tempfile.mkdtemp(prefix="occ-bags-"))
    work.mkdir(parents=True, exist_ok=True)
    o, _, s = LATTICES["fine"]
    key_lo = [int(round(o[a] / res)) + compare.K0 for a in range(3)]
    key_hi = [key_lo[a] + s[a] for a in range(3)]
    tree_full = compare.build_tree("OcTree", res)
    states = {
        "full": compare.cell_states(tree_full, res, key_lo, key_hi),
        "binary": compare.cell_states(tree, res, key_lo, key_hi),
    }

    bag = work / "bag"
    if bag.exists():
        import shutil
        shutil.rmtree(bag)
    clouds = {}
    with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP if args.storage == "mcap" else StoragePlugin.SQLITE3) as w:
        conns = {}
        for t in ["/map_full", "/map_binary"]:
            conns[t] = w.add_connection(t, "octomap_msgs/msg/Octomap", typestore=ts)
        for t in CLOUD_LAYOUTS:
            conns[t] = w.add_connection(t, "sensor_msgs/msg/PointCloud2", typestore=ts)
        for k in range(3):
            stamp = T0 + k * 100_000_000
            for t, data, b in [("/map_full", full, False), ("/map_binary", binary, True)]:
                m = octomap_msg(ts, stamp, data, b, "OcTree", res)
                w.write(conns[t], stamp, ts.serialize_cdr(m, "octomap_msgs/msg/Octomap"))
            for i, (t, layout) in enumerate(CLOUD_LAYOUTS.items()):
                pts = cloud_points(10 * k + i, 8 * 1500)
                clouds[(t, k)] = pts
                m = cloud_msg(ts, stamp + 1000 * (i + 1), pts, layout)
                # Big-endian clouds as big-endian CDR too.
                little = not layout[4]
                w.write(conns[t], stamp + 1000 * (i + 1), ts.serialize_cdr(m, "sensor_msgs/msg/PointCloud2", little_endian=little))

    # One occupancy node per input and lattice and encoding.
    nodes = []
    cases = []
    for lat, (origin, vres, size) in LATTICES.items():
        for enc in ["bits", "percent"]:
            for stream in ["full", "binary"]:
                name = f"map_{stream}_{lat}_{enc}"
                nodes.append((name, f"/map_{stream}", "octomap_msgs/msg/Octomap", origin, vres, size, enc))
                cases.append(("octree", name, stream, lat, enc))
        for t in CLOUD_LAYOUTS:
            name = f"{t.strip('/')}_{lat}"
            nodes.append((name, t, "sensor_msgs/msg/PointCloud2", origin, vres, size, "bits"))
            cases.append(("cloud", name, t, lat, "bits"))
    cfg = ["launch:"]
    for name, topic, ty, origin, vres, size, enc in nodes:
        cfg.append(f"- node:\n    pkg: chronotope\n    exec: occupancy\n    name: {name}\n    param:")
        cfg.append(f"    - {{name: input_topic, value: {topic}}}")
        cfg.append(f"    - {{name: input_type, value: {ty}}}")
        cfg.append(f"    - {{name: origin, value: [{', '.join(repr(float(v)) for v in origin)}]}}")
        cfg.append(f"    - {{name: resolution, value: {vres!r}}}")
        cfg.append(f"    - {{name: size, value: [{', '.join(str(v) for v in size)}]}}")
        cfg.append(f"    - {{name: encoding, value: {enc}}}")
    launch = work / "occupancy.yaml"
    launch.write_text("\n".join(cfg) + "\n")
    out = work / "out.mcap"
    report = work / "report.json"
    r = subprocess.run([args.chronotope, "replay", str(bag), "--launch", str(launch), "--out", str(out),
                        "--report", str(report), "--overwrite"], capture_output=True, text=True)
    if r.returncode != 0:
        print(r.stdout, r.stderr)
        say("replay", False, "chronotope replay failed")
        return 1

    frames = {}
    with AnyReader([out]) as reader:
        for conn, stamp, raw in reader.messages():
            m = reader.deserialize(raw, conn.msgtype)
            frames.setdefault(conn.topic, []).append(m)

    print(f"| case | result | detail ({args.storage} bag by rosbags, frames read back by rosbags) |")
    print("|---|---|---|")
    for kind, name, src, lat, enc in cases:
        origin, vres, size = LATTICES[lat]
        got = frames.get(f"/{name}/occupancy", [])
        n = size[0] * size[1] * size[2]
        if len(got) != 3:
            say(name, False, f"{len(got)} frames, expected 3")
            continue
        ok, detail = True, []
        for k, g in enumerate(got):
            data = np.asarray(g.data, dtype=np.uint8)
            if kind == "octree":
                bits, pct, _, _ = compare.octree_reference(states[src], key_lo, res, origin, vres, size, False, True)
                if enc == "bits":
                    v = np.unpackbits(data, bitorder="little")[:n].astype(bool)
                    bad = int(np.sum(v != bits))
                    detail.append(f"{n - bad}/{n} equal ({int(bits.sum())} occupied)")
                else:
                    bad = int(np.sum(data != pct))
                    detail.append(f"{n - bad}/{n} equal ({int(np.sum(pct == 255))} unknown)")
            else:
                pts = clouds[(src, k)]
                fin = np.all(np.isfinite(pts), axis=1)
                idx = np.floor((pts[fin] - np.array(origin)) / vres).astype(np.int64)
                inside = np.all((idx >= 0) & (idx < np.array(size)), axis=1)
                want = np.zeros(n, bool)
                i = idx[inside]
                want[i[:, 0] + size[0] * (i[:, 1] + size[1] * i[:, 2])] = True
                v = np.unpackbits(data, bitorder="little")[:n].astype(bool)
                bad = int(np.sum(v != want))
                detail.append(f"{n - bad}/{n} equal ({int(want.sum())} occupied, {int(np.sum(~fin))} NaN/inf, {int(np.sum(~inside))} outside)")
            ok &= bad == 0 and g.size_x == size[0] and abs(g.resolution - vres) < 1e-12
        say(name, ok, "; ".join(detail[:1]) + f" (×{len(got)} frames)")
    # The node's counts of skipped points are numpy's.
    import json
    counts = json.loads(report.read_text())["nodes"]
    for kind, name, src, lat, enc in cases:
        if kind != "cloud":
            continue
        origin, vres, size = LATTICES[lat]
        nan = out_ = 0
        for k in range(3):
            pts = clouds[(src, k)]
            fin = np.all(np.isfinite(pts), axis=1)
            idx = np.floor((pts[fin] - np.array(origin)) / vres)
            nan += int(np.sum(~fin))
            out_ += int(np.sum(~np.all((idx >= 0) & (idx < np.array(size)), axis=1)))
        c = counts[f"/{name}"].get("counts", {})
        got = (c.get("points_nonfinite", 0), c.get("points_outside", 0))
        say(name + " counts", got == (nan, out_), f"NaN/inf {got[0]} (numpy {nan}), outside {got[1]} (numpy {out_})")
    print(f"{len(cases) - len(FAILED)} passed, {len(FAILED)} failed")
    return 1 if FAILED else 0


if __name__ == "__main__":
    sys.exit(main())
