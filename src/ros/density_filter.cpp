// Voxel-mean density normalisation (see density_filter.h).
#include "dimr/ros/density_filter.h"

#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace dimr::ros1 {

VoxelFilterStats VoxelMeanFilter(BackendCloud* cloud, double voxel_size) {
  VoxelFilterStats stats;
  const std::size_t n = cloud->points.size();
  stats.input_points = stats.output_points = n;
  if (!(voxel_size > 0) || n == 0) return stats;
  Eigen::Vector3d lo = cloud->points[0].cast<double>(), hi = lo;
  for (const Eigen::Vector3f& p : cloud->points) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  constexpr double kMaxCells = static_cast<double>(1u << 21);
  if (!(((hi - lo) / voxel_size).maxCoeff() < kMaxCells - 1)) return stats;

  const bool colors = cloud->colors.size() == n, normals = cloud->normals.size() == n;
  const double inv = 1.0 / voxel_size;
  struct Cell {
    Eigen::Vector3d p = Eigen::Vector3d::Zero(), c = Eigen::Vector3d::Zero(),
                    nrm = Eigen::Vector3d::Zero();
    int count = 0;
  };
  std::vector<Cell> cells;
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  index.reserve(n / 4 + 16);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = cloud->points[i].cast<double>();
    auto q = [&](int a) {
      return static_cast<std::uint64_t>(std::floor((p[a] - lo[a]) * inv)) & 0x1fffff;
    };
    const std::uint64_t key = q(0) | (q(1) << 21) | (q(2) << 42);
    auto [it, fresh] = index.emplace(key, static_cast<std::uint32_t>(cells.size()));
    if (fresh) cells.emplace_back();
    Cell& c = cells[it->second];
    c.p += p;
    if (colors) c.c += cloud->colors[i].cast<double>();
    if (normals) c.nrm += cloud->normals[i].cast<double>();
    ++c.count;
  }
  std::vector<Eigen::Vector3f> pts, cols, nrms;
  pts.reserve(cells.size());
  if (colors) cols.reserve(cells.size());
  if (normals) nrms.reserve(cells.size());
  for (const Cell& c : cells) {
    pts.push_back((c.p / c.count).cast<float>());
    if (colors) cols.push_back((c.c / c.count).cwiseMax(0.0).cwiseMin(1.0).cast<float>());
    if (normals) {
      const double len = c.nrm.norm();
      nrms.push_back(len > 1e-6 ? Eigen::Vector3f((c.nrm / len).cast<float>())
                                : Eigen::Vector3f::Zero());
    }
  }
  cloud->points = std::move(pts);
  cloud->colors = std::move(cols);
  cloud->normals = std::move(nrms);
  stats.output_points = cloud->points.size();
  stats.applied = true;
  return stats;
}

}  // namespace dimr::ros1
