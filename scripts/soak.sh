#!/usr/bin/env bash
# Soak benchmark of the dimr nodelet (docs/ros.md, "Soak"): a SynthScan test room's bag, its
# /map_cloud messages replayed in a loop for SIM_MINUTES of simulated time (SPEEDUP x faster
# than real time; scripts/soak.py publishes /clock) through dimr/ReconstructionNodelet with
# config/default.yaml. Reports latency and RSS over time: out/soak/soak.{json,csv,svg} + a table.
#   scripts/soak.sh [SIM_MINUTES=30] [SPEEDUP=4] [BAG]
# Needs the catkin build (scripts/setup.sh). Not a test: run it by hand (nice -n 10 on a shared
# machine).
set -eo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
cd "$REPO"
SIM_MINUTES=${1:-30}
SPEEDUP=${2:-4}
BAG=${3:-}
OUT="$REPO/out/soak"
DIMR=build/devel/bin/dimr
[ -e build/devel/setup.bash ] || { echo "soak: build/devel/setup.bash missing (scripts/setup.sh)" >&2; exit 1; }
mkdir -p "$OUT"
if [ -z "$BAG" ]; then
  if [ ! -e "$OUT/synth/bags/scene8000_00.bag" ]; then
    "$DIMR" synth --scenes 1 --seed 7 --split test --out "$OUT/synth" --bags --quiet > "$OUT/synth.log"
  fi
  BAG="$OUT/synth/bags/scene8000_00.bag"
fi
# shellcheck source=scripts/ros_env.sh
source scripts/ros_env.sh
LPID=""
cleanup() {
  if [ -n "$LPID" ]; then kill -INT "$LPID" 2> /dev/null || true; wait "$LPID" 2> /dev/null || true; fi
}
trap cleanup EXIT
# replay.launch with play:=false: use_sim_time true, the nodelet in its own manager, no rosbag.
roslaunch -p "$PORT" dimr replay.launch bag:="$BAG" play:=false manager:=dimr_manager \
  > "$OUT/roslaunch.log" 2>&1 &
LPID=$!
# The manager process that hosts the nodelet (its CPU time per reconstruction is reported).
NODE_PID=0
for _ in $(seq 1 100); do
  NODE_PID=$(pgrep -f "__name:=dimr_manager" | head -n 1 || true)
  [ -n "$NODE_PID" ] && break
  sleep 0.2
done
/usr/bin/python3 scripts/soak.py "$BAG" "$OUT/soak" --sim-minutes "$SIM_MINUTES" --speedup "$SPEEDUP" \
  --node-pid "${NODE_PID:-0}" \
  --warmup-minutes "$(/usr/bin/python3 -c "print(min(5.0, $SIM_MINUTES / 6))")"
