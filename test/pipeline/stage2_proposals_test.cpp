#include "dimr/pipeline/stage2_proposals.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage2_model.h"
#include "dimr/pipeline/stage1_segmenter.h"
#include "dimr/pipeline/stage2_predictor.h"

namespace dimr::pipeline {
namespace {

// Points on the surface of an oriented box, plus a constant offset of the whole scene.
std::vector<Eigen::Vector3f> BoxPoints(const geometry::OrientedBox& b, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  const Eigen::Matrix3d R = b.Rotation();
  std::vector<Eigen::Vector3f> out;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d p(u(rng), u(rng), u(rng));
    p[i % 3] = (i / 3) % 2 ? 0.5 : -0.5;
    out.push_back((b.center + R * p.cwiseProduct(b.size)).cast<float>());
  }
  return out;
}

TEST(Stage2Proposals, CanonicalisationRoundTrip) {
  geometry::OrientedBox b;
  b.center = Eigen::Vector3d(103.2, -47.5, 0.45);  // far from the origin: nothing may depend on it
  b.size = Eigen::Vector3d(1.2, 0.6, 0.9);
  b.heading = 0.7;
  const auto pts = BoxPoints(b, 600, 1);
  std::vector<int> idx(pts.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  const int fd = 2;
  std::vector<float> feats(pts.size() * fd, 0.5f);
  ProposalFrame f;
  const nn::Stage2Sample s = CanonicaliseProposal(pts, feats, fd, 0.0f, idx, 4, b.heading, &f);
  // With the true heading the canonical box is the object box.
  EXPECT_LT((f.center - b.center).norm(), 1e-3);
  EXPECT_LT((f.extent - b.size).norm(), 2e-3);
  EXPECT_NEAR(s.center_height, 0.45, 1e-3);
  ASSERT_EQ(s.local.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    // Round trip world -> canonical -> world.
    const Eigen::Vector3d back = f.ToWorld(s.local[i].cast<double>());
    EXPECT_LT((back - pts[i].cast<double>()).norm(), 1e-4);
    EXPECT_LE(s.local[i].cwiseAbs().maxCoeff(), 0.5 * b.size.maxCoeff() + 1e-4);
  }
  // Translating the scene changes nothing but the centre.
  std::vector<Eigen::Vector3f> moved = pts;
  for (auto& p : moved) p += Eigen::Vector3f(-200.0f, 55.0f, 0.0f);
  ProposalFrame g;
  const nn::Stage2Sample t = CanonicaliseProposal(moved, feats, fd, 0.0f, idx, 4, b.heading, &g);
  for (std::size_t i = 0; i < pts.size(); ++i) EXPECT_LT((t.local[i] - s.local[i]).norm(), 2e-3);
  EXPECT_LT((t.extent - s.extent).norm(), 2e-3);
  // Bad input.
  EXPECT_THROW(CanonicaliseProposal(pts, feats, fd, 0.0f, {}, 4, 0.0, nullptr), InvalidArgument);
  EXPECT_THROW(
      CanonicaliseProposal(pts, feats, fd, 0.0f, {static_cast<int>(pts.size())}, 4, 0.0, nullptr),
      InvalidArgument);
  EXPECT_THROW(CanonicaliseProposal(pts, feats, 3, 0.0f, idx, 4, 0.0, nullptr), InvalidArgument);
  EXPECT_THROW(CanonicaliseProposal(pts, feats, fd, 0.0f, idx, 8, 0.0, nullptr), InvalidArgument);
  EXPECT_THROW(CanonicaliseProposal(pts, feats, fd, 0.0f, idx, 1, NAN, nullptr), InvalidArgument);
}

TEST(Stage2Proposals, DecodeBoxResidualsAndClamp) {
  ProposalFrame f;
  f.heading = M_PI / 2;
  f.center = Eigen::Vector3d(1, 2, 3);
  f.extent = Eigen::Vector3d(1.0, 2.0, 0.5);
  // Centre residual in the canonical frame: forward (x) becomes +y in the world at 90 deg.
  const geometry::OrientedBox b =
      DecodeBox(f, Eigen::Vector3f(0.1f, 0.0f, 0.2f), Eigen::Vector3f(-0.5f, 0.3f, -0.01f));
  EXPECT_NEAR(b.center.x(), 1.0, 1e-6);
  EXPECT_NEAR(b.center.y(), 2.1, 1e-6);
  EXPECT_NEAR(b.center.z(), 3.2, 1e-6);
  EXPECT_NEAR(b.size.x(), 0.9, 1e-6);   // -0.5 clamped to -10 % of 1.0
  EXPECT_NEAR(b.size.y(), 2.3, 1e-6);   // growth unlimited
  EXPECT_NEAR(b.size.z(), 0.49, 1e-6);  // -0.01 > -0.05: kept
  EXPECT_DOUBLE_EQ(b.heading, M_PI / 2);
  const geometry::OrientedBox p = ProposalBox(f);
  EXPECT_LT((p.center - f.center).norm(), 1e-12);
  EXPECT_LT((p.size - f.extent).norm(), 1e-12);
}

TEST(Stage2Proposals, TargetsReproduceTheGtBox) {
  geometry::OrientedBox gt;
  gt.center = Eigen::Vector3d(4.0, 1.0, 0.4);
  gt.size = Eigen::Vector3d(0.8, 0.7, 0.8);
  gt.heading = 2.0;
  // A proposal that saw only part of the object, heading off by 0.1.
  auto pts = BoxPoints(gt, 400, 2);
  std::vector<int> idx;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].x() < 4.2f) idx.push_back(static_cast<int>(i));
  }
  const ProposalFrame f = ComputeProposalFrame(pts, idx, gt.heading + 0.1);
  nn::Stage2Sample s;
  ProposalMatch m{0.8, 0};
  const Eigen::VectorXf code = Eigen::VectorXf::LinSpaced(6, 0, 1);
  SetStage2Targets(f, m, 5, &gt, &code, &s);
  EXPECT_EQ(s.gt_class, 5);
  EXPECT_EQ(s.code.size(), 6u);
  EXPECT_NEAR(s.heading_target, -0.1, 1e-6);
  // Decoding the targets as residuals gives the GT centre back (in the world frame).
  const geometry::OrientedBox d =
      DecodeBox(f, s.center_target, s.size_target - f.extent.cast<float>());
  EXPECT_LT((d.center - gt.center).norm(), 1e-5);
  // No CAD class / no code: no box target.
  SetStage2Targets(f, m, -1, &gt, &code, &s);
  EXPECT_FALSE(s.has_box_target());
  EXPECT_FLOAT_EQ(s.iou, 0.8f);
}

