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

// A room with a floor (semantic 1, no instance) and two CAD instances: a 0.4 m chair-like box
// with a heading and a small table-like box of only 30 points (below the mixing minimum).
Stage1Sample Furnished(std::uint64_t seed, float floor_z, bool with_colours = true) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Stage1Sample s;
  s.name = "furnished";
  s.instances.push_back({5, 1, true, 0.3});   // chair, heading 0.3
  s.instances.push_back({7, 0, false, 0.0});  // table, too small
  for (int i = 0; i < 3000; ++i) {
    s.points.emplace_back(3 * u(rng), 3 * u(rng), floor_z);
    s.semantic.push_back(1);
    s.instance.push_back(-1);
  }
  for (int i = 0; i < 400; ++i) {
    s.points.emplace_back(1 + 0.4f * u(rng), 1 + 0.2f * u(rng), floor_z + 0.9f * u(rng));
    s.semantic.push_back(5);
    s.instance.push_back(0);
  }
  for (int i = 0; i < 30; ++i) {
    s.points.emplace_back(2 + 0.1f * u(rng), 2 + 0.1f * u(rng), floor_z + 0.7f);
    s.semantic.push_back(7);
    s.instance.push_back(1);
  }
  if (with_colours) {
    for (std::size_t i = 0; i < s.points.size(); ++i)
      s.colors.emplace_back(0.2f, 0.4f, s.instance[i] == 0 ? 0.9f : 0.1f);
  }
  return s;
}

TEST(Stage1Realism, MixInstancesPastesCadInstancesOnTheFloorInsideTheRoom) {
  const Stage1Sample dst = Furnished(1, 0.0f);
  Stage1Sample src = Furnished(2, 1.5f);  // another room, its floor 1.5 m higher
  for (auto& p : src.points) p += Eigen::Vector3f(10, -4, 0);  // and far away
  std::mt19937_64 rng(7);
  const Stage1Sample m = MixInstances(dst, src, 3, &rng);
  m.Validate();
  // Only the chair is eligible (the table has 30 < 50 points): 400 points appended.
  ASSERT_EQ(m.points.size(), dst.points.size() + 400);
  ASSERT_EQ(m.instances.size(), 3u);
  EXPECT_EQ(m.instances[2].semantic, 5);
  EXPECT_EQ(m.instances[2].cad_class, 1);
  ASSERT_TRUE(m.instances[2].has_heading);
  for (std::size_t i = 0; i < dst.points.size(); ++i) {  // dst untouched, in order
    ASSERT_EQ(m.points[i], dst.points[i]);
    ASSERT_EQ(m.instance[i], dst.instance[i]);
  }
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e9f), hi = -lo;
  for (std::size_t i = dst.points.size(); i < m.points.size(); ++i) {
    EXPECT_EQ(m.instance[i], 2);
    EXPECT_EQ(m.semantic[i], 5);
    EXPECT_FLOAT_EQ(m.colors[i].z(), 0.9f);  // its own colours came along
    lo = lo.cwiseMin(m.points[i]);
    hi = hi.cwiseMax(m.points[i]);
  }
  EXPECT_NEAR(lo.z(), 0.0f, 1e-5f);  // standing on dst's floor
  EXPECT_LT(hi.z(), 0.91f);
  EXPECT_GE(lo.x(), -1e-4f);  // inside dst's 3 m x 3 m footprint
  EXPECT_GE(lo.y(), -1e-4f);
  EXPECT_LE(hi.x(), 3.0f + 1e-4f);
  EXPECT_LE(hi.y(), 3.0f + 1e-4f);
  // A rigid motion: the pairwise distances of the pasted points are the source's.
  const std::size_t b = dst.points.size(), sb = 3000;
  for (int k = 1; k < 50; ++k) {
    EXPECT_NEAR((m.points[b] - m.points[b + k]).norm(),
                (src.points[sb] - src.points[sb + k]).norm(), 1e-4f);
  }
  // The heading turned with the points: recover the rotation from the x-y footprint of two points.
  const Eigen::Vector2f d_src = (src.points[sb + 1] - src.points[sb]).head<2>();
  const Eigen::Vector2f d_dst = (m.points[b + 1] - m.points[b]).head<2>();
  const double turn = std::atan2(d_dst.y(), d_dst.x()) - std::atan2(d_src.y(), d_src.x());
  const double dh = m.instances[2].heading - src.instances[0].heading;
  EXPECT_NEAR(std::remainder(dh - turn, 2 * M_PI), 0.0, 1e-3);
  // Deterministic; count 0 or nothing eligible returns dst as it was.
  std::mt19937_64 rng2(7);
  const Stage1Sample again = MixInstances(dst, src, 3, &rng2);
  ASSERT_EQ(again.points.size(), m.points.size());
  for (std::size_t i = 0; i < m.points.size(); ++i) ASSERT_EQ(again.points[i], m.points[i]);
  EXPECT_EQ(MixInstances(dst, src, 0, &rng).points.size(), dst.points.size());
  Stage1Sample bare = src;
  for (auto& inst : bare.instances) inst.cad_class = -1;
  EXPECT_EQ(MixInstances(dst, bare, 3, &rng).points.size(), dst.points.size());
  // A colourless source pasted into a coloured room: grey.
  const Stage1Sample grey_src = Furnished(3, 0.0f, false);
  const Stage1Sample g = MixInstances(dst, grey_src, 1, &rng);
  ASSERT_EQ(g.colors.size(), g.points.size());
  EXPECT_FLOAT_EQ(g.colors.back().x(), 0.5f);
  EXPECT_THROW(MixInstances(dst, src, -1, &rng), InvalidArgument);
}

