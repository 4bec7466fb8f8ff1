#!/usr/bin/env python3
"""chronotope's streamed check side by side with FCL (PyPI python-fcl), on the same scenes.

  python bench/fcl/compare.py [--bin target/release/chronotope]
                              [--scenes four-spheres machine-tool periodic sparse percent graze]
                              [--grids 32 64 128] [--mt-grids 64 128] [--periodic-duration 10]
                              [--sparse-frames 3 5] [--percent-grids 64] [--graze 0.235,0.24 0.24,0.2]
                              [--encoding bits|percent] [--reps 3]
                              [--out results.md] [--json results.json] [--work DIR] [--from-json J]

For every scene (written by `chronotope scene ...`, but for `graze`, which this script writes:
see README.md), each repetition runs, one after the other so that the machine's load falls
on all of them alike:

* chronotope, streamed: `replay BAG --launch bench/fcl/detect.yaml --report R.json` (the
  mesher and the rolling checker, every pair, no resolution);
* chronotope, at once: `check BAG --report R.json` (its report's `mesh` + `check` timings are
  the detection; `resolve`, the resolutions `check` always computes, is left out);
* FCL, streamed the same way, frame by frame, keeping two frames: per body and frame, a
  triangle mesh from the same voxels (marching cubes at the 0.5 level on the zero-padded
  occupancy, the PERCENT fraction as the scalar field), an `fcl.BVHModel` (OBB-RSS), then
    - discrete: `fcl.collide` for every pair at every frame;
    - continuous: `fcl.continuousCollide` for every pair over every frame period, FCL's
      default solver (conservative advancement, translation motion), the earlier frame's
      meshes moved by the translation estimated from the occupancy (the shift of the
      occupancy's centroid; see README.md for why the pair's relative translation moves one
      body and the other stays);
    - continuous, FCL's naive solver: `collide` at 10 instants of each period.

Time per frame period = a run's time / (frames - 1), the median over --reps. Errors are
against the exact answers computed here from each scene's definition (docs/scenes.md):
the spheres' quadratics, the periodic swing, the machine-tool cell's boxes and cylinders
on their keyframes, and the graze's straight pass. Needs python-fcl, numpy, scikit-image, mcap, mcap-ros2-support.
"""

import argparse
import datetime
import hashlib
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
DETECT_CFG = HERE / "detect.yaml"


def log(msg):
    print(f"fcl-compare: {msg}", file=sys.stderr, flush=True)


# ---- exact answers, from each scene's definition (docs/scenes.md) -------------------------

def pair_key(a, b):
    return tuple(sorted((a, b)))


# four-spheres: c(t) = c0 + v t for t in [0, 1] s, radius 0.125 m.
FOUR_SPHERES = {
    "/sphere_a/occupancy": ((0.5, 0.5, 0.2), (0.0, 0.0, 0.6)),
    "/sphere_b/occupancy": ((0.35, 0.7, 0.5), (0.0, -0.4, 0.0)),
    "/sphere_c/occupancy": ((0.3, 0.35, 0.3), (0.45, 0.0, 0.0)),
    "/sphere_d/occupancy": ((0.75, 0.65, 0.7), (-0.45, 0.0, 0.0)),
}
FOUR_SPHERES_R = 0.125


def four_spheres_exact():
    """Open intervals where |c_i(t) - c_j(t)| < 2r: the roots of |q|^2 t^2 + 2 p.q t + |p|^2 - 4r^2."""
    out = {}
    names = sorted(FOUR_SPHERES)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            p = np.subtract(FOUR_SPHERES[b][0], FOUR_SPHERES[a][0])
            q = np.subtract(FOUR_SPHERES[b][1], FOUR_SPHERES[a][1])
            A, B, C = q @ q, 2 * p @ q, p @ p - 4 * FOUR_SPHERES_R ** 2
            disc = B * B - 4 * A * C
            iv = []
            if A > 0 and disc > 0:
                t0 = (-B - math.sqrt(disc)) / (2 * A)
                t1 = (-B + math.sqrt(disc)) / (2 * A)
                s, e = max(t0, 0.0), min(t1, 1.0)
                if s < e:
                    iv.append((float(s), float(e)))
            out[pair_key(a, b)] = iv
    return out


def periodic_exact(span_s):
    """The swinger's centre x(t) = 0.25 + 0.25 tri(t) (tri: 0 -> 1 at 1 s -> 0 at 2 s), the
    post's at 0.7, radii 0.15: overlap while 0.45 - 0.25 tri(t) < 0.3, i.e. tri(t) > 0.6."""
    out = []
    k = 0
    while 2 * k + 0.6 < span_s:
        out.append((2 * k + 0.6, min(2 * k + 1.4, span_s)))
        k += 1
    return {pair_key("/swinger/occupancy", "/post/occupancy"): out}


# machine-tool: shapes at rest and keyframed offsets against u = t / span (docs/scenes.md).
MT_SHAPES = {
    "/spindle/occupancy": [
        ("zcyl", (0.44, 0.64), 0.08, (0.56, 0.80)),           # tool
        ("zcyl", (0.44, 0.64), 0.12, (0.80, 0.88)),           # nose
        ("box", (0.30, 0.50, 0.88), (0.58, 0.78, 1.16)),      # head
    ],
    "/table/occupancy": [
        ("box", (0.24, 0.32, 0.12), (1.04, 0.96, 0.24)),      # plate
        ("box", (0.36, 0.48, 0.24), (0.68, 0.80, 0.44)),      # workpiece
    ],
    "/fixture/occupancy": [
        ("box", (0.76, 0.52, 0.24), (0.88, 0.76, 0.48)),      # clamp block
        ("ycyl", (0.82, 0.48), 0.06, (0.48, 0.80)),           # clamp bar: axis x, z; y range
    ],
}
MT_KEYS = {
    "/spindle/occupancy": [(0.0, (0, 0, 0)), (0.2, (0, 0, -0.20)), (0.7, (0.54, 0, -0.20)),
                           (0.85, (0.54, 0, 0)), (1.0, (0.54, -0.24, 0))],
    "/table/occupancy": [(0.0, (0, 0, 0)), (1.0, (-0.12, 0, 0))],
    "/fixture/occupancy": [(0.0, (0, 0, 0)), (1.0, (-0.12, 0, 0))],
}


def mt_offset(body, u):
    keys = MT_KEYS[body]
    for (u0, o0), (u1, o1) in zip(keys, keys[1:]):
        if u <= u1:
            f = (u - u0) / (u1 - u0)
            return np.add(o0, f * np.subtract(o1, o0))
    return np.array(keys[-1][1], float)


