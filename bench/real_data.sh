#!/usr/bin/env bash
# Self-calibration on the five real TSA-Net snapshots (660×714, 660×660 mask):
# calibrate each, reconstruct with GAP-TV under the nominal and the calibrated
# model, keep the calibration JSON and both previews in bench/results/real/,
# combine the five calibrations (one camera: `cassi combine`, its printout in
# combined.<preset>.txt; with the default preset also refitted jointly on the
# five measurements, `--joint`: combined_joint.<preset>.*), and write bench/results/real/README.<preset>.md (table of
# parameters and residuals).
#
# Run from the repository root: bench/real_data.sh [--preset default|paper]
set -euo pipefail
preset=default
if [[ "${1:-}" == "--preset" ]]; then preset="$2"; fi
data=../shared/data/real
out=bench/results/real
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli
cassi=target/release/cassi
mkdir -p "$out"
for meas in "$data"/scene*.mat; do
  name=$(basename "$meas" .mat)
  echo "== $name"
  "$cassi" calibrate "$meas" --mask "$data/tsa_real_mask660.mat" --preset "$preset" \
    -o "$out/$name.$preset.calib.json"
  "$cassi" reconstruct "$meas" --mask "$data/tsa_real_mask660.mat" -q -o "$work/$name.nominal.npy"
  "$cassi" reconstruct "$meas" --mask "$data/tsa_real_mask660.mat" -q \
    --calibration "$out/$name.$preset.calib.json" -o "$work/$name.calibrated.npy"
  cp "$work/$name.nominal.png" "$out/$name.nominal.png"
  cp "$work/$name.calibrated.png" "$out/$name.$preset.calibrated.png"
  cp "$work/$name.nominal.json" "$out/$name.nominal.recon.json"
  cp "$work/$name.calibrated.json" "$out/$name.$preset.calibrated.recon.json"
done
# one camera, five snapshots: their calibrations combined, and whether they agree
"$cassi" combine "$out"/scene*."$preset".calib.json -o "$out/combined.$preset.calib.json" \
  > "$out/combined.$preset.txt"
# and refitted on the five measurements as one fit (one ψ, each its own scene)
if [[ "$preset" == default ]]; then
  "$cassi" combine "$out"/scene*."$preset".calib.json -o "$out/combined_joint.$preset.calib.json" \
    --joint "$data"/scene*.mat --mask "$data/tsa_real_mask660.mat" > "$out/combined_joint.$preset.txt"
fi
python3 bench/real_data_table.py "$out" "$preset" > "$out/README.$preset.md"
echo "wrote $out/README.$preset.md"