TEST(Stage1Realism, InstanceMixInBatchesOnItsOwnStream) {
  const Stage1Sample a = Furnished(4, 0.0f), b = Furnished(5, 0.0f);
  AugmentConfig plain = Plain();
  AugmentConfig mix = plain;
  mix.realism.instance_mix = 1.0;
  mix.realism.instance_mix_count = 2;
  EXPECT_FALSE(mix.realism.any());  // the point / colour part stays off
  const Stage1Batch base = MakeStage1Batch({&a, &b}, Rgb(), &plain, 11);
  const Stage1Batch mixed = MakeStage1Batch({&a, &b}, Rgb(), &mix, 11);
  // Each scene received the other's chair (400 points); instance ids stay batch-unique.
  ASSERT_EQ(mixed.num_points(), base.num_points() + 800);
  EXPECT_EQ(mixed.point_offsets[1], base.point_offsets[1] + 400);
  std::int64_t max_base = -1, max_mixed = -1;
  for (auto v : base.instance) max_base = std::max(max_base, v);
  for (auto v : mixed.instance) max_mixed = std::max(max_mixed, v);
  EXPECT_EQ(max_mixed, max_base + 2);
  // The first part of each scene is the unmixed scene's batch, bit for bit.
  for (std::int64_t i = 0; i < base.point_offsets[1]; ++i) {
    ASSERT_EQ(mixed.points[3 * i], base.points[3 * i]);
    ASSERT_EQ(mixed.semantic[i], base.semantic[i]);
  }
  // Pasted points have offset targets towards their own (new) instance centre.
  for (std::int64_t i = base.point_offsets[1]; i < mixed.point_offsets[1]; ++i)
    EXPECT_EQ(mixed.offset_valid[i], 1);
  // instance_mix 0: the batch is the plain one exactly; a batch of one scene is never mixed.
  AugmentConfig off = plain;
  off.realism.instance_mix = 0;
  const Stage1Batch same = MakeStage1Batch({&a, &b}, Rgb(), &off, 11);
  EXPECT_EQ(same.points, base.points);
  EXPECT_EQ(MakeStage1Batch({&a}, Rgb(), &mix, 11).num_points(),
            static_cast<std::int64_t>(a.points.size()));
  EXPECT_EQ(RealismAugment::FromString("instance_mix=0.5 instance_mix_count=4").instance_mix_count,
            4);
  EXPECT_THROW(RealismAugment::FromString("instance_mix=1.5"), InvalidArgument);
}

