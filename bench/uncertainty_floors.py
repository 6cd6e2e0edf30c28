#!/usr/bin/env python3
"""Re-derive the calibration's model-error floors from a tuning-half run.

    python3 bench/uncertainty_floors.py TUNING.json [MORE_TUNING.json …] [--confidence C]
        [--by-scene] [--check RUN.json …]

TUNING.json: `cargo run --release -p cassi-bench --bin calibrate -- --half tuning
--cases 6 --no-recon --no-limits --no-inverse-crime` (random, aligned-blur and wide-blur rows),
which records per case and parameter the stated standard error `uncertainty` and the
floor inside it, `uncertainty_floor` (and since stop 67 the share of the spread it took,
`uncertainty_spread_scale`). The fit's spread (block sandwich and disagreement) is
s = sqrt(uncertainty² − floor²) / share. The stated error is hypot(c·s, F(σ̂)) with
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
Since stop 66 σ's sharp floors of the default's fit (`SCENE_DETAIL_PASS`) are variances, derived
by `bench/sigma_variance.py --floor` (σ errs by a size in σ², not in σ); its table entries for σ
stay, for the trade-offs and the wide blur.

Several tuning runs are pooled (the scene fit's: the tuning half as it is and
`--scene-transform flip-cols / flip-rows / transpose`, each with its own seed round). A run
of the captured-mask instrument (`--mask-capture SIGMA`: a binary code rendered crisp, the
calibration handed its blurred image) pools as regimes of its own, each held to the target,
and its scene configurations are their own; σ's floors ignore it unless its record carries
σ's exact reference (`sigma_reference`, since stop 43; before it σ had no exact truth there).

--by-scene (the scene fit's floors): the standard-error floors are grown by κ ≥ 1, the
smallest factor that makes floors derived without each scene configuration (a tuning scene
in one orientation) cover that configuration's cases (leave one out; `scene_inflation`). The 95 % floors already demand every tuning
case; κ is printed for them but not applied, and a 95 % floor below its grown
standard-error floor is raised to it (an interval is never narrower than one standard error).

The spread's share c (stop 67, `SpreadShare` in calib/uncertainty.rs): for each parameter's
standard error the floors are derived (and grown) with each share in SHARES, and the share
whose stated errors have the smallest median over the tuning cases is printed with its floor
— the narrowest bars that still cover as above (σ's share stays 1: its floors are
variances; the 95 % half-width takes the whole spread). The default's fit states dx and a1
so; where the share printed is 1 the floor is the table's.

--check RUN.json (repeatable, pooled) prints, beside each floor, its coverage per regime on
other runs and the median error it would have stated there (held-out or fresh-seed records:
the check, not a choice; exact, since the floors enter in quadrature).
"""

import functools
import json
import math
import sys

SHARP_BLUR_PX, WIDE_BLUR_PX = 0.8, 1.0
HEADLINE = ("random", "aligned_blur")
WIDE = ("wide_blur",)
STEP = 1.002  # relative precision of the floor search
# the shares of the fit's spread searched for the standard error (`spread_scale`)
SHARES = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
# what each floor is for: (multiple of the sandwich part, target coverage); only the
# standard error's floors are grown by --by-scene
STANDARD_ERROR = "standard error (floor_sharp / floor_wide): 68 % within hypot(c·s, F)"
LEVELS = {
    STANDARD_ERROR: (1.0, 0.68),
    "95 % half-width (floor95_sharp / floor95_wide): 95 % within hypot(2s, F)": (2.0, 0.95),
}


def ramp(blur):
    t = (abs(blur) - SHARP_BLUR_PX) / (WIDE_BLUR_PX - SHARP_BLUR_PX)
    return min(max(t, 0.0), 1.0)


def regime(case, instrument=""):
    """The case's kind; the wide-blur row split into its aligned and random-pose halves;
    a captured-mask instrument's cases a regime of their own (`instrument`)."""
    if case["kind"] != "wide_blur":
        return case["kind"] + instrument
    t = case["truth"]
    return ("wide_blur aligned" if t["dx"] == 0 and t["dy"] == 0 else "wide_blur random pose") + instrument


def captured_mask(run):
    """The run's instrument carries a binary code and the calibration its blurred image
    (the benchmark's `--mask-capture`)."""
    return bool(run.get("instrument", {}).get("mask_capture"))


def sigma_without_truth(run):
    """A captured-mask run made before σ had an exact reference there (stop 43's
    `sigma_reference`, the σ the crisp-cell model fits with the scene known): its σ errors
    are against the instrument's own σ, which the model's σ does not stand for."""
    return captured_mask(run) and any(c.get("sigma_reference") is None for c in run["cases"]
                                      if c["kind"] in HEADLINE + WIDE)


def spread_part(case, p):
    """The fit's whole spread in `p`'s stated standard error: √(u² − floor²) / c, c the
    share of it the standard error took (`uncertainty_spread_scale`; 1 in records made
    before stop 67, when it took the whole). None where the case states no error."""
    u, f = case["uncertainty"].get(p), case.get("uncertainty_floor", {}).get(p)
    if u is None or f is None:
        return None
    c = (case.get("uncertainty_spread_scale") or {}).get(p) or 1.0
    return math.sqrt(max(u * u - f * f, 0.0)) / c


