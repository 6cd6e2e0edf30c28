#!/usr/bin/env python3
"""Re-derive the calibration's model-error floors from a tuning-half run.

    python3 bench/uncertainty_floors.py TUNING.json [--confidence C]

TUNING.json: `cargo run --release -p cassi-bench --bin calibrate -- --half tuning
--cases 6 --no-recon --no-limits --no-inverse-crime` (random, aligned-blur and wide-blur rows),
which records per case and parameter the stated standard error `uncertainty` and the
floor inside it, `uncertainty_floor`. The block-sandwich part is
s = sqrt(uncertainty² − floor²). The stated error is hypot(s, F(σ̂)) with
F(σ̂) = sharp + t(σ̂)·(wide − sharp), t rising linearly from 0 at σ̂ = 0.8 px to 1 at
1.0 px (`calib/uncertainty.rs`). Printed: per parameter and level (the standard
error: 68 % within hypot(s, F); the 95 % half-width: 95 % within hypot(2s, F95)) the
smallest `sharp` floor that covers the random and aligned-blur cases, and the smallest
`wide` (≥ sharp) that covers the wide-blur cases, with the coverage each gives.

"Covers" means two things. In each regime (random, aligned-blur; the wide row's aligned
and random-pose halves) at least the target: a floor set on the pooled cases left the
harder random poses short (64 % of a1 at 1σ on the tuning half). And over all the
cases a finite-sample margin: a floor that covers exactly 68 % of n tuning cases covers
less on new ones about half the time (set that way, the floors covered dx 54 % at 1σ
held out after 72 % on the tuning half). So the count of covered cases k must make the
one-sided Clopper–Pearson lower bound on the coverage, at confidence C (default 0.8),
reach the target; where even k = n cannot (95 % on a few dozen cases), every case must
be covered. The floors are then copied into `calib/uncertainty.rs` by hand, rounded up;
coverage is reported on the held-out half, never here.
"""

import functools
import json
import math
import sys

SHARP_BLUR_PX, WIDE_BLUR_PX = 0.8, 1.0
HEADLINE = ("random", "aligned_blur")
WIDE = ("wide_blur",)
STEP = 1.002  # relative step of the scan
# what each floor is for: (multiple of the sandwich part, target coverage)
LEVELS = {
    "standard error (floor_sharp / floor_wide): 68 % within hypot(s, F)": (1.0, 0.68),
    "95 % half-width (floor95_sharp / floor95_wide): 95 % within hypot(2s, F)": (2.0, 0.95),
}


def ramp(blur):
    t = (abs(blur) - SHARP_BLUR_PX) / (WIDE_BLUR_PX - SHARP_BLUR_PX)
    return min(max(t, 0.0), 1.0)


def regime(case):
    """The case's kind; the wide-blur row split into its aligned and random-pose halves."""
    if case["kind"] != "wide_blur":
        return case["kind"]
    t = case["truth"]
    return "wide_blur aligned" if t["dx"] == 0 and t["dy"] == 0 else "wide_blur random pose"


def cases(run, kinds, p):
    """(|error|, sandwich part, fitted blur, regime) of the cases of `kinds` with a stated σ."""
    out = []
    for c in run["cases"]:
        u, f = c["uncertainty"].get(p), c.get("uncertainty_floor", {}).get(p)
        if c["kind"] in kinds and u is not None and f is not None:
            s = math.sqrt(max(u * u - f * f, 0.0))
            out.append((abs(c["error"][p]), s, c["estimate"]["blur_sigma_px"], regime(c)))
    return out


def covered(rows, sharp, wide, k):
    """Share of `rows` with |error| ≤ hypot(k·s, F(σ̂))."""
    hits = 0
    for e, s, blur, _ in rows:
        hits += e <= math.hypot(k * s, sharp + ramp(blur) * max(wide - sharp, 0.0))
    return hits / len(rows)


def binomial_tail(n, k, p):
    """P(X ≥ k) for X ~ Binomial(n, p)."""
    return sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1))


def lower_bound(n, k, confidence):
    """One-sided Clopper–Pearson lower bound on a proportion seen k times in n."""
    if k == 0:
        return 0.0
    lo, hi = 0.0, 1.0
    for _ in range(60):  # the p at which P(X ≥ k) = 1 − confidence
        mid = 0.5 * (lo + hi)
        if binomial_tail(n, k, mid) < 1 - confidence:
            lo = mid
        else:
            hi = mid
    return lo


@functools.cache
def needed(n, target, confidence):
    """Fewest covered cases of n whose lower bound reaches `target` (n if none does)."""
    return next((k for k in range(n + 1) if lower_bound(n, k, confidence) >= target), n)


def covers(rows, sharp, wide, level, confidence):
    """The margin on all `rows`, and the target itself in each regime among them."""
    k, target = level
    hits = round(covered(rows, sharp, wide, k) * len(rows))
    if hits < needed(len(rows), target, confidence):
        return False
    for r in {row[3] for row in rows}:
        part = [row for row in rows if row[3] == r]
        if covered(part, sharp, wide, k) < target:
            return False
    return True


def smallest(ok, start):
    v = start
    while not ok(v):
        v *= STEP
    return v


def main():
    args = sys.argv[1:]
    confidence = 0.8
    if len(args) == 3 and args[1] == "--confidence":
        confidence = float(args[2])
        args = args[:1]
    if len(args) != 1 or not 0.0 < confidence < 1.0:
        sys.exit(__doc__)
    run = json.load(open(args[0]))
    params = list(run["cases"][0]["error"].keys())
    for name, level in LEVELS.items():
        print(f"\n{name}  (confidence {confidence})")
        print(f"{'parameter':<14} {'sharp':>9} {'covers (n)':>14} {'wide':>9} {'covers (n)':>14}")
        for p in params:
            head, wide_rows = cases(run, HEADLINE, p), cases(run, WIDE, p)
            if not head:
                continue
            tiny = 1e-6
            sharp, wide = tiny, tiny
            for _ in range(3):  # the two floors meet in the ramp: settle both
                sharp = smallest(
                    lambda v: covers(head, v, max(wide, v), level, confidence), tiny
                )
                if wide_rows:
                    wide = smallest(
                        lambda v: covers(wide_rows, sharp, v, level, confidence), sharp
                    )
            h = covered(head, sharp, wide, level[0])
            line = f"{p:<14} {sharp:9.4g} {100 * h:9.0f} % ({len(head)})"
            if wide_rows:
                w = covered(wide_rows, sharp, wide, level[0])
                line += f" {wide:9.4g} {100 * w:9.0f} % ({len(wide_rows)})"
            print(line)
    error_correlation(run)


def error_correlation(run):
    """Σ eₐ·e_b / √(Σ eₐ² Σ e_b²) over every tuning case: `error_correlation` in
    calib/uncertainty.rs (the floors' covariance, from which the trade-offs are read)."""
    params = list(run["cases"][0]["error"].keys())
    rows = [c["error"] for c in run["cases"] if c["kind"] in HEADLINE + WIDE]
    print(f"\nerror correlation over {len(rows)} cases")
    print(" " * 14 + "".join(f"{q[:8]:>9}" for q in params))
    for p in params:
        cells = []
        for q in params:
            num = sum(r[p] * r[q] for r in rows)
            den = math.sqrt(sum(r[p] ** 2 for r in rows) * sum(r[q] ** 2 for r in rows))
            cells.append(f"{num / den:+9.2f}")
        print(f"{p:<14}" + "".join(cells))


if __name__ == "__main__":
    main()
