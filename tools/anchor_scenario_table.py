#!/usr/bin/env python3
"""The anchoring suite's table (tools/bench_anchor_scenarios.sh): one row per scenario with the
worst of its runs, then the suite's worst figures, each against issue 17's targets.

Input: a TSV of runs (scenario, run, anchors CSV of `epiloc anchor`, evaluation JSON of `epiloc
evaluate --json` of it, wall milliseconds), and the number of runs per scenario.

Per run: "ok" the anchors called ok of those attempted (the CSV's rows); horizontal median / max
and rotation max over the ok anchors (evaluate); "along bias" their mean signed along-track error
(the structure's shared error: positive ahead); "s/anchor" the anchors' own time (the CSV's
`seconds`, the map bundle's share included; the VO and the synthetic world not counted) and the
wall time per anchor. A row takes each figure's worst run. Targets: synthetic rows 90 % ok,
horizontal max 0.05 m, rotation max 0.1 deg; KITTI rows 90 % ok, median 0.2 m, max 0.5 m,
rotation 0.5 deg; every row 2 s per anchor. A figure beyond its target is marked with '!'.
"""
import csv
import json
import math
import sys
from collections import OrderedDict


def anchor_method(summary):
    for m in summary["methods"]:
        if m["method"] == "anchor":
            return m
    return None


def run_figures(anchors_path, summary_path, wall_ms):
    with open(anchors_path) as f:
        rows = list(csv.DictReader(f))
    with open(summary_path) as f:
        m = anchor_method(json.load(f))
    seconds = [float(r["seconds"]) for r in rows if r.get("seconds")]
    out = dict(rows=len(rows), ok=0, h_median=math.nan, h_max=math.nan, rot_max=math.nan,
               along_bias=math.nan, s_per_anchor=sum(seconds) / max(len(seconds), 1),
               wall_per_anchor=wall_ms / 1000.0 / max(len(rows), 1))
    if m is not None and m["counts"]["evaluated"] > 0:
        out.update(ok=m["counts"]["ok"], h_median=m["horizontal_m"]["median_abs"],
                   h_max=m["horizontal_m"]["max"], rot_max=m["rotation_deg"]["max"],
                   along_bias=m["along_track_m"]["bias"])
    out["share"] = out["ok"] / out["rows"] if out["rows"] else 0.0
    return out


def worst(values, key=max):
    finite = [v for v in values if not math.isnan(v)]
    return key(finite) if finite else math.nan


def targets(name):
    if name.startswith("kitti"):
        return dict(share=0.9, h_median=0.2, h_max=0.5, rot_max=0.5, s_per_anchor=2.0)
    return dict(share=0.9, h_max=0.05, rot_max=0.1, s_per_anchor=2.0)


def cell(value, fmt, target=None, at_least=False):
    if math.isnan(value):
        return "-"
    text = fmt.format(value)
    if target is not None and (value < target if at_least else value > target):
        text += "!"
    return text


def main():
    path, expected_runs = sys.argv[1], int(sys.argv[2])
    scenarios = OrderedDict()
    with open(path) as f:
        for line in f:
            name, run, anchors, summary, wall_ms = line.rstrip("\n").split("\t")
            scenarios.setdefault(name, []).append(run_figures(anchors, summary, float(wall_ms)))
    header = ("| scenario | runs | ok (worst) | horizontal median | horizontal max | "
              "rotation max | along bias | s/anchor (wall) |")
    print(header)
    print("|" + "---|" * 8)
    suite = dict(share=[], h_median=[], h_max=[], rot_max=[], s_per_anchor=[])
    misses = []
    for name, runs in scenarios.items():
        t = targets(name)
        share = min(r["share"] for r in runs)
        worst_share = min(runs, key=lambda r: r["share"])
        h_median = worst([r["h_median"] for r in runs])
        h_max = worst([r["h_max"] for r in runs])
        rot_max = worst([r["rot_max"] for r in runs])
        bias = worst([r["along_bias"] for r in runs], key=lambda v: max(v, key=abs))
        s = worst([r["s_per_anchor"] for r in runs])
        wall = worst([r["wall_per_anchor"] for r in runs])
        runs_text = str(len(runs)) + ("" if len(runs) == expected_runs else " (incomplete)")
        print(f"| {name} | {runs_text} | "
              f"{worst_share['ok']} of {worst_share['rows']} "
              f"{cell(100 * share, '({:.0f} %)', 100 * t['share'], at_least=True)} | "
              f"{cell(h_median, '{:.3f} m', t.get('h_median'))} | "
              f"{cell(h_max, '{:.3f} m', t['h_max'])} | "
              f"{cell(rot_max, '{:.3f} deg', t['rot_max'])} | {cell(bias, '{:+.3f} m')} | "
              f"{cell(s, '{:.2f}', t['s_per_anchor'])} ({wall:.2f}) |")
        for key, value, target, low in (("ok share", share, t["share"], True),
                                        ("horizontal median", h_median, t.get("h_median"), False),
                                        ("horizontal max", h_max, t["h_max"], False),
                                        ("rotation max", rot_max, t["rot_max"], False),
                                        ("s/anchor", s, t["s_per_anchor"], False)):
            if target is None or math.isnan(value):
                continue
            if (value < target) if low else (value > target):
                misses.append(f"{name}: {key} {value:.3f} (target {target})")
        suite["share"].append(share)
        for key, value in (("h_median", h_median), ("h_max", h_max), ("rot_max", rot_max),
                           ("s_per_anchor", s)):
            suite[key].append(value)
    print()
    # Without an ok anchor in any run there is no error to report: "-", as in the table.
    print(f"suite worst: ok share {100 * worst(suite['share'], min):.0f} %, horizontal median "
          f"{cell(worst(suite['h_median']), '{:.3f} m')}, "
          f"max {cell(worst(suite['h_max']), '{:.3f} m')}, "
          f"rotation max {cell(worst(suite['rot_max']), '{:.3f} deg')}, "
          f"{cell(worst(suite['s_per_anchor']), '{:.2f}')} s per anchor")
    print("beyond target: " + ("none" if not misses else "; ".join(misses)))


if __name__ == "__main__":
    main()
