#!/usr/bin/env bash
# Sourced by the device training scripts: unpacks the libraries carried in .devdeps/ (made by
# scripts/device/prepare_deps.sh) and builds `dimr` against the GPU host's PyTorch LibTorch once.
# Sets B (the dimr binary), T0 (start time, kept if the caller set it), el() (seconds since T0).
OUT=${OUT:-out/device}
mkdir -p "$OUT"
T0=${T0:-$(date +%s)}
export T0
el() { echo $(( $(date +%s) - T0 )); }
D=$PWD/.devdeps
L=$D/lib/x86_64-linux-gnu
export LD_LIBRARY_PATH=$L:${LD_LIBRARY_PATH:-}
B=$PWD/build-host/bin/dimr
if [ ! -x "$B" ]; then
  [ -d "$D" ] || { echo "host_setup: no .devdeps/ (carry it; scripts/device/prepare_deps.sh)"; exit 1; }
  xz -T0 -dc "$D/xz/libembree3.so.3.13.5.xz" > "$L/libembree3.so.3.13.5" || exit 1
  ln -sf libembree3.so.3.13.5 "$L/libembree3.so.3"
  ln -sf libtbb.so.12.8 "$L/libtbb.so.12"
  ln -sf libyaml-cpp.so.0.7.0 "$L/libyaml-cpp.so.0.7"
  ln -sf libyaml-cpp.so.0.7 "$L/libyaml-cpp.so"
  export DIMR_DEPS_PREFIX=$D DIMR_JOBS=${DIMR_JOBS:-$(nproc)}
  nvidia-smi -L; nproc; g++ --version | head -1
  python3 -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available())'
  scripts/build_training_host.sh > "$OUT/build.log" 2>&1 || { tail -80 "$OUT/build.log"; exit 1; }
  echo "build done at $(el) s"
fi
