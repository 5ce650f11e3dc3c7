#!/usr/bin/env bash
# The README's first command: the dimr nodelet on a rosbag, with rviz.
#  1. set-up if needed (scripts/setup.sh: apt packages, configure, build; DIMR_DEMO_SETUP=0 skips);
#  2. one SynthScan test room (seed 7) with its ground truth and a rosbag (/tf, /camera/points,
#     /map_cloud every 10 frames) -> demo_out/synth/;
#  3. the bag replayed (use_sim_time, --clock) through dimr/ReconstructionNodelet in a nodelet
#     manager with the default models (launch/replay.launch), rviz (config/dimr.rviz) on a
#     virtual X server (Xvfb);
#  4. once the last map cloud is reconstructed: ~save_scene into demo_out/ (instance meshes as
#     PLY in `map` + scene.json), a screenshot of rviz -> demo_out/rviz.png, and a summary
#     (instances per class, latency) -> stdout and demo_out/summary.json.
# The offline library demo (dimr synth / reconstruct / eval on two rooms) is scripts/demo_offline.sh.
set -eo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
cd "$REPO"
if [ "${DIMR_DEMO_SETUP:-1}" = 1 ]; then "$REPO/scripts/setup.sh"; fi
OUT="$REPO/demo_out"
DIMR=build/devel/bin/dimr
for need in "$DIMR" build/devel/setup.bash; do
  [ -e "$need" ] || { echo "demo: $need missing (run scripts/setup.sh)" >&2; exit 1; }
done
for tool in Xvfb import roslaunch rviz; do
  command -v "$tool" > /dev/null || { echo "demo: '$tool' not found (scripts/setup.sh installs it)" >&2; exit 1; }
done
rm -rf "$OUT"
mkdir -p "$OUT"

echo "demo: generating a SynthScan test room and its rosbag"
"$DIMR" synth --scenes 1 --seed 7 --split test --out "$OUT/synth" --bags --quiet > "$OUT/synth.log"
BAG=$(ls "$OUT"/synth/bags/*.bag | head -n 1)
GT=$(ls "$OUT"/synth/scans/*/*.synthscan.json | head -n 1)
START=$(date +%s)

# shellcheck source=scripts/ros_env.sh
source scripts/ros_env.sh
DISP=$((50 + RANDOM % 400))
while [ -e "/tmp/.X$DISP-lock" ]; do DISP=$((DISP + 1)); done

XPID="" LPID=""
cleanup() {
  if [ -n "$LPID" ]; then kill -INT "$LPID" 2> /dev/null || true; wait "$LPID" 2> /dev/null || true; fi
  if [ -n "$XPID" ]; then kill "$XPID" 2> /dev/null || true; wait "$XPID" 2> /dev/null || true; fi
}
trap cleanup EXIT

Xvfb ":$DISP" -screen 0 1024x768x24 -nolisten tcp > "$OUT/xvfb.log" 2>&1 &
XPID=$!
export DISPLAY=":$DISP"
echo "demo: replaying $(basename "$BAG") through dimr/ReconstructionNodelet (master :$PORT, display $DISPLAY)"
roslaunch -p "$PORT" dimr replay.launch bag:="$BAG" manager:=dimr_manager rviz:=true \
  start_delay:=5 > "$OUT/roslaunch.log" 2>&1 &
LPID=$!
if ! /usr/bin/python3 scripts/demo_ros_client.py "$BAG" "$OUT" "${DIMR_DEMO_TIMEOUT:-900}" "$GT"; then
  echo "demo: failed; the node's output is in $OUT/roslaunch.log" >&2
  tail -n 30 "$OUT/roslaunch.log" >&2
  exit 1
fi
sleep "${DIMR_DEMO_RENDER_WAIT:-4}"  # rviz draws the latched markers
import -window root "$OUT/rviz.png"
echo "demo: rviz screenshot $OUT/rviz.png"
cleanup
LPID="" XPID=""
echo "demo: replay + reconstruction + save + screenshot took $(( $(date +%s) - START )) s"
echo "demo: outputs in $OUT: instance_*.ply + scene.json (save_scene), summary.json, rviz.png,"
echo "      synth/ (the room: ScanNet/Scan2CAD/ShapeNet files, bags/), roslaunch.log"
