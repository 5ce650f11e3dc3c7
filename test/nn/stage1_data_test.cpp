#include "dimr/nn/stage1_data.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::nn {
namespace {

constexpr double kPi = 3.14159265358979323846;

double AngleDiff(double a, double b) {
  double d = std::fmod(a - b, 2 * kPi);
  if (d > kPi) d -= 2 * kPi;
  if (d < -kPi) d += 2 * kPi;
  return std::abs(d);
}

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("dimr_stage1_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

// Points of an oriented box object (centre c, half sizes along its forward/left/up axes,
// heading h). Symmetric in left/up; the front half (local x > 0) has twice the points, so the
// forward direction is recoverable from the points: mean(front) - mean(all) is along +forward.
void AddBoxObject(Stage1Sample* s, const Eigen::Vector3f& c, const Eigen::Vector3f& half, double h,
                  int semantic, int cad_class, std::mt19937_64* rng,
                  std::vector<int>* front = nullptr) {
  const int id = static_cast<int>(s->instances.size());
  Stage1Instance in;
  in.semantic = semantic;
  in.cad_class = cad_class;
  in.has_heading = cad_class >= 0;
  in.heading = h;
  s->instances.push_back(in);
  const float ch = static_cast<float>(std::cos(h)), sh = static_cast<float>(std::sin(h));
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (int i = 0; i < 300; ++i) {
    // Mirror pairs in y and z keep the cloud symmetric about the forward axis.
    Eigen::Vector3f l(u(*rng), u(*rng), u(*rng));
    if (i % 3 != 0) l.x() = std::abs(l.x());  // 2/3 of the points in front
    for (int sy = -1; sy <= 1; sy += 2) {
      for (int sz = -1; sz <= 1; sz += 2) {
        const Eigen::Vector3f q(l.x() * half.x(), sy * l.y() * half.y(), sz * l.z() * half.z());
        const Eigen::Vector3f p(c.x() + ch * q.x() - sh * q.y(), c.y() + sh * q.x() + ch * q.y(),
                                c.z() + q.z());
        if (front && q.x() > 0) front->push_back(static_cast<int>(s->points.size()));
        s->points.push_back(p);
        s->colors.push_back(Eigen::Vector3f(0.2f, 0.5f, 0.8f));
        s->semantic.push_back(semantic);
        s->instance.push_back(id);
      }
    }
  }
}

// A room: floor at floor_z (4 x 5 m, origin offset), two walls (instances), two CAD objects,
// some unlabelled clutter.
Stage1Sample MakeRoom(std::uint64_t seed, float floor_z = 0.7f,
                      const Eigen::Vector2f& shift = Eigen::Vector2f(100.f, -50.f)) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Stage1Sample s;
  s.name = "room" + std::to_string(seed);
  auto add = [&](const Eigen::Vector3f& p, int sem, int inst) {
    s.points.push_back(p + Eigen::Vector3f(shift.x(), shift.y(), 0.f));
    s.colors.push_back(Eigen::Vector3f(u(rng), u(rng), u(rng)));
    s.semantic.push_back(sem);
    s.instance.push_back(inst);
  };
  s.instances.push_back({1, -1, false, 0});  // 0: floor
  s.instances.push_back({0, -1, false, 0});  // 1: wall
  for (int i = 0; i < 1500; ++i) {
    add(Eigen::Vector3f(4 * u(rng), 5 * u(rng), floor_z + 0.004f * (u(rng) - 0.5f)), 1, 0);
  }
  for (int i = 0; i < 600; ++i) add(Eigen::Vector3f(0, 5 * u(rng), floor_z + 2.5f * u(rng)), 0, 1);
  for (int i = 0; i < 200; ++i) {  // clutter, unlabelled
    add(Eigen::Vector3f(4 * u(rng), 5 * u(rng), floor_z + 1.5f * u(rng)), kStage1Ignore, -1);
  }
  std::mt19937_64 r2(seed + 7);
  Stage1Sample objs;
  AddBoxObject(&objs, Eigen::Vector3f(1.5f, 2.f, floor_z + 0.45f),
               Eigen::Vector3f(0.3f, 0.25f, 0.45f), 0.4 + 0.3 * static_cast<double>(seed % 5), 4, 1,
               &r2);
  AddBoxObject(&objs, Eigen::Vector3f(3.f, 4.f, floor_z + 0.4f), Eigen::Vector3f(0.6f, 0.4f, 0.4f),
               -2.0, 6, 3, &r2);
  const int base = static_cast<int>(s.instances.size());
  for (std::size_t i = 0; i < objs.points.size(); ++i) {
    s.points.push_back(objs.points[i] + Eigen::Vector3f(shift.x(), shift.y(), 0.f));
    s.colors.push_back(objs.colors[i]);
    s.semantic.push_back(objs.semantic[i]);
    s.instance.push_back(base + objs.instance[i]);
  }
  for (const auto& in : objs.instances) s.instances.push_back(in);
  // A few outliers below the floor (sensor noise) must not be taken for the floor.
  for (int i = 0; i < 10; ++i)
    add(Eigen::Vector3f(2 * u(rng), 2 * u(rng), floor_z - 0.5f), kStage1Ignore, -1);
  return s;
}

// Forward direction (x-y angle) of points `all` with front subset `front`.
double GeometryHeading(const std::vector<Eigen::Vector3f>& pts, const std::vector<int>& all,
                       const std::vector<int>& front) {
  Eigen::Vector3d ma = Eigen::Vector3d::Zero(), mf = Eigen::Vector3d::Zero();
  for (int i : all) ma += pts[i].cast<double>();
  for (int i : front) mf += pts[i].cast<double>();
  const Eigen::Vector3d d = mf / front.size() - ma / all.size();
  return std::atan2(d.y(), d.x());
}

AugmentConfig NoCrop() {
  AugmentConfig a;
  a.max_points = 1 << 30;
  return a;
}

// ---------------------------------------------------------------- heading
TEST(Stage1Data, HeadingRoundTrip) {
  int checked = 0;
  std::vector<double> angles;
  for (double h = -4 * kPi; h <= 4 * kPi; h += 0.0137) angles.push_back(h);
  for (int k = -24; k <= 24; ++k) {
    for (double e : {-1e-9, 0.0, 1e-9}) {
      angles.push_back(k * kPi / 6 + kPi / 12 + e);  // bin edges
      angles.push_back(k * kPi / 6 + e);             // bin centres
    }
  }
  for (double h : angles) {
    const HeadingCode c = EncodeHeading(h);
    ASSERT_GE(c.bin, 0);
    ASSERT_LT(c.bin, kHeadingBins);
    ASSERT_GE(c.residual, -1.0);
    ASSERT_LT(c.residual, 1.0);
    const double d = DecodeHeading(c.bin, c.residual);
    ASSERT_GT(d, -kPi - 1e-12);
    ASSERT_LE(d, kPi + 1e-12);
    ASSERT_LT(AngleDiff(d, h), 1e-9) << h;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
  EXPECT_EQ(EncodeHeading(0).bin, 0);
  EXPECT_NEAR(EncodeHeading(0).residual, 0, 1e-12);
  EXPECT_EQ(EncodeHeading(kPi / 2).bin, 3);
  EXPECT_NEAR(EncodeHeading(kPi / 2).residual, 0, 1e-9);
  EXPECT_EQ(EncodeHeading(-kPi / 2).bin, 9);
  EXPECT_EQ(EncodeHeading(kPi).bin, 6);
  EXPECT_EQ(EncodeHeading(kPi / 12 + 1e-6).bin, 1);
  EXPECT_NEAR(EncodeHeading(kPi / 12 + 1e-6).residual, -1, 1e-4);
  // Predicted residuals are unbounded: decoding wraps fully into (-pi, pi].
  EXPECT_NEAR(DecodeHeading(0, -13.0), -13.0 * kPi / 12 + 2 * kPi, 1e-12);
  EXPECT_NEAR(DecodeHeading(6, 0.0), kPi, 1e-12);
  EXPECT_NEAR(DecodeHeading(11, 30.0), std::remainder(11 * kPi / 6 + 30 * kPi / 12, 2 * kPi),
              1e-12);
  EXPECT_EQ(EncodeHeading(kPi / 12 - 1e-6).bin, 0);
  EXPECT_NEAR(EncodeHeading(kPi / 12 - 1e-6).residual, 1, 1e-4);
  EXPECT_EQ(EncodeHeading(0.5).bin, 1);  // 0.5 rad = 28.6 deg
  EXPECT_NEAR(EncodeHeading(0.5).residual, (0.5 - kPi / 6) / (kPi / 12), 1e-9);
  EXPECT_NEAR(DecodeHeading(6, 0), kPi, 1e-12);
  EXPECT_NEAR(DecodeHeading(11, 0.5), -kPi / 6 + kPi / 24, 1e-12);
}

// ---------------------------------------------------------------- network frame
TEST(Stage1Data, NetworkFrameFindsFloorAndCentre) {
  const Stage1Sample room = MakeRoom(3);
  const NetworkFrame f = EstimateNetworkFrame(room.points);
  EXPECT_NEAR(f.floor_z, 0.7, 0.02);
  EXPECT_EQ(f.floor_z, f.origin.z());
  Eigen::Vector3f lo = room.points[0], hi = lo;
  for (const auto& p : room.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  EXPECT_NEAR(f.origin.x(), 0.5f * (lo.x() + hi.x()), 1e-4);
  EXPECT_NEAR(f.origin.y(), 0.5f * (lo.y() + hi.y()), 1e-4);
  EXPECT_NEAR(f.origin.x(), 102.0, 0.05);
  EXPECT_NEAR(f.origin.y(), -47.5, 0.05);
  // The frame is origin-free: shifting the room shifts the origin by the same amount.
  const Stage1Sample moved = MakeRoom(3, -3.2f, Eigen::Vector2f(-7.f, 12.f));
  const NetworkFrame g = EstimateNetworkFrame(moved.points);
  EXPECT_NEAR(g.floor_z, -3.2, 0.02);
  EXPECT_NEAR(g.origin.x() - f.origin.x(), -107.f, 1e-3);
  EXPECT_NEAR(g.origin.y() - f.origin.y(), 62.f, 1e-3);
  EXPECT_THROW(EstimateNetworkFrame({}), InvalidArgument);
  EXPECT_THROW(EstimateNetworkFrame({Eigen::Vector3f(0, NAN, 0)}), InvalidArgument);
}

// ---------------------------------------------------------------- augmentation
TEST(Stage1Data, AugmentHeadingMatchesGeometry) {
  for (double jitter : {0.0, 0.1}) {
    int flips = 0;
    for (int seed = 0; seed < 40; ++seed) {
      Stage1Sample s;
      std::vector<int> front;
      std::mt19937_64 r(seed);
      const double h0 = -2.9 + 0.15 * seed;
      AddBoxObject(&s, Eigen::Vector3f(0.5f, -0.3f, 0.4f), Eigen::Vector3f(0.4f, 0.3f, 0.4f), h0, 4,
                   1, &r, &front);
      std::vector<int> all(s.points.size());
      for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
      ASSERT_LT(AngleDiff(GeometryHeading(s.points, all, front), h0), 1e-4);
      AugmentConfig cfg;
      cfg.jitter = jitter;
      std::mt19937_64 rng(1000 + seed);
      Eigen::Matrix3f m;
      AugmentAffine(&s, cfg, &rng, &m);
      const double h = s.instances[0].heading;
      EXPECT_GE(h, -kPi);
      EXPECT_LT(h, kPi);
      EXPECT_LT(AngleDiff(GeometryHeading(s.points, all, front), h), 2e-4)
          << "seed " << seed << " jitter " << jitter;
      if (jitter == 0) {
        const bool flipped = m.determinant() < 0;
        flips += flipped;
        EXPECT_NEAR(std::abs(m.determinant()), 1.0, 1e-5);
        // m = Rz(theta) F: column 0 is +-(cos theta, sin theta).
        const double sign = flipped ? -1 : 1;
        const double theta = std::atan2(sign * m(1, 0), sign * m(0, 0));
        const double expect = flipped ? kPi - h0 + theta : h0 + theta;
        EXPECT_LT(AngleDiff(h, expect), 1e-5);
      }
    }
    if (jitter == 0) {
      EXPECT_GT(flips, 8);
      EXPECT_LT(flips, 32);
    }
  }
}

TEST(Stage1Data, FlipMirrorsHeadingOnlyWhenFlipped) {
  AugmentConfig cfg;
  cfg.jitter = 0;
  cfg.rotate = false;
  int flipped = 0, kept = 0;
  for (int seed = 0; seed < 30; ++seed) {
    Stage1Sample s;
    std::mt19937_64 r(seed);
    AddBoxObject(&s, Eigen::Vector3f(1, 2, 0.5f), Eigen::Vector3f(0.3f, 0.2f, 0.4f), 0.3, 4, 1, &r);
    const auto before = s.points;
    std::mt19937_64 rng(seed);
    AugmentAffine(&s, cfg, &rng);
    if (s.points[0].x() == -before[0].x()) {
      ++flipped;
      EXPECT_NEAR(s.instances[0].heading, kPi - 0.3, 1e-9);
      for (std::size_t i = 0; i < before.size(); ++i) {
        ASSERT_EQ(s.points[i], Eigen::Vector3f(-before[i].x(), before[i].y(), before[i].z()));
      }
    } else {
      ++kept;
      EXPECT_NEAR(s.instances[0].heading, 0.3, 1e-9);  // the reference's bug gave pi - 0.3 here
      for (std::size_t i = 0; i < before.size(); ++i) ASSERT_EQ(s.points[i], before[i]);
    }
  }
  EXPECT_GT(flipped, 5);
  EXPECT_GT(kept, 5);
  cfg.flip = false;  // no flip, no rotation, no jitter: identity
  Stage1Sample s;
  std::mt19937_64 r(1);
  AddBoxObject(&s, Eigen::Vector3f(1, 2, 0.5f), Eigen::Vector3f(0.3f, 0.2f, 0.4f), -1.0, 4, 1, &r);
  const auto before = s.points;
  for (int seed = 0; seed < 5; ++seed) {
    std::mt19937_64 rng(seed);
    AugmentAffine(&s, cfg, &rng);
    EXPECT_EQ(s.points, before);
    EXPECT_NEAR(s.instances[0].heading, -1.0, 1e-12);
  }
}

TEST(Stage1Data, BatchKeepsLabelsAndTargetsConsistent) {
  const Stage1Sample a = MakeRoom(1), b = MakeRoom(2);
  Stage1InputConfig input;
  input.use_rgb = true;
  const AugmentConfig aug = NoCrop();
  const Stage1Batch batch = MakeStage1Batch({&a, &b}, input, &aug, 77);
  ASSERT_EQ(batch.batch_size, 2);
  ASSERT_EQ(batch.feature_channels, 6);
  ASSERT_EQ(
      batch.point_offsets,
      (std::vector<std::int64_t>{0, static_cast<std::int64_t>(a.points.size()),
                                 static_cast<std::int64_t>(a.points.size() + b.points.size())}));
  ASSERT_EQ(batch.points.size(), 3 * batch.semantic.size());
  ASSERT_EQ(batch.features.size(), 6 * batch.semantic.size());
  ASSERT_EQ(batch.voxel.size(), 4 * batch.semantic.size());
  const Stage1Sample* src[2] = {&a, &b};
  for (int s = 0; s < 2; ++s) {
    const Stage1Sample& in = *src[s];
    const std::int64_t o = batch.point_offsets[s];
    const std::int64_t inst_base = s == 0 ? 0 : static_cast<std::int64_t>(a.instances.size());
    std::map<std::int64_t, std::pair<Eigen::Vector3f, Eigen::Vector3f>> box;
    Eigen::Vector3i vmin = Eigen::Vector3i::Constant(1 << 30);
    for (std::size_t i = 0; i < in.points.size(); ++i) {
      const std::int64_t j = o + static_cast<std::int64_t>(i);
      ASSERT_EQ(batch.semantic[j], in.semantic[i]);
      ASSERT_EQ(batch.instance[j], in.instance[i] < 0 ? -1 : inst_base + in.instance[i]);
      ASSERT_EQ(batch.voxel[4 * j], s);
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(batch.features[6 * j + c], batch.points[3 * j + c]);
        ASSERT_NEAR(batch.features[6 * j + 3 + c], in.colors[i][c] - 0.5f, 1e-6);
        vmin[c] = std::min(vmin[c], batch.voxel[4 * j + 1 + c]);
      }
      const Eigen::Vector3f p(batch.points[3 * j], batch.points[3 * j + 1],
                              batch.points[3 * j + 2]);
      if (in.instance[i] >= 0) {
        auto it = box.emplace(batch.instance[j], std::make_pair(p, p)).first;
        it->second.first = it->second.first.cwiseMin(p);
        it->second.second = it->second.second.cwiseMax(p);
      }
    }
    EXPECT_EQ(vmin, Eigen::Vector3i::Zero());
    // Offsets point to the AABB centre of the transformed instance; headings match geometry.
    for (std::size_t i = 0; i < in.points.size(); ++i) {
      const std::int64_t j = o + static_cast<std::int64_t>(i);
      const Eigen::Vector3f p(batch.points[3 * j], batch.points[3 * j + 1],
                              batch.points[3 * j + 2]);
      const Eigen::Vector3f g(batch.offset_target[3 * j], batch.offset_target[3 * j + 1],
                              batch.offset_target[3 * j + 2]);
      if (in.instance[i] < 0) {
        ASSERT_EQ(batch.offset_valid[j], 0);
        ASSERT_EQ(g, Eigen::Vector3f::Zero());
        ASSERT_EQ(batch.heading_bin[j], kStage1Ignore);
        continue;
      }
      ASSERT_EQ(batch.offset_valid[j], 1);
      const auto& bb = box.at(batch.instance[j]);
      ASSERT_LT((p + g - 0.5f * (bb.first + bb.second)).norm(), 1e-5);
      const Stage1Instance& inst = in.instances[in.instance[i]];
      if (!inst.has_heading) {
        ASSERT_EQ(batch.heading_bin[j], kStage1Ignore);
        ASSERT_EQ(batch.heading_residual[j], 0.f);
      } else {
        ASSERT_GE(batch.heading_bin[j], 0);
        ASSERT_LT(batch.heading_bin[j], kHeadingBins);
      }
    }
    // CAD objects: the decoded heading target matches the forward direction of their points.
    for (int k = 0; k < static_cast<int>(in.instances.size()); ++k) {
      if (!in.instances[k].has_heading) continue;
      std::vector<int> all, front;
      std::vector<Eigen::Vector3f> pts;
      std::int64_t first = -1;
      // Front points: local x > 0 in the source object frame.
      const double h = in.instances[k].heading;
      Eigen::Vector3f c = Eigen::Vector3f::Zero();
      int n = 0;
      for (std::size_t i = 0; i < in.points.size(); ++i) {
        if (in.instance[i] == k) c += in.points[i], ++n;
      }
      c /= static_cast<float>(n);
      for (std::size_t i = 0; i < in.points.size(); ++i) {
        if (in.instance[i] != k) continue;
        const std::int64_t j = o + static_cast<std::int64_t>(i);
        if (first < 0) first = j;
        const int idx = static_cast<int>(pts.size());
        pts.emplace_back(batch.points[3 * j], batch.points[3 * j + 1], batch.points[3 * j + 2]);
        all.push_back(idx);
        const Eigen::Vector3f d = in.points[i] - c;
        if (std::cos(h) * d.x() + std::sin(h) * d.y() > 1e-6f) front.push_back(idx);
      }
      // Front-heavy sampling: front = local x > 0 (the mean sits slightly in front, fine: the
      // difference of the two means is still along the forward axis).
      const double target =
          DecodeHeading(static_cast<int>(batch.heading_bin[first]), batch.heading_residual[first]);
      EXPECT_LT(AngleDiff(GeometryHeading(pts, all, front), target), 1e-3) << "instance " << k;
    }
  }
  // No augmentation: points are exactly p - origin, voxels floor(scale p - min).
  const Stage1Batch plain = MakeStage1Batch({&a}, Stage1InputConfig(), nullptr, 77);
  const NetworkFrame f = EstimateNetworkFrame(a.points);
  ASSERT_EQ(plain.feature_channels, 3);
  Eigen::Vector3f qmin = Eigen::Vector3f::Constant(1e9f);
  for (const auto& p : a.points) qmin = qmin.cwiseMin(20.f * (p - f.origin));
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const float p = a.points[i][c] - f.origin[c];
      ASSERT_EQ(plain.points[3 * i + c], p);
      ASSERT_EQ(plain.voxel[4 * i + 1 + c], static_cast<int>(std::floor(20.f * p - qmin[c])));
    }
  }
  // Same seed, same bytes; another seed, another augmentation.
  const Stage1Batch again = MakeStage1Batch({&a, &b}, input, &aug, 77);
  EXPECT_EQ(again.points, batch.points);
  EXPECT_EQ(again.voxel, batch.voxel);
  EXPECT_EQ(again.heading_residual, batch.heading_residual);
  const Stage1Batch other = MakeStage1Batch({&a, &b}, input, &aug, 78);
  EXPECT_NE(other.points, batch.points);
}

