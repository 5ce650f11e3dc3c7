#include "dimr/pipeline/bsp_mesher.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "bsp_mesher_reference.h"
#include "dimr/geometry/error.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/shape_pool.h"

namespace dimr::pipeline {
namespace {

// Appends the 6 planes of the box [lo, hi]^3 (inside iff n.x + d <= 0).
void AddBox(Eigen::MatrixXf* planes, std::vector<int>* ids, const Eigen::Vector3f& lo,
            const Eigen::Vector3f& hi) {
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector4f p = Eigen::Vector4f::Zero();
    p[a] = 1;
    p[3] = -hi[a];  // x - hi <= 0
    planes->conservativeResize(planes->rows() + 1, 4);
    planes->row(planes->rows() - 1) = p.transpose();
    ids->push_back(static_cast<int>(planes->rows() - 1));
    p = Eigen::Vector4f::Zero();
    p[a] = -1;
    p[3] = lo[a];  // lo - x <= 0
    planes->conservativeResize(planes->rows() + 1, 4);
    planes->row(planes->rows() - 1) = p.transpose();
    ids->push_back(static_cast<int>(planes->rows() - 1));
  }
}

struct Scene {
  Eigen::MatrixXf planes{0, 4};
  std::vector<std::vector<int>> convexes{4};
};

Scene MakeScene() {
  Scene s;
  AddBox(&s.planes, &s.convexes[0], Eigen::Vector3f::Constant(-0.5f),
         Eigen::Vector3f::Constant(0.5f));
  AddBox(&s.planes, &s.convexes[1], Eigen::Vector3f::Constant(-0.2f),
         Eigen::Vector3f::Constant(0.2f));
  AddBox(&s.planes, &s.convexes[2], Eigen::Vector3f::Constant(0.3f),
         Eigen::Vector3f::Constant(0.9f));
  // Contradictory: x <= -0.5 and x >= 0.5.
  s.planes.conservativeResize(s.planes.rows() + 2, 4);
  s.planes.row(s.planes.rows() - 2) << 1, 0, 0, 0.5f;
  s.planes.row(s.planes.rows() - 1) << -1, 0, 0, 0.5f;
  s.convexes[3] = {static_cast<int>(s.planes.rows() - 2), static_cast<int>(s.planes.rows() - 1)};
  return s;
}

TEST(BspMesher, KeepsNonRedundantConvexesAsClosedPolytopes) {
  const Scene s = MakeScene();
  const BspMeshResult r = ExtractBspMesh(s.planes, s.convexes);
  EXPECT_EQ(r.nonempty_convexes, 3);
  ASSERT_EQ(r.kept_convexes, (std::vector<int>{0, 2}));
  // Sum of the two closed parts (overlap counted twice, as the reference's concatenation).
  EXPECT_NEAR(r.mesh.SignedVolume(), 1.0 + 0.6 * 0.6 * 0.6, 1e-5);
  EXPECT_NEAR(r.mesh.SurfaceArea(), 6.0 + 6 * 0.36, 1e-5);
  ASSERT_EQ(r.face_convex.size(), r.mesh.faces.size());
  // Every edge of every part is shared by exactly two triangles with opposite orientation.
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : r.mesh.faces) {
    for (int e = 0; e < 3; ++e) directed[{f[e], f[(e + 1) % 3]}]++;
  }
  for (const auto& [edge, n] : directed) {
    EXPECT_EQ(n, 1);
    EXPECT_EQ(directed.count({edge.second, edge.first}), 1u);
  }
  for (const auto& v : r.mesh.vertices) EXPECT_TRUE(v.allFinite());
}

Eigen::MatrixX3f RandomPoints(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Eigen::MatrixX3f pts(n, 3);
  for (int i = 0; i < pts.rows(); ++i) pts.row(i) << u(rng), u(rng), u(rng);
  return pts;
}

