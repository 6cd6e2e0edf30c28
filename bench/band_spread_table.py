#!/usr/bin/env python3
"""Tables of snapshots calibrated with each band spread in the model (bench/band_spread_real.sh):
each answer per spread, the calibration's proxy score and the GAP-TV reconstruction's relative
residual under it (lower: the model explains the snapshot better — the spread adds no free
parameter), and per spread the snapshots' a1 spread (max − min) and SD.

    python3 bench/band_spread_table.py DIR [--truth MEAS_DIR] [--spreads point,uniform,linear]

DIR holds <name>.<spread>.calib.json and <name>.<spread>.recon.json. --truth MEAS_DIR: the
measurements' sidecars <name>.json (a control's), to print each answer's error against the
instrument's ψ (σ the optics' blur). Plain python3, no numpy."""
import argparse
import glob
import json
import os
import statistics

KEYS = ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"]
SHORT = {"dx": "dx", "dy": "dy", "theta_deg": "θ", "a1": "a1", "alpha_deg": "α", "blur_sigma_px": "σ"}
TOL = {"dx": 0.05, "dy": 0.05, "theta_deg": 0.05, "a1": 0.005, "alpha_deg": 0.1, "blur_sigma_px": 0.05}


def load(path):
    with open(path) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--truth")
    ap.add_argument("--spreads", default="point,uniform,linear")
    a = ap.parse_args()
    spreads = a.spreads.split(",")
    names = sorted({os.path.basename(p).split(".")[0]
                    for p in glob.glob(os.path.join(a.dir, "*.calib.json"))})
    print("| snapshot | spread | " + " | ".join(SHORT[k] for k in KEYS)
          + " | proxy score | GAP-TV rel. residual |")
    print("|---|---|" + "---|" * (len(KEYS) + 2))
    a1 = {s: [] for s in spreads}
    residual = {s: [] for s in spreads}
    within = {s: 0 for s in spreads}
    for name in names:
        truth = None
        if a.truth:
            truth = load(os.path.join(a.truth, f"{name}.json"))["simulation"]["mismatch"]
        for s in spreads:
            cal_path = os.path.join(a.dir, f"{name}.{s}.calib.json")
            if not os.path.exists(cal_path):
                continue
            cal = load(cal_path)
            p = cal["parameters"]
            rec_path = os.path.join(a.dir, f"{name}.{s}.recon.json")
            res = load(rec_path)["relative_residual"] if os.path.exists(rec_path) else float("nan")
            a1[s].append(p["a1"])
            residual[s].append(res)
            if truth is None:
                cells = [f"{p[k]:+.4f}" if k == "a1" else f"{p[k]:+.3f}" for k in KEYS]
            else:
                err = {k: p[k] - truth[k] for k in KEYS}
                ok = all(abs(err[k]) <= TOL[k] for k in KEYS)
                within[s] += ok
                cells = [f"{err[k]:+.4f}" if k == "a1" else f"{err[k]:+.3f}" for k in KEYS]
            print(f"| {name} | {s} | " + " | ".join(cells)
                  + f" | {cal['score']:.5e} | {res:.5f} |")
    print()
    head = "errors against the truth" if a.truth else "answers"
    print(f"({head}; σ is the optics' blur the model fits beside the spread)")
    print()
    for s in spreads:
        if len(a1[s]) < 2:
            continue
        line = (f"- {s}: a1 spread {max(a1[s]) - min(a1[s]):.4f} (SD {statistics.stdev(a1[s]):.4f}), "
                f"mean GAP-TV relative residual {statistics.mean(residual[s]):.5f}")
        if a.truth:
            line += f", all six within tolerance {within[s]} of {len(a1[s])}"
        print(line)
    base = spreads[0]
    for s in spreads[1:]:
        pairs = [(r0, r1) for r0, r1 in zip(residual[base], residual[s])]
        if pairs:
            lower = sum(r1 < r0 for r0, r1 in pairs)
            ratio = statistics.mean(r1 / r0 for r0, r1 in pairs)
            print(f"- {s} against {base}: residual lower on {lower} of {len(pairs)}, "
                  f"mean ratio {ratio:.4f}")


if __name__ == "__main__":
    main()
