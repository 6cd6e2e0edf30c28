#!/usr/bin/env python3
"""Along which band the blind calibration's dx–a1 errors pivot, per scene, beside where the
scene's light and texture sit among the bands.

Band k lands at dx + a1·k (the model's convention: band 0 at the mask's shift), so an error
that keeps band p's code in place has dx_err = −p·a1_err. Over the random poses of the records
given, per held-out scene: p from the least-squares fit of dx_err on a1_err (through 0), the
correlation, a1's RMSE and dx's RMSE off that line; then each scene cube's band centroids
weighted by mean brightness and by horizontal-gradient energy (every second row), read from
$CASSI_SHARED_DATA/scenes/<scene>.npy (default ../shared/data) when there. Then the same pivot
at each stage's answer (the records' `stages`), all scenes together: where it appears. Last,
the error of where bands 0 (dx itself), 13.5 and 27 land (dx_err + k·a1_err): RMSE and the
count within 0.05 px.

    python3 bench/dx_a1_pivot.py RECORD.json [RECORD.json ...]
"""
import ast
import json
import math
import os
import struct
import sys
from array import array
from collections import defaultdict


def npy_float32(path):
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":
            raise SystemExit(f"{path}: not a .npy file")
        major = f.read(2)[0]
        header_len = struct.unpack("<H" if major == 1 else "<I", f.read(2 if major == 1 else 4))[0]
        header = ast.literal_eval(f.read(header_len).decode())
        if header["descr"] != "<f4" or header["fortran_order"]:
            raise SystemExit(f"{path}: dtype {header['descr']}, want C-ordered <f4")
        data = array("f")
        data.frombytes(f.read())
    return header["shape"], data


def centroids(path):
    (bands, rows, cols), a = npy_float32(path)
    n = rows * cols
    mean, grad = [], []
    for k in range(bands):
        band = a[k * n:(k + 1) * n]
        mean.append(sum(band) / n)
        g = 0.0
        for r in range(0, rows, 2):
            row = band[r * cols:(r + 1) * cols]
            g += sum((row[i + 1] - row[i]) ** 2 for i in range(cols - 1))
        grad.append(g)
    at = lambda w: sum(k * v for k, v in enumerate(w)) / sum(w)
    return at(mean), at(grad)


def pivot(x, y):
    """p with dx_err ≈ −p·a1_err (least squares through 0)."""
    return -sum(a * b for a, b in zip(x, y)) / sum(b * b for b in y)


def rms(v):
    return math.sqrt(sum(a * a for a in v) / len(v))


def stages(cases):
    errors = defaultdict(lambda: ([], []))
    order = []
    for c in cases:
        for st in c.get("stages", []):
            name = st["name"]
            if name not in order:
                order.append(name)
            errors[name][0].append(st["parameters"]["dx"] - c["truth"]["dx"])
            errors[name][1].append(st["parameters"]["a1"] - c["truth"]["a1"])
    print("\nat each stage's answer (all scenes):")
    print(f"{'stage':<62}{'n':>4}{'pivot':>7}{'a1 RMSE':>9}{'dx RMSE':>9}{'dx ≤ 0.05':>10}")
    for name in order:
        x, y = errors[name]
        within = sum(1 for a in x if abs(a) <= 0.05)
        print(f"{name[:61]:<62}{len(x):>4}{pivot(x, y):>7.1f}{rms(y):>9.4f}{rms(x):>9.3f}{within:>10}")


def main(paths):
    cases = [c for p in paths for c in json.load(open(p))["cases"] if c["kind"] == "random"]
    if not cases:
        raise SystemExit("no random-pose cases in the records given")
    data = os.environ.get("CASSI_SHARED_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data"))
    by = defaultdict(list)
    for c in cases:
        by[c["scene"]].append(c)
    print(f"{len(cases)} random poses; pivot p: dx_err ≈ −p·a1_err")
    print(f"{'scene':<28}{'n':>4}{'pivot':>7}{'corr':>7}{'a1 RMSE':>9}{'dx off-line':>12}{'light':>7}{'texture':>8}")
    for scene in sorted(by) + ["(all)"]:
        group = cases if scene == "(all)" else by[scene]
        x = [c["error"]["dx"] for c in group]
        y = [c["error"]["a1"] for c in group]
        p = pivot(x, y)
        mx, my = sum(x) / len(x), sum(y) / len(y)
        sxy = sum((a - mx) * (b - my) for a, b in zip(x, y))
        corr = sxy / math.sqrt(sum((a - mx) ** 2 for a in x) * sum((b - my) ** 2 for b in y))
        off = rms([a + p * b for a, b in zip(x, y)])
        rmse = rms(y)
        cube = os.path.join(data, "scenes", f"{scene}.npy")
        light = texture = ""
        if scene != "(all)" and os.path.exists(cube):
            m, g = centroids(cube)
            light, texture = f"{m:7.1f}", f"{g:8.1f}"
        print(f"{scene:<28}{len(group):>4}{p:>7.1f}{corr:>7.3f}{rmse:>9.4f}{off:>12.3f}{light:>7}{texture:>8}")
    stages(cases)
    print("\nwhere a band lands, dx_err + k·a1_err (all scenes):")
    for k in (0.0, 13.5, 27.0):
        e = [c["error"]["dx"] + k * c["error"]["a1"] for c in cases]
        within = sum(1 for v in e if abs(v) <= 0.05)
        print(f"  band {k:>4}: RMSE {rms(e):.3f} px, within 0.05 px {within} of {len(e)}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    main(sys.argv[1:])
