#!/usr/bin/env python3
"""Several snapshots of one instrument: their combination against their joint fit.

Reads calibration-bench records made with `--snapshots N --joint` and
prints, per kind (pooled over the records), for the combination (the
median of the snapshots' answers, `calib::combine_snapshots`), the joint
fit's detail pass and the joint fit (`calib::joint_scene_fit`, from the
combination): how many instruments are within the issue's tolerances on
all six and on each parameter, the RMSE per parameter, and how often the
combination's stated 1σ and 95 % bars cover each answer's error. Then
every instrument where the two answers differ in being within tolerance.

Usage: python3 bench/joint_fit_table.py RECORD.json [RECORD.json ...]
"""
import json
import math
import sys
from collections import defaultdict

PARAMS = ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"]
NAMES = ["dx", "dy", "θ", "a1", "α", "σ"]
TOL = {"dx": 0.05, "dy": 0.05, "theta_deg": 0.05, "a1": 0.005, "alpha_deg": 0.1, "blur_sigma_px": 0.05}


def answers(g):
    """Each answer's errors: the combination's, the joint detail pass's, the joint fit's."""
    joint = g.get("joint")
    if joint is None:
        raise SystemExit(f"instrument {g['instrument_seed']}: no joint fit (a record made without --joint)")
    return {"combined": g["error"], "joint detail": joint["detail_pass"]["error"], "joint": joint["error"]}


def within(err):
    return all(abs(err[p]) <= TOL[p] for p in PARAMS)


def main(paths):
    if not paths:
        raise SystemExit(__doc__)
    by_kind = defaultdict(list)
    for path in paths:
        with open(path) as f:
            record = json.load(f)
        groups = (record.get("snapshots") or {}).get("instruments")
        if not groups:
            raise SystemExit(f"{path}: no snapshots block (a record made without --snapshots)")
        for g in groups:
            by_kind[g["kind"]].append((path, g))
    for kind, rows in sorted(by_kind.items()):
        n = len(rows)
        print(f"\n{kind}: {n} instruments")
        print(f"{'answer':<14} {'all six':>8}  " + "  ".join(f"{m:>11}" for m in NAMES) + "   (within; RMSE)")
        for name in ["combined", "joint detail", "joint"]:
            errs = [answers(g)[name] for _, g in rows]
            all_six = sum(within(e) for e in errs)
            cells = []
            for p in PARAMS:
                hits = sum(abs(e[p]) <= TOL[p] for e in errs)
                rmse = math.sqrt(sum(e[p] ** 2 for e in errs) / n)
                cells.append(f"{hits:>2} {rmse:8.4f}")
            print(f"{name:<14} {all_six:>3} of {n:<2}  " + "  ".join(cells))
        for name in ["combined", "joint"]:
            for bar, label in [("uncertainty", "1σ"), ("interval_95", "95 %")]:
                cov = []
                for i, p in enumerate(PARAMS):
                    stated = [(answers(g)[name][p], g[bar][p]) for _, g in rows if g[bar][p] is not None]
                    cov.append(f"{NAMES[i]} {sum(abs(e) <= s for e, s in stated)}/{len(stated)}")
                print(f"  the combination's {label:>4} bar covers the {name:<8} answer: " + ", ".join(cov))
        for path, g in rows:
            a = answers(g)
            if within(a["combined"]) != within(a["joint"]):
                print(f"  {path.split('/')[-1]} instrument {g['instrument_seed']}: combined {verdict(a['combined'])}, joint {verdict(a['joint'])}")


def verdict(err):
    if within(err):
        return "within"
    worst = max(PARAMS, key=lambda p: abs(err[p]) / TOL[p])
    return f"misses ({worst} {err[worst]:+.4f})"


if __name__ == "__main__":
    main(sys.argv[1:])
