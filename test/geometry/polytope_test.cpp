#include "dimr/geometry/polytope.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "dimr/core/hash.h"
#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

HalfSpace H(double a, double b, double c, double d) { return HalfSpace{Vec3(a, b, c), d}; }

// The unit cube [0,1]^3 as 6 half-spaces: x <= 1, x >= 0, y <= 1, y >= 0, z <= 1, z >= 0.
std::vector<HalfSpace> CubePlanes() {
  return {H(1, 0, 0, -1), H(-1, 0, 0, 0), H(0, 1, 0, -1),
          H(0, -1, 0, 0), H(0, 0, 1, -1), H(0, 0, -1, 0)};
}

// Unit normal and offset of a half-space (pre-scaled so that tiny normals do not underflow).
std::pair<Vec3, double> Normalized(const HalfSpace& h) {
  const double m = h.normal.cwiseAbs().maxCoeff();
  const Vec3 n = h.normal / m;
  return {n.normalized(), h.offset / m / n.norm()};
}

// Newell normal of a face (length = twice its area).
Vec3 FaceNormal(const Polytope& p, const std::vector<int>& f) {
  Vec3 n = Vec3::Zero();
  for (std::size_t k = 0; k < f.size(); ++k) {
    const Vec3& a = p.vertices[f[k]];
    const Vec3& b = p.vertices[f[(k + 1) % f.size()]];
    n += a.cross(b);
  }
  return n;
}

// Structural checks shared by every test: the mesh is closed and consistently oriented (every
// directed edge once, its reverse exactly once), faces are simple polygons, each face with a
// plane index lies on that plane with its outward normal along the plane normal, and the
// mesh volume equals Volume().
void CheckStructure(const Polytope& p, const std::vector<HalfSpace>& planes) {
  ASSERT_EQ(p.faces.size(), p.face_plane.size());
  ASSERT_GE(p.faces.size(), 4u);
  std::map<std::pair<int, int>, int> edges;
  std::vector<int> used(p.vertices.size(), 0);
  for (std::size_t f = 0; f < p.faces.size(); ++f) {
    const auto& face = p.faces[f];
    ASSERT_GE(face.size(), 3u);
    ASSERT_EQ(std::set<int>(face.begin(), face.end()).size(), face.size()) << "face " << f;
    for (std::size_t k = 0; k < face.size(); ++k) {
      ASSERT_GE(face[k], 0);
      ASSERT_LT(face[k], static_cast<int>(p.vertices.size()));
      used[face[k]] = 1;
      ++edges[{face[k], face[(k + 1) % face.size()]}];
    }
    const int pi = p.face_plane[f];
    ASSERT_GE(pi, -1);
    ASSERT_LT(pi, static_cast<int>(planes.size()));
    if (pi >= 0) {
      const auto [n, d] = Normalized(planes[pi]);
      for (int v : face) EXPECT_NEAR(n.dot(p.vertices[v]) + d, 0.0, 1e-9) << "face " << f;
      EXPECT_GT(FaceNormal(p, face).dot(n), 0.0) << "face " << f << " is not CCW from outside";
    }
  }
  for (int u : used) EXPECT_EQ(u, 1) << "unreferenced vertex";
  for (const auto& [e, count] : edges) {
    ASSERT_EQ(count, 1) << "edge " << e.first << "->" << e.second;
    const auto twin = edges.find({e.second, e.first});
    ASSERT_TRUE(twin != edges.end()) << "open edge " << e.first << "->" << e.second;
  }
  const TriangleMesh mesh = p.ToMesh();
  std::map<std::pair<int, int>, int> tri_edges;
  for (const Vec3i& t : mesh.faces) {
    for (int k = 0; k < 3; ++k) ++tri_edges[{t[k], t[(k + 1) % 3]}];
  }
  for (const auto& [e, count] : tri_edges) {
    ASSERT_EQ(count, 1);
    ASSERT_EQ(tri_edges.count({e.second, e.first}), 1u);
  }
  EXPECT_NEAR(mesh.SignedVolume(), p.Volume(), 1e-12);
  EXPECT_GT(p.Volume(), 0.0);
}

TEST(Polytope, UnitCubeFromSixPlanes) {
  const auto planes = CubePlanes();
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), 8u);
  ASSERT_EQ(p.faces.size(), 6u);
  for (const auto& f : p.faces) EXPECT_EQ(f.size(), 4u);
  EXPECT_DOUBLE_EQ(p.Volume(), 1.0);
  std::set<int> labels(p.face_plane.begin(), p.face_plane.end());
  EXPECT_EQ(labels, (std::set<int>{0, 1, 2, 3, 4, 5}));
  std::set<std::vector<double>> corners;
  for (const Vec3& v : p.vertices) corners.insert({v.x(), v.y(), v.z()});
  std::set<std::vector<double>> want;
  for (int i = 0; i < 8; ++i) want.insert({double(i & 1), double((i >> 1) & 1), double(i >> 2)});
  EXPECT_EQ(corners, want);  // exact coordinates
  const TriangleMesh mesh = p.ToMesh();
  EXPECT_EQ(mesh.faces.size(), 12u);
  EXPECT_DOUBLE_EQ(mesh.SurfaceArea(), 6.0);

  // Bounds equal to the cube: the input planes take over the box faces.
  PolytopeOptions opt;
  opt.bounds.min = Vec3::Zero();
  opt.bounds.max = Vec3::Ones();
  const Polytope q = IntersectHalfSpaces(planes, opt);
  CheckStructure(q, planes);
  EXPECT_EQ(q.vertices.size(), 8u);
  EXPECT_EQ(std::set<int>(q.face_plane.begin(), q.face_plane.end()),
            (std::set<int>{0, 1, 2, 3, 4, 5}));
}