TEST(Stage1Data, ElasticDistortionIsBoundedSmoothAndDeterministic) {
  std::vector<Eigen::Vector3f> q;
  for (int i = 0; i < 2000; ++i) {
    q.emplace_back(static_cast<float>(i % 20) * 5.f - 50.f,
                   static_cast<float>((i / 20) % 10) * 9.f - 45.f,
                   static_cast<float>(i / 200) * 5.f);
  }
  auto a = q, b = q, c = q;
  std::mt19937_64 r1(5), r2(5), r3(6);
  ElasticDistortion(&a, 6, 40, &r1);
  ElasticDistortion(&b, 6, 40, &r2);
  ElasticDistortion(&c, 6, 40, &r3);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  double max_d = 0, mean_d = 0;
  for (std::size_t i = 0; i < q.size(); ++i) {
    const double d = (a[i] - q[i]).norm();
    max_d = std::max(max_d, d);
    mean_d += d / q.size();
  }
  EXPECT_LT(max_d, 40.0);  // blurred unit noise times mag stays well below mag
  EXPECT_GT(mean_d, 0.5);  // but it does move points
  // Smooth: two points 0.5 voxel apart move almost alike.
  std::vector<Eigen::Vector3f> pair = {Eigen::Vector3f(3, 4, 5), Eigen::Vector3f(3.5f, 4, 5)};
  std::mt19937_64 r4(9);
  ElasticDistortion(&pair, 6, 40, &r4);
  EXPECT_LT(((pair[1] - Eigen::Vector3f(3.5f, 4, 5)) - (pair[0] - Eigen::Vector3f(3, 4, 5))).norm(),
            2.0);
  std::vector<Eigen::Vector3f> bad = {Eigen::Vector3f(0, INFINITY, 0)};
  EXPECT_THROW(ElasticDistortion(&bad, 6, 40, &r4), InvalidArgument);
  EXPECT_THROW(ElasticDistortion(&a, 0, 40, &r4), InvalidArgument);
}

