#!/usr/bin/env python3
"""The hostile-input campaign: generate bad bags, configs, scenes and pose streams, run the
chronotope binary on each under a timeout and an address-space cap, and classify the outcome.

    python3 bench/hostile/campaign.py --bin target/release/chronotope --out /tmp/hostile
    python3 bench/hostile/campaign.py --bin target/release/chronotope --quick
    python3 bench/hostile/campaign.py --bin B --only voxelgrid,launch -j 2 --timeout 20
    python3 bench/hostile/campaign.py --bin B --only outputs,bombs,signals,hangs,silent,errors,wal,links

See bench/hostile/README.md for the categories, the classes and the oracles.
"""

import argparse
import json
import os
import random
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import gen  # noqa: E402
import recording  # noqa: E402

CLASSES = ["ok", "counted", "clean_error", "unclear", "slow", "created", "temp_left", "lost",
           "silent", "wrong", "disk", "panic", "hang", "memory", "destroyed"]
BAD = {"unclear", "slow", "created", "temp_left", "lost", "silent", "wrong", "disk", "panic",
       "hang", "memory", "destroyed"}
# Worse classes win when a case has several runs or oracles.
RANK = {c: i for i, c in enumerate(CLASSES)}


def limit_memory(gb):
    def apply():
        cap = int(gb * (1 << 30))
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        os.setsid()
    return apply


def run(cmd, cwd, timeout, mem_gb):
    """Runs one command; returns a dict with rc, seconds, stdout/stderr tails, timed_out."""
    start = time.monotonic()
    p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         stdin=subprocess.DEVNULL, preexec_fn=limit_memory(mem_gb))
    try:
        out, err = p.communicate(timeout=timeout)
        timed_out = False
    except subprocess.TimeoutExpired:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = p.communicate()
        timed_out = True
    return {
        "cmd": [str(c) for c in cmd],
        "rc": p.returncode,
        "seconds": round(time.monotonic() - start, 3),
        "timed_out": timed_out,
        "stdout": out.decode(errors="replace")[-6000:],
        "stderr": err.decode(errors="replace")[-6000:],
    }


# ----------------------------------------------------------------------------------------
# Classification of one run, then of the case through its oracles.
# ----------------------------------------------------------------------------------------

DEBUG_DUMP = re.compile(r"\b[A-Z][A-Za-z0-9_]* \{ (\.\.|[a-z_]+: )")
LONG_NUMBER = re.compile(r"\d{60,}")
TWICE = re.compile(r"bodies (\S+) and (\S+) ")


def message_problems(text, case):
    """Why an error message is not one a user can act on (empty list if it is)."""
    problems = []
    if not text.strip():
        problems.append("no message")
    if DEBUG_DUMP.search(text) or "{ .." in text:
        problems.append("debug dump in the message")
    if LONG_NUMBER.search(text):
        problems.append("a number of 60+ digits echoed")
    for a, b in TWICE.findall(text):
        if a.rstrip(",:") == b.rstrip(",:"):
            problems.append(f"names one body twice ({a})")
    m = re.search(r"no messages of type (\S+); topics in the bag: (.*)", text)
    if m and f"({m.group(1)})" in m.group(2):
        problems.append("says there is no topic of a type it then lists")
    if "holds no messages" in text and case.get("expect", {}).get("has_messages"):
        problems.append("says the bag holds no messages, but it has (unreadable) ones")
    if "fewer than two frames" in text:
        for body, n in case.get("expect", {}).get("valid_frames", {}).items():
            if n >= 2 and body in text:
                problems.append(f"'fewer than two frames' for {body}, which has {n} valid")
    if re.search(r"\(got 1\)", text) and case.get("expect", {}).get("nan_input"):
        problems.append("a NaN reported as '(got 1)'")
    return problems


