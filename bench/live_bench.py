#!/usr/bin/env python3
"""Live benchmarks of the suite on DDS, each a rerunnable command:

  python3 bench/live_bench.py cyclone   [--loops 3] [--hz 10]
      A Cyclone DDS peer (PyPI cyclonedds, tests/py/cyclone_peer.py's types) publishes the
      four-spheres frames at --hz frames per second, --loops times (header stamps shifted per
      loop, a pause longer than the mesher's idle timeout between loops, so every loop is a new
      stream and a new check), into `chronotope launch launch_configs/four_spheres.yaml`, and
      takes the report, labels and markers.  Prints, per topic, delivered/sent (sent from the
      launch's --summary), the transport latency (reception at the peer minus the DDS source
      timestamp, same host and clock; includes the peer's Python decoding) and the end-to-end
      time from a loop's last frame to its report (includes the mesher's idle timeout, 2 s).
  python3 bench/live_bench.py idle      [--seconds 30]
      CPU load and resident memory of an idle `chronotope launch launch_configs/machine_tool.yaml`.
  python3 bench/live_bench.py mesher    [--hz 10] [--seconds S | --frames N] [--bag B] [--grid 128]
      `chronotope play --rate` plays the scene's frames (0.1 s apart) at --hz frames per second
      (--seconds S: a scene of S x hz frames per body).
      Prints, per input topic, frames received, dropped (the launch's --summary), the lag
      p50/p99/max (reader to end of handling) also in frame periods, the launch's CPU while
      playing and in all, its RSS and peak RSS, and the CPU per thread of the launch.
  python3 bench/live_bench.py carving   [--setup small|big|alone-small|alone-big] [--seconds 60]
                                        [--frame-hz 30] [--pose-hz 1000] [--speed 0.05] [--display]
      A Cyclone DDS peer sends geometry_msgs/PoseStamped on /haptic/pose at --pose-hz for
      --seconds (absolute deadlines: sleep, then spin for the last 0.3 ms), a knife slicing
      back and forth through the block in fresh kerfs, into a launch written from --setup:
      `small` = the carving_session.yaml block (60 x 60 x 30 mm at 2 mm), `big` = 360 x 360 x
      16 mm at 0.5 mm (~1.1M surfels), both with a mesher and a checker of /carving/occupancy
      (a lone body: no fixture publishes live); `alone-*` = the carving node alone; frames at
      --frame-hz. Another process takes /carving/wrench and the poses. Latency of a pose = its
      wrench's DDS source timestamp minus the pose's (matched by header stamp, which the node
      copies). Prints poses sent, wrenches received, poses without a wrench, latency
      p50/p99/max, the launch's CPU and RSS, and the peer's achieved rate and jitter.
      --display: a third process subscribes to the surfels and occupancy as a display would
      (reliable, keep last 1; it never decodes them). Without a subscriber
      the node's writers keep every frame until RustDDS's 8192-sample limit (no reader ever
      acknowledges them): the launch's RSS grows by each frame's bytes.
  python3 bench/live_bench.py stop      [--signals 1|2] [--hz 30] [--frames 400] [--seconds 12]
      How long a launch behind its input takes to stop. `chronotope play` plays a machine-tool
      scene of --frames frames per body at --hz frames per second into `launch machine_tool.yaml`
      (faster than the checker keeps up, so its queue fills), is stopped after --seconds, then
      the launch gets --signals SIGINTs one second apart (1: stop, it finishes what is queued;
      2: abort, what is queued is discarded). Prints the time from the first signal to the
      launch's exit, and per node the messages received, dropped and discarded (--summary).
  python3 bench/live_bench.py periodic  [--seconds 600]
      A Cyclone DDS peer (tests/py/cyclone_peer.py) plays the periodic scene (48^3, 20 Hz,
      `chronotope scene periodic --duration S`) with its recorded timing into
      `chronotope launch launch_configs/periodic.yaml` and takes the contact events and reports.
      Prints contacts begun while streaming and in the last report, the latency from writing
      the frame that completes a contact's slab to taking its event (p50/p99/max, all events and
      BEGIN), and the launch's resident memory every 10 s (a line per minute: min and max).

  python3 bench/live_bench.py robot     [--loops 3] [--grid 128] [--frame-hz 30] [--joint-hz 500]
      `chronotope scene robot-cell` at those rates (4 s: the arm dips, the table shuttles out)
      played --loops times by a Cyclone peer (tests/py/cyclone_peer.py --loops: stamps shifted
      per loop, 3.5 s between loops) into `launch robot_cell.yaml` (robot node at the table's
      stamps, mesher, checker). Prints per input topic received, dropped and lag (--summary),
      the contact events' latency (from writing the last input that completes the contact's
      slab: the table's frame and the first joint state at or after its stamp, to taking the
      event at the peer) also in frame periods, the launch's CPU and RSS per minute.
  python3 bench/live_bench.py cloud     [--loops 3] [--cloud-grid 64] [--frames 150]
                                        [--frame-hz 30] [--camera 640x480]
      The same for `chronotope scene person-cell` (a depth camera's organised cloud of
      WxH points, NaN where a ray misses, an OctoMap at half the rate, the machine-tool
      bodies' frames) into `launch person_cell.yaml`; latency from the cell's frames.

Build first: cargo build --release.  --exe selects another binary.  --json FILE writes the
figures as JSON too (with the load average: other builds share the cores).
Domain: --domain, else 120 + pid % 50 (never ROS_DOMAIN_ID's value), loopback discovery.
"""

import argparse
import gc
import importlib.util
import json
import math
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_EXE = ROOT / "target" / "release" / "chronotope"


def log(msg: str) -> None:
    print(f"live_bench: {msg}", file=sys.stderr, flush=True)


def peer_module():
    """tests/py/cyclone_peer.py, imported for its types and readers (it sets CYCLONEDDS_URI)."""
    spec = importlib.util.spec_from_file_location("cyclone_peer", ROOT / "tests/py/cyclone_peer.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def proc_cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process (and its reaped children) from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    tick = os.sysconf("SC_CLK_TCK")
    return sum(int(fields[i]) for i in (11, 12, 13, 14)) / tick


def proc_rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def pct(v, q):
    if not v:
        return float("nan")
    v = sorted(v)
    return v[min(len(v) - 1, round((len(v) - 1) * q))]


def start_launch(exe, cfg, domain, seconds, summary, logf):
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), RUST_LOG=os.environ.get("RUST_LOG", "warn"))
    return subprocess.Popen(
        [str(exe), "launch", str(cfg), "--duration", str(seconds), "--summary", str(summary)],
        env=env, stdout=subprocess.DEVNULL, stderr=open(logf, "w"))


def wait(p, what, timeout):
    try:
        p.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        raise SystemExit(f"{what} did not finish within {timeout} s")
    if p.returncode != 0:
        raise SystemExit(f"{what} exited with {p.returncode}")


def stop_launch(p, what, finish_s, abort_s=30):
    """Stops a launch: one SIGTERM (the nodes finish what is queued), and a second one (an
    abort: what waits in the queues is discarded and counted) if it has not finished within
    `finish_s`. Returns whether it had to be aborted."""
    p.terminate()
    try:
        p.wait(timeout=finish_s)
        aborted = False
    except subprocess.TimeoutExpired:
        log(f"{what} still finishing after {finish_s} s: aborting (a second SIGTERM)")
        p.terminate()
        aborted = True
    wait(p, what, abort_s if aborted else 1)
    return aborted


# ---- cyclone ----------------------------------------------------------------------------