TEST(Stage1Data, CropKeepsAtMostMaxPointsAndCompactsInstances) {
  // A 30 x 30 m hall of 100 instances (semantic = instance % 25), well above max_points.
  Stage1Sample s;
  s.name = "hall";
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int k = 0; k < 100; ++k) s.instances.push_back({k % 25, -1, false, 0});
  for (int i = 0; i < 30000; ++i) {
    const float x = 30 * u(rng), y = 30 * u(rng);
    const int k = static_cast<int>(x / 3) * 10 + static_cast<int>(y / 3);
    s.points.emplace_back(x, y, 0.3f * u(rng));
    s.semantic.push_back(k % 25);
    s.instance.push_back(k);
  }
  AugmentConfig aug;
  aug.max_points = 5000;
  aug.jitter = 0;
  Stage1InputConfig input;  // scale 20: the crop box is 512 * 20 / 50 = 204.8 voxels = 10.24 m
  const Stage1Batch b = MakeStage1Batch({&s, &s}, input, &aug, 3);
  std::int64_t next_id = 0;
  for (int scene = 0; scene < 2; ++scene) {
    const std::int64_t n = b.point_offsets[scene + 1] - b.point_offsets[scene];
    EXPECT_LE(n, 5000);
    EXPECT_GT(n, 500);
    std::map<std::int64_t, int> sem_of;
    std::set<std::int64_t> ids;
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e9f), hi = -lo;
    for (std::int64_t j = b.point_offsets[scene]; j < b.point_offsets[scene + 1]; ++j) {
      ASSERT_GE(b.instance[j], 0);
      ids.insert(b.instance[j]);
      auto it = sem_of.emplace(b.instance[j], static_cast<int>(b.semantic[j])).first;
      ASSERT_EQ(it->second, b.semantic[j]);  // one instance, one class
      const Eigen::Vector3f p(b.points[3 * j], b.points[3 * j + 1], b.points[3 * j + 2]);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      ASSERT_EQ(b.voxel[4 * j], scene);
    }
    // Instance ids are contiguous and batch-unique: scene 1 continues after scene 0.
    EXPECT_EQ(*ids.begin(), next_id);
    EXPECT_EQ(*ids.rbegin(), next_id + static_cast<std::int64_t>(ids.size()) - 1);
    EXPECT_LT(ids.size(), 100u);
    next_id += static_cast<std::int64_t>(ids.size());
    // The crop box (10.24 m in the augmented frame) bounds the voxel coords; the metric points
    // differ from them only by the elastic displacement.
    EXPECT_LE(hi.x() - lo.x(), 10.24f + 1.0f);
    EXPECT_LE(hi.y() - lo.y(), 10.24f + 1.0f);
    EXPECT_GT(hi.x() - lo.x(), 3.0f);
    int vmax = 0;
    for (std::int64_t j = b.point_offsets[scene]; j < b.point_offsets[scene + 1]; ++j) {
      vmax = std::max({vmax, b.voxel[4 * j + 1], b.voxel[4 * j + 2]});
    }
    EXPECT_LT(vmax, 205);
  }
}

