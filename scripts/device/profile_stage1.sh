#!/usr/bin/env bash
# GPU-host profile of a stage-1 training step (where the time goes: loader, voxelise, kernel maps,
# U-Net convolutions, loss, backward, optimiser), for batch sizes $BATCHES, each for $MINUTES.
# Builds dimr (unless done) and synthesises $SCENES rooms there. Medians land in $OUT/profile.txt.
#   BATCHES="8 16" MINUTES=0.6 SCENES=24 scripts/device/profile_stage1.sh
set -o pipefail
source scripts/device/host_setup.sh
SCENES=${SCENES:-24}
MINUTES=${MINUTES:-0.6}
mkdir -p /tmp/sp
$B synth --scenes "$SCENES" --seed 1 --split train --jobs "$(nproc)" --quiet --out /tmp/sp/train \
  > /tmp/sp/synth.log 2>&1 || { tail -20 /tmp/sp/synth.log; exit 1; }
echo "synth done at $(el) s"
for BATCH in ${BATCHES:-8 16}; do
  rm -rf /tmp/sp/run
  OMP_NUM_THREADS=8 $B train stage1 --train /tmp/sp/train --out /tmp/sp/run \
    --init models/stage1/stage1.pt --config "scale=20 rgb=1 widths=16,32,48,64,96,128 reps=1 classes=25" \
    --epochs 400 --batch "$BATCH" --lr 1e-4 --seed 1 --threads 8 --loader-threads 6 \
    --device "${DEVICE:-cuda}" --max-minutes "$MINUTES" --checkpoint-every 100000 --no-elastic \
    > /tmp/sp/train_$BATCH.log 2>&1 || { tail -20 /tmp/sp/train_$BATCH.log; }
  python3 - "$BATCH" /tmp/sp/run/train_log.csv >> "$OUT/profile.txt" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[2])))
rows = rows[3:] if len(rows) > 6 else rows  # skip warm-up steps
cols = [c for c in rows[0] if c.endswith("_ms")]
print(f"batch {sys.argv[1]}: {len(rows)} steps; median ms " +
      " ".join(f"{c[:-3]}={statistics.median(float(r[c]) for r in rows):.1f}" for c in cols) +
      f"; s/step {(float(rows[-1]['seconds']) - float(rows[0]['seconds'])) / max(1, len(rows) - 1):.3f}")
PY
  echo "batch $BATCH done at $(el) s"
done
cat "$OUT/profile.txt"
