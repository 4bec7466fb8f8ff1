#!/usr/bin/env python3
"""Markdown tables of `bench/live_bench.py ... --json FILE` results (carving and mesher runs):

    python3 bench/live_table.py bench/results/baseline-*.json
"""

import json
import sys
from pathlib import Path


def f(x, nd=2):
    return "n/a" if x is None or x != x else f"{x:.{nd}f}"


def load(v):
    return " ".join(f"{x:.1f}" for x in v)


def carving_rows(runs):
    print("| setup | poses sent | received by the launch | wrenches sent | wrenches received | "
          "poses without a wrench | latency p50 [ms] | p99 [ms] | max [ms] | launch CPU [% of one core] | "
          "RSS end / peak [MB] | peer's rate [Hz] | load before -> after |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for path, c in runs:
        r, p = c["result"], c["pacing"]
        note = (f" (stopped at {c['stopped_early_rss_mb']:.0f} MB RSS)"
                if c.get("stopped_early_rss_mb") else "")
        print(f"| {c['description']}{note} | {r['poses_sent']} | {r.get('launch_poses_received', 'n/a')} | "
              f"{r.get('launch_wrenches_sent', 'n/a')} | {r['wrenches_received']} | "
              f"**{r['poses_without_wrench']}** | {f(r['latency_ms_p50'])} | **{f(r['latency_ms_p99'])}** | "
              f"{f(r['latency_ms_max'])} | {100 * c['launch_cpu_fraction_of_one_core']:.0f} | "
              f"{c['rss_mb']:.0f} / {c['peak_rss_mb']:.0f} | {p['achieved_hz']:.0f} | "
              f"{load(c['loadavg_before'])} -> {load(c['loadavg_after'])} |")


def mesher_rows(runs):
    print("| rate | topic | received | dropped | lag p50 [ms] | p99 [ms] | max [ms] | p99 [periods] | "
          "busy p50 [ms] | launch CPU while playing [% of one core] | RSS end / peak [MB] | "
          "load before -> after |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for path, m in runs:
        cpu = 100 * m["cpu_s_while_playing"] / max(m["play_s"], 1e-9)
        for i, t in enumerate(m["topics"]):
            tail = (f"{cpu:.0f} | {m['rss_mb']:.0f} / {m['peak_rss_mb']:.0f} | "
                    f"{load(m['loadavg_before'])} -> {load(m['loadavg_after'])}") if i == 0 else " | | "
            print(f"| {m['hz']:g} Hz ({max(m['frames_per_topic'].values())} frames per body) | "
                  f"`{t['topic']}` | {t['received']} | {t['dropped']} | {f(t['lag_ms_p50'], 0)} | "
                  f"{f(t['lag_ms_p99'], 0)} | {f(t['lag_ms_max'], 0)} | {f(t['lag_p99_periods'], 1)} | "
                  f"{f(t['busy_ms_p50'], 1)} | {tail} |")


def main() -> int:
    carving, mesher = [], []
    for p in sys.argv[1:]:
        d = json.loads(Path(p).read_text())
        if "carving" in d:
            carving.append((p, d["carving"]))
        if "mesher" in d:
            mesher.append((p, d["mesher"]))
    if carving:
        carving_rows(carving)
        print()
    if mesher:
        mesher_rows(mesher)
    return 0


if __name__ == "__main__":
    sys.exit(main())
