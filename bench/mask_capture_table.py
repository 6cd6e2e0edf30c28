#!/usr/bin/env python3
"""The captured-mask instrument's figures (the calibrate benchmark's `--mask-capture SIGMA_PX`).

There the instrument carries a binary code (the mask file thresholded at half its maximum,
rendered crisp) and the calibration is handed that code blurred by a Gaussian of SIGMA_PX, as a
camera's mask file is an image of its code. The model's blur σ then stands for the blur beyond
the file's own: for a smooth scene the model's code, blurred by σ_c and then by σ, matches the
instrument's, blurred by σ_o, when σ = σ_eff = sqrt(max(σ_o² − σ_c², 0)) — an approximation (the
instrument blurs the scene too, and the code's cells are crisp), so σ's figures against it are
indicative. Prints, per record and kind (random poses, aligned-with-blur): the five geometric
parameters all within the issue's tolerances, their RMSE, σ − σ_eff before and after the blur
pass (the stage before it, and the answer), and the 95 % intervals' coverage of all five.
A record made since stop 43 carries the exact reference per case (`sigma_reference`: the σ the
model fits with the true scene and geometry known); then σ is judged against it (σ_ref below),
the approximation's distance from it is printed, and so is σ's own 95 % coverage. A record
made with --recon adds GAP-TV's PSNR with the answer before the blur pass and with it.

    python3 bench/mask_capture_table.py RECORD.json@SIGMA_C [RECORD.json@SIGMA_C ...]
    (SIGMA_C 0 for a record of the standard instrument: σ_eff = σ_o)
"""
import json
import math
import sys

TOL = {"dx": .05, "dy": .05, "theta_deg": .05, "a1": .005, "alpha_deg": .1, "blur_sigma_px": .05}
GEOMETRY = ["dx", "dy", "theta_deg", "a1", "alpha_deg"]
BLUR_PASS_STAGE = "blur pass"  # the start of the pass's stage name (calib::BLUR_PASS_STAGE)


def rms(xs):
    return math.sqrt(sum(x * x for x in xs) / len(xs))


def reference(case, sigma_c):
    """σ's reference and whether it is the record's exact one."""
    exact = case.get("sigma_reference")
    if exact is not None:
        return exact, True
    so = case["truth"]["blur_sigma_px"]
    return math.sqrt(max(so * so - sigma_c * sigma_c, 0.0)), False


def approximation(case, sigma_c):
    """σ_eff from the instrument's σ (the record's own when it has one)."""
    so = case.get("instrument_blur_sigma_px", case["truth"]["blur_sigma_px"])
    return math.sqrt(max(so * so - sigma_c * sigma_c, 0.0))


def sigma_errors(case, sigma_c):
    """σ − its reference before the blur pass and at the answer."""
    ref, _ = reference(case, sigma_c)
    names = [s["name"] for s in case["stages"]]
    passes = [i for i, n in enumerate(names) if n.startswith(BLUR_PASS_STAGE)]
    before = case["stages"][passes[0] - 1]["parameters"] if passes else case["estimate"]
    return abs(before["blur_sigma_px"]) - ref, case["estimate"]["blur_sigma_px"] - ref


def table(path, sigma_c):
    cases = [c for c in json.load(open(path))["cases"] if c["kind"] in ("random", "aligned_blur")]
    print(f"{path} (σ_c {sigma_c})")
    for kind in ("random", "aligned_blur"):
        k = [c for c in cases if c["kind"] == kind]
        if not k:
            continue
        geometry = [all(abs(c["error"][p]) <= TOL[p] for p in GEOMETRY) for c in k]
        covered = sum(all(abs(c["error"][p]) <= c["interval_95"][p] for p in GEOMETRY) for c in k)
        before, after = zip(*(sigma_errors(c, sigma_c) for c in k))
        six = sum(g and abs(s) <= TOL["blur_sigma_px"] for g, s in zip(geometry, after))
        within = lambda xs: sum(abs(x) <= TOL["blur_sigma_px"] for x in xs)
        exact = [reference(c, sigma_c)[1] for c in k]
        name = "σ_ref" if all(exact) else "σ_eff"
        print(f"  {kind:13s} n {len(k)}: geometry within {sum(geometry)}, 95 % covers it {covered}; "
              f"σ − {name} before the pass RMSE {rms(before):.3f} (within {within(before)}), "
              f"after RMSE {rms(after):.3f} mean {sum(after) / len(after):+.3f} (within {within(after)}); "
              f"all six against {name} {six}")
        if all(exact):
            gap = [approximation(c, sigma_c) - reference(c, sigma_c)[0] for c in k]
            sigma_covered = sum(abs(s) <= c["interval_95"]["blur_sigma_px"] for s, c in zip(after, k))
            print(f"    σ's 95 % interval covers σ_ref {sigma_covered}; σ_eff − σ_ref mean "
                  f"{sum(gap) / len(gap):+.3f}, range {min(gap):+.3f} … {max(gap):+.3f}")
        print("    RMSE " + "  ".join(f"{p} {rms([c['error'][p] for c in k]):.4f}" for p in GEOMETRY))
        recon(k)


def recon(cases):
    """GAP-TV's PSNR (a record made with --recon): what the blur pass's σ buys the reconstruction.
    Records from stop 44 on reconstruct III with the model's own σ and hold the pass's in
    III_blur_pass_sigma; earlier ones reconstructed with the pass's and held III_before_blur_pass."""
    db = [c.get("psnr_db", {}) for c in cases]
    if not db:
        return
    if all("III_blur_pass_sigma" in d for d in db):
        model_sigma = [d["III_calibrated"] for d in db]
        pass_sigma = [d["III_blur_pass_sigma"] for d in db]
    elif all("III_before_blur_pass" in d for d in db):
        model_sigma = [d["III_before_blur_pass"] for d in db]
        pass_sigma = [d["III_calibrated"] for d in db]
    else:
        return
    mean = lambda key: sum(d[key] for d in db) / len(db)
    gain = [p - m for p, m in zip(pass_sigma, model_sigma)]
    line = (f"    GAP-TV PSNR mean: II nominal {mean('II_nominal'):.2f}, III with the model's own σ "
            f"{sum(model_sigma) / len(db):.2f}, with the blur pass's {sum(pass_sigma) / len(db):.2f}, "
            f"IV {mean('IV_true'):.2f} dB")
    if all("IV_instrument_sigma" in d for d in db):
        line += f" (IV at the instrument's σ {mean('IV_instrument_sigma'):.2f})"
    print(line)
    print(f"    the blur pass: PSNR up in {sum(g > 0 for g in gain)} of {len(gain)}, "
          f"mean {sum(gain) / len(gain):+.3f} dB, range {min(gain):+.3f} … {max(gain):+.3f}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for arg in sys.argv[1:]:
        path, _, sigma_c = arg.partition("@")
        table(path, float(sigma_c or 0))
