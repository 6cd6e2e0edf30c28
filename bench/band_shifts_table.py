#!/usr/bin/env python3
"""The band shifts' table: per snapshot the shape's size on the whole frame and its
halves, and whether a shape is shared — between the halves of one exposure and
across the snapshots of one camera.

    python3 bench/band_shifts_table.py RECORD.json [MORE.json …] [--control CONTROL.json]
    python3 bench/band_shifts_table.py --applied APPLY.json [MORE.json …]

RECORD: `cargo run --release -p cassi-bench --bin band_shifts` (one or several
records; their cases pooled). Printed per snapshot: the whole frame's shape RMS
(the band positions' departure from their best straight line, px), the line (a
common shift and a slope change), the objective's change, the halves' shape RMS,
the RMS of their mean and of their difference, and their correlation. Then over the
snapshots: each whole-frame shape's correlation with the mean of the others (leave
one out), the mean shape and its standard error per band; the step about band 22
(`red_step`). A shape the camera has
is shared by the halves and by the snapshots; a shape the fit makes of the scene
and the noise is not. --control: the same table for the control (measurements
simulated with a straight prism, `bench/band_shifts_control.sh`), whose shapes
are the fit's own. --applied: `band_shifts --apply` records (the others' mean shape
held on each snapshot: the objective's change with it and with its opposite).
"""
import json
import math
import sys


def rms(v):
    return math.sqrt(sum(x * x for x in v) / len(v))


def corr(a, b):
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    num = sum((x - ma) * (y - mb) for x, y in zip(a, b))
    den = math.sqrt(sum((x - ma) ** 2 for x in a) * sum((y - mb) ** 2 for y in b))
    return num / den if den > 0 else float("nan")


def red_step(along):
    """The step about band 22: the mean of bands 23–25 minus that of bands 18–21, each
    about the least-squares line through bands 14–27 (the red half's own line). A
    statistic chosen after seeing the real snapshots' mean shape (stop 54); a pure step
    of s px from band 22 on reads 0.53·s."""
    ks = list(range(14, len(along)))
    v = [along[k] for k in ks]
    mk, mv = sum(ks) / len(ks), sum(v) / len(v)
    slope = sum((k - mk) * (x - mv) for k, x in zip(ks, v)) / sum((k - mk) ** 2 for k in ks)
    r = [along[k] - (mv + slope * (k - mk)) for k in range(len(along))]
    return sum(r[23:26]) / 3 - sum(r[18:22]) / 4


def windows(case):
    return {w["window"]: w["shifts"] for w in case["windows"]}


def table(cases, label):
    print(f"\n{label}: {len(cases)} snapshots")
    print(f"{'snapshot':<20} {'whole RMS':>9} {'line c':>7} {'slope':>8} {'objective':>10}"
          f" {'top':>6} {'bottom':>6} {'mean':>6} {'diff':>6} {'r(top,bottom)':>13}"
          f" {'step 22 (whole/top/bottom)':>27}")
    shapes = []
    for c in cases:
        w = windows(c)
        whole, top, bottom = w["whole"], w["top"], w["bottom"]
        change = whole["score_shifted"] / whole["score_unshifted"] - 1.0
        mean = [(a + b) / 2 for a, b in zip(top["shape"], bottom["shape"])]
        diff = [a - b for a, b in zip(top["shape"], bottom["shape"])]
        print(f"{c['snapshot']:<20} {rms(whole['shape']):9.3f} {whole['line'][0]:+7.3f}"
              f" {whole['line'][1]:+8.4f} {100 * change:+9.1f}%"
              f" {rms(top['shape']):6.3f} {rms(bottom['shape']):6.3f} {rms(mean):6.3f}"
              f" {rms(diff):6.3f} {corr(top['shape'], bottom['shape']):+13.2f}"
              f"   {red_step(whole['along']):+.2f} / {red_step(top['along']):+.2f} /"
              f" {red_step(bottom['along']):+.2f}")
        shapes.append((c["snapshot"], whole["shape"]))
    if len(shapes) > 1:
        print("leave-one-out: each whole shape's correlation with the others' mean")
        for i, (name, s) in enumerate(shapes):
            others = [t for j, (_, t) in enumerate(shapes) if j != i]
            mean = [sum(v) / len(others) for v in zip(*others)]
            print(f"  {name:<20} r {corr(s, mean):+.2f}")
        n = len(shapes)
        bands = list(zip(*(s for _, s in shapes)))
        mean = [sum(b) / n for b in bands]
        se = [math.sqrt(sum((x - m) ** 2 for x in b) / (n - 1) / n) for b, m in zip(bands, mean)]
        print("mean shape ± standard error per band (px):")
        print("  " + " ".join(f"{m:+.2f}±{e:.2f}" for m, e in zip(mean, se)))
        beyond = sum(abs(m) > 2 * e for m, e in zip(mean, se))
        print(f"  bands whose mean is beyond 2 standard errors: {beyond} of {len(mean)}")


def applied(path):
    """An `--apply` record: each snapshot's objective with the others' mean shape and
    its opposite, relative to no shift; the antisymmetric part (opposite − shape) / 2
    is what the shape's sign does, the symmetric part what moving the bands at all does."""
    run = json.load(open(path))
    print(f"\n{path}: the others' mean shape applied (objective change, %)")
    print(f"{'snapshot':<20} {'shape':>7} {'opposite':>9} {'(opp-shape)/2':>14} {'(opp+shape)/2':>14}")
    for c in run["cases"]:
        base = c["score_unshifted"]
        s = 100 * (c["score_others_shape"] / base - 1)
        o = 100 * (c["score_opposite_shape"] / base - 1)
        print(f"{c['snapshot']:<20} {s:+7.2f} {o:+9.2f} {(o - s) / 2:+14.2f} {(o + s) / 2:+14.2f}")


def main(argv):
    if argv[:1] == ["--applied"]:
        for p in argv[1:]:
            applied(p)
        return
    control = []
    if "--control" in argv:
        i = argv.index("--control")
        control = argv[i + 1:]
        argv = argv[:i]
    if not argv:
        sys.exit(__doc__)
    cases = [c for p in argv for c in json.load(open(p))["cases"]]
    table(cases, "real snapshots")
    if control:
        table([c for p in control for c in json.load(open(p))["cases"]], "control (straight prism)")


if __name__ == "__main__":
    main(sys.argv[1:])
