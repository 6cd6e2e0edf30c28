#!/usr/bin/env python3
"""The random poses' errors along the two ridges, pooled over rounds 36-46 (stop 62's estimates;
36-40 re-run at stop 62): the least-squares slope and correlation of dx's error on a1's and of
dy's on α's, leaving out the ridge slides beyond 0.5 px in dx (one here: peppers 52501, −1.53 px). Run from the
repository root:

    python3 bench/results/default_stop63/ridges.py
"""
import glob
import json

FILES = (sorted(glob.glob("bench/results/default_stop62/held_out/rerun/round*_stop62.json"))
         + ["bench/results/default_stop62/held_out/round41.json"]
         + sorted(glob.glob("bench/results/default_stop63/held_out/round4*.json")))


def fit(x, y):
    n = len(x)
    mx, my = sum(x) / n, sum(y) / n
    sxy = sum((a - mx) * (b - my) for a, b in zip(x, y))
    sxx = sum((a - mx) ** 2 for a in x)
    syy = sum((b - my) ** 2 for b in y)
    return sxy / sxx, sxy / (sxx * syy) ** 0.5


errors = [c["error"] for f in FILES for c in json.load(open(f))["cases"] if c["kind"] == "random"]
kept = [e for e in errors if abs(e["dx"]) <= 0.5]
print(f"{len(FILES)} records, {len(errors)} random poses, {len(kept)} with |dx error| <= 0.5 px")
slope, r = fit([e["a1"] for e in kept], [e["dx"] for e in kept])
print(f"dx error = {slope:.1f} x a1 error (correlation {r:.2f})")
slope, r = fit([e["alpha_deg"] for e in kept], [e["dy"] for e in kept])
print(f"dy error = {slope:.2f} px/deg x alpha error (correlation {r:.2f})")