def bench_cyclone(a, exe, domain, tmp):
    cp = peer_module()
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    bag = ROOT / "bags/four-spheres-32-bits.mcap"
    cfg = ROOT / "launch_configs/four_spheres.yaml"
    frames = cp.read_frames(str(bag))
    stamps = sorted({m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, _, m in frames})
    n_steps = len(stamps)
    span_ns = stamps[-1] - stamps[0] + int(10**9 / a.hz)
    gap_s = 3.5  # > the mesher's idle timeout (2 s): each loop is a stream of its own
    run_s = a.loops * (n_steps / a.hz + gap_s) + 40
    summary = tmp / "summary.json"
    launch = start_launch(exe, cfg, domain, int(run_s), summary, tmp / "launch.log")
    # A RustDDS peer too: `chronotope record` keeps each message's DDS source timestamp as its
    # publish time, next to the time it was received (log time).
    rec_bag = tmp / "record.mcap"
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), RUST_LOG="warn")
    record = subprocess.Popen(
        [str(exe), "record", "/checker/report", "/checker/labels", "/checker/markers",
         "--out", str(rec_bag), "--discovery", "15"],
        env=env, stdout=subprocess.DEVNULL, stderr=open(tmp / "record.log", "w"))

    dp = DomainParticipant(domain)
    frame_qos = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                    Policy.Durability.Volatile, Policy.History.KeepLast(16))
    topics = sorted({t for _, t, _ in frames})
    writers = {t: DataWriter(dp, Topic(dp, cp.dds_topic(t), cp.VoxelGrid), qos=frame_qos) for t in topics}
    rqos = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
               Policy.Durability.Volatile, Policy.History.KeepLast(256))
    readers = {
        "/checker/report": DataReader(dp, Topic(dp, "rt/checker/report", cp.InterferenceReport), qos=rqos),
        "/checker/labels": DataReader(dp, Topic(dp, "rt/checker/labels", cp.TetLabels), qos=rqos),
    }
    # Markers (~1.1 MB, ~0.5 s each to decode in Python) in a process of their own, so that
    # their decoding does not delay the report and labels.
    ctx = multiprocessing.get_context("spawn")
    marker_q, marker_ready = ctx.Queue(), ctx.Event()
    marker_proc = ctx.Process(target=take_markers, args=(domain, run_s, marker_q, marker_ready))
    marker_proc.start()
    deadline = time.monotonic() + 30
    while any(not w.get_matched_subscriptions() for w in writers.values()) or \
            any(not r.get_matched_publications() for r in readers.values()) or \
            not marker_ready.is_set():
        if time.monotonic() > deadline:
            launch.kill()
            marker_proc.kill()
            raise SystemExit("no match with chronotope launch within 30 s")
        time.sleep(0.05)

    got = {t: [] for t in readers}  # (receive wall ns, source timestamp ns)
    take_s = {t: [] for t in readers}  # Python's take() (decoding) per sample
    report_at = []  # receive wall ns of each report

    def drain():
        for t, r in readers.items():
            while True:
                c0 = time.perf_counter()
                ss = r.take(N=1)
                if not ss:
                    break
                now = time.time_ns()
                take_s[t].append(time.perf_counter() - c0)
                got[t].append((now, ss[0].sample_info.source_timestamp))
                if t == "/checker/report":
                    report_at.append(now)

    loop_end = []
    by_step = {s: i for i, s in enumerate(stamps)}
    for k in range(a.loops):
        t0 = time.monotonic()
        for _, topic, msg in frames:
            st = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            step = by_step[st]
            due = t0 + step / a.hz
            while time.monotonic() < due:
                drain()
                time.sleep(0.001)
            shifted = st + k * (span_ns + 10**9 * 10)
            msg.header.stamp = cp.Time(sec=shifted // 10**9, nanosec=shifted % 10**9)
            writers[topic].write(msg)
            msg.header.stamp = cp.Time(sec=st // 10**9, nanosec=st % 10**9)
        loop_end.append(time.time_ns())
        end = time.monotonic() + gap_s
        while time.monotonic() < end or len(report_at) < k + 1 and time.monotonic() < end + 30:
            drain()
            time.sleep(0.001)
    quiet = time.monotonic()
    while time.monotonic() - quiet < a.quiet:
        n = sum(len(v) for v in got.values())
        drain()
        if sum(len(v) for v in got.values()) != n:
            quiet = time.monotonic()
        time.sleep(0.002)
    launch.terminate()
    wait(launch, "chronotope launch", 30)
    time.sleep(1)
    record.terminate()
    wait(record, "chronotope record", 30)
    rust = {}
    from mcap.reader import make_reader
    with open(rec_bag, "rb") as f:
        for _, ch, m in make_reader(f).iter_messages():
            rust.setdefault(ch.topic, []).append((m.log_time - m.publish_time) / 1e6)
    got["/checker/markers"], take_s["/checker/markers"] = marker_q.get(timeout=60)
    marker_proc.join(timeout=10)
    sent = json.loads(summary.read_text())["transport"]["sent"]
    rows = []
    for t, v in got.items():
        lat = [(r - s) / 1e6 for r, s in v]
        rows.append({
            "topic": t, "sent": sent.get(t, 0), "delivered": len(v),
            "distinct_source_timestamps": len({st for _, st in v}),
            "latency_ms_p50": pct(lat, 0.5), "latency_ms_p99": pct(lat, 0.99),
            "latency_ms_max": max(lat) if lat else float("nan"),
            "peer_decode_ms_p50": pct([x * 1e3 for x in take_s[t]], 0.5),
            "rustdds_delivered": len(rust.get(t, [])),
            "rustdds_latency_ms_p50": pct(rust.get(t, []), 0.5),
            "rustdds_latency_ms_max": max(rust.get(t, [float("nan")])),
        })
    e2e = []
    for k, end_ns in enumerate(loop_end):
        after = [r for r in report_at if r > end_ns]
        if after:
            e2e.append((min(after) - end_ns) / 1e9)
    print(f"\ncyclone: {len(frames)} frames x {a.loops} loops at {a.hz} Hz "
          f"({len(topics)} bodies, 32^3) into `launch four_spheres.yaml`")
    print("| topic | Cyclone: delivered / sent | latency p50 [ms] | p99 [ms] | max [ms] | "
          "peer's decoding p50 [ms] | RustDDS (`record`): delivered | latency p50 [ms] | max [ms] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| `{r['topic']}` | {r['delivered']} / {r['sent']} | {r['latency_ms_p50']:.1f} | "
              f"{r['latency_ms_p99']:.1f} | {r['latency_ms_max']:.1f} | {r['peer_decode_ms_p50']:.1f} | "
              f"{r['rustdds_delivered']} | {r['rustdds_latency_ms_p50']:.1f} | {r['rustdds_latency_ms_max']:.1f} |")
    print("last frame -> report received [s] per loop (includes the 2 s idle timeout): "
          + ", ".join(f"{x:.2f}" for x in e2e))
    return {"topics": rows, "last_frame_to_report_s": e2e, "frames_per_loop": len(frames),
            "loops": a.loops, "hz": a.hz}


def take_markers(domain, run_s, out, ready):
    """A second participant that takes /checker/markers until `run_s` passed or none came
    for 15 s after the first; puts ([(receive ns, source ns)], [decode s]) on `out`."""
    cp = peer_module()
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    dp = DomainParticipant(domain)
    qos = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
              Policy.Durability.Volatile, Policy.History.KeepLast(256))
    r = DataReader(dp, Topic(dp, "rt/checker/markers", cp.MarkerArray), qos=qos)
    t_end = time.monotonic() + run_s
    while not r.get_matched_publications() and time.monotonic() < t_end:
        time.sleep(0.05)
    ready.set()
    got, dec, last = [], [], None
    while time.monotonic() < t_end and (last is None or time.monotonic() - last < 15):
        c0 = time.perf_counter()
        ss = r.take(N=1)
        if not ss:
            time.sleep(0.002)
            continue
        last = time.monotonic()
        got.append((time.time_ns(), ss[0].sample_info.source_timestamp))
        dec.append(time.perf_counter() - c0)
    out.put((got, dec))


# ---- shared measurements ------------------------------------------------------------------

def loadavg() -> list:
    """The 1, 5 and 15 minute load averages (other engineers build on the same cores)."""
    return [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]


def machine_probe_ms() -> float:
    """Milliseconds a fixed single-thread workload takes (SHA-256 of 64 MiB, best of 3),
    before and after a run: whether the cores' own arithmetic was slower. On the dev VM it
    stayed at 46-50 ms while the same launch's handling time (`handling_s`) went from 8 to
    11 s, so the slow hours there are not slower arithmetic (docs/performance.md)."""
    import hashlib
    data = bytes(64 << 20)
    best = math.inf
    for _ in range(3):
        t = time.perf_counter()
        hashlib.sha256(data).digest()
        best = min(best, (time.perf_counter() - t) * 1e3)
    return best


def memory_probe_ms() -> dict:
    """Milliseconds two fixed memory-bound workloads take (best of 3), before and after a
    run: 8 Mi random reads from 512 MiB (latency) and a copy of 512 MiB (bandwidth). The
    SHA-256 probe above stays in the core's caches; these do not, so a neighbour on the
    host taking the shared cache or memory shows here and not there."""
    import numpy as np
    a = np.ones(64 << 20, dtype=np.int64)
    idx = np.random.default_rng(7).integers(0, a.size, 8 << 20)
    b = np.empty_like(a)
    gather = copy = math.inf
    for _ in range(3):
        t = time.perf_counter()
        a[idx].sum()
        gather = min(gather, (time.perf_counter() - t) * 1e3)
        t = time.perf_counter()
        np.copyto(b, a)
        copy = min(copy, (time.perf_counter() - t) * 1e3)
    return {"random_reads_ms": gather, "copy_ms": copy}


def steal_s() -> float:
    """CPU time the hypervisor gave to others while this VM's CPUs wanted it (all CPUs, s):
    a stall that hits every process at once shows here."""
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
    return int(fields[8]) / os.sysconf("SC_CLK_TCK") if len(fields) > 8 else float("nan")


def proc_peak_rss_mb(pid: int) -> float:
    """Peak resident memory (VmHWM) of a process."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def thread_cpu_s(pid: int) -> dict:
    """CPU seconds per thread name (threads of the same name summed), from /proc: where the
    launch's time goes, whatever its executor (node threads are named after their node when
    the executor names them)."""
    tick = os.sysconf("SC_CLK_TCK")
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            stat = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
        except OSError:
            continue  # the thread ended
        name = stat[stat.index("(") + 1:stat.rindex(")")]
        fields = stat.rsplit(")", 1)[1].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return {k: round(v, 2) for k, v in sorted(out.items(), key=lambda kv: -kv[1])}


def bag_frames(bag: Path):
    """(median log-time step [s] between two VoxelGrid frames of one topic, frames per topic)."""
    from mcap.reader import make_reader
    times = {}
    with open(bag, "rb") as f:
        for schema, ch, m in make_reader(f).iter_messages(log_time_order=True):
            if schema is not None and schema.name == "chronotope_msgs/msg/VoxelGrid":
                times.setdefault(ch.topic, []).append(m.log_time)
    steps = [b - a for ts in times.values() for a, b in zip(ts, ts[1:]) if b > a]
    if not steps:
        raise SystemExit(f"{bag}: fewer than two VoxelGrid frames on any topic")
    return statistics.median(steps) / 1e9, {t: len(ts) for t, ts in sorted(times.items())}


def summary_extras(full: dict) -> dict:
    """From a launch's --summary: each node's counted problems, and every number whose path
    of keys names CPU (wherever the executor reports it: per node, per thread)."""
    problems = {n: s.get("problems", {}) for n, s in full.get("nodes", {}).items()
                if s.get("problems")}
    cpu = {}

    def walk(v, path):
        items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
        for k, x in items:
            p = f"{path}.{k}" if path else str(k)
            if isinstance(x, (int, float)) and not isinstance(x, bool) and "cpu" in p.lower():
                cpu[p] = x
            else:
                walk(x, p)
    walk(full, "")
    return {"problems": problems, "cpu": cpu}


# ---- mesher -----------------------------------------------------------------------------

def bench_mesher(a, exe, domain, tmp):
    bag = Path(a.bag) if a.bag else tmp / f"machine-tool-{a.grid}.mcap"
    if not a.bag:
        cmd = [str(exe), "scene", "machine-tool", "--grid", str(a.grid), "--out", str(bag)]
        # --seconds N: N seconds of play at --hz (the scene's choreography, stretched over
        # N x hz frames; the default 64 frames play for 2.1 s at 30 Hz, too short for the
        # queue to fill).
        frames = a.frames or (round(a.seconds * a.hz) if a.seconds else None)
        if frames:
            cmd += ["--frames", str(frames)]
        log(f"generating the machine-tool scene at {a.grid}^3 -> {bag}")
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    # `chronotope play` keeps the recorded timing scaled by --rate: the scene's frames are
    # `period` apart, so --rate hz * period plays --hz frames per second (the stamps keep
    # their recorded spacing; the nodes' lag is measured in wall time).
    period, per_topic = bag_frames(bag)
    rate = a.hz * period
    cfg = Path(a.config) if a.config else ROOT / "launch_configs/machine_tool.yaml"
    summary = tmp / "summary.json"
    load0 = loadavg()
    launch = start_launch(exe, cfg, domain, a.seconds_max, summary, tmp / "launch.log")
    time.sleep(1.0)
    marker_proc = None
    if a.markers_reader:
        # A display's reader of the markers (rviz2, Foxglove): without one the checker
        # builds none. Started and matched before the frames.
        ctx = multiprocessing.get_context("spawn")
        marker_q, marker_ready = ctx.Queue(), ctx.Event()
        marker_proc = ctx.Process(target=take_markers,
                                  args=(domain, a.seconds_max, marker_q, marker_ready))
        marker_proc.start()
        if not marker_ready.wait(30):
            launch.kill()
            marker_proc.kill()
            raise SystemExit("the markers reader did not match the launch within 30 s")
        time.sleep(0.5)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), RUST_LOG="warn")
    cpu0 = proc_cpu_s(launch.pid)
    t0 = time.monotonic()
    play = subprocess.run([str(exe), "play", str(bag), "--wait", "3", "--rate", f"{rate:.6g}"],
                          env=env, capture_output=True, text=True)
    t_play = time.monotonic() - t0 - 3
    cpu_play = proc_cpu_s(launch.pid) - cpu0
    log(play.stderr.strip().splitlines()[-1] if play.stderr.strip() else "play: no output")
    if play.returncode != 0:
        launch.kill()
        raise SystemExit(f"chronotope play exited with {play.returncode}")
    # Let the nodes close the streams (idle timeout) and check.
    time.sleep(a.settle)
    cpu = proc_cpu_s(launch.pid)
    rss = proc_rss_mb(launch.pid)
    peak = proc_peak_rss_mb(launch.pid)
    threads = thread_cpu_s(launch.pid)
    launch.terminate()
    wait(launch, "chronotope launch", 300)
    markers = None
    if marker_proc is not None:
        got, _ = marker_q.get(timeout=120)
        marker_proc.join(timeout=30)
        lat = sorted((r - src) / 1e6 for r, src in got)
        markers = {"received": len(got),
                   "latency_ms_p50": lat[len(lat) // 2] if lat else None,
                   "latency_ms_max": lat[-1] if lat else None}
    load1 = loadavg()
    full = json.loads(summary.read_text())
    s = full["transport"]
    lag = s.get("lag", {})
    frame_s = 1.0 / a.hz
    print(f"\nmesher: machine-tool {a.grid}^3 bag ({max(per_topic.values())} frames per body, "
          f"{period * 1e3:.0f} ms apart) played at "
          f"{a.hz:g} Hz (--rate {rate:.3g}, {t_play:.1f} s) into `launch {cfg.name}`")
    print("| topic | received | dropped | lag p50 [ms] | p99 [ms] | max [ms] | p99 [frame periods] | "
          "busy p50 [ms] |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for t in sorted(s["received"]):
        l = lag.get(t, {})
        nan = float("nan")
        row = {"topic": t, "received": s["received"][t], "dropped": s["dropped"].get(t, 0),
               "lag_ms_p50": l.get("p50_ms", nan), "lag_ms_p99": l.get("p99_ms", nan),
               "lag_ms_max": l.get("max_ms", nan), "busy_ms_p50": l.get("busy_p50_ms", nan),
               "lag_p99_periods": l.get("p99_ms", nan) / 1e3 / frame_s}
        rows.append(row)
        print(f"| `{t}` | {row['received']} | {row['dropped']} | {row['lag_ms_p50']:.1f} | "
              f"{row['lag_ms_p99']:.1f} | {row['lag_ms_max']:.1f} | {row['lag_p99_periods']:.2f} | "
              f"{row['busy_ms_p50']:.1f} |")
    print(f"launch CPU while playing: {cpu_play:.1f} s in {t_play:.1f} s "
          f"({100 * cpu_play / max(t_play, 1e-9):.0f} % of one core); until {a.settle:.0f} s after "
          f"the bag: {cpu:.1f} s; RSS {rss:.0f} MB (peak {peak:.0f} MB); load {load0} -> {load1}")
    print("CPU per thread [s]: " + ", ".join(f"{k} {v}" for k, v in threads.items()))
    extras = summary_extras(full)
    if extras["cpu"]:
        print("CPU in --summary: " + ", ".join(f"{k} {v}" for k, v in extras["cpu"].items()))
    if extras["problems"]:
        print("problems counted: " + "; ".join(f"{n} {p}" for n, p in extras["problems"].items()))
    if markers is not None:
        print(f"markers reader: {markers['received']} MarkerArrays, publish-to-take p50 "
              f"{markers['latency_ms_p50']} ms, max {markers['latency_ms_max']} ms")
    return {"topics": rows, "summary_cpu": extras["cpu"], "problems": extras["problems"], "hz": a.hz, "config": str(cfg), "play_rate": rate, "bag_frame_period_s": period,
            "markers_reader": markers,
            "frames_per_topic": per_topic,
            "grid": a.grid, "play_s": t_play, "cpu_s_while_playing": cpu_play, "cpu_s": cpu,
            "rss_mb": rss, "peak_rss_mb": peak, "cpu_s_per_thread": threads,
            "loadavg_before": load0, "loadavg_after": load1, "summary": full}


# ---- carving ----------------------------------------------------------------------------

# The workpieces of `carving --setup`: the block of launch_configs/carving_session.yaml
# (60 x 60 x 30 mm at 2 mm) and a realistic one (360 x 360 x 16 mm at 0.5 mm, ~1.1M surfels);
# `alone-*` runs the carving node by itself, the others add a mesher and a checker of its
# occupancy frames in the same launch (the shape of carving_session.yaml).
CARVING_SETUPS = {
    "alone-small": {"lo": [0.0, 0.0, 0.0], "hi": [0.06, 0.06, 0.03], "spacing": 0.002, "pipeline": False},
    "small": {"lo": [0.0, 0.0, 0.0], "hi": [0.06, 0.06, 0.03], "spacing": 0.002, "pipeline": True},
    "alone-big": {"lo": [0.0, 0.0, 0.0], "hi": [0.36, 0.36, 0.016], "spacing": 0.0005, "pipeline": False},
    "big": {"lo": [0.0, 0.0, 0.0], "hi": [0.36, 0.36, 0.016], "spacing": 0.0005, "pipeline": True},
}
# The knife of carving_session.yaml (m).
KNIFE = {"length": 0.016, "width": 0.010, "thickness": 0.002}
POSE_TOPIC = "/haptic/pose"
# The pose sender's SCHED_FIFO priority with --peer-realtime (below the node's 40).
PEER_RT_PRIORITY = 30
WRENCH_TOPIC = "/carving/wrench"


def carving_config(setup: str, frame_hz: float, realtime: bool = False, queue_depth: int = 0) -> str:
    """The launch config of a `carving --setup`, as ROS 2 launch YAML. The checker of the
    pipeline setups is given no `pairs`: /carving/occupancy is then a lone body, meshed and
    reported (a fixture body would have no publisher live)."""
    s = CARVING_SETUPS[setup]
    vec = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
    params = [
        ("pose_topic", POSE_TOPIC), ("frame_id", "world"),
        ("workpiece_min", vec(s["lo"])), ("workpiece_max", vec(s["hi"])),
        ("spacing_m", repr(s["spacing"])), ("tool", "knife"),
        ("knife_length_m", repr(KNIFE["length"])), ("knife_width_m", repr(KNIFE["width"])),
        ("knife_thickness_m", repr(KNIFE["thickness"])),
        # The force parameters of carving_session.yaml.
        ("force_model", "section"), ("cutting_pressure_n_per_m2", "200000.0"),
        ("filter_cutoff_hz", "30.0"), ("coupling_stiffness_n_per_m", "2000.0"),
        ("coupling_damping_ns_per_m", "8.0"), ("proxy_mass_kg", "0.02"), ("max_force_n", "10.0"),
        ("occupancy_period_s", f"{1.0 / frame_hz:.6f}"),
    ]
    if realtime:
        # The node's own thread (SCHED_FIFO if allowed) and DDS participant.
        params.append(("realtime", "true"))
    lines = [f"# live_bench.py carving --setup {setup}", "launch:", "- node:", "    pkg: chronotope",
             "    exec: carving", "    name: carving", "    param:"]
    lines += [f"    - {{name: {k}, value: {v}}}" for k, v in params]
    if s["pipeline"]:
        lines += ["- node:", "    pkg: chronotope", "    exec: mesher", "    name: mesher", "    param:",
                  "    - {name: bodies, value: [/carving/occupancy]}"]
        if queue_depth:
            lines += [f"    - {{name: queue_depth, value: {queue_depth}}}"]
        lines += ["- node:", "    pkg: chronotope", "    exec: checker", "    name: checker"]
        if queue_depth:
            lines += ["    param:", f"    - {{name: queue_depth, value: {queue_depth}}}"]
    return "\n".join(lines) + "\n"


class KnifePath:
    """A tool path that cuts all the time: the knife (length along x, width along z, blade
    face normal to y) slices along x through the block at `speed` m/s, back and forth, from
    outside its -x face to outside its +x face; at each turn (outside the block) it moves one
    blade thickness along y, so every pass cuts a fresh kerf next to the last one; when y has
    crossed the block it goes `layer` m deeper and comes back along y. Positions are a
    function of time, so a late pose is where the tool is then."""

    # Rotation of -90 degrees about x: tool y -> -z (the width hangs down), tool z -> y.
    QUAT = (-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))

    def __init__(self, lo, hi, speed=0.05, knife=KNIFE, layer=None):
        self.lo, self.hi, self.speed = lo, hi, speed
        self.half_len = knife["length"] / 2
        self.half_w = knife["width"] / 2
        self.step_y = knife["thickness"]
        self.layer = layer if layer is not None else knife["width"] / 2
        margin = 0.002
        self.x0 = lo[0] - self.half_len - margin  # the whole blade outside the block
        self.x1 = hi[0] + self.half_len + margin
        self.pass_s = (self.x1 - self.x0) / speed
        self.passes_per_layer = max(1, math.ceil((hi[1] - lo[1]) / self.step_y))

    def at(self, t: float):
        """(position, quaternion x y z w) at `t` seconds after the start."""
        k = int(t // self.pass_s)  # pass index
        u = t / self.pass_s - k  # 0..1 within the pass
        x = self.x0 + (self.x1 - self.x0) * (u if k % 2 == 0 else 1.0 - u)
        j, i = divmod(k, self.passes_per_layer)  # layer, pass within it
        if j % 2 == 1:
            i = self.passes_per_layer - 1 - i  # back along y
        y = self.lo[1] + (i + 0.5) * self.step_y
        bottom = max(self.hi[2] - (j + 1) * self.layer, self.lo[2] + 0.001)
        z = bottom + self.half_w
        return (x, y, z), self.QUAT


def pacing_stats(deadlines_s, sent_s, seconds) -> dict:
    """How well the peer held its send schedule: the achieved rate, the lateness of each send
    after its deadline and the intervals between sends (ms)."""
    late = [(s - d) * 1e3 for d, s in zip(deadlines_s, sent_s)]
    gaps = [(b - a) * 1e3 for a, b in zip(sent_s, sent_s[1:])]
    return {
        "sent": len(sent_s),
        "achieved_hz": len(sent_s) / seconds if seconds > 0 else float("nan"),
        "late_ms_p50": pct(late, 0.5), "late_ms_p99": pct(late, 0.99),
        "late_ms_max": max(late) if late else float("nan"),
        "interval_ms_p1": pct(gaps, 0.01), "interval_ms_p50": pct(gaps, 0.5),
        "interval_ms_p99": pct(gaps, 0.99), "interval_ms_max": max(gaps) if gaps else float("nan"),
        "intervals_over_2ms": sum(1 for g in gaps if g > 2.0),
    }


def match_wrenches(sent, seen_poses, wrenches) -> dict:
    """Latency of each pose = its wrench's DDS source timestamp minus the pose's.

    `sent`: {stamp ns: source timestamp ns given to write()}, every pose sent;
    `seen_poses`: {stamp ns: source timestamp ns} as a Cyclone reader of the pose topic saw
    them (SampleInfo.source_timestamp; preferred where present);
    `wrenches`: [(header stamp ns, source timestamp ns, |force| N)], as received.
    A wrench is matched to the pose of the same header stamp (the node copies it); a wrench
    whose stamp matches no pose sent, and a second wrench for the same pose, are counted."""
    lat, forces, unknown, dup, first = [], [], 0, 0, {}
    for stamp, src, f in wrenches:
        if stamp not in sent:
            unknown += 1
            continue
        if stamp in first:
            dup += 1
            continue
        first[stamp] = src
        lat.append((src - seen_poses.get(stamp, sent[stamp])) / 1e6)
        forces.append(f)
    missing = len(sent) - len(first)
    # Runs of consecutive poses (in send order) without a wrench: scattered single losses
    # (the wire) or long runs (a stalled handler, a burst the writer's history kept the last
    # of).
    runs, longest, cur = 0, 0, 0
    for stamp in sorted(sent):
        if stamp in first:
            cur = 0
            continue
        runs += cur == 0
        cur += 1
        longest = max(longest, cur)
    return {
        "missing_runs": runs, "longest_missing_run": longest,
        "poses_sent": len(sent), "poses_seen_by_peer_reader": len(seen_poses),
        "source_timestamp_mismatches": sum(1 for k, v in seen_poses.items() if sent.get(k) != v),
        "wrenches_received": len(wrenches), "poses_with_wrench": len(first),
        "poses_without_wrench": missing, "wrenches_unmatched": unknown, "wrenches_duplicate": dup,
        "latency_ms_p50": pct(lat, 0.5), "latency_ms_p99": pct(lat, 0.99),
        "latency_ms_p999": pct(lat, 0.999), "latency_ms_max": max(lat) if lat else float("nan"),
        "latency_over_1ms": sum(1 for x in lat if x > 1.0),
        "latency_over_2ms": sum(1 for x in lat if x > 2.0),
        "wrenches_with_force": sum(1 for f in forces if f > 1e-9),
        "force_n_p50": pct(forces, 0.5), "force_n_max": max(forces) if forces else float("nan"),
    }


def carving_types(cp):
    """geometry_msgs PoseStamped and WrenchStamped, field for field, on tests/py/cyclone_peer.py's
    Header, Point, Quaternion, Pose and Vector3 (plain CDR, as RustDDS reads and writes)."""
    from dataclasses import dataclass
    from cyclonedds.idl import IdlStruct

    @dataclass
    class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
        header: cp.Header
        pose: cp.Pose

    @dataclass
    class Wrench(IdlStruct, typename="geometry_msgs::msg::dds_::Wrench_"):
        force: cp.Vector3
        torque: cp.Vector3

    @dataclass
    class WrenchStamped(IdlStruct, typename="geometry_msgs::msg::dds_::WrenchStamped_"):
        header: cp.Header
        wrench: Wrench

    return PoseStamped, WrenchStamped


def display_types(cp):
    """sensor_msgs PointField and PointCloud2, field for field."""
    from dataclasses import dataclass
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import sequence, uint8, uint32

    @dataclass
    class PointField(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
        name: str
        offset: uint32
        datatype: uint8
        count: uint32

    @dataclass
    class PointCloud2(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
        header: cp.Header
        height: uint32
        width: uint32
        fields: sequence[PointField]
        is_bigendian: bool
        point_step: uint32
        row_step: uint32
        data: sequence[uint8]
        is_dense: bool

    return PointCloud2


def display_peer(domain, ready, done, max_s):
    """A display's subscriptions (as rviz2 or Foxglove would hold them): reliable readers of
    /carving/surfels (transient local) and /carving/occupancy, keep last 1. It never takes
    (decoding a 36 MB cloud in Python takes seconds): Cyclone receives, acknowledges and keeps
    the latest sample, so the node's writers see a reader acknowledge what they send."""
    cp = peer_module()
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    PointCloud2 = display_types(cp)
    dp = DomainParticipant(domain)
    def qos(durability):
        return Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000), durability,
                   Policy.History.KeepLast(1))
    # The node offers the surfels latched (transient local), the occupancy volatile.
    readers = [DataReader(dp, Topic(dp, "rt/carving/surfels", PointCloud2),
                          qos=qos(Policy.Durability.TransientLocal)),
               DataReader(dp, Topic(dp, "rt/carving/occupancy", cp.VoxelGrid),
                          qos=qos(Policy.Durability.Volatile))]
    t_end = time.monotonic() + max_s
    while any(not r.get_matched_publications() for r in readers) and time.monotonic() < t_end:
        time.sleep(0.05)
    ready.set()
    while not done.is_set() and time.monotonic() < t_end:
        time.sleep(0.1)


