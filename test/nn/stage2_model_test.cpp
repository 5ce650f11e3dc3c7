#include "dimr/nn/stage2_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage2_data.h"

namespace dimr::nn {
namespace {

// A proposal: points on the surface of a box of the given size (canonical, centred), random
// features, a matched GT of class `cls` with a code that depends on the size.
Stage2Sample MakeSample(int cls, const Eigen::Vector3f& size, std::uint64_t seed, int feature_dim,
                        int code_dim, float iou = 0.9f) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  Stage2Sample s;
  s.scene = "test";
  s.proposal_class = cls;
  s.feature_dim = feature_dim;
  for (int i = 0; i < 150; ++i) {
    Eigen::Vector3f p(u(rng), u(rng), u(rng));
    const int face = i % 3;
    p[face] = (i / 3) % 2 ? 0.5f : -0.5f;
    s.local.push_back(p.cwiseProduct(size));
    for (int f = 0; f < feature_dim; ++f) s.features.push_back(0.3f * g(rng) + 0.1f * cls);
  }
  s.extent = size;
  s.center_height = 0.5f * size.z();
  s.iou = iou;
  s.gt_class = cls;
  s.center_target = Eigen::Vector3f(0.05f, -0.02f, 0.01f) * (1 + cls);
  s.size_target = 1.1f * size;
  for (int d = 0; d < code_dim; ++d) s.code.push_back(std::sin(0.3f * d + size.x() * 3) * 0.5f);
  return s;
}

Stage2Config SmallConfig() {
  Stage2Config c;
  c.input.feature_dim = 4;
  c.widths = {16, 24};
  c.reps = 1;
  c.latent_dim = 8;
  return c;
}

TEST(Stage2Config, RoundTripAndErrors) {
  const Stage2Config c = SmallConfig();
  EXPECT_EQ(Stage2Config::FromString(c.ToString()).ToString(), c.ToString());
  EXPECT_EQ(c.ToString(),
            "features=4 height=1 grid=20 widths=16,24 reps=1 latent=8 center_height=1");
  EXPECT_EQ(c.pooled_dim(), 16 + 3 + 1);
  EXPECT_EQ(c.input.channels(), 4 + 3 + 1);
  EXPECT_THROW(Stage2Config::FromString("widths=16 bogus=1"), InvalidArgument);
  EXPECT_THROW(Stage2Config::FromString("reps=x"), InvalidArgument);
  EXPECT_THROW(Stage2Config::FromString("widths=8,8,8,8,8,8"), InvalidArgument);
}

TEST(Stage2Data, VoxelGridClampsIndexTwenty) {
  // Longest axis 1 m: lambda = 20, the point at the far end lands on 20 -> clamped to 19.
  // Isotropic: y and z use the same scale (20 voxels per metre here).
  std::vector<Eigen::Vector3f> local{{-0.5f, 0, 0}, {0.5f, 0.25f, 0.125f}, {0.0f, 0.0f, 0.0f}};
  std::vector<std::int32_t> v;
  Stage2VoxelCoords(local, 20, &v);
  ASSERT_EQ(v.size(), 9u);
  EXPECT_EQ(v[0], 0);
  EXPECT_EQ(v[3], 19);  // index 20 clamped
  EXPECT_EQ(v[4], 5);   // trunc(20 * 0.25)
  EXPECT_EQ(v[5], 2);   // trunc(20 * 0.125)
  EXPECT_EQ(v[6], 10);
  // A degenerate proposal (one position) lands in voxel 0, no division by zero.
  std::vector<std::int32_t> d;
  Stage2VoxelCoords({{1, 2, 3}, {1, 2, 3}}, 20, &d);
  EXPECT_EQ(d, std::vector<std::int32_t>(6, 0));
}

TEST(Stage2Data, SoftTargets) {
  EXPECT_FLOAT_EQ(SoftScoreTarget(0.8f), 1.0f);
  EXPECT_FLOAT_EQ(SoftScoreTarget(0.2f), 0.0f);
  EXPECT_NEAR(SoftScoreTarget(0.5f), 2 * 0.5f - 0.5f, 1e-6);
  EXPECT_NEAR(SoftScoreTarget(0.6f), 2 * 0.6f - 0.5f, 1e-6);
}

TEST(Stage2Data, CacheRoundTripAndCorruption) {
  std::vector<Stage2Sample> samples{MakeSample(1, {0.5f, 0.6f, 0.9f}, 1, 4, 16),
                                    MakeSample(3, {1.8f, 0.9f, 0.8f}, 2, 4, 0, 0.1f)};
  samples[1].gt_class = -1;
  samples[1].prior_score = 0.25f;
  samples[0].heading_target = 0.3f;
  const std::string path =
      (std::filesystem::temp_directory_path() / "dimr_stage2_cache_test.bin").string();
  WriteStage2Samples(path, samples);
  const auto back = ReadStage2Samples(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].local.size(), samples[0].local.size());
  EXPECT_EQ(back[0].features, samples[0].features);
  EXPECT_EQ(back[0].code, samples[0].code);
  EXPECT_FLOAT_EQ(back[0].heading_target, 0.3f);
  EXPECT_FLOAT_EQ(back[1].prior_score, 0.25f);
  EXPECT_EQ(back[1].gt_class, -1);
  EXPECT_TRUE((back[1].size_target - samples[1].size_target).norm() < 1e-7);
  // Truncated file: a ParseError naming the file, no crash.
  const auto full = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, full - 7);
  try {
    ReadStage2Samples(path);
    FAIL() << "truncated cache accepted";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("dimr_stage2_cache_test"), std::string::npos);
  }
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f << "DIMRST2S garbage";
  }
  EXPECT_THROW(ReadStage2Samples(path), ParseError);
  std::filesystem::remove(path);
}