TEST(Polytope, Tetrahedron) {
  const std::vector<HalfSpace> planes = {H(-1, 0, 0, 0), H(0, -1, 0, 0), H(0, 0, -1, 0),
                                         H(1, 1, 1, -1)};
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), 4u);
  ASSERT_EQ(p.faces.size(), 4u);
  for (const auto& f : p.faces) EXPECT_EQ(f.size(), 3u);
  EXPECT_NEAR(p.Volume(), 1.0 / 6.0, 1e-15);
  for (const Vec3& v : p.vertices) {
    const bool is_corner =
        v == Vec3(0, 0, 0) || v == Vec3(1, 0, 0) || v == Vec3(0, 1, 0) || v == Vec3(0, 0, 1);
    EXPECT_TRUE(is_corner) << v.transpose();
  }
  EXPECT_EQ(std::set<int>(p.face_plane.begin(), p.face_plane.end()), (std::set<int>{0, 1, 2, 3}));
}

TEST(Polytope, RedundantPlanesLeaveTheCubeUnchanged) {
  auto planes = CubePlanes();
  planes.push_back(H(1, 0, 0, -2));      // x <= 2: beyond the cube (and the bounds)
  planes.push_back(H(1, 1, 1, -3));      // touches only the corner (1,1,1)
  planes.push_back(H(1, 1, 0, -2));      // touches only the edge x = y = 1
  planes.push_back(H(-1, -1, 0, -0.5));  // x + y >= -0.5: far away
  planes.push_back(H(0, 0, 5, -5));      // z <= 1 again, scaled normal
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), 8u);
  EXPECT_EQ(p.faces.size(), 6u);
  EXPECT_DOUBLE_EQ(p.Volume(), 1.0);
  for (int l : p.face_plane) EXPECT_LT(l, 6);
  // The same planes in another order: the redundant ones first.
  std::vector<HalfSpace> reordered(planes.begin() + 6, planes.end());
  reordered.insert(reordered.end(), planes.begin(), planes.begin() + 6);
  const Polytope q = IntersectHalfSpaces(reordered);
  CheckStructure(q, reordered);
  EXPECT_EQ(q.vertices.size(), 8u);
  EXPECT_EQ(q.faces.size(), 6u);
  EXPECT_DOUBLE_EQ(q.Volume(), 1.0);
}

TEST(Polytope, DuplicatedPlanes) {
  auto planes = CubePlanes();
  const auto once = planes;
  planes.insert(planes.end(), once.begin(), once.end());
  for (const HalfSpace& h : once) planes.push_back({h.normal * 3.5, h.offset * 3.5});
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), 8u);
  EXPECT_EQ(p.faces.size(), 6u);
  EXPECT_DOUBLE_EQ(p.Volume(), 1.0);
  // The first occurrence owns the face.
  EXPECT_EQ(std::set<int>(p.face_plane.begin(), p.face_plane.end()),
            (std::set<int>{0, 1, 2, 3, 4, 5}));
}

TEST(Polytope, NearlyParallelPlanesMakeNoSlivers) {
  auto planes = CubePlanes();
  planes.push_back(H(1, 0, 0, -(1 + 1e-12)));  // x <= 1 + 1e-12
  planes.push_back(H(1, 0, 0, -(1 - 1e-12)));  // x <= 1 - 1e-12
  planes.push_back(H(1, 1e-12, 0, -1));        // tilted by 1e-12
  planes.push_back(H(0, -1, 1e-12, -1e-12));   // y >= 1e-12 z - 1e-12
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), 8u);
  EXPECT_EQ(p.faces.size(), 6u);
  EXPECT_NEAR(p.Volume(), 1.0, 1e-11);
  for (const Vec3& v : p.vertices) EXPECT_TRUE(v.allFinite());
}

