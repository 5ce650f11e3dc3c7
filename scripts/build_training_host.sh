#!/usr/bin/env bash
# Builds the `dimr` command on a training host that has only a PyTorch install (its bundled
# LibTorch, CPU or CUDA), a C++17 compiler and CMake: no ROS, no PCL, no apt packages.
# Header-only dependencies (Eigen, CLI11, nlohmann-json; GoogleTest for the tests) and yaml-cpp
# (model cards: the pipeline layer, and with it `dimr train bsp`, needs it) are taken from
# $DIMR_DEPS_PREFIX if set (a prefix with include/ and share/ or lib/cmake, e.g. the .devdeps/ of
# scripts/device/prepare_deps.sh), else from the system. Layers whose dependencies are missing
# (data, ros; pipeline without yaml-cpp) are skipped, and so are the `dimr` subcommands that
# need them. Output: build-host/bin/dimr.
#   scripts/build_training_host.sh [--tests]
set -eo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
cd "$REPO"
PY=${PYTHON:-python3}
TORCH_PREFIX=$($PY -c 'import torch; print(torch.utils.cmake_prefix_path)')
PREFIX="$TORCH_PREFIX"
if [ -n "${DIMR_DEPS_PREFIX:-}" ]; then PREFIX="$DIMR_DEPS_PREFIX;$PREFIX"; fi
cmake -S . -B build-host -DDIMR_WITH_ROS=OFF -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$PREFIX" ${DIMR_CMAKE_ARGS:-}
JOBS=${DIMR_JOBS:-$(nproc)}
cmake --build build-host --target dimr_cli -j"$JOBS"
if [ "${1:-}" = "--tests" ]; then
  cmake --build build-host --target tests -j"$JOBS"
  ctest --test-dir build-host --output-on-failure -j"$JOBS"
fi
