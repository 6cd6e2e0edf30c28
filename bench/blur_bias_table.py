#!/usr/bin/env python3
"""The blind blur estimate's error against the true blur, from calibration records.

    python3 bench/blur_bias_table.py RECORD.json [MORE.json …]

RECORD.json: `cargo run --release -p cassi-bench --bin calibrate -- …` (any half). Pools
the records' cases (inverse-crime rows left out) and prints, per case kind (random,
aligned_blur, wide_blur), the mean σ error in bins of the true σ, the least-squares line
error = a + b·σ, and how many cases are within the benchmark's tolerance. A bias that
follows σ in one kind and not in another says where it comes from (the aligned
instruments put the mask on whole pixels, where the dispersed-mask model is exact).
"""
import json
import statistics
import sys

BINS = [(0.0, 0.15), (0.15, 0.4), (0.4, 0.6), (0.6, 0.9), (0.9, 2.0)]
KINDS = ["random", "aligned_blur", "wide_blur"]


def main(paths):
    if not paths:
        sys.exit(__doc__)
    cases = []
    tolerance = None
    for path in paths:
        with open(path) as f:
            record = json.load(f)
        tolerance = record["tolerances"]["blur_sigma_px"]
        cases += [c for c in record["cases"] if not c.get("inverse_crime")]
    print(f"records: {', '.join(paths)}\n")
    print("| kind | n | error = a + b·σ | within ±%.2f px | mean error per true σ (n) |" % tolerance)
    print("|---|---|---|---|---|")
    for kind in KINDS:
        rows = [
            (c["truth"]["blur_sigma_px"], c["error"]["blur_sigma_px"])
            for c in cases
            if c["kind"] == kind
        ]
        if len(rows) < 2:
            continue
        sigmas, errors = zip(*rows)
        if len(set(sigmas)) > 1:
            slope, intercept = statistics.linear_regression(sigmas, errors)
            line = f"{intercept:+.3f} {slope:+.3f}·σ"
        else:
            line = "one σ"
        within = sum(abs(e) <= tolerance for e in errors)
        per_bin = []
        for lo, hi in BINS:
            inside = [e for s, e in rows if lo <= s < hi]
            if inside:
                per_bin.append(f"[{lo}, {hi}) {statistics.mean(inside):+.3f} ({len(inside)})")
        print(f"| {kind} | {len(rows)} | {line} | {within} | {'; '.join(per_bin)} |")


if __name__ == "__main__":
    main(sys.argv[1:])
