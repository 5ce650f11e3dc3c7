// Voxel-mean density normalisation: cell means of points, colours and normals, first-point
// order, the cell count of a dense plane, and the cases that leave the cloud unchanged.
#include "dimr/ros/density_filter.h"

#include <gtest/gtest.h>

namespace dimr::ros1 {
namespace {

TEST(VoxelMeanFilter, CellMeansOfPointsColoursAndNormals) {
  BackendCloud c;
  // Cell (0,0,0) relative to the lower corner (0, 0, 0): two points; cell (10,0,0): one point.
  c.points = {{0.01f, 0.01f, 0.01f}, {0.5f, 0.0f, 0.0f}, {0.03f, 0.02f, 0.04f}};
  c.colors = {{1.0f, 0.0f, 0.2f}, {0.5f, 0.5f, 0.5f}, {0.0f, 1.0f, 0.4f}};
  c.normals = {{1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, {0.0f, 1.0f, 0.0f}};
  const VoxelFilterStats s = VoxelMeanFilter(&c, 0.045);
  EXPECT_TRUE(s.applied);
  EXPECT_EQ(s.input_points, 3u);
  EXPECT_EQ(s.output_points, 2u);
  ASSERT_EQ(c.points.size(), 2u);
  ASSERT_EQ(c.colors.size(), 2u);
  ASSERT_EQ(c.normals.size(), 2u);
  // Order of the cells' first points: the two-point cell first.
  EXPECT_NEAR(c.points[0].x(), 0.02f, 1e-6f);
  EXPECT_NEAR(c.points[0].y(), 0.015f, 1e-6f);
  EXPECT_NEAR(c.points[0].z(), 0.025f, 1e-6f);
  EXPECT_NEAR(c.colors[0].x(), 0.5f, 1e-6f);
  EXPECT_NEAR(c.colors[0].y(), 0.5f, 1e-6f);
  EXPECT_NEAR(c.colors[0].z(), 0.3f, 1e-6f);
  EXPECT_NEAR(c.normals[0].x(), std::sqrt(0.5f), 1e-6f);
  EXPECT_NEAR(c.normals[0].y(), std::sqrt(0.5f), 1e-6f);
  EXPECT_NEAR(c.normals[0].z(), 0.0f, 1e-6f);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(0.5f, 0.0f, 0.0f));
  EXPECT_EQ(c.normals[1], Eigen::Vector3f(0.0f, 0.0f, 1.0f));
}

TEST(VoxelMeanFilter, OppositeNormalsBecomeUnknownAndMissingChannelsStayMissing) {
  BackendCloud c;
  c.points = {{0.0f, 0.0f, 0.0f}, {0.01f, 0.0f, 0.0f}};
  c.normals = {{0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, -1.0f}};
  VoxelMeanFilter(&c, 0.05);
  ASSERT_EQ(c.points.size(), 1u);
  EXPECT_TRUE(c.colors.empty());
  ASSERT_EQ(c.normals.size(), 1u);
  EXPECT_EQ(c.normals[0], Eigen::Vector3f::Zero());
}

TEST(VoxelMeanFilter, DensePlaneGetsOnePointPerOccupiedCell) {
  BackendCloud c;
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 200; ++j)
      c.points.emplace_back(0.01f + i * 0.005f, 0.01f + j * 0.005f, 0.7f);
  ASSERT_EQ(c.points.size(), 40401u);
  const VoxelFilterStats s = VoxelMeanFilter(&c, 0.045);
  // x and y in [0.01, 1.01]: cells 0..22 on each axis (absolute grid), one layer in z.
  EXPECT_EQ(s.output_points, 23u * 23u);
  EXPECT_EQ(c.points.size(), 23u * 23u);
  for (const Eigen::Vector3f& p : c.points) {
    EXPECT_GE(p.x(), 0.01f - 1e-5f);
    EXPECT_LE(p.x(), 1.01f + 1e-5f);
    EXPECT_NEAR(p.z(), 0.7f, 1e-6f);
  }
  // A second pass at the same size keeps every cell (idempotent up to the grid shift).
  const std::size_t n = c.points.size();
  VoxelMeanFilter(&c, 0.045);
  EXPECT_GE(c.points.size(), n * 9 / 10);
  EXPECT_LE(c.points.size(), n);
}

TEST(VoxelMeanFilter, LeavesTheCloudAloneWhenOffEmptyOrTooLarge) {
  BackendCloud c;
  c.points = {{0.0f, 0.0f, 0.0f}, {0.001f, 0.0f, 0.0f}};
  EXPECT_FALSE(VoxelMeanFilter(&c, 0.0).applied);
  EXPECT_EQ(c.points.size(), 2u);
  BackendCloud empty;
  EXPECT_FALSE(VoxelMeanFilter(&empty, 0.045).applied);
  BackendCloud huge;
  huge.points = {{0.0f, 0.0f, 0.0f}, {1.0e5f, 0.0f, 0.0f}, {1.0e5f, 0.0f, 0.0f}};
  const VoxelFilterStats s = VoxelMeanFilter(&huge, 0.01);  // 1e7 cells > 2^21
  EXPECT_FALSE(s.applied);
  EXPECT_EQ(huge.points.size(), 3u);
  EXPECT_EQ(s.output_points, 3u);
}

// A 3 x 3 m room: floor, four walls to 2.5 m, a ceiling at 2.5 m (2 cm grid); colours encode
// the height so that their alignment with the points can be checked after the filter.
BackendCloud RoomWithCeiling(bool ceiling) {
  BackendCloud c;
  c.name = "room";
  auto add = [&](float x, float y, float z) {
    c.points.emplace_back(x, y, z);
    c.colors.emplace_back(z / 2.5f, 0.5f, 0.5f);
  };
  for (int i = 0; i <= 150; ++i) {
    for (int j = 0; j <= 150; ++j) {
      add(0.02f * i, 0.02f * j, 0.f);
      if (ceiling) add(0.02f * i, 0.02f * j, 2.5f);
    }
    for (int k = 1; k < 125; ++k) {
      const float t = 0.02f * i, z = 0.02f * k;
      add(t, 0.f, z), add(t, 3.f, z), add(0.f, t, z), add(3.f, t, z);
    }
  }
  return c;
}

TEST(CeilingFilter, DropsTheCeilingAndKeepsColoursAligned) {
  BackendCloud c = RoomWithCeiling(true);
  const std::size_t n = c.points.size();
  const CeilingFilterStats s = CeilingFilter(&c);
  ASSERT_TRUE(s.found);
  EXPECT_NEAR(s.ceiling_z, 2.5, 0.01);
  EXPECT_GE(s.removed, 151u * 151u);  // the ceiling and the walls' top 3 cm
  EXPECT_EQ(c.points.size(), n - s.removed);
  ASSERT_EQ(c.colors.size(), c.points.size());
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    EXPECT_LT(c.points[i].z(), 2.47f);
    EXPECT_FLOAT_EQ(c.colors[i].x(), c.points[i].z() / 2.5f);
  }
  // Without a ceiling, or empty: unchanged.
  BackendCloud open = RoomWithCeiling(false);
  const std::size_t m = open.points.size();
  EXPECT_FALSE(CeilingFilter(&open).found);
  EXPECT_EQ(open.points.size(), m);
  EXPECT_EQ(open.colors.size(), m);
  BackendCloud empty;
  EXPECT_FALSE(CeilingFilter(&empty).found);
}

}  // namespace
}  // namespace dimr::ros1
