#!/usr/bin/env python3
"""How precisely each parameter must be known for ρ ≥ 95 %: the table of a `calibrate
--rho-sensitivity` record (crates/cassi-bench/src/bin/calibrate/rho_sensitivity.rs).

Each case's GAP-TV reconstructed with the true ψ but one parameter moved by a share of the
issue's tolerance (−1, −0.5, −0.2, +0.2, +0.5, +1); ρ against that case's own II and IV.
Prints, per kind (random, aligned by σ), for each parameter and move, how many cases keep
ρ ≥ 95 %, then for each case with a ρ miss in the record, the calibration's errors beside
the moves that cost it 5 % of ρ: whether the figure asks for more than the tolerances.

    python3 bench/rho_sensitivity_table.py RECORD.json
"""
import json
import sys

PARAMS = ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"]
SHARES = [-1.0, -0.5, -0.2, 0.2, 0.5, 1.0]


def group(case):
    if case["kind"] == "aligned_blur":
        return f"aligned σ {case['truth']['blur_sigma_px']:.1f}"
    return case["kind"]


def main(path):
    cases = [c for c in json.load(open(path))["cases"] if c.get("rho_sensitivity")]
    if not cases:
        sys.exit(f"{path}: no case holds rho_sensitivity (run calibrate with --rho-sensitivity)")
    groups = sorted({group(c) for c in cases})
    print(f"{path}: {len(cases)} cases; ρ ≥ 95 % at truth + share × tolerance (count of cases)")
    head = "".join(f"{s:>+7.1f}" for s in SHARES)
    for g in groups:
        gc = [c for c in cases if group(c) == g]
        print(f"\n{g} ({len(gc)} cases; calibrated ρ ≥ 95 % in "
              f"{sum(1 for c in gc if c['rho'] is not None and c['rho'] >= 0.95)})")
        print(f"  {'parameter':<14}{head}")
        for p in PARAMS:
            cells = []
            for s in SHARES:
                rows = [r for c in gc for r in c["rho_sensitivity"][p] if r["share"] == s]
                if not rows:
                    cells.append(f"{'—':>7}")
                    continue
                ok = sum(1 for r in rows if r["rho"] is not None and r["rho"] >= 0.95)
                cells.append(f"{ok:>4}/{len(rows):<2}")
            print(f"  {p:<14}{''.join(cells)}")
    misses = [c for c in cases if c["rho"] is not None and c["rho"] < 0.95]
    if misses:
        print("\nρ misses: the calibration's error per parameter (share of tolerance) and the "
              "smallest move of it, either way, that costs 5 % of ρ at the truth")
    for c in misses:
        iv_ii = c["psnr_db"]["IV_true"] - c["psnr_db"]["II_nominal"]
        print(f"  {c['scene']} seed {c['seed']} {group(c)}: ρ {c['rho']:.3f}, IV − II {iv_ii:.2f} dB, "
              f"IV − III {c['psnr_db']['IV_true'] - c['psnr_db']['III_calibrated']:.3f} dB")
        for p in PARAMS:
            tol = next(r["move"] / r["share"] for r in c["rho_sensitivity"][p] if r["share"])
            costly = [abs(r["share"]) for r in c["rho_sensitivity"][p]
                      if r["rho"] is not None and r["rho"] < 0.95]
            edge = f"{min(costly):.1f}" if costly else "> 1"
            print(f"    {p:<14} error {c['error'][p] / tol:+.2f} of tolerance; ρ < 95 % from {edge}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
