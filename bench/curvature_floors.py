#!/usr/bin/env python3
"""The fitted curvature a2's error floors, and their coverage, from calibration records.

    python3 bench/curvature_floors.py TUNING.json [MORE.json …] [--confidence C]
        [--floors F F95] [--check RUN.json …]

Each record: `cargo run --release -p cassi-bench --bin calibrate -- … --fine-pass 0.01
--fine-pass-free geometry-and-curvature` (the fine pass fitting a2), on any instrument
(`--dispersion-a2 A2`: its curvature, the truth a2 is scored against; `--model-a2 A2`: the
value the fit starts from). The bench records a fitted a2 in each case's `curvature`
(estimate, the instrument's a2, their difference, the stated errors): ψ's own truth
carries no a2, the curvature is the instrument's. The stated a2 error is hypot(s, F) with s the fine pass's block sandwich
(`calib/uncertainty.rs`: `two_pass_uncertainty`) and F the floor; one floor for all blurs
(no wide-blur rows were run). The floors are the smallest that cover the target in each
record (a regime: a straight or a curved instrument, a start at the truth or off it) and,
over all cases, at the one-sided Clopper–Pearson margin (`uncertainty_floors.py`, the same
rule the other parameters' floors follow): 68 % within hypot(s, F), 95 % within
hypot(2s, F95). Copied into `uncertainty.rs` by hand, rounded up. --check: coverage of
the stated a2 errors on other runs — held-out records, never used to choose — as recorded,
or with --floors F F95 as those floors state them (for records made before the floors: the
recorded floor taken out of the sandwich part, these put in).
"""

import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from uncertainty_floors import covers, smallest  # noqa: E402

LEVELS = {"standard error": (1.0, 0.68), "95 % half-width": (2.0, 0.95)}


def sandwich(k):
    """The sandwich part of a case's stated a2 error: its floor taken out."""
    return math.sqrt(max(k["uncertainty"] ** 2 - (k.get("uncertainty_floor") or 0.0) ** 2, 0.0))


def rows(path):
    """(|a2 error|, sandwich part, blur, regime, scene) per case that states a2."""
    run = json.load(open(path))
    truth = run["instrument"].get("dispersion_a2") or 0.0
    flags = run["flags"]
    start = next((flags[i + 1] for i, f in enumerate(flags) if f == "--model-a2"), "0")
    regime = f"instrument a2 {truth:+g}, start {start}"
    out = []
    for c in run["cases"]:
        k = c.get("curvature")
        if not k:
            continue
        out.append((abs(k["error"]), sandwich(k), 0.0, regime, c["scene"]))
    return out


def main():
    args = sys.argv[1:]
    confidence = 0.8
    if "--confidence" in args:
        i = args.index("--confidence")
        confidence = float(args[i + 1])
        del args[i : i + 2]
    floors = None
    if "--floors" in args:
        i = args.index("--floors")
        floors = (float(args[i + 1]), float(args[i + 2]))
        del args[i : i + 3]
    checks = []
    if "--check" in args:
        i = args.index("--check")
        checks = args[i + 1 :]
        args = args[:i]
    tuning = [r for p in args for r in rows(p)]
    if tuning:
        print(f"{len(tuning)} tuning cases")
        for regime in sorted({r[3] for r in tuning}):
            part = [r[0] for r in tuning if r[3] == regime]
            rms = math.sqrt(sum(e * e for e in part) / len(part))
            print(f"  {regime}: n {len(part)}, a2 error RMS {rms:.5f}, max {max(part):.5f}")
        for name, level in LEVELS.items():
            floor = smallest(lambda v: covers(tuning, v, v, level, confidence), 1e-7)
            print(f"{name}: floor {floor:.6f} px/band²")
    for path in checks:
        run = json.load(open(path))
        stated = [c["curvature"] for c in run["cases"] if c.get("curvature")]
        n = len(stated)

        def bounds(k):
            """The stated 1σ and 95 % half-width, with `floors` where given (the records'
            own floors taken out of their sandwich part first), else as recorded."""
            if floors is None:
                return k["uncertainty"], k["interval_95"]
            f, f95 = floors
            s = sandwich(k)
            return math.hypot(s, f), math.hypot(2 * s, f95)

        one = sum(abs(k["error"]) <= bounds(k)[0] for k in stated)
        ninety_five = sum(abs(k["error"]) <= bounds(k)[1] for k in stated)
        rms = math.sqrt(sum(k["error"] ** 2 for k in stated) / n)
        print(
            f"{path}: n {n}, a2 error RMS {rms:.5f}; within 1σ {one} ({100 * one / n:.0f} %), "
            f"within the 95 % interval {ninety_five} ({100 * ninety_five / n:.0f} %)"
        )


if __name__ == "__main__":
    main()
