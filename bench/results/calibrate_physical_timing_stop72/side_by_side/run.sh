#!/bin/bash
set -e
cd /work/main
export CASSI_SHARED_DATA=/work/shared/data
out=/tmp/ts72
echo 66a12ca74fdb35d4def8f37a7a75f77326513df5 > $out/base.rev
git rev-parse HEAD > $out/new.rev
for which in base new; do
  date > $out/${which}_started
  /tmp/d72/calibrate_$which --no-recon --no-limits --no-inverse-crime --no-wide-blur --out $out/${which}_timing.json > $out/${which}_timing.log 2>&1
done
i=0
for s in scene1_legoplant scene2_realplant1 scene3_legoman scene4_realplant2 scene5_strawberry; do
  if (( i % 2 == 0 )); then order="new base"; else order="base new"; fi
  for which in $order; do
    /tmp/d72/cassi_$which calibrate /work/shared/data/real/$s.mat --mask /work/shared/data/real/tsa_real_mask660.mat -o $out/real/$s.$which.calib.json > $out/real/$s.$which.log 2>&1
  done
  i=$((i+1))
done
date > $out/done