def _moved(shape, o):
    kind = shape[0]
    if kind == "box":
        return ("box", tuple(np.add(shape[1], o)), tuple(np.add(shape[2], o)))
    if kind == "zcyl":  # axis (x, y), radius, z range
        (x, y), r, (z0, z1) = shape[1], shape[2], shape[3]
        return ("zcyl", (x + o[0], y + o[1]), r, (z0 + o[2], z1 + o[2]))
    (x, z), r, (y0, y1) = shape[1], shape[2], shape[3]  # ycyl: axis (x, z), radius, y range
    return ("ycyl", (x + o[0], z + o[2]), r, (y0 + o[1], y1 + o[1]))


def _rect_dist(px, py, lo, hi):
    dx = max(lo[0] - px, 0.0, px - hi[0])
    dy = max(lo[1] - py, 0.0, py - hi[1])
    return math.hypot(dx, dy)


def _open_overlap(a0, a1, b0, b1):
    return max(a0, b0) < min(a1, b1)


def _shapes_meet(s, t):
    """Whether two open solids (axis-aligned boxes, cylinders along z or y) share an interior point."""
    if s[0] > t[0]:
        s, t = t, s
    ks = (s[0], t[0])
    if ks == ("box", "box"):
        return all(_open_overlap(s[1][i], s[2][i], t[1][i], t[2][i]) for i in range(3))
    if ks == ("box", "zcyl"):
        (x, y), r, (z0, z1) = t[1], t[2], t[3]
        return _open_overlap(z0, z1, s[1][2], s[2][2]) and \
            _rect_dist(x, y, (s[1][0], s[1][1]), (s[2][0], s[2][1])) < r
    if ks == ("box", "ycyl"):
        (x, z), r, (y0, y1) = t[1], t[2], t[3]
        return _open_overlap(y0, y1, s[1][1], s[2][1]) and \
            _rect_dist(x, z, (s[1][0], s[1][2]), (s[2][0], s[2][2])) < r
    if ks == ("ycyl", "zcyl"):
        (xb, zb), rb, (yb0, yb1) = s[1], s[2], s[3]
        (xa, ya), ra, (za0, za1) = t[1], t[2], t[3]
        # the point of the y-range nearest the z-cylinder's axis, the z nearest the y-axis
        if not (_open_overlap(yb0, yb1, ya - ra, ya + ra) and _open_overlap(za0, za1, zb - rb, zb + rb)):
            return False
        dy = 0.0 if yb0 < ya < yb1 else min(abs(ya - yb0), abs(ya - yb1))
        dz = 0.0 if za0 < zb < za1 else min(abs(zb - za0), abs(zb - za1))
        if dy >= ra or dz >= rb:
            return False
        wa, wb = math.sqrt(ra * ra - dy * dy), math.sqrt(rb * rb - dz * dz)
        return _open_overlap(xa - wa, xa + wa, xb - wb, xb + wb)
    if ks == ("zcyl", "zcyl"):
        return _open_overlap(s[3][0], s[3][1], t[3][0], t[3][1]) and \
            math.dist(s[1], t[1]) < s[2] + t[2]
    if ks == ("ycyl", "ycyl"):
        return _open_overlap(s[3][0], s[3][1], t[3][0], t[3][1]) and \
            math.dist(s[1], t[1]) < s[2] + t[2]
    raise ValueError(ks)


def mt_bodies_meet(a, b, u):
    sa = [_moved(s, mt_offset(a, u)) for s in MT_SHAPES[a]]
    sb = [_moved(s, mt_offset(b, u)) for s in MT_SHAPES[b]]
    return any(_shapes_meet(s, t) for s in sa for t in sb)


def machine_tool_exact(span_s, steps=5000):
    """Scans u in [0, 1] and bisects each change to 1e-12 of the run."""
    out = {}
    names = sorted(MT_SHAPES)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            us = np.linspace(0.0, 1.0, steps + 1)
            inside = [mt_bodies_meet(a, b, u) for u in us]
            iv, start = [], None
            for k in range(len(us)):
                if k > 0 and inside[k] != inside[k - 1]:
                    lo, hi = us[k - 1], us[k]
                    for _ in range(60):
                        mid = 0.5 * (lo + hi)
                        if mt_bodies_meet(a, b, mid) == inside[k - 1]:
                            lo = mid
                        else:
                            hi = mid
                    edge = 0.5 * (lo + hi)
                    if inside[k]:
                        start = edge
                    else:
                        iv.append((start, edge))
                        start = None
                elif k == 0 and inside[0]:
                    start = 0.0
            if start is not None:
                iv.append((start, 1.0))
            out[pair_key(a, b)] = [(float(s * span_s), float(e * span_s)) for s, e in iv]
    return out


# ---- cases -------------------------------------------------------------------------------

class Case:
    def __init__(self, label, scene, args, exact_fn, make=None):
        self.label, self.scene, self.args, self.exact_fn = label, scene, args, exact_fn
        self.make = make  # writes the bag itself (scenes `chronotope scene` has not)


# graze: written here, not by `chronotope scene`. A sphere A (radius 0.125 m) passes a still
# sphere B at a miss distance b between their centres, moving s metres a frame along x at
# 10 Hz, 4 frames; the frames are placed so that A is level with B half-way between frames 1
# and 2, and neither frame shows the spheres overlapping. On a 128³ lattice of 1 cm voxels.
GRAZE_R, GRAZE_B_CENTRE, GRAZE_FRAMES, GRAZE_PERIOD = 0.125, (0.64, 0.64, 0.64), 4, 0.1


def graze_x0(s):
    return GRAZE_B_CENTRE[0] - s * (GRAZE_FRAMES - 1) / 2


def graze_exact(b, s):
    w = math.sqrt((2 * GRAZE_R) ** 2 - b * b)
    v = s / GRAZE_PERIOD
    x0 = graze_x0(s)
    t0, t1 = (GRAZE_B_CENTRE[0] - w - x0) / v, (GRAZE_B_CENTRE[0] + w - x0) / v
    return {pair_key("/grazer/occupancy", "/post/occupancy"): [(t0, t1)]}


