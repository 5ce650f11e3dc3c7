#include "dimr/geometry/mesh_distance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "dimr/geometry/error.h"
#include "geometry/test_meshes.h"

namespace dimr::geometry {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void ExpectVecEq(const Vec3& got, const Vec3& want) {
  EXPECT_EQ(got.x(), want.x()) << got.transpose() << " vs " << want.transpose();
  EXPECT_EQ(got.y(), want.y()) << got.transpose() << " vs " << want.transpose();
  EXPECT_EQ(got.z(), want.z()) << got.transpose() << " vs " << want.transpose();
}

TEST(MeshDistanceClosestPoint, EveryRegionOfARightTriangle) {
  const Vec3 a(0, 0, 0), b(2, 0, 0), c(0, 2, 0);
  // Vertex regions.
  ExpectVecEq(ClosestPointOnTriangle(Vec3(-1, -1, 3), a, b, c), a);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(3, -1, 0), a, b, c), b);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(-1, 3, 1), a, b, c), c);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(5, 1, -2), a, b, c), b);  // beyond b along bc's side
  // Edge regions.
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, -2, 5), a, b, c), Vec3(1, 0, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(-3, 0.5, -2), a, b, c), Vec3(0, 0.5, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(2, 2, 1), a, b, c), Vec3(1, 1, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(2, 1, 0), a, b, c), Vec3(1.5, 0.5, 0));
  // In the face and above/below it.
  ExpectVecEq(ClosestPointOnTriangle(Vec3(0.5, 0.5, 0), a, b, c), Vec3(0.5, 0.5, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(0.5, 0.25, -7), a, b, c), Vec3(0.5, 0.25, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, 0.5, 3), a, b, c), Vec3(1, 0.5, 0));
  // Vertex order must not matter.
  ExpectVecEq(ClosestPointOnTriangle(Vec3(2, 2, 1), c, a, b), Vec3(1, 1, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, -2, 5), b, c, a), Vec3(1, 0, 0));
}

TEST(MeshDistanceClosestPoint, TiltedTriangle) {
  // The triangle x + y + z = 1 in the positive octant.
  const Vec3 a(1, 0, 0), b(0, 1, 0), c(0, 0, 1);
  const Vec3 g = ClosestPointOnTriangle(Vec3(1, 1, 1), a, b, c);
  EXPECT_NEAR(g.x(), 1.0 / 3, 1e-15);
  EXPECT_NEAR(g.y(), 1.0 / 3, 1e-15);
  EXPECT_NEAR(g.z(), 1.0 / 3, 1e-15);
  // (2, 2, -3) lies in the triangle's plane, outside, symmetric about the edge ab: the
  // closest point is the midpoint of ab.
  const Vec3 m = ClosestPointOnTriangle(Vec3(2, 2, -3), a, b, c);
  EXPECT_NEAR(m.x(), 0.5, 1e-15);
  EXPECT_NEAR(m.y(), 0.5, 1e-15);
  EXPECT_NEAR(m.z(), 0.0, 1e-15);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(0, 0, 5), a, b, c), c);
}

TEST(MeshDistanceClosestPoint, DegenerateTriangles) {
  // Collapsed to the segment [0, 4] on the x axis (c in the middle).
  const Vec3 a(0, 0, 0), b(4, 0, 0), c(2, 0, 0);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, 3, 0), a, b, c), Vec3(1, 0, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(3, -1, 2), a, b, c), Vec3(3, 0, 0));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(5, 1, 1), a, b, c), b);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(-2, 0, 1), a, b, c), a);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(5, 1, 1), c, a, b), b);
  // Two coincident vertices: the segment from (0,0,0) to (0,0,2).
  const Vec3 z(0, 0, 2);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, 0, 1), a, a, z), Vec3(0, 0, 1));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, 0, 1), a, z, a), Vec3(0, 0, 1));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(1, 0, 1), z, a, a), Vec3(0, 0, 1));
  ExpectVecEq(ClosestPointOnTriangle(Vec3(0, 3, -4), a, a, z), a);
  // Collapsed to a point.
  const Vec3 p(1, 2, 3);
  ExpectVecEq(ClosestPointOnTriangle(Vec3(-5, 7, 0.5), p, p, p), p);
  for (const Vec3& r : {ClosestPointOnTriangle(Vec3(1, 3, 0), a, b, c),
                        ClosestPointOnTriangle(Vec3(7, 7, 7), p, p, p)}) {
    EXPECT_TRUE(r.allFinite());
  }
}

using testing::UnitCube;