// ---------------------------------------------------------------- cache
TEST(Stage1Data, CacheRoundTripAndCorruptFiles) {
  std::vector<Stage1Sample> samples = {MakeRoom(1), MakeRoom(2), Stage1Sample()};
  samples[1].colors.clear();
  samples[1].instances[2].heading = -3.0000001;
  samples[2].name = "empty";
  const std::string path = TempPath("cache.bin");
  WriteStage1Samples(path, samples);
  const auto back = ReadStage1Samples(path);
  ASSERT_EQ(back.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back[i].name, samples[i].name);
    EXPECT_EQ(back[i].points, samples[i].points);
    EXPECT_EQ(back[i].colors, samples[i].colors);
    EXPECT_EQ(back[i].semantic, samples[i].semantic);
    EXPECT_EQ(back[i].instance, samples[i].instance);
    ASSERT_EQ(back[i].instances.size(), samples[i].instances.size());
    for (std::size_t k = 0; k < back[i].instances.size(); ++k) {
      EXPECT_EQ(back[i].instances[k].semantic, samples[i].instances[k].semantic);
      EXPECT_EQ(back[i].instances[k].cad_class, samples[i].instances[k].cad_class);
      EXPECT_EQ(back[i].instances[k].has_heading, samples[i].instances[k].has_heading);
      EXPECT_EQ(back[i].instances[k].heading, samples[i].instances[k].heading);
    }
  }
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto write = [&](const std::string& b) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(b.data(), static_cast<std::streamsize>(b.size()));
  };
  // Every truncation is a ParseError naming the file.
  int truncations = 0;
  for (std::size_t len = 0; len < bytes.size(); len += 1 + len / 7) {
    write(bytes.substr(0, len));
    try {
      ReadStage1Samples(path);
      ADD_FAILURE() << "truncated to " << len << " bytes was accepted";
    } catch (const ParseError& e) {
      EXPECT_EQ(e.source(), path);
      ++truncations;
    }
  }
  EXPECT_GT(truncations, 20);
  // A point count of 2^62 is rejected before allocating.
  std::string huge = bytes;
  const std::size_t count_pos = 8 + 4 + 8 + 4 + samples[0].name.size();
  const std::uint64_t big = 1ull << 62;
  std::memcpy(&huge[count_pos], &big, 8);
  write(huge);
  EXPECT_THROW(ReadStage1Samples(path), ParseError);
  // An instance index out of range names the sample.
  std::string bad = bytes;
  const std::size_t n0 = samples[0].points.size();
  const std::size_t inst_pos = count_pos + 8 + 12 * n0 + 1 + 12 * n0 + 4 * n0;
  const std::int32_t wrong = 99;
  std::memcpy(&bad[inst_pos], &wrong, 4);
  write(bad);
  try {
    ReadStage1Samples(path);
    ADD_FAILURE() << "bad instance index accepted";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("sample 0"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("instance[0]"), std::string::npos) << e.what();
  }
  std::string magic = bytes;
  magic[3] = 'X';
  write(magic);
  EXPECT_THROW(ReadStage1Samples(path), ParseError);
  write(bytes + "x");
  EXPECT_THROW(ReadStage1Samples(path), ParseError);
  EXPECT_THROW(ReadStage1Samples(path + ".missing"), ParseError);
  std::filesystem::remove(path);
  Stage1Sample invalid = MakeRoom(1);
  invalid.semantic[5] = 25;
  EXPECT_THROW(WriteStage1Samples(path, {invalid}), InvalidArgument);
  EXPECT_THROW(invalid.Validate(), InvalidArgument);
}

