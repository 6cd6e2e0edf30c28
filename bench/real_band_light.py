#!/usr/bin/env python3
"""Light per band of reconstructed cubes, relative to each cube's mean, and their mean profile.

    python3 bench/real_band_light.py OUT.json CUBE.npy [CUBE.npy …]

CUBE.npy: float32 (bands, rows, cols), as `cassi reconstruct` writes it. Writes, per cube, each
band's mean over the cube's mean, and the mean of those profiles over the cubes scaled to its
last band (the bench's `REAL_BAND_LIGHT`, `--scene-transform real-band-light`). Pure Python (no
numpy on a fresh machine): reads the .npy header and data itself.
"""

import array
import ast
import json
import os
import struct
import sys


def load(path):
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":
            sys.exit(f"{path}: not a .npy file")
        major = f.read(2)[0]
        size = struct.unpack("<H" if major == 1 else "<I", f.read(2 if major == 1 else 4))[0]
        header = ast.literal_eval(f.read(size).decode())
        if header["descr"] != "<f4" or header["fortran_order"] or len(header["shape"]) != 3:
            sys.exit(f"{path}: wanted a C-order float32 (bands, rows, cols) array, got {header}")
        data = array.array("f")
        data.frombytes(f.read())
    return header["shape"], data


def profile(path):
    (bands, rows, cols), data = load(path)
    n = rows * cols
    means = [sum(data[k * n : (k + 1) * n]) / n for k in range(bands)]
    mean = sum(means) / bands
    return [m / mean for m in means]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out, cubes = sys.argv[1], sys.argv[2:]
    profiles = {os.path.basename(p): profile(p) for p in cubes}
    bands = len(next(iter(profiles.values())))
    average = [sum(p[k] for p in profiles.values()) / len(profiles) for k in range(bands)]
    relative = [v / average[-1] for v in average]
    record = {"per_cube": profiles, "mean_relative_to_last_band": relative}
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(record, f, indent=1)
    os.replace(tmp, out)
    print(", ".join(f"{v:.3f}" for v in relative))


if __name__ == "__main__":
    main()
