// OctoMap scan integration: occupied cells where scans hit, free space cleared by later scans,
// colours carried, memory bounded by the map cube and the cell cap.
#include "dimr/ros/scan_map.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

// A wall at x (y, z in [-half, half]) seen from the origin.
std::vector<Eigen::Vector3f> Wall(float x, float half = 0.5f, float step = 0.02f) {
  std::vector<Eigen::Vector3f> p;
  const int n = static_cast<int>(std::lround(2 * half / step));
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) p.emplace_back(x, -half + i * step, -half + j * step);
  return p;
}

TEST(ScanMap, OccupiedCellsOnTheScannedSurface) {
  ScanMapConfig c;
  c.resolution = 0.05;
  ScanMap map(c);
  const auto wall = Wall(2.0f);
  std::vector<Eigen::Vector3f> colors(wall.size(), Eigen::Vector3f(1.0f, 0.0f, 0.2f));
  const ScanInsertStats st = map.Insert(wall, colors, Eigen::Vector3f::Zero());
  EXPECT_EQ(st.inserted, wall.size());
  EXPECT_EQ(map.scans(), 1u);
  std::vector<Eigen::Vector3f> pts, cols;
  map.ExtractOccupied(&pts, &cols);
  // 1 m x 1 m at 5 cm: about 20 x 20 cells (+ one row/column at the boundaries).
  EXPECT_GE(pts.size(), 380u);
  EXPECT_LE(pts.size(), 500u);
  ASSERT_EQ(cols.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR(pts[i].x(), 2.0, 0.05);
    EXPECT_NEAR(cols[i].x(), 1.0, 0.01);
    EXPECT_NEAR(cols[i].z(), 0.2, 0.01);
  }
}

TEST(ScanMap, LaterScansClearFreeSpace) {
  ScanMapConfig c;
  c.resolution = 0.05;
  ScanMap map(c);
  // An object at x = 1 seen once, then gone: a larger wall behind it is seen through it 5
  // times (its rays cross x = 1 within [-0.6, 0.6]).
  map.Insert(Wall(1.0f), {}, Eigen::Vector3f::Zero());
  for (int i = 0; i < 5; ++i) map.Insert(Wall(2.0f, 1.2f), {}, Eigen::Vector3f::Zero());
  std::vector<Eigen::Vector3f> pts, cols;
  map.ExtractOccupied(&pts, &cols);
  int near_one = 0, near_two = 0;
  for (const auto& p : pts) {
    near_one += std::abs(p.x() - 1.0f) < 0.1f;
    near_two += std::abs(p.x() - 2.0f) < 0.1f;
  }
  EXPECT_EQ(near_one, 0);
  EXPECT_GT(near_two, 1500);  // 48 x 48 cells

  c.ray_casting = false;  // without ray casting the first object stays
  ScanMap keep(c);
  keep.Insert(Wall(1.0f), {}, Eigen::Vector3f::Zero());
  for (int i = 0; i < 5; ++i) keep.Insert(Wall(2.0f, 1.2f), {}, Eigen::Vector3f::Zero());
  keep.ExtractOccupied(&pts, &cols);
  near_one = 0;
  for (const auto& p : pts) near_one += std::abs(p.x() - 1.0f) < 0.1f;
  EXPECT_GT(near_one, 300);
}

TEST(ScanMap, BoundedByTheCubeAndTheCellCap) {
  ScanMapConfig c;
  c.resolution = 0.05;
  c.max_extent = 3.0;  // cube [-1.5, 1.5]^3 around the first origin
  c.max_occupied_cells = 100;
  ScanMap map(c);
  map.Insert(Wall(1.0f), {}, Eigen::Vector3f::Zero());
  const ScanInsertStats st = map.Insert(Wall(2.0f), {}, Eigen::Vector3f::Zero());
  EXPECT_EQ(st.inserted, 0u);
  EXPECT_EQ(st.out_of_bounds, Wall(2.0f).size());
  std::vector<Eigen::Vector3f> pts, cols;
  map.ExtractOccupied(&pts, &cols);
  EXPECT_EQ(pts.size(), 100u);
  for (const auto& p : pts) EXPECT_LE(p.x(), 1.5f);
  EXPECT_GT(map.memory_bytes(), 0u);
  map.Clear();
  EXPECT_EQ(map.leaf_count(), 0u);
  EXPECT_EQ(map.scans(), 0u);
}

TEST(ScanMap, MaxRangeAndBadInput) {
  ScanMapConfig c;
  c.resolution = 0.05;
  c.max_range = 1.5;
  ScanMap map(c);
  map.Insert(Wall(2.0f), {}, Eigen::Vector3f::Zero());
  std::vector<Eigen::Vector3f> pts, cols;
  map.ExtractOccupied(&pts, &cols);
  EXPECT_TRUE(pts.empty());  // every end point beyond the range
  EXPECT_THROW(map.Insert(Wall(1.0f), {}, Eigen::Vector3f(NAN, 0, 0)), InvalidArgument);
  EXPECT_THROW(map.Insert(Wall(1.0f), {Eigen::Vector3f::Zero()}, Eigen::Vector3f::Zero()),
               InvalidArgument);
  c.resolution = 0;
  EXPECT_THROW(ScanMap{c}, InvalidArgument);
}

}  // namespace
}  // namespace dimr::ros1
