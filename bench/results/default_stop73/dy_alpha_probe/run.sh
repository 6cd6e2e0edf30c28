#!/bin/bash
# stop 73 probe: the off-grid run, then dy and alpha refitted (pass's 20-iteration solves); tuning half, 4 seed rounds, random poses
cd /work/main
export CASSI_SHARED_DATA=/work/shared/data
out=/tmp/p73/dyalpha
mkdir -p $out
git rev-parse HEAD > $out/rev
echo "--fine-pass-off-grid-run 60,pose-and-slope,then-dy-and-alpha --no-aligned" > $out/flags
for r in 0 1 2 3; do
  /tmp/d73/calibrate_probe --half tuning --seed-round $r --cases 6 --no-aligned --no-recon --no-limits --no-inverse-crime --no-wide-blur \
    --fine-pass-off-grid-run 60,pose-and-slope,then-dy-and-alpha --out $out/round$r.json > $out/round$r.log 2>&1
done
date > $out/done
