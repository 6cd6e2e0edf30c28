#!/usr/bin/env python3
"""How closely a few spectral functions hold each CAVE scene's spectra: the relative RMS of
what the least-squares fit through them leaves (‖X − P X‖ / ‖X‖ over every 7th pixel's
28-band spectrum), for the coarse scene's evenly spaced nodes (piecewise linear, 6 and 10:
`calib::CoarseScene`), 6 clamped cubic B-splines, and the scene's own 6 uncentred principal
spectra (the true cube's: what `calib::SpectralBasis` takes from GAP-TV's reconstruction could
at best reach). Why (stop 60): is there a basis with 6 functions that holds the spectra as 10
nodes do?

    python3 bench/spectral_basis_fit.py > bench/results/default_stop60/spectral_basis_fit.tsv

Needs ../shared/data and python3 with numpy.
"""
import glob
import os

import numpy as np

BANDS = 28


def nodes(n):
    """Piecewise linear between n evenly spaced band nodes (CoarseScene's band taps)."""
    b = np.zeros((BANDS, n))
    for k in range(BANDS):
        t = k * (n - 1) / (BANDS - 1)
        j = min(int(np.floor(t)), n - 2)
        f = t - j
        b[k, j] += 1 - f
        b[k, j + 1] += f
    return b


def bsplines(n, degree=3):
    """n clamped uniform B-splines of the degree over the band index."""
    inner = n - degree - 1
    knots = np.concatenate([[0] * (degree + 1), np.linspace(0, BANDS - 1, inner + 2)[1:-1],
                            [BANDS - 1] * (degree + 1)])
    x = np.arange(BANDS, dtype=float)

    def basis(i, p):
        if p == 0:
            r = ((knots[i] <= x) & (x < knots[i + 1])).astype(float)
            if knots[i + 1] == BANDS - 1 and knots[i] < knots[i + 1]:
                r[x == BANDS - 1] = 1.0
            return r
        a = 0 if knots[i + p] == knots[i] else (x - knots[i]) / (knots[i + p] - knots[i]) * basis(i, p - 1)
        c = 0 if knots[i + p + 1] == knots[i + 1] else \
            (knots[i + p + 1] - x) / (knots[i + p + 1] - knots[i + 1]) * basis(i + 1, p - 1)
        return a + c
    return np.stack([basis(i, degree) for i in range(n)], 1)


def left_out(x, b):
    r = x - b @ np.linalg.pinv(b) @ x
    return float(np.sqrt((r ** 2).sum() / (x ** 2).sum()))


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    scenes = sorted(glob.glob(os.path.join(here, "../../shared/data/scenes/cave_*.npy")))
    print("scene\tnodes6\tnodes10\tbsplines6\tprincipal6")
    for path in scenes:
        x = np.load(path).reshape(BANDS, -1)[:, ::7].astype(np.float64)
        u = np.linalg.svd(x, full_matrices=False)[0]
        row = [left_out(x, nodes(6)), left_out(x, nodes(10)), left_out(x, bsplines(6)),
               left_out(x, u[:, :6])]
        name = os.path.basename(path)[len("cave_"):-len(".npy")]
        print(name + "\t" + "\t".join(f"{v:.4f}" for v in row))


if __name__ == "__main__":
    main()