def scale_at(c, blur):
    """The spread's share c at a fitted blur: c up to SHARP_BLUR_PX, 1 from WIDE_BLUR_PX
    (the wide floors were set with the whole spread), linear between (`spread_scale`)."""
    return c + ramp(blur) * (1.0 - c)


def cases(run, kinds, p):
    """(|error|, sandwich part, fitted blur, regime, scene configuration) of the cases of
    `kinds` with a stated σ; the configuration is the scene and its `--scene-transform`."""
    if isinstance(run, list):
        return [row for r in run for row in cases(r, kinds, p)]
    transform = run.get("scene_transform", "none")
    instrument = ""
    if captured_mask(run):
        # in a record without σ's exact reference σ has no truth there (the model's σ
        # stands for the blur beyond the mask file's own): its floors come from the
        # other records alone
        if p == "blur_sigma_px" and sigma_without_truth(run):
            return []
        instrument = ", captured mask"
    out = []
    for c in run["cases"]:
        s = spread_part(c, p)
        if c["kind"] in kinds and s is not None:
            out.append(
                (
                    abs(c["error"][p]),
                    s,
                    c["estimate"]["blur_sigma_px"],
                    regime(c, instrument),
                    f"{c['scene']} ({transform}{instrument})",
                )
            )
    return out


def covered(rows, sharp, wide, k, c=1.0):
    """Share of `rows` with |error| ≤ hypot(k·c(σ̂)·s, F(σ̂)), c(σ̂) the spread's share."""
    hits = 0
    for e, s, blur, *_ in rows:
        hits += e <= math.hypot(k * scale_at(c, blur) * s, sharp + ramp(blur) * max(wide - sharp, 0.0))
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


def covers(rows, sharp, wide, level, confidence, c=1.0):
    """The margin on all `rows`, and the target itself in each regime among them."""
    k, target = level
    hits = round(covered(rows, sharp, wide, k, c) * len(rows))
    if hits < needed(len(rows), target, confidence):
        return False
    for r in {row[3] for row in rows}:
        part = [row for row in rows if row[3] == r]
        if covered(part, sharp, wide, k, c) < target:
            return False
    return True


def smallest(ok, start):
    """The smallest v ≥ start with ok(v), to a relative STEP (ok is monotone in v:
    a larger floor covers more): doubling, then bisection."""
    if ok(start):
        return start
    lo, hi = start, start * 2.0
    while not ok(hi):
        lo, hi = hi, hi * 2.0
    while hi > lo * STEP:
        mid = 0.5 * (lo + hi)
        if ok(mid):
            hi = mid
        else:
            lo = mid
    return hi


def derive(head, wide_rows, level, confidence, c=1.0):
    """The smallest (sharp, wide) floors that cover `head` and `wide_rows` at `level`
    with the spread's share c."""
    tiny = 1e-6
    sharp, wide = tiny, tiny
    for _ in range(3):  # the two floors meet in the ramp: settle both
        sharp = smallest(lambda v: covers(head, v, max(wide, v), level, confidence, c), tiny)
        if wide_rows:
            wide = smallest(lambda v: covers(wide_rows, sharp, v, level, confidence, c), sharp)
    return sharp, wide


def scene_inflation(head, wide_rows, level, confidence, c=1.0):
    """The smallest κ ≥ 1 such that floors κ·F₋ₛ derived without scene s cover
    scene s's cases as `covers` demands, pooled over every s (leave one scene out).

    A scene's seeds share its errors (the aligned beads miss dx by +0.35…+0.45 px in
    all three), so the cases are not independent draws: floors that cover 68 % of the
    tuning cases covered θ in 53–72 % of held-out ones. Held-out scenes are what a
    user's camera brings; the inflation is how much a floor must grow to cover a scene
    it never saw."""
    scenes = sorted({r[4] for r in head + wide_rows})
    held = []  # (row, floors derived without its scene)
    for sc in scenes:
        fs = derive(
            [r for r in head if r[4] != sc],
            [r for r in wide_rows if r[4] != sc],
            level,
            confidence,
            c,
        )
        held += [(r, fs) for r in head + wide_rows if r[4] == sc]

    def ok(kappa, rows):
        k, target = level
        hits = [
            r[0] <= math.hypot(k * scale_at(c, r[2]) * r[1], kappa * (sh + ramp(r[2]) * max(wd - sh, 0.0)))
            for r, (sh, wd) in rows
        ]
        if sum(hits) < target * len(hits):
            return False
        for reg in {r[3] for r, _ in rows}:
            part = [h for h, (r, _) in zip(hits, rows) if r[3] == reg]
            if sum(part) < target * len(part):
                return False
        return True

    head_held = [h for h in held if h[0][3] in HEADLINE]
    wide_held = [h for h in held if h[0][3] not in HEADLINE]
    kappa = smallest(lambda v: ok(v, head_held), 1.0)
    if wide_held:
        kappa = max(kappa, smallest(lambda v: ok(v, wide_held), 1.0))
    return kappa


