// Voxel-mean density normalisation of the node's input cloud. Stage 1 is trained on
// ScanNet-mesh-like density (SynthScan `mesh`: one fused point per occupied 4.5 cm cell); a
// robot's accumulated map cloud (every depth return, deduplicated at 2 cm) is ~5x denser and
// unfused, and the networks then find a quarter of the objects they find on the same room at
// training density (docs/ros.md, "Input density"). The node therefore replaces every occupied
// cell of `voxel_size` by the mean of its points (colours averaged, normals averaged and
// re-normalised) - pipeline::VoxelMeanDownsample, the same function `dimr real eval --voxel`
// uses. ROS-free.
#pragma once

#include <cstddef>

#include "dimr/ros/scene_backend.h"

namespace dimr::ros1 {

struct VoxelFilterStats {
  std::size_t input_points = 0;
  std::size_t output_points = 0;
  bool applied = false;  // false: voxel_size 0, an empty cloud, or an extent beyond 2^21 cells
};

// Replaces `cloud` by its voxel means (pipeline::VoxelMeanDownsample: cells [i, i+1) *
// voxel_size in the cloud's frame, in the order of each cell's first point: deterministic). Colours
// / normals are averaged when present (a normal whose mean is shorter than 1e-6 becomes zero =
// unknown). Leaves the cloud as it is when voxel_size <= 0, when the cloud is empty, or when it
// spans more than 2^21 cells along an axis (the pipeline then refuses it by its own max_extent).
// Expects finite coordinates.
VoxelFilterStats VoxelMeanFilter(BackendCloud* cloud, double voxel_size);

// Ceiling removal before stage 1 (pipeline::RemoveCeiling, docs/real.md "Ceilings"): a robot's
// map holds the ceiling, which stage 1 never saw in training and turns into furniture. Drops
// the ceiling's points from `cloud` when one is found (`remove_ceiling` parameter). Leaves the
// cloud as it is when it is empty or malformed (the pipeline reports that later).
struct CeilingFilterStats {
  bool found = false;
  double ceiling_z = 0;  // m in the cloud's frame when found
  std::size_t removed = 0;
};
CeilingFilterStats CeilingFilter(BackendCloud* cloud);

}  // namespace dimr::ros1