// Expects occupancy == inside one of the cubes [lo, hi]^3 for every point farther than 2 cm from
// their faces; returns how many points were checked.
int ExpectCubeOccupancy(const Eigen::MatrixX3f& pts, const std::vector<std::uint8_t>& occ,
                        const std::vector<std::pair<float, float>>& cubes) {
  int checked = 0;
  for (int i = 0; i < pts.rows(); ++i) {
    const Eigen::Vector3f p = pts.row(i);
    auto in_cube = [&](const std::pair<float, float>& c, float margin) {
      return (p.array() > c.first + margin).all() && (p.array() < c.second - margin).all();
    };
    bool inside = false, near_face = false;
    for (const auto& c : cubes) {
      inside = inside || in_cube(c, 0.f);
      near_face = near_face || in_cube(c, -0.02f) != in_cube(c, 0.02f);
    }
    if (near_face) continue;
    ++checked;
    EXPECT_EQ(occ[i] != 0, inside) << p.transpose();
  }
  return checked;
}

TEST(BspMesher, OccupancyMatchesTheExtractedPartsAwayFromFaces) {
  const Scene s = MakeScene();
  const Eigen::MatrixX3f pts = RandomPoints(4000, 4);
  const auto occ = BspOccupancy(s.planes, s.convexes, pts);
  EXPECT_GT(ExpectCubeOccupancy(pts, occ, {{-0.5f, 0.5f}, {0.3f, 0.9f}}), 3500);
}

// A dilation moves every plane outwards (unit normals here: by the dilation in metres): the
// parts grow, the contradictory convex stays empty, and the occupancy is the grown parts.
TEST(BspMesher, DilationGrowsPartsAndOccupancyAlike) {
  const Scene s = MakeScene();
  BspMeshOptions opt;
  opt.dilation = 0.1f;
  const BspMeshResult r = ExtractBspMesh(s.planes, s.convexes, opt);
  EXPECT_EQ(r.nonempty_convexes, 3);
  ASSERT_EQ(r.kept_convexes, (std::vector<int>{0, 2}));
  // [-0.6, 0.6]^3 and [0.2, 1.0]^3 (clipped at the bound 1).
  EXPECT_NEAR(r.mesh.SignedVolume(), 1.2 * 1.2 * 1.2 + 0.8 * 0.8 * 0.8, 1e-5);
  const Eigen::MatrixX3f pts = RandomPoints(3000, 5);
  const auto occ = BspOccupancy(s.planes, s.convexes, pts, 0.01f, 0.1f);
  EXPECT_GT(ExpectCubeOccupancy(pts, occ, {{-0.6f, 0.6f}, {0.2f, 1.0f}}), 2500);
  opt.dilation = -0.1f;
  EXPECT_THROW(ExtractBspMesh(s.planes, s.convexes, opt), InvalidArgument);
  EXPECT_THROW(BspOccupancy(s.planes, s.convexes, pts, 0.01f, -1.0f), InvalidArgument);
}

