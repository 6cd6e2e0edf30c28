#!/bin/bash
cd /work/main
export CASSI_SHARED_DATA=/work/shared/data
git rev-parse HEAD > /tmp/r3/rev
B="--half tuning --seed-round 3 --cases 6 --no-aligned --no-recon --no-limits --no-inverse-crime --no-wide-blur"
/tmp/d72/calibrate_head $B --out /tmp/r3/default.json > /tmp/r3/default.log 2>&1
/tmp/d72/calibrate_head $B --fine-pass-off-grid-run none --out /tmp/r3/before.json > /tmp/r3/before.log 2>&1
/tmp/d72/calibrate_head $B --fine-pass-off-grid-run 60,pose-and-slope,then-the-pass --out /tmp/r3/then.json > /tmp/r3/then.log 2>&1
date > /tmp/r3/done
