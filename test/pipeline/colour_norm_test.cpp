// Per-scene colour standardisation (colour_norm.h) and its stage-1 inference key.
#include "dimr/pipeline/colour_norm.h"

#include <gtest/gtest.h>

#include <random>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/stage1_segmenter.h"

namespace dimr::pipeline {
namespace {

std::vector<Eigen::Vector3f> DarkContrastyScan(int n, unsigned seed) {
  // Like a ScanNet room against SynthScan: darker (mean ~0.44) and ~2.5x the spread.
  std::mt19937 rng(seed);
  std::normal_distribution<float> r(0.50f, 0.25f), g(0.44f, 0.22f), b(0.39f, 0.20f);
  std::vector<Eigen::Vector3f> c(n);
  for (auto& x : c) x = Eigen::Vector3f(r(rng), g(rng), b(rng)).cwiseMax(0.f).cwiseMin(1.f);
  return c;
}

TEST(ColourNorm, MeasureKnownValues) {
  const ColourStats s =
      MeasureColourStats({Eigen::Vector3f(0.2f, 0.5f, 1.0f), Eigen::Vector3f(0.4f, 0.5f, 0.0f)});
  EXPECT_NEAR(s.mean.x(), 0.3f, 1e-6);
  EXPECT_NEAR(s.mean.z(), 0.5f, 1e-6);
  EXPECT_NEAR(s.std.x(), 0.1f, 1e-6);  // population std
  EXPECT_NEAR(s.std.y(), 0.0f, 1e-6);
  EXPECT_NEAR(s.std.z(), 0.5f, 1e-6);
  EXPECT_THROW(MeasureColourStats({}), InvalidArgument);
  EXPECT_THROW(MeasureColourStats({Eigen::Vector3f(0.f, std::nanf(""), 0.f)}), InvalidArgument);
}

TEST(ColourNorm, StandardisedSceneHasTheTargetStatistics) {
  const auto scan = DarkContrastyScan(50000, 3);
  ColourStats target;
  target.mean = Eigen::Vector3f(0.70f, 0.68f, 0.65f);
  target.std = Eigen::Vector3f(0.09f, 0.11f, 0.14f);
  const auto out = StandardiseColours(scan, target);
  ASSERT_EQ(out.size(), scan.size());
  const ColourStats got = MeasureColourStats(out);
  // Clamping at 1 trims a little of the top tail only.
  EXPECT_NEAR(got.mean.x(), 0.70f, 2e-3);
  EXPECT_NEAR(got.mean.z(), 0.65f, 2e-3);
  EXPECT_NEAR(got.std.y(), 0.11f, 3e-3);
  EXPECT_NEAR(got.std.z(), 0.14f, 3e-3);
  // Affine per channel: the order of two points' channel values is kept.
  EXPECT_EQ(scan[0].x() < scan[1].x(), out[0].x() < out[1].x());
  for (const auto& c : out) {
    EXPECT_GE(c.minCoeff(), 0.f);
    EXPECT_LE(c.maxCoeff(), 1.f);
  }
  // A room that already has the target statistics is (almost) unchanged.
  const auto again = StandardiseColours(out, MeasureColourStats(out));
  for (std::size_t i = 0; i < out.size(); i += 997)
    EXPECT_NEAR((again[i] - out[i]).norm(), 0, 1e-5);
}

TEST(ColourNorm, FlatChannelIsOnlyShiftedAndEmptyStaysEmpty) {
  const std::vector<Eigen::Vector3f> grey(10, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  ColourStats target;
  target.mean = Eigen::Vector3f(0.7f, 0.6f, 0.2f);
  target.std = Eigen::Vector3f(0.1f, 0.1f, 0.1f);
  const auto out = StandardiseColours(grey, target);
  EXPECT_NEAR(out[3].x(), 0.7f, 1e-6);
  EXPECT_NEAR(out[3].z(), 0.2f, 1e-6);
  EXPECT_TRUE(StandardiseColours({}, target).empty());
}

TEST(ColourNorm, AverageOfRoomsAndTextForm) {
  ColourStats a, b;
  a.mean = Eigen::Vector3f(0.6f, 0.6f, 0.6f);
  a.std = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
  b.mean = Eigen::Vector3f(0.8f, 0.7f, 0.6f);
  b.std = Eigen::Vector3f(0.3f, 0.2f, 0.1f);
  const ColourStats avg = AverageRoomColourStats({a, b});
  EXPECT_NEAR(avg.mean.x(), 0.7f, 1e-6);
  EXPECT_NEAR(avg.std.z(), 0.2f, 1e-6);
  EXPECT_EQ(avg.ToString(), "0.7000,0.6500,0.6000,0.2000,0.2000,0.2000");
  ColourStats back;
  ASSERT_TRUE(ColourStats::Parse(avg.ToString(), &back));
  EXPECT_NEAR(back.std.x(), 0.2f, 1e-6);
  EXPECT_FALSE(ColourStats::Parse("none", &back));
  EXPECT_FALSE(ColourStats::Parse("", &back));
  EXPECT_THROW(ColourStats::Parse("0.5,0.5,0.5,0.1,0.1", &back), InvalidArgument);
  EXPECT_THROW(ColourStats::Parse("0.5,0.5,1.5,0.1,0.1,0.1", &back), InvalidArgument);
  EXPECT_THROW(ColourStats::Parse("0.5,0.5,0.5,0.1,0,0.1", &back), InvalidArgument);
  EXPECT_THROW(ColourStats::Parse("0.5,0.5,0.5,0.1,x,0.1", &back), InvalidArgument);
  EXPECT_THROW(AverageRoomColourStats({}), InvalidArgument);
}

TEST(ColourNorm, Stage1InferenceKey) {
  const auto c = Stage1InferenceConfig::FromString(
      "rotations=2 colour_norm=0.7000,0.6800,0.6500,0.0900,0.1100,0.1400");
  EXPECT_TRUE(c.colour_norm);
  EXPECT_NEAR(c.colour_target.std.y(), 0.11f, 1e-6);
  EXPECT_NE(c.ToString().find("colour_norm=0.7000,0.6800,0.6500,0.0900,0.1100,0.1400"),
            std::string::npos);
  const auto off = Stage1InferenceConfig::FromString("colour_norm=none", c);
  EXPECT_FALSE(off.colour_norm);
  EXPECT_EQ(off.ToString().find("colour_norm"), std::string::npos);
  EXPECT_FALSE(Stage1InferenceConfig().colour_norm);
  try {
    Stage1InferenceConfig::FromString("colour_norm=0.7,0.7");
    ADD_FAILURE() << "accepted 2 values";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("colour_norm"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dimr::pipeline