TEST(Polytope, ContradictoryPlanesGiveEmpty) {
  // x <= -0.5 and x >= 0.5.
  Polytope p = IntersectHalfSpaces({H(1, 0, 0, 0.5), H(-1, 0, 0, 0.5)});
  EXPECT_TRUE(p.empty());
  EXPECT_TRUE(p.vertices.empty());
  EXPECT_EQ(p.Volume(), 0.0);
  EXPECT_TRUE(p.ToMesh().faces.empty());
  // The same along a diagonal, with the cube around.
  auto planes = CubePlanes();
  planes.push_back(H(1, 1, 1, -0.5));    // x + y + z <= 0.5
  planes.push_back(H(-2, -2, -2, 2.2));  // x + y + z >= 1.1
  EXPECT_TRUE(IntersectHalfSpaces(planes).empty());
  // Entirely outside the bounds.
  EXPECT_TRUE(IntersectHalfSpaces({H(-1, 0, 0, 3)}).empty());  // x >= 3
}

TEST(Polytope, ZeroThicknessSlabGivesEmpty) {
  EXPECT_TRUE(IntersectHalfSpaces({H(1, 0, 0, -0.3), H(-1, 0, 0, 0.3)}).empty());
  auto planes = CubePlanes();
  planes.push_back(H(1, 1, 0, -1));
  planes.push_back(H(-1, -1, 0, 1));  // the plane x + y = 1 from both sides
  EXPECT_TRUE(IntersectHalfSpaces(planes).empty());
  planes.back().offset = 1 - 1e-12;  // thickness 1e-12 / sqrt(2): below the tolerance
  EXPECT_TRUE(IntersectHalfSpaces(planes).empty());
  // A thin but real slab survives: 0.3 <= x <= 0.3 + 1e-6.
  const std::vector<HalfSpace> thin = {H(1, 0, 0, -0.300001), H(-1, 0, 0, 0.3)};
  const Polytope p = IntersectHalfSpaces(thin);
  CheckStructure(p, thin);
  EXPECT_NEAR(p.Volume(), 4e-6, 1e-12);
  // A slab touching the bounds from outside: x >= 1 within [-1, 1]^3.
  EXPECT_TRUE(IntersectHalfSpaces({H(-1, 0, 0, 1)}).empty());
}

TEST(Polytope, UnboundedSetsAreClippedToTheBounds) {
  // No plane: the bounds box itself.
  Polytope p = IntersectHalfSpaces({});
  CheckStructure(p, {});
  EXPECT_EQ(p.vertices.size(), 8u);
  EXPECT_DOUBLE_EQ(p.Volume(), 8.0);
  for (int l : p.face_plane) EXPECT_EQ(l, -1);
  // x + y + z <= 0 halves [-1,1]^3 through a regular hexagon.
  const std::vector<HalfSpace> half = {H(1, 1, 1, 0)};
  p = IntersectHalfSpaces(half);
  CheckStructure(p, half);
  EXPECT_EQ(p.vertices.size(), 10u);
  ASSERT_EQ(p.faces.size(), 7u);
  EXPECT_NEAR(p.Volume(), 4.0, 1e-14);
  int caps = 0;
  for (std::size_t f = 0; f < p.faces.size(); ++f) {
    if (p.face_plane[f] == 0) {
      ++caps;
      EXPECT_EQ(p.faces[f].size(), 6u);
      // Regular hexagon with side sqrt(2): area 3 sqrt(3).
      EXPECT_NEAR(FaceNormal(p, p.faces[f]).norm() / 2, 3 * std::sqrt(3.0), 1e-13);
    }
  }
  EXPECT_EQ(caps, 1);
  // A wedge (two planes) in a non-symmetric box: [0,2]x[0,3]x[0,4], x <= 1, y <= x + 1.
  PolytopeOptions opt;
  opt.bounds.min = Vec3(0, 0, 0);
  opt.bounds.max = Vec3(2, 3, 4);
  const std::vector<HalfSpace> wedge = {H(1, 0, 0, -1), H(-1, 1, 0, -1)};
  p = IntersectHalfSpaces(wedge, opt);
  CheckStructure(p, wedge);
  // Cross-section {0<=x<=1, 0<=y<=x+1}: area 1.5; times 4 in z.
  EXPECT_NEAR(p.Volume(), 6.0, 1e-14);
  for (const Vec3& v : p.vertices) {
    EXPECT_TRUE(opt.bounds.Contains(v));
  }
}

TEST(Polytope, ZeroNormalPlanes) {
  auto planes = CubePlanes();
  planes.push_back(H(0, 0, 0, -1));  // 0 <= 1: everywhere
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_DOUBLE_EQ(p.Volume(), 1.0);
  planes.push_back(H(0, 0, 0, 1e-30));  // 1e-30 <= 0: nowhere
  EXPECT_TRUE(IntersectHalfSpaces(planes).empty());
  // Tiny but non-zero normals are ordinary planes: 1e-300 x <= 0.5e-300 -> x <= 0.5.
  const std::vector<HalfSpace> tiny = {H(1e-300, 0, 0, -0.5e-300)};
  const Polytope t = IntersectHalfSpaces(tiny);
  CheckStructure(t, tiny);
  EXPECT_NEAR(t.Volume(), 6.0, 1e-14);
}

