// TSDF fusion -> marching cubes -> cleaning -> decimation on a known solid (an analytic box).
#include "dimr/data/tsdf_fusion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "dimr/geometry/error.h"
#include "dimr/geometry/kdtree.h"

namespace dimr::data {
namespace {

using geometry::Color;
using geometry::Vec3;

const Vec3 kCentre(0.0, 0.0, 0.5);
const Vec3 kHalf(0.5, 0.3, 0.25);

// Face colour by the axis (and sign) of the box face a point lies on.
Color FaceColor(int axis, bool positive) {
  const Color table[6] = {Color(200, 40, 40),  Color(40, 200, 40),  Color(40, 40, 200),
                          Color(200, 200, 40), Color(40, 200, 200), Color(200, 40, 200)};
  return table[2 * axis + (positive ? 1 : 0)];
}

// Distance of p to the surface of the box.
double BoxDistance(const Vec3& p) {
  const Vec3 q = (p - kCentre).cwiseAbs() - kHalf;
  const double outside = q.cwiseMax(0.0).norm();
  const double inside = std::min(q.maxCoeff(), 0.0);
  return std::abs(outside + inside);
}

// Ray-box (slab) intersection; returns t or +inf, and the hit face.
double CastBox(const Vec3& o, const Vec3& d, int* axis, bool* positive) {
  double t0 = -std::numeric_limits<double>::infinity(), t1 = -t0;
  int enter_axis = -1;
  for (int k = 0; k < 3; ++k) {
    const double lo = kCentre[k] - kHalf[k], hi = kCentre[k] + kHalf[k];
    if (std::abs(d[k]) < 1e-12) {
      if (o[k] < lo || o[k] > hi) return std::numeric_limits<double>::infinity();
      continue;
    }
    double a = (lo - o[k]) / d[k], b = (hi - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    if (a > t0) {
      t0 = a;
      enter_axis = k;
    }
    t1 = std::min(t1, b);
  }
  if (t0 > t1 || t0 <= 0 || enter_axis < 0) return std::numeric_limits<double>::infinity();
  *axis = enter_axis;
  *positive = d[enter_axis] < 0;
  return t0;
}

// Camera looking at `target` from `eye` (optical frame: x right, y down, z forward).
Eigen::Isometry3d LookAt(const Vec3& eye, const Vec3& target) {
  const Vec3 fwd = (target - eye).normalized();
  const Vec3 right = fwd.cross(Vec3::UnitZ()).normalized();
  const Vec3 down = fwd.cross(right);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = right;
  pose.linear().col(1) = down;
  pose.linear().col(2) = fwd;
  pose.translation() = eye;
  return pose;
}

std::vector<RgbdFrame> BoxFrames() {
  std::vector<RgbdFrame> frames;
  for (int ring = 0; ring < 2; ++ring) {
    for (int i = 0; i < 12; ++i) {
      const double a = 2 * M_PI * (i + 0.5 * ring) / 12;
      const Vec3 eye(1.8 * std::cos(a), 1.8 * std::sin(a), ring == 0 ? 0.9 : 1.6);
      RgbdFrame f;
      f.width = 160;
      f.height = 120;
      f.fx = f.fy = 140;
      f.cx = 79.5;
      f.cy = 59.5;
      f.pose = LookAt(eye, kCentre);
      f.depth.assign(160 * 120, 0.0f);
      f.color.assign(160 * 120, Color(0, 0, 0));
      for (int v = 0; v < f.height; ++v) {
        for (int u = 0; u < f.width; ++u) {
          const Vec3 dc((u - f.cx) / f.fx, (v - f.cy) / f.fy, 1.0);
          const Vec3 dw = f.pose.linear() * dc.normalized();
          int axis = 0;
          bool positive = false;
          const double t = CastBox(eye, dw, &axis, &positive);
          if (!std::isfinite(t)) continue;
          f.depth[v * f.width + u] = static_cast<float>(t * dc.normalized().z());
          f.color[v * f.width + u] = FaceColor(axis, positive);
        }
      }
      frames.push_back(std::move(f));
    }
  }
  return frames;
}

FusedMesh FuseBox(const TsdfConfig& c) {
  TsdfFusion fusion(c);
  for (const auto& f : BoxFrames()) fusion.Integrate(f);
  EXPECT_EQ(fusion.frames(), 24);
  return fusion.Extract();
}

TEST(TsdfFusionTest, BoxVerticesLieOnItsFaces) {
  TsdfConfig c;  // 1 cm voxels, 4 cm truncation, 2 cm target spacing
  const FusedMesh m = FuseBox(c);
  ASSERT_GT(m.mesh.vertices.size(), 500u);
  ASSERT_EQ(m.colors.size(), m.mesh.vertices.size());
  EXPECT_GT(m.marching_cubes_vertices, 3 * m.mesh.vertices.size());  // decimated
  // Seen surface: 4 sides and the top (the bottom face at z = 0.25 is never seen).
  const double seen_area = 2 * (2 * kHalf.x() * 2 * kHalf.z() + 2 * kHalf.y() * 2 * kHalf.z()) +
                           2 * kHalf.x() * 2 * kHalf.y();
  EXPECT_NEAR(m.surface_area, seen_area, 0.15 * seen_area);
  // Tolerance: vertices more than 3 cm from every box edge lie within half a voxel (5 mm) of
  // a face, 90 % of them within 2 mm (marching-cubes interpolation of a projective TSDF whose
  // voxel centres do not lie on the faces); all vertices within 2 voxels
  // (2 cm): a projective TSDF bulges convex edges outwards by ~1.5 voxels, and the open
  // boundary at the unseen bottom overshoots by about as much.
  std::vector<double> d;
  std::vector<double> flat_d;
  for (const auto& p : m.mesh.vertices) {
    d.push_back(BoxDistance(p));
    const Vec3 q = (p - kCentre).cwiseAbs();
    int near_planes = 0;
    for (int k = 0; k < 3; ++k) near_planes += q[k] > kHalf[k] - 0.03;
    if (near_planes <= 1) {
      EXPECT_LT(d.back(), 0.005) << p.transpose();
      flat_d.push_back(d.back());
    }
  }
  ASSERT_GT(flat_d.size(), m.mesh.vertices.size() / 2);
  std::sort(flat_d.begin(), flat_d.end());
  EXPECT_LT(flat_d[flat_d.size() * 9 / 10], 0.002);
  std::sort(d.begin(), d.end());
  EXPECT_LT(d.back(), 0.02);
  // Vertices on the flat interior of the +x face carry that face's colour.
  int checked = 0;
  for (std::size_t i = 0; i < m.mesh.vertices.size(); ++i) {
    const Vec3 q = m.mesh.vertices[i] - kCentre;
    if (std::abs(q.x() - kHalf.x()) < 0.003 && std::abs(q.y()) < kHalf.y() - 0.05 &&
        std::abs(q.z()) < kHalf.z() - 0.05) {
      const Color want = FaceColor(0, true);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(m.colors[i][k], want[k], 12) << i;
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
  // Decimated to about the target spacing: median nearest-neighbour distance.
  const geometry::KdTree tree(m.mesh.vertices);
  std::vector<double> nn;
  for (const auto& p : m.mesh.vertices) nn.push_back(std::sqrt(tree.KNearest(p, 2)[1].second));
  std::nth_element(nn.begin(), nn.begin() + nn.size() / 2, nn.end());
  const double median = nn[nn.size() / 2];
  EXPECT_GT(median, 0.4 * c.target_spacing);
  EXPECT_LT(median, 2.0 * c.target_spacing);
  // Faces index valid vertices.
  for (const auto& f : m.mesh.faces) {
    EXPECT_GE(f.minCoeff(), 0);
    EXPECT_LT(f.maxCoeff(), static_cast<int>(m.mesh.vertices.size()));
  }
  std::printf(
      "box: %zu MC vertices -> %zu vertices, area %.3f m2, median NN %.4f m, max dist %.4f\n"
      "timings: %s\n",
      m.marching_cubes_vertices, m.mesh.vertices.size(), m.surface_area, median, d.back(),
      m.timings.ToString().c_str());
}

// dimr's cleaning + decimation (the default) against Open3D 0.16's (open3d_simplify = 1, what
// SynthScan v2 used before): the same cleaned surface, about as many vertices, the same
// spacing and the same closeness to the box.
TEST(TsdfFusionTest, DimrAndOpen3dSimplificationAgree) {
  TsdfConfig c;
  const FusedMesh ours = FuseBox(c);
  c.open3d_simplify = 1;
  const FusedMesh theirs = FuseBox(c);
  EXPECT_EQ(ours.marching_cubes_triangles, theirs.marching_cubes_triangles);
  EXPECT_EQ(ours.removed_components, theirs.removed_components);
  EXPECT_NEAR(ours.surface_area, theirs.surface_area, 1e-9 * theirs.surface_area);
  const double nv = static_cast<double>(theirs.mesh.vertices.size());
  EXPECT_NEAR(static_cast<double>(ours.mesh.vertices.size()), nv, 0.1 * nv);
  EXPECT_LE(ours.mesh.faces.size(), theirs.mesh.faces.size() + 2);
  auto median_nn = [](const FusedMesh& m) {
    const geometry::KdTree tree(m.mesh.vertices);
    std::vector<double> nn;
    for (const auto& p : m.mesh.vertices) nn.push_back(std::sqrt(tree.KNearest(p, 2)[1].second));
    std::nth_element(nn.begin(), nn.begin() + nn.size() / 2, nn.end());
    return nn[nn.size() / 2];
  };
  EXPECT_NEAR(median_nn(ours), median_nn(theirs), 0.1 * median_nn(theirs));
  auto p90_distance = [](const FusedMesh& m) {
    std::vector<double> d;
    for (const auto& p : m.mesh.vertices) d.push_back(BoxDistance(p));
    std::sort(d.begin(), d.end());
    return d[d.size() * 9 / 10];
  };
  EXPECT_LT(p90_distance(ours), 1.2 * p90_distance(theirs) + 5e-4);
  std::printf("dimr: %zu vertices, decimate %.0f ms; open3d: %zu vertices, decimate %.0f ms\n",
              ours.mesh.vertices.size(), ours.timings.ms("decimate"), theirs.mesh.vertices.size(),
              theirs.timings.ms("decimate"));
}

TEST(TsdfFusionTest, SmallComponentsAreRemovedAndOutputIsDeterministic) {
  TsdfConfig c;
  c.target_spacing = 0.03;
  auto frames = BoxFrames();
  // A speck of 3x3 pixels floating 0.6 m in front of the camera in one frame only.
  for (int v = 60; v < 63; ++v) {
    for (int u = 80; u < 83; ++u) frames[0].depth[v * 160 + u] = 0.6f;
  }
  auto fuse = [&]() {
    TsdfFusion fusion(c);
    for (const auto& f : frames) fusion.Integrate(f);
    return fusion.Extract();
  };
  const FusedMesh a = fuse();
  EXPECT_GE(a.removed_components, 1u);
  for (const auto& p : a.mesh.vertices) EXPECT_LT(BoxDistance(p), 0.02);
  const FusedMesh b = fuse();
  ASSERT_EQ(a.mesh.vertices.size(), b.mesh.vertices.size());
  ASSERT_EQ(a.mesh.faces.size(), b.mesh.faces.size());
  for (std::size_t i = 0; i < a.mesh.vertices.size(); ++i) {
    ASSERT_EQ(a.mesh.vertices[i], b.mesh.vertices[i]) << i;
    ASSERT_EQ(a.colors[i], b.colors[i]) << i;
  }
}

TEST(TsdfFusionTest, BadInputNamesTheProblem) {
  TsdfConfig c;
  c.truncation = 0.005;  // < 2 voxels
  EXPECT_THROW(c.Validate(), InvalidArgument);
  c = TsdfConfig();
  c.block_resolution = 12;
  EXPECT_THROW(TsdfFusion{c}, InvalidArgument);
  TsdfFusion fusion{TsdfConfig()};
  RgbdFrame f = BoxFrames()[0];
  f.depth.pop_back();
  try {
    fusion.Integrate(f);
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("frame 0"), std::string::npos) << e.what();
  }
  f = BoxFrames()[0];
  f.pose.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fusion.Integrate(f), InvalidArgument);
  // NaN depths are skipped, not fused.
  f = BoxFrames()[0];
  for (auto& z : f.depth) z = std::numeric_limits<float>::quiet_NaN();
  fusion.Integrate(f);
  EXPECT_TRUE(fusion.Extract().mesh.vertices.empty());
  EXPECT_THROW(fusion.Extract(), Error);
}

}  // namespace
}  // namespace dimr::data
