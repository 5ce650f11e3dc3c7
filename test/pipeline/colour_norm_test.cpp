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

ColourRange TrainingLike() {
  ColourRange r;
  r.mean_min = Eigen::Vector3f(0.61f, 0.57f, 0.51f);
  r.mean_max = Eigen::Vector3f(0.80f, 0.79f, 0.79f);
  r.std_min = Eigen::Vector3f(0.045f, 0.051f, 0.064f);
  r.std_max = Eigen::Vector3f(0.13f, 0.137f, 0.171f);
  return r;
}

TEST(ColourNorm, OutOfRangeSceneIsBroughtToTheNearestInRangeStatistics) {
  const auto scan = DarkContrastyScan(50000, 3);
  const ColourStats own = MeasureColourStats(scan);
  ASSERT_LT(own.mean.x(), 0.61f);  // darker and more contrasty than every training room
  ASSERT_GT(own.std.x(), 0.13f);
  bool changed = false;
  const auto out = StandardiseColours(scan, TrainingLike(), &changed);
  EXPECT_TRUE(changed);
  ASSERT_EQ(out.size(), scan.size());
  const ColourStats got = MeasureColourStats(out);
  // The edge of the range (clamping at 0 / 1 trims little at these values).
  EXPECT_NEAR(got.mean.x(), 0.61f, 2e-3);
  EXPECT_NEAR(got.mean.z(), 0.51f, 2e-3);
  EXPECT_NEAR(got.std.y(), 0.137f, 3e-3);
  EXPECT_NEAR(got.std.z(), 0.171f, 3e-3);
  // Affine per channel: the order of two points' channel values is kept.
  EXPECT_EQ(scan[0].x() < scan[1].x(), out[0].x() < out[1].x());
  for (const auto& c : out) {
    EXPECT_GE(c.minCoeff(), 0.f);
    EXPECT_LE(c.maxCoeff(), 1.f);
  }
}

TEST(ColourNorm, InRangeSceneIsLeftExactlyAsItIs) {
  std::mt19937 rng(5);
  std::normal_distribution<float> n(0.7f, 0.09f);
  std::vector<Eigen::Vector3f> room(20000);
  for (auto& c : room) c = Eigen::Vector3f(n(rng), n(rng), n(rng));
  bool changed = true;
  const auto out = StandardiseColours(room, TrainingLike(), &changed);
  EXPECT_FALSE(changed);
  EXPECT_EQ(out, room);
  // One channel out of range (blue spread too small): only that channel moves.
  for (auto& c : room) c.z() = 0.6f + 0.2f * (c.z() - 0.7f);
  const auto one = StandardiseColours(room, TrainingLike(), &changed);
  EXPECT_TRUE(changed);
  EXPECT_EQ(one[7].x(), room[7].x());
  EXPECT_NEAR(MeasureColourStats(one).std.z(), 0.064f, 1e-3);
}

TEST(ColourNorm, FlatChannelIsOnlyShiftedAndEmptyStaysEmpty) {
  const std::vector<Eigen::Vector3f> grey(10, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  const auto out = StandardiseColours(grey, TrainingLike());
  EXPECT_NEAR(out[3].x(), 0.61f, 1e-6);
  EXPECT_NEAR(out[3].z(), 0.51f, 1e-6);
  EXPECT_TRUE(StandardiseColours({}, TrainingLike()).empty());
}

TEST(ColourNorm, RangeOfRoomsAndTextForm) {
  ColourStats a, b;
  a.mean = Eigen::Vector3f(0.6f, 0.6f, 0.6f);
  a.std = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
  b.mean = Eigen::Vector3f(0.8f, 0.7f, 0.5f);
  b.std = Eigen::Vector3f(0.3f, 0.2f, 0.1f);
  const ColourRange r = RangeOfRooms({a, b});
  EXPECT_NEAR(r.mean_min.z(), 0.5f, 1e-6);
  EXPECT_NEAR(r.mean_max.x(), 0.8f, 1e-6);
  EXPECT_NEAR(r.std_min.x(), 0.1f, 1e-6);
  EXPECT_NEAR(r.std_max.z(), 0.3f, 1e-6);
  EXPECT_EQ(r.ToString(),
            "0.6000,0.6000,0.5000,0.8000,0.7000,0.6000,0.1000,0.2000,0.1000,0.3000,0.2000,0.3000");
  ColourRange back;
  ASSERT_TRUE(ColourRange::Parse(r.ToString(), &back));
  EXPECT_NEAR(back.std_max.x(), 0.3f, 1e-6);
  EXPECT_FALSE(ColourRange::Parse("none", &back));
  EXPECT_FALSE(ColourRange::Parse("", &back));
  EXPECT_THROW(ColourRange::Parse("0.5,0.5,0.5,0.1,0.1", &back), InvalidArgument);
  EXPECT_THROW(ColourRange::Parse("0.9,0.6,0.5,0.8,0.7,0.6,0.1,0.2,0.1,0.3,0.2,0.3", &back),
               InvalidArgument);  // mean min above max
  EXPECT_THROW(ColourRange::Parse("0.6,0.6,0.5,0.8,0.7,0.6,0.1,0.2,0.1,0.3,1.2,0.3", &back),
               InvalidArgument);
  EXPECT_THROW(ColourRange::Parse("0.6,0.6,0.5,0.8,0.7,0.6,0.1,0.2,x,0.3,0.2,0.3", &back),
               InvalidArgument);
  EXPECT_THROW(RangeOfRooms({}), InvalidArgument);
}

TEST(ColourNorm, Stage1InferenceKey) {
  const std::string text =
      "0.6100,0.5700,0.5100,0.8000,0.7900,0.7900,0.0450,0.0510,0.0640,0.1300,0.1370,0.1710";
  const auto c = Stage1InferenceConfig::FromString("rotations=2 colour_norm=" + text);
  EXPECT_TRUE(c.colour_norm);
  EXPECT_NEAR(c.colour_range.std_max.y(), 0.137f, 1e-6);
  EXPECT_NE(c.ToString().find("colour_norm=" + text), std::string::npos);
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