// A distance dilation moves every face by the same Euclidean distance whatever the scale of
// its plane; a plane-unit dilation does not. Box [-0.5, 0.5]^3 whose x planes are scaled by 4:
// plane units grow x by 0.1 / 4 and y, z by 0.1, the distance 0.1 grows all three by 0.1.
TEST(BspMesher, DistanceDilationMovesEveryFaceByTheSameDistance) {
  Scene s;
  s.convexes.resize(1);
  AddBox(&s.planes, &s.convexes[0], Eigen::Vector3f::Constant(-0.5f),
         Eigen::Vector3f::Constant(0.5f));
  s.planes.topRows(2) *= 4.0f;  // x <= 0.5 as 4x - 2 <= 0, -x <= 0.5 likewise
  const Eigen::MatrixXf shifted = DistanceDilatedPlanes(s.planes, 0.1f);
  EXPECT_FLOAT_EQ(shifted(0, 3), -2.0f - 0.4f);
  EXPECT_FLOAT_EQ(shifted(2, 3), -0.5f - 0.1f);
  EXPECT_EQ((shifted.leftCols(3) - s.planes.leftCols(3)).cwiseAbs().maxCoeff(), 0.f);
  BspMeshOptions dist;
  dist.distance_dilation = 0.1f;
  EXPECT_NEAR(ExtractBspMesh(s.planes, s.convexes, dist).mesh.SignedVolume(), 1.2 * 1.2 * 1.2,
              1e-5);
  BspMeshOptions plane;
  plane.dilation = 0.1f;
  EXPECT_NEAR(ExtractBspMesh(s.planes, s.convexes, plane).mesh.SignedVolume(), 1.05 * 1.2 * 1.2,
              1e-5);
  // Both together add up per face: x by 0.1 + 0.025, y and z by 0.1 + 0.1.
  BspMeshOptions both = dist;
  both.dilation = 0.1f;
  EXPECT_NEAR(ExtractBspMesh(s.planes, s.convexes, both).mesh.SignedVolume(), 1.25 * 1.4 * 1.4,
              1e-5);
  // The occupancy follows the same faces: x = 0.57 is inside with the distance, not without.
  Eigen::MatrixX3f pts(2, 3);
  pts << 0.57f, 0.f, 0.f, 0.f, 0.57f, 0.f;
  EXPECT_EQ(BspOccupancy(s.planes, s.convexes, pts, dist), (std::vector<std::uint8_t>{1, 1}));
  EXPECT_EQ(BspOccupancy(s.planes, s.convexes, pts, plane), (std::vector<std::uint8_t>{0, 1}));
  EXPECT_EQ(BspOccupancy(s.planes, s.convexes, pts, BspMeshOptions()),
            (std::vector<std::uint8_t>{0, 0}));
  dist.distance_dilation = -0.1f;
  EXPECT_THROW(ExtractBspMesh(s.planes, s.convexes, dist), InvalidArgument);
  EXPECT_THROW(BspOccupancy(s.planes, s.convexes, pts, dist), InvalidArgument);
  EXPECT_THROW(DistanceDilatedPlanes(Eigen::MatrixXf::Zero(2, 3), 0.1f), InvalidArgument);
}

