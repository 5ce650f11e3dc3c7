#include "dimr/geometry/voxelize.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

// Closed axis-aligned box [lo, hi], outward triangles (inward when `inverted`).
TriangleMesh Box(const Vec3& lo, const Vec3& hi, bool inverted = false) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.emplace_back((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(),
                            (i & 4) ? hi.z() : lo.z());
  }
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) {
    if (inverted) {
      m.faces.emplace_back(t[0], t[2], t[1]);
    } else {
      m.faces.emplace_back(t[0], t[1], t[2]);
    }
  }
  return m;
}

// UV sphere of radius r at the origin with `rings` latitude bands and `segs` longitudes.
TriangleMesh UvSphere(double r, int rings, int segs) {
  TriangleMesh m;
  m.vertices.emplace_back(0, 0, r);
  for (int i = 1; i < rings; ++i) {
    const double th = M_PI * i / rings;
    for (int j = 0; j < segs; ++j) {
      const double ph = 2 * M_PI * j / segs;
      m.vertices.emplace_back(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph),
                              r * std::cos(th));
    }
  }
  m.vertices.emplace_back(0, 0, -r);
  const int south = static_cast<int>(m.vertices.size()) - 1;
  auto ring = [segs](int i, int j) { return 1 + (i - 1) * segs + (j % segs); };
  for (int j = 0; j < segs; ++j) m.faces.emplace_back(0, ring(1, j), ring(1, j + 1));
  for (int i = 1; i + 1 < rings; ++i) {
    for (int j = 0; j < segs; ++j) {
      m.faces.emplace_back(ring(i, j), ring(i + 1, j), ring(i + 1, j + 1));
      m.faces.emplace_back(ring(i, j), ring(i + 1, j + 1), ring(i, j + 1));
    }
  }
  for (int j = 0; j < segs; ++j)
    m.faces.emplace_back(south, ring(rings - 1, j + 1), ring(rings - 1, j));
  return m;
}

VoxelGrid UnitGrid(int n) {
  VoxelGrid g;
  g.origin = Vec3::Zero();
  g.voxel_size = 1.0;
  g.dims = Vec3i::Constant(n);
  g.occupied.assign(static_cast<std::size_t>(n) * n * n, 0);
  return g;
}

TEST(VoxelGrid, MakeGridCoversBoundsWithPadding) {
  AABB b;
  b.Extend(Vec3(0, 0, 0));
  b.Extend(Vec3(1.0, 0.25, 0.5));
  const VoxelGrid g = MakeGrid(b, 0.1, 2);
  EXPECT_EQ(g.dims, Vec3i(14, 7, 9));  // ceil(10, 2.5, 5) + 2 * 2
  EXPECT_NEAR(g.origin.x(), -0.2, 1e-15);
  EXPECT_NEAR(g.origin.y(), -0.2, 1e-15);
  EXPECT_EQ(g.occupied.size(), 14u * 7u * 9u);
  EXPECT_EQ(g.Count(), 0u);
  EXPECT_NEAR(g.CellCenter(2, 0, 0).x(), 0.05, 1e-15);
  EXPECT_THROW(MakeGrid(b, 0.0), InvalidArgument);
  EXPECT_THROW(MakeGrid(b, 0.1, -1), InvalidArgument);
  EXPECT_THROW(MakeGrid(AABB(), 0.1), InvalidArgument);
}

TEST(VoxelGrid, AxisAlignedBoxSurfaceAndFilledCounts) {
  // Faces at half-integer coordinates: cells x 2..7 (6), y 3..6 (4), z 1..9 (9).
  const TriangleMesh box = Box(Vec3(2.5, 3.5, 1.5), Vec3(7.5, 6.5, 9.5));
  VoxelGrid surf = UnitGrid(12);
  VoxelizeSurface(box, &surf);
  // Shell = all covered cells minus the interior 4 x 2 x 7.
  EXPECT_EQ(surf.Count(), 6u * 4u * 9u - 4u * 2u * 7u);
  EXPECT_TRUE(surf.At(2, 3, 1));
  EXPECT_TRUE(surf.At(7, 6, 9));
  EXPECT_FALSE(surf.At(4, 4, 4));  // interior
  EXPECT_FALSE(surf.At(1, 3, 1));  // outside
  VoxelGrid solid = UnitGrid(12);
  VoxelizeFilled(box, &solid);
  EXPECT_EQ(solid.Count(), 6u * 4u * 9u);
  for (int k = 0; k < 12; ++k) {
    for (int j = 0; j < 12; ++j) {
      for (int i = 0; i < 12; ++i) {
        const bool in = i >= 2 && i <= 7 && j >= 3 && j <= 6 && k >= 1 && k <= 9;
        ASSERT_EQ(solid.At(i, j, k), in) << i << " " << j << " " << k;
      }
    }
  }
}

