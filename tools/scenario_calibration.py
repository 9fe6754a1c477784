#!/usr/bin/env python3
"""How honest the localizer's measurement sigmas are over a scenario suite run.

  python3 tools/scenario_calibration.py CACHE/runs [EPIPOLAR_FLOOR_M PNP_FLOOR_M]

For every run directory holding diagnostics.csv (localize --diagnostics) and errors.csv
(evaluate --errors), per frame: the epipolar measurement (epipolar_l_m, epipolar_sigma_m) and the
6-DoF one (pnp_s_m, pnp_sigma_m) against the truth's along-route s. Prints per measurement and
scenario the share within 2 sigma and, over the whole suite, the share within 2 sigma for other
floors F of each measurement (sigma^2 = model^2 + F^2, the model part being the reported sigma
without the floor FLOOR_M it was run with): how EvidenceOptions::floor_sigma_m and
pnp_floor_sigma_m are chosen, by the suite as a whole.
"""
import csv
import glob
import math
import os
import sys


def quantile(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    pos = q * (len(v) - 1)
    lo = int(math.floor(pos))
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (pos - lo)


def main():
    runs = sys.argv[1]
    floors = {"epipolar": float(sys.argv[2]) if len(sys.argv) > 2 else 0.10,
              "pnp": float(sys.argv[3]) if len(sys.argv) > 3 else 0.03}
    samples = {"epipolar": [], "pnp": []}
    print("| run | measurement | frames | within 2 sigma | median abs error [m] | max abs error [m] |")
    print("|---|---|---|---|---|---|")
    for run in sorted(glob.glob(os.path.join(runs, "*_run*"))):
        diag_path, err_path = os.path.join(run, "diagnostics.csv"), os.path.join(run, "errors.csv")
        if not (os.path.exists(diag_path) and os.path.exists(err_path)):
            continue
        truth = {}
        with open(err_path) as f:
            for r in csv.DictReader(f):
                if r["method"] == "online":
                    truth[r["frame"]] = float(r["truth_s_m"])
        frames = {}
        with open(diag_path) as f:
            for r in csv.DictReader(f):
                frames.setdefault(r["frame"], r)
        for name, value, sigma in (("epipolar", "epipolar_l_m", "epipolar_sigma_m"),
                                   ("pnp", "pnp_s_m", "pnp_sigma_m")):
            errors = []
            within = 0
            for frame, r in frames.items():
                if frame not in truth or not r.get(value) or not r.get(sigma):
                    continue
                e, s = float(r[value]) - truth[frame], float(r[sigma])
                errors.append(abs(e))
                within += abs(e) <= 2 * s
                samples[name].append((abs(e), math.sqrt(max(s * s - floors[name] ** 2, 0.0))))
            if errors:
                print(f"| {os.path.basename(run)} | {name} | {len(errors)} | "
                      f"{100.0 * within / len(errors):.1f} % | {quantile(errors, 0.5):.3f} | "
                      f"{max(errors):.3f} |")
    for name, values in samples.items():
        if not values:
            continue
        shares = []
        for floor in (0.03, 0.05, 0.08, 0.10, 0.15, 0.20):
            within = sum(1 for e, model in values if e <= 2 * math.hypot(model, floor))
            shares.append(f"{floor:.2f} m: {100.0 * within / len(values):.1f} %")
        print(f"{name}: {len(values)} measurements; within 2 sigma with a floor of " +
              ", ".join(shares))


if __name__ == "__main__":
    main()
