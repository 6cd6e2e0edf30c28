#!/usr/bin/env python3
"""Along which band the blind calibration's dx–a1 errors pivot, per scene, beside where the
scene's light and texture sit among the bands.

Band k lands at dx + a1·k (the model's convention: band 0 at the mask's shift), so an error
that keeps band p's code in place has dx_err = −p·a1_err. Over the random poses of the records
given, per held-out scene: p from the least-squares fit of dx_err on a1_err (through 0), the
correlation, a1's RMSE and dx's RMSE off that line; then each scene cube's band centroids
weighted by mean brightness and by horizontal-gradient energy (every second row), read from
$CASSI_SHARED_DATA/scenes/<scene>.npy (default ../shared/data) when there.

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
        k = sum(a * b for a, b in zip(x, y)) / sum(b * b for b in y)
        mx, my = sum(x) / len(x), sum(y) / len(y)
        sxy = sum((a - mx) * (b - my) for a, b in zip(x, y))
        corr = sxy / math.sqrt(sum((a - mx) ** 2 for a in x) * sum((b - my) ** 2 for b in y))
        off = math.sqrt(sum((a - k * b) ** 2 for a, b in zip(x, y)) / len(x))
        rmse = math.sqrt(sum(b * b for b in y) / len(y))
        cube = os.path.join(data, "scenes", f"{scene}.npy")
        light = texture = ""
        if scene != "(all)" and os.path.exists(cube):
            m, g = centroids(cube)
            light, texture = f"{m:7.1f}", f"{g:8.1f}"
        print(f"{scene:<28}{len(group):>4}{-k:>7.1f}{corr:>7.3f}{rmse:>9.4f}{off:>12.3f}{light:>7}{texture:>8}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    main(sys.argv[1:])
