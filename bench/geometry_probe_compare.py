#!/usr/bin/env python3
"""A probe's calibration record against a base record, case by case (same scene, seed and kind):
each case's dx, a1, dy, α and σ errors before → after and its all-six verdict; then per parameter
the cases within tolerance, the geometry (all but σ) and all six within, and the RMSE and mean
error of dx, a1, dy and α. Usage: bench/geometry_probe_compare.py BASE.json PROBE.json"""
import json
import math
import sys

GEOMETRY = ["dx", "dy", "theta_deg", "a1", "alpha_deg"]


def main(base_path, probe_path):
    base = json.load(open(base_path))
    probe = json.load(open(probe_path))
    tol = base["tolerances"]
    by_key = {(c["scene"], c["seed"], c["kind"]): c for c in base["cases"]}
    pairs = [(by_key[k], c) for c in probe["cases"]
             if (k := (c["scene"], c["seed"], c["kind"])) in by_key]
    within = lambda c, ps: all(abs(c["error"][p]) <= tol[p] for p in ps)
    for b, c in pairs:
        e = lambda case, p: case["error"][p]
        print(f"{c['scene'][:28]:28s} {c['seed']:6d} {c['kind']:7s} "
              f"dx {e(b, 'dx'):+.3f}→{e(c, 'dx'):+.3f}  a1 {e(b, 'a1'):+.4f}→{e(c, 'a1'):+.4f}  "
              f"dy {e(b, 'dy'):+.3f}→{e(c, 'dy'):+.3f}  α {e(b, 'alpha_deg'):+.3f}→{e(c, 'alpha_deg'):+.3f}  "
              f"σ {e(b, 'blur_sigma_px'):+.3f}→{e(c, 'blur_sigma_px'):+.3f}  "
              f"all six {int(b['all_within_tolerance'])}→{int(c['all_within_tolerance'])}")
    n = len(pairs)
    counts = ", ".join(f"{p} {sum(within(b, [p]) for b, _ in pairs)}→{sum(within(c, [p]) for _, c in pairs)}"
                       for p in tol)
    print(f"{n} cases; within tolerance base → probe: {counts}; "
          f"geometry {sum(within(b, GEOMETRY) for b, _ in pairs)}→{sum(within(c, GEOMETRY) for _, c in pairs)}; "
          f"all six {sum(b['all_within_tolerance'] for b, _ in pairs)}→{sum(c['all_within_tolerance'] for _, c in pairs)}")
    for p in ["dx", "a1", "dy", "alpha_deg"]:
        eb = [b["error"][p] for b, _ in pairs]
        ep = [c["error"][p] for _, c in pairs]
        rmse = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
        print(f"{p} RMSE {rmse(eb):.4f}→{rmse(ep):.4f}, mean {sum(eb) / n:+.4f}→{sum(ep) / n:+.4f}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
