"""The real snapshots' a2 profile (bench/real_data_a2.sh): per held curvature
a2, each snapshot's a1, dx and the last stage's residual, and a1's spread
across the snapshots. Usage: real_data_a2_table.py FOLDER > README.md"""
import glob
import json
import os
import sys

folder = sys.argv[1]


def first_pass(rec):
    """The scene fit's first pass's objective (its stage is named so)."""
    return next(s["score"] for s in rec["stages"] if s["name"].startswith("scene fit ("))


rows = {}
for path in sorted(glob.glob(os.path.join(folder, "*.a2_*.calib.json"))):
    name, a2 = os.path.basename(path)[: -len(".calib.json")].split(".a2_")
    with open(path) as f:
        rec = json.load(f)
    rows.setdefault(float(a2), {})[name] = rec
names = sorted({n for r in rows.values() for n in r})
print("# Real TSA-Net snapshots: a profile over the dispersion's curvature a2\n")
print("`bench/real_data_a2.sh`: `cassi calibrate` (default preset) with the curvature held at")
print("each a2 (band k at a1·k + a2·k² px; `--dispersion-a2`). Residuals r1 / r2: the objective")
print("of the scene fit's first pass and of its fine pass (ridge-penalised) at their answers,")
print("comparable between a2 values on one snapshot (not between the two).")
print("No ground truth: what the profile can say is which a2 each snapshot's data prefer")
print("and whether a1 agrees across the snapshots there.\n")
short = [n.split("_", 1)[1] if "_" in n else n for n in names]
print("| a2 (px/band²) | " + " | ".join(short) + " | a1 spread |")
print("|---|" + "---|" * (len(names) + 1))
for a2 in sorted(rows):
    cells = []
    a1s = []
    for n in names:
        rec = rows[a2].get(n)
        if rec is None:
            cells.append("–")
            continue
        p = rec["parameters"]
        a1s.append(p["a1"])
        last = rec["stages"][-1]["score"]
        first = first_pass(rec)
        cells.append(f"a1 {p['a1']:.4f} ± {rec['uncertainty'].get('a1') or float('nan'):.4f}, "
                     f"dx {p['dx']:+.2f}, r1 {first:.4f}, r2 {last:.4f}")
    spread = f"{max(a1s) - min(a1s):.4f}" if len(a1s) == len(names) else "–"
    print(f"| {a2:+.3f} | " + " | ".join(cells) + f" | {spread} |")
for label, of in [("first pass", first_pass), ("fine pass", lambda r: r["stages"][-1]["score"])]:
    best = {}
    for n in names:
        scored = [(of(rows[a2][n]), a2) for a2 in rows if n in rows[a2]]
        best[n] = min(scored)[1]
    print(f"\nLowest {label} residual per snapshot: " +
          ", ".join(f"{s} a2 = {best[n]:+.3f}" for s, n in zip(short, names)) + ".")
