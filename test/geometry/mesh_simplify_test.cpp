// Mesh cleaning (edge-connected components) and quadric-error decimation.
#include "dimr/geometry/mesh_simplify.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "dimr/geometry/error.h"
#include "dimr/geometry/mesh_distance.h"

namespace dimr::geometry {
namespace {

// n x n cells of a regular grid on z = height over [x0, x0 + n * step] x [0, n * step],
// two faces per cell, counter-clockwise seen from +z.
void AddGrid(TriangleMesh* m, int n, double step, double x0 = 0, double height = 0) {
  const int base = static_cast<int>(m->vertices.size());
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) m->vertices.emplace_back(x0 + i * step, j * step, height);
  }
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int a = base + i * (n + 1) + j, b = a + 1, c = a + n + 1, d = c + 1;
      m->faces.emplace_back(a, c, b);
      m->faces.emplace_back(b, c, d);
    }
  }
}

// Unit sphere: an icosahedron subdivided `levels` times (20 * 4^levels faces), outward faces.
TriangleMesh Icosphere(int levels) {
  TriangleMesh m;
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  const double raw[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                             {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                             {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (const auto& r : raw) m.vertices.push_back(Vec3(r[0], r[1], r[2]).normalized());
  m.faces = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      const int id = static_cast<int>(m.vertices.size()) - 1;
      mid.emplace(key, id);
      return id;
    };
    std::vector<Vec3i> next;
    for (const Vec3i& f : m.faces) {
      const int ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
      next.emplace_back(f[0], ab, ca);
      next.emplace_back(f[1], bc, ab);
      next.emplace_back(f[2], ca, bc);
      next.emplace_back(ab, bc, ca);
    }
    m.faces = std::move(next);
  }
  return m;
}

// Faces per undirected edge.
std::map<std::pair<int, int>, int> EdgeUse(const std::vector<Vec3i>& faces) {
  std::map<std::pair<int, int>, int> use;
  for (const Vec3i& f : faces) {
    for (int k = 0; k < 3; ++k) ++use[std::minmax(f[k], f[(k + 1) % 3])];
  }
  return use;
}

double Area(const TriangleMesh& m) { return m.SurfaceArea(); }

TEST(EdgeConnectedComponents, JoinsThroughEdgesNotVertices) {
  TriangleMesh m;
  AddGrid(&m, 3, 1.0);  // 18 faces
  // Two faces touching the grid's corner vertex 0 only, and each other through an edge.
  m.vertices.emplace_back(-1, 0, 0);
  m.vertices.emplace_back(-1, -1, 0);
  m.vertices.emplace_back(0, -1, 0);
  const int a = static_cast<int>(m.vertices.size()) - 3;
  m.faces.emplace_back(0, a, a + 1);
  m.faces.emplace_back(0, a + 1, a + 2);
  // One lone face far away.
  m.vertices.emplace_back(10, 10, 0);
  m.vertices.emplace_back(11, 10, 0);
  m.vertices.emplace_back(10, 11, 0);
  const int b = static_cast<int>(m.vertices.size()) - 3;
  m.faces.emplace_back(b, b + 1, b + 2);
  const FaceComponents c = EdgeConnectedComponents(m.faces, m.vertices.size());
  ASSERT_EQ(c.size.size(), 3u);
  EXPECT_EQ(c.size[0], 18u);
  EXPECT_EQ(c.size[1], 2u);
  EXPECT_EQ(c.size[2], 1u);
  for (int f = 0; f < 18; ++f) EXPECT_EQ(c.component[f], 0);
  EXPECT_EQ(c.component[18], 1);
  EXPECT_EQ(c.component[19], 1);
  EXPECT_EQ(c.component[20], 2);
  m.faces.back()[2] = static_cast<int>(m.vertices.size());
  EXPECT_THROW(EdgeConnectedComponents(m.faces, m.vertices.size()), InvalidArgument);
}

TEST(RemoveSmallComponents, DropsFragmentsDegenerateFacesAndUnusedVertices) {
  TriangleMesh m;
  AddGrid(&m, 4, 0.1);               // 25 vertices, 32 faces
  AddGrid(&m, 1, 0.1, 5.0);          // a 2-face fragment: vertices 25..28
  m.vertices.emplace_back(9, 9, 9);  // unreferenced: 29
  m.faces.emplace_back(3, 3, 4);     // degenerate
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    m.vertex_colors.emplace_back(static_cast<std::uint8_t>(v), 0, 0);
  m.SetAttribute("label", ScalarType::kInt32, std::vector<double>(m.vertices.size(), 0.0));
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    m.FindAttribute("label")->values[v] = static_cast<double>(100 + v);
  const std::vector<Vec3i> grid_faces(m.faces.begin(), m.faces.begin() + 32);
  const CleanStats s = RemoveSmallComponents(&m, 3);
  // The fragment; the degenerate face shares edge 3-4 with the grid, so it is in the grid's
  // component and goes as degenerate.
  EXPECT_EQ(s.removed_components, 1u);
  EXPECT_EQ(s.removed_faces, 3u);
  EXPECT_EQ(s.removed_vertices, 5u);
  ASSERT_EQ(m.vertices.size(), 25u);
  ASSERT_EQ(m.faces.size(), 32u);
  for (std::size_t f = 0; f < 32; ++f) EXPECT_EQ(m.faces[f], grid_faces[f]) << f;  // same order
  for (std::size_t v = 0; v < 25; ++v) {
    EXPECT_EQ(static_cast<std::size_t>(m.vertex_colors[v][0]), v);
    EXPECT_EQ(m.FindAttribute("label")->values[v], 100.0 + v);
  }
  // Threshold 0 keeps every component but still drops degenerate faces.
  TriangleMesh k;
  AddGrid(&k, 1, 1.0);
  k.faces.emplace_back(0, 1, 1);
  EXPECT_EQ(RemoveSmallComponents(&k, 0).removed_faces, 1u);
  EXPECT_EQ(k.faces.size(), 2u);
  EXPECT_THROW(RemoveSmallComponents(&k, -1), InvalidArgument);
  EXPECT_THROW(RemoveSmallComponents(nullptr, 1), InvalidArgument);
}

TEST(DecimateQuadric, PlaneKeepsItsShapeCornersAndOrientation) {
  TriangleMesh m;
  AddGrid(&m, 40, 0.025);  // 1 m x 1 m, 3200 faces
  QuadricDecimationConfig c;
  c.target_faces = 300;
  DecimationStats st;
  const TriangleMesh d = DecimateQuadric(m.vertices, m.faces, c, &st);
  EXPECT_LE(d.faces.size(), 300u);
  EXPECT_GE(d.faces.size(), 250u);
  EXPECT_GT(st.collapses, 1000u);
  EXPECT_NEAR(Area(d), 1.0, 1e-9);  // the boundary planes keep the border straight
  for (const Vec3& p : d.vertices) EXPECT_EQ(p.z(), 0.0);
  for (const Vec3& corner : {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}) {
    bool found = false;
    for (const Vec3& p : d.vertices) found |= (p - corner).norm() < 1e-12;
    EXPECT_TRUE(found) << corner.transpose();
  }
  for (const Vec3i& f : d.faces) {
    const Vec3 n = (d.vertices[f[1]] - d.vertices[f[0]]).cross(d.vertices[f[2]] - d.vertices[f[0]]);
    EXPECT_GT(n.z(), 0) << f.transpose();  // no face flipped or collapsed
  }
  // Every vertex referenced; indices valid.
  std::vector<int> used(d.vertices.size(), 0);
  for (const Vec3i& f : d.faces) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_GE(f[k], 0);
      ASSERT_LT(f[k], static_cast<int>(d.vertices.size()));
      used[f[k]] = 1;
    }
  }
  EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);
}