TEST(BspMesher, RejectsBadInput) {
  Scene s = MakeScene();
  s.convexes[0].push_back(999);
  EXPECT_THROW(ExtractBspMesh(s.planes, s.convexes), InvalidArgument);
  Scene t = MakeScene();
  t.planes(0, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(ExtractBspMesh(t.planes, t.convexes), InvalidArgument);
  EXPECT_THROW(ExtractBspMesh(Eigen::MatrixXf::Zero(3, 3), {}), InvalidArgument);
  // No convex at all: an empty mesh, not an error.
  EXPECT_TRUE(ExtractBspMesh(Eigen::MatrixXf::Zero(0, 4), {}).mesh.faces.empty());
}

// Bit-for-bit equality of two extraction results (vertices compared as doubles, not nearly).
void ExpectSameResult(const BspMeshResult& want, const BspMeshResult& got,
                      const std::string& what) {
  EXPECT_EQ(got.nonempty_convexes, want.nonempty_convexes) << what;
  EXPECT_EQ(got.kept_convexes, want.kept_convexes) << what;
  EXPECT_EQ(got.face_convex, want.face_convex) << what;
  ASSERT_EQ(got.mesh.vertices.size(), want.mesh.vertices.size()) << what;
  ASSERT_EQ(got.mesh.faces.size(), want.mesh.faces.size()) << what;
  for (std::size_t v = 0; v < want.mesh.vertices.size(); ++v) {
    ASSERT_TRUE((got.mesh.vertices[v].array() == want.mesh.vertices[v].array()).all())
        << what << ": vertex " << v;
  }
  for (std::size_t f = 0; f < want.mesh.faces.size(); ++f) {
    ASSERT_EQ(got.mesh.faces[f], want.mesh.faces[f]) << what << ": face " << f;
  }
}

// The shipped decoder's shapes (pool codes of every class): the subdivided grid test gives
// exactly the reference extraction (every cell of the grown polytope's box tested with every
// plane), with the card's decoding, the reference decoding and a large plane dilation.
TEST(BspMesher, FastExtractionEqualsTheReferenceOnDecodedShapes) {
  const BspDecoder decoder = BspDecoder::Load(std::string(DIMR_SOURCE_DIR) + "/models/bsp/bsp.pt");
  const ShapePool pool = ShapePool::Load(std::string(DIMR_SOURCE_DIR) + "/models/bsp/pool.bin");
  ASSERT_GE(pool.size(), 16u);
  std::vector<BspMeshOptions> options(3, decoder.mesh_options());
  options[1] = BspMeshOptions();
  options[2].dilation = 0.2f;
  int kept = 0;
  for (std::size_t s = 0; s < 16; ++s) {
    const PoolEntry& e = pool.entries()[s * pool.size() / 16];
    const Eigen::MatrixXf planes = decoder.Planes(e.code, e.cad_class);
    for (std::size_t o = 0; o < options.size(); ++o) {
      const BspMeshResult want =
          testing::ReferenceExtractBspMesh(planes, decoder.convex_planes(), options[o]);
      const BspMeshResult got = ExtractBspMesh(planes, decoder.convex_planes(), options[o]);
      ExpectSameResult(want, got, e.model_id + " options " + std::to_string(o));
      kept += static_cast<int>(got.kept_convexes.size());
    }
  }
  EXPECT_GT(kept, 16 * 3 * 4);  // real shapes of several parts, not empty ones
}

// Random plane sets built to hit the subdivision's branches: convexes of a few cutting planes
// among hundreds that are positive nowhere, tiny and huge plane scales, zero normals, planes
// far outside, planes near the float range, coarse and odd grids, a clipping box smaller and
// larger than [-1, 1]^3, a zero and a large threshold.
TEST(BspMesher, FastExtractionEqualsTheReferenceOnRandomPlaneSets) {
  std::mt19937 rng(19);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  int nonempty = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int P = 400, C = 24;
    Eigen::MatrixXf planes(P, 4);
    for (int p = 0; p < P; ++p) {
      Eigen::Vector3f n(u(rng), u(rng), u(rng));
      const float kind = 0.5f * (u(rng) + 1.f);
      float scale = kind < 0.1f ? 1e-3f : (kind > 0.9f ? 50.f : 1.f + u(rng));
      if (p % 97 == 5) n.setZero();
      // Planes through a point near the origin: the convex is a part of about half a unit.
      const float offset = kind < 0.6f ? 0.3f + 0.3f * u(rng) : 2.0f + u(rng);
      planes.row(p) << scale * n.x(), scale * n.y(), scale * n.z(),
          -scale * (offset * n.norm() + 0.2f * u(rng) * (p % 3 == 0));
    }
    // Planes near the float range, whose values overflow to inf (or NaN) in the cell test.
    for (int p = 0; p < P && trial % 8 == 3; p += 3) {
      if (planes.row(p).cwiseAbs().maxCoeff() < 2.5f) planes.row(p) *= 1.3e38f;  // still finite
    }
    std::vector<std::vector<int>> convexes(C);
    for (int k = 0; k < C; ++k) {
      const int m = k % 6 == 0 ? 3 : 6 + static_cast<int>(rng() % 200);
      for (int j = 0; j < m; ++j) convexes[k].push_back(static_cast<int>(rng() % P));
    }
    BspMeshOptions opt;
    opt.grid = std::vector<int>{32, 2, 5, 17, 32, 40}[trial % 6];
    opt.bound = std::vector<double>{1.0, 0.7, 1.5, 1.0}[trial % 4];
    opt.inside_threshold = std::vector<float>{0.01f, 0.0f, 0.3f}[trial % 3];
    opt.dilation = trial % 5 == 1 ? 0.05f : 0.0f;
    opt.distance_dilation = trial % 7 == 2 ? 0.02f : 0.0f;
    const BspMeshResult want = testing::ReferenceExtractBspMesh(planes, convexes, opt);
    const BspMeshResult got = ExtractBspMesh(planes, convexes, opt);
    ExpectSameResult(want, got, "trial " + std::to_string(trial));
    nonempty += want.nonempty_convexes;
  }
  EXPECT_GT(nonempty, 24);
}