TEST(VoxelGrid, NonUnitPitchAndOrigin) {
  // Same box scaled by 0.1 and moved; grid from MakeGrid (origin = bounds.min - pad).
  const TriangleMesh box = Box(Vec3(-1.0, 2.0, 0.3), Vec3(-0.48, 2.27, 0.62));
  AABB b;
  b.Extend(Vec3(-1.05, 1.95, 0.25));
  b.Extend(Vec3(-0.35, 2.35, 0.75));
  VoxelGrid g = MakeGrid(b, 0.1, 1);  // origin (-1.15, 1.85, 0.15); box faces mid-cell
  VoxelizeFilled(box, &g);
  // (p - origin) / 0.1: x 1.5..6.7 -> cells 1..6; y 1.5..4.2 -> 1..4; z 1.5..4.7 -> 1..4.
  EXPECT_EQ(g.Count(), 6u * 4u * 4u);
  EXPECT_TRUE(g.At(1, 1, 1));
  EXPECT_TRUE(g.At(6, 4, 4));
  EXPECT_FALSE(g.At(7, 4, 4));
}

TEST(VoxelGrid, HollowBoxIsFilledAndOpenBoxIsNot) {
  TriangleMesh hollow = Box(Vec3::Constant(1.5), Vec3::Constant(8.5));
  hollow.Append(Box(Vec3::Constant(3.5), Vec3::Constant(6.5), /*inverted=*/true));
  VoxelGrid surf = UnitGrid(10);
  VoxelizeSurface(hollow, &surf);
  EXPECT_EQ(surf.Count(), (512u - 216u) + (64u - 8u));  // outer shell + inner shell
  VoxelGrid solid = UnitGrid(10);
  VoxelizeFilled(hollow, &solid);
  EXPECT_EQ(solid.Count(), 512u);  // 8^3: the cavity is closed and filled
  EXPECT_TRUE(solid.At(4, 4, 4));

  // Remove the two top triangles: the flood fill now enters, only the shell remains.
  TriangleMesh open = Box(Vec3::Constant(1.5), Vec3::Constant(8.5));
  open.faces.erase(open.faces.begin() + 2, open.faces.begin() + 4);
  VoxelGrid open_surf = UnitGrid(10);
  VoxelizeSurface(open, &open_surf);
  VoxelGrid open_fill = UnitGrid(10);
  VoxelizeFilled(open, &open_fill);
  EXPECT_EQ(open_surf.Count(), 512u - 216u - 36u);  // top layer interior 6x6 missing
  EXPECT_EQ(open_fill.Count(), open_surf.Count());
}

