#!/usr/bin/env python3
"""Compares chronotope-occupancy with independent producers.

OctoMap streams are written by the OctoMap library itself (PyPI `pyoctomap`,
which bundles OctoMap 1.10): maps built with `insertPointCloud` (ray casting,
automatic pruning) and `updateNode`, written with `write()` (full stream) and
`writeBinary()` (binary stream; OctoMap makes the tree max-likelihood and
prunes it first), the file header stripped to leave what `octomap_msgs` puts in
`Octomap.data`. The reference for every voxel comes from the library's own
`search()` at the centres of the tree's finest cells inside the voxel (at the
voxel centre when the lattice is the tree's or finer), with its
`isNodeOccupied` rule (log-odds >= the tree's threshold).

PointCloud2 messages are built with numpy structured arrays in several layouts
and serialised to CDR by PyPI `rosbags` (both CDR byte orders); the reference
voxels are computed with numpy from the points.

The crate's example `occupancy_rasterize` reads the message (the stream and fields, or the
whole CDR message) and writes VoxelGrid.data; this script compares it byte for
byte (aligned lattices) or within the stated tolerance (unaligned ones).

Usage (from the repository root, after building the example):
    cargo build --release -p chronotope-occupancy --example occupancy_rasterize
    python3 -m venv /tmp/occ-venv && /tmp/occ-venv/bin/pip install -r tests/py/occupancy/requirements.txt
    /tmp/occ-venv/bin/python tests/py/occupancy/compare.py [--bin target/release/examples/occupancy_rasterize]

Prints a markdown table (one row per case) and exits non-zero on a mismatch.
"""

import argparse
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
import pyoctomap as po
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

K0 = 32768
OCTOMAP_MSG = """std_msgs/Header header
bool binary
string id
float64 resolution
int8[] data
"""

ROWS = []
FAILED = []


def record(case, producer, what, result, ok):
    ROWS.append((case, producer, what, result))
    if not ok:
        FAILED.append(case)


# ---------------------------------------------------------------- the bridge


def run_bridge(args, cmd, extra, out_name="out.bin"):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, out_name)
        files = {}
        argv = [args.bin, cmd]
        for k, v in extra.items():
            if isinstance(v, (bytes, bytearray, memoryview)):
                p = os.path.join(d, k + ".bin")
                with open(p, "wb") as f:
                    f.write(bytes(v))
                files[k] = p
                argv += ["--" + k, p]
            elif v is True:
                argv += ["--" + k]
            else:
                argv += ["--" + k, str(v)]
        argv += ["--out", out]
        r = subprocess.run(argv, capture_output=True, text=True)
        if r.returncode != 0:
            return None, r.stderr.strip()
        with open(out, "rb") as f:
            data = f.read()
        stats = dict(w.split("=") for w in r.stdout.split())
        return data, stats


def lattice_args(origin, res, size, encoding):
    return {
        "origin": ",".join(repr(float(v)) for v in origin),
        "lattice-res": repr(float(res)),
        "size": ",".join(str(int(v)) for v in size),
        "encoding": encoding,
    }


def unpack_bits(data, n):
    return np.unpackbits(np.frombuffer(data, dtype=np.uint8), bitorder="little")[:n].astype(bool)


# ------------------------------------------------------------ octomap trees


def strip_header(blob):
    """The tree stream after the file header (`...\\ndata\\n`)."""
    i = blob.index(b"\ndata\n") + len(b"\ndata\n")
    return blob[i:]


