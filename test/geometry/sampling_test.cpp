#include "dimr/geometry/sampling.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

// Closed box [lo, hi]; faces 2f and 2f+1 form side f: -z, +z, -y, +y, -x, +x.
TriangleMesh Box(const Vec3& lo, const Vec3& hi) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.emplace_back((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(),
                            (i & 4) ? hi.z() : lo.z());
  }
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) m.faces.emplace_back(t[0], t[1], t[2]);
  return m;
}

// Distance of a point of the closed box to the box surface (0 on the surface); large if
// the point is outside.
double DistanceToBoxSurface(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  double outside = 0.0, inside = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    outside = std::max({outside, lo[k] - p[k], p[k] - hi[k]});
    inside = std::min({inside, p[k] - lo[k], hi[k] - p[k]});
  }
  return outside > 0 ? outside : inside;
}

TEST(SampleSurface, FaceFrequenciesFollowArea) {
  const Vec3 lo(-1, 0.5, 2), hi(1, 1.5, 2.5);  // 2 x 1 x 0.5
  const TriangleMesh box = Box(lo, hi);
  const std::size_t n = 200000;
  const SurfaceSamples s = SampleSurface(box, n, 42);
  ASSERT_EQ(s.points.size(), n);
  ASSERT_EQ(s.normals.size(), n);
  ASSERT_EQ(s.face_index.size(), n);
  // Side areas: z sides 2 x 1, y sides 2 x 0.5, x sides 1 x 0.5; total 7.
  const double area[6] = {2, 2, 1, 1, 0.5, 0.5};
  const Vec3 normal[6] = {-Vec3::UnitZ(), Vec3::UnitZ(),  -Vec3::UnitY(),
                          Vec3::UnitY(),  -Vec3::UnitX(), Vec3::UnitX()};
  std::size_t count[6] = {0, 0, 0, 0, 0, 0};
  std::size_t tri_count[12] = {};
  Vec3 mean = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const int f = s.face_index[i];
    ASSERT_GE(f, 0);
    ASSERT_LT(f, 12);
    ++count[f / 2];
    ++tri_count[f];
    ASSERT_LT(DistanceToBoxSurface(s.points[i], lo, hi), 1e-12);
    ASSERT_NEAR((s.normals[i] - normal[f / 2]).norm(), 0.0, 1e-12);
    // The point lies on the plane of its face.
    const int axis = 2 - f / 4;
    const double plane = (f / 2) % 2 ? hi[axis] : lo[axis];
    ASSERT_NEAR(s.points[i][axis], plane, 1e-12);
    mean += s.points[i];
  }
  // Per side and per triangle: binomial counts within 5 sigma.
  for (int side = 0; side < 6; ++side) {
    const double p = area[side] / 7.0;
    EXPECT_NEAR(static_cast<double>(count[side]), n * p, 5 * std::sqrt(n * p * (1 - p)))
        << "side " << side;
  }
  for (int t = 0; t < 12; ++t) {
    const double p = area[t / 2] / 14.0;
    EXPECT_NEAR(static_cast<double>(tri_count[t]), n * p, 5 * std::sqrt(n * p * (1 - p)))
        << "triangle " << t;
  }
  // Chi-square over the 12 triangles, 11 degrees of freedom: P(chi2 > 45) < 1e-5.
  double chi2 = 0.0;
  for (int t = 0; t < 12; ++t) {
    const double e = n * area[t / 2] / 14.0;
    chi2 += (tri_count[t] - e) * (tri_count[t] - e) / e;
  }
  EXPECT_LT(chi2, 45.0);
  // The area centroid of the surface is the box centre; per-axis std of a sample <= 1.
  mean /= static_cast<double>(n);
  EXPECT_NEAR((mean - 0.5 * (lo + hi)).norm(), 0.0, 5.0 * std::sqrt(3.0 / n));
}

TEST(SampleSurface, UnitCubeUniformOnEachFace) {
  const TriangleMesh cube = Box(Vec3::Zero(), Vec3::Ones());
  const std::size_t n = 120000;
  const SurfaceSamples s = SampleSurface(cube, n, 3);
  // On the -z side (faces 0 and 1): x and y uniform in [0,1): 10-bin histograms.
  std::vector<int> hx(10, 0), hy(10, 0);
  int on_side = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (s.face_index[i] / 2 != 0) continue;
    ++on_side;
    ++hx[std::min(9, static_cast<int>(s.points[i].x() * 10))];
    ++hy[std::min(9, static_cast<int>(s.points[i].y() * 10))];
  }
  EXPECT_NEAR(on_side, n / 6.0, 5 * std::sqrt(n / 6.0 * 5.0 / 6.0));
  for (int b = 0; b < 10; ++b) {
    const double e = on_side / 10.0, sd = std::sqrt(on_side * 0.1 * 0.9);
    EXPECT_NEAR(hx[b], e, 5 * sd);
    EXPECT_NEAR(hy[b], e, 5 * sd);
  }
}

