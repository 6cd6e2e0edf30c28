#!/usr/bin/env bash
# Two builds' calibration time side by side on this machine: the 25 timing
# cases of the calibration benchmark (`calibrate --no-recon --no-limits
# --no-inverse-crime --no-wide-blur`, round 0: 10 random poses, 15 aligned
# instruments) and, when ../shared/data/real is there, the five real TSA
# snapshots (`cassi calibrate`, the default). Each run is alone; the order
# alternates (the benchmark: FIRST's build first; the snapshots: by turns), so
# a drift of the machine falls on both. Speed is the per-case ratio, not one
# sitting's median: the project's VMs drift by as much as a change gains.
#
# Run from the repository root with a clean tree:
#   bench/timing_side_by_side.sh OUTDIR BASE_REV NEW_REV [--first base|new]
# OUTDIR must be new or empty. Writes OUTDIR/{base,new}_timing.json, OUTDIR/real/<snapshot>.{base,new}.calib.json
# and prints the table (bench/timing_table.py OUTDIR).
set -euo pipefail
out=$1
base_rev=$2
new_rev=$3
first=base
case "${4:-} ${5:-}" in
  " ") ;;
  "--first new") first=new ;;
  "--first base") ;;
  *) echo "usage: $0 OUTDIR BASE_REV NEW_REV [--first base|new]" >&2; exit 2 ;;
esac
# a fresh OUTDIR: no earlier sitting's files mixed into this one's table
if [[ -e $out && -n $(ls -A "$out" 2>/dev/null) ]]; then
  echo "$out: not empty; give a new or empty OUTDIR" >&2
  exit 2
fi
root=$(pwd)
# the builds live in temporary worktrees: the benchmark's scenes and masks
# are found through this, not through ../shared beside them
export CASSI_SHARED_DATA=${CASSI_SHARED_DATA:-$(cd "$root/.." && pwd)/shared/data}
mkdir -p "$out/real"
out=$(cd "$out" && pwd)
work=$(mktemp -d)
trap 'git -C "$root" worktree remove --force "$work/base" 2>/dev/null || true;
      git -C "$root" worktree remove --force "$work/new" 2>/dev/null || true; rm -rf "$work"' EXIT
for which in base new; do
  rev=$base_rev
  [[ $which == new ]] && rev=$new_rev
  git -C "$root" worktree add -q --detach "$work/$which" "$rev"
  (cd "$work/$which" && cargo build --release -q -p cassi-cli -p cassi-bench --bin cassi --bin calibrate)
  cp "$work/$which/target/release/cassi" "$work/cassi_$which"
  cp "$work/$which/target/release/calibrate" "$work/calibrate_$which"
  git -C "$work/$which" rev-parse HEAD > "$out/$which.rev"
done

# a run's output goes to its log; a failed run shows the log's end and stops
logged() {
  local log=$1
  shift
  "$@" > "$log" 2>&1 || { echo "failed: $* (log $log):" >&2; tail -n 5 "$log" >&2; exit 1; }
}

order="base new"
[[ $first == new ]] && order="new base"
for which in $order; do
  echo "== timing cases, $which ($(cat "$out/$which.rev"))"
  logged "$out/${which}_timing.log" "$work/calibrate_$which" --no-recon --no-limits \
    --no-inverse-crime --no-wide-blur --out "$out/${which}_timing.json"
done

data=$CASSI_SHARED_DATA/real
if [[ -d $data ]]; then
  i=0
  for meas in "$data"/scene*.mat; do
    name=$(basename "${meas%.*}")
    pair="base new"
    (( i % 2 == 1 )) && pair="new base"
    for which in $pair; do
      echo "== $name, $which"
      logged "$out/real/$name.$which.log" "$work/cassi_$which" calibrate "$meas" \
        --mask "$data/tsa_real_mask660.mat" -o "$out/real/$name.$which.calib.json"
    done
    i=$((i + 1))
  done
fi
python3 "$root/bench/timing_table.py" "$out"
