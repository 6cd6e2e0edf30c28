"""Markdown table of the real-data calibrations written by bench/real_data.sh.

Usage: python3 bench/real_data_table.py bench/results/real PRESET
"""
import json
import pathlib
import sys

out, preset = pathlib.Path(sys.argv[1]), sys.argv[2]
print(f"# Real TSA-Net snapshots: `{preset}` self-calibration\n")
print("No ground truth exists for these measurements. Evidence of a real mismatch is a lower")
print("residual under the calibrated model and agreement between independent scenes.\n")
print("Score = residual per measurement pixel of the proxy reconstruction (calibration objective);")
print("GAP-TV residual = ‖y − A x̂‖/‖y‖ after 100 GAP-TV iterations with that model.\n")
print("| scene | dx (px) | dy (px) | θ (°) | a1 | α (°) | score nominal → calibrated | GAP-TV residual nominal → calibrated | time (s) | previews |")
print("|---|---|---|---|---|---|---|---|---|---|")
for calib in sorted(out.glob(f"*.{preset}.calib.json")):
    name = calib.name.split(".")[0]
    c = json.loads(calib.read_text())
    p = c["parameters"]
    nom = json.loads((out / f"{name}.nominal.recon.json").read_text())
    cal = json.loads((out / f"{name}.{preset}.calibrated.recon.json").read_text())
    change = 100.0 * (c["score"] / c["nominal_score"] - 1.0)
    print(
        f"| {name} | {p['dx']:+.3f} | {p['dy']:+.3f} | {p['theta_deg']:+.3f} | {p['a1']:.4f} "
        f"| {p['alpha_deg']:+.2f} | {c['nominal_score']:.3e} → {c['score']:.3e} ({change:+.0f} %) "
        f"| {nom['relative_residual']:.4f} → {cal['relative_residual']:.4f} | {c['seconds']:.1f} "
        f"| [nominal]({name}.nominal.png) · [calibrated]({name}.{preset}.calibrated.png) |"
    )
