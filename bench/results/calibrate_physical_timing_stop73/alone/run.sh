#!/bin/bash
# stop 73: the default (stop 72's, c2813f7) alone on this VM: the 25 timing cases, then the five real snapshots
set -e
cd /work/main
export CASSI_SHARED_DATA=/work/shared/data
out=/tmp/ts73
git rev-parse HEAD > $out/rev
date > $out/started
/tmp/d73/calibrate --no-recon --no-limits --no-inverse-crime --no-wide-blur --out $out/timing.json > $out/timing.log 2>&1
date > $out/cases_done
for s in scene1_legoplant scene2_realplant1 scene3_legoman scene4_realplant2 scene5_strawberry; do
  /tmp/d73/cassi calibrate /work/shared/data/real/$s.mat --mask /work/shared/data/real/tsa_real_mask660.mat -o $out/real/$s.calib.json > $out/real/$s.log 2>&1
done
date > $out/done
