#!/bin/bash
# Device call B: Fig. 7 of Oz et al., one sweep process per variant sharing the GPU.
set -u
T=python3; [ -x .venv/bin/python ] && T=.venv/bin/python
M=${M:-7}; W=${W:-4}; OUT=${OUT:-/tmp/outB}; mkdir -p $OUT
for v in kpn kpn-no-offset e2e; do
  $T benchmarks/kpn_fig7.py --minutes $M --device ${DEV:-cuda} --workers $W --variants $v \
     --ns ${NS:-1,3,5,7,9,11} ${QUICK:-} --json $OUT/fig7_$v.json > $OUT/fig7_$v.log 2>&1 &
done
wait
$T benchmarks/kpn_fig7.py --merge $OUT/fig7_kpn.json $OUT/fig7_kpn-no-offset.json $OUT/fig7_e2e.json --json $OUT/fig7.json
for f in $OUT/*.log; do echo "== $f"; grep -v "^step" $f | tail -n 8; done
