#!/usr/bin/env python3
"""Live benchmarks of the suite on DDS (issue 5), each a rerunnable command:

  python3 bench/live_bench.py cyclone   [--loops 3] [--hz 10]
      A Cyclone DDS peer (PyPI cyclonedds, tests/py/cyclone_peer.py's types) publishes the
      four-spheres frames at --hz frames per second, --loops times (header stamps shifted per
      loop, a pause longer than the mesher's idle timeout between loops, so every loop is a new
      stream and a new check), into `chronotope launch launch_configs/four_spheres.yaml`, and
      takes the report, labels and markers.  Prints, per topic, delivered/sent (sent from the
      launch's --summary), the transport latency (reception at the peer minus the DDS source
      timestamp, same host and clock; includes the peer's Python decoding) and the end-to-end
      time from a loop's last frame to its report (includes the mesher's idle timeout, 2 s).
  python3 bench/live_bench.py mesher    [--bag B] [--grid 128]
      `chronotope play` (RustDDS) publishes the machine-tool scene (grid^3 voxels, its frame
      rate) into `chronotope launch` of the machine-tool config; prints frames received,
      dropped, the per-frame lag (reader to end of handling) and the CPU time of the launch.
  python3 bench/live_bench.py idle      [--seconds 30]
      CPU load and resident memory of an idle `chronotope launch launch_configs/machine_tool.yaml`.

Build first: cargo build --release.  --exe selects another binary.  --json FILE writes the
figures as JSON too.  Domain: 120 + pid % 50 (never ROS_DOMAIN_ID's value), loopback discovery.
"""

import argparse
import importlib.util
import json
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


# ---- mesher -----------------------------------------------------------------------------

def bench_mesher(a, exe, domain, tmp):
    bag = Path(a.bag) if a.bag else tmp / f"machine-tool-{a.grid}.mcap"
    if not a.bag:
        log(f"generating the machine-tool scene at {a.grid}^3 -> {bag}")
        subprocess.run([str(exe), "scene", "machine-tool", "--grid", str(a.grid), "--out", str(bag)],
                       check=True, stdout=subprocess.DEVNULL)
    cfg = ROOT / "launch_configs/machine_tool.yaml"
    summary = tmp / "summary.json"
    launch = start_launch(exe, cfg, domain, a.seconds_max, summary, tmp / "launch.log")
    time.sleep(1.0)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), RUST_LOG="warn")
    t0 = time.monotonic()
    play = subprocess.run([str(exe), "play", str(bag), "--wait", "3"], env=env,
                          capture_output=True, text=True)
    t_play = time.monotonic() - t0 - 3
    log(play.stderr.strip().splitlines()[-1] if play.stderr.strip() else "play: no output")
    # Let the nodes close the streams (idle timeout) and check.
    time.sleep(a.settle)
    cpu = proc_cpu_s(launch.pid)
    rss = proc_rss_mb(launch.pid)
    launch.terminate()
    wait(launch, "chronotope launch", 300)
    s = json.loads(summary.read_text())["transport"]
    lag = s.get("lag", {})
    print(f"\nmesher: machine-tool {a.grid}^3 bag played at its frame rate ({t_play:.1f} s) into "
          f"`launch machine_tool.yaml`")
    print("| topic | received | dropped | lag p50 [ms] | p99 [ms] | max [ms] | busy p50 [ms] |")
    print("|---|---|---|---|---|---|---|")
    for t in sorted(s["received"]):
        l = lag.get(t, {})
        print(f"| `{t}` | {s['received'][t]} | {s['dropped'].get(t, 0)} | {l.get('p50_ms', float('nan')):.1f} | "
              f"{l.get('p99_ms', float('nan')):.1f} | {l.get('max_ms', float('nan')):.1f} | "
              f"{l.get('busy_p50_ms', float('nan')):.1f} |")
    print(f"launch CPU until {a.settle:.0f} s after the bag: {cpu:.1f} s; RSS {rss:.0f} MB")
    return {"transport": s, "cpu_s": cpu, "rss_mb": rss, "play_s": t_play, "grid": a.grid}


# ---- idle -------------------------------------------------------------------------------

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
    ap.add_argument("case", choices=["cyclone", "mesher", "idle", "all"])
    ap.add_argument("--exe", default=str(DEFAULT_EXE))
    ap.add_argument("--loops", type=int, default=3)
    ap.add_argument("--hz", type=float, default=10.0)
    ap.add_argument("--bag", default=None, help="mesher: a machine-tool bag (default: generate)")
    ap.add_argument("--grid", type=int, default=128)
    ap.add_argument("--settle", type=float, default=20.0,
                    help="mesher: seconds after the bag before the launch is stopped")
    ap.add_argument("--seconds-max", type=int, default=600)
    ap.add_argument("--seconds", type=float, default=30.0, help="idle: measuring time")
    ap.add_argument("--quiet", type=float, default=10.0,
                    help="cyclone: stop taking results after this many seconds without any")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    exe = Path(a.exe)
    if not exe.exists():
        ap.error(f"{exe} not found: cargo build --release")
    if not (1 <= a.loops <= 100 and 0.1 <= a.hz <= 1000):
        ap.error("--loops in 1..100, --hz in 0.1..1000")
    domain = 120 + os.getpid() % 50
    out = {"machine": {"nproc": os.cpu_count()}}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        cases = ["idle", "cyclone", "mesher"] if a.case == "all" else [a.case]
        for c in cases:
            sub = tmp / c
            sub.mkdir()
            out[c] = {"idle": bench_idle, "cyclone": bench_cyclone, "mesher": bench_mesher}[c](
                a, exe, domain, sub)
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