def take_wrenches(domain, out_path, ready, done, quiet_s, max_s):
    """A process of its own (its Python decoding must not delay the 1 kHz sender): takes
    /carving/wrench and, to read each pose's DDS source timestamp as a reader sees it, the
    pose topic; after `done`, until no wrench came for `quiet_s`; writes JSON to out_path."""
    cp = peer_module()
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    PoseStamped, WrenchStamped = carving_types(cp)
    dp = DomainParticipant(domain)
    # Best effort as the node's writer; a deep history so that nothing is overwritten
    # before it is taken.
    qos = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(100_000))
    wr = DataReader(dp, Topic(dp, cp.dds_topic(WRENCH_TOPIC), WrenchStamped), qos=qos)
    pr = DataReader(dp, Topic(dp, cp.dds_topic(POSE_TOPIC), PoseStamped), qos=qos)
    t_end = time.monotonic() + max_s
    while not wr.get_matched_publications() and time.monotonic() < t_end:
        time.sleep(0.05)
    ready.set()
    wrenches, poses, last = [], [], time.monotonic()
    while time.monotonic() < t_end:
        got = 0
        for s in wr.take(N=256):
            f = s.wrench.force
            wrenches.append([s.header.stamp.sec * 10**9 + s.header.stamp.nanosec,
                             s.sample_info.source_timestamp, time.time_ns(),
                             math.sqrt(f.x * f.x + f.y * f.y + f.z * f.z)])
            got += 1
        for s in pr.take(N=256):
            poses.append([s.header.stamp.sec * 10**9 + s.header.stamp.nanosec,
                          s.sample_info.source_timestamp])
        if got:
            last = time.monotonic()
        elif done.is_set() and time.monotonic() - last > quiet_s:
            break
        else:
            time.sleep(0.0005)
    Path(out_path).write_text(json.dumps({"wrenches": wrenches, "poses": poses}))


