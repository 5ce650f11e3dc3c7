// BSP sample building: the cell occupancy both sides of the cell IoU use (thin parts count as
// the cells they pass through, a decoded shape's cavities stay empty), its identity with the
// encoder grid, and the left-right mirror augmentation.
#include "dimr/pipeline/bsp_data.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/bsp_mesher.h"

namespace dimr::pipeline {
namespace {

// Closed, outward-oriented axis-aligned box.
geometry::TriangleMesh Box(const geometry::Vec3& lo, const geometry::Vec3& hi) {
  geometry::TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(),
                            i & 4 ? hi.z() : lo.z());
  }
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.faces.emplace_back(q[0], q[1], q[2]);
    m.faces.emplace_back(q[0], q[2], q[3]);
  }
  return m;
}

std::size_t Count(const std::vector<std::uint8_t>& g) {
  std::size_t n = 0;
  for (auto v : g) n += v != 0;
  return n;
}

std::size_t Cell(int R, int i, int j, int k) {
  return static_cast<std::size_t>(i + R * (j + R * k));
}

// A sheet a tenth of a cell thick lies between the cell centres: the centre rule sees nothing,
// the cell occupancy exactly the 2 x 2 cells it passes through.
TEST(BspCellOccupancy, ThinSheetCountsTheCellsItPassesThrough) {
  const int R = 4;  // cells of 0.5, centres at -0.75, -0.25, 0.25, 0.75
  const geometry::TriangleMesh sheet =
      Box(geometry::Vec3(-0.45, -0.45, 0.10), geometry::Vec3(0.45, 0.45, 0.15));
  const std::vector<std::uint8_t> occ = BspCellOccupancy(sheet, R, 4);
  ASSERT_EQ(occ.size(), 64u);
  EXPECT_EQ(Count(occ), 4u);
  for (int i : {1, 2})
    for (int j : {1, 2}) EXPECT_TRUE(occ[Cell(R, i, j, 2)]) << i << " " << j;
  // A solid block fills every cell it touches, inside cells included.
  const std::vector<std::uint8_t> block =
      BspCellOccupancy(Box(geometry::Vec3(-0.9, -0.9, -0.9), geometry::Vec3(0.4, 0.9, 0.9)), R);
  EXPECT_EQ(Count(block), 3u * 4u * 4u);
  EXPECT_FALSE(block[Cell(R, 3, 0, 0)]);
  EXPECT_TRUE(block[Cell(R, 1, 1, 1)]);
  // Empty mesh: empty grid; bad sizes: a clear error.
  EXPECT_EQ(Count(BspCellOccupancy(geometry::TriangleMesh(), R)), 0u);
  EXPECT_THROW(BspCellOccupancy(sheet, 0, 4), InvalidArgument);
  EXPECT_THROW(BspCellOccupancy(sheet, 32, 0), InvalidArgument);
  EXPECT_THROW(BspCellOccupancy(sheet, 512, 4), InvalidArgument);
}

// MakeBspSample's encoder grid is the cell occupancy of the normalised mesh; its centre grid
// misses the thin seat the cell occupancy keeps.
TEST(BspCellOccupancy, IsTheEncoderGridOfMakeBspSample) {
  // A thin seat on a thin post, in any frame (MakeBspSample normalises the bounds); the seat
  // (normalised z 0.131 .. 0.135) lies between the cell centres 0.0625 and 0.1875.
  geometry::TriangleMesh stool = Box(geometry::Vec3(0, 0, 0.57), geometry::Vec3(1, 1, 0.574));
  stool.Append(Box(geometry::Vec3(0.49, 0.49, 0), geometry::Vec3(0.502, 0.502, 1.0)));
  BspSampleOptions opt;
  opt.resolution = 16;
  const nn::BspSample s = MakeBspSample(stool, 1, "stool", opt, 7);
  EXPECT_EQ(s.grid, BspCellOccupancy(NormalizeForBsp(stool, 16), 16, opt.fine_factor));
  // The seat: one layer of 16 x 16 cells; the post: 2 x 2 columns through the height.
  EXPECT_GE(Count(s.grid), 16u * 16u + 4u * 14u);
  for (int i = 0; i < 16; ++i) EXPECT_TRUE(s.grid[Cell(16, i, 5, 9)]) << i;
  EXPECT_LT(Count(s.iou_grid), Count(s.grid) / 4);
}

// A decoded shape is the union of its convexes: six wall slabs enclosing a cube keep the cube's
// inside empty, where filling their concatenated mesh would close it.
TEST(BspCellOccupancy, DecodedConvexesKeepTheirCavity) {
  const double a = 0.7, t = 0.1;  // faces off the cell boundaries
  BspMeshResult decoded;
  const geometry::Vec3 lo = geometry::Vec3::Constant(-a), hi = geometry::Vec3::Constant(a);
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      geometry::Vec3 l = lo, h = hi;
      if (side == 0) {
        h[axis] = -a + t;
      } else {
        l[axis] = a - t;
      }
      const int convex = 2 * axis + side;
      const geometry::TriangleMesh slab = Box(l, h);
      decoded.mesh.Append(slab);
      decoded.face_convex.insert(decoded.face_convex.end(), slab.faces.size(), convex);
      decoded.kept_convexes.push_back(convex);
    }
  }
  const int R = 8;  // cells of 0.25: the walls are the outer ring of cells 1 and 6
  const std::vector<std::uint8_t> occ = BspCellOccupancy(decoded, R, 4);
  EXPECT_FALSE(occ[Cell(R, 3, 4, 4)]);
  EXPECT_TRUE(occ[Cell(R, 1, 4, 4)]);
  EXPECT_EQ(Count(occ), 6u * 6u * 6u - 4u * 4u * 4u);
  // Filling the concatenated mesh closes the cavity (the cell occupancy of a CAD mesh).
  const std::vector<std::uint8_t> filled = BspCellOccupancy(decoded.mesh, R, 4);
  EXPECT_TRUE(filled[Cell(R, 3, 4, 4)]);
  EXPECT_EQ(Count(filled), 6u * 6u * 6u);
  // Inconsistent convex ids are an error; no faces, an empty grid.
  BspMeshResult bad = decoded;
  bad.face_convex.pop_back();
  EXPECT_THROW(BspCellOccupancy(bad, R, 4), InvalidArgument);
  EXPECT_EQ(Count(BspCellOccupancy(BspMeshResult(), R, 4)), 0u);
}

TEST(MirrorLeftRight, FlipsYAndKeepsOrientation) {
  const geometry::TriangleMesh box =
      Box(geometry::Vec3(-0.2, 0.1, 0.0), geometry::Vec3(0.3, 0.6, 0.5));
  ASSERT_GT(box.SignedVolume(), 0.0);
  const geometry::TriangleMesh m = MirrorLeftRight(box);
  EXPECT_NEAR(m.SignedVolume(), box.SignedVolume(), 1e-12);
  const geometry::AABB b = m.Bounds();
  EXPECT_DOUBLE_EQ(b.min.y(), -0.6);
  EXPECT_DOUBLE_EQ(b.max.y(), -0.1);
  EXPECT_DOUBLE_EQ(b.min.x(), -0.2);
  EXPECT_DOUBLE_EQ(b.max.z(), 0.5);
  // Twice is the identity.
  const geometry::TriangleMesh back = MirrorLeftRight(m);
  EXPECT_EQ(back.faces, box.faces);
  for (std::size_t v = 0; v < box.vertices.size(); ++v)
    EXPECT_EQ(back.vertices[v], box.vertices[v]);
}

}  // namespace
}  // namespace dimr::pipeline
