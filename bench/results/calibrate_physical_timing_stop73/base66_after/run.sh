#!/bin/bash
# stop 73: the default before stop 72 (66a12ca) on this VM, the 25 timing cases, right after the current default's run
cd /work/main
export CASSI_SHARED_DATA=/work/shared/data
out=/tmp/ts73/base66
mkdir -p $out
echo 66a12ca74fdb35d4def8f37a7a75f77326513df5 > $out/rev
date > $out/started
/tmp/d73/calibrate_base66 --no-recon --no-limits --no-inverse-crime --no-wide-blur --out $out/timing.json > $out/timing.log 2>&1
date > $out/done
/tmp/p73/run.sh
