#!/usr/bin/env bash
# The AVX-512 copy against the AVX copy on this Intel VM: one build (the
# calibration code of 4e17c4c; the probe build adds only an environment
# switch, CASSI_PROBE_NO_AVX512, that makes the dispatch skip AVX-512), the
# 25 timing cases in four sittings (512, avx, avx, 512), then the five real
# snapshots by turns. Every run alone.
set -euo pipefail
out=$(cd "$(dirname "$0")" && pwd)
export CASSI_SHARED_DATA=/work/shared/data
cases="--no-recon --no-limits --no-inverse-crime --no-wide-blur"
run() { # name env...
  local name=$1; shift
  echo "== $name $(date -u +%H:%M:%S)"
  env "$@" /tmp/calib_probe512 $cases --out "$out/$name.json" > "$out/$name.log" 2>&1
}
run avx512_1
run avx_1 CASSI_PROBE_NO_AVX512=1
run avx_2 CASSI_PROBE_NO_AVX512=1
run avx512_2
mkdir -p "$out/real"
for s in scene1_legoplant scene2_realplant1 scene3_legoman scene4_realplant2 scene5_strawberry; do
  for which in avx512 avx; do
    echo "== real $s $which $(date -u +%H:%M:%S)"
    e=(); [[ $which == avx ]] && e=(CASSI_PROBE_NO_AVX512=1)
    env "${e[@]}" /tmp/cassi_probe512 calibrate /work/shared/data/real/$s.mat --mask /work/shared/data/real/tsa_real_mask660.mat -o "$out/real/$s.$which.calib.json" > "$out/real/$s.$which.log" 2>&1
  done
done
echo "== done $(date -u +%H:%M:%S)"