def counted(r, report):
    """Did an exit-0 run say (stderr, or counters in its report) that something was wrong?"""
    if re.search(r"\b(WARN|ERROR)\b", r["stderr"]) or "problem" in r["stdout"]:
        return True
    if not isinstance(report, dict):
        return False
    inp = report.get("input") or {}
    if inp.get("bag_errors") or any((inp.get("undecodable") or {}).values()) or any(
            (inp.get("wrong_type") or {}).values()):
        return True
    for node in (report.get("nodes") or {}).values():
        if any((node.get("problems") or {}).values()):
            return True
    for b in report.get("bodies", []):
        if b.get("skipped_frames"):
            return True
    if report.get("bag_errors"):
        return True
    return False


def run_class(r, case):
    err = r["stderr"] + r["stdout"]
    if r["timed_out"]:
        return "hang", "no answer within the timeout"
    if r["rc"] == 101 or "panicked at" in err:
        return "panic", err.strip().splitlines()[-1][:200] if err.strip() else "panic"
    if r["rc"] is not None and r["rc"] < 0 or "memory allocation of" in err \
            or "Cannot allocate memory" in err or "out of memory" in err.lower():
        return "memory", f"killed by signal {-r['rc']}" if r["rc"] < 0 else "allocation failed"
    if r["rc"] != 0:
        probs = message_problems(r["stderr"] or r["stdout"], case)
        if probs:
            return "unclear", "; ".join(probs)
        return "clean_error", (r["stderr"].strip().splitlines() or [""])[-1][:200]
    return None, ""


def load_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def has_nan(report):
    """Numbers in a report that are NaN or null where a number belongs."""
    bad = []
    for b in report.get("bodies", []) if isinstance(report, dict) else []:
        v = b.get("hypervolume_m3s", 0.0)
        if v is None or v != v:
            bad.append(f"hypervolume of {b.get('id')} is {v}")
    for p in report.get("pairs", []) if isinstance(report, dict) else []:
        v = p.get("overlap_hypervolume_m3s", 0.0)
        if v is None or v != v:
            bad.append(f"overlap of {p.get('a')} x {p.get('b')} is {v}")
    for res in report.get("resolutions", []) if isinstance(report, dict) else []:
        for k in ("distance", "scale"):
            v = res.get(k, 0.0)
            if v != v:
                bad.append(f"resolution {k} is NaN")
    return bad


def verdicts(report):
    if not isinstance(report, dict):
        return {}
    return {tuple(sorted((p["a"], p["b"]))): bool(p["interfering"])
            for p in report.get("pairs", [])}


def frames(report):
    if not isinstance(report, dict):
        return {}
    return {b["id"]: b.get("frames", 0) for b in report.get("bodies", [])}


