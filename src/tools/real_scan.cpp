#include "tools/real_scan.h"

#include <cmath>
#include <cstdlib>

#include "dimr/core/error.h"

namespace dimr::tools {

std::vector<std::vector<int>> RealScanInput::ScanPointsOfNetworkPoints() const {
  const std::size_t kept = cut.cloud.points.size();
  const auto scan_index = [&](std::size_t i) {
    return cut.found ? cut.kept[i] : static_cast<int>(i);
  };
  std::vector<std::vector<int>> out(network().points.size());
  for (std::size_t i = 0; i < kept; ++i) {
    const std::size_t j = voxel > 0 ? static_cast<std::size_t>(reduced.cell_of_point[i]) : i;
    out[j].push_back(scan_index(i));
  }
  return out;
}

RealScanInput PrepareRealScan(const StatsCloud& c, const pipeline::CeilingConfig& ceiling,
                              const std::string& voxel, bool grey) {
  pipeline::PointCloudInput scan;
  scan.name = c.name;
  for (const auto& p : c.points) scan.points.push_back(p.cast<float>());
  for (const auto& col : c.colors) scan.colors.push_back(col.cast<float>() / 255.0f);
  if (grey) scan.colors.assign(scan.points.size(), Eigen::Vector3f::Constant(0.5f));
  RealScanInput r;
  r.scan_points = scan.points.size();
  // As the product does: a detected ceiling leaves before stage 1 (its points: no class).
  r.cut = pipeline::RemoveCeiling(std::move(scan), ceiling);
  // The product's density rule (dimr reconstruct --input-voxel, the node's input_voxel_size):
  // auto = voxel means at the training density when the scan is denser than it.
  if (voxel == "auto") {
    pipeline::DensityNormalisation d = pipeline::NormaliseDensity(
        r.cut.cloud, pipeline::kTrainingVoxelSize, pipeline::kDenserThanTrainingPointsPerCell);
    if (d.applied) {
      r.voxel = pipeline::kTrainingVoxelSize;
      r.reduced.cloud = std::move(d.cloud);
      r.reduced.cell_of_point = std::move(d.cell_of_point);
    }
  } else {
    char* end = nullptr;
    r.voxel = std::strtod(voxel.c_str(), &end);
    if (voxel.empty() || *end != '\0' || !std::isfinite(r.voxel) || r.voxel < 0 || r.voxel > 1) {
      throw InvalidArgument("--voxel: expected auto, 0 or an edge in (0, 1] m, got '" + voxel +
                            "'");
    }
    if (r.voxel > 0) r.reduced = pipeline::VoxelMeanDownsample(r.cut.cloud, r.voxel);
  }
  return r;
}

}  // namespace dimr::tools