TEST(Polytope, RejectsBadInput) {
  EXPECT_THROW(IntersectHalfSpaces({H(std::nan(""), 0, 0, 0)}), InvalidArgument);
  EXPECT_THROW(IntersectHalfSpaces({H(1, 0, 0, INFINITY)}), InvalidArgument);
  PolytopeOptions opt;
  opt.bounds = AABB();  // empty
  EXPECT_THROW(IntersectHalfSpaces({}, opt), InvalidArgument);
  opt.bounds.min = Vec3(0, 0, 0);
  opt.bounds.max = Vec3(1, INFINITY, 1);
  EXPECT_THROW(IntersectHalfSpaces({}, opt), InvalidArgument);
  opt.bounds.max = Vec3(1, 0, 1);  // flat box: nothing has volume
  EXPECT_TRUE(IntersectHalfSpaces({}, opt).empty());
}

TEST(Polytope, OctahedronFourPlanesPerVertex) {
  std::vector<HalfSpace> planes;
  for (int i = 0; i < 8; ++i) {
    planes.push_back(H(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1, -1));
  }
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), 6u);
  ASSERT_EQ(p.faces.size(), 8u);
  for (const auto& f : p.faces) EXPECT_EQ(f.size(), 3u);
  EXPECT_NEAR(p.Volume(), 4.0 / 3.0, 1e-14);
  for (const Vec3& v : p.vertices) EXPECT_NEAR(v.cwiseAbs().sum(), 1.0, 1e-15);
}

TEST(Polytope, SixtyFourPlanesThroughOneApex) {
  // A pyramid over a regular 64-gon of inradius 0.5 at z = 0 with apex (0, 0, 0.5).
  constexpr int kSides = 64;
  std::vector<HalfSpace> planes;
  for (int k = 0; k < kSides; ++k) {
    const double t = 2 * M_PI * k / kSides;
    planes.push_back(H(std::cos(t), std::sin(t), 1, -0.5));
  }
  planes.push_back(H(0, 0, -1, 0));
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  EXPECT_EQ(p.vertices.size(), kSides + 1u);
  EXPECT_EQ(p.faces.size(), kSides + 1u);
  const double base = kSides * 0.25 * std::tan(M_PI / kSides);
  EXPECT_NEAR(p.Volume(), base * 0.5 / 3, 1e-12);
}

TEST(Polytope, ManyTangentPlanesApproximateASphere) {
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<HalfSpace> planes;
  for (int i = 0; i < 400; ++i) {
    const Vec3 n = Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
    planes.push_back({n, -0.8});
  }
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  const double sphere = 4.0 / 3.0 * M_PI * 0.8 * 0.8 * 0.8;
  EXPECT_GT(p.Volume(), sphere);
  EXPECT_LT(p.Volume(), 1.1 * sphere);
  EXPECT_GT(p.faces.size(), 300u);  // most tangent planes contribute a face
}

// Half-spaces with normals in {-1,0,1}^3 and offsets in {0, -0.5, -1}: many exact vertex
// coincidences (4+ planes through a vertex, planes through existing edges).
TEST(Polytope, LatticePlanesWithCoincidences) {
  std::mt19937 rng(77);
  int non_empty = 0;
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<HalfSpace> planes;
    const int k = 3 + static_cast<int>(rng() % 12);
    while (static_cast<int>(planes.size()) < k) {
      const Vec3 n(static_cast<int>(rng() % 3) - 1, static_cast<int>(rng() % 3) - 1,
                   static_cast<int>(rng() % 3) - 1);
      if (n.isZero()) continue;
      planes.push_back({n, -0.5 * static_cast<int>(rng() % 3)});
    }
    const Polytope p = IntersectHalfSpaces(planes);
    // Exact volume by counting cells of a fine grid is not available; compare with a
    // Monte-Carlo estimate and check the structure.
    std::uniform_real_distribution<double> ub(-1.0, 1.0);
    int inside = 0;
    constexpr int kSamples = 20000;
    for (int s = 0; s < kSamples; ++s) {
      const Vec3 x(ub(rng), ub(rng), ub(rng));
      bool in = true;
      for (const HalfSpace& h : planes) in = in && h.normal.dot(x) + h.offset <= 0;
      inside += in;
    }
    const double frac = static_cast<double>(inside) / kSamples;
    const double sigma = 8.0 * std::sqrt(std::max(frac * (1 - frac), 1.0 / kSamples) / kSamples);
    EXPECT_NEAR(p.Volume(), 8.0 * frac, 5 * sigma + 1e-9) << "trial " << trial;
    if (p.empty()) continue;
    ++non_empty;
    CheckStructure(p, planes);
    for (const Vec3& v : p.vertices) {
      for (const HalfSpace& h : planes) {
        EXPECT_LE(h.normal.dot(v) + h.offset, 1e-9 * h.normal.norm());
      }
    }
  }
  EXPECT_GT(non_empty, 50);
}

