#!/usr/bin/env bash
# Packs what a PyTorch-only GPU host lacks into .devdeps/ (git-ignored), from this Debian 12
# machine's packages: header-only Eigen, CLI11, nlohmann-json, GoogleTest (static), yaml-cpp
# (shared), Embree 3 + TBB (shared; Embree travels xz-compressed: 44 MB -> 9 MB). The data layer
# (SynthScan) then builds on the GPU host, so training rooms are generated there instead of
# carrying the 1.1 GB stage-1 cache. Run once here; the device command names .devdeps in carry.
#   scripts/device/prepare_deps.sh && du -sh .devdeps      # ~23 MB
set -euo pipefail
REPO=$(cd "$(dirname "$0")/../.." && pwd)
D=$REPO/.devdeps
A=/usr/lib/x86_64-linux-gnu
L=$D/lib/x86_64-linux-gnu
grep -qx '/.devdeps/' "$REPO/.git/info/exclude" 2>/dev/null || echo '/.devdeps/' >> "$REPO/.git/info/exclude"
mkdir -p "$D/include" "$D/share/cmake" "$D/share/eigen3" "$L/cmake" "$D/lib/cmake/embree-3.13.5" "$D/xz"
for h in eigen3 CLI nlohmann gtest gmock yaml-cpp embree3; do cp -a "/usr/include/$h" "$D/include/"; done
cp -a /usr/share/eigen3/cmake "$D/share/eigen3/"
cp -a /usr/share/cmake/CLI11 /usr/share/cmake/nlohmann_json "$D/share/cmake/"
cp -a $A/libgtest*.a $A/libgmock*.a $A/libyaml-cpp.so* $A/libtbb.so.12* "$L/"
cp -a $A/cmake/GTest $A/cmake/yaml-cpp "$L/cmake/"
xz -T2 -6 -c $A/libembree3.so.3.13.5 > "$D/xz/libembree3.so.3.13.5.xz"
# Debian's embree-config.cmake needs TBB's CMake package; this one only imports the library.
cat > "$D/lib/cmake/embree-3.13.5/embree-config.cmake" <<'CFG'
# Relocatable Embree 3 for a training host: the library unpacked from xz/ by the device script,
# headers in include/; libtbb.so.12 beside it, found through LD_LIBRARY_PATH.
get_filename_component(_emb_prefix "${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
if(NOT TARGET embree)
  add_library(embree SHARED IMPORTED)
  set_target_properties(embree PROPERTIES
    IMPORTED_LOCATION "${_emb_prefix}/lib/x86_64-linux-gnu/libembree3.so.3.13.5"
    IMPORTED_SONAME "libembree3.so.3"
    INTERFACE_INCLUDE_DIRECTORIES "${_emb_prefix}/include")
endif()
set(EMBREE_VERSION 3.13.5)
CFG
cat > "$D/lib/cmake/embree-3.13.5/embree-config-version.cmake" <<'CFG'
set(PACKAGE_VERSION 3.13.5)
set(PACKAGE_VERSION_COMPATIBLE FALSE)
if(PACKAGE_FIND_VERSION_MAJOR EQUAL 3)
  set(PACKAGE_VERSION_COMPATIBLE TRUE)
  if(PACKAGE_FIND_VERSION VERSION_EQUAL PACKAGE_VERSION)
    set(PACKAGE_VERSION_EXACT TRUE)
  endif()
endif()
CFG
du -sh "$D"