TEST(DecimateQuadric, IrregularPlaneDecimatedHardNeverFolds) {
  // A planar grid with jittered vertices decimated to 3 % of its faces: every collapse costs
  // ~0, so only the flip test keeps faces from folding over (each stays counter-clockwise).
  TriangleMesh m;
  AddGrid(&m, 60, 0.02);
  std::uint64_t state = 12345;
  auto uniform = [&state]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 9007199254740992.0 - 0.5;
  };
  for (Vec3& p : m.vertices) {
    const bool border = p.x() < 1e-9 || p.y() < 1e-9 || p.x() > 1.2 - 1e-9 || p.y() > 1.2 - 1e-9;
    if (!border) p += Vec3(0.008 * uniform(), 0.008 * uniform(), 0);
  }
  QuadricDecimationConfig c;
  c.target_faces = 200;
  DecimationStats st;
  const TriangleMesh d = DecimateQuadric(m.vertices, m.faces, c, &st);
  EXPECT_LE(d.faces.size(), 200u);
  EXPECT_GT(st.rejected_flips, 0u);
  EXPECT_GT(st.purged_entries, 0u);  // the sweep of outdated heap entries ran
  for (const Vec3i& f : d.faces) {
    const Vec3 n = (d.vertices[f[1]] - d.vertices[f[0]]).cross(d.vertices[f[2]] - d.vertices[f[0]]);
    EXPECT_GT(n.z(), 0) << f.transpose();
  }
  EXPECT_NEAR(Area(d), Area(m), 1e-9);
}

