#!/usr/bin/env bash
# Snapshots calibrated with a band table held (`cassi calibrate --band-offsets`):
# each snapshot holds the mean band shape the band-shift fit measured on the
# OTHER snapshots (leave one out: `others_mean_shape` of a `band_shifts --apply`
# record), with the ridge probes on — do the snapshots' a1 agree better, and do
# the objective's profiles along the dx–a1 and dy–α ridges become single-basin?
# By default the five real TSA snapshots with the real shapes
# (bench/results/real/band_shifts/real_apply.json); the same without a table is
# bench/results/real/stop52_ridge_probes/ (the default's answers, bitwise).
#
# Run from the repository root:
#   [MEAS=DIR] [SHAPES=RECORD] bench/band_offsets_real.sh [OUTDIR] [extra calibrate flags]
# OUTDIR defaults to bench/results/real/band_offsets; MEAS to ../shared/data/real
# (scene*.mat; otherwise DIR/scene*.npy, e.g. bench/real_content_simulate.sh's
# control measurements). Writes, per snapshot, <name>.others_shape.txt (the
# table held), <name>.held_shape.calib.json and its log.
set -euo pipefail
out=${1:-bench/results/real/band_offsets}
shift || true
data=../shared/data/real
meas_dir=${MEAS:-$data}
shapes=${SHAPES:-bench/results/real/band_shifts/real_apply.json}
cargo build --release -q -p cassi-cli
cassi=target/release/cassi
mkdir -p "$out"
python3 - "$shapes" "$out" <<'PY'
import json, sys
record, out = sys.argv[1], sys.argv[2]
for case in json.load(open(record))["cases"]:
    with open(f"{out}/{case['snapshot']}.others_shape.txt", "w") as f:
        f.write(f"# {case['snapshot']}: the other snapshots' mean band shape, px along the\n"
                f"# dispersion (from {record}, others_mean_shape), one per band\n")
        f.write("\n".join(f"{v:.6f}" for v in case["others_mean_shape"]) + "\n")
PY
shopt -s nullglob
for meas in "$meas_dir"/scene*.mat "$meas_dir"/scene*.npy; do
  name=$(basename "${meas%.*}")
  echo "== $name"
  "$cassi" calibrate "$meas" --mask "$data/tsa_real_mask660.mat" --ridge-probes \
    --band-offsets "$out/$name.others_shape.txt" "$@" \
    -o "$out/$name.held_shape.calib.json" > "$out/$name.held_shape.log" 2>&1
  tail -n 12 "$out/$name.held_shape.log"
done