TEST(Stage2Proposals, Matching) {
  // GT: instance 0 = points 0..9, instance 1 = points 10..19, points 20..24 none.
  std::vector<int> gt(25, -1);
  for (int i = 0; i < 20; ++i) gt[i] = i / 10;
  std::vector<std::vector<int>> props{{0, 1, 2, 3, 4, 5, 6, 7, 8, 9},
                                      {5, 6, 7, 8, 9, 10, 11},
                                      {20, 21, 22},
                                      {12, 13, 14, 15, 16, 17, 18, 19, 20, 21}};
  const auto m = MatchProposals(props, gt, 2);
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[0].gt, 0);
  EXPECT_NEAR(m[0].iou, 1.0, 1e-5);
  EXPECT_EQ(m[1].gt, 0);  // 5 of instance 0 vs 2 of instance 1
  EXPECT_NEAR(m[1].iou, 5.0 / 12.0, 1e-5);
  EXPECT_EQ(m[2].gt, -1);
  EXPECT_DOUBLE_EQ(m[2].iou, 0.0);
  EXPECT_EQ(m[3].gt, 1);
  EXPECT_NEAR(m[3].iou, 8.0 / 12.0, 1e-5);
  EXPECT_THROW(MatchProposals({{30}}, gt, 2), InvalidArgument);
  EXPECT_THROW(MatchProposals(props, std::vector<int>(25, 3), 2), InvalidArgument);
}

TEST(Stage2Predictor, ScoresBoxesAndFilter) {
  nn::Stage2Config c;
  c.input.feature_dim = 3;
  c.widths = {8, 16};
  c.latent_dim = 4;
  Stage2Predictor predictor{nn::Stage2Model(c, 2)};
  geometry::OrientedBox a, b;
  a.center = Eigen::Vector3d(0, 0, 0.5);
  a.size = Eigen::Vector3d(1, 1, 1);
  b = a;
  b.center.x() = 3;
  auto pts = BoxPoints(a, 300, 3);
  const auto pb = BoxPoints(b, 300, 4);
  pts.insert(pts.end(), pb.begin(), pb.end());
  std::vector<float> feats(pts.size() * 3, 0.1f);
  Stage2SceneInput in{&pts, &feats, 3, 0.0f};
  std::vector<ScoredInstance> props(3);
  for (int i = 0; i < 300; ++i) props[0].points.push_back(i);
  for (int i = 300; i < 600; ++i) props[1].points.push_back(i);
  for (int i = 0; i < 290; ++i) props[2].points.push_back(i);  // duplicate of 0
  props[0].cad_class = 1;
  props[1].cad_class = 2;
  props[2].cad_class = 1;
  const auto d = predictor.Predict(in, props);
  ASSERT_EQ(d.size(), 3u);
  for (const auto& x : d) {
    EXPECT_EQ(x.code.size(), 8);
    EXPECT_GT(x.score, 0.0);
    EXPECT_LT(x.score, 1.0);
    // Box within the decode rule: size >= 0.9 s0.
    EXPECT_TRUE((x.box.size.array() >= 0.9 * x.frame.extent.array() - 1e-6).all());
  }
  EXPECT_NEAR(d[1].frame.center.x(), 3.0, 0.02);
  Stage2FilterConfig filter;
  filter.score_threshold = 0.0;
  const auto kept = FilterDetections(d, filter);
  ASSERT_EQ(kept.size(), 2u);  // the duplicate is suppressed
  EXPECT_GE(kept[0].score, kept[1].score);
  filter.min_points = 295;  // drops the 290-point duplicate before NMS
  EXPECT_EQ(FilterDetections(d, filter).size(), 2u);
  filter.score_threshold = 1.0;
  EXPECT_TRUE(FilterDetections(d, filter).empty());
  // The same through a stage-1 result (floor = the network origin's z).
  Stage1Result r;
  r.features = feats;
  r.feature_dim = 3;
  r.instances = props;
  const auto viaresult = predictor.Predict(pts, r);
  ASSERT_EQ(viaresult.size(), 3u);
  EXPECT_FLOAT_EQ(static_cast<float>(viaresult[1].score), static_cast<float>(d[1].score));
  r.network_origin.z() = -0.5f;  // another floor: the proposal is higher above it
  EXPECT_NE(predictor.Predict(pts, r)[1].score, d[1].score);
  r.features.clear();
  EXPECT_THROW(predictor.Predict(pts, r), InvalidArgument);
  // A stage-1 model of another width is refused with a clear message.
  Stage2SceneInput wrong{&pts, &feats, 4, 0.0f};
  EXPECT_THROW(predictor.Predict(wrong, props), InvalidArgument);
  EXPECT_THROW(Stage2Predictor::Load("/nonexistent/stage2.pt"), ParseError);
}

}  // namespace
}  // namespace dimr::pipeline