TEST(SampleSurface, UniformInsideOneTriangle) {
  // Right triangle (0,0), (1,0), (0,1): the density of x is 2 (1 - x).
  TriangleMesh tri;
  tri.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  tri.faces = {Vec3i(0, 1, 2)};
  const std::size_t n = 100000;
  const SurfaceSamples s = SampleSurface(tri, n, 11);
  std::vector<int> hx(10, 0);
  // The 4 midpoint sub-triangles have equal area: corners at (0,0), (1,0), (0,1), and the
  // central inverted one (x + y >= 0.5, x <= 0.5, y <= 0.5).
  int sub[4] = {0, 0, 0, 0};
  for (const Vec3& p : s.points) {
    ASSERT_GE(p.x(), 0.0);
    ASSERT_GE(p.y(), 0.0);
    ASSERT_LE(p.x() + p.y(), 1.0 + 1e-15);
    ASSERT_EQ(p.z(), 0.0);
    ++hx[std::min(9, static_cast<int>(p.x() * 10))];
    if (p.x() + p.y() < 0.5) {
      ++sub[0];
    } else if (p.x() > 0.5) {
      ++sub[1];
    } else if (p.y() > 0.5) {
      ++sub[2];
    } else {
      ++sub[3];
    }
  }
  for (int b = 0; b < 10; ++b) {
    const double a = b / 10.0, c = (b + 1) / 10.0;
    const double p = (1 - a) * (1 - a) - (1 - c) * (1 - c);
    EXPECT_NEAR(hx[b], n * p, 5 * std::sqrt(n * p * (1 - p))) << "bin " << b;
  }
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(sub[k], n / 4.0, 5 * std::sqrt(n * 0.25 * 0.75)) << "sub-triangle " << k;
  }
}

TEST(SampleSurface, DeterministicPerSeed) {
  const TriangleMesh box = Box(Vec3::Zero(), Vec3(2, 1, 0.5));
  const SurfaceSamples a = SampleSurface(box, 1000, 123);
  const SurfaceSamples b = SampleSurface(box, 1000, 123);
  const SurfaceSamples c = SampleSurface(box, 1000, 124);
  ASSERT_EQ(a.points.size(), 1000u);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.face_index, b.face_index);
  std::size_t same = 0;
  for (std::size_t i = 0; i < 1000; ++i) same += a.points[i] == c.points[i];
  EXPECT_EQ(same, 0u);
  // A prefix of a longer run with the same seed is the shorter run.
  const SurfaceSamples d = SampleSurface(box, 10, 123);
  EXPECT_TRUE(std::equal(d.points.begin(), d.points.end(), a.points.begin()));
}

TEST(SampleSurface, DegenerateInputs) {
  TriangleMesh empty;
  EXPECT_TRUE(SampleSurface(empty, 10, 1).points.empty());
  TriangleMesh flat;
  flat.vertices = {Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2)};
  flat.faces = {Vec3i(0, 1, 2), Vec3i(0, 0, 1)};
  EXPECT_TRUE(SampleSurface(flat, 10, 1).points.empty());
  EXPECT_TRUE(SampleSurface(Box(Vec3::Zero(), Vec3::Ones()), 0, 1).points.empty());
  // Zero-area faces mixed in are never sampled.
  TriangleMesh mixed = Box(Vec3::Zero(), Vec3::Ones());
  mixed.faces.insert(mixed.faces.begin() + 3, Vec3i(0, 0, 1));
  mixed.faces.emplace_back(1, 1, 1);
  const SurfaceSamples s = SampleSurface(mixed, 20000, 5);
  for (int f : s.face_index) {
    ASSERT_NE(f, 3);
    ASSERT_NE(f, 13);
  }
  TriangleMesh bad = Box(Vec3::Zero(), Vec3::Ones());
  bad.faces.emplace_back(0, 1, 8);
  EXPECT_THROW(SampleSurface(bad, 10, 1), InvalidArgument);
}

TEST(SampleSurfaceEven, RespectsRadiusAndCount) {
  const TriangleMesh cube = Box(Vec3::Zero(), Vec3::Ones());
  const std::size_t n = 400;
  const SurfaceSamples s = SampleSurfaceEven(cube, n, 9);
  // Default radius sqrt(area / (3 n)) = sqrt(6 / 1200).
  const double r = std::sqrt(6.0 / (3.0 * n));
  ASSERT_LE(s.points.size(), n);
  EXPECT_GT(s.points.size(), n * 3 / 4);
  ASSERT_EQ(s.normals.size(), s.points.size());
  ASSERT_EQ(s.face_index.size(), s.points.size());
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_LT(DistanceToBoxSurface(s.points[i], Vec3::Zero(), Vec3::Ones()), 1e-12);
    for (std::size_t j = i + 1; j < s.points.size(); ++j) {
      ASSERT_GE((s.points[i] - s.points[j]).norm(), r) << i << " " << j;
    }
  }
  // Deterministic; the points are a subset of the plain samples, in order.
  const SurfaceSamples again = SampleSurfaceEven(cube, n, 9);
  EXPECT_EQ(s.points, again.points);
  const SurfaceSamples plain = SampleSurface(cube, 3 * n, 9);
  std::size_t k = 0;
  for (const Vec3& p : plain.points) {
    if (k < s.points.size() && p == s.points[k]) ++k;
  }
  EXPECT_EQ(k, s.points.size());
  EXPECT_EQ(s.points.front(), plain.points.front());
}

TEST(SampleSurfaceEven, ExplicitRadius) {
  const TriangleMesh cube = Box(Vec3::Zero(), Vec3::Ones());
  // Larger than the diagonal: exactly one point survives.
  EXPECT_EQ(SampleSurfaceEven(cube, 100, 1, 2.0).points.size(), 1u);
  // Radius 0.3: all kept pairs at least 0.3 apart; a 1-cube surface cannot hold many.
  const SurfaceSamples s = SampleSurfaceEven(cube, 1000, 2, 0.3);
  EXPECT_GT(s.points.size(), 20u);
  EXPECT_LT(s.points.size(), 200u);
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    for (std::size_t j = i + 1; j < s.points.size(); ++j) {
      ASSERT_GE((s.points[i] - s.points[j]).norm(), 0.3);
    }
  }
  EXPECT_TRUE(SampleSurfaceEven(TriangleMesh(), 10, 1).points.empty());
}

}  // namespace
}  // namespace dimr::geometry
