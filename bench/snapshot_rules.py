#!/usr/bin/env python3
"""Compare ways of combining several snapshots' calibrations of one instrument.

Reads calibration-bench records made with `--snapshots N` (each case a
snapshot, `instrument_seed` its instrument), regroups the snapshots per
instrument and, for each centre (mean, inverse-variance mean, median) and
each error bar (the stated errors combined as independent, the snapshots'
scatter with Student's t, the larger of the two), prints per kind how many
combinations are within the issue's tolerances (all six, each parameter)
and the coverage of the 1σ and 95 % bars. The stated errors are combined
as correlated between snapshots at each `--rho=R` (default 0 and 0.5). `--check` also recomputes the
shipped rule (`cassi_core::calib::combine_snapshots`, its default) and
compares it with the record's `snapshots.instruments` (the code and this
script agree). Last, the shipped rule on every subset of k of each
instrument's snapshots (k = 1: the snapshots alone, their own errors), with
the record's rule or `--centre` and each `--rho`.

Usage: python3 bench/snapshot_rules.py RECORD.json [RECORD.json ...] [--rho=R ...] [--centre=mean|median|inverse_variance] [--check]
"""
import itertools
import json
import math
import sys
from collections import defaultdict

PARAMS = ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"]
# Student's t, two-sided 68.27 % and 95 %, by degrees of freedom
T68 = {1: 1.8373, 2: 1.3213, 3: 1.1969, 4: 1.1417, 5: 1.1105, 6: 1.0903, 7: 1.0762, 8: 1.0657, 9: 1.0576}
T95 = {1: 12.7062, 2: 4.3027, 3: 3.1824, 4: 2.7764, 5: 2.5706, 6: 2.4469, 7: 2.3646, 8: 2.3060, 9: 2.2622}
MEDIAN_FACTOR = math.sqrt(math.pi / 2)


def mean(v):
    return sum(v) / len(v)


def sd(v):
    m = mean(v)
    return math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))


def median(v):
    s = sorted(v)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def combine(values, sigmas, halves, centre, bar, rho):
    """One parameter: (value, 1σ, 95 % half-width) as `centre` and `bar` say,
    the stated errors combined as correlated at `rho` between snapshots
    (as cassi_core::calib::combine_snapshots does)."""
    k = len(values)
    dof = k - 1
    factor = 1.0
    if centre == "inverse_variance":
        w = [1 / s ** 2 for s in sigmas]
        a = [wi / sum(w) for wi in w]
        value = sum(x * ai for x, ai in zip(values, a))
    else:
        a = [1 / k] * k
        value = mean(values)
        if centre == "median":
            value, factor = median(values), MEDIAN_FACTOR

    def formal(s):
        own = sum((ai * si) ** 2 for ai, si in zip(a, s))
        tot = sum(ai * si for ai, si in zip(a, s))
        return factor * math.sqrt(max(own + rho * (tot * tot - own), 0.0))

    centre_w = sum(x * ai for x, ai in zip(values, a))
    scatter = factor * math.sqrt(sum(ai * (x - centre_w) ** 2 for x, ai in zip(values, a)) / dof)
    s1, s95 = T68[dof] * scatter, T95[dof] * scatter
    if bar == "stated":
        return value, formal(sigmas), formal(halves)
    if bar == "scatter":
        return value, s1, s95
    return value, max(formal(sigmas), s1), max(formal(halves), s95)


def instruments(records):
    groups = defaultdict(list)
    for path in records:
        d = json.load(open(path))
        for c in d["cases"]:
            if c.get("instrument_seed") is not None:
                groups[(path, c["instrument_seed"])].append(c)
    return groups


