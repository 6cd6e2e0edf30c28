#!/usr/bin/env python3
"""How binary the mask files are: the share of each mask's values between 10 % and 90 % of its
maximum (0 for a binary code; a blurred capture of one has many), and its lag-1 autocorrelation
along rows and columns. Why: the 4× simulator renders crisp cells whose transmissions are these
values, so a smooth file makes the crisp-cell model right by construction on the benchmark, while
a real camera's physical mask is presumably a binary code whose file is its blurred image.

    python3 bench/mask_crispness.py > bench/results/mask_crispness.tsv

Needs ../shared/data and python3 with numpy and scipy.
"""
import sys

import numpy as np
import scipy.io as sio

MASKS = ["../shared/data/real/tsa_real_mask660.mat", "../shared/data/masks/tsa_simu_mask256.mat"]


def lag1(m, axis):
    a = m - m.mean()
    x, y = (a[:, :-1], a[:, 1:]) if axis == 1 else (a[:-1, :], a[1:, :])
    return float((x * y).sum() / np.sqrt((x * x).sum() * (y * y).sum()))


def main():
    print("mask\trows\tcols\tshare_in_0.1_0.9_of_max\tlag1_along_rows\tlag1_along_cols")
    for path in MASKS:
        data = sio.loadmat(path)
        name = [k for k in data if not k.startswith("__")][0]
        m = np.asarray(data[name], dtype=float)
        m = m / m.max()
        mid = float(((m > 0.1) & (m < 0.9)).mean())
        print(f"{path.split('/')[-1]}\t{m.shape[0]}\t{m.shape[1]}\t{mid:.3f}\t{lag1(m, 1):.3f}\t{lag1(m, 0):.3f}")


if __name__ == "__main__":
    sys.exit(main())
