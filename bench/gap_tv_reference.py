#!/usr/bin/env python3
"""Reference GAP-TV in plain NumPy + scikit-image, for side-by-side checks of
cassi's GAP-TV (accuracy and speed). Same algorithm, float32 throughout:

    Phi = sum_k shift_k(m^2);  inv = 1/Phi where Phi > 0 else 0
    x = A^T y;  y1 = 0
    repeat n: yh = A x;  e = y - yh
              accelerated: y1 += e; r = (y1 - yh) * inv      plain: r = e * inv
              x = max(x + A^T r, 0)
              x = denoise_tv_chambolle(x, weight, max_num_iter=inner, channel_axis=0)

Stride-2 rounded dispersion, no mismatch, no noise (the KAIST/TSA simulation protocol).
Usage: gap_tv_reference.py --scenes DIR --mask MASK.mat [--iterations 100] [--weight 0.1]
       [--inner 5] [--plain] [--out results.json]
Needs numpy, scipy, scikit-image.
"""
import argparse, glob, json, os, platform, time

import numpy as np
import scipy.io
from skimage.restoration import denoise_tv_chambolle


def forward(x, mask, step):
    L, H, W = x.shape
    y = np.zeros((H, W + (L - 1) * step), np.float32)
    for k in range(L):
        y[:, k * step:k * step + W] += mask * x[k]
    return y


def adjoint(y, mask, L, step):
    H, W = mask.shape
    return np.stack([y[:, k * step:k * step + W] * mask for k in range(L)]).astype(np.float32)


def gap_tv(y, mask, L, step, iterations, weight, inner, accelerate=True):
    phi = forward(np.ones((L,) + mask.shape, np.float32), mask * mask, step)
    inv = np.where(phi > 0, 1.0 / np.where(phi > 0, phi, 1), 0).astype(np.float32)
    x = adjoint(y, mask, L, step)
    y1 = np.zeros_like(y)
    for _ in range(iterations):
        yh = forward(x, mask, step)
        e = y - yh
        if accelerate:
            y1 += e
            r = (y1 - yh) * inv
        else:
            r = e * inv
        x = np.maximum(x + adjoint(r, mask, L, step), 0)
        x = denoise_tv_chambolle(x, weight=weight, max_num_iter=inner, channel_axis=0).astype(np.float32)
    return x


def psnr(truth, est):
    mse = np.mean((truth.astype(np.float64) - est.astype(np.float64)) ** 2)
    return float(10 * np.log10(1.0 / mse))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", required=True)
    ap.add_argument("--mask", required=True)
    ap.add_argument("--iterations", type=int, default=100)
    ap.add_argument("--weight", type=float, default=0.1)
    ap.add_argument("--inner", type=int, default=5)
    ap.add_argument("--plain", action="store_true")
    ap.add_argument("--limit", type=int, default=0, help="only the first N scenes")
    ap.add_argument("--out")
    a = ap.parse_args()
    mask = scipy.io.loadmat(a.mask)["mask"].astype(np.float32)
    rows = []
    for path in sorted(glob.glob(os.path.join(a.scenes, "*.npy")))[: a.limit or None]:
        truth = np.load(path).astype(np.float32)
        L = truth.shape[0]
        y = forward(truth, mask, 2)
        t0 = time.perf_counter()
        x = gap_tv(y, mask, L, 2, a.iterations, a.weight, a.inner, not a.plain)
        secs = time.perf_counter() - t0
        rows.append({"scene": os.path.basename(path)[:-4], "psnr": psnr(truth, np.clip(x, 0, 1)), "seconds": secs})
        print(f"{rows[-1]['scene']:<32} {rows[-1]['psnr']:7.3f} dB {secs:6.2f} s", flush=True)
    out = {
        "implementation": "numpy + scikit-image denoise_tv_chambolle",
        "numpy": np.__version__,
        "python": platform.python_version(),
        "threads_env": {k: os.environ.get(k) for k in ["OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"]},
        "settings": {"iterations": a.iterations, "weight": a.weight, "inner": a.inner, "accelerate": not a.plain},
        "scenes": rows,
        "mean_psnr": float(np.mean([r["psnr"] for r in rows])),
        "median_seconds": float(np.median([r["seconds"] for r in rows])),
    }
    if a.out:
        with open(a.out, "w") as f:
            json.dump(out, f, indent=2)
    print(f"mean PSNR {out['mean_psnr']:.3f} dB, median {out['median_seconds']:.2f} s per scene")


if __name__ == "__main__":
    main()