// dst: a 4 x 5 m room (floor class 1 as one instance, wall points class 0 without one) with a
// chair (class 5, CAD 1) in its x < 0.6, y < 0.6 corner; src: the same layout with other labels
// (floor 3, wall 2, no chair), 1.5 m higher and far away.
Stage1Sample CuboidRoom(std::uint64_t seed, bool is_src) {
  Stage1Sample s = Room(seed, 6000);
  const int floor_class = is_src ? 3 : 1, wall_class = is_src ? 2 : 0;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    s.semantic[i] = s.instance[i] == 0 ? floor_class : wall_class;
  }
  s.instances[0].semantic = floor_class;
  if (!is_src) {
    std::mt19937_64 rng(seed + 1);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    s.instances.push_back({5, 1, true, 0.7});
    for (int i = 0; i < 200; ++i) {
      s.points.emplace_back(0.1f + 0.4f * u(rng), 0.1f + 0.4f * u(rng), 0.8f * u(rng));
      s.colors.emplace_back(0.9f, 0.1f, 0.1f);
      s.semantic.push_back(5);
      s.instance.push_back(1);
    }
  } else {
    for (auto& p : s.points) p += Eigen::Vector3f(10, -4, 1.5f);
  }
  return s;
}

TEST(Stage1Realism, MixCuboidsSwapsQuadrantsOfAnotherRoomIn) {
  const Stage1Sample dst = CuboidRoom(21, false), src = CuboidRoom(22, true);
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    SCOPED_TRACE(seed);
    std::mt19937_64 rng(seed);
    const Stage1Sample m = MixCuboids(dst, src, &rng);
    m.Validate();
    // dst's kept points first, in order and unchanged; then src's, moved rigidly.
    std::size_t n_dst = 0;
    for (std::size_t i = 0;
         i < m.points.size() && (m.semantic[i] == 0 || m.semantic[i] == 1 || m.semantic[i] == 5);
         ++i) {
      ++n_dst;
    }
    const std::size_t n_src = m.points.size() - n_dst;
    // 1 to 3 of 4 quadrants each, a quadrant holding >= 9 % of a room's points.
    EXPECT_GT(n_dst, dst.points.size() / 12);
    EXPECT_LT(n_dst, dst.points.size() - dst.points.size() / 12);
    EXPECT_GT(n_src, src.points.size() / 12);
    for (std::size_t i = n_dst; i < m.points.size(); ++i) {
      ASSERT_TRUE(m.semantic[i] == 2 || m.semantic[i] == 3) << i;
    }
    std::size_t j = 0;  // dst's kept points are a subsequence of dst
    for (std::size_t i = 0; i < n_dst; ++i) {
      while (j < dst.points.size() && dst.points[j] != m.points[i]) ++j;
      ASSERT_LT(j, dst.points.size()) << "output point " << i << " is not a dst point";
      EXPECT_EQ(m.semantic[i], dst.semantic[j]);
      EXPECT_EQ(m.colors[i], dst.colors[j]);
    }
    // One translation for every src point: floor onto dst's floor (z = 0).
    float src_floor = 1e9f;
    for (std::size_t i = n_dst; i < m.points.size(); ++i)
      src_floor = std::min(src_floor, m.points[i].z());
    EXPECT_NEAR(src_floor, 0.0f, 0.03f);
    // The src part is a subsequence of src's points under one translation.
    bool rigid = false;
    for (std::size_t j0 = 0; j0 < src.points.size() && !rigid; ++j0) {
      const Eigen::Vector3f t = m.points[n_dst] - src.points[j0];
      std::size_t j = j0 + 1, i = n_dst + 1;
      for (; i < m.points.size(); ++i, ++j) {
        while (j < src.points.size() && (src.points[j] + t - m.points[i]).norm() > 1e-4f) ++j;
        if (j == src.points.size()) break;
      }
      rigid = i == m.points.size();
      if (rigid) {
        EXPECT_NEAR(t.z(), -1.5f, 0.03f);
      }
    }
    EXPECT_TRUE(rigid);
    // The two parts meet at one split point (30-70 % of dst's 4 x 5 m): about it, each quadrant
    // holds points of one room only (on a 1 cm search grid: up to 1 % in the strips between).
    bool separable = false;
    for (int ix = 0; ix <= 160 && !separable; ++ix) {
      for (int iy = 0; iy <= 200 && !separable; ++iy) {
        const float cx = 1.2f + 0.01f * ix, cy = 1.5f + 0.01f * iy;
        std::size_t count[4][2] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
        for (std::size_t i = 0; i < m.points.size(); ++i) {
          const int q = (m.points[i].x() >= cx ? 1 : 0) + (m.points[i].y() >= cy ? 2 : 0);
          ++count[q][i < n_dst ? 0 : 1];
        }
        std::size_t minority = 0;
        for (const auto& c : count) minority += std::min(c[0], c[1]);
        separable = minority <= m.points.size() / 100;
      }
    }
    EXPECT_TRUE(separable);
    // Instances: dst's floor, the chair only if its corner stayed, src's floor; compacted.
    bool chair_kept = false;
    for (std::size_t i = 0; i < n_dst; ++i) chair_kept = chair_kept || m.semantic[i] == 5;
    ASSERT_EQ(m.instances.size(), chair_kept ? 3u : 2u);
    EXPECT_EQ(m.instances.back().semantic, 3);
    if (chair_kept) {
      EXPECT_EQ(m.instances[1].cad_class, 1);
      EXPECT_DOUBLE_EQ(m.instances[1].heading, 0.7);
    }
    for (std::size_t i = 0; i < m.points.size(); ++i) {
      int want = m.instance[i];
      if (m.semantic[i] == 5) want = 1;
      if (m.semantic[i] == 3) want = static_cast<int>(m.instances.size()) - 1;
      if (m.semantic[i] == 0 || m.semantic[i] == 2) want = -1;
      ASSERT_EQ(m.instance[i], want) << i;
    }
    // Deterministic in the generator.
    std::mt19937_64 rng2(seed);
    EXPECT_EQ(MixCuboids(dst, src, &rng2).points, m.points);
  }
  // A weighted dst: src points get weight 1.
  Stage1Sample w = dst;
  w.weight.assign(w.points.size(), 4.0f);
  std::mt19937_64 rng(3);
  const Stage1Sample mw = MixCuboids(w, src, &rng);
  ASSERT_EQ(mw.weight.size(), mw.points.size());
  EXPECT_FLOAT_EQ(mw.weight.front(), 4.0f);
  EXPECT_FLOAT_EQ(mw.weight.back(), 1.0f);
  EXPECT_THROW(MixCuboids(dst, src, nullptr), InvalidArgument);
  Stage1Sample bad = dst;
  bad.semantic.pop_back();
  EXPECT_THROW(MixCuboids(bad, src, &rng), InvalidArgument);
}

