#!/usr/bin/env bash
# GPU-host run (BSP-CVAE fine-tune), from the repository root with .devdeps/ carried: builds dimr
# (unless done), prepares fresh training shapes there (a seed never used for validation or test)
# and the validation shapes of models/bsp/model.yaml, then continues the discrete phase of the
# shipped model in up to three variants at once on the one GPU (launch-bound steps leave room),
# each keeping its best validation epoch (--keep-best) at a constant KL weight (--kl-warmup 0).
# Results (bsp.pt, model.yaml, train_log.csv per variant) land in $OUT/bsp_ft/<variant>.
#   BUDGET=540 scripts/device/finetune_bsp.sh
set -o pipefail
source scripts/device/host_setup.sh
BUDGET=${BUDGET:-540}
JOBS=${JOBS:-$(nproc)}
PER_CLASS=${PER_CLASS:-1250}
VARIANTS=${VARIANTS:-"A:1e-4:0.005:20 B:3e-5:0.005:1000 C:1e-4:0.002:20"}   # name:lr:kl:lr-step
mkdir -p /tmp/bsp "$OUT/bsp_ft"
$B bsp prepare --per-class "$PER_CLASS" --seed 12 --jobs "$JOBS" --out /tmp/bsp/train.bin 2>/dev/null || exit 1
$B bsp prepare --per-class 25 --seed 2 --jobs "$JOBS" --out /tmp/bsp/val.bin 2>/dev/null || exit 1
echo "bsp data done at $(el) s"
LEFT=$(( BUDGET - $(el) - 45 ))
MAXMIN=$(python3 -c "print(round(max(0.5, $LEFT / 60), 3))")
echo "fine-tuning for $MAXMIN min: $VARIANTS"
for v in $VARIANTS; do
  IFS=: read -r name lr kl step <<< "$v"
  OMP_NUM_THREADS=4 $B train bsp --train /tmp/bsp/train.bin --val /tmp/bsp/val.bin \
    --out "/tmp/bsp/$name" --init models/bsp/bsp.pt --epochs 0,1000,0 --batch 32 --points 2048 \
    --lr "$lr" --kl "$kl" --kl-warmup 0 --lr-step "$step" --seed 21 --threads 4 --device cuda \
    --max-minutes "$MAXMIN" --checkpoint-every 2 --keep-best > "$OUT/bsp_ft/$name.log" 2>&1 &
done
wait
echo "training done at $(el) s"
for v in $VARIANTS; do
  name=${v%%:*}
  mkdir -p "$OUT/bsp_ft/$name"
  cp /tmp/bsp/$name/bsp.pt /tmp/bsp/$name/model.yaml /tmp/bsp/$name/train_log.csv "$OUT/bsp_ft/$name/" 2>/dev/null
  echo "== $name"; grep -v '^epoch' "$OUT/bsp_ft/$name.log" | tail -4
  grep '^epoch' "$OUT/bsp_ft/$name.log" | grep -v 'val_iou -' | awk 'NR%3==0' | tail -12
done
ls -la "$OUT/bsp_ft"/*
