// Real-scan augmentation of stage-1 batches (nn::RealismAugment, issue 22).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "dimr/core/error.h"
#include "dimr/nn/stage1_data.h"

namespace dimr::nn {
namespace {

Stage1Sample Room(std::uint64_t seed, int n = 4000) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Stage1Sample s;
  s.name = "room";
  s.instances.push_back({1, -1, false, 0});
  for (int i = 0; i < n; ++i) {
    s.points.emplace_back(4 * u(rng), 5 * u(rng), i < n / 2 ? 0.f : 2 * u(rng));
    s.colors.emplace_back(0.3f + 0.4f * u(rng), 0.4f + 0.2f * u(rng), 0.5f);
    s.semantic.push_back(i < n / 2 ? 1 : 0);
    s.instance.push_back(i < n / 2 ? 0 : -1);
  }
  return s;
}

// No affine part, no elastic, no crop: the realism part alone.
AugmentConfig Plain() {
  AugmentConfig a;
  a.jitter = 0;
  a.flip = false;
  a.rotate = false;
  a.elastic = false;
  return a;
}

Stage1InputConfig Rgb() {
  Stage1InputConfig in;
  in.use_rgb = true;
  return in;
}

double ChannelStd(const Stage1Batch& b, int channel) {
  const int C = b.feature_channels;
  double s = 0, s2 = 0;
  const std::int64_t n = b.num_points();
  for (std::int64_t i = 0; i < n; ++i) {
    const double v = b.features[C * i + channel];
    s += v;
    s2 += v * v;
  }
  return std::sqrt(s2 / n - (s / n) * (s / n));
}

TEST(Stage1Realism, OffByDefaultAndOnItsOwnRandomStream) {
  const Stage1Sample room = Room(1);
  EXPECT_FALSE(RealismAugment().any());
  AugmentConfig def;  // the default augmentation, as the shipped model trained
  AugmentConfig colour = def;
  colour.realism.color_jitter = 0.2;
  colour.realism.greyscale = 0.5;
  // Colour augmentation on an xyz-only input changes nothing, and does not shift the affine /
  // elastic / crop draws.
  const Stage1Batch a = MakeStage1Batch({&room}, Stage1InputConfig(), &def, 5);
  const Stage1Batch b = MakeStage1Batch({&room}, Stage1InputConfig(), &colour, 5);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.voxel, b.voxel);
  // With rgb only the colour channels change.
  const Stage1Batch c = MakeStage1Batch({&room}, Rgb(), &def, 5);
  const Stage1Batch d = MakeStage1Batch({&room}, Rgb(), &colour, 5);
  EXPECT_EQ(c.points, d.points);
  int changed = 0;
  for (std::int64_t i = 0; i < c.num_points(); ++i)
    for (int k = 3; k < 6; ++k) changed += c.features[6 * i + k] != d.features[6 * i + k];
  EXPECT_GT(changed, c.num_points());
  // Same seed, same batch.
  const Stage1Batch e = MakeStage1Batch({&room}, Rgb(), &colour, 5);
  EXPECT_EQ(d.features, e.features);
}

TEST(Stage1Realism, PointNoiseHasItsSigmaAndScaleIsExact) {
  const Stage1Sample room = Room(2);
  AugmentConfig plain = Plain();
  const Stage1Batch ref = MakeStage1Batch({&room}, Stage1InputConfig(), &plain, 3);
  AugmentConfig noisy = plain;
  noisy.realism.point_noise = 0.005;
  const Stage1Batch b = MakeStage1Batch({&room}, Stage1InputConfig(), &noisy, 3);
  ASSERT_EQ(b.points.size(), ref.points.size());
  // The network frame is estimated from the original points, so the displacement is the noise.
  double s2 = 0;
  for (std::size_t i = 0; i < b.points.size(); ++i) {
    const double d = b.points[i] - ref.points[i];
    s2 += d * d;
  }
  const double sigma = std::sqrt(s2 / b.points.size());
  EXPECT_NEAR(sigma, 0.005, 0.0003);
  // Labels and instance membership do not move.
  EXPECT_EQ(b.semantic, ref.semantic);
  EXPECT_EQ(b.instance, ref.instance);

  AugmentConfig scaled = plain;
  scaled.realism.scale_min = scaled.realism.scale_max = 1.25;
  const Stage1Batch s = MakeStage1Batch({&room}, Stage1InputConfig(), &scaled, 3);
  for (std::size_t i = 0; i < s.points.size(); ++i)
    ASSERT_NEAR(s.points[i], 1.25f * ref.points[i], 1e-5f) << i;
}

