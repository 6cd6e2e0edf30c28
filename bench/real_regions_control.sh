#!/usr/bin/env bash
# The control of `calibrate_real_regions`: for each real TSA snapshot, a
# measurement simulated from its own GAP-TV reconstruction (under its
# calibrated model: bench/results/real/<name>.default.calib.json; clipped to
# [0, its 99.9th percentile] and scaled to [0, 1]) at its own calibrated ψ, by
# the 4× oversampled instrument (crisp mask cells, continuous dispersion,
# Gaussian blur, the 660×714 detector, 2·10⁴ e⁻ peak, 3 e⁻ read noise): the
# snapshots' scene content with one known ψ for every region. Then the
# regions' calibrations of those measurements
# → bench/results/real/regions/control_<regions>.json.
#
# --decoupled: the reconstruction smoothed by a 1-px Gaussian (it carries the
# mask's imprint at the ψ it was made with, which would draw a fit toward that
# ψ) and the truth moved off that ψ by dx +0.35 px, dy −0.25 px, θ +0.02°,
# a1 +0.012, α −0.2° (what imprint is left pulls away from the truth)
# → control_decoupled_<regions>.json.
#
# The scenes and ψ come from bench/real_content.py. Run from the repository root:
#   bench/real_regions_control.sh [--decoupled] [whole|halves|thirds ...]
# (default: all three). Needs ../shared/data/real and python3 with numpy.
set -euo pipefail
decoupled=0
if [[ "${1:-}" == "--decoupled" ]]; then decoupled=1; shift; fi
regions=("${@:-whole halves thirds}")
data=../shared/data/real
mask=$data/tsa_real_mask660.mat
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli -p cassi-bench
cassi=target/release/cassi
mkdir -p "$work/sim"
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
    --detector 660x714 --photon-peak 20000 --read-noise 3 --noise-seed "$seed" -q \
    -o "$work/sim/$name.npy"
  echo "$name: $psi"
done
label=control
if [[ $decoupled == 1 ]]; then label=control_decoupled; fi
for r in ${regions[*]}; do
  target/release/calibrate_real_regions --measurements "$work/sim" --label "$label" --regions "$r"
done
