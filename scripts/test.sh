#!/usr/bin/env bash
# Installs, builds, then runs every test (gtest per layer, fuzz smoke runs, rostests).
# This is the README's test command and what CI (.ci/run) runs.
set -eo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
cd "$REPO"
"$REPO/scripts/setup.sh" "$@"
export ROS_HOME="$REPO/build/ros_home" ROS_HOSTNAME=localhost
cmake --build build -j"${DIMR_JOBS:-2}" --target tests
ntests=$(ctest --test-dir build -N | sed -n 's/^Total Tests: *//p')
if [ -z "$ntests" ] || [ "$ntests" = 0 ]; then
  echo "test.sh: no tests registered - refusing to report success" >&2
  exit 1
fi
ctest --test-dir build --output-on-failure -j"${DIMR_JOBS:-2}"
