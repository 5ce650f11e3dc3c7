#include "dimr/pipeline/bsp_mesher.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <utility>
#include <vector>

#include "dimr/geometry/error.h"

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
