#include "dimr/pipeline/voxel_downsample.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dimr/core/error.h"

namespace dimr::pipeline {
namespace {

using V = Eigen::Vector3f;

TEST(VoxelMeanDownsample, MeansPerCellAndTheMapBack) {
  // Cells of 0.1 m: points 0, 1, 3 share the first cell, point 2 is alone in the next one.
  PointCloudInput in;
  in.name = "t";
  in.points = {V(0.01f, 0.02f, 0.03f), V(0.05f, 0.06f, 0.07f), V(0.15f, 0.f, 0.f),
               V(0.09f, 0.01f, 0.02f)};
  in.colors = {V(0, 0, 0), V(1, 0, 0), V(0, 1, 0), V(0, 0, 1)};
  in.normals = {V(0, 0, 1), V(0, 0, -1), V(1, 0, 0), V(0, 1, 0)};
  const VoxelDownsample d = VoxelMeanDownsample(in, 0.1);
  ASSERT_EQ(d.cloud.points.size(), 2u);
  EXPECT_EQ(d.cell_of_point, std::vector<int>({0, 0, 1, 0}));
  EXPECT_LT((d.cloud.points[0] - V(0.05f, 0.03f, 0.04f)).norm(), 1e-6f);
  EXPECT_LT((d.cloud.points[1] - V(0.15f, 0.f, 0.f)).norm(), 1e-6f);
  EXPECT_LT((d.cloud.colors[0] - V(1.f / 3, 0, 1.f / 3)).norm(), 1e-6f);
  // (0,0,1) + (0,0,-1) + (0,1,0) -> (0,1,0) re-normalised.
  EXPECT_LT((d.cloud.normals[0] - V(0, 1, 0)).norm(), 1e-6f);
  EXPECT_EQ(d.cloud.name, "t");
  // Back to the input points.
  EXPECT_EQ(ExpandCellLabels({7, 9}, d.cell_of_point), std::vector<int>({7, 7, 9, 7}));
  EXPECT_EQ(ExpandCellPoints({1, 0}, d.cell_of_point), std::vector<int>({2, 0, 1, 3}));
  EXPECT_THROW(ExpandCellLabels({7}, d.cell_of_point), InvalidArgument);
  EXPECT_THROW(ExpandCellPoints({2}, d.cell_of_point), InvalidArgument);
}

TEST(VoxelMeanDownsample, DensityOfAGridAndBadInput) {
  // A 1 cm grid of 60 x 60 points on a plane: 4.5 cm cells hold ~20 points each.
  PointCloudInput in;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) in.points.emplace_back(0.01f * i + 0.005f, 0.01f * j + 0.005f, 0);
  const VoxelDownsample d = VoxelMeanDownsample(in, 0.045);
  EXPECT_EQ(d.cloud.points.size(), 14u * 14u);  // ceil(0.6 / 0.045) = 14 cells per axis
  EXPECT_TRUE(d.cloud.colors.empty());
  EXPECT_THROW(VoxelMeanDownsample(in, 0.0), InvalidArgument);
  EXPECT_THROW(VoxelMeanDownsample(in, std::nan("")), InvalidArgument);
  PointCloudInput bad = in;
  bad.points[5].x() = NAN;
  EXPECT_THROW(VoxelMeanDownsample(bad, 0.05), InvalidArgument);
  bad = in;
  bad.colors.resize(3);
  EXPECT_THROW(VoxelMeanDownsample(bad, 0.05), InvalidArgument);
  bad = in;
  bad.points[0] = V(1e6f, 0, 0);  // millimetres, say: beyond 2^21 cells of 1 cm
  EXPECT_THROW(VoxelMeanDownsample(bad, 0.01), InvalidArgument);
}

TEST(NormaliseDensity, ReducesDenseCloudsOnlyAndReportsTheRatio) {
  // 1 cm grid: 3600 points in 196 cells of 4.5 cm -> 18.4 points per cell: reduced.
  PointCloudInput dense;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j)
      dense.points.emplace_back(0.01f * i + 0.005f, 0.01f * j + 0.005f, 0);
  const DensityNormalisation a = NormaliseDensity(dense, 0.045, 1.5);
  EXPECT_TRUE(a.applied);
  EXPECT_NEAR(a.points_per_cell, 3600.0 / 196.0, 1e-9);
  EXPECT_EQ(a.cloud.points.size(), 196u);
  // Every input point knows its cell (the same map VoxelMeanDownsample gives).
  EXPECT_EQ(a.cell_of_point, VoxelMeanDownsample(dense, 0.045).cell_of_point);
  // 5 cm grid (coarser than the cell): one point per occupied cell: left as it is.
  PointCloudInput sparse;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) sparse.points.emplace_back(0.05f * i + 0.01f, 0.05f * j, 0.3f);
  const DensityNormalisation b = NormaliseDensity(sparse, 0.045, 1.5);
  EXPECT_FALSE(b.applied);
  EXPECT_NEAR(b.points_per_cell, 1.0, 1e-9);
  EXPECT_EQ(b.cloud.points, sparse.points);
  EXPECT_TRUE(b.cell_of_point.empty());
  // The same dense grid with a threshold above its ratio is kept.
  EXPECT_FALSE(NormaliseDensity(dense, 0.045, 20.0).applied);
  // Empty: nothing to do; bad thresholds are errors.
  EXPECT_FALSE(NormaliseDensity(PointCloudInput{}, 0.045, 1.5).applied);
  EXPECT_THROW(NormaliseDensity(dense, 0.045, 0.5), InvalidArgument);
  EXPECT_THROW(NormaliseDensity(dense, 0.0, 1.5), InvalidArgument);
}

}  // namespace
}  // namespace dimr::pipeline
