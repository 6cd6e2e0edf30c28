#!/usr/bin/env bash
# The physical calibration benchmark (cassi-bench's `calibrate`) on the real
# TSA snapshots' content: ten 256×256 scenes cut from the five snapshots' GAP-TV
# reconstructions (under their calibrated models,
# bench/results/real/<name>.default.calib.json), smoothed by 1 px (the
# reconstruction's mask imprint) — bench/real_content.py — in place of the CAVE
# scenes; the benchmark's own simulator (4× oversampled, crisp cells, blur,
# 256×310 detector, 2·10⁴ e⁻ peak, 3 e⁻ read noise), mismatches, seeds and
# mask. Its "tuning" half is the a_* crops, its held-out half the b_* ones (the
# default was tuned on neither: both are held out for it).
#
# Run from the repository root: bench/real_content_benchmark.sh [calibrate flags …]
# (default record bench/results/calibrate_physical_real_content.json unless
# --out is given). Needs ../shared/data and python3 with numpy.
set -euo pipefail
data=../shared/data
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli -p cassi-bench
cassi=target/release/cassi
mkdir -p "$work/data/scenes" "$work/data/masks"
ln -s "$(realpath "$data/masks/tsa_simu_mask256.mat")" "$work/data/masks/"
for meas in "$data"/real/scene*.mat; do
  name=$(basename "$meas" .mat)
  "$cassi" reconstruct "$meas" --mask "$data/real/tsa_real_mask660.mat" -q \
    --calibration "bench/results/real/$name.default.calib.json" -o "$work/$name.recon.npy"
  python3 bench/real_content.py scene "$work/$name.recon.npy" "$work/$name.scene.npy" --smooth
  python3 bench/real_content.py crops "$work/$name.scene.npy" "$work/data/scenes" "$name"
done
out=()
if [[ " $* " != *" --out "* ]]; then out=(--out bench/results/calibrate_physical_real_content.json); fi
CASSI_SHARED_DATA="$work/data" target/release/calibrate "$@" "${out[@]}"
