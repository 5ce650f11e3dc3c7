#!/usr/bin/env bash
# GPU-host run (BSP-CVAE), from the repository root with .devdeps/ carried: builds dimr (unless
# done), prepares the training and validation shapes there (`dimr bsp prepare --jobs`, as
# models/bsp/model.yaml's data lines), then trains a BSP-CVAE from scratch on CUDA: phase 0
# (continuous) for PHASE0_FRACTION of the time left, phase 1 (discrete) for the rest.
# Results (bsp.pt, model.yaml, train_log.csv) land in $OUT/bsp.
#   BUDGET=560 scripts/device/train_bsp.sh
set -o pipefail
source scripts/device/host_setup.sh
BUDGET=${BUDGET:-560}
JOBS=${JOBS:-$(nproc)}
BATCH=${BATCH:-64}
PHASE0_FRACTION=${PHASE0_FRACTION:-0.62}
mkdir -p /tmp/bsp "$OUT/bsp"
$B bsp prepare --per-class "${PER_CLASS:-250}" --seed 1 --jobs "$JOBS" --out /tmp/bsp/train.bin 2>/dev/null || exit 1
$B bsp prepare --per-class "${VAL_PER_CLASS:-25}" --seed 2 --jobs "$JOBS" --out /tmp/bsp/val.bin 2>/dev/null || exit 1
echo "bsp data done at $(el) s"
LEFT=$(( BUDGET - $(el) - 25 ))
read -r MAXMIN P0MIN < <(python3 -c "m=max(0.5,$LEFT/60); print(round(m,3), round(m*$PHASE0_FRACTION,3))")
echo "bsp: training for $MAXMIN min, phase 0 for $P0MIN min, batch $BATCH"
$B train bsp --train /tmp/bsp/train.bin --val /tmp/bsp/val.bin --out /tmp/bsp/run \
  --epochs 5000,5000,0 --batch "$BATCH" --points 2048 --lr "${LR:-3e-4}" --seed 1 --device "${DEVICE:-cuda}" \
  --max-minutes "$MAXMIN" --phase0-minutes "$P0MIN" --lr-step "${LR_STEP:-250}" \
  --checkpoint-every 20 > "$OUT/bsp/train.log" 2>&1
echo "bsp train exit $? at $(el) s"
grep -v '^epoch' "$OUT/bsp/train.log" | tail -5
grep '^epoch' "$OUT/bsp/train.log" | awk 'NR%50==0' | tail -30
tail -3 "$OUT/bsp/train.log"
cp /tmp/bsp/run/bsp.pt /tmp/bsp/run/model.yaml /tmp/bsp/run/train_log.csv "$OUT/bsp/" 2>/dev/null
ls -la "$OUT/bsp"
