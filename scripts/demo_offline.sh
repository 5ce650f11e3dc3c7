#!/usr/bin/env bash
# The offline demo (scripts/demo.sh is the ROS one): installs and builds (scripts/setup.sh), then runs
# the library end to end on the bundled default models, without ROS nodes:
#  1. two SynthScan rooms (ScanNet/Scan2CAD/ShapeNet formats, top-down renders, rosbags);
#  2. held-out procedural CAD objects encoded and decoded by the bundled BSP-CVAE
#     (models/bsp): IoU / Chamfer table and a picture of originals next to reconstructions;
#  3. the two rooms segmented by the bundled stage-1 model (models/stage1): semantic IoU,
#     instance AP and ground-truth-vs-prediction pictures.
# Output goes to out/demo/.
set -eo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
cd "$REPO"
"$REPO/scripts/setup.sh"
# build/devel/bin/dimr is the catkin (ROS) build, which can also write rosbags.
DIMR=build/devel/bin/dimr
BAGS="--bags"
if [ ! -x "$DIMR" ]; then DIMR=build/bin/dimr; BAGS=""; fi
OUT=out/demo
mkdir -p "$OUT"
"$DIMR" synth --scenes 2 --seed 7 --split val --out "$OUT/synth" --render $BAGS
"$DIMR" bsp eval-cad --model models/bsp/bsp.pt --per-class 5 --seed 3 | tee "$OUT/bsp_eval.md"
"$DIMR" bsp render --model models/bsp/bsp.pt --per-class 2 --out "$OUT/bsp_reconstructions.png" \
  --interp-out "$OUT/bsp_interpolation.png"
"$DIMR" stage1 eval --model models/stage1/stage1.pt --scans "$OUT/synth" --passes s0.12,s0.2,s0.3 --render 2 \
  --render-dir "$OUT/stage1" | tee "$OUT/stage1_eval.md"
# The whole pipeline (stage 1 -> stage 2 -> BSP meshes -> box + ICP): labelled complete meshes of both
# rooms, evaluated against their placed CAD ground truth (docs/results.md has the 60-room numbers).
"$DIMR" export gt --split "$OUT/synth" --out "$OUT/gt"
"$DIMR" reconstruct "$OUT/synth" --mode generation --preset accurate --gt-meshes "$OUT/gt/meshes" \
  --out "$OUT/reconstruct"
"$DIMR" eval --pred "$OUT/reconstruct/meshes" --gt "$OUT/gt/meshes" --gt-points "$OUT/gt/points" \
  --metrics all 2>/dev/null | tee "$OUT/reconstruct_eval.md"
echo "demo: outputs in $OUT (synth/scans, synth/renders, synth/bags, bsp_*.png, bsp_eval.md, stage1/*.png,"
echo "      stage1_eval.md, reconstruct/meshes/*.ply, reconstruct/*.json, reconstruct/vis/*.png, reconstruct_eval.md)"