// Convexes that hold grid cells only through the tolerance: cells whose summed excess is just
// below the threshold count (nonempty), whole blocks of them, and still make no polytope.
TEST(BspMesher, CellsJustBelowTheThresholdCount) {
  // Cell centres of the 32^3 grid: x = (2i + 1) / 32 - 1, so i = 16 is at x = 0.03125.
  Eigen::MatrixXf planes(6, 4);
  planes << 1, 0, 0, 0,  // x <= 0
      -1, 0, 0, 0.03f,   // x >= 0.03
      0, 1, 0, 0,        // y <= 0
      0, -1, 0, 0.03f,   // y >= 0.03
      0, 0, 1, 0.5f,     // z <= -0.5
      0, 0, -1, -0.6f;   // z >= -0.6 (a real slab: the cells are a whole block)
  const std::vector<std::vector<int>> convexes = {{0, 1, 4, 5}, {0, 1, 2, 3, 4, 5}};
  BspMeshOptions opt;
  opt.inside_threshold = 0.0313f;  // one excess of 0.03125 is inside, two are not
  BspMeshResult r = ExtractBspMesh(planes, convexes, opt);
  EXPECT_EQ(r.nonempty_convexes, 1);
  EXPECT_TRUE(r.kept_convexes.empty());
  ExpectSameResult(testing::ReferenceExtractBspMesh(planes, convexes, opt), r, "one excess");
  opt.inside_threshold = 0.0626f;  // 2 x 0.03125 = 0.0625 is inside
  r = ExtractBspMesh(planes, convexes, opt);
  EXPECT_EQ(r.nonempty_convexes, 2);
  ExpectSameResult(testing::ReferenceExtractBspMesh(planes, convexes, opt), r, "two excesses");
  opt.inside_threshold = 0.0312f;  // neither
  EXPECT_EQ(ExtractBspMesh(planes, convexes, opt).nonempty_convexes, 0);
}

TEST(BspMesher, RejectsBadBound) {
  const Scene s = MakeScene();
  BspMeshOptions opt;
  for (double b : {0.0, -1.0, std::numeric_limits<double>::infinity()}) {
    opt.bound = b;
    EXPECT_THROW(ExtractBspMesh(s.planes, s.convexes, opt), InvalidArgument) << b;
  }
}

TEST(BspMesher, GridCentersAndOccupancyIoU) {
  const Eigen::MatrixX3f c = BspGridCenters(4);
  ASSERT_EQ(c.rows(), 64);
  EXPECT_FLOAT_EQ(c(0, 0), -0.75f);
  EXPECT_FLOAT_EQ(c(1, 0), -0.25f);  // x fastest
  EXPECT_FLOAT_EQ(c(4, 1), -0.25f);  // then y
  EXPECT_FLOAT_EQ(c(63, 2), 0.75f);
  EXPECT_DOUBLE_EQ(OccupancyIoU({1, 1, 0, 0}, {1, 0, 1, 0}), 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(OccupancyIoU({0, 0}, {0, 0}), 1.0);
  EXPECT_THROW(OccupancyIoU({1}, {1, 0}), InvalidArgument);
}

}  // namespace
}  // namespace dimr::pipeline