// Every vertex satisfies every plane within 1e-9 (the default tolerance for [-1,1]^3).
void CheckVerticesInside(const Polytope& p, const std::vector<HalfSpace>& planes) {
  for (const Vec3& v : p.vertices) {
    ASSERT_TRUE(v.allFinite());
    for (const HalfSpace& h : planes) {
      const auto [n, d] = Normalized(h);
      EXPECT_LE(n.dot(v) + d, 1e-9 + 1e-15);
    }
  }
}

std::vector<HalfSpace> FromRows(const std::vector<std::array<double, 4>>& rows) {
  std::vector<HalfSpace> planes;
  for (const auto& r : rows) planes.push_back(H(r[0], r[1], r[2], r[3]));
  return planes;
}

// Regression cases found by a 10^6-set stress run (planes passing within 1e-12..1e-6 of
// common points). The first makes a cap touch itself at one vertex (it must be split into
// two simple faces); the second cuts off only a vertex lying on a straight edge (no cap).
TEST(Polytope, ToleranceRegressionPinchedCap) {
  const auto planes = FromRows(
      {{-0x1.82af438bafc12p-3, 0x1.280c47f07fe4ap-1, 0x1.96644c3986b6bp-1, -0x1.c8ad944f83ccfp-6},
       {-0x1.e2a09e767f622p-4, 0x1.c95b92fcd3d87p-1, -0x1.bc33319402791p-2, -0x1.112704dd977b2p-2},
       {0x1.5dab0af42edccp-1, -0x1.6637fa8aead11p-3, -0x1.6b1eba4e8c0edp-1, -0x1.660c759106542p-5},
       {-0x1.ce530db1070ecp-1, 0x1.a506bd1c9c50dp-6, 0x1.b7368738e57dp-2, -0x1.719dd2c5f49e9p-5},
       {0x1.f5a9389bb39e7p-4, 0x1.ee3cab8b9c3bfp-1, -0x1.d84c1e844c8b2p-3, -0x1.17cc3b9963bep-4},
       {-0x1.09cb3ee6083abp-1, 0x1.794bcb821aa51p-7, 0x1.b5908db34161bp-1, -0x1.1d836d521f5b7p-3},
       {0x1.ec8a008b23ea8p-1, -0x1.6b9077be41de2p-3, 0x1.a8fb3dc479f46p-3, -0x1.e143b1c0d0ff8p-6},
       {-0x1.987a87e6e1e67p-3, 0x1.dd192b01fb1a5p-1, 0x1.366fdc2716d18p-2, -0x1.39182520bcbdp-6},
       {-0x1.8cf9a1b3d66abp-1, -0x1.2e5209622bb8ap-2, -0x1.1dd76984df64p-1, -0x1.54b2e1beda51fp-4},
       {0x1.f98809aaafeadp-5, 0x1.1847b12f4a907p-1, -0x1.ab4dda6d7c228p-1, -0x1.ebb20b330823dp-4},
       {0x1.4718dd1971fb5p-4, 0x1.71e19c61da3f3p-4, 0x1.fc4427120aa2ap-1, -0x1.c18e9cd25be7fp-3},
       {0x1.1b9592cf8d237p-5, 0x1.ebe10413d9c18p-2, 0x1.c0b69b19b9cb5p-1, -0x1.46f7f90d0e95ep-2},
       {-0x1.2714263ec658ep-4, 0x1.0da7ab402cd36p-2, 0x1.ec8caf584c3a7p-1, -0x1.0b97866af8bfp-2},
       {0x1.c80b56b90f0acp-1, 0x1.a0216312e1e1bp-2, -0x1.a1294bbb8b755p-3, -0x1.43e9c8ca0a26dp-8}});
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  CheckVerticesInside(p, planes);
}