TEST(Stage1Realism, CuboidMixInBatchesOnItsOwnStream) {
  const Stage1Sample a = CuboidRoom(31, false), b = CuboidRoom(32, true);
  AugmentConfig plain = Plain();
  AugmentConfig mix = plain;
  mix.realism.cuboid_mix = 1.0;
  EXPECT_FALSE(mix.realism.any());
  const Stage1Batch base = MakeStage1Batch({&a, &b}, Rgb(), &plain, 11);
  const Stage1Batch mixed = MakeStage1Batch({&a, &b}, Rgb(), &mix, 11);
  // Scene 0 now holds points of scene 1's labels (2, 3) and scene 1 of scene 0's (0, 1, 5).
  bool a_has_b = false, b_has_a = false;
  for (std::int64_t i = 0; i < mixed.point_offsets[1]; ++i)
    a_has_b = a_has_b || mixed.semantic[i] == 2 || mixed.semantic[i] == 3;
  for (std::int64_t i = mixed.point_offsets[1]; i < mixed.num_points(); ++i)
    b_has_a = b_has_a || mixed.semantic[i] == 0 || mixed.semantic[i] == 1;
  EXPECT_TRUE(a_has_b);
  EXPECT_TRUE(b_has_a);
  AugmentConfig off = plain;
  off.realism.cuboid_mix = 0;
  EXPECT_EQ(MakeStage1Batch({&a, &b}, Rgb(), &off, 11).points, base.points);
  EXPECT_EQ(MakeStage1Batch({&a}, Rgb(), &mix, 11).num_points(),
            static_cast<std::int64_t>(a.points.size()));
  EXPECT_DOUBLE_EQ(RealismAugment::FromString("cuboid_mix=0.5").cuboid_mix, 0.5);
  EXPECT_THROW(RealismAugment::FromString("cuboid_mix=2"), InvalidArgument);
}

}  // namespace
}  // namespace dimr::nn
