#!/usr/bin/env python3
"""Would the blind objective choose how much to sharpen a captured mask file? (stop 44 probe)

Reads calibration-bench records of the same cases run with `--mask-capture S --limits` and
different `--mask-sharpen V` (a record without the flag is V = 0), and compares the geometry
(dx, dy, θ, a1, α) of each fixed V with the V each case's scene-fit objective at its own answer
prefers (`limits.scene_objective.at_estimate`: the first pass's objective, the coarse scene
solved cold, on the same measurement — comparable across handed files).

    python3 bench/mask_sharpen_choice.py RECORD@V [RECORD@V …]
"""
import json
import math
import sys

GEOMETRY = ["dx", "dy", "theta_deg", "a1", "alpha_deg"]


def load(arg):
    path, v = arg.rsplit("@", 1)
    record = json.load(open(path))
    cases = {(c["scene"], c["seed"]): c for c in record["cases"] if c["kind"] == "random"}
    return float(v), record["tolerances"], cases


def within(case, tol):
    return all(abs(case["error"][p]) <= tol[p] for p in GEOMETRY)


def summary(label, chosen, tol):
    rms = {p: math.sqrt(sum(c["error"][p] ** 2 for c in chosen) / len(chosen)) for p in GEOMETRY}
    print(f"  {label:<26} geometry within {sum(within(c, tol) for c in chosen):>2} of {len(chosen)}; RMSE "
          + "  ".join(f"{p} {rms[p]:.4f}" for p in GEOMETRY))


def main(args):
    if not args:
        sys.exit(__doc__)
    runs = sorted(load(a) for a in args)
    tol = runs[0][1]
    keys = sorted(set.intersection(*(set(cases) for _, _, cases in runs)))
    print(f"{len(keys)} random cases in all {len(runs)} records")
    for v, _, cases in runs:
        summary(f"V = {v:g}", [cases[k] for k in keys], tol)
    picks = []
    for k in keys:
        scored = [(cases[k]["limits"]["scene_objective"]["at_estimate"], v, cases[k]) for v, _, cases in runs]
        picks.append(min(scored, key=lambda t: t[0]))
    summary("V the objective prefers", [c for _, _, c in picks], tol)
    for (score, v, c) in picks:
        sigma_o = c.get("instrument_blur_sigma_px")
        print(f"    {c['scene']:<32} seed {c['seed']}  σ_o {sigma_o:.2f}  chose V {v:g}  geometry "
              f"{'within' if within(c, tol) else 'out'}")


if __name__ == "__main__":
    main(sys.argv[1:])
