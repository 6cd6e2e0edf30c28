#!/usr/bin/env python3
"""Probe (stop 40): does a scene's fine texture tell where the opt-in blur pass helps?

Per scene: the high-passed luminance's standard deviation over its mean (luminance = the
band mean; high pass = minus a 1-px Gaussian), from the TRUE scene — an oracle statistic, a
feasibility check for a blind rule, not one — beside the blur pass's mean change of |σ error| on
the random poses of the records that ran it (the stage before the pass is the default's answer).

    python3 bench/blur_pass_texture_probe.py SCENE_DIR [SCENE_DIR ...] > bench/results/blur_pass_texture_probe.tsv

SCENE_DIRs hold the scenes as (bands, rows, cols) .npy: ../shared/data/scenes (CAVE) and the
real-content crops that bench/real_content_benchmark.sh builds (a_*/b_*; its temporary folder,
or the same steps by hand with bench/real_content.py).
"""
import glob
import json
import sys

import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from held_out_pool import before_blur_pass  # noqa: E402  (the default's answer)
from real_content import smooth  # noqa: E402  (the same 1-px Gaussian)

RECORDS = [
    "bench/results/calibrate_physical_held_out_round12_blur_pass.json",
    "bench/results/calibrate_physical_held_out_round17_blur_pass.json",
    "bench/results/calibrate_physical_real_content_blur_pass.json",
]


def texture(path):
    lum = np.load(path).mean(0)
    high = lum - smooth(lum[None])[0]
    return float(high.std() / lum.mean())


def gains():
    out = {}
    for path in RECORDS:
        record = json.load(open(path))
        for c in record["cases"]:
            if c["kind"] != "random":
                continue
            default = before_blur_pass(c, record["tolerances"])
            if default is c:  # no blur pass in this case
                continue
            change = abs(c["error"]["blur_sigma_px"]) - abs(default["error"]["blur_sigma_px"])
            out.setdefault(c["scene"], []).append(change)
    return out


def main(dirs):
    if not dirs:
        sys.exit(__doc__)
    tex = {}
    for d in dirs:
        for path in sorted(glob.glob(f"{d}/*.npy")):
            tex[path.rsplit("/", 1)[1][:-4]] = texture(path)
    g = gains()
    print("scene\ttexture\tblur_pass_abs_sigma_error_change_mean_px\trandom_cases")
    for name in sorted(tex, key=tex.get):
        v = g.get(name)
        print(f"{name}\t{tex[name]:.4f}\t{'' if not v else f'{np.mean(v):+.4f}'}\t{len(v) if v else 0}")


if __name__ == "__main__":
    main(sys.argv[1:])