def main():
    args = sys.argv[1:]
    confidence = 0.8
    by_scene = "--by-scene" in args
    args = [a for a in args if a != "--by-scene"]
    check = []  # every --check RUN.json, pooled
    while "--check" in args:
        i = args.index("--check")
        if i + 1 >= len(args):
            sys.exit(__doc__)
        check.append(json.load(open(args[i + 1])))
        args = args[:i] + args[i + 2 :]
    if "--confidence" in args:
        i = args.index("--confidence")
        if i + 1 >= len(args):
            sys.exit(__doc__)
        confidence = float(args[i + 1])
        args = args[:i] + args[i + 2 :]
    if not args or not 0.0 < confidence < 1.0:
        sys.exit(__doc__)
    run = [json.load(open(a)) for a in args]
    params = list(run[0]["cases"][0]["error"].keys())
    grown = {}  # parameter → the standard error's (sharp, wide)
    for name, level in LEVELS.items():
        print(f"\n{name}  (confidence {confidence})")
        print(
            f"{'parameter':<14} {'share':>5} {'sharp':>9} {'covers (n)':>14} {'wide':>9} {'covers (n)':>14}"
            + (f" {'κ':>6}" if by_scene else "")
        )
        for p in params:
            head, wide_rows = cases(run, HEADLINE, p), cases(run, WIDE, p)
            if not head:
                continue
            standard = name == STANDARD_ERROR
            # the spread's share: searched for the standard error (σ's stays whole: its
            # floors are variances, bench/sigma_variance.py); the 95 % takes it whole
            shares = SHARES if standard and p != "blur_sigma_px" else (1.0,)
            best = None
            for c in shares:
                sharp, wide = derive(head, wide_rows, level, confidence, c)
                kappa = scene_inflation(head, wide_rows, level, confidence, c) if by_scene else 1.0
                if standard:
                    sharp, wide = kappa * sharp, kappa * wide
                width = median_stated(head + wide_rows, sharp, wide, level[0], c)
                if best is None or width < best[0]:
                    best = (width, c, sharp, wide, kappa)
            _, c, sharp, wide, kappa = best
            if standard:
                grown[p] = (sharp, wide)
            elif p in grown:
                sharp, wide = max(sharp, grown[p][0]), max(wide, grown[p][1])
            h = covered(head, sharp, wide, level[0], c)
            line = f"{p:<14} {c:5.2f} {sharp:9.4g} {100 * h:9.0f} % ({len(head)})"
            if wide_rows:
                w = covered(wide_rows, sharp, wide, level[0], c)
                line += f" {wide:9.4g} {100 * w:9.0f} % ({len(wide_rows)})"
            if by_scene:
                line += f" {kappa:6.3f}" + ("" if standard else " (not applied)")
            if check:
                line += "   check:" + check_coverage(check, p, sharp, wide, level[0], c)
            print(line)
    error_correlation(run)


def median_stated(rows, sharp, wide, k, c):
    """The median stated error hypot(k·c(σ̂)·s, F(σ̂)) over `rows`: what a user reads."""
    widths = sorted(
        math.hypot(k * scale_at(c, blur) * s, sharp + ramp(blur) * max(wide - sharp, 0.0))
        for _, s, blur, *_ in rows
    )
    return widths[len(widths) // 2]


def check_coverage(runs, p, sharp, wide, k, c):
    """Coverage of these floors on other runs' cases (their spreads), per regime, with the
    median stated error: what the calibration would have stated there (exact: the floors
    enter in quadrature)."""
    out = []
    rows = cases(runs, HEADLINE + WIDE, p)
    for reg in sorted({r[3] for r in rows}):
        part = [r for r in rows if r[3] == reg]
        out.append(
            f" {reg.replace('wide_blur ', 'w-')} {100 * covered(part, sharp, wide, k, c):.0f}%"
            f" ±{median_stated(part, sharp, wide, k, c):.3g}"
        )
    return "".join(out)


def error_correlation(runs):
    """Σ eₐ·e_b / √(Σ eₐ² Σ e_b²) over every tuning case: `error_correlation` in
    calib/uncertainty.rs (the floors' covariance, from which the trade-offs are read)."""
    params = list(runs[0]["cases"][0]["error"].keys())
    # (errors, from a captured-mask run without σ's reference: σ's error there has no
    # exact truth and is left out)
    rows = [(c["error"], sigma_without_truth(r)) for r in runs for c in r["cases"]
            if c["kind"] in HEADLINE + WIDE]
    print(f"\nerror correlation over {len(rows)} cases (σ's over {sum(not k for _, k in rows)})")
    print(" " * 14 + "".join(f"{q[:8]:>9}" for q in params))
    for p in params:
        cells = []
        for q in params:
            pair = [r for r, captured in rows if not (captured and "blur_sigma_px" in (p, q))]
            num = sum(r[p] * r[q] for r in pair)
            den = math.sqrt(sum(r[p] ** 2 for r in pair) * sum(r[q] ** 2 for r in pair))
            cells.append(f"{num / den:+9.2f}")
        print(f"{p:<14}" + "".join(cells))


if __name__ == "__main__":
    main()