def bench_carving(a, exe, domain, tmp):
    cp = peer_module()
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.topic import Topic
    PoseStamped, _ = carving_types(cp)

    setup = CARVING_SETUPS[a.setup]
    cfg = tmp / f"carving-{a.setup}.yaml"
    cfg.write_text(carving_config(a.setup, a.frame_hz, a.realtime, a.queue_depth))
    summary = tmp / "summary.json"
    load0 = loadavg()
    launch = start_launch(exe, cfg, domain, int(a.seconds + 120), summary, tmp / "launch.log")
    ctx = multiprocessing.get_context("spawn")
    ready, done = ctx.Event(), ctx.Event()
    got_path = tmp / "wrenches.json"
    rx = ctx.Process(target=take_wrenches, args=(domain, str(got_path), ready, done, 2.0, a.seconds + 90))
    rx.start()
    disp = None
    disp_ready = ctx.Event()
    if a.display:
        disp = ctx.Process(target=display_peer, args=(domain, disp_ready, done, a.seconds + 90))
        disp.start()

    def fail(why):
        launch.kill()
        rx.kill()
        if disp is not None:
            disp.kill()
        log_tail = (tmp / "launch.log").read_text()[-2000:]
        raise SystemExit(f"{why}\nlaunch log (end):\n{log_tail}")

    # A haptic device's driver runs at real-time priority; with --peer-realtime the sender
    # does too (its Cyclone threads, started below, inherit it). The launch, the wrench
    # receiver and the display peer were started before and keep normal priority.
    peer_sched = "normal"
    if a.peer_realtime:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PEER_RT_PRIORITY))
            peer_sched = f"SCHED_FIFO {PEER_RT_PRIORITY}"
        except OSError as e:
            peer_sched = f"normal (SCHED_FIFO refused: {e})"
        log(f"pose sender: {peer_sched}")
    dp = DomainParticipant(domain)
    w = DataWriter(dp, Topic(dp, cp.dds_topic(POSE_TOPIC), PoseStamped),
                   qos=Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile,
                           Policy.History.KeepLast(1)))
    deadline = time.monotonic() + 60
    # The node's pose reader and the receiver's; the receiver is ready once the node's
    # wrench writer matched it.
    while len(w.get_matched_subscriptions()) < 2 or not ready.is_set() or \
            (disp is not None and not disp_ready.is_set()):
        if launch.poll() is not None:
            fail(f"chronotope launch exited with {launch.returncode} before matching")
        if time.monotonic() > deadline:
            fail("no match with chronotope launch within 60 s")
        time.sleep(0.05)
    time.sleep(1.0)  # let discovery finish in both directions

    path = KnifePath(setup["lo"], setup["hi"], speed=a.speed)
    period = 1.0 / a.pose_hz
    sent, deadlines, sent_at = {}, [], []
    rss_peak_seen, rss_stop, rss_series = 0.0, None, []  # [s after the first pose, MB]
    cpu0, wall0, pcpu0 = proc_cpu_s(launch.pid), time.monotonic(), time.process_time()
    steal0 = steal_s()
    # No garbage collection pauses inside the send loop (a device driver has none): a
    # collection between a pose's stamp and its write counted as the launch's latency.
    gc.collect()
    gc.disable()
    t0 = time.perf_counter()
    next_check = t0 + 1.0
    k = skipped = 0
    while True:
        due = t0 + k * period
        if due - t0 >= a.seconds:
            break
        # Absolute deadlines: sleep while more than 0.3 ms is left (the scheduler's wake-up
        # is late by tens of microseconds), then spin. A slot missed by more than a period
        # is not caught up with a burst: the schedule moves on (a device samples at its rate).
        while True:
            now = time.perf_counter()
            left = due - now
            if left <= 0:
                break
            if left > 0.0003:
                time.sleep(left - 0.0002)
        if now - due > period:
            skipped += int((now - t0) / period) - k
            k = int((now - t0) / period)
            continue
        pos, q = path.at(now - t0)
        pose = cp.Pose(position=cp.Point(x=pos[0], y=pos[1], z=pos[2]),
                       orientation=cp.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))
        # The stamp (the latency's start) as late as the message allows: what comes before
        # it is the peer's own work.
        stamp = time.time_ns()
        msg = PoseStamped(
            header=cp.Header(stamp=cp.Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="world"),
            pose=pose)
        w.write(msg, timestamp=stamp)
        sent[stamp] = stamp
        deadlines.append(due - t0)
        sent_at.append(now - t0)
        k += 1
        if now >= next_check:
            next_check = now + 1.0
            if launch.poll() is not None:
                break
            rss_now = proc_rss_mb(launch.pid)
            rss_series.append([round(now - t0, 1), round(rss_now)])
            rss_peak_seen = max(rss_peak_seen, rss_now)
            if rss_peak_seen > a.max_rss_mb:
                rss_stop = rss_peak_seen
                break
    send_s = time.perf_counter() - t0
    steal = steal_s() - steal0
    gc.enable()
    pcpu = time.process_time() - pcpu0
    exited = launch.poll()
    if exited is not None:
        done.set()
        rx.join(timeout=30)
        fail(f"chronotope launch exited with {exited} while the poses were sent")
    cpu_run, wall_run = proc_cpu_s(launch.pid) - cpu0, time.monotonic() - wall0
    done.set()
    rx.join(timeout=120)
    if disp is not None:
        disp.join(timeout=30)
    if rx.exitcode != 0:
        fail(f"the wrench receiver failed (exit {rx.exitcode})")
    cpu = proc_cpu_s(launch.pid)
    rss = proc_rss_mb(launch.pid)
    peak = proc_peak_rss_mb(launch.pid)
    threads = thread_cpu_s(launch.pid)
    aborted = stop_launch(launch, "chronotope launch", 120)
    load1 = loadavg()
    full = json.loads(summary.read_text())
    got = json.loads(got_path.read_text())
    seen = {s: src for s, src, in got["poses"]}
    res = match_wrenches(sent, seen, [(s, src, f) for s, src, _, f in got["wrenches"]])
    pace = pacing_stats(deadlines, sent_at, send_s)
    pace["slots_skipped"] = skipped  # send slots missed by more than a period (not caught up)
    t = full.get("transport", {})
    counts = {k: t.get(k, {}) for k in ("received", "dropped", "sent", "undecodable", "send_errors")}
    desc = (f"{a.setup}: {'x'.join(f'{1e3 * (h - l):g}' for l, h in zip(setup['lo'], setup['hi']))} mm "
            f"at {setup['spacing'] * 1e3:g} mm, frames at {a.frame_hz:g} Hz"
            + (", mesher + checker of /carving/occupancy" if setup["pipeline"] else ", carving alone")
            + (", a display peer subscribed to the surfels and occupancy" if a.display else ""))
    print(f"\ncarving {desc}; Cyclone peer sends {POSE_TOPIC} at {a.pose_hz:g} Hz for {a.seconds:g} s "
          f"(knife at {a.speed * 100:g} cm/s)")
    # Where a pose lost its wrench: not received by the launch (best effort, keep last 1: the
    # node's reader overwrites a pose not taken in time), or a wrench sent but not received.
    res["launch_poses_received"] = counts["received"].get(POSE_TOPIC, 0)
    res["launch_wrenches_sent"] = counts["sent"].get(WRENCH_TOPIC, 0)
    print("| poses sent | received by the launch | wrenches sent | wrenches received | "
          "poses without a wrench | latency p50 [ms] | p99 [ms] | max [ms] | "
          "launch CPU [% of one core] | RSS [MB] (peak) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    print(f"| {res['poses_sent']} | {res['launch_poses_received']} | {res['launch_wrenches_sent']} | "
          f"{res['wrenches_received']} | {res['poses_without_wrench']} | "
          f"{res['latency_ms_p50']:.2f} | {res['latency_ms_p99']:.2f} | {res['latency_ms_max']:.2f} | "
          f"{100 * cpu_run / wall_run:.0f} | {rss:.0f} ({peak:.0f}) |")
    print(f"the pose sender: {peer_sched}; the hypervisor's steal while sending: {steal:.2f} s of CPU")
    print(f"peer pacing: {pace['achieved_hz']:.1f} Hz achieved, lateness p50/p99/max "
          f"{pace['late_ms_p50']:.3f}/{pace['late_ms_p99']:.3f}/{pace['late_ms_max']:.3f} ms, "
          f"intervals p1/p50/p99/max {pace['interval_ms_p1']:.3f}/{pace['interval_ms_p50']:.3f}/"
          f"{pace['interval_ms_p99']:.3f}/{pace['interval_ms_max']:.3f} ms, "
          f"{pace['intervals_over_2ms']} over 2 ms, {skipped} slots skipped; the sender used {100 * pcpu / send_s:.0f} % of a core")
    print(f"wrenches with a force: {res['wrenches_with_force']} (median {res['force_n_p50']:.2f} N, "
          f"max {res['force_n_max']:.2f} N); latency over 1 ms: {res['latency_over_1ms']}, "
          f"over 2 ms: {res['latency_over_2ms']}; unmatched {res['wrenches_unmatched']}, "
          f"duplicate {res['wrenches_duplicate']}; missing in {res['missing_runs']} runs, the longest "
          f"{res['longest_missing_run']} poses; peer's pose reader saw {res['poses_seen_by_peer_reader']} "
          f"({res['source_timestamp_mismatches']} source-timestamp mismatches)")
    print("launch transport: " + "; ".join(f"{k} {v}" for k, v in counts.items() if v))
    print(f"launch CPU per thread [s]: " + ", ".join(f"{k} {v}" for k, v in threads.items()))
    extras = summary_extras(full)
    if extras["cpu"]:
        print("CPU in --summary: " + ", ".join(f"{k} {v}" for k, v in extras["cpu"].items()))
    if extras["problems"]:
        print("problems counted: " + "; ".join(f"{n} {p}" for n, p in extras["problems"].items()))
    print(f"load {load0} -> {load1}; launch RSS [MB] every ~10 s: "
          + ", ".join(f"{s:g} s {m}" for s, m in rss_series[::10]))
    if rss_stop is not None:
        print(f"STOPPED EARLY: the launch's RSS reached {rss_stop:.0f} MB (--max-rss-mb {a.max_rss_mb})")
    return {"setup": a.setup, "description": desc, "config": cfg.read_text(), "seconds": a.seconds,
            "pose_hz": a.pose_hz, "frame_hz": a.frame_hz, "display_peer": a.display, "peer_scheduling": peer_sched,
            "launch_aborted_at_stop": aborted, "steal_s_while_sending": steal, "knife_speed_m_per_s": a.speed,
            "result": res, "pacing": pace, "summary_cpu": extras["cpu"], "problems": extras["problems"], "sender_cpu_fraction": pcpu / send_s,
            "launch_cpu_s_while_sending": cpu_run, "launch_cpu_fraction_of_one_core": cpu_run / wall_run,
            "launch_cpu_s": cpu, "rss_mb": rss, "peak_rss_mb": peak, "cpu_s_per_thread": threads,
            "stopped_early_rss_mb": rss_stop, "rss_mb_series": rss_series, "loadavg_before": load0, "loadavg_after": load1,
            "summary": full}


