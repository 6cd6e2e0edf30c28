#!/usr/bin/env bash
# Measurements with the real TSA snapshots' content at a known ψ, for the
# controls of the real-data benches: for each snapshot, its GAP-TV
# reconstruction under its calibrated model
# (bench/results/real/<name>.default.calib.json; clipped to [0, its 99.9th
# percentile] and scaled to [0, 1]) simulated at that calibrated ψ by the 4×
# oversampled instrument with a straight prism (crisp mask cells, continuous
# dispersion, Gaussian blur, the 660×714 detector, 2·10⁴ e⁻ peak, 3 e⁻ read
# noise) → OUTDIR/<name>.npy (and its sidecar, the truth).
#
# --decoupled: the reconstruction smoothed by a 1-px Gaussian (it carries the
# mask's imprint at the ψ it was made with, which would draw a fit toward that
# ψ) and the truth moved off that ψ by dx +0.35 px, dy −0.25 px, θ +0.02°,
# a1 +0.012, α −0.2° (what imprint is left pulls away from the truth).
#
# Any further flags go to `cassi simulate` (e.g. `--dispersion-step 22:0.5`: an instrument
# whose bands from 22 on land 0.5 px further).
#
# The scenes and ψ come from bench/real_content.py. Run from the repository root:
#   bench/real_content_simulate.sh OUTDIR [--decoupled] [SIMULATE_FLAG ...]
# Needs ../shared/data/real, target/release/cassi and python3 with numpy.
set -euo pipefail
outdir=$1
shift
decoupled=0
if [[ "${1:-}" == "--decoupled" ]]; then decoupled=1; shift; fi
data=../shared/data/real
mask=$data/tsa_real_mask660.mat
cassi=target/release/cassi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$outdir"
seed=0
for meas in "$data"/scene*.mat; do
  name=$(basename "$meas" .mat)
  seed=$((seed + 1))
  "$cassi" reconstruct "$meas" --mask "$mask" -q \
    --calibration "bench/results/real/$name.default.calib.json" -o "$work/$name.recon.npy"
  if [[ $decoupled == 1 ]]; then
    python3 bench/real_content.py scene "$work/$name.recon.npy" "$work/$name.scene.npy" --smooth
    psi=$(python3 bench/real_content.py psi "bench/results/real/$name.default.calib.json" --offset)
  else
    python3 bench/real_content.py scene "$work/$name.recon.npy" "$work/$name.scene.npy"
    psi=$(python3 bench/real_content.py psi "bench/results/real/$name.default.calib.json")
  fi
  # shellcheck disable=SC2086
  "$cassi" simulate --scene "$work/$name.scene.npy" --mask "$mask" --oversample 4 $psi \
    --detector 660x714 --photon-peak 20000 --read-noise 3 --noise-seed "$seed" -q "$@" \
    -o "$outdir/$name.npy"
  echo "$name: $psi"
done
