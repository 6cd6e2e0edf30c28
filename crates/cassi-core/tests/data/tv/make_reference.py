#!/usr/bin/env python3
"""Reference outputs of scikit-image's Chambolle TV denoiser for cassi's
TvChambolle2d / TvChambolle3d.

Run with the project's reference venv (numpy 2.x, scikit-image 0.26):

    /work/pyref/bin/python crates/cassi-core/tests/data/tv/make_reference.py

Writes reference.json next to this script. Every array (inputs and outputs)
is float32, stored EXACTLY as a string of 8-hex-digit big-endian IEEE-754 bit
patterns, row-major, shape (bands, rows, cols). Inputs are textured scenes plus
Gaussian noise, values q / 2**20 in [0, 1].

Cases:
- "2d":  skimage.restoration.denoise_tv_chambolle(x, weight=w, eps=2e-4,
         max_num_iter=n, channel_axis=0)  (each band on its own, its own stop)
- "3d":  the same with channel_axis=None on the whole float32 cube: isotropic
         TV over (band, row, col) = cassi's TvChambolle3d, spectral weight 1.

The weight is passed as float(np.float32(w)) so that Python and Rust use the
same number. `iterations` is how many passes of skimage's while loop ran (per
band for "2d", one number for "3d"), counted from np.diff calls (ndim per
pass); the stopping rule shows up as a count below max_num_iter.
"""

import json
import os

import numpy as np
import skimage
from skimage.restoration import denoise_tv_chambolle

SCALE = 2**20


def hexf32(a):
    a = np.ascontiguousarray(a, dtype=np.float32)
    return a.astype(">f4").tobytes().hex()


def scene(rng, bands, rows, cols, noise):
    r = np.arange(rows)[:, None]
    c = np.arange(cols)[None, :]
    out = np.empty((bands, rows, cols))
    f1, f2 = rng.uniform(0.15, 0.6, 2)
    for k in range(bands):
        s = 0.5 + 0.3 * np.sin(f1 * r + 0.4 * k) * np.cos(f2 * c - 0.2 * k)
        s += 0.25 * ((r // 7 + c // 9 + k) % 2)  # piecewise-constant patches
        out[k] = s + noise * rng.standard_normal((rows, cols))
    out = np.clip(out, 0.0, 1.0)
    q = np.round(out * SCALE)
    return (q / SCALE).astype(np.float32)


class DiffCounter:
    """Counts np.diff calls made by skimage's _denoise_tv_chambolle_nd."""

    def __init__(self):
        self.calls = 0
        self.orig = np.diff

    def __enter__(self):
        def counted(*a, **k):
            self.calls += 1
            return self.orig(*a, **k)

        np.diff = counted
        return self

    def __exit__(self, *exc):
        np.diff = self.orig


def run_2d(x, w, n):
    iters = []
    out = np.empty_like(x)
    for b in range(x.shape[0]):
        with DiffCounter() as dc:
            out[b] = denoise_tv_chambolle(
                x[b : b + 1], weight=w, eps=2e-4, max_num_iter=n, channel_axis=0
            )[0]
        iters.append(dc.calls // 2)
    # the whole-cube call with channel_axis=0 must give the same thing
    full = denoise_tv_chambolle(x, weight=w, eps=2e-4, max_num_iter=n, channel_axis=0)
    assert full.dtype == np.float32
    assert np.array_equal(full, out)
    return out, iters


def run_3d(x, w, n):
    with DiffCounter() as dc:
        out = denoise_tv_chambolle(x, weight=w, eps=2e-4, max_num_iter=n)
    assert out.dtype == np.float32
    return out, dc.calls // 3


def main():
    rng = np.random.default_rng(7)
    inputs = {
        "a": scene(rng, 3, 32, 40, 0.08),
        "b": scene(rng, 2, 17, 23, 0.15),
    }
    plan = [
        ("a", "2d", 0.1, 5),
        ("a", "2d", 0.5, 5),
        ("a", "2d", 0.05, 200),
        ("a", "2d", 2.0, 60),
        ("a", "3d", 0.1, 200),
        ("b", "2d", 0.1, 5),
        ("b", "2d", 0.3, 200),
        ("b", "3d", 0.2, 8),
    ]
    cases = []
    for name, kind, w, n in plan:
        x = inputs[name]
        w = float(np.float32(w))
        if kind == "2d":
            out, iters = run_2d(x, w, n)
        else:
            out, iters = run_3d(x, w, n)
        diff = float(np.abs(out - x).max())
        print(f"{name} {kind} w={w:.6g} n={n}: iterations {iters}, max|out-in| {diff:.4f}")
        cases.append(
            {
                "input": name,
                "kind": kind,
                "weight": w,
                "max_iter": n,
                "eps": 2e-4,
                "iterations": iters,
                "output_hex": hexf32(out),
            }
        )
    ref = {
        "generator": f"make_reference.py, numpy {np.__version__}, scikit-image {skimage.__version__}",
        "inputs": {
            k: {"shape": list(v.shape), "hex": hexf32(v)} for k, v in inputs.items()
        },
        "cases": cases,
    }
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "reference.json")
    with open(path, "w") as fh:
        json.dump(ref, fh, indent=1)
        fh.write("\n")
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")


if __name__ == "__main__":
    main()
