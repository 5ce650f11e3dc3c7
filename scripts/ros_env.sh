# Sourced by scripts/demo.sh and scripts/soak.sh (REPO set, cwd = REPO): the devel space of
# build/, a ROS_HOME inside the build and a master on a random free-ish port, so runs never
# meet another master (CI, rostests, a user's roscore).
set +u
# shellcheck disable=SC1091
source build/devel/setup.bash
set -u
export ROS_HOME="$REPO/build/ros_home" ROS_HOSTNAME=localhost
mkdir -p "$ROS_HOME"
PORT=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI="http://localhost:$PORT"