def classify(case, runs, workdir):
    """The case's class and the reasons, from its runs and oracles."""
    expect = case.get("expect", {})
    worst, reasons = "ok", []

    def bump(cls, why):
        nonlocal worst
        if RANK[cls] > RANK[worst]:
            worst = cls
        reasons.append(f"{cls}: {why}")

    reports = {}
    for name, r in runs.items():
        cls, why = run_class(r, case)
        rep = load_json(workdir / f"{name}.json")
        reports[name] = rep
        if cls is None:
            if counted(r, rep):
                bump("counted", f"{name}: counted")
            for b in has_nan(rep):
                bump("wrong", f"{name}: {b}")
            for out_check in case.get("out_checks", []):
                bad = gen.check_output(out_check, workdir)
                if bad:
                    bump("wrong", f"{name}: {bad}")
        else:
            bump(cls, f"{name}: {why}")
            if cls in ("clean_error", "unclear") and (expect.get("must_succeed")
                                                     or expect.get("intact_pairs")):
                bump("lost", f"{name}: refused the whole input ({why[:120]})")
    ok_runs = {n: r for n, r in runs.items() if r["rc"] == 0 and not r["timed_out"]}
    # check and replay must agree on every pair both report.
    vc, vr = verdicts(reports.get("check")), verdicts(reports.get("replay"))
    if "check" in ok_runs and "replay" in ok_runs:
        for k in set(vc) & set(vr):
            if vc[k] != vr[k]:
                bump("wrong", f"check says {'COLLIDE' if vc[k] else 'clear'}, replay says "
                              f"{'COLLIDE' if vr[k] else 'clear'} for {k[0]} x {k[1]}")
    truth = {tuple(sorted(k.split(" "))): v for k, v in expect.get("truth", {}).items()}
    for name in ok_runs:
        v = verdicts(reports.get(name))
        for k, collide in v.items():
            if k in truth and collide and not truth[k]:
                bump("wrong", f"{name}: COLLIDE for {k[0]} x {k[1]}, which the accepted data "
                              "says is clear")
            if k in truth and truth[k] and not collide and expect.get("truth_exact"):
                bump("wrong", f"{name}: clear for {k[0]} x {k[1]}, which collides")
        for pair in expect.get("intact_pairs", []):
            k = tuple(sorted(pair.split(" ")))
            if name in ("check", "replay") and reports.get(name) is not None and k not in v:
                bump("lost", f"{name}: pair {k[0]} x {k[1]} (undamaged bodies) not reported")
        fr = frames(reports.get(name))
        for body, n in expect.get("valid_frames", {}).items():
            if n >= 2 and body in fr and fr[body] == 0:
                bump("wrong", f"{name}: {body} reported with 0 frames; it has {n} valid")
        if expect.get("must_count") and not counted(ok_runs[name], reports.get(name)):
            bump("wrong", f"{name}: accepted silently ({expect['must_count']})")
        if name == "check" and reports.get(name) is not None and expect.get("py_frames"):
            if not reports[name].get("pairs") and not reports[name].get("bodies"):
                bump("wrong", "check: empty table, though frames are readable")
    # Recovery against the Python indexed reader (CRC-protected forms only: unchunked data
    # can change silently).
    rec = expect.get("py_frames")
    if rec and "replay" in ok_runs and isinstance(reports.get("replay"), dict):
        fr = frames(reports["replay"])
        for body, n in rec.items():
            if n >= 2 and fr.get(body, 0) == 0 and expect.get("crc_protected"):
                bump("lost", f"replay: {body} has no frames; the Python indexed reader "
                             f"reads {n}")
    if worst == "ok" and any(r["rc"] != 0 for r in runs.values()):
        worst = "clean_error"
    return worst, reasons, reports


def recovered(report):
    if isinstance(report, dict):
        return (report.get("input") or {}).get("messages")
    return None


