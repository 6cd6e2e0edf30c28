#!/usr/bin/env python3
"""A probe's calibration record against a base record of the same cases, case by case: each case's
dx, a1, dy, α and σ errors before → after and its all-six verdict; then, for each side, what
`bench/held_out_pool.py --per-parameter` prints (all six within, per parameter within, the
geometry within, RMSE, mean error). For the three-round tuning judgement use
`bench/tuning_compare.py`; this is one record against one.

    python3 bench/geometry_probe_compare.py BASE.json PROBE.json
"""
import sys

from held_out_pool import cases, per_parameter, summary


def main(base_path, probe_path):
    base = cases(base_path)
    probe = {k: c for k, c in cases(probe_path).items() if k in base}
    for key, c in probe.items():
        b = base[key]
        pairs = "  ".join(f"{label} {b['error'][p]:+.{digits}f}→{c['error'][p]:+.{digits}f}"
                          for label, p, digits in [("dx", "dx", 3), ("a1", "a1", 4), ("dy", "dy", 3),
                                                   ("α", "alpha_deg", 3), ("σ", "blur_sigma_px", 3)])
        print(f"{c['scene'][:28]:28s} {c['seed']:6d} {c['kind']:12s} {pairs}  "
              f"all six {int(b['all_within_tolerance'])}→{int(c['all_within_tolerance'])}")
    shared = {k: base[k] for k in probe}
    for side, pool in (("base", shared), ("probe", probe)):
        print(f"{side}: {summary(pool, coverage=False)}")
        print(per_parameter(pool))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