TEST(Polytope, ToleranceRegressionVertexOnStraightEdge) {
  const auto planes = FromRows(
      {{0x1.5fab2e2594e5cp-3, -0x1.835cea14b7cecp-2, 0x1.d1ba3a3697407p-1, -0x1.8479c2541638p-8},
       {-0x1.9b2690d0107fep-1, -0x1.596f229bf6cb3p-2, -0x1.f70ffe09fe356p-2, -0x1.c17db3de696abp-6},
       {-0x1.a0505928513bfp-3, 0x1.c68f82145002bp-1, -0x1.a6c86eb8e59p-2, -0x1.43fd3bc4b0ee8p-3},
       {0x1.6e69bf3c24141p-4, 0x1.e8a7030bc0cf5p-4, -0x1.fa469f4bf3829p-1, -0x1.2c0f3b6be6e6ap-8},
       {-0x1.703c6146db34bp-1, -0x1.70ae3c818ffe4p-2, -0x1.303eb69061d7bp-1, -0x1.66e728471abcp-4},
       {-0x1.277537dd57cc6p-3, 0x1.32e174ee8142p-1, -0x1.9320cc859205ep-1, -0x1.4aef904d17417p-6},
       {-0x1.8d857b5434cep-2, -0x1.8b69740194f65p-1, -0x1.0176b944e0f83p-1, -0x1.c4bbf609e3cf4p-6},
       {-0x1.ac2f5a4a6c697p-1, 0x1.9c48b26047d71p-2, -0x1.7d16a8281e534p-2, -0x1.4931a935e155dp-3},
       {0x1.02d3ed26ce4abp-2, 0x1.161176cc23a5ap-3, -0x1.ea78ff58b5d2ep-1, -0x1.61062e854f8dfp-4},
       {-0x1.e2c91c0317bdap-1, -0x1.3b83191cef994p-4, -0x1.4bb3d9f0806f2p-2, -0x1.7bed50752cc8p-4},
       {0x1.df20b51db9c52p-3, -0x1.75b39e2b43eb1p-1, 0x1.48da02a554464p-1, -0x1.01134ddf21337p-8},
       {-0x1.eefec4e8ae905p-2, -0x1.39c759e86aa65p-3, 0x1.b949ceaa94266p-1, -0x1.c04bb44517606p-4},
       {-0x1.c40a3cad8b1fbp-1, -0x1.40b84962fa625p-4, -0x1.da1ddabf3b8e8p-2, -0x1.846b1ecd0ed58p-6},
       {-0x1.4152878fe4aa5p-2, -0x1.98a78b518b2ccp-3, 0x1.db489f4c7bc23p-1, -0x1.66d72e48c79f8p-4},
       {-0x1.0ffe025cf155cp-1, 0x1.a6a44b817ab6p-1, 0x1.86a76ba15becep-3, -0x1.f5960de0b929p-4},
       {-0x1.4245e18ef9659p-3, 0x1.f2eba68a2e879p-2, -0x1.b7cc4e176a932p-1, -0x1.3f516c0957d8ep-10},
       {0x1.797534e0b57d1p-4, 0x1.84c2eb57dc914p-4, -0x1.fb800634c3999p-1, -0x1.495d44500bda3p-8},
       {0x1.c00748aab13b7p-2, 0x1.79d80eb5a02cfp-1, 0x1.070cec8d6c484p-1, -0x1.95f80a9b33215p-5},
       {-0x1.3fd96aa4aed15p-1, 0x1.46588edf6786cp-5, 0x1.8f47a57d1383cp-1, -0x1.4d1354d290751p-8},
       {-0x1.4b9543da60ep-1, -0x1.7a0dc035499a2p-2, -0x1.55453bf1747cep-1, -0x1.b125761eeed7cp-6},
       {-0x1.e1ee18a9d22bp-1, -0x1.494521ccd28eep-2, 0x1.a6031bab98c1dp-4, -0x1.6582f184992c9p-5},
       {-0x1.b40f6f34bbc11p-1, -0x1.4429b27ca086p-4, 0x1.093e0d039feabp-1, -0x1.d79a232b36589p-7},
       {-0x1.2ec3cd43b9bfbp-4, -0x1.efcaafa2fa1fp-1, 0x1.e84c99d26a8d3p-3, -0x1.2f27d98261ba2p-6},
       {0x1.3499529936e57p-3, -0x1.319ff10a4e62dp-1, 0x1.93777cea3d2e6p-1, -0x1.c0a1fd54b720ap-10},
       {0x1.4da318cb76a1ep-3, -0x1.ca814f7da08fap-1, 0x1.a81341cd3a626p-2, -0x1.5d7f0738993dap-7},
       {-0x1.92ebdf5cefd65p-1, 0x1.813c4f3643547p-2, -0x1.f4c9505d06752p-2, -0x1.a989219ffe9e2p-4},
       {0x1.7a64ebc7766ecp-2, 0x1.57251259fda62p-3, 0x1.d3f679f0b357fp-1, -0x1.098eb97af61e1p-5},
       {-0x1.8f84ed0d3ce3bp-3, -0x1.13c0368affc8cp-1, 0x1.a3ad87e7559afp-1, -0x1.e1d939352adc4p-8},
       {0x1.751d0197d7476p-2, 0x1.b37c7a00360e3p-1, 0x1.844a55c0a4465p-2, -0x1.603e7361eb0ap-6},
       {0x1.b9fb4f9f1a977p-2, 0x1.417cb0baecc0cp-4, -0x1.cc19a30a560bbp-1, -0x1.d2f5e57a0c67ap-5},
       {0x1.77b9773826201p-3, 0x1.dc278ab57a248p-3, 0x1.e907c9b20c156p-1, -0x1.0d7591378ff5ep-4},
       {-0x1.9904099650165p-1, 0x1.842af5a045998p-3, -0x1.244a06f97ec12p-1, -0x1.4f5c9e1fe341p-4},
       {-0x1.7ddae70729991p-2, 0x1.d56ec27cf24fep-3, 0x1.cc58613fffff9p-1, -0x1.129d55c625f1dp-3},
       {-0x1.6b5fa64f82defp-1, 0x1.53309e7545bcdp-2, -0x1.3e575c68b38f2p-1, -0x1.5347bbef538b5p-3},
       {-0x1.bcc7611378ca2p-1, -0x1.fa9bdec7e1a19p-3, -0x1.b76e775d1c988p-2, -0x1.b1656525779e4p-6},
       {-0x1.ae8e18b81265p-2, 0x1.e7ab4b387dfap-2, 0x1.8b6769faa4d1cp-1, -0x1.0069f594d1f81p-6},
       {-0x1.220487b073dccp-1, 0x1.6faebca8b8fbcp-3, -0x1.9bce61faa69e3p-1,
        -0x1.173f7b6bef89fp-5}});
  const Polytope p = IntersectHalfSpaces(planes);
  CheckStructure(p, planes);
  CheckVerticesInside(p, planes);
}