// ---------------------------------------------------------------- loader
std::vector<Stage1Sample> SmallRooms(int n) {
  std::vector<Stage1Sample> out;
  for (int i = 0; i < n; ++i) out.push_back(MakeRoom(10 + i));
  return out;
}

std::vector<Stage1Batch> Epoch(Stage1Loader* loader, int epoch, int first = 0) {
  loader->StartEpoch(epoch, first);
  std::vector<Stage1Batch> out;
  Stage1Batch b;
  while (loader->Next(&b)) out.push_back(b);
  return out;
}

void ExpectSame(const Stage1Batch& a, const Stage1Batch& b) {
  EXPECT_EQ(a.names, b.names);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.voxel, b.voxel);
  EXPECT_EQ(a.instance, b.instance);
  EXPECT_EQ(a.heading_bin, b.heading_bin);
}

TEST(Stage1Data, LoaderIsDeterministicAcrossThreadCounts) {
  const auto rooms = SmallRooms(7);
  AugmentConfig aug = NoCrop();
  Stage1Loader one(&rooms, Stage1InputConfig(), aug, 2, 42, 1, 2);
  Stage1Loader three(&rooms, Stage1InputConfig(), aug, 2, 42, 3, 4);
  EXPECT_EQ(one.batches_per_epoch(), 3);
  for (int e = 0; e < 2; ++e) {
    const auto a = Epoch(&one, e);
    const auto b = Epoch(&three, e);
    ASSERT_EQ(a.size(), 3u);
    ASSERT_EQ(b.size(), 3u);
    for (int k = 0; k < 3; ++k) ExpectSame(a[k], b[k]);
    // Restart in the middle of the epoch.
    const auto tail = Epoch(&three, e, 1);
    ASSERT_EQ(tail.size(), 2u);
    ExpectSame(tail[0], a[1]);
    ExpectSame(tail[1], a[2]);
  }
  // Epochs differ in order; each epoch covers distinct samples.
  const auto e0 = Epoch(&one, 0), e1 = Epoch(&one, 1);
  std::vector<std::string> n0, n1;
  for (const auto& b : e0) n0.insert(n0.end(), b.names.begin(), b.names.end());
  for (const auto& b : e1) n1.insert(n1.end(), b.names.begin(), b.names.end());
  EXPECT_EQ(n0.size(), 6u);
  EXPECT_EQ(std::set<std::string>(n0.begin(), n0.end()).size(), 6u);
  EXPECT_NE(n0, n1);
  Stage1Loader keep_last(&rooms, Stage1InputConfig(), aug, 2, 42, 2, 4, false);
  EXPECT_EQ(keep_last.batches_per_epoch(), 4);
  const auto all = Epoch(&keep_last, 0);
  ASSERT_EQ(all.size(), 4u);
  EXPECT_EQ(all[3].batch_size, 1);
}

TEST(Stage1Data, LoaderStopsMidEpochAndRethrowsWorkerErrors) {
  const auto rooms = SmallRooms(8);
  const auto t0 = std::chrono::steady_clock::now();
  {
    Stage1Loader loader(&rooms, Stage1InputConfig(), NoCrop(), 1, 1, 3, 3);
    loader.StartEpoch(0);
    Stage1Batch b;
    ASSERT_TRUE(loader.Next(&b));
  }  // destroyed with batches in flight
  { Stage1Loader idle(&rooms, Stage1InputConfig(), NoCrop(), 1, 1, 2, 2); }  // never started
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);

  auto broken = SmallRooms(2);
  broken[1].colors.clear();
  Stage1InputConfig rgb;
  rgb.use_rgb = true;
  Stage1Loader loader(&broken, rgb, NoCrop(), 2, 5, 2);
  loader.StartEpoch(0);
  Stage1Batch b;
  EXPECT_THROW(loader.Next(&b), InvalidArgument);
  EXPECT_FALSE(loader.Next(&b));
  EXPECT_THROW(Stage1Loader(&broken, rgb, NoCrop(), 0, 5), InvalidArgument);
}

}  // namespace
}  // namespace dimr::nn