TEST(MeshDistance, UnitCubeKnownDistances) {
  const MeshDistance md(UnitCube());
  ASSERT_FALSE(md.empty());
  EXPECT_EQ(md.num_triangles(), 12u);
  // Inside: distance to the nearest face.
  EXPECT_DOUBLE_EQ(md.Query(Vec3(0.2, 0.5, 0.6)).distance, 0.2);
  EXPECT_DOUBLE_EQ(md.Query(Vec3(0.5, 0.9, 0.4)).distance, 0.1);
  EXPECT_DOUBLE_EQ(md.Query(Vec3(0.5, 0.5, 0.5)).distance, 0.5);
  ClosestPoint cp = md.Query(Vec3(0.7, 0.6, 0.75));
  EXPECT_DOUBLE_EQ(cp.distance, 0.25);
  EXPECT_DOUBLE_EQ(cp.point.z(), 1.0);
  EXPECT_TRUE(cp.face == 2 || cp.face == 3) << cp.face;  // the z = 1 faces
  // Outside, straight above a face.
  cp = md.Query(Vec3(0.5, 0.25, 3.0));
  EXPECT_DOUBLE_EQ(cp.distance, 2.0);
  ExpectVecEq(cp.point, Vec3(0.5, 0.25, 1.0));
  // Outside along the diagonal from the corner (1,1,1): sqrt(3) t.
  for (double t : {0.01, 0.5, 1.0, 7.0}) {
    cp = md.Query(Vec3(1 + t, 1 + t, 1 + t));
    EXPECT_NEAR(cp.distance, std::sqrt(3.0) * t, 1e-14 * (1 + t));
    ExpectVecEq(cp.point, Vec3(1, 1, 1));
    cp = md.Query(Vec3(-t, -t, -t));
    EXPECT_NEAR(cp.distance, std::sqrt(3.0) * t, 1e-14 * (1 + t));
    ExpectVecEq(cp.point, Vec3(0, 0, 0));
  }
  // Outside an edge: (2, 2, 0.5) -> edge x = y = 1, distance sqrt(2).
  EXPECT_NEAR(md.Query(Vec3(2, 2, 0.5)).distance, std::sqrt(2.0), 1e-15);
  // On the surface.
  EXPECT_EQ(md.Query(Vec3(1, 0.3, 0.3)).distance, 0.0);
}

TEST(MeshDistance, EmptyMesh) {
  TriangleMesh m;
  m.vertices.emplace_back(1, 2, 3);  // vertices but no faces
  const MeshDistance md(m);
  EXPECT_TRUE(md.empty());
  const ClosestPoint cp = md.Query(Vec3(0, 0, 0));
  EXPECT_EQ(cp.distance, kInf);
  EXPECT_EQ(cp.face, -1);
  const auto d = md.Distances({Vec3::Zero(), Vec3::Ones()});
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0], kInf);
  EXPECT_EQ(d[1], kInf);
}

TEST(MeshDistance, RejectsBadMeshAndNonFiniteQueries) {
  TriangleMesh m = UnitCube();
  m.faces.emplace_back(0, 1, 8);
  EXPECT_THROW(MeshDistance{m}, InvalidArgument);
  m = UnitCube();
  m.faces.emplace_back(0, -1, 2);
  EXPECT_THROW(MeshDistance{m}, InvalidArgument);
  m = UnitCube();
  m.vertices[3].x() = std::nan("");
  EXPECT_THROW(MeshDistance{m}, InvalidArgument);
  const MeshDistance md(UnitCube());
  const ClosestPoint cp = md.Query(Vec3(kInf, 0, 0));
  EXPECT_EQ(cp.face, -1);
  EXPECT_TRUE(std::isnan(cp.distance));
}

TEST(MeshDistance, MatchesBruteForceOnRandomMesh) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.04);
  TriangleMesh m;
  for (int f = 0; f < 2000; ++f) {
    const Vec3 center(u(rng), u(rng), u(rng));
    const int base = static_cast<int>(m.vertices.size());
    for (int k = 0; k < 3; ++k) m.vertices.push_back(center + Vec3(g(rng), g(rng), g(rng)));
    if (f % 97 == 0) m.vertices.back() = m.vertices[base];  // degenerate: segment
    if (f % 211 == 0) m.vertices[base + 1] = m.vertices[base + 2] = m.vertices[base];  // point
    m.faces.emplace_back(base, base + 1, base + 2);
  }
  // A few large triangles too (they overlap many BVH boxes).
  for (int f = 0; f < 20; ++f) {
    const int base = static_cast<int>(m.vertices.size());
    for (int k = 0; k < 3; ++k) m.vertices.emplace_back(u(rng), u(rng), u(rng));
    m.faces.emplace_back(base, base + 1, base + 2);
  }
  const MeshDistance md(m);
  std::uniform_real_distribution<double> uq(-0.5, 1.5);
  std::vector<Vec3> queries;
  for (int i = 0; i < 5000; ++i) queries.emplace_back(uq(rng), uq(rng), uq(rng));
  for (int i = 0; i < 50; ++i) queries.push_back(m.vertices[(i * 37) % m.vertices.size()]);
  const std::vector<double> dist = md.Distances(queries);
  ASSERT_EQ(dist.size(), queries.size());
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Vec3& q = queries[i];
    double best = kInf;
    for (const Vec3i& f : m.faces) {
      const Vec3 cp =
          ClosestPointOnTriangle(q, m.vertices[f[0]], m.vertices[f[1]], m.vertices[f[2]]);
      best = std::min(best, (cp - q).squaredNorm());
    }
    best = std::sqrt(best);
    const ClosestPoint cp = md.Query(q);
    ASSERT_NEAR(cp.distance, best, 1e-12) << "query " << i;
    ASSERT_NEAR(dist[i], best, 1e-12) << "query " << i;
    // The reported point and face are consistent with the distance.
    ASSERT_NEAR((cp.point - q).norm(), cp.distance, 1e-12);
    const Vec3i& f = m.faces[cp.face];
    const Vec3 on_face =
        ClosestPointOnTriangle(q, m.vertices[f[0]], m.vertices[f[1]], m.vertices[f[2]]);
    ASSERT_NEAR((on_face - q).norm(), best, 1e-12);
    if (i >= 5000) {
      ASSERT_EQ(cp.distance, 0.0);
    }
  }
}

}  // namespace
}  // namespace dimr::geometry
