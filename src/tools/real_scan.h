// A real scan as stage 1 sees it, for `dimr real eval` and `dimr real pseudo-label`: the
// product's preparation (a detected ceiling removed, then the density rule of
// `dimr reconstruct --input-voxel` / the node's input_voxel_size), with the maps back to the
// scan's own points.
#pragma once

#include <string>
#include <vector>

#include "dimr/pipeline/ceiling.h"
#include "dimr/pipeline/point_cloud_input.h"
#include "dimr/pipeline/voxel_downsample.h"
#include "tools/stats_inputs.h"

namespace dimr::tools {

struct RealScanInput {
  std::size_t scan_points = 0;        // points of the scan as read
  pipeline::CeilingRemoval cut;       // cut.cloud: the scan without its ceiling (all when none)
  double voxel = 0.0;                 // edge of the voxel means the network sees; 0 = none
  pipeline::VoxelDownsample reduced;  // when voxel > 0: the means and cut.cloud's point -> cell

  // The cloud the network sees.
  const pipeline::PointCloudInput& network() const { return voxel > 0 ? reduced.cloud : cut.cloud; }
  // Per network point, the scan points it stands for (indices into the scan as read).
  std::vector<std::vector<int>> ScanPointsOfNetworkPoints() const;
};

// `voxel`: "auto" (voxel means at the training density when the scan is denser than it), "0"
// (none) or an edge in (0, 1] m; anything else throws dimr::InvalidArgument naming --voxel.
// `grey`: every colour set to mid grey. Colours in [0, 1].
RealScanInput PrepareRealScan(const StatsCloud& c, const pipeline::CeilingConfig& ceiling,
                              const std::string& voxel, bool grey = false);

}  // namespace dimr::tools
