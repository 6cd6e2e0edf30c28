#!/usr/bin/env python3
"""Which σ GAP-TV should reconstruct with (stop 63): the calibrated model's own (the scene fit's,
`Calibration::model_blur_sigma_px`, III today, `psnr_db.III_calibrated`) or the reported one (the
blur pass's, `psnr_db.III_blur_pass_sigma`). Per record: ρ = (III − II)/(IV − II) ≥ 95 % with each
(cases with IV − II ≥ 0.1 dB, as the bench counts), and the mean PSNR change pass − model, per
kind. The tuning half's records are the ones a choice may be made on; the held-out rounds are
listed for what they show. Run from the repository root:

    python3 bench/results/default_stop63/tuning/recon_sigma.py
"""
import json

RECORDS = [
    ("tuning half, random poses", "bench/results/default_stop63/tuning/random_recon.json"),
    ("tuning half, aligned", "bench/results/default_stop63/tuning/aligned_recon.json"),
    ("round 41 (held out)", "bench/results/default_stop62/held_out/round41.json"),
    ("round 42 (held out)", "bench/results/default_stop63/held_out/round42.json"),
    ("round 43 (held out)", "bench/results/default_stop63/held_out/round43.json"),
]
RHO_MIN_GAIN_DB = 0.1

for label, path in RECORDS:
    cases = json.load(open(path))["cases"]
    for kind in ("random", "aligned_blur"):
        rows = [c for c in cases if c["kind"] == kind and "psnr_db" in c]
        if not rows:
            continue
        defined = model_ok = pass_ok = 0
        change = []
        for c in rows:
            p = c["psnr_db"]
            ii, model, iv, passed = p["II_nominal"], p["III_calibrated"], p["IV_true"], p["III_blur_pass_sigma"]
            change.append(passed - model)
            if iv - ii < RHO_MIN_GAIN_DB:
                continue
            defined += 1
            model_ok += (model - ii) / (iv - ii) >= 0.95
            pass_ok += (passed - ii) / (iv - ii) >= 0.95
        print(f"{label}, {kind}: rho >= 95 % with the model's σ {model_ok}, with the pass's {pass_ok} "
              f"(of {defined}); PSNR pass - model: mean {sum(change) / len(change):+.4f} dB, "
              f"min {min(change):+.3f}, max {max(change):+.3f} ({len(change)} cases)")
