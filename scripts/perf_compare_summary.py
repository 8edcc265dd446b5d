#!/usr/bin/env python3
"""Summary of scripts/perf_compare.sh's runs: each figure's median over the repetitions for
the base and the head, and the ratio head/base (> 1: the head is slower, or worse).

Usage: perf_compare_summary.py RUNS_DIR REPS
Reads RUNS_DIR/{base,head}-R.{detect.json,ingest.txt,demo.json} for R = 1..REPS.
"""
import json
import math
import re
import statistics
import sys
from pathlib import Path


def median(xs):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return statistics.median(xs) if xs else None


def detect_figures(path):
    j = json.loads(path.read_text())
    out = {}
    for method, t in j["throughput_ms"].items():
        out[f"detect {method} median ms (all classes)"] = t.get("median")
    for c in j["classes"]:
        for m in c["methods"]:
            if m["method"] not in ("fast", "tracking"):
                continue
            key = f"detect {m['method']:8s} {c['name']}"
            out[f"{key} median ms"] = m.get("median_ms")
            if c["catheter"]:
                v = m["volumes"]
                out[f"{key} found fraction"] = m["detected"] / v if v else None
                for fig in ("angle_deg", "tip_mm", "target_mm"):
                    q = m.get(fig) or {}
                    out[f"{key} {fig} median"] = q.get("median")
            else:
                out[f"{key} false detections"] = m.get("false_detections")
    return out


INGEST = re.compile(r"^loopback, slice-by-8.*?\|\s*([\d.]+) vol/s.*?latency ms p50 ([\d.]+) "
                    r"p99 ([\d.]+)")


def ingest_figures(path):
    for line in path.read_text().splitlines():
        m = INGEST.match(line)
        if m:
            return {"ingest vol/s": float(m.group(1)),
                    "ingest latency p50 ms": float(m.group(2)),
                    "ingest latency p99 ms": float(m.group(3))}
    return {}


def demo_figures(path):
    j = json.loads(path.read_text())
    t = j.get("timing") or {}
    out = {
        "demo tip-to-target RMS mm (EM)": j.get("tip_to_target_rms_mm"),
        "demo tip-to-target RMS mm (true)": j.get("true_tip_to_target_rms_mm"),
        "demo latency p50 ms": j["latency_ms"]["p50"],
        "demo latency p99 ms": j["latency_ms"]["p99"],
        "demo volumes tracked": j.get("volumes"),
        "demo missed acquisitions": j.get("missed_acquisitions"),
        "demo shed volumes (stale, tracker)": j.get("shed_volumes"),
        "demo dropped frames (missed + shed + not found)": j.get("dropped_frames"),
        "demo servo overruns": j.get("servo_overruns"),
    }
    for k, label in (("wakeup_latency_us", "wake-up"), ("cycle_duration_us", "cycle")):
        if isinstance(t.get(k), dict):
            out[f"demo servo {label} p99 us"] = t[k].get("p99")
    return out


def collect(runs, name, reps):
    per_rep = []
    for r in range(1, reps + 1):
        figs = {}
        for suffix, reader in ((".detect.json", detect_figures), (".ingest.txt", ingest_figures),
                               (".demo.json", demo_figures)):
            p = runs / f"{name}-{r}{suffix}"
            if p.exists():
                try:
                    figs.update(reader(p))
                except (ValueError, KeyError) as e:
                    print(f"perf_compare: {p}: unreadable ({e})", file=sys.stderr)
        per_rep.append(figs)
    keys = []
    for figs in per_rep:
        keys += [k for k in figs if k not in keys]
    return keys, {k: median([f.get(k) for f in per_rep]) for k in keys}


def fmt(x):
    if x is None:
        return "-"
    return f"{x:.3f}" if abs(x) < 100 else f"{x:.1f}"


def main():
    runs, reps = Path(sys.argv[1]), int(sys.argv[2])
    base_keys, base = collect(runs, "base", reps)
    head_keys, head = collect(runs, "head", reps)
    keys = base_keys + [k for k in head_keys if k not in base_keys]
    width = max(len(k) for k in keys) if keys else 10
    print(f"{'figure (median of ' + str(reps) + ' runs)':{width}s}  {'base':>9s}  {'head':>9s}  "
          f"{'head/base':>9s}")
    for k in keys:
        b, h = base.get(k), head.get(k)
        ratio = h / b if b not in (None, 0) and h is not None else None
        print(f"{k:{width}s}  {fmt(b):>9s}  {fmt(h):>9s}  {fmt(ratio):>9s}")


if __name__ == "__main__":
    main()