def scene_points(res):
    """Surface points of a small cell: a floor, a wall, a box and a post."""
    rng = np.random.default_rng(3)
    pts = []
    n = 4000
    u, v = rng.random(n), rng.random(n)
    pts.append(np.c_[u * 2.0 - 0.2, v * 2.0 - 0.2, np.full(n, 0.01)])  # floor
    pts.append(np.c_[np.full(n // 2, 1.78), u[: n // 2] * 2.0 - 0.2, v[: n // 2] * 0.9])  # wall
    b = rng.random((n // 2, 2))
    pts.append(np.c_[0.4 + b[:, 0] * 0.5, 0.3 + b[:, 1] * 0.4, np.full(n // 2, 0.45)])  # box top
    a = rng.random(n // 4) * 2 * np.pi
    pts.append(np.c_[1.2 + 0.1 * np.cos(a), 1.3 + 0.1 * np.sin(a), rng.random(n // 4) * 0.7])  # post
    return np.ascontiguousarray(np.vstack(pts), dtype=np.float64)


def build_tree(kind, res):
    tree = {"OcTree": po.OcTree, "OcTreeStamped": po.OcTreeStamped, "ColorOcTree": po.ColorOcTree}[kind](res)
    pts = scene_points(res)
    origins = [np.array([0.9, 0.8, 0.85]), np.array([0.1, 1.5, 0.6])]
    for o in origins:
        tree.insertPointCloud(pts, o, max_range=3.0)
    # A solid block from many identical updates: OctoMap prunes it to coarse leaves.
    step = res
    lo = np.array([-0.8, -0.8, 0.0])
    cells = int(round(0.4 / step))
    for i in range(cells):
        for j in range(cells):
            for k in range(cells // 2):
                c = lo + (np.array([i, j, k]) + 0.5) * step
                if kind == "OcTreeStamped":
                    tree.updateNode(float(c[0]), float(c[1]), float(c[2]), 4.0)
                else:
                    tree.updateNode(c, 4.0)
    # A few cells near the threshold (log-odds +0.3, -0.1): the threshold decides them.
    for n, c in enumerate([[1.9, 1.9, 1.02], [1.9, 1.8, 1.02], [1.8, 1.9, 1.02]]):
        c = np.array(c)
        if kind == "OcTreeStamped":
            tree.updateNode(float(c[0]), float(c[1]), float(c[2]), 0.3 if n != 1 else -0.1)
        else:
            tree.updateNode(c, 0.3 if n != 1 else -0.1)
    if kind == "ColorOcTree":
        for c in pts[:200]:
            tree.setNodeColor(c, 200, 100, 50)
    if hasattr(tree, "updateInnerOccupancy"):
        tree.updateInnerOccupancy()
    return tree


def cell_states(tree, res, key_lo, key_hi):
    """State of every finest cell in the key box: -1 unknown, 0 free, 1 occupied,
    from the library's search() at the cell centre and its isNodeOccupied()."""
    shape = [key_hi[a] - key_lo[a] for a in range(3)]
    states = np.full((shape[2], shape[1], shape[0]), -1, dtype=np.int8)
    for kz in range(shape[2]):
        z = (key_lo[2] + kz - K0 + 0.5) * res
        for ky in range(shape[1]):
            y = (key_lo[1] + ky - K0 + 0.5) * res
            for kx in range(shape[0]):
                x = (key_lo[0] + kx - K0 + 0.5) * res
                node = tree.search([x, y, z])
                if node is not None:
                    states[kz, ky, kx] = 1 if tree.isNodeOccupied(node) else 0
    return states


def overlap_matrix(v0, vres, nv, c0, cres, nc):
    """W[i, j]: fraction of voxel i's edge covered by cell j (1D)."""
    vi = v0 + np.arange(nv + 1) * vres
    cj = c0 + np.arange(nc + 1) * cres
    lo = np.maximum(vi[:-1, None], cj[None, :-1])
    hi = np.minimum(vi[1:, None], cj[None, 1:])
    return np.clip(hi - lo, 0.0, None) / vres


def octree_reference(states, key_lo, res, origin, vres, size, unknown_occupied, exact):
    """Expected bits and percent. `exact`: the lattice is aligned and every
    voxel holds whole cells (or lies in one): integer counts."""
    nx, ny, nz = size
    occ = (states == 1).astype(np.float64)
    free = (states == 0).astype(np.float64)
    c0 = [(key_lo[a] - K0) * res for a in range(3)]
    W = [overlap_matrix(origin[a], vres, size[a], c0[a], res, states.shape[2 - a]) for a in range(3)]
    o = np.einsum("za,yb,xc,abc->zyx", W[2], W[1], W[0], occ, optimize=True)
    f = np.einsum("za,yb,xc,abc->zyx", W[2], W[1], W[0], free, optimize=True)
    if exact:
        # Volumes are multiples of 1/m for m cells per voxel: round to those.
        m = max(1.0, round((vres / res) ** 3))
        o = np.round(o * m) / m
        f = np.round(f * m) / m
    bits = o > (0 if exact else 1e-9)
    if unknown_occupied:
        bits |= (o + f) < 1 - (0 if exact else 1e-9)
    pct = np.where(o + f == 0, 255, 0).astype(np.int64)
    if exact:
        m = max(1, int(round((vres / res) ** 3)))
        nfree = np.round(f * m).astype(np.int64)
        p = -((-100 * (m - nfree)) // m)  # ceil(100 (m - free) / m)
    else:
        p = np.ceil(100 * (1 - f) - 1e-9).astype(np.int64)
    p = np.where(o > 0, np.maximum(p, 1), p)
    pct = np.where(o + f == 0, 255, np.clip(p, 0, 100))
    return bits.reshape(-1), pct.reshape(-1).astype(np.uint8), o.reshape(-1), f.reshape(-1)


def compare_octree(args, case, producer, msg_fields, states, key_lo, res, origin, vres, size, exact,
                   unknown_occupied=False, threshold=None, cdr=None, extra=None):
    n = size[0] * size[1] * size[2]
    results = []
    ok_all = True
    for encoding in ("bits", "percent"):
        opts = dict(lattice_args(origin, vres, size, encoding))
        if unknown_occupied:
            opts["unknown-occupied"] = True
        if threshold is not None:
            opts["threshold"] = repr(threshold)
        if extra:
            opts.update(extra)
        if cdr is not None:
            data, stats = run_bridge(args, "octomap-cdr", dict(msg=cdr, **opts))
        else:
            data, stats = run_bridge(args, "octomap", dict(**msg_fields, **opts))
        if data is None:
            record(case, producer, encoding, "refused: " + stats, False)
            return
        bits, pct, o, f = octree_reference(states, key_lo, res, origin, vres, size, unknown_occupied, exact)
        if encoding == "bits":
            got = unpack_bits(data, n)
            if exact:
                bad = int(np.sum(got != bits))
            else:
                sliver = (o > 0) & (o <= 1e-6)
                bad = int(np.sum((got != bits) & ~sliver))
            ok = bad == 0 and len(data) == (n + 7) // 8
            results.append(f"bits: {n - bad}/{n} equal, {int(bits.sum())} occupied")
        else:
            got = np.frombuffer(data, dtype=np.uint8)
            if exact:
                bad = int(np.sum(got != pct))
                results.append(f"percent: {n - bad}/{n} equal")
            else:
                known = (o + f) > 1e-6
                nothing = (o + f) == 0
                bad = int(np.sum(known & (np.abs(got.astype(int) - pct.astype(int)) > 1)))
                bad += int(np.sum(nothing & (got != 255)))
                results.append(f"percent: {n - bad}/{n} within 1 point, {int(np.sum(got == pct))} equal")
            ok = bad == 0 and len(data) == n
        ok_all &= ok
    record(case, producer, f"{size[0]}x{size[1]}x{size[2]} at {vres:g} m" + (" (aligned)" if exact else " (unaligned)"),
           "; ".join(results) + ("" if ok_all else "  **MISMATCH**"), ok_all)


def octomap_cases(args):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    ts.register(get_types_from_msg(OCTOMAP_MSG, "octomap_msgs/msg/Octomap"))
    Octomap = ts.types["octomap_msgs/msg/Octomap"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]

    for kind, res in [("OcTree", 0.05), ("OcTree", 0.1), ("OcTree", 0.02), ("OcTree", 0.037),
                      ("OcTreeStamped", 0.05), ("ColorOcTree", 0.05)]:
        tree = build_tree(kind, res)
        # Key box of the compared region: the scene (about -1..2 m, 0..1 m) and a margin.
        lo_m = np.array([-1.0, -1.0, -0.2])
        hi_m = np.array([2.1, 2.0, 1.1])
        key_lo = [int(math.floor(lo_m[a] / res)) + K0 for a in range(3)]
        key_hi = [int(math.ceil(hi_m[a] / res)) + K0 for a in range(3)]
        cell0 = [(key_lo[a] - K0) * res for a in range(3)]
        span = [key_hi[a] - key_lo[a] for a in range(3)]
        producer = f"pyoctomap {kind} {res:g} m"

        def lattices():
            # (origin, voxel edge, size, exact)
            yield cell0, res, span, True
            yield cell0, 2 * res, [s // 2 for s in span], True
            yield cell0, 4 * res, [s // 4 for s in span], True
            if res >= 0.05:
                # Finer than the tree: every voxel in one cell (a part of the box).
                half = [min(s, 60) for s in span]
                yield [cell0[0] + 0.5 * res, cell0[1] + 0.5 * res, cell0[2]], res / 2, half, True
            # Unaligned: another edge, an origin off the tree's grid.
            e = res * 1.37
            yield [cell0[0] + 0.31 * res, cell0[1] + 0.77 * res, cell0[2] + 0.13 * res], e, [int((span[a] - 1) * res / e) for a in range(3)], False

        blob = tree.write()
        full = strip_header(blob)
        states = cell_states(tree, res, key_lo, key_hi)
        fields = {"binary": "0", "id": kind, "res": repr(res), "data": full}
        leaves = sum(1 for _ in tree.begin_leafs()) if hasattr(tree, "begin_leafs") else None
        for origin, vres, size, exact in lattices():
            compare_octree(args, f"{kind} {res:g} full", producer + f", full stream ({len(full)} B, {tree.size()} nodes)",
                           fields, states, key_lo, res, origin, vres, size, exact)
        if kind == "OcTree" and res == 0.05:
            # The tree's own threshold moved (cells hit once, log-odds 0.85, become
            # free): OctoMap's isNodeOccupied and ours agree.
            tree.setOccupancyThres(0.8)
            states8 = cell_states(tree, res, key_lo, key_hi)
            compare_octree(args, "OcTree 0.05 full, threshold 0.8", producer + ", full stream, occupancy threshold 0.8",
                           fields, states8, key_lo, res, cell0, res, span, True, threshold=tree.getOccupancyThresLog())
            tree.setOccupancyThres(0.5)
        if kind == "ColorOcTree":
            # pyoctomap's ColorOcTree.writeBinary appends its own colour trailer
            # after OctoMap's stream: refused by default, read with allow_trailing_bytes.
            with tempfile.TemporaryDirectory() as d:
                p = os.path.join(d, "c.bt")
                tree.writeBinary(p)
                with open(p, "rb") as fh:
                    binary = strip_header(fh.read())
            statesb = cell_states(tree, res, key_lo, key_hi)
            fieldsb = {"binary": "1", "id": kind, "res": repr(res), "data": binary}
            data, err = run_bridge(args, "octomap", dict(**fieldsb, **lattice_args(cell0, res, span, "bits")))
            refused = data is None and "after the tree ends" in err
            record(f"{kind} {res:g} binary + trailer", producer + ", writeBinary() with pyoctomap's colour trailer",
                   "default options", ("refused: " + err) if data is None else "accepted  **MISMATCH**", refused)
            compare_octree(args, f"{kind} {res:g} binary + trailer", producer + ", writeBinary() with pyoctomap's colour trailer",
                           fieldsb, statesb, key_lo, res, cell0, res, span, True, extra={"allow-trailing": True})
            continue
        # Binary: OctoMap turns the tree max-likelihood and prunes it, then writes.
        binary = strip_header(tree.writeBinary())
        states_b = cell_states(tree, res, key_lo, key_hi)
        fieldsb = {"binary": "1", "id": kind, "res": repr(res), "data": binary}
        for origin, vres, size, exact in lattices():
            compare_octree(args, f"{kind} {res:g} binary", producer + f", binary stream ({len(binary)} B, {tree.size()} nodes, pruned)",
                           fieldsb, states_b, key_lo, res, origin, vres, size, exact)
        if kind == "OcTree" and res == 0.05:
            compare_octree(args, "OcTree 0.05 binary, unknown occupied", producer + ", binary stream, unknown_occupied",
                           fieldsb, states_b, key_lo, res, cell0, 2 * res, [s // 2 for s in span], True, unknown_occupied=True)
            for le in (True, False):
                msg = Octomap(header=Header(stamp=Time(sec=1, nanosec=2), frame_id="cell"), binary=True, id=kind,
                              resolution=res, data=np.frombuffer(binary, dtype=np.int8))
                cdr = bytes(ts.serialize_cdr(msg, "octomap_msgs/msg/Octomap", little_endian=le))
                compare_octree(args, f"OcTree 0.05 binary via CDR {'LE' if le else 'BE'}",
                               f"pyoctomap stream in an octomap_msgs/Octomap serialised by rosbags ({'little' if le else 'big'}-endian CDR)",
                               None, states_b, key_lo, res, cell0, 2 * res, [s // 2 for s in span], True, cdr=cdr)


# ------------------------------------------------------------------- clouds


def cloud_points(rng):
    """Sparse clutter, clusters (for min_points), a tilted surface (for fills)
    and a few special values; some points outside the lattice."""
    clutter = rng.uniform([-0.3, -0.4, -0.2], [2.6, 2.2, 1.8], size=(3000, 3))
    centres = rng.uniform([0.0, 0.0, 0.0], [2.2, 1.8, 1.5], size=(40, 3))
    clusters = centres[rng.integers(0, 40, 20000)] + rng.normal(0, 0.01, size=(20000, 3))
    uv = rng.uniform([-0.2, -0.3], [2.5, 2.1], size=(20000, 2))
    surface = np.c_[uv, 0.6 + 0.15 * uv[:, 0] + rng.normal(0, 0.005, 20000)]
    pts = np.vstack([clutter, clusters, surface])
    pts[5] = [np.nan, 0.5, 0.5]
    pts[6] = [0.5, np.inf, 0.5]
    pts[7] = [0.5, 0.5, -np.inf]
    pts[8] = [0.3, 0.3, 5.0]  # above the top: a column source when filling down
    return pts


def encode_cloud(pts, layout):
    """Structured numpy array of the layout; returns (fields, point_step, row_step, data, height, width)."""
    names = ["x", "y", "z"]
    fmt = layout["formats"]  # e.g. ['<f4','<f4','<f4']
    offsets = layout["offsets"]
    dt_fields = {"names": names + ["intensity"], "formats": fmt + ["u1"],
                 "offsets": offsets + [layout.get("intensity", 0)], "itemsize": layout["step"]}
    dt = np.dtype(dt_fields)
    height = layout.get("height", 1)
    n = len(pts) - len(pts) % height
    pts = pts[:n]
    arr = np.zeros(n, dtype=dt)
    for a, nm in enumerate(names):
        arr[nm] = pts[:, a]
    width = n // height
    pad = layout.get("pad", 0)
    raw = arr.tobytes()
    rows = [raw[r * width * layout["step"]:(r + 1) * width * layout["step"]] + b"\xcd" * pad for r in range(height)]
    data = b"".join(rows)
    datatype = {"f4": 7, "f8": 8}
    fields = [(nm, offsets[a], datatype[fmt[a][1:]]) for a, nm in enumerate(names)] + [("intensity", layout.get("intensity", 0), 2)]
    stored = np.zeros((n, 3))
    for a, nm in enumerate(names):
        stored[:, a] = arr[nm].astype(np.float64)  # the values as stored (f32 rounding)
    return fields, layout["step"], width * layout["step"] + pad, data, height, width, stored


def cloud_reference(stored, origin, res, size, min_points=1, dilate=0.0, fill=None, matrix=None):
    p = stored.copy()
    if matrix is not None:
        r = matrix
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        # Row by row, left to right, as the crate (no fused multiply-add).
        p = np.stack([r[0] * x + r[1] * y + r[2] * z + r[9], r[3] * x + r[4] * y + r[5] * z + r[10],
                      r[6] * x + r[7] * y + r[8] * z + r[11]], axis=1)
    finite = np.all(np.isfinite(p), axis=1)
    p = p[finite]
    n = np.array(size)
    u = (p - np.array(origin)) * (1.0 / res)
    inside = np.all((u >= 0) & (u < n), axis=1)
    cells = np.floor(u[inside]).astype(np.int64)
    marks = [cells]
    rad = dilate / res
    out = u[~inside]
    kept = np.zeros(len(out), dtype=bool)
    if rad > 0:
        d = np.maximum(np.maximum(-out, out - n), 0.0)
        r2 = (rad * (1 + 1e-9)) ** 2
        kept = np.sum(d * d, axis=1) <= r2
        marks.append(np.clip(np.floor(out[kept]), 0, n - 1).astype(np.int64))
    if fill is not None:
        ax, sign = fill
        others = [b for b in range(3) if b != ax]
        beyond = (out[:, ax] >= n[ax]) if sign < 0 else (out[:, ax] < 0)
        inside_o = np.all((out[:, others] >= 0) & (out[:, others] < n[others]), axis=1)
        col = beyond & inside_o & ~kept
        marks.append(np.clip(np.floor(out[col]), 0, n - 1).astype(np.int64))
        kept = kept | col
    allc = np.vstack(marks)
    counts = np.zeros((size[2], size[1], size[0]), dtype=np.int64)
    np.add.at(counts, (allc[:, 2], allc[:, 1], allc[:, 0]), 1)
    occ = counts >= min_points
    if rad > 0:
        rr = rad * (1 + 1e-9) + 1e-12
        R = int(math.floor(rr)) + 1
        grown = np.zeros_like(occ)
        for dz in range(-R, R + 1):
            for dy in range(-R, R + 1):
                for dx in range(-R, R + 1):
                    g = [max(0, abs(v) - 1) for v in (dx, dy, dz)]
                    if g[0] ** 2 + g[1] ** 2 + g[2] ** 2 > rr * rr:
                        continue
                    src = occ[max(0, -dz):size[2] - max(0, dz), max(0, -dy):size[1] - max(0, dy), max(0, -dx):size[0] - max(0, dx)]
                    grown[max(0, dz):size[2] - max(0, -dz), max(0, dy):size[1] - max(0, -dy), max(0, dx):size[0] - max(0, -dx)] |= src
        occ = grown
    if fill is not None:
        ax, sign = fill
        npax = 2 - ax  # array axes are z, y, x
        if sign < 0:
            occ = np.flip(np.logical_or.accumulate(np.flip(occ, axis=npax), axis=npax), axis=npax)
        else:
            occ = np.logical_or.accumulate(occ, axis=npax)
    return occ.reshape(-1), int(np.sum(~finite)), int(np.sum(~inside) - np.sum(kept))


def cloud_cases(args):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    PointCloud2 = ts.types["sensor_msgs/msg/PointCloud2"]
    PointField = ts.types["sensor_msgs/msg/PointField"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    rng = np.random.default_rng(11)
    pts = cloud_points(rng)
    origin, res, size = [-0.1, -0.2, 0.0], 0.05, [48, 40, 32]
    layouts = {
        "xyz f32 + intensity, LE, unorganised": {"formats": ["<f4", "<f4", "<f4"], "offsets": [0, 4, 8], "intensity": 12, "step": 16},
        "xyz f32, BE data, organised 8 rows, 12 B row padding": {"formats": [">f4", ">f4", ">f4"], "offsets": [4, 8, 12], "intensity": 0, "step": 20, "height": 8, "pad": 12},
        "xyz f64 at odd offsets (z, x, y order), LE, point_step 45": {"formats": ["<f8", "<f8", "<f8"], "offsets": [14, 22, 5], "intensity": 0, "step": 45},
        "xyz f64, BE data, organised 4 rows, 3 B padding": {"formats": [">f8", ">f8", ">f8"], "offsets": [8, 16, 24], "intensity": 2, "step": 33, "height": 4, "pad": 3},
        "x f64, y f32, z f32 mixed, LE": {"formats": ["<f8", "<f4", "<f4"], "offsets": [1, 9, 13], "intensity": 0, "step": 17},
    }
    q = np.array([0.1, -0.3, 0.2, 0.9])
    q = q / np.linalg.norm(q)
    x, y, z, w = q
    rot = [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
           2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
           2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]
    matrix = rot + [0.35, -0.2, 0.1]
    option_sets = [
        ("plain", {}, {}),
        ("min_points 3", {"min-points": 3}, {"min_points": 3}),
        ("dilate 0.07 m", {"dilate": 0.07}, {"dilate": 0.07}),
        ("fill z- (to the floor)", {"fill": "z-"}, {"fill": (2, -1)}),
        ("fill x+", {"fill": "x+"}, {"fill": (0, 1)}),
        ("transform", {"matrix": ",".join(repr(float(v)) for v in matrix)}, {"matrix": matrix}),
        ("all: transform, min_points 2, dilate 0.03, fill z-",
         {"matrix": ",".join(repr(float(v)) for v in matrix), "min-points": 2, "dilate": 0.03, "fill": "z-"},
         {"matrix": matrix, "min_points": 2, "dilate": 0.03, "fill": (2, -1)}),
    ]
    n = size[0] * size[1] * size[2]
    for lname, layout in layouts.items():
        fields, step, row_step, data, height, width, stored = encode_cloud(pts, layout)
        big = layout["formats"][0].startswith(">")
        msg = PointCloud2(header=Header(stamp=Time(sec=3, nanosec=4), frame_id="sensor"), height=height, width=width,
                          fields=[PointField(name=nm, offset=o, datatype=d, count=1) for nm, o, d in fields],
                          is_bigendian=big, point_step=step, row_step=row_step,
                          data=np.frombuffer(data, dtype=np.uint8), is_dense=False)
        cdr_orders = (True, False) if lname.startswith("xyz f32 + intensity") else (True,)
        sets = option_sets if lname.startswith("xyz f32 + intensity") else option_sets[:1] + option_sets[-1:]
        for le in cdr_orders:
            cdr = bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2", little_endian=le))
            for oname, bridge_opts, ref_opts in sets:
                want, nonfinite, outside = cloud_reference(stored, origin, res, size, **ref_opts)
                results, ok_all = [], True
                for encoding in ("bits", "percent"):
                    got, stats = run_bridge(args, "cloud-cdr", dict(msg=cdr, **lattice_args(origin, res, size, encoding), **bridge_opts))
                    if got is None:
                        results.append("refused: " + stats)
                        ok_all = False
                        continue
                    if encoding == "bits":
                        g = unpack_bits(got, n)
                    else:
                        g = np.frombuffer(got, dtype=np.uint8)
                        ok_all &= bool(np.all((g == 100) | (g == 0)))
                        g = g == 100
                    bad = int(np.sum(g != want))
                    ok = bad == 0 and int(stats["nonfinite"]) == nonfinite and int(stats["outside"]) == outside
                    ok_all &= ok
                    if encoding == "bits":
                        results.append(f"{n - bad}/{n} voxels equal ({int(want.sum())} occupied); nonfinite {stats['nonfinite']}/{nonfinite}, outside {stats['outside']}/{outside}")
                record(f"cloud: {oname}", f"numpy layout \"{lname}\", rosbags CDR {'LE' if le else 'BE'}, {width * height} points",
                       "bits and percent", "; ".join(results) + ("" if ok_all else "  **MISMATCH**"), ok_all)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--bin", default=os.path.join(here, "..", "..", "..", "target", "release", "examples", "occupancy_rasterize"))
    ap.add_argument("--only", choices=["octomap", "cloud"], default=None)
    args = ap.parse_args()
    if not os.path.exists(args.bin):
        sys.exit(f"no bridge binary at {args.bin}: build it with `cargo build --release -p chronotope-occupancy --example occupancy_rasterize`")
    print(f"pyoctomap {getattr(po, '__version__', '?')}, numpy {np.__version__}", file=sys.stderr)
    if args.only in (None, "octomap"):
        octomap_cases(args)
    if args.only in (None, "cloud"):
        cloud_cases(args)
    print("| case | producer | lattice / options | result |")
    print("|---|---|---|---|")
    for row in ROWS:
        print("| " + " | ".join(str(c) for c in row) + " |")
    print(f"\n{len(ROWS) - len(FAILED)} passed, {len(FAILED)} failed")
    sys.exit(1 if FAILED else 0)


if __name__ == "__main__":
    main()
