#include "dimr/pipeline/icp.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>

#include "dimr/geometry/error.h"
#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/sampling.h"

namespace dimr::pipeline {
namespace {

// An asymmetric chair-like mesh (seat, back, one leg) so that the alignment is unique.
geometry::TriangleMesh ChairLike() {
  geometry::OrientedBox seat{geometry::Vec3(0, 0, 0.45), geometry::Vec3(0.5, 0.5, 0.06), 0};
  geometry::OrientedBox back{geometry::Vec3(-0.22, 0, 0.75), geometry::Vec3(0.06, 0.5, 0.55), 0};
  geometry::OrientedBox leg{geometry::Vec3(0.2, 0.2, 0.21), geometry::Vec3(0.05, 0.05, 0.42), 0};
  geometry::TriangleMesh m = seat.ToMesh();
  m.Append(back.ToMesh());
  m.Append(leg.ToMesh());
  return m;
}

Eigen::Matrix3d Rzyx(double rz, double ry, double rx) {
  return (Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

// Mean distance of the observed points to the mesh surface (dense samples of it).
double MeanDistance(const geometry::TriangleMesh& mesh, const std::vector<geometry::Vec3>& target) {
  const geometry::KdTree surface(geometry::SampleSurface(mesh, 40000, 99).points);
  const auto d = geometry::NearestDistances(target, surface);
  double sum = 0;
  for (double x : d) sum += x;
  return sum / static_cast<double>(d.size());
}

TEST(Icp, DecomposeRecoversRzRyRxAngles) {
  for (const auto& a : {Eigen::Vector3d(0.3, -0.1, 0.05), Eigen::Vector3d(-2.5, 0.4, -0.7),
                        Eigen::Vector3d(1.0, 0.0, 0.0)}) {
    double rx, ry, rz;
    DecomposeRzRyRx(Rzyx(a[0], a[1], a[2]), &rx, &ry, &rz);
    EXPECT_NEAR(rz, a[0], 1e-9);
    EXPECT_NEAR(ry, a[1], 1e-9);
    EXPECT_NEAR(rx, a[2], 1e-9);
  }
}

TEST(Icp, ImprovesAPerturbedPlacementAndIsAccepted) {
  const geometry::TriangleMesh truth = ChairLike();
  // Observed points: the true surface, far from the origin (a map frame), partial (no points
  // below 0.1 m, as a scan misses the floor contact).
  const geometry::Vec3 where(12.0, -7.0, 0.0);
  std::vector<geometry::Vec3> target;
  for (const auto& p : geometry::SampleSurface(truth, 3000, 5).points) {
    if (p.z() > 0.1) target.push_back(p + where);
  }
  geometry::TriangleMesh placed = truth;
  placed.Transform(Eigen::Matrix3d::Identity(), where);
  // Perturb: 6 degrees of yaw about the object's centre plus 2.5 cm of shift.
  const Eigen::Matrix3d r = Rzyx(6.0 * M_PI / 180.0, 0, 0);
  const geometry::Vec3 c = where + geometry::Vec3(0, 0, 0.5);
  placed.Transform(r, c - r * c + geometry::Vec3(0.025, -0.015, 0.0));
  const double before = MeanDistance(placed, target);

  // Both backends (the own ICP with both metrics, PCL's with the first pipeline's settings).
  for (int variant = 0; variant < 3; ++variant) {
    IcpConfig cfg;
    cfg.backend = variant == 2 ? IcpBackend::kPcl : IcpBackend::kOwn;
    cfg.metric = variant == 1 ? IcpMetric::kPointToPlane : IcpMetric::kPointToPoint;
    SCOPED_TRACE(std::string(IcpBackendName(cfg.backend)) + " " + IcpMetricName(cfg.metric));
    if (!IcpBackendAvailable(cfg.backend)) continue;
    if (cfg.backend == IcpBackend::kPcl) {
      cfg.max_iterations = 300;
      cfg.samples = 2048;
    }
    geometry::TriangleMesh mesh = placed;
    const IcpResult res = RefineMeshByIcp(&mesh, target, cfg);
    ASSERT_TRUE(res.ran);
    EXPECT_TRUE(res.accepted) << res.note;
    EXPECT_GT(res.source_points, cfg.samples / 2);
    EXPECT_LE(res.source_points, cfg.samples);
    const double after = MeanDistance(mesh, target);
    EXPECT_LT(after, 0.5 * before) << "before " << before << " after " << after;
    EXPECT_LT(after, 0.006);
    // The recovered yaw undoes the perturbation.
    EXPECT_NEAR(res.yaw, -6.0 * M_PI / 180.0, 1.0 * M_PI / 180.0);
    EXPECT_LT(std::abs(res.roll), 1.0 * M_PI / 180.0);
    EXPECT_LT(std::abs(res.pitch), 1.0 * M_PI / 180.0);
  }
}

TEST(Icp, RejectsATiltBeyondTheLimitAndLeavesTheMesh) {
  const geometry::TriangleMesh truth = ChairLike();
  std::vector<geometry::Vec3> target = geometry::SampleSurface(truth, 3000, 5).points;
  // The placed mesh is rolled by 8 degrees: ICP must roll it back by ~ -8 degrees; with a
  // 5-degree limit that is rejected, with the default 10 degrees accepted.
  geometry::TriangleMesh placed = truth;
  const Eigen::Matrix3d r = Rzyx(0, 0, 8.0 * M_PI / 180.0);
  const geometry::Vec3 c(0, 0, 0.5);
  placed.Transform(r, c - r * c);
  IcpConfig strict;
  strict.max_correspondence = 0.1;
  strict.max_tilt_deg = 5.0;
  geometry::TriangleMesh copy = placed;
  const IcpResult rej = RefineMeshByIcp(&copy, target, strict);
  ASSERT_TRUE(rej.ran);
  EXPECT_FALSE(rej.accepted);
  EXPECT_NEAR(rej.roll, -8.0 * M_PI / 180.0, 1.5 * M_PI / 180.0);
  for (std::size_t i = 0; i < copy.vertices.size(); ++i) {
    EXPECT_EQ(copy.vertices[i], placed.vertices[i]);
  }
  IcpConfig loose = strict;
  loose.max_tilt_deg = 10.0;
  copy = placed;
  const IcpResult acc = RefineMeshByIcp(&copy, target, loose);
  EXPECT_TRUE(acc.accepted);
  EXPECT_NE(copy.vertices[0], placed.vertices[0]);
}

// A known small rigid motion (4 deg yaw, 1.5 deg roll, 1 deg pitch about the object's centre,
// 2 / -1.5 / 1 cm of shift) applied to the mesh: the own backend must return its inverse
// within 0.3 degrees and 3 mm (the surface samples are 1-2 cm apart, so this is sub-sample
// accuracy), in at most the configured 30 iterations, with the early stop firing; both metrics.
TEST(Icp, OwnBackendRecoversAKnownSmallRigidTransform) {
  for (const IcpMetric metric : {IcpMetric::kPointToPoint, IcpMetric::kPointToPlane}) {
    SCOPED_TRACE(IcpMetricName(metric));
    const geometry::TriangleMesh truth = ChairLike();
    const geometry::Vec3 where(-30.0, 45.0, 1.0);  // far from the origin
    std::vector<geometry::Vec3> target;
    for (const auto& p : geometry::SampleSurface(truth, 4000, 11).points)
      target.push_back(p + where);
    const Eigen::Matrix3d r0 = Rzyx(4.0 * M_PI / 180.0, 1.0 * M_PI / 180.0, 1.5 * M_PI / 180.0);
    const geometry::Vec3 c = where + geometry::Vec3(0, 0, 0.5);
    const geometry::Vec3 t0 = c - r0 * c + geometry::Vec3(0.02, -0.015, 0.01);
    geometry::TriangleMesh moved = truth;
    moved.Transform(Eigen::Matrix3d::Identity(), where);
    moved.Transform(r0, t0);

    IcpConfig cfg;
    cfg.metric = metric;
    ASSERT_EQ(cfg.backend, IcpBackend::kOwn);
    ASSERT_LE(cfg.max_iterations, 30);
    const IcpResult res = AlignMeshToPoints(moved, target, cfg);
    ASSERT_TRUE(res.ran) << res.note;
    EXPECT_TRUE(res.accepted) << res.note;
    EXPECT_TRUE(res.converged);
    EXPECT_GE(res.iterations, 2);
    EXPECT_LE(res.iterations, cfg.max_iterations);
    EXPECT_GT(res.correspondences, res.source_points / 2);
    // Composed with the known motion, the result must be the identity.
    const Eigen::Matrix3d r_err = res.transform.block<3, 3>(0, 0) * r0;
    const geometry::Vec3 t_err =
        res.transform.block<3, 3>(0, 0) * t0 + res.transform.block<3, 1>(0, 3);
    const double angle_deg = Eigen::AngleAxisd(r_err).angle() * 180.0 / M_PI;
    EXPECT_LT(angle_deg, 0.3);
    // Translation error measured at the object (the rotation error moves points too).
    const geometry::Vec3 at_centre = r_err * c + t_err - c;
    EXPECT_LT(at_centre.norm(), 0.003) << at_centre.transpose();
    EXPECT_NEAR(res.yaw, -4.0 * M_PI / 180.0, 0.3 * M_PI / 180.0);
    // Mean squared pair distance: bounded by the target's sample spacing (~2 cm for 4000 samples
    // on this ~1.5 m^2 surface), not zero.
    EXPECT_LT(res.fitness, 0.015 * 0.015);
    std::printf("angle error %.4f deg, centre error %.2f mm, %d iterations, rms %.4f m\n",
                angle_deg, 1e3 * at_centre.norm(), res.iterations, std::sqrt(res.fitness));
  }
}

// Point sets that are exact rigid copies: ICP converges to the motion to numerical precision.
TEST(Icp, AlignPointsIsExactOnARigidCopy) {
  const std::vector<geometry::Vec3> target = geometry::SampleSurface(ChairLike(), 1500, 3).points;
  const Eigen::Matrix3d r0 = Rzyx(-0.05, 0.02, -0.01);
  const geometry::Vec3 t0(0.01, 0.005, -0.008);
  std::vector<geometry::Vec3> source;
  for (const auto& p : target) source.push_back(r0 * p + t0);
  IcpConfig cfg;
  cfg.max_correspondence = 0.1;
  cfg.relative_rms_change = 0;  // stop on the step size only
  cfg.max_iterations = 60;
  const IcpResult res = AlignPoints(source, target, cfg);
  ASSERT_TRUE(res.ran);
  EXPECT_TRUE(res.converged);
  EXPECT_LT((res.transform.block<3, 3>(0, 0) * r0 - Eigen::Matrix3d::Identity()).norm(), 1e-6);
  EXPECT_LT((res.transform.block<3, 3>(0, 0) * t0 + res.transform.block<3, 1>(0, 3)).norm(), 1e-6);
  EXPECT_LT(res.fitness, 1e-12);
  EXPECT_EQ(res.correspondences, static_cast<int>(source.size()));
}

TEST(Icp, NoPairsWithinTheDistanceLeavesTheIdentity) {
  const std::vector<geometry::Vec3> target = geometry::SampleSurface(ChairLike(), 500, 3).points;
  std::vector<geometry::Vec3> source;
  for (const auto& p : target) source.push_back(p + geometry::Vec3(1.0, 0, 0));
  const IcpResult res = AlignPoints(source, target, IcpConfig());
  EXPECT_EQ(res.iterations, 0);
  EXPECT_TRUE(res.transform.isIdentity());
  EXPECT_FALSE(res.note.empty());
}

TEST(Icp, BackendNamesRoundTrip) {
  EXPECT_EQ(ParseIcpBackend(IcpBackendName(IcpBackend::kOwn)), IcpBackend::kOwn);
  EXPECT_EQ(ParseIcpBackend(IcpBackendName(IcpBackend::kPcl)), IcpBackend::kPcl);
  EXPECT_THROW(ParseIcpBackend("open3d"), InvalidArgument);
  EXPECT_EQ(ParseIcpMetric(IcpMetricName(IcpMetric::kPointToPlane)), IcpMetric::kPointToPlane);
  EXPECT_EQ(ParseIcpMetric(IcpMetricName(IcpMetric::kPointToPoint)), IcpMetric::kPointToPoint);
  EXPECT_THROW(ParseIcpMetric("plane"), InvalidArgument);
  IcpConfig c;
  c.relative_rms_change = 1.0;
  EXPECT_THROW(c.Validate(), InvalidArgument);
}

TEST(Icp, NothingToAlignIsReportedNotThrown) {
  geometry::TriangleMesh empty;
  const IcpResult a = AlignMeshToPoints(empty, {geometry::Vec3(0, 0, 0)}, IcpConfig());
  EXPECT_FALSE(a.ran);
  EXPECT_FALSE(a.accepted);
  EXPECT_FALSE(a.note.empty());
  const IcpResult b = AlignMeshToPoints(ChairLike(), {geometry::Vec3(0, 0, 0)}, IcpConfig());
  EXPECT_FALSE(b.ran);
  EXPECT_TRUE(b.transform.isIdentity());
}

TEST(Icp, BadConfigAndNonFiniteTargetsThrowNamingTheKey) {
  IcpConfig c;
  c.max_correspondence = 0;
  try {
    c.Validate();
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("icp.max_correspondence"), std::string::npos);
  }
  c = IcpConfig();
  c.samples = 1;
  EXPECT_THROW(c.Validate(), InvalidArgument);
  c = IcpConfig();
  c.max_tilt_deg = std::nan("");
  EXPECT_THROW(c.Validate(), InvalidArgument);
  std::vector<geometry::Vec3> t(10, geometry::Vec3(0, 0, 0));
  t[3].x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(AlignMeshToPoints(ChairLike(), t, IcpConfig()), InvalidArgument);
}

}  // namespace
}  // namespace dimr::pipeline
