#!/bin/bash
# Device call A: the shipped compact KPN, the paper's configuration, and the real-camera path
# (unit 7 chamber -> model), trained side by side on one GPU. M = minutes of training.
set -u
M=${M:-7}; MC=${MC:-6}; DEV=${DEV:-cuda}; W1=${W1:-6}; W2=${W2:-4}; W3=${W3:-3}
OUT=${OUT:-/tmp/outA}; mkdir -p $OUT
T=python3; [ -x .venv/bin/python ] && T=.venv/bin/python
run() { $T -c "from thermocal.cli import main; main()" "$@"; }
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader 2>/dev/null
COMMON="--frames 7 --variant kpn --kernel 5 --centre --fpa-input --units 0-23 --val-units 50-53 --threads 2 --device $DEV"
( run train --out $OUT/kpn_n7.pt $COMMON --mu 16 --levels 3 --crop 64 --batch 32 \
    --steps-per-epoch 300 --max-epochs 1000 --lr 1e-3 --max-minutes $M --workers $W1 \
    > $OUT/compact.log 2>&1 ) &
( run train --out /tmp/paper.pt $COMMON --mu 64 --levels 4 --crop 128 --batch 16 \
    --steps-per-epoch 200 --max-epochs 1000 --lr 1e-4 --max-minutes $M --workers $W2 \
    > $OUT/paper.log 2>&1 ) &
( run simulate chamber /tmp/unit7.h5 --unit 7 --seed 7 --ambient-c 5:45 \
  && run train --out $OUT/kpn_n7_chamber_unit7.pt --chamber /tmp/unit7.h5 --frames 7 \
    --variant kpn --kernel 5 --centre --fpa-input --threads 2 --device $DEV --mu 16 --levels 3 \
    --crop 64 --batch 32 --steps-per-epoch 300 --max-epochs 1000 --lr 1e-3 --max-minutes $MC \
    --workers $W3 ) > $OUT/chamber.log 2>&1 &
wait
$T benchmarks/kpn.py --model /tmp/paper.pt --accuracy-only --device $DEV ${QUICK:-} \
    --json $OUT/paper_eval.json >> $OUT/paper.log 2>&1
rm -f $OUT/kpn_n7_chamber_unit7.ckpt
for f in $OUT/*.log; do echo "== $f"; tail -n 4 $f; done; tail -n 25 $OUT/paper.log
