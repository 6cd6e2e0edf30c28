#!/usr/bin/env python3
"""Tables of the snapshots calibrated with a band table held (bench/band_offsets_real.sh)
against the same snapshots without one: each answer, the five's a1 spread, and the ridge
probes' profiles — whether each side of each profile rises monotonically from the answer
(single-basin there) and which ends scored within the probes' 1 % margin.

    python3 bench/band_offsets_table.py HELD_DIR BASELINE [--baseline-suffix S] [--truth DIR]

HELD_DIR holds <name>.held_shape.calib.json; BASELINE is a folder of <name><S> (default
".probes.calib.json", bench/results/real/stop52_ridge_probes/) or a band_shifts record
(its cases' calibrations, e.g. bench/results/real/band_shifts/control.json). --truth DIR: the
measurements' sidecars <name>.json (a control's), to print each answer's error.
Plain python3, no numpy."""
import argparse
import glob
import json
import os
import statistics

KEYS = ["dx", "dy", "theta_deg", "a1", "alpha_deg", "blur_sigma_px"]
TOL = {"dx": 0.05, "dy": 0.05, "theta_deg": 0.05, "a1": 0.005, "alpha_deg": 0.1, "blur_sigma_px": 0.05}


def load(path):
    with open(path) as f:
        return json.load(f)


def monotone_sides(profile):
    """How many of the profile's two sides rise (never fall) going out from the answer."""
    steps, objective = profile["steps_px"], profile["relative_objective"]
    centre = steps.index(0.0)
    sides = [objective[centre:], objective[centre::-1]]
    return sum(all(b >= a for a, b in zip(side, side[1:])) for side in sides)


def at(profile, step):
    return profile["relative_objective"][profile["steps_px"].index(step)]


def summary(cal):
    probes = cal.get("ridge_probes") or {"profiles": [], "ends": []}
    profiles = {(p["ridge"], p["moved"]): p for p in probes["profiles"]}
    mono = sum(monotone_sides(p) for p in profiles.values())
    dx_first = profiles.get(("dx_a1", "first"))
    rise = (at(dx_first, -1.0), at(dx_first, 1.0)) if dx_first else (None, None)
    alternatives = [e for e in probes["ends"] if e.get("alternative")]
    return mono, len(profiles) * 2, rise, alternatives


def fmt_rise(r):
    return "–" if r[0] is None else f"{100 * r[0]:+.1f} / {100 * r[1]:+.1f} %"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("held")
    ap.add_argument("baseline")
    ap.add_argument("--baseline-suffix", default=".probes.calib.json")
    ap.add_argument("--truth")
    a = ap.parse_args()
    held_files = sorted(glob.glob(os.path.join(a.held, "*.held_shape.calib.json")))
    a1 = {"held": [], "without": []}
    a1_error = {"held": [], "without": []}
    print("| snapshot | table | dx, dy (px) | θ (°) | a1 | α (°) | σ (px) | profile sides rising (of 8) | dx–a1 band 0 at −1 / +1 px | ends within 1 % |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in held_files:
        name = os.path.basename(path).replace(".held_shape.calib.json", "")
        base_path = (a.baseline if a.baseline.endswith(".json")
                     else os.path.join(a.baseline, name + a.baseline_suffix))
        truth = None
        if a.truth:
            truth = load(os.path.join(a.truth, name + ".json"))["simulation"]["mismatch"]
        for label, p in [("held", path), ("without", base_path)]:
            if not os.path.exists(p):
                print(f"| {name} | {label} | (no record {p}) |")
                continue
            cal = load(p)
            if "cases" in cal:
                cal = next(c["calibration"] for c in cal["cases"] if c["snapshot"] == name)
            m = cal["parameters"]
            a1[label].append(m["a1"])
            mono, sides, rise, alts = summary(cal)
            ends = ", ".join(
                f"{e['ridge']} {e['moved']} {e['step_px']:+.2f} px → {100 * e['relative_objective']:+.2f} %"
                for e in alts
            ) or "none"
            values = {k: m[k] for k in KEYS}
            if truth:
                errors = {k: values[k] - truth[k] for k in KEYS}
                a1_error[label].append(errors["a1"])
                within = sum(abs(errors[k]) <= TOL[k] for k in KEYS)
                cells = [f"{errors['dx']:+.3f}, {errors['dy']:+.3f}", f"{errors['theta_deg']:+.3f}",
                         f"{errors['a1']:+.4f}", f"{errors['alpha_deg']:+.2f}",
                         f"{errors['blur_sigma_px']:+.3f} (errors; {within}/6 within)"]
            else:
                cells = [f"{values['dx']:+.3f}, {values['dy']:+.3f}", f"{values['theta_deg']:+.3f}",
                         f"{values['a1']:.4f}", f"{values['alpha_deg']:+.2f}", f"{values['blur_sigma_px']:.3f}"]
            side_cell = f"{mono} of {sides}" if sides else "– (no probes)"
            print(f"| {name} | {label} | " + " | ".join(cells) + f" | {side_cell} | {fmt_rise(rise)} | {ends} |")
    print()
    for label, values in a1.items():
        if len(values) > 1:
            print(f"a1 {label}: {', '.join(f'{v:.4f}' for v in values)}; spread (max − min) "
                  f"{max(values) - min(values):.4f}, SD {statistics.stdev(values):.4f}")
    for label, errors in a1_error.items():
        if len(errors) > 1:
            rms = (sum(e * e for e in errors) / len(errors)) ** 0.5
            print(f"a1 error {label}: {', '.join(f'{e:+.4f}' for e in errors)}; spread "
                  f"{max(errors) - min(errors):.4f}, SD {statistics.stdev(errors):.4f}, RMS {rms:.4f}")


if __name__ == "__main__":
    main()