// Planes through (or within 1e-12..1e-6 of) a few shared points, and near-copies of earlier
// planes (some flipped into thin slabs): the classification tolerance decides many
// incidences; the result must stay closed, consistently oriented and inside every plane.
TEST(Polytope, NearCoincidentPlanesStress) {
  std::mt19937 rng(31337);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int non_empty = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    std::vector<Vec3> anchors;
    for (int i = 0; i < 3; ++i) anchors.emplace_back(0.15 * g(rng), 0.15 * g(rng), 0.15 * g(rng));
    std::vector<HalfSpace> planes;
    const int k = 4 + static_cast<int>(rng() % 40);
    for (int i = 0; i < k; ++i) {
      if (trial % 2 == 1 && !planes.empty() && u(rng) < 0.6) {
        HalfSpace h = planes[rng() % planes.size()];
        const double e = std::pow(10.0, -8 - 6 * u(rng));
        h.normal += Vec3(g(rng), g(rng), g(rng)) * e;
        h.offset += g(rng) * e;
        if (u(rng) < 0.2) {
          h.normal = -h.normal;
          h.offset = -h.offset - 1e-3 * u(rng);
        }
        planes.push_back(h);
        continue;
      }
      Vec3 n = Vec3(g(rng), g(rng), g(rng)).normalized();
      double d;
      if (trial % 2 == 0) {
        const Vec3& a = anchors[rng() % 3];
        d = -n.dot(a) + std::pow(10.0, -6 - 6 * u(rng)) * (u(rng) < 0.5 ? -1 : 1);
        if (d > 0) {
          n = -n;
          d = -d;
        }
      } else {
        d = -(0.05 + 0.9 * u(rng));
      }
      planes.push_back({n, d});
    }
    const Polytope p = IntersectHalfSpaces(planes);
    if (p.empty()) continue;
    ++non_empty;
    CheckStructure(p, planes);
    CheckVerticesInside(p, planes);
    if (HasFailure()) {
      ADD_FAILURE() << "trial " << trial;
      return;
    }
  }
  EXPECT_GT(non_empty, 2000);
}

// 200 random half-space sets against brute force.
TEST(Polytope, RandomSetsMatchMonteCarlo) {
  std::mt19937 rng(2024);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  int non_empty = 0, empty = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int k = 4 + static_cast<int>(rng() % 27);
    std::vector<HalfSpace> planes;
    for (int i = 0; i < k; ++i) {
      Vec3 n(gauss(rng), gauss(rng), gauss(rng));
      n.normalize();
      // Mostly around the origin; every 5th set may exclude it (possibly empty sets).
      const double r = trial % 5 == 4 ? -0.6 + 1.4 * u01(rng) : 0.15 + 0.8 * u01(rng);
      const double scale = 0.25 + 4 * u01(rng);  // unnormalised input
      planes.push_back({n * scale, -r * scale});
      if (trial % 7 == 3 && i % 4 == 0) planes.push_back(planes.back());  // duplicate
      if (trial % 11 == 5 && i % 3 == 0) {  // nearly parallel companion
        HalfSpace h = planes.back();
        h.normal += Vec3(1e-13, -2e-13, 0);
        h.offset += 1e-12;
        planes.push_back(h);
      }
    }
    const Polytope p = IntersectHalfSpaces(planes);
    // Normalised planes for the checks.
    std::vector<Vec3> nn;
    std::vector<double> dd;
    for (const HalfSpace& h : planes) {
      nn.push_back(Normalized(h).first);
      dd.push_back(Normalized(h).second);
    }
    // Monte-Carlo volume in [-1,1]^3 and a point-wise inside/outside comparison with the
    // output faces (for points farther than 1e-6 from every plane).
    constexpr int kSamples = 20000;
    std::uniform_real_distribution<double> ub(-1.0, 1.0);
    std::vector<Vec3> fn;
    std::vector<double> fd;
    for (const auto& f : p.faces) {
      const Vec3 n = FaceNormal(p, f).normalized();
      fn.push_back(n);
      fd.push_back(-n.dot(p.vertices[f[0]]));
    }
    int inside = 0, mismatches = 0;
    for (int s = 0; s < kSamples; ++s) {
      const Vec3 x(ub(rng), ub(rng), ub(rng));
      bool in = true;
      double margin = 1.0;
      for (std::size_t i = 0; i < nn.size(); ++i) {
        const double v = nn[i].dot(x) + dd[i];
        in = in && v <= 0;
        margin = std::min(margin, std::abs(v));
      }
      inside += in;
      if (margin < 1e-6) continue;
      bool in_poly = !p.empty();
      for (std::size_t f = 0; f < fn.size() && in_poly; ++f) in_poly = fn[f].dot(x) + fd[f] <= 0;
      mismatches += in != in_poly;
    }
    EXPECT_EQ(mismatches, 0) << "trial " << trial;
    const double frac = static_cast<double>(inside) / kSamples;
    const double estimate = 8.0 * frac;
    const double sigma = 8.0 * std::sqrt(std::max(frac * (1 - frac), 1.0 / kSamples) / kSamples);
    EXPECT_NEAR(p.Volume(), estimate, 5 * sigma + 1e-9) << "trial " << trial;
    if (p.empty()) {
      ++empty;
      EXPECT_LT(inside, 3) << "trial " << trial;
      continue;
    }
    ++non_empty;
    CheckStructure(p, planes);
    // Every vertex satisfies every plane (and the bounds) and lies on >= 3 of them.
    for (const Vec3& v : p.vertices) {
      int on = 0;
      for (std::size_t i = 0; i < nn.size(); ++i) {
        const double s = nn[i].dot(v) + dd[i];
        EXPECT_LE(s, 1e-9) << "trial " << trial;
        on += std::abs(s) <= 1e-9;
      }
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(v[a], -1 - 1e-12);
        EXPECT_LE(v[a], 1 + 1e-12);
        on += std::abs(v[a] - 1) <= 1e-9;
        on += std::abs(v[a] + 1) <= 1e-9;
      }
      EXPECT_GE(on, 3) << "trial " << trial << " vertex " << v.transpose();
    }
  }
  // The generator really produces both kinds.
  std::printf("random polytopes: %d non-empty, %d empty\n", non_empty, empty);
  EXPECT_GT(non_empty, 150);
  EXPECT_GT(empty, 3);
}

