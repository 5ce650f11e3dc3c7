#!/usr/bin/env bash
# GPU-host run (stage 1), from the repository root with .devdeps/ made by
# scripts/device/prepare_deps.sh (through the device tool: carry [".devdeps"]). Unpacks the carried
# libraries (yaml-cpp, Embree, TBB), builds dimr with the data/eval/nn/pipeline layers against the
# host's PyTorch LibTorch, generates SynthScan rooms there (the 1.1 GB cache cannot travel), then
# fine-tunes the bundled stage-1 model on CUDA for the rest of the budget, the learning rate decayed
# over the time budget. Results (weights, model card, logs) land in $OUT (default out/device).
#   BUDGET=545 SCENES=480 scripts/device/train_stage1.sh
set -o pipefail
source scripts/device/host_setup.sh
BUDGET=${BUDGET:-560}
SCENES=${SCENES:-480}
SYNTH_JOBS=${SYNTH_JOBS:-$(nproc)}
THREADS=${THREADS:-8}
mkdir -p /tmp/ss
$B synth --scenes 20 --seed 1 --split val --jobs 4 --quiet --out /tmp/ss/val > /tmp/ss/val.log 2>&1 &
$B synth --scenes "$SCENES" --seed 1 --split train --jobs "$SYNTH_JOBS" --quiet --out /tmp/ss/train \
  > /tmp/ss/train.log 2>&1 || { tail -20 /tmp/ss/train.log; exit 1; }
wait
tail -n 3 /tmp/ss/train.log /tmp/ss/val.log
echo "synth done at $(el) s"
LEFT=$(( BUDGET - $(el) - 45 ))
MAXMIN=$(python3 -c "print(round(max(0.5, $LEFT/60), 3))")
echo "training for $MAXMIN min"
OMP_NUM_THREADS=$THREADS $B train stage1 --train /tmp/ss/train --val /tmp/ss/val --out /tmp/s1 \
  --init models/stage1/stage1.pt --config "scale=20 rgb=1 widths=16,32,48,64,96,128 reps=1 classes=25" \
  --epochs 400 --batch 8 --lr "${LR:-1e-3}" --lr-decay 0.05 --seed 124 --threads "$THREADS" --loader-threads 6 \
  --data-threads "$SYNTH_JOBS" --device "${DEVICE:-cuda}" --max-minutes "$MAXMIN" --lr-by-time --checkpoint-every 100000 \
  --val-scenes 20 --val-every 4 --no-elastic --class-weights sqrt-inverse > "$OUT/train.log" 2>&1
echo "train exit $? at $(el) s"
tr '\r' '\n' < "$OUT/train.log" | grep -v '^\[epoch' | tail -30
tr '\r' '\n' < "$OUT/train.log" | grep '^\[epoch' | tail -3
cp /tmp/s1/stage1.pt /tmp/s1/model.yaml /tmp/s1/train_log.csv /tmp/s1/val_log.csv "$OUT/" 2>/dev/null
ls -la "$OUT"; echo "end at $(el) s"
