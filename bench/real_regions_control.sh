#!/usr/bin/env bash
# The control of `calibrate_real_regions`: the regions' calibrations of
# measurements with each real TSA snapshot's content at its own calibrated ψ
# (bench/real_content_simulate.sh: its GAP-TV reconstruction simulated by the
# 4× oversampled instrument) → bench/results/real/regions/control_<regions>.json.
#
# --decoupled: the scenes smoothed and the truth moved off the reconstructions'
# ψ (see real_content_simulate.sh) → control_decoupled_<regions>.json.
#
# Run from the repository root:
#   bench/real_regions_control.sh [--decoupled] [whole|halves|thirds ...]
# (default: all three). Needs ../shared/data/real and python3 with numpy.
set -euo pipefail
decoupled=()
if [[ "${1:-}" == "--decoupled" ]]; then decoupled=(--decoupled); shift; fi
regions=("${@:-whole halves thirds}")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli -p cassi-bench
bench/real_content_simulate.sh "$work/sim" "${decoupled[@]}"
label=control
if [[ ${#decoupled[@]} == 1 ]]; then label=control_decoupled; fi
for r in ${regions[*]}; do
  target/release/calibrate_real_regions --measurements "$work/sim" --label "$label" --regions "$r"
done
