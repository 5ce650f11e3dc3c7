// Per-class prior correction (pipeline/class_bias.h): re-weighting, the exact coordinate-ascent
// fit against a brute-force scan, the classic over-predicted rare class, and errors.
#include "dimr/pipeline/class_bias.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {
namespace {

TEST(ApplyClassBias, ReweightsRenormalisesAndTakesTheArgmax) {
  std::vector<float> prob = {0.6f, 0.3f, 0.1f,   // class 0
                             0.2f, 0.2f, 0.6f};  // class 2
  // Class 1 x e^1.5 = 4.48: row 0 becomes 0.6 : 1.345 : 0.1 -> class 1; row 1 0.2 : 0.896 : 0.6.
  const std::vector<float> bias = {0.0f, 1.5f, 0.0f};
  const std::vector<int> arg = ApplyClassBias(bias, &prob, 3);
  ASSERT_EQ(arg.size(), 2u);
  EXPECT_EQ(arg[0], 1);
  EXPECT_EQ(arg[1], 1);
  const double e = std::exp(1.5);
  EXPECT_NEAR(prob[0], 0.6 / (0.6 + 0.3 * e + 0.1), 1e-6);
  EXPECT_NEAR(prob[1], 0.3 * e / (0.6 + 0.3 * e + 0.1), 1e-6);
  EXPECT_NEAR(prob[3] + prob[4] + prob[5], 1.0, 1e-6);
  EXPECT_NEAR(prob[5], 0.6 / (0.2 + 0.2 * e + 0.6), 1e-6);
}

TEST(ApplyClassBias, EmptyBiasIsThePlainArgmaxAndLeavesTheProbabilities) {
  std::vector<float> prob = {0.1f, 0.7f, 0.2f, 0.5f, 0.1f, 0.4f};
  const std::vector<float> copy = prob;
  const std::vector<int> arg = ApplyClassBias({}, &prob, 3);
  EXPECT_EQ(arg, (std::vector<int>{1, 0}));
  EXPECT_EQ(prob, copy);
}

TEST(ApplyClassBias, BadInputIsNamed) {
  std::vector<float> prob = {0.5f, 0.5f, 0.2f};
  EXPECT_THROW(ApplyClassBias({}, &prob, 2), InvalidArgument);  // not a multiple
  prob = {0.5f, std::numeric_limits<float>::quiet_NaN()};
  try {
    ApplyClassBias({}, &prob, 2);
    FAIL() << "NaN accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("point 0, class 1"), std::string::npos) << e.what();
  }
  prob = {0.5f, 0.5f};
  EXPECT_THROW(ApplyClassBias({0.0f, 1.0f, 2.0f}, &prob, 2), InvalidArgument);
  EXPECT_THROW(ApplyClassBias({0.0f, std::numeric_limits<float>::infinity()}, &prob, 2),
               InvalidArgument);
}

// A common class 0 and a rare class 1 whose probabilities are inflated the way inverse class
// weights inflate them: the true posterior of class 1 is q, the "network" reports
// w q / (w q + 1 - q) with w = 8.
struct Inflated {
  std::vector<int> labels;
  std::vector<float> prob;
};
Inflated MakeInflated(int n, double w, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Inflated d;
  for (int i = 0; i < n; ++i) {
    const double q = std::pow(u(rng), 3.0);  // mostly small: class 1 is rare
    const int label = u(rng) < q ? 1 : 0;
    const double p1 = w * q / (w * q + 1.0 - q);
    d.labels.push_back(label);
    d.prob.push_back(static_cast<float>(1.0 - p1));
    d.prob.push_back(static_cast<float>(p1));
  }
  return d;
}

TEST(FitClassBias, PullsAnOverPredictedRareClassBackAndRaisesTheMeanIou) {
  const Inflated d = MakeInflated(20000, 8.0, 5);
  const ClassBiasFit fit = FitClassBias(d.labels, d.prob, 2);
  EXPECT_GT(fit.miou_after, fit.miou_before + 0.02);
  // Only the difference matters with two classes: class 1 must come down against class 0.
  EXPECT_LT(fit.bias[1] - fit.bias[0], -0.5);
  // The reported IoU is what the re-weighted argmax really gets.
  std::vector<float> prob = d.prob;
  const std::vector<int> pred = ApplyClassBias(fit.bias, &prob, 2);
  std::vector<double> per;
  EXPECT_NEAR(MeanIouPresent(d.labels, pred, 2, &per), fit.miou_after, 1e-12);
  EXPECT_NEAR(per[1], fit.iou_after[1], 1e-12);
}

TEST(FitClassBias, MatchesABruteForceScanOfTheGrid) {
  // Three classes, random probabilities: coordinate ascent (exact bucketed scoring) must reach
  // at least the best single-class move found by brute force, and every fitted bias lies on
  // the grid.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int n = 3000, C = 3;
  std::vector<int> labels(n);
  std::vector<float> prob;
  for (int i = 0; i < n; ++i) {
    labels[i] = u(rng) < 0.6 ? 0 : (u(rng) < 0.7 ? 1 : 2);
    double row[3], sum = 0;
    for (int c = 0; c < C; ++c) sum += row[c] = u(rng) + (c == labels[i] ? 0.5 : 0.0);
    for (int c = 0; c < C; ++c) prob.push_back(static_cast<float>(row[c] / sum));
  }
  labels[7] = -1;  // unlabelled points are ignored
  ClassBiasFitOptions opt;
  opt.min_bias = -2.0;
  opt.max_bias = 2.0;
  opt.step = 0.1;
  const ClassBiasFit fit = FitClassBias(labels, prob, C, opt);
  double brute = 0;
  for (int c = 0; c < C; ++c) {
    for (int k = 0; k <= 40; ++k) {
      std::vector<float> b(C, 0.0f);
      b[c] = static_cast<float>(-2.0 + 0.1 * k);
      std::vector<float> p = prob;
      brute = std::max(brute, MeanIouPresent(labels, ApplyClassBias(b, &p, C), C));
    }
  }
  EXPECT_GE(fit.miou_after, brute - 1e-12);
  EXPECT_GE(fit.miou_after, fit.miou_before);
  std::vector<float> p = prob;
  EXPECT_NEAR(MeanIouPresent(labels, ApplyClassBias(fit.bias, &p, C), C), fit.miou_after, 1e-12);
  for (float b : fit.bias) {
    EXPECT_NEAR(std::round((b + 2.0) / 0.1), (b + 2.0) / 0.1, 1e-3) << b;
  }
}

TEST(FitClassBias, KeepsZeroWhenNothingIsGained) {
  // Perfectly separated data: mIoU 1 at b = 0, so the bias must stay 0 (ties go to zero).
  std::vector<int> labels = {0, 1, 2, 0, 1, 2};
  std::vector<float> prob = {0.9f, 0.05f, 0.05f, 0.1f, 0.8f, 0.1f, 0.2f, 0.2f, 0.6f,
                             0.7f, 0.2f,  0.1f,  0.3f, 0.6f, 0.1f, 0.1f, 0.1f, 0.8f};
  const ClassBiasFit fit = FitClassBias(labels, prob, 3);
  EXPECT_DOUBLE_EQ(fit.miou_before, 1.0);
  EXPECT_DOUBLE_EQ(fit.miou_after, 1.0);
  EXPECT_EQ(fit.bias, (std::vector<float>{0.0f, 0.0f, 0.0f}));
}

TEST(FitClassBias, BadInputIsNamed) {
  const std::vector<float> prob = {0.5f, 0.5f, 0.4f, 0.6f};
  EXPECT_THROW(FitClassBias({0}, prob, 2), InvalidArgument);       // size
  EXPECT_THROW(FitClassBias({0, 2}, prob, 2), InvalidArgument);    // label >= C
  EXPECT_THROW(FitClassBias({-1, -1}, prob, 2), InvalidArgument);  // nothing labelled
  ClassBiasFitOptions bad;
  bad.min_bias = 0.5;  // grid without 0
  EXPECT_THROW(FitClassBias({0, 1}, prob, 2, bad), InvalidArgument);
  bad = ClassBiasFitOptions();
  bad.step = 0;
  EXPECT_THROW(FitClassBias({0, 1}, prob, 2, bad), InvalidArgument);
  EXPECT_THROW(MeanIouPresent({0, 1}, {0}, 2), InvalidArgument);
}

}  // namespace
}  // namespace dimr::pipeline
