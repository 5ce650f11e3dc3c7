#!/usr/bin/env bash
# Installs every dependency of dimr with apt (idempotent: a no-op when all are present),
# then configures and builds the package with plain CMake into build/ (Recipe B of
# docs/ros-build.md). Usage: scripts/setup.sh [--no-build] [--no-apt]
set -eo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
cd "$REPO"

PACKAGES=(
  build-essential cmake git
  # ROS 1 (Debian's own packaging)
  ros-core-dev ros-core-python-dev python3-rostest
  libnodeletlib-dev libnodeletlib-tools
  libtf2-ros-dev libtf2-eigen-dev libtf2-sensor-msgs-dev tf2-tools
  libpcl-conversions-dev libpcl-dev liboctomap-dev
  libdiagnostic-updater-dev libpcl-ros-dev   # node diagnostics; pcl_ros filter nodelets (launch option)
  # core libraries
  libeigen3-dev libembree-dev libopen3d-dev nlohmann-json3-dev libyaml-cpp-dev libcli11-dev zlib1g-dev
  # real furniture (SynthScan v2): Sweet Home 3D catalogues, texture decoders
  sweethome3d-furniture libpng-dev libjpeg-dev
  # LibTorch (CPU) + a fast BLAS for it (see docs/ros-build.md, BLAS section)
  libtorch-dev libopenblas0-openmp
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # scripts/demo.sh: rviz on a virtual X server, screenshot with ImageMagick's import
  rviz xvfb imagemagick
)

DO_APT=1
DO_BUILD=1
for arg in "$@"; do
  case "$arg" in
    --no-apt) DO_APT=0 ;;
    --no-build) DO_BUILD=0 ;;
    *) echo "setup.sh: unknown argument '$arg'" >&2; exit 2 ;;
  esac
done

if [ "$DO_APT" = 1 ]; then
  missing=()
  for p in "${PACKAGES[@]}"; do
    case "$p" in \#*) continue ;; esac
    status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
    [ "$status" = "install ok installed" ] || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup.sh: installing ${#missing[@]} missing packages: ${missing[*]}"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
  else
    echo "setup.sh: all apt dependencies present"
  fi
fi

if [ "$DO_BUILD" = 1 ]; then
  export ROS_HOME="$REPO/build/ros_home" ROS_HOSTNAME=localhost
  # The devel python folder must exist before the first configure (recipe pitfall P3).
  mkdir -p build/devel/lib/python3/dist-packages "$ROS_HOME"
  # Use Debian's python3, not a pyenv shim (recipe pitfall P1).
  cmake -S . -B build -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo ${DIMR_CMAKE_ARGS:-}
  cmake --build build -j"${DIMR_JOBS:-2}"
  echo "setup.sh: built; the dimr command is build/devel/bin/dimr (build/bin/dimr without ROS)"
fi
