#!/usr/bin/env python3
"""Which parameters the held-out random poses miss, over calibration records: each pattern of
parameters outside the record's tolerances and how many random poses show it, and σ within its
tolerance by the instrument's true σ (below and from 0.25 px). A case in a later file replaces
the same (scene, seed, kind) in an earlier one, as bench/held_out_pool.py pools them.

    python3 bench/held_out_misses.py RECORD.json [RECORD.json ...]
"""
import collections
import sys

from held_out_pool import cases as record_cases


def main(paths):
    cases = {}
    for path in paths:
        cases.update({k: c for k, c in record_cases(path).items() if c["kind"] == "random"})
    tolerances = next(iter(cases.values()))["tolerances"]
    patterns = collections.Counter()
    by_sigma = {"below 0.25 px": [0, 0], "from 0.25 px": [0, 0]}
    for c in cases.values():
        missed = tuple(p for p in tolerances if abs(c["error"][p]) > tolerances[p])
        patterns[missed] += 1
        regime = "below 0.25 px" if c["instrument_blur_sigma_px"] < 0.25 else "from 0.25 px"
        by_sigma[regime][0] += abs(c["error"]["blur_sigma_px"]) <= tolerances["blur_sigma_px"]
        by_sigma[regime][1] += 1
    print(f"{len(cases)} random poses; parameters missed (none: all six within):")
    for missed, n in patterns.most_common():
        print(f"  {n:4d}  {', '.join(missed) or 'none'}")
    for regime, (within, n) in by_sigma.items():
        print(f"σ within its tolerance, true σ {regime}: {within} of {n}")


if __name__ == "__main__":
    main(sys.argv[1:])
