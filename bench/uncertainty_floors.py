#!/usr/bin/env python3
"""Re-derive the calibration's model-error floors from a tuning-half run.

    python3 bench/uncertainty_floors.py TUNING.json

TUNING.json: `cargo run --release -p cassi-bench --bin calibrate -- --half tuning
--no-recon --no-limits --no-inverse-crime` (random, aligned-blur and wide-blur rows),
which records per case and parameter the stated standard error `uncertainty` and the
floor inside it, `uncertainty_floor`. The block-sandwich part is
s = sqrt(uncertainty² − floor²). The stated error is hypot(s, F(σ̂)) with
F(σ̂) = sharp + t(σ̂)·(wide − sharp), t rising linearly from 0 at σ̂ = 0.8 px to 1 at
1.0 px (`calib/uncertainty.rs`). Printed: per parameter the smallest `sharp` that
covers ≥ 68 % of the random and aligned-blur cases at 1σ and ≥ 95 % at 2σ, and the
smallest `wide` (≥ sharp) that does so on the wide-blur cases, with the coverage each
gives. The floors are then copied into `floor_sharp` / `floor_wide` by hand; coverage is
reported on the held-out half, never here.
"""

import json
import math
import sys

SHARP_BLUR_PX, WIDE_BLUR_PX = 0.8, 1.0
HEADLINE = ("random", "aligned_blur")
WIDE = ("wide_blur",)
STEP = 1.002  # relative step of the scan


def ramp(blur):
    t = (abs(blur) - SHARP_BLUR_PX) / (WIDE_BLUR_PX - SHARP_BLUR_PX)
    return min(max(t, 0.0), 1.0)


def cases(run, kinds, p):
    """(|error|, sandwich part, fitted blur) of the cases of `kinds` with a stated σ."""
    out = []
    for c in run["cases"]:
        u, f = c["uncertainty"].get(p), c.get("uncertainty_floor", {}).get(p)
        if c["kind"] in kinds and u is not None and f is not None:
            s = math.sqrt(max(u * u - f * f, 0.0))
            out.append((abs(c["error"][p]), s, c["estimate"]["blur_sigma_px"]))
    return out


def coverage(rows, sharp, wide):
    n1 = n2 = 0
    for e, s, blur in rows:
        sigma = math.hypot(s, sharp + ramp(blur) * max(wide - sharp, 0.0))
        n1 += e <= sigma
        n2 += e <= 2 * sigma
    return n1 / len(rows), n2 / len(rows)


def covers(rows, sharp, wide):
    one, two = coverage(rows, sharp, wide)
    return one >= 0.68 and two >= 0.95


def smallest(ok, start):
    v = start
    while not ok(v):
        v *= STEP
    return v


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    run = json.load(open(sys.argv[1]))
    params = list(run["cases"][0]["error"].keys())
    print(f"{'parameter':<14} {'sharp':>9} {'cover 1σ/2σ (n)':>18} {'wide':>9} {'cover 1σ/2σ (n)':>18}")
    for p in params:
        head, wide_rows = cases(run, HEADLINE, p), cases(run, WIDE, p)
        if not head:
            continue
        tiny = 1e-6
        sharp, wide = tiny, tiny
        for _ in range(3):  # the two floors meet in the ramp: settle both
            sharp = smallest(lambda v: covers(head, v, max(wide, v)), tiny)
            if wide_rows:
                wide = smallest(lambda v: covers(wide_rows, sharp, v), sharp)
        h1, h2 = coverage(head, sharp, wide)
        line = f"{p:<14} {sharp:9.4g} {100 * h1:7.0f}/{100 * h2:.0f} % ({len(head)})"
        if wide_rows:
            w1, w2 = coverage(wide_rows, sharp, wide)
            line += f" {wide:9.4g} {100 * w1:7.0f}/{100 * w2:.0f} % ({len(wide_rows)})"
        print(line)


if __name__ == "__main__":
    main()
