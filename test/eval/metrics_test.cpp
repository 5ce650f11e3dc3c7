#include <gtest/gtest.h>

#include <cmath>

#include "dimr/eval/mesh_metrics.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/voxelize.h"
#include "eval/test_meshes.h"

namespace dimr::eval {
namespace {

using geometry::Vec3;
using testing::Box;

TEST(ChamferTest, IdenticalAndEmpty) {
  const auto pts = ChamferSamples(Box({0, 0, 0}, {1, 1, 1}), 7);
  ASSERT_EQ(pts.size(), kCdSamples);
  EXPECT_EQ(ChamferDistance(pts, pts), 0.0);
  EXPECT_TRUE(std::isnan(ChamferDistance(pts, {})));
  // Same seed, same samples (deterministic); another seed differs.
  EXPECT_EQ(ChamferSamples(Box({0, 0, 0}, {1, 1, 1}), 7), pts);
  EXPECT_NE(ChamferSamples(Box({0, 0, 0}, {1, 1, 1}), 8), pts);
}

TEST(ChamferTest, HandComputedPointSets) {
  // a = {0, 1} on x, b = {0.25}: b->a mean = 0.25; a->b mean = (0.25 + 0.75) / 2 = 0.5.
  // CD = (0.25 + 0.5) / 2 = 0.375 (plain distances, halved sum of both means).
  EXPECT_DOUBLE_EQ(ChamferDistance({Vec3(0, 0, 0), Vec3(1, 0, 0)}, {Vec3(0.25, 0, 0)}), 0.375);
}

TEST(ChamferTest, TranslatedPlanePatch) {
  // Two unit squares 0.1 apart along the normal: every nearest neighbour is 0.1 away plus an
  // in-plane offset to the nearest of 4096 samples (mean ~ 0.5 / sqrt(4096) = 0.008), which
  // adds sqrt(0.1^2 + r^2) - 0.1 < 0.001: CD in [0.1, 0.101].
  const double cd = ChamferDistance(ChamferSamples(testing::Square(0.0), 1),
                                    ChamferSamples(testing::Square(0.1), 2));
  EXPECT_GE(cd, 0.1);
  EXPECT_LT(cd, 0.101);
  // The same patch sampled twice (different seeds): CD is the sampling error only, ~0.005.
  const double self = ChamferDistance(ChamferSamples(testing::Square(0.0), 1),
                                      ChamferSamples(testing::Square(0.0), 2));
  EXPECT_GT(self, 0.002);
  EXPECT_LT(self, 0.01);
}

TEST(PcrTest, PointsOnAndOffTheMesh) {
  const geometry::MeshDistance md(testing::Square(0.0));
  // On the surface, 0.0469 above (covered), exactly omega = 0.047 above (not: strict <), far.
  const std::vector<Vec3> pts = {
      {0.5, 0.5, 0.0}, {0.2, 0.7, 0.0469}, {0.5, 0.5, 0.047}, {2.0, 2.0, 0.0}};
  EXPECT_DOUBLE_EQ(PointCoverageRatio(md, pts), 0.5);
  // Beyond an edge: distance to the edge, not to the plane: (1.03, 0.5, 0.03) is
  // sqrt(0.03^2 + 0.03^2) = 0.0424 < 0.047 away; (1.04, 0.5, 0.04) is 0.0566 away.
  EXPECT_DOUBLE_EQ(PointCoverageRatio(md, {{1.03, 0.5, 0.03}, {1.04, 0.5, 0.04}}), 0.5);
  EXPECT_DOUBLE_EQ(PointCoverageRatio(md, {}), 0.0);
}

TEST(IouTest, IdenticalAndShiftedBoxes) {
  const auto a = Box({0, 0, 0}, {1, 1, 1});
  for (bool exact : {false, true}) {
    const auto va = geometry::VoxelizeReference(a, kIouVoxelSize, exact);
    EXPECT_EQ(va.d, 21);  // int(1 / 0.047)
    EXPECT_DOUBLE_EQ(geometry::ReferenceMeshIoU(va, va, exact), 1.0);
    // Shift by 0.5 along x. Reference: A's points x = i/20 (i = 0..20) fall in B's grid for
    // round((i/20 - 0.5) * 20) >= 0, i.e. i >= 10: 11 of 21 columns, both ways, so
    // alpha = 11/21 and IoU = alpha / (2 - alpha) = 11/31 (the true box IoU is 1/3). With the
    // exact pitch, A's centre 10.5/21 lies exactly on B's cell boundary (a tie), so only the
    // reference variant is checked here.
    if (!exact) {
      const auto vb =
          geometry::VoxelizeReference(Box({0.5, 0, 0}, {1.5, 1, 1}), kIouVoxelSize, exact);
      EXPECT_NEAR(geometry::ReferenceMeshIoU(va, vb, exact), 11.0 / 31.0, 1e-12);
    }
    // Shift by 0.25: reference round((i/20 - 0.25) * 20) >= 0 -> i >= 5; exact pitch
    // (i + 0.5)/21 >= 0.25 -> i >= 5: 16 of 21 columns both ways, IoU = 16/26 (true 0.6).
    const auto vc =
        geometry::VoxelizeReference(Box({0.25, 0, 0}, {1.25, 1, 1}), kIouVoxelSize, exact);
    EXPECT_NEAR(geometry::ReferenceMeshIoU(va, vc, exact), 16.0 / 26.0, 1e-12);
    // Disjoint boxes.
    const auto vd = geometry::VoxelizeReference(Box({3, 0, 0}, {4, 1, 1}), kIouVoxelSize, exact);
    EXPECT_EQ(geometry::ReferenceMeshIoU(va, vd, exact), 0.0);
  }
}

TEST(ProtocolTest, Names) {
  EXPECT_EQ(ParseProtocol("reference"), Protocol::kReference);
  EXPECT_EQ(ParseProtocol("corrected"), Protocol::kCorrected);
  EXPECT_STREQ(ProtocolName(Protocol::kCorrected), "corrected");
  EXPECT_THROW(ParseProtocol("paper"), InvalidArgument);
}

}  // namespace
}  // namespace dimr::eval
