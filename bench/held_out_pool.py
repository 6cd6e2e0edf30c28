#!/usr/bin/env python3
"""Pooled figures over held-out calibration records (bench/results/calibrate_physical_held_out*.json).

Each case is keyed by (scene, seed, kind); a case in a later file replaces the same case in an
earlier one (a re-run of part of a round). Only the physical rows are pooled (random poses and
aligned-with-blur); the wide-blur and inverse-crime rows are left out. Prints, per file and pooled:
cases, all six parameters within the issue's tolerances (random / aligned), and the share of cases
whose |error| is within the stated standard error and within the stated 95 % half-width.
With --before-blur-pass, a case run with the blur pass counts with the answer of the stage
before it (the pass changes σ alone and states no new errors): the default's answer before stop
41, which made the pass the default's last stage (`--no-blur-pass` runs the default without it).

With --per-parameter, the pool's figures per kind follow: each parameter's count within its
tolerance, RMSE and mean error, the geometry (all but σ) within, and the worst case (largest error over its
tolerance) — the README's table is these.

    python3 bench/held_out_pool.py RECORD.json [RECORD.json ...] [--no-coverage] [--before-blur-pass] [--per-parameter]
"""
import json
import math
import os
import sys

PARAMS = ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"]
KINDS = ("random", "aligned_blur")


BLUR_PASS_STAGE = "blur pass"  # the start of the pass's stage name (calib::BLUR_PASS_STAGE)


def before_blur_pass(case, tolerances):
    """The case as the default before stop 41 answered it: the stage before the blur pass."""
    names = [s["name"] for s in case["stages"]]
    passes = [i for i, n in enumerate(names) if n.startswith(BLUR_PASS_STAGE)]
    if not passes:
        return case
    answer = case["stages"][passes[0] - 1]["parameters"]
    error = {p: answer[p] - case["truth"][p] for p in PARAMS}
    return dict(case, error=error,
                all_within_tolerance=all(abs(error[p]) <= tolerances[p] for p in PARAMS))


def cases(path, default_answer=False):
    record = json.load(open(path))
    out = {}
    for c in record["cases"]:
        if c["kind"] in KINDS:
            case = before_blur_pass(c, record["tolerances"]) if default_answer else c
            out[(c["scene"], c["seed"], c["kind"])] = dict(case, tolerances=record["tolerances"])
    return out


def per_parameter(pool):
    """Per kind: each parameter within tolerance, its RMSE and mean error, the geometry within, the worst case."""
    lines = []
    for kind in KINDS:
        group = [c for c in pool.values() if c["kind"] == kind]
        if not group:
            continue
        n = len(group)
        within = lambda c, p: abs(c["error"][p]) <= c["tolerances"][p]
        lines.append(f"  {kind} ({n}): within " + ", ".join(
            f"{p} {sum(within(c, p) for c in group)}" for p in PARAMS)
            + f"; geometry (all but σ) {sum(all(within(c, p) for p in PARAMS[:5]) for c in group)}")
        lines.append("    RMSE " + ", ".join(
            f"{p} {math.sqrt(sum(c['error'][p] ** 2 for c in group) / n):.4f}" for p in PARAMS))
        lines.append("    mean error " + ", ".join(
            f"{p} {sum(c['error'][p] for c in group) / n:+.4f}" for p in PARAMS))
        worst = max(group, key=lambda c: max(abs(c["error"][p]) / c["tolerances"][p] for p in PARAMS))
        lines.append(f"    worst {worst['scene']} seed {worst['seed']}: " + ", ".join(
            f"{p} {worst['error'][p]:+.3f}" for p in PARAMS))
    return "\n".join(lines)


def summary(pool, coverage):
    n = len(pool)
    within = {k: [0, 0] for k in KINDS}
    one = {p: 0 for p in PARAMS}
    ninety_five = {p: 0 for p in PARAMS}
    for c in pool.values():
        within[c["kind"]][0] += c["all_within_tolerance"]
        within[c["kind"]][1] += 1
        for p in PARAMS:
            e = abs(c["error"][p])
            one[p] += e <= c["uncertainty"][p]
            ninety_five[p] += e <= c["interval_95"][p]
    total = sum(w[0] for w in within.values())
    line = f"{n} cases: all six {total} (random {within['random'][0]}/{within['random'][1]}, aligned {within['aligned_blur'][0]}/{within['aligned_blur'][1]})"
    if coverage:
        line += "; 1σ " + ", ".join(f"{p} {round(100 * one[p] / n)}" for p in PARAMS)
        line += " %; 95 % " + ", ".join(f"{p} {round(100 * ninety_five[p] / n)}" for p in PARAMS) + " %"
    return line


def main(args):
    coverage = "--no-coverage" not in args
    default_answer = "--before-blur-pass" in args
    flags = ("--no-coverage", "--before-blur-pass", "--per-parameter")
    paths = [a for a in args if a not in flags]
    pool = {}
    for path in paths:
        own = cases(path, default_answer)
        print(f"{os.path.basename(path)}: {summary(own, coverage)}")
        pool.update(own)
    print(f"pooled: {summary(pool, coverage)}")
    if "--per-parameter" in args:
        print(per_parameter(pool))


if __name__ == "__main__":
    main(sys.argv[1:])
