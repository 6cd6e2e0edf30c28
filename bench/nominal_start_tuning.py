#!/usr/bin/env python3
"""The nominal start's effect on the tuning half (bench/results/calibrate_physical_tuning_nominal_start/).

Its records ran with min_a1_gap 0.04; the baseline is the same default without the start
(bench/results/calibrate_physical_tuning_nodes6_floors/, same cases and seeds). A case runs the
start when its first pass ends with |a1 - 2| above the gap, a function of the first pass alone
(identical in both runs), so for a larger gap G the outcome is exact: the new record's case where
the first pass ended beyond G, the baseline's elsewhere.

    python3 bench/nominal_start_tuning.py [GAP ...]
"""
import collections
import glob
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
NEW = os.path.join(HERE, "results/calibrate_physical_tuning_nominal_start")
BASE = os.path.join(HERE, "results/calibrate_physical_tuning_nodes6_floors")
TOL = {"dx": 0.05, "dy": 0.05, "theta_deg": 0.05, "a1": 0.005, "alpha_deg": 0.1, "blur_sigma_px": 0.05}
STRIDE = 2.0


def first_pass_a1(case):
    return next(s for s in case["stages"] if s["name"].startswith("scene fit ("))["parameters"]["a1"]


def main(gaps):
    pairs = []
    for path in sorted(glob.glob(os.path.join(NEW, "*.json"))):
        new = json.load(open(path))
        base = json.load(open(os.path.join(BASE, os.path.basename(path))))
        by_key = {(c["scene"], c["seed"], c["kind"]): c for c in base["cases"]}
        for c in new["cases"]:
            b = by_key[(c["scene"], c["seed"], c["kind"])]
            assert first_pass_a1(b) == first_pass_a1(c), "first passes differ"
            pairs.append((b, c))
    print("gap  kind       cases  ran  moved  all-six before -> after  within per parameter before -> after")
    for gap in [None] + gaps:
        for kind in ("random", "wide_blur"):
            n = ran = moved = 0
            before = collections.Counter()
            after = collections.Counter()
            worst = [0.0, 0.0]
            for b, c in pairs:
                if c["kind"] != kind:
                    continue
                n += 1
                runs = abs(first_pass_a1(c) - STRIDE) > (gap if gap is not None else 0.04)
                pick = c if runs else b
                ran += runs
                moved += pick["estimate"] != b["estimate"]
                worst[0] = max(worst[0], abs(b["error"]["a1"]))
                worst[1] = max(worst[1], abs(pick["error"]["a1"]))
                before["all"] += b["all_within_tolerance"]
                after["all"] += pick["all_within_tolerance"]
                for p, t in TOL.items():
                    before[p] += abs(b["error"][p]) <= t
                    after[p] += abs(pick["error"][p]) <= t
            per = "  ".join(f"{p} {before[p]}->{after[p]}" for p in TOL)
            label = "0.04" if gap is None else f"{gap:.2f}"
            print(f"{label}  {kind:10s} {n:5d} {ran:4d} {moved:6d}  {before['all']:3d} -> {after['all']:3d}  {per}"
                  f"  worst |a1 error| {worst[0]:.4f} -> {worst[1]:.4f}")


if __name__ == "__main__":
    main([float(g) for g in sys.argv[1:]] or [0.05, 0.07])
