#!/usr/bin/env python3
"""Reference values for cassi_core::metrics, from scikit-image / numpy.

Run with the project's reference venv (numpy, scipy, scikit-image):

    /work/pyref/bin/python crates/cassi-core/tests/data/metrics/make_reference.py

Writes reference.json next to this script. Each case holds a truth and an
estimate cube of shape (bands, rows, cols), stored as flat row-major lists of
integers q with value = q / 2**20 (exact in f32 and f64, so Rust and Python see
identical inputs; estimates may be negative or above 1 — metrics do not clip).
The references are computed in float64 on those exact values:

- psnr:            skimage.metrics.peak_signal_noise_ratio(data_range=1), whole cube
- psnr_per_band:   the same per band; psnr_band_mean is their mean
- ssim_per_band:   skimage.metrics.structural_similarity(data_range=1.0,
                   gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
- sam_deg:         mean over pixels with both spectra non-zero of
                   degrees(arccos(clip(t.e / (|t| |e|), -1, 1))), in long double
"""

import json
import os

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

SCALE = 2**20


def quantize(a):
    return np.round(np.asarray(a, dtype=np.float64) * SCALE).astype(np.int64)


def smooth_scene(rng, bands, rows, cols):
    """Smooth spatial structure with band-dependent spectra, plus texture."""
    r = np.arange(rows)[:, None]
    c = np.arange(cols)[None, :]
    out = np.empty((bands, rows, cols))
    f1, f2 = rng.uniform(0.1, 0.5, 2)
    for k in range(bands):
        s = 0.5 + 0.3 * np.sin(f1 * r + 0.4 * k) * np.cos(f2 * c - 0.2 * k)
        out[k] = s + 0.08 * rng.standard_normal((rows, cols))
    return np.clip(out, 0.0, 1.0)


def make_cases():
    rng = np.random.default_rng(20240611)
    cases = []

    # 1. Textured truth; estimate = truth + structured error + noise, clipped.
    L, H, W = 3, 24, 31
    t = smooth_scene(rng, L, H, W)
    rr, cc = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    err = np.stack(
        [0.05 * np.sin(0.3 * cc + k) + 0.03 * (rr / H - 0.5) for k in range(L)]
    )
    e = np.clip(0.9 * t + 0.04 + err + 0.03 * rng.standard_normal(t.shape), 0, 1)
    cases.append(("textured_3x24x31", t, e))

    # 2. Uniform random truth, heavy noise.
    t = rng.uniform(0, 1, (5, 16, 16))
    e = np.clip(t + 0.15 * rng.standard_normal(t.shape), 0, 1)
    cases.append(("random_5x16x16", t, e))

    # 3. Zero-spectrum pixels in truth, estimate, both; unclipped estimate
    #    with values outside [0, 1] and one sign-flipped spectrum.
    L, H, W = 4, 20, 17
    t = smooth_scene(rng, L, H, W)
    e = t + 0.1 * rng.standard_normal(t.shape)  # not clipped
    t[:, 0, 0:3] = 0.0  # truth zero
    e[:, 1, 4:6] = 0.0  # estimate zero
    t[:, 2, 7] = 0.0  # both zero
    e[:, 2, 7] = 0.0
    e[:, 5, 5] = -t[:, 5, 5]  # opposite spectrum: 180 degrees
    e[:, 6, 6] = 3.0 * t[:, 6, 6]  # scaled spectrum: 0 degrees
    cases.append(("zeros_unclipped_4x20x17", t, e))

    # 4. Minimum SSIM size: 11 rows, so the cropped SSIM map has one row.
    t = smooth_scene(rng, 2, 11, 13)
    e = np.clip(t + 0.05 * rng.standard_normal(t.shape), 0, 1)
    cases.append(("minimal_2x11x13", t, e))

    # 5. Some bands exact: per-band PSNR infinite in band 0 (written as null).
    t = smooth_scene(rng, 3, 12, 12)
    e = t.copy()
    e[1:] = np.clip(e[1:] + 0.02 * rng.standard_normal(e[1:].shape), 0, 1)
    cases.append(("exact_band_3x12x12", t, e))

    return cases


def sam_deg(t, e):
    t = t.astype(np.longdouble)
    e = e.astype(np.longdouble)
    dot = (t * e).sum(axis=0)
    nt = np.sqrt((t * t).sum(axis=0))
    ne = np.sqrt((e * e).sum(axis=0))
    valid = (nt > 0) & (ne > 0)
    if not valid.any():
        return 0.0
    cos = np.clip(dot[valid] / (nt[valid] * ne[valid]), -1, 1)
    return float(np.degrees(np.arccos(cos)).mean())


def finite_or_none(v):
    v = float(v)
    return v if np.isfinite(v) else None


def reference(name, tq, eq):
    t = tq.astype(np.float64) / SCALE
    e = eq.astype(np.float64) / SCALE
    L = t.shape[0]
    with np.errstate(divide="ignore"):
        psnr = peak_signal_noise_ratio(t, e, data_range=1)
        per_band = [peak_signal_noise_ratio(t[k], e[k], data_range=1) for k in range(L)]
    ssim = [
        structural_similarity(
            t[k],
            e[k],
            data_range=1.0,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
        )
        for k in range(L)
    ]
    return {
        "name": name,
        "shape": list(t.shape),
        "truth_q": tq.ravel().tolist(),
        "estimate_q": eq.ravel().tolist(),
        "psnr": finite_or_none(psnr),
        "psnr_per_band": [finite_or_none(p) for p in per_band],
        "psnr_band_mean": finite_or_none(np.mean(per_band)),
        "ssim_per_band": [float(s) for s in ssim],
        "ssim": float(np.mean(ssim)),
        "sam_deg": sam_deg(t, e),
    }


def main():
    out = []
    for name, t, e in make_cases():
        out.append(reference(name, quantize(t), quantize(e)))
    doc = {
        "generator": "make_reference.py",
        "scale": SCALE,
        "versions": {
            "numpy": np.__version__,
            "scipy": __import__("scipy").__version__,
            "skimage": __import__("skimage").__version__,
        },
        "cases": out,
    }
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "reference.json")
    with open(path, "w") as f:
        json.dump(doc, f, separators=(",", ":"))
        f.write("\n")
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")
    for c in out:
        print(c["name"], c["psnr"], c["psnr_band_mean"], c["ssim"], c["sam_deg"])


if __name__ == "__main__":
    main()