TEST(Stage2Data, AugmentRecentres) {
  Stage2Sample s = MakeSample(0, {1.0f, 0.5f, 0.7f}, 3, 4, 16);
  Stage2Augment aug;
  aug.enabled = true;
  aug.keep_min = 0.5;
  aug.jitter = 0.0;
  std::mt19937_64 rng(5);
  const Stage2Sample a = AugmentStage2Sample(s, aug, &rng);
  ASSERT_LE(a.local.size(), s.local.size());
  ASSERT_GE(a.local.size(), s.local.size() / 2 - 1);
  Eigen::Vector3f lo = a.local[0], hi = a.local[0];
  for (const auto& p : a.local) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  EXPECT_LT((lo + hi).norm(), 1e-5);  // centred again
  EXPECT_LT((hi - lo - a.extent).norm(), 1e-5);
  // The GT centre stays where it was: old c0 + old target = new c0 + new target.
  const Eigen::Vector3f shift = s.center_target - a.center_target;  // = new c0 - old c0
  EXPECT_NEAR(a.center_height - s.center_height, shift.z(), 1e-5);
  EXPECT_EQ(a.features.size(), a.local.size() * 4);
}

TEST(Stage2Model, LossesDecreaseOnAFixedBatch) {
  const Stage2Config c = SmallConfig();
  Stage2Model model(c, 7);
  std::vector<Stage2Sample> samples;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3f size(0.4f + 0.15f * k, 0.5f + 0.05f * (k % 3), 0.6f + 0.1f * (k % 2));
    samples.push_back(MakeSample(k % 8, size, 100 + k, 4, 16, k % 3 == 2 ? 0.1f : 0.9f));
    if (k % 3 == 2) {
      samples.back().gt_class = -1;
      samples.back().code.clear();
    }
  }
  std::vector<const Stage2Sample*> ptrs;
  for (const auto& s : samples) ptrs.push_back(&s);
  const Stage2Batch batch = MakeStage2Batch(ptrs, c.input, Stage2ClassWeights(samples));
  const Stage2LossTerms before = model.EvaluateLoss(batch);
  for (int it = 0; it < 60; ++it) model.TrainStep(batch, 3e-3);
  const Stage2LossTerms after = model.EvaluateLoss(batch);
  EXPECT_LT(after.total, 0.5 * before.total) << before.total << " -> " << after.total;
  EXPECT_LT(after.score, before.score);
  EXPECT_LT(after.latent, 0.5 * before.latent);
  EXPECT_LT(after.center, before.center);
  EXPECT_LT(after.size, 0.5 * before.size);
  // Predictions: scores follow the targets (matched proposals score higher).
  const Stage2Output o = model.Predict(batch);
  ASSERT_EQ(o.batch_size, 8);
  EXPECT_GT(o.score(0), o.score(2));
  EXPECT_EQ(o.Code(0).size(), 16);
  // The trained size residual of a matched proposal approaches 0.1 * extent.
  const Eigen::Vector3f ds = o.SizeResidual(0, samples[0].gt_class);
  EXPECT_LT((ds - 0.1f * samples[0].extent).norm(),
            0.5f * (0.1f * samples[0].extent).norm() + 0.05f);
}

TEST(Stage2Model, SaveLoadAndErrors) {
  const Stage2Config c = SmallConfig();
  Stage2Model model(c, 3);
  std::vector<Stage2Sample> samples{MakeSample(2, {0.5f, 0.5f, 0.5f}, 9, 4, 16)};
  const Stage2Output a = model.Predict(samples);
  const std::string path =
      (std::filesystem::temp_directory_path() / "dimr_stage2_model_test.pt").string();
  model.Save(path);
  const Stage2Model back = Stage2Model::Load(path);
  EXPECT_EQ(back.config().ToString(), c.ToString());
  const Stage2Output b = back.Predict(samples);
  ASSERT_EQ(a.code.size(), b.code.size());
  for (std::size_t i = 0; i < a.code.size(); ++i) EXPECT_FLOAT_EQ(a.code[i], b.code[i]);
  EXPECT_FLOAT_EQ(a.score_logit[0], b.score_logit[0]);
  // Wrong feature size -> InvalidArgument; corrupt file -> ParseError.
  std::vector<Stage2Sample> wrong{MakeSample(2, {0.5f, 0.5f, 0.5f}, 9, 5, 16)};
  EXPECT_THROW(model.Predict(wrong), InvalidArgument);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  EXPECT_THROW(Stage2Model::Load(path), ParseError);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace dimr::nn
