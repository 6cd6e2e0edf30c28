#!/usr/bin/env python3
"""Two builds' calibration time side by side, as bench/timing_side_by_side.sh
writes it (OUTDIR/{base,new}_timing.json and OUTDIR/real/<snapshot>.{base,new}.calib.json),
or any two benchmark records and any directory of such snapshot pairs:

    python3 bench/timing_table.py OUTDIR
    python3 bench/timing_table.py --cases BASE.json NEW.json [--real DIR]

Prints markdown: per build the median seconds per case (random / aligned), the
total and the count with all six within tolerance; the per-case ratio new/base
(median, random, aligned) and how many cases give equal estimates, stated errors
and 95 % half-widths; for the snapshots each one's seconds, the ratio, and
whether the two files agree in every field but the times.
"""

import argparse
import glob
import json
import os
import statistics
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def without_times(value):
    """The record with every `seconds` field dropped, at any depth."""
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if k != "seconds"}
    if isinstance(value, list):
        return [without_times(v) for v in value]
    return value


def median(values):
    return statistics.median(values) if values else float("nan")


def cases_table(base_path, new_path):
    base, new = load(base_path), load(new_path)
    by_key = {(c["scene"], c["seed"], c["kind"]): c for c in base["cases"]}
    pairs = []
    for c in new["cases"]:
        key = (c["scene"], c["seed"], c["kind"])
        if key not in by_key:
            sys.exit(f"{new_path}: case {key} is not in {base_path}")
        pairs.append((by_key[key], c))
    if len(pairs) != len(base["cases"]):
        sys.exit(f"{base_path} and {new_path} hold different cases")

    def row(name, path, record):
        cases = record["cases"]
        secs = [c["seconds"] for c in cases]
        rnd = [c["seconds"] for c in cases if c["kind"] == "random"]
        ali = [c["seconds"] for c in cases if c["kind"] != "random"]
        within = sum(c["all_within_tolerance"] for c in cases)
        machine = record.get("machine", {})
        # records before stop 64's machine field do not say which copy ran
        kernels = machine.get("kernels", "not recorded")
        return (
            f"| {name} | `{os.path.basename(path)}` | {median(secs):.2f} s | "
            f"{median(rnd):.2f} / {median(ali):.2f} s | {sum(secs):.1f} s | "
            f"{within} of {len(cases)} | {machine.get('cpu', '?')}, {machine.get('threads', '?')} threads, kernels {kernels} |"
        )

    print("| build | record | median per case | random / aligned median | total | all six within tolerance | machine |")
    print("|---|---|---|---|---|---|---|")
    print(row("base", base_path, base))
    print(row("new", new_path, new))
    ratios = [n["seconds"] / b["seconds"] for b, n in pairs]
    rnd = [n["seconds"] / b["seconds"] for b, n in pairs if b["kind"] == "random"]
    ali = [n["seconds"] / b["seconds"] for b, n in pairs if b["kind"] != "random"]
    fields = ("estimate", "uncertainty", "interval_95")
    equal = sum(all(b[f] == n[f] for f in fields) for b, n in pairs)
    print()
    print(
        f"Per-case ratio new / base: median {median(ratios):.3f} "
        f"(random {median(rnd):.3f}, aligned {median(ali):.3f}); estimates, stated errors "
        f"and 95 % half-widths equal in {equal} of {len(pairs)} cases."
    )


def real_table(directory):
    bases = sorted(glob.glob(os.path.join(directory, "*.base.calib.json")))
    if not bases:
        return
    rows = []
    for base_path in bases:
        name = os.path.basename(base_path)[: -len(".base.calib.json")]
        new_path = os.path.join(directory, f"{name}.new.calib.json")
        if not os.path.exists(new_path):
            sys.exit(f"{new_path}: missing (its base is {base_path})")
        base, new = load(base_path), load(new_path)
        same = without_times(base) == without_times(new)
        rows.append((name, base["seconds"], new["seconds"], same))
    print()
    print("| snapshot | base | new | new / base | every field but the times equal |")
    print("|---|---|---|---|---|")
    for name, b, n, same in rows:
        print(f"| {name} | {b:.1f} s | {n:.1f} s | {n / b:.3f} | {'yes' if same else '**no**'} |")
    print(
        f"| **median** | **{median([r[1] for r in rows]):.1f} s** | "
        f"**{median([r[2] for r in rows]):.1f} s** | **{median([r[2] / r[1] for r in rows]):.3f}** | "
        f"{sum(r[3] for r in rows)} of {len(rows)} |"
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("outdir", nargs="?", help="bench/timing_side_by_side.sh's OUTDIR")
    parser.add_argument("--cases", nargs=2, metavar=("BASE", "NEW"), help="two benchmark records")
    parser.add_argument("--real", metavar="DIR", help="snapshot pairs <name>.{base,new}.calib.json")
    args = parser.parse_args()
    if args.outdir:
        if args.cases or args.real:
            parser.error("OUTDIR or --cases/--real, not both")
        cases = (
            os.path.join(args.outdir, "base_timing.json"),
            os.path.join(args.outdir, "new_timing.json"),
        )
        real = os.path.join(args.outdir, "real")
    else:
        if not args.cases:
            parser.error("OUTDIR or --cases BASE NEW")
        cases, real = args.cases, args.real
    for path in cases:
        if not os.path.exists(path):
            sys.exit(f"{path}: no such record")
    cases_table(*cases)
    if real:
        real_table(real)


if __name__ == "__main__":
    main()
