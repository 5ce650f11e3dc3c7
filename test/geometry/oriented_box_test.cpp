#include "dimr/geometry/oriented_box.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

namespace dimr::geometry {
namespace {

using Vec2 = Eigen::Vector2d;

void ExpectVecNear(const Vec3& a, const Vec3& b, double tol = 1e-12) {
  EXPECT_NEAR((a - b).norm(), 0.0, tol) << a.transpose() << " vs " << b.transpose();
}

TEST(OrientedBox, CornersOrderAndRotation) {
  OrientedBox b{Vec3(1, 2, 3), Vec3(4, 2, 1), 0.0};
  auto c = b.Corners();
  ExpectVecNear(c[0], Vec3(-1, 1, 2.5));
  ExpectVecNear(c[1], Vec3(3, 1, 2.5));
  ExpectVecNear(c[2], Vec3(3, 3, 2.5));
  ExpectVecNear(c[3], Vec3(-1, 3, 2.5));
  ExpectVecNear(c[4], Vec3(-1, 1, 3.5));
  ExpectVecNear(c[6], Vec3(3, 3, 3.5));
  // Heading 90 degrees: local +x (forward) points to world +y.
  b.heading = M_PI / 2;
  ExpectVecNear(b.Rotation() * Vec3::UnitX(), Vec3::UnitY());
  c = b.Corners();
  ExpectVecNear(c[1], Vec3(2, 4, 2.5));  // local (+2, -1) -> (+1, +2)
  ExpectVecNear(c[3], Vec3(0, 0, 2.5));  // local (-2, +1) -> (-1, -2)
  ExpectVecNear(c[7], Vec3(0, 0, 3.5));
  EXPECT_NEAR(b.Rotation().determinant(), 1.0, 1e-14);
  EXPECT_DOUBLE_EQ(b.Volume(), 8.0);
}

TEST(OrientedBox, ContainsAndBounds) {
  const OrientedBox b{Vec3(0, 0, 1), Vec3(2, 2, 2), M_PI / 4};
  EXPECT_TRUE(b.Contains(Vec3(0, 0, 1)));
  // Along the diagonal direction the rotated square reaches sqrt(2).
  EXPECT_TRUE(b.Contains(Vec3(1.41, 0, 1)));
  EXPECT_FALSE(b.Contains(Vec3(1.42, 0, 1)));
  EXPECT_FALSE(b.Contains(Vec3(0.8, 0.8, 1)));  // local x = 1.13 > 1
  EXPECT_TRUE(b.Contains(Vec3(0.7, 0.7, 1)));   // local x = 0.99
  EXPECT_FALSE(b.Contains(Vec3(0, 0, 2.01)));
  EXPECT_TRUE(b.Contains(Vec3(0, 0, 2.01), 0.02));
  EXPECT_TRUE(b.Contains(Vec3(1.42, 0, 1), 0.01));
  const AABB bb = b.Bounds();
  ExpectVecNear(bb.min, Vec3(-std::sqrt(2.0), -std::sqrt(2.0), 0));
  ExpectVecNear(bb.max, Vec3(std::sqrt(2.0), std::sqrt(2.0), 2));
}

TEST(OrientedBox, ToMeshIsClosedAndOutward) {
  const OrientedBox b{Vec3(0.5, -1, 2), Vec3(3, 2, 0.5), 0.3};
  const TriangleMesh m = b.ToMesh();
  ASSERT_EQ(m.vertices.size(), 8u);
  ASSERT_EQ(m.faces.size(), 12u);
  EXPECT_NEAR(m.SignedVolume(), 3.0, 1e-12);  // positive = outward
  EXPECT_NEAR(m.SurfaceArea(), 2 * (6 + 1.5 + 1), 1e-12);
  // Every face normal points away from the centre; every edge is shared by two faces in
  // opposite directions (closed, consistently oriented).
  std::map<std::pair<int, int>, int> edges;
  for (const Vec3i& f : m.faces) {
    const Vec3 n = (m.vertices[f[1]] - m.vertices[f[0]]).cross(m.vertices[f[2]] - m.vertices[f[0]]);
    EXPECT_GT(n.dot(m.vertices[f[0]] - b.center), 0.0);
    for (int k = 0; k < 3; ++k) ++edges[{f[k], f[(k + 1) % 3]}];
  }
  for (const auto& [e, count] : edges) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(edges.count({e.second, e.first}), 1u);
  }
}

TEST(ConvexPolygonIntersection, AnalyticAreas) {
  const std::vector<Vec2> sq = {{0, 0}, {2, 0}, {2, 2}, {0, 2}};
  const std::vector<Vec2> shifted = {{1, 1}, {3, 1}, {3, 3}, {1, 3}};
  EXPECT_NEAR(ConvexPolygonIntersectionArea(sq, shifted), 1.0, 1e-12);
  EXPECT_NEAR(ConvexPolygonIntersectionArea(sq, sq), 4.0, 1e-12);
  // Clockwise input is accepted.
  const std::vector<Vec2> cw = {{1, 3}, {3, 3}, {3, 1}, {1, 1}};
  EXPECT_NEAR(ConvexPolygonIntersectionArea(sq, cw), 1.0, 1e-12);
  // Triangle (0,0),(4,0),(0,4) vs the square: the square lies inside except the corner
  // x + y > 4 (none: max x + y = 4) -> 4.
  const std::vector<Vec2> tri = {{0, 0}, {4, 0}, {0, 4}};
  EXPECT_NEAR(ConvexPolygonIntersectionArea(sq, tri), 4.0, 1e-12);
  // Triangle (0,0),(2,0),(0,2) vs square [1,3]^2: empty interior (touches at a point).
  const std::vector<Vec2> tri2 = {{0, 0}, {2, 0}, {0, 2}};
  EXPECT_NEAR(ConvexPolygonIntersectionArea(tri2, shifted), 0.0, 1e-12);
  // Triangle (0,0),(3,0),(0,3) vs square [1,3]^2: the triangle corner x+y<=3 above (1,1):
  // right triangle with legs 1 -> 0.5.
  const std::vector<Vec2> tri3 = {{0, 0}, {3, 0}, {0, 3}};
  EXPECT_NEAR(ConvexPolygonIntersectionArea(tri3, shifted), 0.5, 1e-12);
  EXPECT_NEAR(ConvexPolygonIntersectionArea(shifted, tri3), 0.5, 1e-12);
  const std::vector<Vec2> far = {{10, 10}, {11, 10}, {11, 11}};
  EXPECT_EQ(ConvexPolygonIntersectionArea(sq, far), 0.0);
  EXPECT_EQ(ConvexPolygonIntersectionArea(sq, {}), 0.0);
}

TEST(BoxIoU, IdenticalShiftedDisjoint) {
  const OrientedBox a{Vec3::Zero(), Vec3(2, 2, 2), 0.0};
  EXPECT_NEAR(BoxIoU(a, a), 1.0, 1e-12);
  OrientedBox b = a;
  b.center = Vec3(1, 0, 0);  // overlap 1 x 2 x 2 = 4, union 12
  EXPECT_NEAR(BoxIoU(a, b), 1.0 / 3.0, 1e-12);
  b.center = Vec3(1, 0.5, 0);  // overlap 1 x 1.5 x 2 = 3, union 13
  EXPECT_NEAR(BoxIoU(a, b), 3.0 / 13.0, 1e-12);
  EXPECT_NEAR(BoxIoU(b, a), 3.0 / 13.0, 1e-12);
  b.center = Vec3(2.5, 0, 0);
  EXPECT_EQ(BoxIoU(a, b), 0.0);
  b.center = Vec3(2.0, 0, 0);  // touching faces
  EXPECT_EQ(BoxIoU(a, b), 0.0);
  // Same box, different parameterisation: heading pi with the same size, heading pi/2 with
  // swapped forward/left extents.
  const OrientedBox r{Vec3(0.3, -0.2, 1), Vec3(3, 1, 2), 0.4};
  OrientedBox r2 = r;
  r2.heading += M_PI;
  EXPECT_NEAR(BoxIoU(r, r2), 1.0, 1e-12);
  OrientedBox r3{r.center, Vec3(1, 3, 2), r.heading + M_PI / 2};
  EXPECT_NEAR(BoxIoU(r, r3), 1.0, 1e-12);
}

TEST(BoxIoU, HeightOnlyOverlap) {
  const OrientedBox a{Vec3(0, 0, 1), Vec3(2, 2, 2), 0.7};
  OrientedBox b = a;
  b.center.z() = 2;  // z in [1, 3] vs [0, 2]: overlap 1 of 2 -> 4 / (8 + 8 - 4)
  EXPECT_NEAR(BoxIoU(a, b), 1.0 / 3.0, 1e-12);
  b.center.z() = 3;  // touching
  EXPECT_EQ(BoxIoU(a, b), 0.0);
  b.center.z() = 1;
  b.size.z() = 1;  // contained: 4 / 8
  EXPECT_NEAR(BoxIoU(a, b), 0.5, 1e-12);
}

TEST(BoxIoU, RotatedSquareGivesOctagon) {
  // Two 2x2 squares (height 1) with a common centre, one turned by 45 degrees: the overlap
  // is a regular octagon of area 4 - 2 (2 - sqrt 2)^2 = 8 sqrt2 - 8, so
  // IoU = (8 sqrt2 - 8) / (8 - (8 sqrt2 - 8)) = 1 / sqrt 2.
  const OrientedBox a{Vec3(5, -3, 0), Vec3(2, 2, 1), 0.0};
  const OrientedBox b{Vec3(5, -3, 0), Vec3(2, 2, 1), M_PI / 4};
  EXPECT_NEAR(BoxIoU(a, b), 1.0 / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(BoxIoU(b, a), 1.0 / std::sqrt(2.0), 1e-12);
  std::vector<Vec2> pa, pb;
  for (int i = 0; i < 4; ++i) {
    pa.push_back(a.Corners()[i].head<2>());
    pb.push_back(b.Corners()[i].head<2>());
  }
  EXPECT_NEAR(ConvexPolygonIntersectionArea(pa, pb), 8 * std::sqrt(2.0) - 8, 1e-12);
}

TEST(BoxIoU, MatchesMonteCarloOnRandomBoxes) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const OrientedBox a{Vec3(u(rng), u(rng), u(rng)),
                        Vec3(0.5 + u(rng), 0.5 + u(rng), 0.5 + u(rng)), 2 * M_PI * u(rng)};
    const OrientedBox b{Vec3(u(rng), u(rng), u(rng)),
                        Vec3(0.5 + u(rng), 0.5 + u(rng), 0.5 + u(rng)), 2 * M_PI * u(rng)};
    // Fraction of uniform points of a that lie in b = intersection / vol(a).
    const int n = 40000;
    int in = 0;
    const Eigen::Matrix3d R = a.Rotation();
    for (int i = 0; i < n; ++i) {
      const Vec3 local((u(rng) - 0.5) * a.size.x(), (u(rng) - 0.5) * a.size.y(),
                       (u(rng) - 0.5) * a.size.z());
      in += b.Contains(a.center + R * local);
    }
    const double f = static_cast<double>(in) / n;
    const double inter = f * a.Volume();
    const double expected = inter / (a.Volume() + b.Volume() - inter);
    const double sigma = std::sqrt(std::max(f * (1 - f), 1e-4) / n);  // of f
    EXPECT_NEAR(BoxIoU(a, b), expected, 5 * sigma + 1e-9) << "trial " << trial;
  }
}

TEST(AabbIoU, AnalyticValues) {
  AABB a, b;
  a.Extend(Vec3(0, 0, 0));
  a.Extend(Vec3(2, 2, 2));
  b.Extend(Vec3(1, 1, 1));
  b.Extend(Vec3(3, 3, 3));
  EXPECT_NEAR(AabbIoU(a, b), 1.0 / 15.0, 1e-15);
  EXPECT_NEAR(AabbIoU(a, a), 1.0, 1e-15);
  AABB c;
  c.Extend(Vec3(2, 0, 0));
  c.Extend(Vec3(3, 1, 1));
  EXPECT_EQ(AabbIoU(a, c), 0.0);  // touching
  EXPECT_EQ(AabbIoU(a, AABB()), 0.0);
  // Agrees with BoxIoU at heading 0.
  const OrientedBox oa{Vec3(1, 1, 1), Vec3(2, 2, 2), 0}, ob{Vec3(2, 2, 2), Vec3(2, 2, 2), 0};
  EXPECT_NEAR(BoxIoU(oa, ob), AabbIoU(a, b), 1e-12);
}

}  // namespace
}  // namespace dimr::geometry
