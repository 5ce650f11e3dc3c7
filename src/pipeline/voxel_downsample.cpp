#include "dimr/pipeline/voxel_downsample.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>

#include "dimr/core/error.h"

namespace dimr::pipeline {
namespace {

std::string Who(const PointCloudInput& c) {
  return "voxel downsample of '" + (c.name.empty() ? std::string("point cloud") : c.name) + "'";
}

}  // namespace

VoxelDownsample VoxelMeanDownsample(const PointCloudInput& input, double voxel) {
  const std::string who = Who(input);
  if (!(voxel > 0.0) || !std::isfinite(voxel))
    throw InvalidArgument(who + ": voxel must be > 0, got " + std::to_string(voxel));
  const std::size_t n = input.points.size();
  const bool col = input.has_colors(), nor = input.has_normals();
  if (col && input.colors.size() != n)
    throw InvalidArgument(who + ": " + std::to_string(input.colors.size()) + " colours for " +
                          std::to_string(n) + " points");
  if (nor && input.normals.size() != n)
    throw InvalidArgument(who + ": " + std::to_string(input.normals.size()) + " normals for " +
                          std::to_string(n) + " points");
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY);
  for (std::size_t i = 0; i < n; ++i) {
    if (!input.points[i].allFinite())
      throw InvalidArgument(who + ": point " + std::to_string(i) + " is not finite");
    lo = lo.cwiseMin(input.points[i].cast<double>());
  }
  VoxelDownsample out;
  out.cloud.name = input.name;
  out.cell_of_point.resize(n);
  std::unordered_map<std::uint64_t, int> cell_of;
  cell_of.reserve(n);
  std::vector<Eigen::Vector3d> sum_p, sum_c, sum_n;
  std::vector<int> count;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = input.points[i].cast<double>();
    std::uint64_t key = 0;
    for (int k = 0; k < 3; ++k) {
      const double c = std::floor(p[k] / voxel) - std::floor(lo[k] / voxel);
      if (!(c < (1 << 21)))  // the key packs 21 + 21 + 21 bits
        throw InvalidArgument(who + ": the cloud spans more than 2^21 cells of " +
                              std::to_string(voxel) + " m (not a room in metres?)");
      key |= static_cast<std::uint64_t>(c) << (21 * k);
    }
    auto [it, added] = cell_of.emplace(key, static_cast<int>(sum_p.size()));
    if (added) {
      sum_p.push_back(Eigen::Vector3d::Zero());
      if (col) sum_c.push_back(Eigen::Vector3d::Zero());
      if (nor) sum_n.push_back(Eigen::Vector3d::Zero());
      count.push_back(0);
    }
    const int k = it->second;
    out.cell_of_point[i] = k;
    sum_p[k] += p;
    if (col) sum_c[k] += input.colors[i].cast<double>();
    if (nor) sum_n[k] += input.normals[i].cast<double>();
    ++count[k];
  }
  const std::size_t m = sum_p.size();
  out.cloud.points.resize(m);
  if (col) out.cloud.colors.resize(m);
  if (nor) out.cloud.normals.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    out.cloud.points[k] = (sum_p[k] / count[k]).cast<float>();
    if (col) out.cloud.colors[k] = (sum_c[k] / count[k]).cast<float>();
    if (nor) {
      const double len = sum_n[k].norm();
      out.cloud.normals[k] =
          len < 1e-6 ? Eigen::Vector3f::Zero() : Eigen::Vector3f((sum_n[k] / len).cast<float>());
    }
  }
  return out;
}

DensityNormalisation NormaliseDensity(const PointCloudInput& input, double voxel,
                                      double min_points_per_cell) {
  if (!(min_points_per_cell >= 1.0) || !std::isfinite(min_points_per_cell)) {
    throw InvalidArgument(Who(input) + ": min_points_per_cell must be >= 1, got " +
                          std::to_string(min_points_per_cell));
  }
  DensityNormalisation out;
  if (input.points.empty()) {
    out.cloud = input;
    return out;
  }
  VoxelDownsample reduced = VoxelMeanDownsample(input, voxel);
  out.points_per_cell =
      static_cast<double>(input.points.size()) / static_cast<double>(reduced.cloud.points.size());
  out.applied = out.points_per_cell > min_points_per_cell;
  out.cloud = out.applied ? std::move(reduced.cloud) : input;
  if (out.applied) out.cell_of_point = std::move(reduced.cell_of_point);
  return out;
}

std::vector<int> ExpandCellLabels(const std::vector<int>& cell_labels,
                                  const std::vector<int>& cell_of_point) {
  std::vector<int> out(cell_of_point.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    const int c = cell_of_point[i];
    if (c < 0 || static_cast<std::size_t>(c) >= cell_labels.size())
      throw InvalidArgument("ExpandCellLabels: point " + std::to_string(i) + " has cell " +
                            std::to_string(c) + " of " + std::to_string(cell_labels.size()));
    out[i] = cell_labels[c];
  }
  return out;
}

std::vector<int> ExpandCellPoints(const std::vector<int>& cells,
                                  const std::vector<int>& cell_of_point) {
  int max_cell = -1;
  for (int c : cell_of_point) max_cell = std::max(max_cell, c);
  std::vector<std::vector<int>> members(static_cast<std::size_t>(max_cell + 1));
  for (std::size_t i = 0; i < cell_of_point.size(); ++i)
    if (cell_of_point[i] >= 0) members[cell_of_point[i]].push_back(static_cast<int>(i));
  std::vector<int> out;
  for (int c : cells) {
    if (c < 0 || c > max_cell)
      throw InvalidArgument("ExpandCellPoints: cell " + std::to_string(c) + " of " +
                            std::to_string(max_cell + 1));
    out.insert(out.end(), members[c].begin(), members[c].end());
  }
  return out;
}

}  // namespace dimr::pipeline
