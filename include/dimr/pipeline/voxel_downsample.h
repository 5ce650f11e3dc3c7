// Voxel-mean down-sampling of an input cloud to the density stage 1 is trained on (SynthScan's
// fused `mesh` density: one point per occupied 4.5 cm cell of surface). Real ScanNet vh_clean_2
// vertices are ~1.3 cm apart and a robot's accumulated map cloud is denser still; the networks
// see a different point pattern there (docs/real.md, docs/ros.md "Input density"). Predictions
// on the reduced cloud go back to every input point through `cell_of_point`.
#pragma once

#include <vector>

#include "dimr/pipeline/point_cloud_input.h"

namespace dimr::pipeline {

// Stage 1's training density: SynthScan `mesh` keeps one fused point per occupied cell of this
// edge (m). The CLI's `--input-voxel auto` and the node's `input_voxel_size` default use it.
inline constexpr double kTrainingVoxelSize = 0.045;
// `auto` normalises a cloud holding more points than this per occupied training cell.
inline constexpr double kDenserThanTrainingPointsPerCell = 1.5;

struct VoxelDownsample {
  PointCloudInput cloud;           // one point per occupied cell, in order of first appearance
  std::vector<int> cell_of_point;  // per input point: its index in `cloud`
};

// Cells [i, i+1) * voxel in the cloud's frame. Each occupied cell becomes the mean of its
// points, of their colours (when present) and of their normals (re-normalised; a mean shorter
// than 1e-6 becomes zero = unknown). Deterministic. Throws dimr::InvalidArgument naming the
// cloud for voxel <= 0 or not finite, a non-finite point (its index), colours / normals of
// another count than the points, or an extent beyond 2^21 cells along an axis.
VoxelDownsample VoxelMeanDownsample(const PointCloudInput& input, double voxel);

// Density normalisation: the voxel means when the input is denser than stage 1's training
// density, i.e. holds more than `min_points_per_cell` points per occupied cell of `voxel` on
// average (SynthScan mesh density: ~1; a robot's accumulated map cloud or a real ScanNet mesh:
// 4-15); otherwise the input unchanged. `applied` says which; `points_per_cell` is the measured
// ratio either way. Throws as VoxelMeanDownsample and for min_points_per_cell < 1.
struct DensityNormalisation {
  PointCloudInput cloud;
  std::vector<int> cell_of_point;  // when applied: per input point its index in `cloud`
  bool applied = false;
  double points_per_cell = 0.0;
};
DensityNormalisation NormaliseDensity(const PointCloudInput& input, double voxel,
                                      double min_points_per_cell);

// Per-point labels of the reduced cloud back on the input points: out[i] = cell_labels[cell_of
// _point[i]]. Throws dimr::InvalidArgument when a cell index is out of range.
std::vector<int> ExpandCellLabels(const std::vector<int>& cell_labels,
                                  const std::vector<int>& cell_of_point);
// Point indices of the reduced cloud -> the input points in those cells (input order within
// each cell, cells in the given order).
std::vector<int> ExpandCellPoints(const std::vector<int>& cells,
                                  const std::vector<int>& cell_of_point);

}  // namespace dimr::pipeline
