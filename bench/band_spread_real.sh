#!/usr/bin/env bash
# Snapshots calibrated with each band spread in the fitted model (`cassi
# calibrate --band-spread SPREAD`: each band's light spread along the
# dispersion, as a camera's continuous spectrum spreads it), and each
# calibration's GAP-TV reconstruction (its report's relative residual: how
# well that model explains the snapshot, no free parameter added). By
# default the five real TSA snapshots; `MEAS=DIR` for the controls of
# bench/real_content_simulate.sh (DIR/scene*.npy, their sidecars the truth).
# The table: python3 bench/band_spread_table.py OUTDIR.
#
# Run from the repository root:
#   [MEAS=DIR] bench/band_spread_real.sh OUTDIR SPREAD [SPREAD ...]
# (SPREAD: point, uniform or linear). Writes, per snapshot and spread,
# <name>.<spread>.calib.json, its log and <name>.<spread>.recon.json.
set -euo pipefail
out=$1
shift
data=../shared/data/real
meas_dir=${MEAS:-$data}
cargo build --release -q -p cassi-cli
cassi=target/release/cassi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
shopt -s nullglob
for meas in "$meas_dir"/scene*.mat "$meas_dir"/scene*.npy; do
  name=$(basename "${meas%.*}")
  for spread in "$@"; do
    echo "== $name $spread"
    "$cassi" calibrate "$meas" --mask "$data/tsa_real_mask660.mat" --band-spread "$spread" \
      -o "$out/$name.$spread.calib.json" > "$out/$name.$spread.log" 2>&1
    "$cassi" reconstruct "$meas" --mask "$data/tsa_real_mask660.mat" -q \
      --calibration "$out/$name.$spread.calib.json" -o "$work/$name.$spread.npy"
    cp "$work/$name.$spread.json" "$out/$name.$spread.recon.json"
    tail -n 4 "$out/$name.$spread.log"
  done
done