TEST(Stage1Realism, ColourDropGreyscaleAndContrast) {
  const Stage1Sample room = Room(3);
  AugmentConfig plain = Plain();
  const Stage1Batch ref = MakeStage1Batch({&room}, Rgb(), &plain, 4);

  AugmentConfig drop = plain;
  drop.realism.color_drop = 1.0;
  const Stage1Batch d = MakeStage1Batch({&room}, Rgb(), &drop, 4);
  for (std::int64_t i = 0; i < d.num_points(); ++i)
    for (int k = 3; k < 6; ++k) ASSERT_EQ(d.features[6 * i + k], 0.0f);  // 0.5 - 0.5

  AugmentConfig grey = plain;
  grey.realism.greyscale = 1.0;
  const Stage1Batch g = MakeStage1Batch({&room}, Rgb(), &grey, 4);
  for (std::int64_t i = 0; i < g.num_points(); ++i) {
    const float r = ref.features[6 * i + 3] + 0.5f, gg = ref.features[6 * i + 4] + 0.5f,
                b = ref.features[6 * i + 5] + 0.5f;
    const float y = 0.299f * r + 0.587f * gg + 0.114f * b - 0.5f;
    for (int k = 3; k < 6; ++k) ASSERT_NEAR(g.features[6 * i + k], y, 1e-5f);
  }

  // Contrast stretches the spread by a factor in [1, 3] (no clamping: colours in [0.3, 0.7]
  // around 0.5 stay within [0, 1] up to 1.67x; a larger stretch clamps, so the bound is 3).
  AugmentConfig con = plain;
  con.realism.color_contrast = 3.0;
  double lo = 1e9, hi = 0;
  for (std::uint64_t seed = 0; seed < 8; ++seed) {
    const Stage1Batch r0 = MakeStage1Batch({&room}, Rgb(), &plain, seed);
    const Stage1Batch c = MakeStage1Batch({&room}, Rgb(), &con, seed);
    const double ratio = ChannelStd(c, 3) / ChannelStd(r0, 3);
    lo = std::min(lo, ratio);
    hi = std::max(hi, ratio);
  }
  EXPECT_GE(lo, 0.999);
  EXPECT_LE(hi, 3.0 + 1e-6);
  EXPECT_GT(hi, 1.3);  // some scenes were stretched
}

TEST(Stage1Realism, PointDropoutKeepsAFractionAndTheLabelsOfTheRest) {
  const Stage1Sample room = Room(4);
  AugmentConfig drop = Plain();
  drop.realism.point_dropout = 0.6;
  double smallest = 1.0;
  for (std::uint64_t seed = 0; seed < 10; ++seed) {
    const Stage1Batch b = MakeStage1Batch({&room}, Stage1InputConfig(), &drop, seed);
    const double kept = static_cast<double>(b.num_points()) / room.points.size();
    EXPECT_GE(kept, 0.4 - 0.03);
    EXPECT_LE(kept, 1.0);
    smallest = std::min(smallest, kept);
    // Kept points keep their labels: the floor (z = 0) points are label 1.
    for (std::int64_t i = 0; i < b.num_points(); ++i)
      if (b.semantic[i] == 0) {
        ASSERT_EQ(b.instance[i], -1);
      }
  }
  EXPECT_LT(smallest, 0.9);
  // A one-point room survives any dropout.
  const Stage1Sample one = Room(5, 1);
  drop.realism.point_dropout = 0.9;
  EXPECT_EQ(MakeStage1Batch({&one}, Stage1InputConfig(), &drop, 1).num_points(), 1);
}

TEST(Stage1Realism, TextFormAndBadValues) {
  const RealismAugment r =
      RealismAugment::FromString("color_jitter=0.1 point_noise=0.004 scale_min=0.9 scale_max=1.1");
  EXPECT_DOUBLE_EQ(r.color_jitter, 0.1);
  EXPECT_DOUBLE_EQ(r.point_noise, 0.004);
  EXPECT_TRUE(r.any());
  EXPECT_EQ(RealismAugment::FromString(r.ToString()).ToString(), r.ToString());
  EXPECT_THROW(RealismAugment::FromString("point_noise=abc"), InvalidArgument);
  EXPECT_THROW(RealismAugment::FromString("greyscale=1.5"), InvalidArgument);
  EXPECT_THROW(RealismAugment::FromString("scale_min=1.2 scale_max=1.1"), InvalidArgument);
  EXPECT_THROW(RealismAugment::FromString("colour_jitter=0.1"), InvalidArgument);
  AugmentConfig a;
  a.realism.point_dropout = 0.95;
  EXPECT_THROW(a.Validate(), InvalidArgument);
}

}  // namespace
}  // namespace dimr::nn