def make_graze_bag(path, b, s, binary, grid=128, h=0.01):
    """Writes the graze scene as chronotope writes its scenes: BITS, a voxel set iff its centre
    is strictly inside, the VoxelGrid definition taken from a bag the binary writes."""
    from mcap.reader import make_reader
    from mcap_ros2.writer import Writer
    ref = Path(path).with_suffix(".schema.mcap")
    subprocess.run([str(binary), "scene", "four-spheres", "--grid", "4", "--frames", "2", "--out",
                    str(ref), "--overwrite"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(ref, "rb") as f:
        schema = next(sc for sc in make_reader(f).get_summary().schemas.values()
                      if sc.name == "chronotope_msgs/msg/VoxelGrid").data.decode()
    ref.unlink()
    g = (np.arange(grid) + 0.5) * h
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    x0 = graze_x0(s)
    cb = np.array(GRAZE_B_CENTRE)
    with open(path, "wb") as f:
        w = Writer(f)
        sch = w.register_msgdef("chronotope_msgs/msg/VoxelGrid", schema)
        for k in range(GRAZE_FRAMES):
            ns = 1_700_000_000 * 10 ** 9 + round(k * GRAZE_PERIOD * 1e9)
            ca = np.array([x0 + s * k, cb[1] + b, cb[2]])
            for topic, c in (("/grazer/occupancy", ca), ("/post/occupancy", cb)):
                occ = (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2 < GRAZE_R ** 2
                msg = dict(header=dict(stamp=dict(sec=ns // 10 ** 9, nanosec=ns % 10 ** 9), frame_id="world"),
                           origin=dict(x=0.0, y=0.0, z=0.0), resolution=h, size_x=grid, size_y=grid,
                           size_z=grid, encoding=0,
                           data=np.packbits(occ.ravel(), bitorder="little").tobytes())
                w.write_message(topic, sch, msg, log_time=ns, publish_time=ns)
        w.finish()


def build_cases(a):
    cases = []
    enc = ["--encoding", a.encoding]
    for s in a.scenes:
        if s == "four-spheres":
            for g in a.grids:
                cases.append(Case(f"four-spheres {g}³ × 33", "four-spheres", ["--grid", str(g)] + enc,
                                  lambda span: four_spheres_exact()))
        elif s == "machine-tool":
            for g in a.mt_grids:
                cases.append(Case(f"machine-tool {g}³ × 64", "machine-tool", ["--grid", str(g)] + enc,
                                  machine_tool_exact))
        elif s == "periodic":
            d = a.periodic_duration
            cases.append(Case(f"periodic 48³, {d:g} s at 20 Hz", "periodic",
                              ["--duration", f"{d:g}"] + enc, periodic_exact))
        elif s == "percent":
            for g in a.percent_grids:
                cases.append(Case(f"four-spheres {g}³ × 33, PERCENT", "four-spheres",
                                  ["--grid", str(g), "--encoding", "percent"],
                                  lambda span: four_spheres_exact()))
        elif s == "sparse":
            for f in a.sparse_frames:
                cases.append(Case(f"four-spheres 64³ × {f} (sparse)", "four-spheres",
                                  ["--grid", "64", "--frames", str(f)] + enc,
                                  lambda span: four_spheres_exact()))
        elif s == "graze":
            for spec in a.graze:
                b, step = (float(x) for x in spec.split(","))
                depth = 2 * GRAZE_R - b
                cases.append(Case(f"graze 128³ × 4: {step * 100:g} cm a frame, {depth * 100:g} cm deep",
                                  "graze", [f"b{b:g}", f"s{step:g}"],
                                  lambda span, b=b, step=step: graze_exact(b, step),
                                  make=lambda path, b=b, step=step: make_graze_bag(path, b, step, a.bin)))
        else:
            raise SystemExit(f"unknown scene {s!r}")
    return cases


# ---- running chronotope --------------------------------------------------------------------

def run_timed(cmd, log_path):
    """Runs cmd; returns (wall s, CPU s of the child: user + system)."""
    with open(log_path, "w") as lf:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=lf, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} exited with {p.returncode}; see {log_path}")
    return wall, ru.ru_utime + ru.ru_stime


def chronotope_pairs(report):
    out = {}
    for p in report["pairs"]:
        out[pair_key(p["a"], p["b"])] = p
    return out


# ---- FCL -----------------------------------------------------------------------------------

def read_bag(path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    frames = {}
    with open(path, "rb") as f:
        for _, ch, _, m in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            frames.setdefault(ch.topic, []).append(m)
    for t in frames:
        frames[t].sort(key=lambda m: (m.header.stamp.sec, m.header.stamp.nanosec))
    return frames


def stamp_s(m):
    return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9


def occupancy(m):
    """(z, y, x) float32 occupancy fraction: BITS 0/1 (LSB first, x fastest, then y, then z),
    PERCENT /100 (255, unknown, counted occupied as the mesher does by default)."""
    nx, ny, nz = m.size_x, m.size_y, m.size_z
    raw = np.frombuffer(m.data, np.uint8)
    if m.encoding == 0:
        b = np.unpackbits(raw, bitorder="little")[: nx * ny * nz]
        return b.reshape(nz, ny, nx).astype(np.float32)
    a = raw[: nx * ny * nz].reshape(nz, ny, nx).astype(np.float32)
    a[a == 255] = 100.0
    return a / 100.0


def occupied_box(occ):
    """The occupied voxels' index box (z, y, x), one voxel wider all round (within the grid)."""
    zs = np.flatnonzero(occ.any(axis=(1, 2)))
    if len(zs) == 0:
        return None
    yx = occ[zs[0]:zs[-1] + 1].any(axis=0)
    ys, xs = np.flatnonzero(yx.any(axis=1)), np.flatnonzero(yx.any(axis=0))
    lo = [max(int(a[0]) - 1, 0) for a in (zs, ys, xs)]
    hi = [int(a[-1]) + 2 for a in (zs, ys, xs)]
    return lo, hi


def mesh_from_occupancy(occ, m, box):
    """Marching cubes (scikit-image, Lewiner) at the 0.5 level on the occupied box padded by one
    free voxel all round, so every surface closes. Vertices in metres (world frame): voxel
    (i, j, k)'s centre is origin + (i + 0.5, j + 0.5, k + 0.5) * resolution."""
    from skimage.measure import marching_cubes
    lo, hi = box
    sub = np.pad(occ[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]], 1)
    v, f, _, _ = marching_cubes(sub, 0.5, allow_degenerate=False)
    h = m.resolution
    v = (v[:, ::-1] + np.array(lo[::-1], float) - 0.5) * h + \
        np.array([m.origin.x, m.origin.y, m.origin.z])
    return v, np.ascontiguousarray(f[:, ::-1])  # (x, y, z); the swap keeps the winding outward


def centroid(occ, m, box):
    """The occupancy's centroid in metres (weighted by the occupied fraction), from its box."""
    if box is None:
        return None
    lo, hi = box
    sub = occ[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    w = sub.sum()
    if w <= 0:
        return None
    zs, ys, xs = sub.sum(axis=(1, 2)), sub.sum(axis=(0, 2)), sub.sum(axis=(0, 1))
    c = np.array([xs @ np.arange(len(xs)), ys @ np.arange(len(ys)), zs @ np.arange(len(zs))]) / w
    return (c + np.array(lo[::-1]) + 0.5) * m.resolution + np.array([m.origin.x, m.origin.y, m.origin.z])


def rigid_iou(prev, cur, shift_vox):
    """IoU of `cur` with `prev` shifted by whole voxels (x, y, z), occupancy >= 0.5."""
    a = prev >= 0.5
    b = cur >= 0.5
    sx, sy, sz = (int(s) for s in shift_vox)
    a = np.roll(a, (sz, sy, sx), axis=(0, 1, 2))
    inter = np.logical_and(a, b).sum()
    union = np.logical_or(a, b).sum()
    return inter / union if union else 1.0


def tick():
    return time.perf_counter(), time.process_time()


def add_time(acc, t0, t1):
    acc[0] += t1[0] - t0[0]
    acc[1] += t1[1] - t0[1]


def aabb_overlap(lo1, hi1, lo2, hi2):
    return bool(np.all(lo1 <= hi2) and np.all(lo2 <= hi1))


def fcl_run(bag, store=None):
    """One streamed pass of FCL over the bag: per frame, every body's mesh and BVH, the
    discrete check of every pair; per frame period, the continuous check of every pair.
    Returns the timings (s) and what was found. With `store` (a dict), the continuous solver is
    checked where episodes begin (outside the timings) and the checks are put there."""
    import fcl
    import skimage.measure  # noqa: F401  (imported before the clocks start)
    t_read = tick()
    frames = read_bag(bag)
    t_read = (tick()[0] - t_read[0], tick()[1] - t_read[1])
    topics = sorted(frames)
    nf = min(len(frames[t]) for t in topics)
    t_origin = stamp_s(frames[topics[0]][0])
    times = [stamp_s(frames[topics[0]][k]) - t_origin for k in range(nf)]
    pairs = [(topics[i], topics[j]) for i in range(len(topics)) for j in range(i + 1, len(topics))]
    # per component: [wall s, CPU s of this process]
    T = {k: [0.0, 0.0] for k in ("decode", "mesh", "transfer", "bvh", "discrete", "motion",
                                 "continuous", "naive")}
    T["decode"] = [t_read[0], t_read[1]]  # reading the bag (MCAP, CDR) counts as decoding
    cpu0 = time.process_time() - t_read[1]
    wall0 = time.perf_counter() - t_read[0]
    req = fcl.CollisionRequest()
    creq = fcl.ContinuousCollisionRequest()  # FCL's default: conservative advancement, translation
    # FCL's naive solver at its default 10 iterations: discrete checks at t = 0, 1/9, ..., 1
    nreq = fcl.ContinuousCollisionRequest(ccd_solver_type=fcl.CCDSolverType.CCDC_NAIVE)
    ident = fcl.Transform()
    disc = {p: [] for p in pairs}   # per frame: colliding?
    cont = {p: [] for p in pairs}   # per period: time of contact in [0, 1], or None
    naive = {p: [] for p in pairs}  # the same with the naive solver
    tris = []
    rigid = dict(min_iou=1.0, max_volume_change=0.0, periods=0, non_rigid=0)
    ca_calls = ca_culled = 0
    check_wall = check_cpu = 0.0
    prev = None
    for k in range(nf):
        cur = {}
        for t in topics:
            m = frames[t][k]
            c0 = tick()
            occ = occupancy(m)
            c1 = tick()
            box = occupied_box(occ)
            v = f = None
            if box is not None:
                v, f = mesh_from_occupancy(occ, m, box)
            c2 = tick()
            model = None
            if v is not None:
                model = fcl.BVHModel()
                model.beginModel(len(v), len(f))
                model.addSubModel(v, f)
                c3 = tick()
                model.endModel()
                c4 = tick()
                tris.append(len(f))
                lo, hi = v.min(axis=0), v.max(axis=0)
            else:
                c3 = c4 = c2
                lo = hi = None
            add_time(T["decode"], c0, c1)
            add_time(T["mesh"], c1, c2)
            add_time(T["transfer"], c2, c3)
            add_time(T["bvh"], c3, c4)
            cur[t] = dict(occ=occ, msg=m, box=box, model=model, lo=lo, hi=hi,
                          obj=fcl.CollisionObject(model, ident) if model is not None else None)
        c0 = tick()
        for a, b in pairs:
            hit = False
            if cur[a]["obj"] is not None and cur[b]["obj"] is not None:
                r = fcl.CollisionResult()
                hit = fcl.collide(cur[a]["obj"], cur[b]["obj"], req, r) > 0 or r.is_collision
            disc[(a, b)].append(hit)
        add_time(T["discrete"], c0, tick())
        if prev is not None:
            c0 = tick()
            move = {}
            for t in topics:
                p0 = centroid(prev[t]["occ"], prev[t]["msg"], prev[t]["box"])
                p1 = centroid(cur[t]["occ"], cur[t]["msg"], cur[t]["box"])
                move[t] = np.zeros(3) if p0 is None or p1 is None else p1 - p0
            # swept boxes apart: no contact in this period (what a broad phase does)
            near = {}
            for a, b in pairs:
                pa, pb, ma, mb = prev[a], prev[b], move[a], move[b]
                near[(a, b)] = pa["model"] is not None and pb["model"] is not None and aabb_overlap(
                    np.minimum(pa["lo"], pa["lo"] + ma), np.maximum(pa["hi"], pa["hi"] + ma),
                    np.minimum(pb["lo"], pb["lo"] + mb), np.maximum(pb["hi"], pb["hi"] + mb))
            add_time(T["motion"], c0, tick())
            c1 = tick()
            for t in topics:  # whether the motion is rigid (a diagnostic, outside the timings)
                h = cur[t]["msg"].resolution
                v0, v1 = prev[t]["occ"].sum(), cur[t]["occ"].sum()
                iou = rigid_iou(prev[t]["occ"], cur[t]["occ"], np.round(move[t] / h))
                change = abs(v1 - v0) / max(v0, 1.0)
                rigid["min_iou"] = float(min(rigid["min_iou"], iou))
                rigid["max_volume_change"] = float(max(rigid["max_volume_change"], change))
                rigid["periods"] += 1
                rigid["non_rigid"] += int(iou < 0.5 or change > 0.2)
            c2 = tick()
            check_wall += c2[0] - c1[0]
            check_cpu += c2[1] - c1[1]
            for req_, found, key in ((creq, cont, "continuous"), (nreq, naive, "naive")):
                c0 = tick()
                for a, b in pairs:
                    toc = None
                    if near[(a, b)]:
                        if key == "continuous":
                            ca_calls += 1
                        # the pair's relative translation moves a; b stays (see README.md)
                        oa = fcl.CollisionObject(prev[a]["model"], fcl.Transform())
                        ob = fcl.CollisionObject(prev[b]["model"], fcl.Transform())
                        res = fcl.ContinuousCollisionResult()
                        fcl.continuousCollide(oa, fcl.Transform(np.asarray(move[a] - move[b], float)), ob,
                                              fcl.Transform(), req_, res)
                        if res.is_collide:
                            toc = float(res.time_of_contact)
                    elif key == "continuous":
                        ca_culled += 1
                    found[(a, b)].append(toc)
                add_time(T[key], c0, tick())
            if store is not None:
                c0, p0 = time.perf_counter(), time.process_time()
                _check_period(prev, move, pairs, cont, naive, disc, k - 1, store)
                check_wall += time.perf_counter() - c0
                check_cpu += time.process_time() - p0
        prev = cur
    wall = time.perf_counter() - wall0 - check_wall
    cpu = time.process_time() - cpu0 - check_cpu
    return dict(times=times, pairs=pairs, timings=T, wall=wall, cpu=cpu, disc=disc, cont=cont, naive=naive,
                tris_mean=float(np.mean(tris)) if tris else 0.0, tris_max=max(tris) if tris else 0,
                rigid=rigid, ca_calls=ca_calls, ca_culled=ca_culled, frames=nf,
                solver_check=store)


def _check_period(prev, move, pairs, cont, naive, disc, k, store):
    """Outside the timings, a check of FCL's conservative advancement (CA): in every period where
    it begins an episode, or where the naive solver or the next frame's discrete check sees a
    contact that CA does not, the same motion of the same meshes is sampled at 201 instants
    (FCL's naive solver), which gives the time of contact CA should have found to 1/200 of the
    period."""
    import fcl
    for a, b in pairs:
        c = cont[(a, b)]
        began = c[k] is not None and (k == 0 or c[k - 1] is None)
        unseen = c[k] is None and (naive[(a, b)][k] is not None or disc[(a, b)][k + 1])
        if not (began or unseen):
            continue
        oa = fcl.CollisionObject(prev[a]["model"], fcl.Transform())
        ob = fcl.CollisionObject(prev[b]["model"], fcl.Transform())
        req = fcl.ContinuousCollisionRequest(num_max_iterations=201, toc_err=1e-6,
                                             ccd_solver_type=fcl.CCDSolverType.CCDC_NAIVE)
        res = fcl.ContinuousCollisionResult()
        fcl.continuousCollide(oa, fcl.Transform(np.asarray(move[a] - move[b], float)), ob,
                              fcl.Transform(), req, res)
        store.setdefault((a, b), []).append(
            dict(period=k, ca=c[k], naive=naive[(a, b)][k],
                 sampled=float(res.time_of_contact) if res.is_collide else None))


# ---- episodes and errors -------------------------------------------------------------------

def episodes_from_frames(flags, times):
    out, start = [], None
    for k, f in enumerate(flags):
        if f and start is None:
            start = k
        if not f and start is not None:
            out.append((times[start], times[k - 1]))
            start = None
    if start is not None:
        out.append((times[start], times[len(flags) - 1]))
    return out


def episodes_from_periods(tocs, times):
    """A run of periods with a contact: it begins at the first period's time of contact; its end
    is only known to lie before the last period's end."""
    out, start = [], None
    for k, toc in enumerate(tocs):
        if toc is not None and start is None:
            start = times[k] + toc * (times[k + 1] - times[k])
        if toc is None and start is not None:
            out.append((start, times[k]))
            start = None
    if start is not None:
        out.append((start, times[len(tocs)]))
    return out


def score(exact, found, bounds=None):
    """A detected episode that overlaps an exact contact interval finds it; the earliest such
    episode's start is its first contact. Returns the onset errors (detected - exact), the
    exact episodes missed (as indices), the detected episodes that overlap no exact one (false
    alarms, e.g. voxelised bodies touching where the true ones do not), and the stated
    bounds of the matched onsets."""
    errs, missed, bnds, true = [], [], [], set()
    for n, (s, e) in enumerate(exact):
        hits = [i for i, (fs, fe) in enumerate(found) if fs <= e and fe >= s]
        true.update(hits)
        if not hits:
            missed.append(n)
            continue
        first = min(hits, key=lambda i: found[i][0])
        errs.append(found[first][0] - s)
        if bounds is not None:
            bnds.append(bounds[first])
    false = len(found) - len(true)
    return errs, missed, false, bnds


# ---- the benchmark -------------------------------------------------------------------------

def median(v):
    return statistics.median(v) if v else float("nan")


def bench_case(case, a, work):
    bag = work / f"{case.scene}-{'-'.join(x.strip('-') for x in case.args)}.mcap"
    if case.make:
        case.make(bag)
    else:
        subprocess.run([str(a.bin), "scene", case.scene, *case.args, "--out", str(bag), "--overwrite"],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    log(f"{case.label}: {bag.name}")
    rec = dict(replay_wall=[], replay_cpu=[], check_wall=[], check_cpu=[], check_detect=[],
               check_resolve=[], fcl=[])
    rr = cr = fr = None
    for rep in range(a.reps):
        w, c = run_timed([str(a.bin), "replay", str(bag), "--launch", str(DETECT_CFG),
                          "--report", str(work / "replay.json"), "--overwrite"], work / "replay.log")
        rec["replay_wall"].append(w)
        rec["replay_cpu"].append(c)
        rr = json.loads((work / "replay.json").read_text())
        if not a.no_check:
            w, c = run_timed([str(a.bin), "check", str(bag), "--report", str(work / "check.json"),
                              "--overwrite"], work / "check.log")
            cr = json.loads((work / "check.json").read_text())
            tm = cr["timings_ms"]
            rec["check_wall"].append(w)
            rec["check_cpu"].append(c)
            rec["check_detect"].append((tm["mesh"] + tm["check"]) / 1e3)
            rec["check_resolve"].append(tm["resolve"] / 1e3)
        fr = fcl_run(bag, {} if a.check_ccd and rep == 0 else None)
        rec["fcl"].append(fr)
        log(f"  rep {rep + 1}/{a.reps}: replay {rec['replay_wall'][-1]:.2f} s"
            + (f", check {rec['check_wall'][-1]:.2f} s" if rec["check_wall"] else "")
            + f", FCL {fr['wall']:.2f} s (conservative advancement {fr['timings']['continuous'][0]:.2f} s)")
    solver = rec["fcl"][0]["solver_check"]
    periods = fr["frames"] - 1
    times = fr["times"]
    span = times[-1]
    period = span / periods
    exact = case.exact_fn(span)
    # chronotope's answers
    out = dict(label=case.label, bag=bag.name, frames=fr["frames"], periods=periods, span_s=span,
               frame_period_s=period, exact={" x ".join(k): v for k, v in exact.items()},
               tris_mean=fr["tris_mean"], tris_max=fr["tris_max"], rigid=fr["rigid"],
               ca_calls=fr["ca_calls"], ca_culled=fr["ca_culled"], methods={}, pairs={})
    rp = chronotope_pairs(rr)
    cp = chronotope_pairs(cr) if cr else {}
    methods = {}

    def add(name, key_found, wall, cpu, build=None, queries=None, extra=None, unsure_of=None):
        allerr, allfalse, allb, nexact, nmiss, nwarned = [], 0, [], 0, 0, 0
        for pk, ex in exact.items():
            found, bounds = key_found(pk)
            errs, missed, false, bnds = score(ex, found, bounds)
            spans = [u["span_s"] for u in (unsure_of(pk) if unsure_of else [])]
            warned = [n for n in missed if any(u[0] <= ex[n][1] and u[1] >= ex[n][0] for u in spans)]
            allerr += errs
            allfalse += false
            allb += bnds
            nexact += len(ex)
            nmiss += len(missed)
            nwarned += len(warned)
            out["pairs"].setdefault(" x ".join(pk), {})[name] = dict(
                found=found, onset_errors=errs, missed=len(missed), warned=len(warned),
                false_alarms=false, bounds=bnds)
        m = dict(wall=wall, cpu=cpu, build=build, queries=queries, errors=allerr, missed=nmiss,
                 warned=nwarned, contacts=nexact, false_alarms=allfalse, bounds=allb)
        if extra:
            m.update(extra)
        methods[name] = m

    def from_report(pairs):
        def f(pk):
            p = pairs.get(pk)
            if p is None:
                return [], []
            ivs = [tuple(x) for x in p["intervals_s"]]
            eb = p.get("interval_error_bounds_s") or []
            bnds = [b[0] if b else None for b in eb] + [None] * (len(ivs) - len(eb))
            return ivs, bnds
        return f

    verdicts = {" x ".join(pk): p["verdict"] for pk, p in rp.items()}
    unsure = {" x ".join(pk): p["unsure_spans_s"] for pk, p in rp.items() if p.get("unsure_spans_s")}
    add("chronotope replay (streamed)", from_report(rp), median(rec["replay_wall"]) / periods,
        median(rec["replay_cpu"]) / periods, extra=dict(verdicts=verdicts, unsure=unsure),
        unsure_of=lambda pk: rp.get(pk, {}).get("unsure_spans_s", []))
    if cp:
        add("chronotope check (at once)", from_report(cp), median(rec["check_detect"]) / periods,
            None,
            extra=dict(wall_with_resolutions=median(rec["check_wall"]) / periods,
                       verdicts={" x ".join(pk): p["verdict"] for pk, p in cp.items()}),
            unsure_of=lambda pk: cp.get(pk, {}).get("unsure_spans_s", []))
    # FCL: per frame period, the median over the repetitions of each component (wall, CPU)
    tm = {k: [median([r["timings"][k][i] for r in rec["fcl"]]) / periods for i in (0, 1)]
          for k in fr["timings"]}

    def total(*keys):
        return [sum(tm[k][i] for k in keys) for i in (0, 1)]
    build = total("decode", "mesh", "bvh")
    for name, found, queries in (
            ("FCL discrete (every frame)", lambda pk: episodes_from_frames(fr["disc"][pk], times),
             ("discrete",)),
            ("FCL continuous (conservative advancement)",
             lambda pk: episodes_from_periods(fr["cont"][pk], times), ("motion", "continuous")),
            ("FCL continuous (naive, 10 steps)",
             lambda pk: episodes_from_periods(fr["naive"][pk], times), ("motion", "naive"))):
        q = total(*queries)
        add(name, lambda pk, f=found: (f(pk), None), build[0] + q[0], build[1] + q[1],
            build=build[0], queries=q[0], extra=dict(transfer=tm["transfer"][0]))
    out["methods"] = methods
    out["fcl_timings_per_period"] = tm
    out["raw"] = dict(replay_wall=rec["replay_wall"], replay_cpu=rec["replay_cpu"],
                      check_wall=rec["check_wall"], check_cpu=rec["check_cpu"],
                      check_detect=rec["check_detect"],
                      check_resolve=rec["check_resolve"],
                      fcl_wall=[r["wall"] for r in rec["fcl"]], fcl_cpu=[r["cpu"] for r in rec["fcl"]],
                      fcl_continuous=[r["timings"]["continuous"][0] for r in rec["fcl"]])
    if solver:
        out["solver_check"] = {" x ".join(k): v for k, v in solver.items()}
    return out


# ---- the write-up ---------------------------------------------------------------------------

def ms(x):
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x * 1e3:.1f} ms"


def fmt_err(errs):
    if not errs:
        return "—"
    worst = max(errs, key=abs)
    return f"{worst:+.4f} s" + (f" (mean \\|e\\| {np.mean(np.abs(errs)):.4f})" if len(errs) > 1 else "")


def fmt_bound(m):
    if not m["bounds"]:
        return "—"
    b = [x for x in m["bounds"] if x is not None]
    if not b:
        return "none (ill-conditioned)"
    n_in = sum(1 for e, x in zip(m["errors"], m["bounds"]) if x is not None and abs(e) <= x)
    none = len(m["bounds"]) - len(b)
    return f"≤ {max(b):.4f} s, {n_in} of {len(m['bounds'])} within" + (f" ({none} none)" if none else "")


def said_clear(r, name):
    """Exact episodes a chronotope method missed in pairs it called clear."""
    m = r["methods"][name]
    verdicts = m.get("verdicts") or r["methods"]["chronotope replay (streamed)"].get("verdicts", {})
    n = 0
    for pk, per in r["pairs"].items():
        d = per.get(name)
        if d and d["missed"] > d.get("warned", 0) and verdicts.get(pk) == "clear":
            n += d["missed"] - d.get("warned", 0)
    return n


def fmt_miss(m, clear=0):
    out = f"{m['missed']} of {m['contacts']}"
    notes = []
    if m.get("warned"):
        notes.append(f"{m['warned']} said unsure")
    if clear:
        notes.append(f"{clear} said clear")
    return out + (f" ({', '.join(notes)})" if notes else "")


SHORT = {
    "chronotope replay (streamed)": "chronotope `replay` (streamed)",
    "chronotope check (at once)": "chronotope `check` (at once)",
    "FCL discrete (every frame)": "FCL discrete",
    "FCL continuous (conservative advancement)": "FCL continuous (CA)",
    "FCL continuous (naive, 10 steps)": "FCL continuous (naive ×10)",
}


def main_table(results):
    L = ["| scene | method | per frame period | CPU per period | FCL: build + queries | first contact error (worst) | stated bound | missed | false |",
         "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        for name, m in r["methods"].items():
            bq = "—" if m["build"] is None else f"{ms(m['build'])} + {ms(m['queries'])}"
            bound = fmt_bound(m) if name.startswith("chronotope") else "none"
            clear = said_clear(r, name) if name.startswith("chronotope") else 0
            L.append(f"| {r['label']} | {SHORT.get(name, name)} | {ms(m['wall'])} | {ms(m['cpu'])} | {bq} | "
                     f"{fmt_err(m['errors'])} | {bound} | {fmt_miss(m, clear)} | {m['false_alarms']} |")
    return L


def summary_tables(results):
    """Two compact tables: time per frame period, and first contacts against the exact answers."""
    R, C, D, A, N = ("chronotope replay (streamed)", "chronotope check (at once)",
                     "FCL discrete (every frame)", "FCL continuous (conservative advancement)",
                     "FCL continuous (naive, 10 steps)")

    def t(m):
        return f"{m['wall'] * 1e3:.1f}" + ("" if m["cpu"] is None else f" ({m['cpu'] * 1e3:.1f})")

    L = ["Time per frame period, ms: wall (CPU). chronotope on two cores, FCL on one; FCL with "
         "building (reading and decoding, marching cubes, BVH), and its queries alone.\n",
         "| scene | chronotope `replay` | chronotope `check` | FCL discrete | FCL continuous (CA) | "
         "FCL continuous (naive ×10) | FCL queries alone: discrete / CA / naive |",
         "|---|---|---|---|---|---|---|"]
    for r in results:
        m = r["methods"]
        q = " / ".join(f"{m[k]['queries'] * 1e3:.1f}" for k in (D, A, N))
        L.append(f"| {r['label']} | {t(m[R])} | " + (f"{m[C]['wall'] * 1e3:.1f}" if C in m else "—")
                 + f" | {t(m[D])} | {t(m[A])} | {t(m[N])} | {q} |")

    def e(m, bound=False, clear=0):
        out = "—" if not m["errors"] else f"{max(m['errors'], key=abs):+.4f}"
        if bound:
            b = [x for x in m["bounds"] if x is not None]
            if b:
                out += f" (≤ {max(b):.3f})"
        notes = ([f"{m['warned']} said unsure"] if m.get("warned") else []) + \
            ([f"{clear} said clear"] if clear else [])
        miss = f"{m['missed']}" + (f" ({', '.join(notes)})" if notes else "")
        return f"{out}; {miss}; {m['false_alarms']}"

    L += ["", "First contact: the worst error against the exact answer, s (chronotope's stated "
          "bound); contacts missed; contacts reported where there are none.\n",
          "| scene | exact contacts | chronotope `replay` | FCL discrete | FCL continuous (CA) | "
          "FCL continuous (naive ×10) |",
          "|---|---|---|---|---|---|"]
    for r in results:
        m = r["methods"]
        L.append(f"| {r['label']} | {m[R]['contacts']} | {e(m[R], True, said_clear(r, R))} | {e(m[D])} | "
                 f"{e(m[A])} | {e(m[N])} |")
    return L


def write_md(results, meta, path):
    L = []
    L.append(f"# chronotope against FCL, {meta['date']}\n")
    L.append("Command (from the repository root):\n\n```sh\n" + meta["command"] + "\n```\n")
    L.append(f"Machine (`lscpu | head`); load average {meta['load_start']} at the start and "
             f"{meta['load_end']} at the end; the run took {meta['elapsed_s'] / 60:.1f} min:\n\n```\n"
             + meta["lscpu"] + "\n```\n")
    L.append("Versions: " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()) + ".\n")
    L.append(f"chronotope: `{meta['bin']}` ({meta['bin_version']}, {meta['bin_sha']}, built "
             f"{meta['bin_mtime']}); work tree at {meta['git']}.\n")
    reps = meta.get("reps") or len(results[0]["raw"]["replay_wall"])
    L.append(f"Medians of {reps} repetitions; each repetition runs chronotope `replay`, `check` "
             "and one FCL pass in turn. *Per frame period* is a run's wall time / (frames − 1); "
             "*CPU* the CPU time over the same (chronotope's `replay` uses both cores, FCL one "
             "Python thread; `check`'s CPU, resolutions included, is in the runs per scene). "
             "chronotope `replay` runs `bench/fcl/detect.yaml` (every pair, no resolution), timed "
             "from outside (process start and reading the bag included); `check`'s figure is its "
             "report's `mesh` + `check` timings (measured inside the process; its resolutions, "
             "always computed, left out). FCL's *build* is reading the bag and decoding the "
             "frames, marching cubes and `BVHModel.endModel()` (OBB-RSS); handing the arrays to "
             "python-fcl (`addSubModel`, a Python loop) is left out and listed per scene. FCL's "
             "*queries* are `collide` (discrete), or the occupancy-centroid motion estimate plus "
             "`continuousCollide` (continuous: conservative advancement, FCL's default, or the "
             "naive solver's 10 discrete checks per period). *First contact error*: for each "
             "exact contact episode, the start of the earliest detected episode that overlaps "
             "it, minus the exact start (positive: late); the worst over a scene's episodes. "
             "*Missed*: exact episodes that no detected episode overlaps. *False*: detected "
             "episodes that overlap no exact one (voxelised bodies touching where the true ones "
             "do not, faces touching). See bench/fcl/README.md.\n")
    L += summary_tables(results)
    L += ["", "All figures:\n"]
    L += main_table(results)
    L.append("")
    L.append("## Per scene\n")
    for r in results:
        L.append(f"### {r['label']}\n")
        L.append(f"{r['frames']} frames over {r['span_s']:.3f} s (period {r['frame_period_s'] * 1e3:.2f} ms). "
                 f"FCL's meshes: {r['tris_mean']:.0f} triangles per body and frame on average "
                 f"(at most {r['tris_max']}). Motion between frames: a frame against the one "
                 f"before shifted by whole voxels, IoU at least {float(r['rigid']['min_iou']):.3f}, "
                 f"occupied volume changing by at most {float(r['rigid']['max_volume_change']) * 100:.1f} %, "
                 f"{int(r['rigid']['non_rigid'])} of {r['rigid']['periods']} body-periods not rigid "
                 "(IoU under 0.5 or volume changing by over 20 %). "
                 f"`continuousCollide` (CA) called {r['ca_calls']} times; {r['ca_culled']} "
                 "pair-periods left out because their swept boxes are apart.\n")
        tm = r["fcl_timings_per_period"]
        L.append("FCL per frame period, wall (CPU): " + ", ".join(
            f"{k} {ms(v[0])} ({ms(v[1])})" for k, v in tm.items()) + ".\n")
        raw = r["raw"]
        L.append("Runs (s): `replay` " + ", ".join(f"{x:.2f}" for x in raw["replay_wall"])
                 + (("; `check` " + ", ".join(f"{x:.2f}" for x in raw["check_wall"])
                     + " (CPU " + ", ".join(f"{x:.2f}" for x in raw["check_cpu"]) + ")"
                     + " (detection " + ", ".join(f"{x:.2f}" for x in raw["check_detect"])
                     + ", resolutions " + ", ".join(f"{x:.2f}" for x in raw["check_resolve"]) + ")")
                    if raw["check_wall"] else "")
                 + "; FCL pass " + ", ".join(f"{x:.2f}" for x in raw["fcl_wall"])
                 + " (of it CA " + ", ".join(f"{x:.2f}" for x in raw["fcl_continuous"]) + ").\n")
        names = list(r["methods"].keys())
        L.append("| pair | exact (s) | " + " | ".join(SHORT.get(n, n) for n in names) + " |")
        L.append("|---|---|" + "---|" * len(names))
        for pk, ex in r["exact"].items():
            row = [pk.replace("/occupancy", ""), ", ".join(f"{s:.4f}–{e:.4f}" for s, e in ex) or "none"]
            for name in names:
                d = r["pairs"][pk][name]
                if name.startswith("FCL continuous"):
                    found = ", ".join(f"{s:.4f}–(≤{e:.4f})" for s, e in d["found"])
                else:
                    found = ", ".join(f"{s:.4f}–{e:.4f}" for s, e in d["found"])
                row.append(found or "none")
            L.append("| " + " | ".join(row) + " |")
        ver = r["methods"]["chronotope replay (streamed)"].get("verdicts", {})
        uns = r["methods"]["chronotope replay (streamed)"].get("unsure", {})
        L.append("\nchronotope's verdicts: " + ", ".join(f"{k.replace('/occupancy', '')} {v}" for k, v in ver.items()) + ".")
        for k, v in uns.items():
            L.append(f"Unsure spans of {k.replace('/occupancy', '')}: " + "; ".join(
                f"{u['span_s'][0]:.3f}–{u['span_s'][1]:.3f} s, {u['body'].replace('/occupancy', '')} "
                f"{u['code']}: {u['resolve']}" for u in v) + ".")
        if r.get("solver_check"):
            L.append("\nFCL's conservative advancement (CA) checked against the same motion of the "
                     "same meshes sampled at 201 instants (FCL's naive solver), in the periods "
                     "where CA begins an episode or misses one the others see (times of contact "
                     "as fractions of the period):\n")
            for pk, v in r["solver_check"].items():
                f = lambda x: "none" if x is None else f"{x:.3f}"
                L.append(f"- {pk.replace('/occupancy', '')}: " + "; ".join(
                    f"period {x['period']}: CA {f(x['ca'])}, naive ×10 {f(x['naive'])}, "
                    f"sampled {f(x['sampled'])}" for x in v))
        L.append("")
    path.write_text("\n".join(L) + "\n")


def versions():
    out = {"Python": platform.python_version()}
    try:
        from importlib.metadata import version
        for p in ("python-fcl", "numpy", "scikit-image", "mcap", "mcap-ros2-support"):
            try:
                out[p] = version(p)
            except Exception:
                out[p] = "?"
    except Exception:
        pass
    out["FCL (bundled)"] = "0.7.0" if out.get("python-fcl", "").startswith("0.7.0") else "?"
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", type=Path, default=ROOT / "target" / "release" / "chronotope")
    ap.add_argument("--scenes", nargs="+",
                    default=["four-spheres", "machine-tool", "periodic", "sparse", "percent", "graze"],
                    help="four-spheres (at --grids), machine-tool (at --mt-grids), periodic, sparse "
                         "(four-spheres 64³ with --sparse-frames frames), percent (four-spheres with "
                         "PERCENT frames at --percent-grids), graze (written by this script: see --graze)")
    ap.add_argument("--grids", nargs="+", type=int, default=[32, 64, 128], help="four-spheres grids")
    ap.add_argument("--mt-grids", nargs="+", type=int, default=[64, 128], help="machine-tool grids")
    ap.add_argument("--periodic-duration", type=float, default=10.0)
    ap.add_argument("--sparse-frames", nargs="+", type=int, default=[3, 5],
                    help="frame counts of four-spheres at 64³ with few frames")
    ap.add_argument("--percent-grids", nargs="+", type=int, default=[64])
    ap.add_argument("--graze", nargs="+", default=["0.235,0.24", "0.24,0.2"],
                    help="graze scenes as MISS,STEP in metres: the spheres' centres pass MISS apart "
                         "(radii 0.125: the contact is 0.25 - MISS deep), the moving one STEP a frame")
    ap.add_argument("--encoding", choices=["bits", "percent"], default="bits",
                    help="the encoding of every scene but `percent`'s")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--no-check", action="store_true", help="leave out `chronotope check`")
    ap.add_argument("--no-check-ccd", dest="check_ccd", action="store_false",
                    help="leave out the dense sampling that checks FCL's continuous solver")
    ap.add_argument("--out", type=Path, default=HERE / "results.md")
    ap.add_argument("--json", type=Path, help="the figures as JSON too")
    ap.add_argument("--work", type=Path, help="where the bags and reports go (default: a temporary directory)")
    ap.add_argument("--from-json", type=Path, help="write --out again from the --json of an earlier run")
    a = ap.parse_args()
    if a.from_json:
        d = json.loads(a.from_json.read_text())
        write_md(d["results"], d["meta"], a.out)
        return
    if not a.bin.exists():
        raise SystemExit(f"no binary at {a.bin}")
    t_start = time.perf_counter()
    tmp = None
    if a.work:
        work = a.work
        work.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="fcl-compare-")
        work = Path(tmp.name)
    meta = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                command="python bench/fcl/compare.py " + " ".join(sys.argv[1:]),
                load_start="%.2f %.2f %.2f" % os.getloadavg(), versions=versions(), bin=str(a.bin),
                reps=a.reps)
    try:
        meta["lscpu"] = "\n".join(subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines()[:10])
    except OSError:
        meta["lscpu"] = platform.processor()
    h = hashlib.sha256(a.bin.read_bytes()).hexdigest()[:12]
    meta["bin_version"] = subprocess.run([str(a.bin), "--version"], capture_output=True,
                                         text=True).stdout.strip()
    meta["bin_sha"] = f"sha256 {h}"
    meta["bin_mtime"] = datetime.datetime.fromtimestamp(a.bin.stat().st_mtime, datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    try:
        meta["git"] = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                     capture_output=True, text=True).stdout.strip() or "?"
    except OSError:
        meta["git"] = "?"
    results = [bench_case(c, a, work) for c in build_cases(a)]
    meta["load_end"] = "%.2f %.2f %.2f" % os.getloadavg()
    meta["elapsed_s"] = time.perf_counter() - t_start
    write_md(results, meta, a.out)
    if a.json:
        a.json.write_text(json.dumps(dict(meta=meta, results=results), indent=1, default=str))
    log(f"wrote {a.out} ({meta['elapsed_s']:.0f} s)")
    if tmp:
        tmp.cleanup()


if __name__ == "__main__":
    main()