namespace golden {

// Deterministic uniform doubles in [0, 1) (SplitMix64; no standard-library distribution, whose
// output may differ between library versions).
struct Mix {
  std::uint64_t s;
  double Next() {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }
};

std::uint64_t HashOf(const Polytope& p, std::uint64_t h) {
  for (const Vec3& v : p.vertices) h = Fnv1a(v.data(), 3 * sizeof(double), h);
  for (const auto& f : p.faces) h = Fnv1a(f.data(), f.size() * sizeof(int), h);
  return Fnv1a(p.face_plane.data(), p.face_plane.size() * sizeof(int), h);
}

}  // namespace golden

// Sets shaped like the BSP decoder's convexes (hundreds of planes, most of them far outside
// the part, a few cutting it, some unnormalised, duplicated or on the bounds): the vertices,
// faces and face planes hash to the values recorded with the implementation before the
// bounding-box skip of planes that cannot cut (bit-exact, same order).
TEST(Polytope, BspLikeSetsBitExactWithRecordedOutput) {
  golden::Mix rng{77};
  std::uint64_t h = kFnv1aOffset;
  int non_empty = 0;
  for (int trial = 0; trial < 60; ++trial) {
    std::vector<HalfSpace> planes;
    const Vec3 c(rng.Next() - 0.5, rng.Next() - 0.5, rng.Next() - 0.5);
    const double r = 0.1 + 0.5 * rng.Next();
    for (int i = 0; i < 320; ++i) {
      Vec3 n(rng.Next() - 0.5, rng.Next() - 0.5, rng.Next() - 0.5);
      if (n.norm() < 1e-3) n = Vec3(0, 0, 1);
      n.normalize();
      const double kind = rng.Next();
      // Tangent-ish to a sphere around c (cutting), far away (redundant) or an axis plane.
      double dist = kind < 0.15 ? r * (0.8 + 0.4 * rng.Next()) : r + 0.5 + 2.0 * rng.Next();
      if (kind > 0.97) {
        n = Vec3::Zero();
        n[i % 3] = i % 2 ? 1.0 : -1.0;
        dist = 1.0 - n.dot(c);  // n.x <= 1: on a face of the bounds [-1, 1]^3
      }
      const double scale = 0.2 + 5.0 * rng.Next();
      planes.push_back({n * scale, (-dist - n.dot(c)) * scale});
      if (i % 53 == 7) planes.push_back(planes.back());
    }
    const Polytope p = IntersectHalfSpaces(planes);
    h = golden::HashOf(p, h);
    if (p.empty()) continue;
    ++non_empty;
    CheckStructure(p, planes);
    if (HasFailure()) {
      ADD_FAILURE() << "trial " << trial;
      return;
    }
  }
  EXPECT_GT(non_empty, 50);
  std::printf("polytope golden hash %016llx\n", static_cast<unsigned long long>(h));
  EXPECT_EQ(h, 0x66d577ef6ed43843ull);
}

}  // namespace
}  // namespace dimr::geometry
