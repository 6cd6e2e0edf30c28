#!/usr/bin/env bash
# The control of `band_shifts`: the band shifts of measurements with each real
# TSA snapshot's content at a known ψ with a straight prism
# (bench/real_content_simulate.sh --decoupled: its GAP-TV reconstruction,
# smoothed, simulated by the 4× oversampled instrument off its calibrated ψ):
# the shapes a straight dispersion leaves with that content → $OUT (default
# bench/results/real/band_shifts/control.json).
#
# Run from the repository root: [OUT=PATH] bench/band_shifts_control.sh [--scene NAME]…
# (the flags are band_shifts'; every snapshot is simulated). Needs
# ../shared/data/real and python3 with numpy.
set -euo pipefail
out=${OUT:-bench/results/real/band_shifts/control.json}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release -q -p cassi-cli
cargo build --release -q -p cassi-bench --bin band_shifts
bench/real_content_simulate.sh "$work/sim" --decoupled
target/release/band_shifts --measurements "$work/sim" --out "$out" "$@"
