#!/usr/bin/env bash
# Why GAP-TV's residual prefers the median's ψ to the joint fit's on the five
# real snapshots (bench/real_combined_check.sh's joint_psi_residual column):
#
# 1. attribution: each snapshot reconstructed (GAP-TV, shipped settings) with
#    the combination's ψ, with the joint fit's, and with the combination's
#    with one parameter (or dy with α) taken from the joint fit, all at the
#    combination's reconstruction σ → joint_residual_attribution.<preset>.tsv;
# 2. the residual along θ, the combination's other parameters held: every
#    snapshot on the dispersed-mask model (its reconstruction σ), legoplant
#    more finely and on the crisp-cell model (the instrument's σ, which that
#    model fits) → theta_residual_scan.<preset>.tsv.
#
# A probe, not a benchmark figure. Needs bench/real_data.sh's combined and
# combined_joint calibrations. Run from the repository root:
#   bench/real_joint_residual_probe.sh [--preset default|paper]
set -euo pipefail
preset=default
if [[ "${1:-}" == "--preset" ]]; then preset="$2"; fi
data=../shared/data/real
mask="$data/tsa_real_mask660.mat"
out=bench/results/real
combined="$out/combined.$preset.calib.json"
joint="$out/combined_joint.$preset.calib.json"
for f in "$combined" "$joint"; do
  [[ -f "$f" ]] || { echo "$f: missing; run bench/real_data.sh first" >&2; exit 1; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli
cassi=target/release/cassi

# psi FILE MODEL THETA|- VARIANT: the combination's ψ, VARIANT's parameters
# from the joint fit ('median': none, 'joint': all, else '+'-separated keys),
# θ set unless '-', at the model's σ: the combination's reconstruction σ for
# the dispersed-mask model, the instrument's (the blur pass's) otherwise.
psi() {
  python3 - "$combined" "$joint" "$@" <<'PY'
import json, sys
med, joint = (json.load(open(p)) for p in sys.argv[1:3])
path, model, theta, variant = sys.argv[3:7]
p = dict(joint['parameters'] if variant == 'joint' else med['parameters'])
if variant not in ('median', 'joint'):
    for key in variant.split('+'):
        p[key] = joint['parameters'][key]
if theta != '-':
    p['theta_deg'] = float(theta)
p['blur_sigma_px'] = (med['model_blur_sigma_px'] if model == 'dispersed-mask'
                      else med['parameters']['blur_sigma_px'])
json.dump({'parameters': p, 'model': model}, open(path, 'w'))
PY
}

# residual MEAS PSI: GAP-TV's relative residual with that ψ.
residual() {
  "$cassi" reconstruct "$1" --mask "$mask" -q --calibration "$2" -o "$work/r.npy"
  python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['relative_residual'])" "$work/r.json"
}

attribution="$work/attribution.tsv"
printf 'snapshot\tvariant\trelative_residual\n' > "$attribution"
scan="$work/scan.tsv"
printf 'snapshot\tmodel\ttheta_deg\trelative_residual\n' > "$scan"
for meas in "$data"/scene*.mat; do
  name=$(basename "$meas" .mat)
  for variant in median joint dx dy theta_deg a1 alpha_deg dy+alpha_deg; do
    psi "$work/psi.json" dispersed-mask - "$variant"
    printf '%s\t%s\t%s\n' "$name" "$variant" "$(residual "$meas" "$work/psi.json")" >> "$attribution"
  done
  thetas="-0.06 -0.04 -0.02 0.0 0.02 0.04"
  if [[ "$name" == scene1_* ]]; then
    thetas="-0.12 -0.10 -0.08 -0.06 -0.05 -0.04 -0.03 -0.02 -0.01 0.0 0.01 0.02 0.03 0.04 0.06 0.08 0.10 0.12"
  fi
  for t in $thetas; do
    psi "$work/psi.json" dispersed-mask "$t" median
    printf '%s\t%s\t%s\t%s\n' "$name" dispersed-mask "$t" "$(residual "$meas" "$work/psi.json")" >> "$scan"
  done
  if [[ "$name" == scene1_* ]]; then
    for t in -0.08 -0.06 -0.04 -0.02 0.0 0.02 0.04 0.06; do
      psi "$work/psi.json" crisp-cells "$t" median
      printf '%s\t%s\t%s\t%s\n' "$name" crisp-cells "$t" "$(residual "$meas" "$work/psi.json")" >> "$scan"
    done
  fi
done
cp "$attribution" "$out/joint_residual_attribution.$preset.tsv"
cp "$scan" "$out/theta_residual_scan.$preset.tsv"
cat "$out/joint_residual_attribution.$preset.tsv" "$out/theta_residual_scan.$preset.tsv"
