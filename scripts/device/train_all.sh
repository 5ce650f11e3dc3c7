#!/usr/bin/env bash
# One GPU-host call for both trainings (the GPU is mostly idle in each: both are launch-bound):
# builds dimr once, then runs scripts/device/train_bsp.sh on the last BSP_CORES cores and
# scripts/device/train_stage1.sh on the others, side by side, within BUDGET seconds.
#   BUDGET=560 SCENES=360 scripts/device/train_all.sh       (device tool: carry [".devdeps"])
set -o pipefail
source scripts/device/host_setup.sh
BUDGET=${BUDGET:-560}
N=$(nproc)
BSP_CORES=${BSP_CORES:-4}
FIRST=$(( N - BSP_CORES ))
export BUDGET OUT
JOBS=$BSP_CORES taskset -c "$FIRST-$(( N - 1 ))" bash scripts/device/train_bsp.sh > "$OUT/bsp_run.log" 2>&1 &
BSP_PID=$!
SYNTH_JOBS=$FIRST THREADS=$(( FIRST > 10 ? 8 : FIRST / 2 + 1 )) \
  taskset -c "0-$(( FIRST - 1 ))" bash scripts/device/train_stage1.sh
wait $BSP_PID
echo "== BSP run"; cat "$OUT/bsp_run.log"
echo "all done at $(el) s"
