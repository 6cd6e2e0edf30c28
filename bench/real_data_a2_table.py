"""The real snapshots' a2 profile (bench/real_data_a2.sh): per held curvature
a2, each snapshot's a1, dx and residuals, and a1's spread across the
snapshots. Usage: real_data_a2_table.py FOLDER > README.md"""
import glob
import json
import os
import sys

folder = sys.argv[1]
RESTART = "curved dispersion:"  # calib::NOMINAL_A1_RESTART_STAGE's opening


def stage(rec, opening):
    return next((s for s in rec["stages"] if s["name"].startswith(opening)), None)


def kept_restart(rec):
    """Whether a held curvature's restart from the nominal a1 (stop 33) kept
    its own answer: then the file's first-pass and fine-pass stages are the
    passed-over run's, and its residuals are not the answer's."""
    chose, fine = stage(rec, RESTART), stage(rec, "scene fit's fine pass")
    return chose is not None and fine is not None and chose["parameters"] != fine["parameters"]


def first_pass(rec):
    """The scene fit's first pass's objective (its stage is named so)."""
    return None if kept_restart(rec) else stage(rec, "scene fit (")["score"]


def fine_pass(rec):
    """The fine pass's (ridge-penalised) objective at its answer."""
    return None if kept_restart(rec) else stage(rec, "scene fit's fine pass")["score"]


def fmt(r):
    return "–" if r is None else f"{r:.4f}"


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
print("comparable between a2 values on one snapshot (not between the two). Since stop 33 a")
print("held curvature also runs the fits from the nominal a1 and keeps the answer whose")
print("first-pass objective (coarse scene solved cold) is lower: r0 is that objective at the kept")
print("answer (curved rows only); \"restart kept\" marks a cell whose answer came from that second")
print("run, whose own r1 / r2 the file does not hold (–). ± is the stated standard error, which")
print("carries the two runs' disagreement.")
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
        chose = stage(rec, RESTART)
        r0 = f", r0 {chose['score']:.4f}" if chose else ""
        which = ", restart kept" if kept_restart(rec) else ""
        cells.append(f"a1 {p['a1']:.4f} ± {rec['uncertainty'].get('a1') or float('nan'):.4f}, "
                     f"dx {p['dx']:+.2f}{which}, r1 {fmt(first_pass(rec))}, "
                     f"r2 {fmt(fine_pass(rec))}{r0}")
    spread = f"{max(a1s) - min(a1s):.4f}" if len(a1s) == len(names) else "–"
    print(f"| {a2:+.3f} | " + " | ".join(cells) + f" | {spread} |")
for label, of in [("first pass", first_pass), ("fine pass", fine_pass)]:
    best = {}
    for n in names:
        scored = [(of(rows[a2][n]), a2) for a2 in rows if n in rows[a2]]
        known = [(r, a2) for r, a2 in scored if r is not None]
        best[n] = f"{min(known)[1]:+.3f}" if known else "–"
        if len(known) < len(scored):
            best[n] += f" (of {len(known)} a2 values with it)"
    print(f"\nLowest {label} residual per snapshot: " +
          ", ".join(f"{s} a2 = {best[n]}" for s, n in zip(short, names)) + ".")
curved = [a2 for a2 in rows if a2 != 0]
best = {}
for n in names:
    scored = [(stage(rows[a2][n], RESTART)["score"], a2) for a2 in curved
              if n in rows[a2] and stage(rows[a2][n], RESTART)]
    best[n] = f"{min(scored)[1]:+.3f}" if scored else "–"
print("\nLowest r0 (the restart's choosing objective, curved rows) per snapshot: " +
      ", ".join(f"{s} a2 = {best[n]}" for s, n in zip(short, names)) + ".")