def subsets(groups, tol, rule, rho):
    """The rule on every subset of k of each instrument's snapshots."""
    print(f"\n== subsets of k snapshots, centre {rule['centre']}, error bar larger, snapshot correlation {rho}")
    for kind in sorted({cases[0]["kind"] for cases in groups.values()}):
        members = [cases for cases in groups.values() if cases[0]["kind"] == kind]
        for k in range(1, max(len(c) for c in members) + 1):
            n = allw = 0
            c1 = {p: 0 for p in PARAMS}
            c95 = {p: 0 for p in PARAMS}
            for cases in members:
                for subset in itertools.combinations(cases, k):
                    n += 1
                    truth = subset[0]["truth"]
                    ok = True
                    for p in PARAMS:
                        if k == 1:
                            c = subset[0]
                            v, s1, s95 = c["estimate"][p], c["uncertainty"][p], c["interval_95"][p]
                        else:
                            v, s1, s95 = combine(
                                [c["estimate"][p] for c in subset],
                                [c["uncertainty"][p] for c in subset],
                                [c["interval_95"][p] for c in subset],
                                rule["centre"],
                                "larger",
                                rho,
                            )
                        e = abs(v - truth[p])
                        ok &= e <= tol[p]
                        c1[p] += e <= s1
                        c95[p] += e <= s95
                    allw += ok
            cov = lambda c: " ".join(f"{p.split('_')[0]} {100 * c[p] / n:.0f}" for p in PARAMS)
            print(f"  {kind:<13} k {k}: {n:>4} combinations, all six within {100 * allw / n:5.1f} %;"
                  f" 1σ cov % {cov(c1)}; 95 % cov % {cov(c95)}")


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if not args:
        sys.exit(__doc__)
    groups = instruments(args)
    tol = json.load(open(args[0]))["tolerances"]
    explicit = [float(a.split("=", 1)[1]) for a in sys.argv[1:] if a.startswith("--rho=")]
    rhos = explicit or [0.0, 0.5]
    for centre, bar, rho in [(c, b, r) for c in ["mean", "inverse_variance", "median"]
                             for b in ["stated", "scatter", "larger"] for r in rhos]:
        if bar == "scatter" and rho != rhos[0]:
            continue
        if True:
            by_kind = defaultdict(list)
            for (_, _), cases in groups.items():
                truth = cases[0]["truth"]
                row = {}
                for p in PARAMS:
                    v, s1, s95 = combine(
                        [c["estimate"][p] for c in cases],
                        [c["uncertainty"][p] for c in cases],
                        [c["interval_95"][p] for c in cases],
                        centre,
                        bar,
                        rho,
                    )
                    row[p] = (v - truth[p], s1, s95)
                by_kind[cases[0]["kind"]].append(row)
            print(f"\n== centre {centre}, error bar {bar}, snapshot correlation {rho}")
            for kind, rows in sorted(by_kind.items()):
                n = len(rows)
                allw = sum(all(abs(r[p][0]) <= tol[p] for p in PARAMS) for r in rows)
                print(f"  {kind:<13} {n:>3} instruments: all six within {allw}/{n}")
                for p in PARAMS:
                    w = sum(abs(r[p][0]) <= tol[p] for r in rows)
                    c1 = sum(abs(r[p][0]) <= r[p][1] for r in rows)
                    c95 = sum(abs(r[p][0]) <= r[p][2] for r in rows)
                    rmse = math.sqrt(sum(r[p][0] ** 2 for r in rows) / n)
                    print(f"    {p:<14} within {w:>3}/{n}  RMSE {rmse:.4f}  1σ cov {c1:>3}/{n}  95 % cov {c95:>3}/{n}")
    # the snapshots alone, for comparison
    print("\n== single snapshots")
    by_kind = defaultdict(list)
    for cases in groups.values():
        for c in cases:
            by_kind[c["kind"]].append(c)
    for kind, cases in sorted(by_kind.items()):
        n = len(cases)
        allw = sum(c["all_within_tolerance"] for c in cases)
        print(f"  {kind:<13} {n:>3} snapshots: all six within {allw}/{n}")
        for p in PARAMS:
            w = sum(c["within_tolerance"][p] for c in cases)
            rmse = math.sqrt(sum(c["error"][p] ** 2 for c in cases) / n)
            print(f"    {p:<14} within {w:>3}/{n}  RMSE {rmse:.4f}")
    # how the shipped rule fares with fewer snapshots: every subset of k of
    # an instrument's snapshots, k = 2 … K (each subset one combination)
    d = json.load(open(args[0]))
    rule = (d.get("snapshots") or {}).get("rule") or {"centre": "mean", "snapshot_correlation": 0.5}
    centres = [a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith("--centre=")]
    if centres:
        rule = dict(rule, centre=centres[0])
    for rho in explicit or [rule.get("snapshot_correlation", 0.0)]:
        subsets(groups, tol, rule, rho)
    if "--check" in sys.argv:
        worst = 0.0
        for path in args:
            d = json.load(open(path))
            rule = d["snapshots"]["rule"]
            for inst in d["snapshots"]["instruments"]:
                cases = groups[(path, inst["instrument_seed"])]
                for p in PARAMS:
                    v, s1, s95 = combine(
                        [c["estimate"][p] for c in cases],
                        [c["uncertainty"][p] for c in cases],
                        [c["interval_95"][p] for c in cases],
                        rule["centre"],
                        "larger",
                        rule.get("snapshot_correlation", 0.0),
                    )
                    for a, b in [(v, inst["estimate"][p]), (s1, inst["uncertainty"][p]), (s95, inst["interval_95"][p])]:
                        worst = max(worst, abs(a - b) / max(abs(b), 1e-12))
        print(f"\nshipped rule recomputed: largest relative difference {worst:.2e}")
        if worst > 1e-3:
            sys.exit("the record's combinations differ from this script's")


if __name__ == "__main__":
    main()
