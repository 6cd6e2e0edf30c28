#!/usr/bin/env bash
# The calibration benchmark's tuning half on three seed rounds (0, 1, 2: the tuning scenes, 30
# random poses and 15 aligned instruments each, seeds no held-out run uses), one run at a time,
# with the flags given (a probe's; none: the default). Judge a probe with
# bench/tuning_compare.py BASE_DIR OUTDIR: one round's count moves by chance as much as most
# probes move it (bench/results/default_stop66/README.md).
#
# Run from the repository root: bench/tuning_rounds.sh OUTDIR [CALIBRATE FLAGS...]
# OUTDIR must be new or empty; writes OUTDIR/round{0,1,2}.{json,log} and OUTDIR/flags.
set -euo pipefail
out=${1:?usage: bench/tuning_rounds.sh OUTDIR [CALIBRATE FLAGS...]}
shift
if [[ -e $out && -n $(ls -A "$out" 2>/dev/null) ]]; then
  echo "$out: not empty; give a new or empty OUTDIR" >&2
  exit 2
fi
mkdir -p "$out"
export CASSI_SHARED_DATA=${CASSI_SHARED_DATA:-$(cd .. && pwd)/shared/data}
cargo build --release -q -p cassi-bench --bin calibrate
echo "$(git rev-parse HEAD) $*" > "$out/flags"
for round in 0 1 2; do
  target/release/calibrate --half tuning --seed-round "$round" --cases 6 --no-recon --no-limits \
    --no-inverse-crime --no-wide-blur "$@" --out "$out/round$round.json" > "$out/round$round.log" 2>&1
done
echo "wrote $out/round{0,1,2}.json"
