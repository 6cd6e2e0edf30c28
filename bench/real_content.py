#!/usr/bin/env python3
"""Scenes with the real TSA snapshots' content, from their GAP-TV reconstructions
(`cassi reconstruct … --calibration <name>.default.calib.json`), for the
controls that test the calibration on that content at a known ψ.

    real_content.py scene RECON.npy OUT.npy [--smooth]
        the reconstruction clipped to [0, its 99.9th percentile] (GAP-TV's few edge
        outliers would set the scale) and scaled to [0, 1]; --smooth: then a 1-px
        Gaussian over rows and columns (edges replicated): a reconstruction carries
        the mask's imprint at the ψ it was made with, which would draw a fit toward
        that ψ; at the pixel scale the Gaussian attenuates it over 100-fold
    real_content.py crops SCENE.npy OUTDIR NAME
        two 256×256 crops over the middle of the frame, where the objects are (the
        corners are dark background) — rows 100…356 × columns 250…506
        (OUTDIR/a_NAME.npy) and rows 200…456 × columns 150…406 (OUTDIR/b_NAME.npy),
        overlapping by 156×156 — each divided by its maximum, as the CAVE scenes are
    real_content.py psi CALIB.json [--offset]
        the calibration's ψ as `cassi simulate` flags; --offset: moved by dx +0.35 px,
        dy −0.25 px, θ +0.02°, a1 +0.012, α −0.2° (off the reconstruction's ψ)
"""
import json
import sys

import numpy as np

CROPS = (("a", (100, 250)), ("b", (200, 150)))  # (first row, first column)
CROP = 256
OFFSET = (("dx", 0.35), ("dy", -0.25), ("theta_deg", 0.02), ("a1", 0.012), ("alpha_deg", -0.2))


def smooth(cube):
    """A 1-px Gaussian over the last two axes, edges replicated."""
    x = np.arange(-4, 5)
    g = np.exp(-0.5 * x**2)
    g /= g.sum()
    for axis in (1, 2):
        pad = [(0, 0)] * cube.ndim
        pad[axis] = (4, 4)
        padded = np.pad(cube, pad, mode="edge")
        n = cube.shape[axis]
        cube = sum(w * np.take(padded, range(i, i + n), axis=axis) for i, w in enumerate(g))
    return cube


def scene(recon, out, smoothed):
    cube = np.load(recon)
    if cube.ndim != 3:
        sys.exit(f"{recon}: a (bands, rows, cols) cube expected, got shape {cube.shape}")
    top = np.percentile(cube, 99.9)
    cube = np.clip(cube, 0, top) / top
    if smoothed:
        cube = smooth(cube)
    np.save(out, cube.astype(np.float32))


def crops(path, outdir, name):
    cube = np.load(path)
    for tag, (row, col) in CROPS:
        if cube.shape[1] < row + CROP or cube.shape[2] < col + CROP:
            sys.exit(f"{path}: shape {cube.shape} is too small for a {CROP}² crop at {row, col}")
        c = cube[:, row:row + CROP, col:col + CROP]
        np.save(f"{outdir}/{tag}_{name}.npy", (c / c.max()).astype(np.float32))


def psi(calib, offset):
    p = json.load(open(calib))["parameters"]
    if offset:
        for key, off in OFFSET:
            p[key] += off
    print(f"--dx {p['dx']:.4f} --dy {p['dy']:.4f} --theta {p['theta_deg']:.4f} --a1 {p['a1']:.4f}"
          f" --alpha {p['alpha_deg']:.3f} --blur {p['blur_sigma_px']:.3f}")


def main(argv):
    match argv:
        case ["scene", recon, out, *flag] if flag in ([], ["--smooth"]):
            scene(recon, out, flag == ["--smooth"])
        case ["crops", path, outdir, name]:
            crops(path, outdir, name)
        case ["psi", calib, *flag] if flag in ([], ["--offset"]):
            psi(calib, flag == ["--offset"])
        case _:
            sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
