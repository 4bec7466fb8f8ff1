#!/usr/bin/env python3
"""Tests of bench/live_bench.py's pure parts (no DDS, no chronotope binary): the carving tool
path, the pose-wrench matching, the pacing figures, the launch configs and the bag's frame
period.

    python3 -m unittest tests/py/test_live_bench.py
"""

import importlib.util
import math
import os
import sys
import tempfile
import unittest
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent


def load_bench():
    sys.dont_write_bytecode = True  # no __pycache__ in bench/
    spec = importlib.util.spec_from_file_location("live_bench", ROOT / "bench/live_bench.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


lb = load_bench()


def rotate(q, v):
    """v rotated by the unit quaternion q = (x, y, z, w)."""
    x, y, z, w = q
    # t = 2 q_vec x v; v' = v + w t + q_vec x t
    t = (2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0]))
    c = (y * t[2] - z * t[1], z * t[0] - x * t[2], x * t[1] - y * t[0])
    return tuple(v[i] + w * t[i] + c[i] for i in range(3))


class KnifePathTest(unittest.TestCase):
    def setUp(self):
        self.lo, self.hi = [0.0, 0.0, 0.0], [0.06, 0.06, 0.03]
        self.p = lb.KnifePath(self.lo, self.hi, speed=0.05)

    def test_orientation_puts_the_blade_face_normal_to_y_and_its_width_along_z(self):
        q = self.p.QUAT
        self.assertAlmostEqual(sum(c * c for c in q), 1.0, places=12)
        n = rotate(q, (0, 0, 1))  # the blade's face normal
        self.assertAlmostEqual(abs(n[1]), 1.0, places=12)
        w = rotate(q, (0, 1, 0))  # the blade's width
        self.assertAlmostEqual(abs(w[2]), 1.0, places=12)
        l = rotate(q, (1, 0, 0))  # its length, along the motion
        self.assertAlmostEqual(l[0], 1.0, places=12)

    def test_the_blade_is_outside_the_block_at_each_turn(self):
        for k in range(6):
            (x, _, _), _ = self.p.at(k * self.p.pass_s)
            outside = x + self.p.half_len < self.lo[0] or x - self.p.half_len > self.hi[0]
            self.assertTrue(outside, f"turn {k}: blade centre at x = {x}")

    def test_it_moves_at_the_speed_asked_within_a_pass(self):
        t = 0.3 * self.p.pass_s
        (x0, y0, z0), _ = self.p.at(t)
        (x1, y1, z1), _ = self.p.at(t + 0.001)
        self.assertAlmostEqual(abs(x1 - x0) / 0.001, 0.05, places=6)
        self.assertEqual((y0, z0), (y1, z1))
        # Back the other way on the next pass.
        (xa, _, _), _ = self.p.at(t + self.p.pass_s)
        (xb, _, _), _ = self.p.at(t + self.p.pass_s + 0.001)
        self.assertLess(xb, xa)

    def test_each_pass_cuts_a_fresh_kerf_then_a_deeper_layer_back_along_y(self):
        n = self.p.passes_per_layer
        self.assertEqual(n, 30)  # 60 mm / 2 mm
        mid = 0.5 * self.p.pass_s
        ys = [self.p.at(k * self.p.pass_s + mid)[0][1] for k in range(2 * n)]
        zs = [self.p.at(k * self.p.pass_s + mid)[0][2] for k in range(2 * n)]
        for k in range(1, n):
            self.assertAlmostEqual(ys[k] - ys[k - 1], 0.002, places=12)
        self.assertAlmostEqual(ys[n], ys[n - 1], places=12)  # the next layer starts there
        for k in range(n + 1, 2 * n):
            self.assertAlmostEqual(ys[k] - ys[k - 1], -0.002, places=12)
        for y in ys:
            self.assertTrue(self.lo[1] < y < self.hi[1])
        # The blade's bottom edge: 5 mm into the block, then 10 mm.
        self.assertAlmostEqual(zs[0] - self.p.half_w, self.hi[2] - 0.005, places=12)
        self.assertAlmostEqual(zs[n] - self.p.half_w, self.hi[2] - 0.010, places=12)

    def test_it_never_goes_below_the_block(self):
        t = 1000 * self.p.pass_s + 0.5 * self.p.pass_s
        (_, _, z), _ = self.p.at(t)
        self.assertGreaterEqual(z - self.p.half_w, self.lo[2])
        self.assertLess(z - self.p.half_w, self.hi[2])  # still in the material

    def test_the_big_block_gets_fresh_kerfs_for_more_than_a_minute(self):
        s = lb.CARVING_SETUPS["big"]
        p = lb.KnifePath(s["lo"], s["hi"], speed=0.05)
        self.assertGreater(p.passes_per_layer * p.pass_s, 60.0)
        (x, y, z), _ = p.at(59.9)
        self.assertTrue(s["lo"][1] < y < s["hi"][1])
        self.assertLess(z - p.half_w, s["hi"][2])