# ----------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", required=True, help="the chronotope binary to test")
    ap.add_argument("--out", default="/tmp/hostile", help="work and result directory")
    ap.add_argument("--quick", action="store_true", help="about 100 cases")
    ap.add_argument("--only", default="", help="comma-separated categories")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per run")
    ap.add_argument("--mem-gb", type=float, default=6.0, help="address-space cap per run")
    ap.add_argument("-j", type=int, default=1, help="runs at once")
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--limit", type=int, default=0, help="stop after N cases")
    ap.add_argument("--resume", action="store_true", help="skip cases already in results")
    ap.add_argument("--disk-cap-gb", type=float, default=None,
                    help="temporary bytes a run may peak at (default: max_decompressed_file_"
                         "bytes as docs/limits.md documents it, else 4)")
    ap.add_argument("--disk-budget-gb", type=float, default=4.0,
                    help="a run is killed (class disk) past min(cap, this) + 64 MiB of "
                         "temporary bytes, so a bomb never fills the disk")
    args = ap.parse_args()

    binary = str(Path(args.bin).resolve())
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    repo = Path(__file__).resolve().parents[2]
    rng = random.Random(args.seed)
    only = set(filter(None, args.only.split(",")))
    cases = gen.generate(repo, out / "cases", rng, quick=args.quick, only=only)
    new = recording.generate(out / "cases", args.seed, quick=args.quick, only=only, repo=repo)
    if new:
        cases += new
        (out / "cases" / "cases.json").write_text(json.dumps(
            [{k: c.get(k) for k in ("id", "category", "kind", "runs", "expect", "what")}
             for c in cases], indent=1, default=str))
    documented = recording.documented_cap(repo)
    cap = int(args.disk_cap_gb * (1 << 30)) if args.disk_cap_gb is not None else \
        (documented or 4 << 30)
    budget = int(args.disk_budget_gb * (1 << 30))
    ctx = {"binary": binary, "repo": str(repo), "shared": str(out / "shared"),
           "timeout": args.timeout, "mem_gb": args.mem_gb, "cap_bytes": cap,
           "kill_bytes": min(cap, budget) + (64 << 20), "rank": RANK,
           "message_problems": message_problems, "counted": counted, "load_json": load_json,
           "dds": lambda: recording.dds_available(binary, out / "shared")}
    if new:
        (out / "disk-cap.json").write_text(json.dumps({
            "cap_bytes": cap, "kill_bytes": ctx["kill_bytes"], "documented_bytes": documented,
            "source": "--disk-cap-gb" if args.disk_cap_gb is not None else
            ("docs/limits.md" if documented else "default 4 GiB")}))
    if args.limit:
        cases = cases[:args.limit]
    results_path = out / "results.jsonl"
    done = set()
    if args.resume and results_path.exists():
        for line in results_path.read_text().splitlines():
            done.add(json.loads(line)["id"])
    else:
        results_path.write_text("")
    print(f"{len(cases)} cases ({len(done)} already done) -> {results_path}", flush=True)

    def do(case):
        if case["category"] in recording.CATEGORIES:
            return recording.run_case(case, ctx)
        workdir = Path(case["dir"])
        runs = {}
        for name, argv in case["runs"]:
            for setup in case.get("setup", []):
                gen.setup(setup, workdir)
            argv = [binary if a == "BIN" else a for a in argv]
            runs[name] = run(argv, workdir, case.get("timeout", args.timeout), args.mem_gb)
        cls, reasons, reports = classify(case, runs, workdir)
        return {
            "id": case["id"], "category": case["category"], "kind": case["kind"],
            "class": cls, "reasons": reasons,
            "runs": {n: {k: r[k] for k in ("cmd", "rc", "seconds", "timed_out")}
                     | {"stderr_tail": r["stderr"][-400:]} for n, r in runs.items()},
            "recovered": {"replay_messages": recovered(reports.get("replay")),
                          "python_indexed": case.get("expect", {}).get("py_messages"),
                          "original": case.get("expect", {}).get("orig_messages")},
        }

    todo = [c for c in cases if c["id"] not in done]
    start = time.monotonic()
    with open(results_path, "a") as f:
        if args.j <= 1:
            it = map(do, todo)
        else:
            from concurrent.futures import ThreadPoolExecutor
            it = ThreadPoolExecutor(args.j).map(do, todo)
        for i, res in enumerate(it, 1):
            f.write(json.dumps(res) + "\n")
            f.flush()
            if i % 25 == 0 or res["class"] in ("panic", "hang", "memory", "wrong",
                                               "destroyed", "disk"):
                print(f"[{i}/{len(todo)} {time.monotonic() - start:.0f}s] {res['id']}: "
                      f"{res['class']} {res['reasons'][:2]}", flush=True)
    summarize(results_path, out / "summary.md")
    print((out / "summary.md").read_text())


