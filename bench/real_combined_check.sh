#!/usr/bin/env bash
# The five real snapshots reconstructed (GAP-TV, shipped settings) with the
# five's combined calibration, with their joint fit (`cassi combine --joint`,
# where bench/real_data.sh made one) and with each snapshot's own ψ, all at
# the same reconstruction σ (the combination's): whose geometry explains a snapshot's
# data better, the blur held equal (a blurred operator cannot fit the
# pixel-scale noise, so residuals at different σ do not compare).
# Needs bench/real_data.sh's outputs. Writes bench/results/real/combined_residuals.<preset>.tsv.
#
# Run from the repository root: bench/real_combined_check.sh [--preset default|paper]
set -euo pipefail
preset=default
if [[ "${1:-}" == "--preset" ]]; then preset="$2"; fi
data=../shared/data/real
out=bench/results/real
combined="$out/combined.$preset.calib.json"
joint="$out/combined_joint.$preset.calib.json"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli
cassi=target/release/cassi
# the σ the combination reconstructs with
sigma=$(python3 -c "import json,sys; c=json.load(open(sys.argv[1])); print(c.get('model_blur_sigma_px') or c['parameters']['blur_sigma_px'])" "$combined")
table="$work/table.tsv"
printf 'snapshot\tsigma_px\town_psi_residual\tcombined_psi_residual\tjoint_psi_residual\n' > "$table"
residual() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['relative_residual'])" "$1"; }
for meas in "$data"/scene*.mat; do
  name=$(basename "$meas" .mat)
  # the snapshot's own ψ with the combination's σ
  python3 -c "import json,sys; c=json.load(open(sys.argv[1])); json.dump({'parameters': dict(c['parameters'], blur_sigma_px=float(sys.argv[2])), 'model': c['model']}, open(sys.argv[3], 'w'))" \
    "$out/$name.$preset.calib.json" "$sigma" "$work/$name.psi.json"
  "$cassi" reconstruct "$meas" --mask "$data/tsa_real_mask660.mat" -q --calibration "$work/$name.psi.json" -o "$work/$name.own.npy"
  "$cassi" reconstruct "$meas" --mask "$data/tsa_real_mask660.mat" -q --calibration "$combined" -o "$work/$name.combined.npy"
  joint_residual=-
  if [[ -f "$joint" ]]; then
    "$cassi" reconstruct "$meas" --mask "$data/tsa_real_mask660.mat" -q --calibration "$joint" -o "$work/$name.joint.npy"
    joint_residual=$(residual "$work/$name.joint.json")
  fi
  printf '%s\t%.4f\t%s\t%s\t%s\n' "$name" "$sigma" "$(residual "$work/$name.own.json")" "$(residual "$work/$name.combined.json")" "$joint_residual" >> "$table"
done
cp "$table" "$out/combined_residuals.$preset.tsv"
cat "$out/combined_residuals.$preset.tsv"