TEST(DecimateQuadric, SphereStaysClosedAndNearTheSurface) {
  const TriangleMesh m = Icosphere(4);  // 5120 faces, 2562 vertices
  ASSERT_EQ(m.faces.size(), 5120u);
  QuadricDecimationConfig c;
  c.target_faces = 600;
  const TriangleMesh d = DecimateQuadric(m.vertices, m.faces, c);
  EXPECT_LE(d.faces.size(), 600u);
  EXPECT_GE(d.faces.size(), 500u);
  // Closed 2-manifold of genus 0: every edge in exactly two faces, V - E + F = 2.
  const auto use = EdgeUse(d.faces);
  for (const auto& [edge, n] : use) EXPECT_EQ(n, 2) << edge.first << "-" << edge.second;
  EXPECT_EQ(static_cast<long>(d.vertices.size()) - static_cast<long>(use.size()) +
                static_cast<long>(d.faces.size()),
            2);
  // Vertices at input positions or midpoints of merged pairs: within a chord's sagitta of
  // the sphere (the input edges are ~0.06, so < 0.01), and the surface is not shrunk: every
  // input vertex within 0.06 of the decimated mesh.
  for (const Vec3& p : d.vertices) EXPECT_NEAR(p.norm(), 1.0, 0.01);
  double worst = 0;
  for (const Vec3& p : m.vertices) {
    double best = 1e9;
    for (const Vec3i& f : d.faces) {
      best = std::min(best, (p - ClosestPointOnTriangle(p, d.vertices[f[0]], d.vertices[f[1]],
                                                        d.vertices[f[2]]))
                                .norm());
    }
    worst = std::max(worst, best);
  }
  EXPECT_LT(worst, 0.06);
  EXPECT_GT(Area(d), 0.95 * Area(m));
  // Outward orientation kept: the signed volume stays positive and close to the input's.
  auto volume = [](const TriangleMesh& t) {
    double v = 0;
    for (const Vec3i& f : t.faces)
      v += t.vertices[f[0]].dot(t.vertices[f[1]].cross(t.vertices[f[2]])) / 6.0;
    return v;
  };
  EXPECT_GT(volume(d), 0.9 * volume(m));
}

TEST(DecimateQuadric, DeterministicHonoursMaxErrorAndRejectsBadInput) {
  TriangleMesh m = Icosphere(3);
  QuadricDecimationConfig c;
  c.target_faces = 200;
  const TriangleMesh a = DecimateQuadric(m.vertices, m.faces, c);
  const TriangleMesh b = DecimateQuadric(m.vertices, m.faces, c);
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) EXPECT_EQ(a.vertices[i], b.vertices[i]);
  for (std::size_t i = 0; i < a.faces.size(); ++i) EXPECT_EQ(a.faces[i], b.faces[i]);
  // A small error budget stops early, before the face target; no collapse exceeds it.
  DecimationStats free_run, bounded;
  DecimateQuadric(m.vertices, m.faces, c, &free_run);
  QuadricDecimationConfig tight = c;
  tight.max_error = 0.25 * free_run.max_collapse_error;
  const TriangleMesh t = DecimateQuadric(m.vertices, m.faces, tight, &bounded);
  EXPECT_GT(t.faces.size(), a.faces.size());
  EXPECT_LE(bounded.max_collapse_error, tight.max_error);
  EXPECT_LT(bounded.collapses, free_run.collapses);
  // Target above the input: nothing happens.
  QuadricDecimationConfig none;
  none.target_faces = m.faces.size();
  const TriangleMesh same = DecimateQuadric(m.vertices, m.faces, none);
  EXPECT_EQ(same.faces.size(), m.faces.size());
  EXPECT_EQ(same.vertices.size(), m.vertices.size());
  // Bad input names what is wrong.
  std::vector<Vec3> nan_vertices = m.vertices;
  nan_vertices[7].y() = std::nan("");
  try {
    DecimateQuadric(nan_vertices, m.faces, c);
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 7"), std::string::npos) << e.what();
  }
  std::vector<Vec3i> bad_faces = m.faces;
  bad_faces[5][1] = -3;
  try {
    DecimateQuadric(m.vertices, bad_faces, c);
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("face 5"), std::string::npos) << e.what();
  }
  QuadricDecimationConfig neg = c;
  neg.boundary_weight = -1;
  EXPECT_THROW(DecimateQuadric(m.vertices, m.faces, neg), InvalidArgument);
  neg = c;
  neg.max_error = std::nan("");
  EXPECT_THROW(DecimateQuadric(m.vertices, m.faces, neg), InvalidArgument);
}

TEST(DecimateQuadric, SolvesForTheOptimalPositionWhenAllowed) {
  // A bent sheet (two planes meeting at a crease along x = 0.5): with the optimal position
  // (invertible_determinant = 0) vertices may leave the input set, yet stay on the two
  // planes; the crease line survives either way.
  TriangleMesh m;
  AddGrid(&m, 20, 0.05);
  for (Vec3& p : m.vertices) p.z() = std::abs(p.x() - 0.5);
  QuadricDecimationConfig c;
  c.target_faces = 120;
  c.invertible_determinant = 0;
  const TriangleMesh d = DecimateQuadric(m.vertices, m.faces, c);
  EXPECT_LE(d.faces.size(), 120u);
  for (const Vec3& p : d.vertices) EXPECT_NEAR(p.z(), std::abs(p.x() - 0.5), 1e-6);
  int on_crease = 0;
  for (const Vec3& p : d.vertices) on_crease += std::abs(p.x() - 0.5) < 1e-6;
  EXPECT_GE(on_crease, 2);
}

}  // namespace
}  // namespace dimr::geometry
