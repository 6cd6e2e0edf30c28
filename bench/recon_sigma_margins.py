#!/usr/bin/env python3
"""GAP-TV's PSNR and ρ with the reconstruction σ moved by a margin, from `calibrate` records.

    python3 bench/recon_sigma_margins.py RECORD.json [RECORD.json …]

The records must come from `calibrate … --recon-sigma-margins D,…` (each case's
`psnr_db.III_sigma_margin` holds III again with σ moved by each D px from the σ the calibration
reconstructed with). Prints, per margin and per kind (random poses, aligned instruments), the cases
with ρ = (III − II)/(IV − II) ≥ 95 % and III's mean and worst change against the margin 0 (III as
the calibration reconstructed). How `OnGridMargin`'s margin was chosen on the tuning half
(bench/results/default_stop68/recon_sigma_margin/).
"""
import json
import statistics
import sys


def rho(ii, iii, iv):
    return (iii - ii) / (iv - ii) if iv - ii > 0 else None


def main(files):
    cases = [c for f in files for c in json.load(open(f))["cases"] if c.get("psnr_db")]
    if not cases or "III_sigma_margin" not in cases[0]["psnr_db"]:
        sys.exit("no III_sigma_margin in the records: run calibrate with --recon-sigma-margins")
    margins = ["0"] + list(cases[0]["psnr_db"]["III_sigma_margin"])
    print(f"{len(cases)} cases")
    for d in margins:
        parts = []
        for kind in ("random", "aligned_blur"):
            cs = [c for c in cases if c["kind"] == kind]
            if not cs:
                continue
            base = [c["psnr_db"]["III_calibrated"] for c in cs]
            iii = base if d == "0" else [c["psnr_db"]["III_sigma_margin"][d] for c in cs]
            passed = 0
            for c, x in zip(cs, iii):
                r = rho(c["psnr_db"]["II_nominal"], x, c["psnr_db"]["IV_true"])
                passed += r is not None and r >= 0.95
            change = [x - b for x, b in zip(iii, base)]
            parts.append(
                f"{kind}: ρ ≥ 95 % {passed}/{len(cs)}, III change mean "
                f"{statistics.mean(change):+.4f} worst {min(change):+.4f} dB"
            )
        print(f"margin {d:>6} px  " + " | ".join(parts))


if __name__ == "__main__":
    main(sys.argv[1:])
