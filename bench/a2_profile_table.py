"""The calibration bench's records with the curvature held at several a2 on
one simulated instrument (`--model-a2`, with or without `--dispersion-a2`):
per case, the scene fit's first-pass (r1) and fine-pass (r2) residuals and
a1's error at each held a2; which a2 each residual prefers; a1's spread.

Usage: a2_profile_table.py TRUE_A2 A2=RECORD [A2=RECORD ...]"""
import json
import sys

true_a2 = float(sys.argv[1])
runs = []
for arg in sys.argv[2:]:
    a2, path = arg.split("=", 1)
    with open(path) as f:
        runs.append((float(a2), json.load(f)))
runs.sort(key=lambda r: r[0])


def stage_score(case, prefix):
    for s in case["stages"]:
        if s["name"].startswith(prefix):
            return s["score"]
    return float("nan")


def r1(case):
    return stage_score(case, "scene fit (")


def r2(case):
    return case["stages"][-1]["score"]


cases = runs[0][1]["cases"]
print(f"true curvature {true_a2:+.3f} px/band²; held: " + ", ".join(f"{a:+.3f}" for a, _ in runs))
print(f"{'case':<26}" + "".join(f"{a:>+28.3f}" for a, _ in runs))
wins = {"r1": 0, "r2": 0}
for i, c in enumerate(cases):
    label = f"{c['scene'][5:17]} σ {c['truth']['blur_sigma_px']:.2f}"
    cells = []
    for a, rec in runs:
        cc = rec["cases"][i]
        assert cc["scene"] == c["scene"] and cc["seed"] == c["seed"]
        cells.append(f"r1 {r1(cc):.4f} r2 {r2(cc):.4f} a1 {cc['error']['a1']:+.4f}")
    print(f"{label:<26}" + "".join(f"{x:>28}" for x in cells))
    for key, f in [("r1", r1), ("r2", r2)]:
        best = min(runs, key=lambda r: f(r[1]["cases"][i]))[0]
        wins[key] += best == true_a2
n = len(cases)
print(f"\nthe true a2 has the lowest residual: first pass {wins['r1']} / {n}, fine pass {wins['r2']} / {n}")
for a, rec in runs:
    e = [c["error"]["a1"] for c in rec["cases"]]
    rms = (sum(x * x for x in e) / len(e)) ** 0.5
    print(f"held a2 {a:+.3f}: a1 error {min(e):+.4f} … {max(e):+.4f} (spread {max(e) - min(e):.4f}, RMS {rms:.4f})")
