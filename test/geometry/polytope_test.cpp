#include "dimr/geometry/polytope.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <utility>
#include <vector>

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

}  // namespace
}  // namespace dimr::geometry
