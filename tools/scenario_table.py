#!/usr/bin/env python3
"""The scenario suite's table (tools/bench_scenarios.sh): one row per scenario with the worst of
its runs, then the suite's worst figures.

Input: a TSV of runs (scenario, run, frames, frames/s, max RSS kB, evaluation JSON of
`epiloc evaluate --json`), and the number of runs per scenario.
"localized" is "K of N" where the query leaves the surveyed route: K frames localized (status ok)
of the N whose ground truth is on the route (evaluate's truth_on_route); the worst run's share.
"""
import json
import sys
from collections import OrderedDict


def method(summary, name):
    """The evaluation of a method ({} when the result has no rows of it)."""
    for m in summary["methods"]:
        if m["method"] == name:
            return m
    return {}


def along(summary, name):
    """A method's evaluation when it has evaluated rows, else None."""
    m = method(summary, name)
    if not m or m["counts"]["evaluated"] == 0:
        return None
    return m


def main():
    path, expected_runs = sys.argv[1], int(sys.argv[2])
    scenarios = OrderedDict()
    with open(path) as f:
        for line in f:
            name, run, frames, fps, rss_kb, summary_path = line.rstrip("\n").split("\t")
            with open(summary_path) as s:
                summary = json.load(s)
            scenarios.setdefault(name, []).append(
                dict(run=int(run), frames=int(frames), fps=float(fps), mb=int(rss_kb) / 1024.0,
                     summary=summary))
    header = ("| scenario | frames | localized | lost | online mean | online max | pnp mean | "
              "pnp max | within 0.5 m | frames/s | peak MB | within 2 sigma | pnp horizontal within 2 sigma |")
    print(header)
    print("|" + "---|" * 13)
    worst = dict(online=(-1.0, ""), pnp=(-1.0, ""), fps=(float("inf"), ""))
    for name, rs in scenarios.items():
        frames = max(r["frames"] for r in rs)
        localized = lost = None
        online_mean = online_max = pnp_mean = pnp_max = None
        within = None
        calibration = None  # worst share of frames within 2 sigma, online and pnp along-track
        horizontal = None  # worst share of pnp frames within 2 sigma_horizontal_m
        for r in rs:
            for name_m in ("online", "pnp"):
                c = method(r["summary"], name_m).get("calibration", {})
                if c.get("along_frames_with_sigma", 0) > 0:
                    share = c["along_within_2_sigma"]
                    calibration = share if calibration is None else min(calibration, share)
                if name_m == "pnp" and c.get("horizontal_frames_with_sigma", 0) > 0:
                    share = c["horizontal_within_2_sigma"]
                    horizontal = share if horizontal is None else min(horizontal, share)
            online = along(r["summary"], "online")
            counts = method(r["summary"], "online").get("counts", {})
            ok = counts.get("ok", 0)
            # Localized among the frames whose truth is on the surveyed route (evaluate's
            # truth_on_route); off it, lost / off_route is the right answer.
            if "truth_on_route" in counts:
                share = (counts["ok_on_route"], counts["truth_on_route"])
            else:
                share = (ok, r["frames"])
            if localized is None or share[0] * localized[1] < localized[0] * share[1]:
                localized = share
            lost = r["frames"] - ok if lost is None else max(lost, r["frames"] - ok)
            if online:
                a = online["along_track_m"]
                mx = max(-a["min"], a["max"])
                online_mean = a["mean_abs"] if online_mean is None else max(online_mean, a["mean_abs"])
                online_max = mx if online_max is None else max(online_max, mx)
                share = a["share_within"]["0.5"]
                within = share if within is None else min(within, share)
            pnp = along(r["summary"], "pnp")
            if pnp:
                a = pnp["along_track_m"]
                mx = max(-a["min"], a["max"])
                pnp_mean = a["mean_abs"] if pnp_mean is None else max(pnp_mean, a["mean_abs"])
                pnp_max = mx if pnp_max is None else max(pnp_max, mx)
        fps = min(r["fps"] for r in rs)
        mb = max(r["mb"] for r in rs)
        if online_max is not None and online_max > worst["online"][0]:
            worst["online"] = (online_max, name)
        if pnp_max is not None and pnp_max > worst["pnp"][0]:
            worst["pnp"] = (pnp_max, name)
        if fps < worst["fps"][0]:
            worst["fps"] = (fps, name)

        def m(v):
            return "-" if v is None else f"{v:.3f}"

        runs_note = "" if len(rs) == expected_runs else f" ({len(rs)} runs)"
        localized_cell = "-" if localized is None else (
            f"{localized[0]}" if localized[1] == frames else f"{localized[0]} of {localized[1]}")
        print(f"| {name}{runs_note} | {frames} | {localized_cell} | {lost} | {m(online_mean)} | "
              f"{m(online_max)} | {m(pnp_mean)} | {m(pnp_max)} | "
              f"{'-' if within is None else f'{100 * within:.1f} %'} | {fps:.1f} | {mb:.0f} | "
              f"{'-' if calibration is None else f'{100 * calibration:.1f} %'} | "
              f"{'-' if horizontal is None else f'{100 * horizontal:.1f} %'} |")
    print(f"worst: online max {worst['online'][0]:.3f} m ({worst['online'][1]}), "
          f"pnp max {worst['pnp'][0]:.3f} m ({worst['pnp'][1]}), "
          f"slowest {worst['fps'][0]:.1f} frames/s ({worst['fps'][1]})")


if __name__ == "__main__":
    main()