TEST(VoxelGrid, SphereFilledMatchesVolume) {
  const double r = 1.0, v = 0.0125;
  const TriangleMesh sphere = UvSphere(r, 96, 192);
  VoxelGrid g = MakeGrid(sphere.Bounds(), v, 1);
  VoxelizeFilled(sphere, &g);
  VoxelGrid shell = MakeGrid(sphere.Bounds(), v, 1);
  VoxelizeSurface(sphere, &shell);
  const double expected = 4.0 / 3.0 * M_PI * r * r * r / (v * v * v);
  const double filled = static_cast<double>(g.Count());
  // Surface cells straddle the sphere: the solid over-counts by about half the shell.
  EXPECT_GT(filled / expected, 1.0);
  EXPECT_LT(filled / expected, 1.035);
  EXPECT_NEAR((filled - 0.5 * shell.Count()) / expected, 1.0, 0.005);
  // Per cell: well inside -> filled, well outside -> empty (inscribed radius >= 0.999 r).
  const double slack = std::sqrt(3.0) / 2 * v;
  std::size_t checked = 0;
  for (int k = 0; k < g.dims.z(); ++k) {
    for (int j = 0; j < g.dims.y(); ++j) {
      for (int i = 0; i < g.dims.x(); ++i) {
        const double dist = g.CellCenter(i, j, k).norm();
        if (dist + slack < 0.999 * r) {
          ASSERT_TRUE(g.At(i, j, k));
          ++checked;
        } else if (dist - slack > r) {
          ASSERT_FALSE(g.At(i, j, k));
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, g.occupied.size() * 9 / 10);
}

TEST(VoxelGrid, RejectsBadInput) {
  VoxelGrid g = UnitGrid(4);
  EXPECT_THROW(VoxelizeSurface(Box(Vec3::Zero(), Vec3::Ones()), nullptr), InvalidArgument);
  TriangleMesh bad = Box(Vec3::Zero(), Vec3::Ones());
  bad.faces.emplace_back(0, 1, 42);
  EXPECT_THROW(VoxelizeSurface(bad, &g), InvalidArgument);
  g.occupied.resize(3);
  EXPECT_THROW(VoxelizeSurface(Box(Vec3::Zero(), Vec3::Ones()), &g), InvalidArgument);
}

// ---------------------------------------------------------------------------------------
// Reference voxel set (metrics spec section 3).
// ---------------------------------------------------------------------------------------

TEST(ReferenceVoxels, UnitCubeEveryCellInUnion) {
  TriangleMesh cube = Box(Vec3(2, -1, 3), Vec3(3, 0, 4));
  const ReferenceVoxels rv = VoxelizeReference(cube, 0.1);
  EXPECT_EQ(rv.d, 10);  // int(1 / 0.1)
  EXPECT_DOUBLE_EQ(rv.extent, 1.0);
  EXPECT_EQ(rv.t, Vec3(2, -1, 3));
  EXPECT_EQ(rv.UnitedCount(), 1000u);
  EXPECT_EQ(rv.SurfaceCount(), 1000u - 512u);  // faces touch only the outer layer (+2%)
  EXPECT_FALSE(rv.surface[rv.Index(1, 1, 1)]);
  EXPECT_TRUE(rv.united[rv.Index(1, 1, 1)]);
  EXPECT_NEAR((rv.CellPoint(9, 0, 0) - Vec3(3, -1, 3)).norm(), 0, 1e-12);  // t + 9 * E/9
  EXPECT_NEAR((rv.CellCentre(9, 0, 0) - Vec3(2.95, -0.95, 3.05)).norm(), 0, 1e-12);
}

TEST(ReferenceVoxels, GridSizeTruncatesTheDoubleQuotient) {
  // 0.3 / 0.1 == 2.9999999999999996 in double -> int() gives 2.
  EXPECT_EQ(VoxelizeReference(Box(Vec3::Zero(), Vec3::Constant(0.3)), 0.1).d, 2);
  // 0.7 / 0.1 == 6.999999999999999 -> 6.
  EXPECT_EQ(VoxelizeReference(Box(Vec3::Zero(), Vec3::Constant(0.7)), 0.1).d, 6);
  EXPECT_EQ(VoxelizeReference(Box(Vec3::Zero(), Vec3::Ones()), 0.3).d, 3);
  EXPECT_EQ(VoxelizeReference(Box(Vec3::Zero(), Vec3::Ones()), 0.7).d, 2);  // max(2, 1)
  EXPECT_EQ(VoxelizeReference(Box(Vec3::Zero(), Vec3(1, 2.5, 0.2)), 0.047).d, 53);
  const ReferenceVoxels small = VoxelizeReference(Box(Vec3::Zero(), Vec3::Constant(0.3)), 0.1);
  EXPECT_EQ(small.UnitedCount(), 8u);
  EXPECT_EQ(small.SurfaceCount(), 8u);
}

TEST(ReferenceVoxels, UnreferencedVerticesSizeTheGrid) {
  TriangleMesh cube = Box(Vec3::Zero(), Vec3::Ones());
  cube.vertices.emplace_back(3, 0, 0);  // referenced by no face
  const ReferenceVoxels rv = VoxelizeReference(cube, 0.12);
  EXPECT_EQ(rv.d, 25);  // E = 3, not 1; cell side 0.12: the cube covers cells 0..8
  EXPECT_EQ(rv.UnitedCount(), 729u);
  EXPECT_TRUE(rv.united[rv.Index(8, 8, 8)]);
  EXPECT_FALSE(rv.united[rv.Index(9, 0, 0)]);
}

TEST(ReferenceVoxels, ThinSlab) {
  // 1 x 1 x 0.06 slab: t.z = 0.42, so the slab lies in layer k = 0 of a d = 10 grid.
  const ReferenceVoxels rv = VoxelizeReference(Box(Vec3(0, 0, 0.42), Vec3(1, 1, 0.48)), 0.1);
  EXPECT_EQ(rv.d, 10);
  EXPECT_EQ(rv.SurfaceCount(), 100u);
  EXPECT_EQ(rv.UnitedCount(), 100u);
  for (int j = 0; j < 10; ++j) {
    for (int i = 0; i < 10; ++i) {
      EXPECT_TRUE(rv.united[rv.Index(i, j, 0)]);
      EXPECT_FALSE(rv.united[rv.Index(i, j, 1)]);
    }
  }
}

TEST(ReferenceVoxels, OverlappingBoxesUseCarvingNotParity) {
  // Two overlapping closed boxes (as in BSP convex unions), footprints [0,0.63]^2 and
  // [0.37,1]^2, full height. Every z layer: cells (0..6)^2 union (3..9)^2 = 49+49-16 = 82.
  TriangleMesh m = Box(Vec3(0, 0, 0), Vec3(0.63, 0.63, 1));
  m.Append(Box(Vec3(0.37, 0.37, 0), Vec3(1, 1, 1)));
  const ReferenceVoxels rv = VoxelizeReference(m, 0.1);
  ASSERT_EQ(rv.d, 10);
  EXPECT_EQ(rv.UnitedCount(), 820u);
  // S: the bottom/top layers (82 each) plus, in the 8 middle layers, the two 7x7 rings
  // (24 each) sharing cells (6,3) and (3,6).
  EXPECT_EQ(rv.SurfaceCount(), 2u * 82u + 8u * 46u);
  // Cells of the overlap region are inside both boxes (a parity test would drop them).
  EXPECT_TRUE(rv.united[rv.Index(4, 5, 4)]);
  EXPECT_FALSE(rv.surface[rv.Index(4, 5, 4)]);
  EXPECT_FALSE(rv.united[rv.Index(8, 1, 4)]);
  EXPECT_FALSE(rv.united[rv.Index(1, 8, 4)]);
}

TEST(ReferenceVoxels, HollowBoxCavityIsFilled) {
  TriangleMesh m = Box(Vec3::Zero(), Vec3::Ones());
  m.Append(Box(Vec3::Constant(0.35), Vec3::Constant(0.65), /*inverted=*/true));
  const ReferenceVoxels rv = VoxelizeReference(m, 0.1);
  EXPECT_EQ(rv.UnitedCount(), 1000u);
  EXPECT_EQ(rv.SurfaceCount(), 488u + 56u);  // outer shell + inner shell (cells 3..6)
  EXPECT_TRUE(rv.united[rv.Index(5, 5, 5)]);
  EXPECT_FALSE(rv.surface[rv.Index(5, 5, 5)]);
}

TEST(ReferenceVoxels, SphereUnionApproximatesVolume) {
  const TriangleMesh sphere = UvSphere(0.5, 48, 96);
  const ReferenceVoxels rv = VoxelizeReference(sphere, 0.024);
  ASSERT_EQ(rv.d, 41);  // int(1.0 / 0.024)
  const double cell = rv.extent / 41;
  const double inner = 4.0 / 3.0 * M_PI * std::pow(0.5 - std::sqrt(3.0) * cell, 3);
  const double outer = 4.0 / 3.0 * M_PI * std::pow(0.5 + std::sqrt(3.0) * cell, 3);
  const double vol = rv.UnitedCount() * cell * cell * cell;
  EXPECT_GT(vol, inner);
  EXPECT_LT(vol, outer);
  // Centre cell is carved in; corner cell is not.
  EXPECT_TRUE(rv.united[rv.Index(20, 20, 20)]);
  EXPECT_FALSE(rv.united[rv.Index(0, 0, 0)]);
}

// Independent, slow construction of the carving set C for one cell: for each axis the line
// through the cell centre is intersected with every triangle via its 3-D plane equation and
// 3-D edge/normal sign tests (no binning, no 2-D projection).
bool NaiveCarved(const TriangleMesh& m, const Vec3& c) {
  for (int a = 0; a < 3; ++a) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const Vec3i& f : m.faces) {
      const Vec3 &p0 = m.vertices[f[0]], &p1 = m.vertices[f[1]], &p2 = m.vertices[f[2]];
      const Vec3 n = (p1 - p0).cross(p2 - p0);
      if (n[a] == 0.0) continue;
      Vec3 q = c;
      q[a] = p0[a] - (n.dot(c - p0) - n[a] * (c[a] - p0[a])) / n[a];
      const double s0 = (p1 - p0).cross(q - p0).dot(n);
      const double s1 = (p2 - p1).cross(q - p1).dot(n);
      const double s2 = (p0 - p2).cross(q - p2).dot(n);
      if (s0 >= 0 && s1 >= 0 && s2 >= 0) {
        lo = std::min(lo, q[a]);
        hi = std::max(hi, q[a]);
      }
    }
    if (!(lo <= c[a] && c[a] <= hi)) return false;
  }
  return true;
}

TEST(ReferenceVoxels, UnionMatchesNaiveCarvingOnRotatedParts) {
  // Overlapping parts, a cavity and a sphere, in a generic orientation (no exact ties).
  TriangleMesh m = Box(Vec3(0, 0, 0), Vec3(0.6, 0.3, 0.5));
  m.Append(Box(Vec3(0.4, 0.1, 0.2), Vec3(0.9, 0.8, 0.4)));
  m.Append(Box(Vec3(0.1, 0.1, 0.1), Vec3(0.3, 0.2, 0.3), /*inverted=*/true));
  TriangleMesh ball = UvSphere(0.2, 12, 24);
  ball.Transform(Eigen::Matrix3d::Identity(), Vec3(0.7, 0.5, 0.7));
  m.Append(ball);
  m.Transform(Eigen::AngleAxisd(0.61, Vec3(1, 2, 3).normalized()).toRotationMatrix(),
              Vec3(-3.1, 0.7, 12.3));
  const ReferenceVoxels rv = VoxelizeReference(m, 0.06);
  ASSERT_GE(rv.d, 14);
  std::size_t carved_only = 0;
  for (int k = 0; k < rv.d; ++k) {
    for (int j = 0; j < rv.d; ++j) {
      for (int i = 0; i < rv.d; ++i) {
        const std::size_t idx = rv.Index(i, j, k);
        const bool carved = NaiveCarved(m, rv.CellCentre(i, j, k));
        ASSERT_EQ(rv.united[idx] != 0, rv.surface[idx] != 0 || carved) << i << " " << j << " " << k;
        carved_only += carved && !rv.surface[idx];
      }
    }
  }
  EXPECT_GT(carved_only, 50u);  // the test exercises C, not just S
  // S is part of U, and every cell holding a surface point is in S.
  const double s = rv.extent / rv.d;
  for (int k = 0; k < rv.d; ++k) {
    for (int j = 0; j < rv.d; ++j) {
      for (int i = 0; i < rv.d; ++i) {
        if (!rv.surface[rv.Index(i, j, k)]) continue;
        ASSERT_TRUE(rv.united[rv.Index(i, j, k)]);
      }
    }
  }
  for (const Vec3i& f : m.faces) {
    for (double u : {0.1, 0.45, 0.8}) {
      for (double v : {0.1, 0.45}) {
        if (u + v > 1) continue;
        const Vec3& p0 = m.vertices[f[0]];
        const Vec3 p = p0 + u * (m.vertices[f[1]] - p0) + v * (m.vertices[f[2]] - p0);
        const Vec3 q = (p - rv.t) / s;
        const int i = std::min(rv.d - 1, static_cast<int>(q.x()));
        const int j = std::min(rv.d - 1, static_cast<int>(q.y()));
        const int kk = std::min(rv.d - 1, static_cast<int>(q.z()));
        ASSERT_TRUE(rv.surface[rv.Index(i, j, kk)]);
      }
    }
  }
}

TEST(ReferenceVoxels, IsFilledRoundsHalfToEven) {
  // d = 9, E = 9/8: E/(d-1) = 9/64, so index values k + 0.5 are exact ties.
  ReferenceVoxels rv;
  rv.t = Vec3(1, 2, 3);
  rv.extent = 1.125;
  rv.d = 9;
  rv.surface.assign(729, 0);
  rv.united.assign(729, 0);
  rv.surface[rv.Index(2, 0, 0)] = rv.united[rv.Index(2, 0, 0)] = 1;
  rv.united[rv.Index(0, 4, 0)] = 1;
  rv.united[rv.Index(8, 8, 8)] = 1;
  const double step = 9.0 / 64.0;
  auto at = [&](double i, double j, double k) -> Vec3 { return rv.t + Vec3(i, j, k) * step; };
  EXPECT_TRUE(rv.IsFilled(at(1.5, 0, 0)));       // 1.5 -> 2
  EXPECT_TRUE(rv.IsFilled(at(2.5, 0, 0)));       // 2.5 -> 2
  EXPECT_FALSE(rv.IsFilled(at(3.5, 0, 0)));      // 3.5 -> 4
  EXPECT_FALSE(rv.IsFilled(at(0.5, 0, 0)));      // 0.5 -> 0
  EXPECT_TRUE(rv.IsFilled(at(2, -0.5, 0.5)));    // -0.5 -> -0 (in range), 0.5 -> 0
  EXPECT_FALSE(rv.IsFilled(at(2, -0.75, 0)));    // -> -1, out of range
  EXPECT_TRUE(rv.IsFilled(at(-0.5, 3.5, 0)));    // (0, 4, 0)
  EXPECT_TRUE(rv.IsFilled(at(0, 4.5, 0)));       // 4.5 -> 4
  EXPECT_FALSE(rv.IsFilled(at(0, 5.5, 0)));      // 5.5 -> 6
  EXPECT_TRUE(rv.IsFilled(at(8.5, 7.5, 8.25)));  // (8, 8, 8)
  EXPECT_FALSE(rv.IsFilled(at(9.5, 8, 8)));      // 9.5 -> 10: outside [0, d)
  // The corrected lookup floors (p - t) * d / E: cell (2,0,0) spans [2, 3) * E/d.
  const double cs = 1.125 / 9;
  EXPECT_TRUE(rv.IsFilledExact(rv.t + Vec3(2.0, 0.5, 0.5) * cs));
  EXPECT_TRUE(rv.IsFilledExact(rv.t + Vec3(2.96875, 0, 0) * cs));
  EXPECT_FALSE(rv.IsFilledExact(rv.t + Vec3(1.96875, 0.5, 0.5) * cs));
  EXPECT_FALSE(rv.IsFilledExact(rv.t + Vec3(2.5, -0.03125, 0.5) * cs));
}

TEST(ReferenceMeshIoU, IdenticalIsOneAndSymmetric) {
  TriangleMesh a = Box(Vec3::Zero(), Vec3(0.63, 0.63, 1));
  a.Append(Box(Vec3(0.37, 0.37, 0), Vec3(1, 1, 1)));
  const ReferenceVoxels va = VoxelizeReference(a, 0.047);
  EXPECT_DOUBLE_EQ(ReferenceMeshIoU(va, va), 1.0);
  EXPECT_DOUBLE_EQ(ReferenceMeshIoU(va, va, true), 1.0);
  const TriangleMesh b = UvSphere(0.55, 32, 64);
  const ReferenceVoxels vb = VoxelizeReference(b, 0.047);
  const double ab = ReferenceMeshIoU(va, vb), ba = ReferenceMeshIoU(vb, va);
  EXPECT_DOUBLE_EQ(ab, ba);
  EXPECT_GT(ab, 0.0);
  EXPECT_LT(ab, 1.0);
}

TEST(ReferenceMeshIoU, BoxShiftedByOnePitch) {
  // Pitch 1/8, unit cube -> d = 8. Shift 1/8 along x. Reference points t + i/7: in the
  // shifted grid round(i - 7/8) = i - 1, so the layer i = 0 misses: alpha1 = alpha2 = 7/8,
  // IoU = (49/64) / (7/4 - 49/64) = 7/9 (= the true IoU 0.875 / 1.125).
  const TriangleMesh a = Box(Vec3::Zero(), Vec3::Ones());
  const TriangleMesh b = Box(Vec3(0.125, 0, 0), Vec3(1.125, 1, 1));
  const ReferenceVoxels va = VoxelizeReference(a, 0.125), vb = VoxelizeReference(b, 0.125);
  ASSERT_EQ(va.d, 8);
  ASSERT_EQ(vb.d, 8);
  EXPECT_NEAR(ReferenceMeshIoU(va, vb), 7.0 / 9.0, 1e-12);
  EXPECT_NEAR(ReferenceMeshIoU(va, vb, true), 7.0 / 9.0, 1e-12);
}

TEST(ReferenceMeshIoU, SubCellShiftSeparatesTheProtocols) {
  // d = 10, shift s = 55/1024 (exact in binary; 9 s = 0.483 < 0.5 < 10 s = 0.537).
  // Reference: indices round(i -/+ 9 s) = i, every point hits -> IoU 1.
  // Corrected: floor(i + 0.5 -/+ 10 s) = i -/+ 1, one layer misses on each side -> 9/11.
  const double s = 55.0 / 1024.0;
  const TriangleMesh a = Box(Vec3::Zero(), Vec3::Ones());
  const TriangleMesh b = Box(Vec3(s, 0, 0), Vec3(1 + s, 1, 1));
  const ReferenceVoxels va = VoxelizeReference(a, 0.1), vb = VoxelizeReference(b, 0.1, true);
  ASSERT_EQ(vb.d, 10);
  EXPECT_TRUE(vb.exact_pitch);
  EXPECT_DOUBLE_EQ(ReferenceMeshIoU(va, vb), 1.0);
  EXPECT_NEAR(ReferenceMeshIoU(va, vb, true), 9.0 / 11.0, 1e-12);
}

TEST(ReferenceMeshIoU, ThreeCellShiftAndFarApart) {
  // d = 8 (pitch 1/8), shift 3/8: points t + i/7 land on round(i - 21/8) = i - 3 (i - 2.625)
  // -> 5 of 8 layers hit on each side: alpha = 5/8, IoU = (25/64)/(80/64 - 25/64) = 5/11.
  const TriangleMesh a = Box(Vec3::Zero(), Vec3::Ones());
  const TriangleMesh b = Box(Vec3(0.375, 0, 0), Vec3(1.375, 1, 1));
  const ReferenceVoxels va = VoxelizeReference(a, 0.125), vb = VoxelizeReference(b, 0.125);
  EXPECT_NEAR(ReferenceMeshIoU(va, vb), 5.0 / 11.0, 1e-12);
  const TriangleMesh far = Box(Vec3(5, 5, 5), Vec3(6, 6, 6));
  EXPECT_EQ(ReferenceMeshIoU(va, VoxelizeReference(far, 0.125)), 0.0);
  EXPECT_EQ(ReferenceMeshIoU(va, VoxelizeReference(far, 0.125), true), 0.0);
  // A mesh without faces has no voxels: IoU 0.
  TriangleMesh points_only;
  points_only.vertices = a.vertices;
  const ReferenceVoxels empty = VoxelizeReference(points_only, 0.1);
  EXPECT_EQ(empty.UnitedCount(), 0u);
  EXPECT_EQ(ReferenceMeshIoU(va, empty), 0.0);
  EXPECT_EQ(ReferenceMeshIoU(empty, empty), 0.0);
}

TEST(ReferenceVoxels, RejectsBadInput) {
  const TriangleMesh a = Box(Vec3::Zero(), Vec3::Ones());
  EXPECT_THROW(VoxelizeReference(a, 0.0), InvalidArgument);
  EXPECT_THROW(VoxelizeReference(a, -1.0), InvalidArgument);
  EXPECT_THROW(VoxelizeReference(a, 1e-5), InvalidArgument);  // 100000 cells per axis
  TriangleMesh bad = a;
  bad.vertices[0].x() = std::nan("");
  EXPECT_THROW(VoxelizeReference(bad, 0.1), InvalidArgument);
}

}  // namespace
}  // namespace dimr::geometry