def summarize(results_path, md_path):
    rows = [json.loads(l) for l in results_path.read_text().splitlines() if l.strip()]
    cats = sorted({r["category"] for r in rows})
    table = {c: {k: 0 for k in CLASSES} for c in cats}
    runs = 0
    for r in rows:
        table[r["category"]][r["class"]] += 1
        runs += len(r["runs"])
    lines = [f"# Hostile-input campaign: {len(rows)} cases, {runs} runs", "",
             "| category | cases | " + " | ".join(CLASSES) + " |",
             "|---|---|" + "---|" * len(CLASSES)]
    for c in cats:
        n = sum(table[c].values())
        lines.append(f"| {c} | {n} | " + " | ".join(str(table[c][k]) for k in CLASSES) + " |")
    tot = {k: sum(table[c][k] for c in cats) for k in CLASSES}
    lines.append(f"| **all** | {len(rows)} | " + " | ".join(str(tot[k]) for k in CLASSES) + " |")
    # Kinds with a bad outcome, for reading.
    old_rows = [r for r in rows if r["category"] not in recording.CATEGORIES]
    new_rows = [r for r in rows if r["category"] in recording.CATEGORIES]
    if old_rows:
        lines += ["", "## Bad outcomes by kind", "", "| kind | class | cases | first reason |",
                  "|---|---|---|---|"]
    by_kind = {}
    for r in old_rows:
        if r["class"] in BAD:
            key = (r["category"] + "/" + r["kind"], r["class"])
            by_kind.setdefault(key, []).append(r)
    for (kind, cls), rs in sorted(by_kind.items()):
        why = next((x for x in rs[0]["reasons"] if x.startswith(cls)), rs[0]["reasons"][:1])
        why = str(why).replace("|", "/")[:160]
        lines.append(f"| {kind} | {cls} | {len(rs)} | {why} |")
    if new_rows:
        cap = md_path.parent / "disk-cap.json"
        if cap.exists():
            c = json.loads(cap.read_text())
            doc = c.get("documented_bytes")
            lines += ["", f"Disk cap: {c['cap_bytes'] / (1 << 30):g} GiB of temporary bytes "
                      f"per run (from {c['source']}"
                      + (f"; docs/limits.md documents max_decompressed_file_bytes = "
                         f"{doc / (1 << 30):g} GiB" if doc and c["source"] != "docs/limits.md"
                         else "") + "); a run is killed (class `disk`) past "
                      f"{c['kill_bytes'] / (1 << 30):.2f} GiB"
                      + (" (the campaign's disk budget, --disk-budget-gb)"
                         if c["kill_bytes"] < c["cap_bytes"] else "")
                      + "; a peak up to 16 MiB over the cap passes."]
        lines += ["", "## Bad outcomes, case by case (outputs, bombs, signals, hangs, silent, "
                  "errors, wal, links)", "", "| case | class | what | reasons |", "|---|---|---|---|"]
        for r in new_rows:
            if r["class"] not in BAD:
                continue
            why = "; ".join(x for x in r["reasons"] if x.split(":")[0] in BAD)
            lines.append(f"| {r['id']} | {r['class']} | {r.get('what', '')[:120]} | "
                         f"{why[:600]} |".replace("\n", " "))
        skipped = [r for r in new_rows if r.get("skipped")]
        if skipped:
            lines += ["", "Skipped: " + "; ".join(f"{r['id']} ({r['reasons'][0]})"
                                                  for r in skipped)]
        watched = [(r, n, x) for r in new_rows for n, x in r["runs"].items()
                   if x.get("peak_temp_bytes") is not None]
        if watched:
            lines += ["", "## Peak temporary bytes (TMPDIR, the output directory and files the "
                      "process had open for writing, sampled every 20 ms)", "",
                      "| case | run | exit | seconds | peak MiB | killed |", "|---|---|---|---|---|---|"]
            for r, n, x in watched:
                lines.append(f"| {r['id']} | {n} | {x['rc']} | {x['seconds']} | "
                             f"{x['peak_temp_bytes'] / (1 << 20):.0f} | {x.get('killed_for') or ''} |")
    # Recovery against the Python indexed reader.
    rec = [r for r in rows if r["category"] == "bag-damage"
           and r["recovered"]["python_indexed"] is not None]
    if rec:
        ours = sum(r["recovered"]["replay_messages"] or 0 for r in rec)
        py = sum(r["recovered"]["python_indexed"] for r in rec)
        orig = sum(r["recovered"]["original"] or 0 for r in rec)
        better = sum(1 for r in rec if (r["recovered"]["replay_messages"] or 0)
                     > r["recovered"]["python_indexed"])
        worse = sum(1 for r in rec if (r["recovered"]["replay_messages"] or 0)
                    < r["recovered"]["python_indexed"])
        lines += ["", "## Messages recovered from damaged bags", "",
                  f"{len(rec)} damaged bags holding {orig} messages: `replay` read {ours}, the "
                  f"Python `mcap` indexed reader (falling back to a linear scan) {py}; replay "
                  f"read more in {better} bags, fewer in {worse}."]
    md_path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
