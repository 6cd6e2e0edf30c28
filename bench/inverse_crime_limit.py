#!/usr/bin/env python3
"""The blind fit without model error beside the physical instrument: paired counts.

    python3 bench/inverse_crime_limit.py RECORD.json [RECORD.json …]

Each record is `calibrate`'s JSON made with its inverse-crime row on (the default; e.g.
`--seed-round R --cases 4 --no-aligned --no-recon --no-limits --no-wide-blur`): every random pose
calibrated twice, from the 4x-oversampled physical instrument (`random`) and from its sharp ψ
through the calibrated model's own operator (`inverse_crime`: no model error, the scene still
blind). Prints, pooled over the records, per kind: all six within the issue's tolerances, the
geometry (all but σ: the inverse-crime truth is sharp, σ = 0, while the physical one is blurred),
each parameter within, RMSE and mean error, dx's slope on a1's error (the dx–a1 ridge), then the
pairs by geometry verdict. The point: if the inverse-crime row reads no better than the physical
one, what is left is the blind scene's, not the model's.
"""
import json
import sys

import numpy as np

GEOMETRY = ["dx", "dy", "theta_deg", "a1", "alpha_deg"]
PARAMS = GEOMETRY + ["blur_sigma_px"]


def within(case, tolerances, params):
    return all(abs(case["error"][p]) <= tolerances[p] for p in params)


def summary(name, cases, tolerances):
    n = len(cases)
    errors = np.array([[c["error"][p] for p in PARAMS] for c in cases])
    print(
        f"{name} ({n}): all six {sum(within(c, tolerances, PARAMS) for c in cases)}, "
        f"geometry {sum(within(c, tolerances, GEOMETRY) for c in cases)}"
    )
    print(
        "  within "
        + ", ".join(f"{p} {sum(abs(c['error'][p]) <= tolerances[p] for c in cases)}" for p in PARAMS)
    )
    rmse = np.sqrt((errors**2).mean(axis=0))
    print("  RMSE " + ", ".join(f"{p} {v:.4f}" for p, v in zip(PARAMS, rmse)))
    print("  mean error " + ", ".join(f"{p} {v:+.4f}" for p, v in zip(PARAMS, errors.mean(axis=0))))
    dx, a1 = errors[:, 0], errors[:, 3]
    slope, offset = np.polyfit(a1, dx, 1)
    rest = dx - (slope * a1 + offset)
    print(
        f"  dx = {slope:.1f} x a1's error {offset:+.4f} px (correlation "
        f"{np.corrcoef(dx, a1)[0, 1]:.2f}; what a1 leaves of dx: {np.sqrt((rest**2).mean()):.4f} px RMS)"
    )


def main(paths):
    pairs, tolerances = {}, None
    for path in paths:
        record = json.load(open(path))
        tolerances = record["tolerances"]
        for c in record["cases"]:
            if c["kind"] in ("random", "inverse_crime"):
                pairs.setdefault((path, c["scene"], c["seed"]), {})[c["kind"]] = c
    complete = [p for p in pairs.values() if len(p) == 2]
    if not complete:
        sys.exit("no random pose with its inverse-crime row in these records")
    for kind in ("random", "inverse_crime"):
        summary(kind, [p[kind] for p in complete], tolerances)
    table = {}
    for p in complete:
        verdict = tuple(within(p[k], tolerances, GEOMETRY) for k in ("random", "inverse_crime"))
        table[verdict] = table.get(verdict, 0) + 1
    print("geometry within, physical / inverse crime (pairs):")
    for verdict, label in [
        ((True, True), "both"),
        ((False, True), "inverse crime only"),
        ((True, False), "physical only"),
        ((False, False), "neither"),
    ]:
        print(f"  {label}: {table.get(verdict, 0)}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
