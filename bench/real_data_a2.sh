#!/usr/bin/env bash
# The five real TSA-Net snapshots calibrated (default preset) with the
# dispersion's curvature a2 held at each of several values (band k at
# a1·k + a2·k² px; `cassi calibrate --dispersion-a2`): a profile over a2.
# Keeps each calibration JSON in bench/results/real/a2_profile/ and writes
# its README.md (a1, dx and the fine pass's residual per snapshot and a2).
#
# Run from the repository root: bench/real_data_a2.sh [A2 ...]
# (default: -0.016 -0.012 -0.008 -0.004 0 0.004 0.008)
set -euo pipefail
values=("$@")
if [[ ${#values[@]} -eq 0 ]]; then values=(-0.016 -0.012 -0.008 -0.004 0 0.004 0.008); fi
data=../shared/data/real
out=bench/results/real/a2_profile
cargo build --release -q -p cassi-cli
cassi=target/release/cassi
mkdir -p "$out"
for a2 in "${values[@]}"; do
  for meas in "$data"/scene*.mat; do
    name=$(basename "$meas" .mat)
    echo "== $name, a2 $a2"
    "$cassi" calibrate "$meas" --mask "$data/tsa_real_mask660.mat" -q \
      --dispersion-a2 "$a2" -o "$out/$name.a2_$a2.calib.json"
  done
done
# written whole or not at all
python3 bench/real_data_a2_table.py "$out" > "$out/README.md.tmp"
mv "$out/README.md.tmp" "$out/README.md"
echo "wrote $out/README.md"
