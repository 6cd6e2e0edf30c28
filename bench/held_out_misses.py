#!/usr/bin/env python3
"""Which parameters the held-out random poses miss, over calibration records: each pattern of
parameters outside the record's tolerances and how many random poses show it, and σ within its
tolerance by the instrument's true σ (below and from 0.25 px), and the poses whose σ reads below
0.03 px: the true σ behind them and how often the 95 % interval as printed since stop 73 (from 0 to
σ̂ + its half-width, where it reaches below 0) holds it. A case in a later file replaces
the same (scene, seed, kind) in an earlier one, as bench/held_out_pool.py pools them.

    python3 bench/held_out_misses.py RECORD.json [RECORD.json ...]
"""
import collections
import sys

from held_out_pool import cases as record_cases

# σ this low reads as "not resolved from 0": held out, such reads came from true σ up to 0.25 px
LOW_READ_PX = 0.03


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
    low = [c for c in cases.values() if c["estimate"]["blur_sigma_px"] < LOW_READ_PX]
    if low:
        truths = sorted(c["truth"]["blur_sigma_px"] for c in low)
        held = sum(
            c["truth"]["blur_sigma_px"] <= c["estimate"]["blur_sigma_px"] + c["interval_95"]["blur_sigma_px"]
            for c in low
        )
        quintiles = ", ".join(f"{truths[min(len(truths) - 1, len(truths) * q // 10)]:.3f}" for q in range(0, 11, 2))
        print(f"σ read below {LOW_READ_PX} px: {len(low)} poses, true σ {truths[0]:.3f} … {truths[-1]:.3f} "
              f"(quintiles {quintiles}), within its tolerance in "
              f"{sum(abs(c['error']['blur_sigma_px']) <= tolerances['blur_sigma_px'] for c in low)}; "
              f"the 95 % interval from 0 holds the truth in {held}")


if __name__ == "__main__":
    main(sys.argv[1:])