# ---- idle -------------------------------------------------------------------------------

def bench_stop(a, exe, domain, tmp):
    bag = Path(a.bag) if a.bag else tmp / f"machine-tool-{a.grid}.mcap"
    frames = a.frames or 400
    if not a.bag:
        log(f"generating the machine-tool scene at {a.grid}^3, {frames} frames -> {bag}")
        subprocess.run([str(exe), "scene", "machine-tool", "--grid", str(a.grid), "--frames",
                        str(frames), "--out", str(bag)], check=True, stdout=subprocess.DEVNULL)
    period, _ = bag_frames(bag)
    rate = a.hz * period
    summary = tmp / "summary.json"
    launch = start_launch(exe, ROOT / "launch_configs/machine_tool.yaml", domain, a.seconds_max,
                          summary, tmp / "launch.log")
    time.sleep(1.0)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), RUST_LOG="warn")
    play = subprocess.Popen([str(exe), "play", str(bag), "--wait", "2", "--rate", f"{rate:.6g}"],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(2 + a.seconds)
    play.send_signal(2)
    wait(play, "chronotope play", 30)
    t0 = time.monotonic()
    for k in range(a.signals):
        if k:
            time.sleep(1.0)
        if launch.poll() is None:
            launch.send_signal(2)
    wait(launch, "chronotope launch", a.seconds_max)
    took = time.monotonic() - t0
    full = json.loads(summary.read_text())
    print(f"\nstop: machine-tool {a.grid}^3 played at {a.hz:g} Hz for {a.seconds:g} s into "
          f"`launch machine_tool.yaml`; {a.signals} SIGINT(s) 1 s apart: the launch exited "
          f"{took:.1f} s after the first")
    print("| node | received | dropped | discarded | unfinished |")
    print("|---|---|---|---|---|")
    nodes = {}
    for name, r in sorted(full["nodes"].items()):
        row = {"received": r["received"], "dropped": sum(r["dropped"].values()),
               "discarded": sum(r.get("discarded", {}).values()),
               "unfinished": r.get("unfinished")}
        nodes[name] = row
        print(f"| `{name}` | {row['received']} | {row['dropped']} | {row['discarded']} | "
              f"{row['unfinished'] or ''} |")
    return {"signals": a.signals, "hz": a.hz, "play_s": a.seconds, "frames": frames,
            "grid": a.grid, "stop_s": took, "nodes": nodes}


def bench_periodic(a, exe, domain, tmp):
    seconds = int(a.seconds)
    bag = tmp / f"periodic-{seconds}.mcap"
    log(f"generating the periodic scene, {seconds} s -> {bag}")
    subprocess.run([str(exe), "scene", "periodic", "--duration", str(seconds), "--out", str(bag)],
                   check=True, stdout=subprocess.DEVNULL)
    summary = tmp / "summary.json"
    launch = start_launch(exe, ROOT / "launch_configs/periodic.yaml", domain, a.seconds_max + seconds,
                          summary, tmp / "launch.log")
    peer_out = tmp / "peer.json"
    peer = subprocess.Popen([sys.executable, str(ROOT / "tests/py/cyclone_peer.py"), "--bag", str(bag),
                             "--out", str(peer_out), "--domain", str(domain), "--timeout", "120"],
                            stdout=subprocess.DEVNULL, stderr=open(tmp / "peer.log", "w"))
    t0 = time.monotonic()
    rss = []
    while peer.poll() is None:
        rss.append((round(time.monotonic() - t0, 1), round(proc_rss_mb(launch.pid), 1)))
        time.sleep(10.0)
    peak = proc_peak_rss_mb(launch.pid)
    launch.send_signal(2)
    wait(launch, "chronotope launch", 300)
    if peer.returncode != 0:
        raise SystemExit(f"the Cyclone peer exited with {peer.returncode}: see {tmp / 'peer.log'}")
    got = json.loads(peer_out.read_text())
    events = got["contacts"]
    begun = [e for e in events if e["event"] == 0]
    lat = [e["latency_s"] * 1e3 for e in events if e["latency_s"] is not None]
    lat_b = [e["latency_s"] * 1e3 for e in begun if e["latency_s"] is not None]
    report = got["report"] or {"pairs": []}
    in_report = sum(len(p["interval_start_s"]) for p in report["pairs"])
    streaming = sum(1 for e in begun if e["while_streaming"])
    print(f"\nperiodic: {seconds} s of the periodic scene (48^3, 20 Hz) from a Cyclone peer into "
          f"`launch periodic.yaml`")
    print(f"contacts: {len(begun)} begun ({streaming} while streaming), {in_report} in the last report; "
          f"{len(events)} events")
    print(f"latency [ms], all events: p50 {pct(lat, 0.5):.0f}, p99 {pct(lat, 0.99):.0f}, max {max(lat, default=math.nan):.0f}; "
          f"BEGIN: p50 {pct(lat_b, 0.5):.0f}, p99 {pct(lat_b, 0.99):.0f}, max {max(lat_b, default=math.nan):.0f}")
    minutes = {}
    for t, r in rss:
        if t <= seconds:
            minutes.setdefault(int(t // 60), []).append(r)
    after = [r for t, r in rss if t > seconds]
    print("RSS [MB] per minute of the stream (min-max of the 10 s samples): " + ", ".join(
        f"{m}-{m + 1} min {min(v):.0f}-{max(v):.0f}" for m, v in sorted(minutes.items()))
          + (f"; after it {min(after):.0f}-{max(after):.0f}" if after else ""))
    print(f"peak RSS {peak:.0f} MB")
    return {"seconds": seconds, "contacts_begun": len(begun), "begun_while_streaming": streaming,
            "intervals_in_report": in_report, "events": len(events),
            "latency_ms": {"p50": pct(lat, 0.5), "p99": pct(lat, 0.99), "max": max(lat, default=math.nan)},
            "latency_begin_ms": {"p50": pct(lat_b, 0.5), "p99": pct(lat_b, 0.99), "max": max(lat_b, default=math.nan)},
            "rss_mb": rss, "peak_rss_mb": peak}


# ---- robot, cloud -----------------------------------------------------------------------

def bench_sources(a, exe, domain, tmp, kind):
    """A Cyclone peer plays a robot cell (URDF, joint states, the table's frames) or a person
    cell (a depth camera's cloud, an OctoMap, the machine-tool bodies) into the launch that
    turns them into bodies, --loops times; contact latency, the launch's drops and lag, and its
    resident memory."""
    frame_hz = a.frame_hz
    if kind == "robot":
        grid = a.grid
        joint_hz = a.joint_hz
        bag = tmp / f"robot-cell-{grid}.mcap"
        scene = ["scene", "robot-cell", "--grid", str(grid), "--frame-hz", f"{frame_hz:g}",
                 "--joint-hz", f"{joint_hz:g}", "--encoding", "bits", "--out", str(bag)]
        cfg = Path(a.config) if a.config else ROOT / "launch_configs/robot_cell.yaml"
        latency_from = "/joint_states,/table/occupancy"
        what = (f"robot cell {grid}^3: joint states at {joint_hz:g} Hz (two partial messages an "
                f"instant), the table's frames at {frame_hz:g} Hz, the robot node's frames at the "
                f"table's stamps (percent)")
    else:
        grid = a.cloud_grid
        frames = a.frames or 150
        bag = tmp / f"person-cell-{grid}.mcap"
        scene = ["scene", "person-cell", "--grid", str(grid), "--frames", str(frames),
                 "--frame-hz", f"{frame_hz:g}", "--camera", a.camera, "--out", str(bag)]
        cfg = Path(a.config) if a.config else ROOT / "launch_configs/person_cell.yaml"
        latency_from = ""
        w, h = (int(v) for v in a.camera.split("x"))
        what = (f"person cell {grid}^3: a {w}x{h} = {w * h}-point organised cloud and the three "
                f"machine-tool bodies at {frame_hz:g} Hz, an OctoMap at {frame_hz / 2:g} Hz")
    log(f"generating {' '.join(scene)}")
    subprocess.run([str(exe), *scene], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    summary = tmp / "summary.json"
    launch = start_launch(exe, cfg, domain, a.seconds_max, summary, tmp / "launch.log")
    peer_out = tmp / "peer.json"
    cmd = [sys.executable, str(ROOT / "tests/py/cyclone_peer.py"), "--bag", str(bag), "--out",
           str(peer_out), "--domain", str(domain), "--timeout", "120", "--loops", str(a.loops),
           "--match-timeout", "60"]
    if latency_from:
        cmd += ["--latency-from", latency_from]
    if not a.labels:
        cmd += ["--no-labels"]
    peer = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=open(tmp / "peer.log", "w"))
    t0 = time.monotonic()
    c0 = proc_cpu_s(launch.pid)
    rss = []
    while peer.poll() is None:
        rss.append((round(time.monotonic() - t0, 1), round(proc_rss_mb(launch.pid), 1)))
        time.sleep(2.0)
    wall = time.monotonic() - t0
    cpu = proc_cpu_s(launch.pid) - c0
    peak = proc_peak_rss_mb(launch.pid)
    stop_launch(launch, "chronotope launch", 120)
    if peer.returncode != 0:
        raise SystemExit(f"the Cyclone peer exited with {peer.returncode}: see {tmp / 'peer.log'}:\n"
                         + (tmp / "peer.log").read_text()[-2000:])
    got = json.loads(peer_out.read_text())
    full = json.loads(summary.read_text())
    s = full["transport"]
    lag = s.get("lag", {})
    events = got["contacts"]
    begun = [e for e in events if e["event"] == 0]
    # Events with a frame (not those that close with a stream, after the idle timeout).
    lat = [e["latency_s"] * 1e3 for e in events if e["latency_s"] is not None and not e["at_stream_end"]]
    lat_b = [e["latency_s"] * 1e3 for e in begun if e["latency_s"] is not None and not e["at_stream_end"]]
    lat_end = [e["latency_s"] * 1e3 for e in events if e["latency_s"] is not None and e["at_stream_end"]]
    period_ms = 1e3 / frame_hz
    print(f"\n{kind}: {what}; a Cyclone peer {'taking labels ' if a.labels else ''}plays it {a.loops} time(s) "
          f"({got['frames_published']} messages, {got['timing_s']['played']:.1f} s) into "
          f"`launch {cfg.name}`")
    print("| topic | received | dropped | lag p50 [ms] | p99 [ms] | max [ms] |")
    print("|---|---|---|---|---|---|")
    rows = []
    nan = float("nan")
    for t in sorted(s["received"]):
        l = lag.get(t, {})
        row = {"topic": t, "received": s["received"][t], "dropped": s["dropped"].get(t, 0),
               "lag_ms_p50": l.get("p50_ms", nan), "lag_ms_p99": l.get("p99_ms", nan),
               "lag_ms_max": l.get("max_ms", nan)}
        rows.append(row)
        print(f"| {t} | {row['received']} | {row['dropped']} | {row['lag_ms_p50']:.1f} | "
              f"{row['lag_ms_p99']:.1f} | {row['lag_ms_max']:.1f} |")
    print(f"contacts: {len(begun)} begun, {len(events)} events (BEGIN/ONGOING/END/UNSURE); latency "
          f"from the input that completes the slab to the event at the peer [ms], the "
          f"{len(lat)} events that come with a frame: p50 {pct(lat, 0.5):.0f}, p99 "
          f"{pct(lat, 0.99):.0f} ({pct(lat, 0.99) / period_ms:.2f} frame periods), max "
          f"{max(lat, default=nan):.0f}; BEGIN p50 {pct(lat_b, 0.5):.0f}, p99 {pct(lat_b, 0.99):.0f}; "
          f"the {len(lat_end)} that close with a stream (after the mesher's 2 s idle timeout): "
          f"max {max(lat_end, default=nan):.0f}")
    minutes = {}
    for t, r in rss:
        minutes.setdefault(int(t // 60), []).append(r)
    print(f"launch CPU {cpu / wall * 100:.0f} % of one core over {wall:.0f} s; RSS [MB] per minute "
          "(min-max of 2 s samples): " + ", ".join(
              f"{m}-{m + 1} min {min(v):.0f}-{max(v):.0f}" for m, v in sorted(minutes.items()))
          + f"; peak {peak:.0f}")
    problems = summary_extras(full)["problems"]
    if problems:
        print(f"counted problems: {problems}")
    # The same work every run: how long the mesher and the checker took to handle their
    # inputs says how fast the machine ran while it played (a slower host, a longer time).
    handling = sum(l.get("busy_total_s", 0.0) for n in ("/mesher", "/checker")
                   for l in full.get("nodes", {}).get(n, {}).get("lag", {}).values())
    print(f"mesher and checker handling their inputs: {handling:.2f} s in all")
    return {"what": what, "config": cfg.name, "scene": scene, "loops": a.loops, "labels": a.labels,
            "handling_s": handling,
            "frames_published": got["frames_published"], "played_s": got["timing_s"]["played"],
            "topics": rows, "contacts_begun": len(begun), "events": len(events),
            "latency_ms": {"p50": pct(lat, 0.5), "p99": pct(lat, 0.99), "max": max(lat, default=nan),
                           "p99_frame_periods": pct(lat, 0.99) / period_ms},
            "latency_begin_ms": {"p50": pct(lat_b, 0.5), "p99": pct(lat_b, 0.99)},
            "latency_at_stream_end_ms": {"n": len(lat_end), "max": max(lat_end, default=nan)},
            "cpu_fraction_of_one_core": cpu / wall, "rss_mb": rss, "peak_rss_mb": peak,
            "problems": problems, "summary": full,
            "events_detail": [{"stamp": e["header"]["stamp"], "pair": [e["body_a"], e["body_b"]],
                               "event": e["event"], "latency_s": e["latency_s"],
                               "at_stream_end": e["at_stream_end"]} for e in events]}


def bench_idle(a, exe, domain, tmp):
    cfg = ROOT / "launch_configs/machine_tool.yaml"
    launch = start_launch(exe, cfg, domain, a.seconds + 30, tmp / "summary.json", tmp / "launch.log")
    time.sleep(5)  # start-up and discovery
    c0, w0 = proc_cpu_s(launch.pid), time.monotonic()
    time.sleep(a.seconds)
    c1, w1 = proc_cpu_s(launch.pid), time.monotonic()
    rss = proc_rss_mb(launch.pid)
    threads = len(os.listdir(f"/proc/{launch.pid}/task"))
    launch.terminate()
    wait(launch, "chronotope launch", 30)
    load = (c1 - c0) / (w1 - w0)
    print(f"\nidle: `launch machine_tool.yaml`, nothing published, {w1 - w0:.0f} s: "
          f"CPU {100 * load:.2f} % of one core, RSS {rss:.0f} MB, {threads} threads")
    return {"cpu_fraction_of_one_core": load, "rss_mb": rss, "threads": threads, "seconds": w1 - w0}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", choices=["cyclone", "mesher", "carving", "idle", "stop", "periodic",
                                     "robot", "cloud", "all"])
    ap.add_argument("--exe", default=str(DEFAULT_EXE))
    ap.add_argument("--loops", type=int, default=3)
    ap.add_argument("--hz", type=float, default=10.0,
                    help="cyclone, mesher: frames per second the scene is played at")
    ap.add_argument("--bag", default=None, help="mesher: a machine-tool bag (default: generate)")
    ap.add_argument("--grid", type=int, default=128)
    ap.add_argument("--config", default=None,
                    help="mesher, robot, cloud: the launch config (default: the scene's, e.g. "
                         "launch_configs/machine_tool.yaml)")
    ap.add_argument("--frames", type=int, default=None,
                    help="mesher: frames per body of the generated scene (default: the scene's, 64)")
    ap.add_argument("--markers-reader", action="store_true",
                    help="mesher: a display's reader subscribes to /checker/markers (without one "
                         "the checker builds no markers)")
    ap.add_argument("--settle", type=float, default=20.0,
                    help="mesher: seconds after the bag before the launch is stopped")
    ap.add_argument("--seconds-max", type=int, default=600)
    ap.add_argument("--seconds", type=float, default=None,
                    help="idle: measuring time (default 30); carving: sending time (default 60); "
                         "mesher: play time (frames = seconds x hz; default: the scene's 64 frames)")
    ap.add_argument("--setup", choices=sorted(CARVING_SETUPS), default="small",
                    help="carving: the workpiece, and whether a mesher and checker run too")
    ap.add_argument("--frame-hz", type=float, default=30.0,
                    help="carving: display frames per second (occupancy_period_s = 1 / this)")
    ap.add_argument("--pose-hz", type=float, default=1000.0, help="carving: poses per second")
    ap.add_argument("--joint-hz", type=float, default=500.0, help="robot: joint states per second")
    ap.add_argument("--camera", default="640x480", help="cloud: the depth camera's pixels, WxH")
    ap.add_argument("--cloud-grid", type=int, default=64, help="cloud: voxels per edge of the cell")
    ap.add_argument("--labels", action="store_true",
                    help="robot, cloud: the peer also takes /checker/labels (every tet's label, "
                         "each slab; the checker then builds them)")
    ap.add_argument("--speed", type=float, default=0.05, help="carving: knife speed [m/s]")
    ap.add_argument("--queue-depth", type=int, default=0,
                    help="carving: queue_depth of the mesher and checker (builds that have the executor)")
    ap.add_argument("--realtime", action="store_true",
                    help="carving: mark the carving node realtime (builds that have the executor)")
    ap.add_argument("--peer-realtime", action="store_true",
                    help="carving: the pose sender runs at SCHED_FIFO, as a haptic device's driver would")
    ap.add_argument("--display", action="store_true",
                    help="carving: a display peer subscribes to /carving/surfels and /carving/occupancy")
    ap.add_argument("--max-rss-mb", type=float, default=8000.0,
                    help="carving: stop sending when the launch's resident memory exceeds this")
    ap.add_argument("--quiet", type=float, default=10.0,
                    help="cyclone: stop taking results after this many seconds without any")
    ap.add_argument("--domain", type=int, default=None,
                    help="DDS domain (default 120 + pid %% 50), e.g. to add a peer of your own")
    ap.add_argument("--signals", type=int, choices=[1, 2], default=1,
                    help="stop: SIGINTs sent to the launch, 1 s apart (2 aborts)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    exe = Path(a.exe)
    if not exe.exists():
        ap.error(f"{exe} not found: cargo build --release")
    if not (1 <= a.loops <= 100 and 0.1 <= a.hz <= 1000):
        ap.error("--loops in 1..100, --hz in 0.1..1000")
    if not (1 <= a.pose_hz <= 10_000 and 0.01 <= a.frame_hz <= 1000 and 0.001 <= a.speed <= 10):
        ap.error("--pose-hz in 1..10000, --frame-hz in 0.01..1000, --speed in 0.001..10 m/s")
    if a.domain is not None and not 0 <= a.domain <= 232:
        ap.error("--domain in 0..232")
    if a.seconds is not None and not 1 <= a.seconds <= 3600:
        ap.error("--seconds in 1..3600")
    domain = a.domain if a.domain is not None else 120 + os.getpid() % 50
    out = {"domain": domain, "machine": {"nproc": os.cpu_count()}, "exe": str(exe), "command": sys.argv,
           "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "loadavg_start": loadavg(),
           "machine_probe_ms_start": machine_probe_ms(), "memory_probe_start": memory_probe_ms(),
           "steal_s_start": steal_s()}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        cases = ["idle", "cyclone", "mesher"] if a.case == "all" else [a.case]
        given = a.seconds
        for c in cases:
            sub = tmp / c
            sub.mkdir()
            # Each case's own default (`all` runs idle, then the mesher with its 64 frames).
            a.seconds = given if given is not None else {"idle": 30.0, "carving": 60.0,
                                                         "stop": 12.0, "periodic": 600.0}.get(c)
            out[c] = {"idle": bench_idle, "cyclone": bench_cyclone, "mesher": bench_mesher,
                      "carving": bench_carving, "stop": bench_stop,
                      "periodic": bench_periodic,
                      "robot": lambda *x: bench_sources(*x, "robot"),
                      "cloud": lambda *x: bench_sources(*x, "cloud")}[c](a, exe, domain, sub)
    out["loadavg_end"] = loadavg()
    out["steal_s"] = steal_s() - out.pop("steal_s_start")
    out["machine_probe_ms_end"] = machine_probe_ms()
    out["memory_probe_end"] = memory_probe_ms()
    m0, m1 = out["memory_probe_start"], out["memory_probe_end"]
    print(f"machine probe (SHA-256 of 64 MiB, best of 3; lower is faster): "
          f"{out['machine_probe_ms_start']:.1f} ms before, {out['machine_probe_ms_end']:.1f} ms after; "
          f"memory (8 Mi random reads of 512 MiB / a 512 MiB copy): {m0['random_reads_ms']:.0f} / "
          f"{m0['copy_ms']:.0f} ms before, {m1['random_reads_ms']:.0f} / {m1['copy_ms']:.0f} ms after; "
          f"CPU stolen by the host during the run: {out['steal_s']:.2f} s")
    if a.json:
        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