class MatchTest(unittest.TestCase):
    def test_latency_counts_and_missing(self):
        ms = 1_000_000
        sent = {1000 * ms + k * ms: 1000 * ms + k * ms for k in range(5)}
        stamps = sorted(sent)
        wrenches = [
            (stamps[0], stamps[0] + ms // 10, 1.0),   # 0.1 ms
            (stamps[1], stamps[1] + 3 * ms, 0.0),      # 3 ms, no force
            (stamps[1], stamps[1] + 4 * ms, 2.0),      # a second wrench for the same pose
            (stamps[3], stamps[3] + ms // 2, 2.0),     # 0.5 ms
            (42, 43, 1.0),                             # no such pose
        ]
        r = lb.match_wrenches(sent, {}, wrenches)
        self.assertEqual(r["poses_sent"], 5)
        self.assertEqual(r["wrenches_received"], 5)
        self.assertEqual(r["poses_with_wrench"], 3)
        self.assertEqual(r["poses_without_wrench"], 2)
        self.assertEqual(r["wrenches_duplicate"], 1)
        self.assertEqual(r["wrenches_unmatched"], 1)
        self.assertAlmostEqual(r["latency_ms_max"], 3.0)
        self.assertAlmostEqual(r["latency_ms_p50"], 0.5)
        self.assertEqual(r["latency_over_1ms"], 1)
        self.assertEqual(r["latency_over_2ms"], 1)
        self.assertEqual(r["wrenches_with_force"], 2)
        self.assertEqual(r["missing_runs"], 2)  # poses 2 and 4, apart
        self.assertEqual(r["longest_missing_run"], 1)

    def test_runs_of_missing_wrenches(self):
        sent = {k: k for k in range(10)}
        have = [0, 1, 5, 9]  # missing 2-4 (a run of 3) and 6-8 (a run of 3)
        r = lb.match_wrenches(sent, {}, [(k, k + 100, 1.0) for k in have])
        self.assertEqual(r["missing_runs"], 2)
        self.assertEqual(r["longest_missing_run"], 3)
        r = lb.match_wrenches(sent, {}, [(k, k, 1.0) for k in [3]])
        self.assertEqual((r["missing_runs"], r["longest_missing_run"]), (2, 6))

    def test_the_pose_readers_source_timestamp_is_preferred(self):
        sent = {10: 10, 20: 20}
        seen = {10: 12}  # a reader saw another source timestamp for the first pose
        r = lb.match_wrenches(sent, seen, [(10, 1_000_012, 1.0), (20, 2_000_020, 1.0)])
        self.assertAlmostEqual(r["latency_ms_p50"], 1.0)
        self.assertAlmostEqual(r["latency_ms_max"], 2.0)
        self.assertEqual(r["source_timestamp_mismatches"], 1)
        self.assertEqual(r["poses_seen_by_peer_reader"], 1)

    def test_no_wrench_at_all(self):
        r = lb.match_wrenches({1: 1, 2: 2}, {}, [])
        self.assertEqual(r["poses_without_wrench"], 2)
        self.assertTrue(math.isnan(r["latency_ms_p50"]))
        self.assertTrue(math.isnan(r["latency_ms_max"]))


class PacingTest(unittest.TestCase):
    def test_rate_lateness_and_long_intervals(self):
        deadlines = [k * 0.001 for k in range(10)]
        sent = list(deadlines)
        sent[5] += 0.0025  # 2.5 ms late: intervals of 3.5 ms and -1.5 ms around it
        r = lb.pacing_stats(deadlines, sent, 0.010)
        self.assertEqual(r["sent"], 10)
        self.assertAlmostEqual(r["achieved_hz"], 1000.0)
        self.assertAlmostEqual(r["late_ms_max"], 2.5)
        self.assertAlmostEqual(r["late_ms_p50"], 0.0)
        self.assertEqual(r["intervals_over_2ms"], 1)
        self.assertAlmostEqual(r["interval_ms_max"], 3.5)
        self.assertAlmostEqual(r["interval_ms_p50"], 1.0)


class ConfigTest(unittest.TestCase):
    def parse(self, setup, hz=30.0):
        import yaml
        return yaml.safe_load(lb.carving_config(setup, hz))["launch"]

    def params(self, node):
        return {p["name"]: p["value"] for p in node["node"].get("param", [])}

    def test_every_setup(self):
        for setup, s in lb.CARVING_SETUPS.items():
            nodes = self.parse(setup)
            execs = [n["node"]["exec"] for n in nodes]
            want = ["carving", "mesher", "checker"] if s["pipeline"] else ["carving"]
            self.assertEqual(execs, want, setup)
            p = self.params(nodes[0])
            self.assertEqual(p["pose_topic"], lb.POSE_TOPIC)
            self.assertEqual(p["spacing_m"], s["spacing"])
            self.assertEqual(p["workpiece_min"], s["lo"])
            self.assertEqual(p["workpiece_max"], s["hi"])
            self.assertAlmostEqual(p["occupancy_period_s"], 1 / 30, places=6)
            self.assertEqual(p["knife_thickness_m"], lb.KNIFE["thickness"])
            if s["pipeline"]:
                self.assertEqual(self.params(nodes[1])["bodies"], ["/carving/occupancy"])
                self.assertNotIn("pairs", self.params(nodes[2]))  # a lone body

    def test_frame_rate(self):
        p = self.params(self.parse("small", hz=10.0)[0])
        self.assertAlmostEqual(p["occupancy_period_s"], 0.1)

    def test_big_is_about_a_million_surfels(self):
        s = lb.CARVING_SETUPS["big"]
        n = [round((h - l) / s["spacing"]) + 1 for l, h in zip(s["lo"], s["hi"])]
        surface = 2 * (n[0] * n[1] + n[0] * n[2] + n[1] * n[2])
        self.assertTrue(1.0e6 < surface < 1.3e6, surface)


class BagTest(unittest.TestCase):
    def test_frame_period_and_counts(self):
        from mcap.writer import Writer
        with tempfile.TemporaryDirectory() as d:
            bag = Path(d) / "b.mcap"
            with open(bag, "wb") as f:
                w = Writer(f)
                w.start(profile="ros2")
                grid = w.register_schema("chronotope_msgs/msg/VoxelGrid", "ros2msg", b"")
                pose = w.register_schema("geometry_msgs/msg/PoseStamped", "ros2msg", b"")
                a = w.register_channel("/a/occupancy", "cdr", grid)
                b = w.register_channel("/b/occupancy", "cdr", grid)
                c = w.register_channel("/pose", "cdr", pose)
                for k in range(5):
                    t = 10**9 + k * 50_000_000
                    w.add_message(a, t, b"x", t)
                    w.add_message(b, t, b"x", t)
                    w.add_message(c, t + 1, b"x", t + 1)  # not a frame: ignored
                w.add_message(a, 10**9 + 5 * 50_000_000, b"x", 0)
                w.finish()
            period, counts = lb.bag_frames(bag)
            self.assertAlmostEqual(period, 0.05)
            self.assertEqual(counts, {"/a/occupancy": 6, "/b/occupancy": 5})


class HelpersTest(unittest.TestCase):
    def test_help_prints(self):
        import subprocess
        r = subprocess.run([sys.executable, "-B", str(ROOT / "bench/live_bench.py"), "--help"],
                           capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        for opt in ("--setup", "--display", "--hz", "--seconds", "--exe", "--domain"):
            self.assertIn(opt, r.stdout)

    def test_summary_extras(self):
        full = {"nodes": {"/a": {"problems": {"x": 2}, "cpu_s": 1.5}, "/b": {"problems": {}}},
                "transport": {"received": {"/t": 3}, "cpu": {"per_node": {"/a": 0.5}}},
                "threads": [{"cpu_fraction": 0.25}]}
        e = lb.summary_extras(full)
        self.assertEqual(e["problems"], {"/a": {"x": 2}})
        self.assertEqual(e["cpu"], {"nodes./a.cpu_s": 1.5, "transport.cpu.per_node./a": 0.5,
                                    "threads.0.cpu_fraction": 0.25})
        self.assertEqual(lb.summary_extras({"nodes": {}})["cpu"], {})

    def test_pct(self):
        self.assertEqual(lb.pct(list(range(101)), 0.5), 50)
        self.assertEqual(lb.pct(list(range(101)), 0.99), 99)
        self.assertEqual(lb.pct([3, 1, 2], 1.0), 3)
        self.assertTrue(math.isnan(lb.pct([], 0.5)))

    def test_proc_readers_on_this_process(self):
        self.assertEqual(len(lb.loadavg()), 3)
        threads = lb.thread_cpu_s(os.getpid())
        self.assertGreaterEqual(len(threads), 1)
        self.assertTrue(all(v >= 0 for v in threads.values()))
        self.assertGreater(lb.proc_peak_rss_mb(os.getpid()), 0)
        self.assertGreaterEqual(lb.proc_peak_rss_mb(os.getpid()), lb.proc_rss_mb(os.getpid()) - 1)


if __name__ == "__main__":
    unittest.main()
