#include "dimr/eval/ap.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dimr/geometry/error.h"

namespace dimr::eval {
namespace {

RankedPrediction P(int scene, double score, std::vector<double> values) {
  RankedPrediction p;
  p.scene = scene;
  p.score = score;
  p.values = std::move(values);
  return p;
}

TEST(ApTest, ElevenPointThresholdsAreDoubleProducts) {
  EXPECT_EQ(ElevenPointThreshold(3), 0.30000000000000004);
  EXPECT_EQ(ElevenPointThreshold(6), 0.6000000000000001);
  EXPECT_EQ(ElevenPointThreshold(7), 0.7000000000000001);
  EXPECT_EQ(ElevenPointThreshold(10), 1.0);
  EXPECT_GT(ElevenPointThreshold(3), 3.0 / 10.0);
}

TEST(ApTest, HandComputedSequence) {
  // 3 GT in one scene, 5 predictions with IoU against each GT. Ranked TP, FP, TP, FP, TP:
  // rec = 1/3 1/3 2/3 2/3 1, prec = 1 1/2 2/3 1/2 3/5.
  // AP = (4 * 1 + 3 * 2/3 + 4 * 3/5) / 11 = 8.4 / 11.
  std::vector<RankedPrediction> preds = {
      P(0, 0.5, {0.0, 0.0, 0.9}),  // TP (gt 2)
      P(0, 0.9, {0.8, 0.1, 0.0}),  // TP (gt 0)
      P(0, 0.8, {0.1, 0.2, 0.0}),  // FP (below threshold)
      P(0, 0.7, {0.0, 0.6, 0.0}),  // TP (gt 1)
      P(0, 0.6, {0.7, 0.0, 0.0}),  // FP (gt 0 already taken, no fallback)
  };
  ClassAp r = EvaluateClassAp(preds, {3}, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(r.npos, 3);
  EXPECT_EQ(r.tp, 3);
  EXPECT_EQ(r.fp, 2);
  EXPECT_EQ(r.order, (std::vector<int>{1, 2, 3, 4, 0}));
  EXPECT_EQ(r.matched_gt, (std::vector<int>{0, -1, 1, -1, 2}));
  EXPECT_NEAR(r.ap, 8.4 / 11.0, 1e-12);
  EXPECT_DOUBLE_EQ(r.precision, 0.6);
  EXPECT_DOUBLE_EQ(r.recall, 1.0);
}

TEST(ApTest, RecallExactlyThreeTenthsDoesNotReachT3) {
  // 10 GT (one per scene), 3 perfect predictions: rec = 0.1, 0.2, 0.3 with prec 1.
  // t_3 = 0.30000000000000004 > 0.3, so only t_0..t_2 count: AP = 3/11 (i/10.0 would give 4/11).
  std::vector<int> gt(10, 1);
  std::vector<RankedPrediction> preds = {P(0, 0.9, {1.0}), P(1, 0.8, {1.0}), P(2, 0.7, {1.0})};
  ClassAp r = EvaluateClassAp(preds, gt, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(r.rec.back(), 3.0 / 10.0);
  EXPECT_DOUBLE_EQ(r.ap, 3.0 / 11.0);
}

TEST(ApTest, TiesKeepBaseOrder) {
  // Equal scores: base order decides. FP first then TP -> prec = 0, 1/2; rec = 0, 1.
  std::vector<RankedPrediction> preds = {P(0, 0.5, {0.1}), P(0, 0.5, {0.9})};
  ClassAp r = EvaluateClassAp(preds, {1}, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(r.order, (std::vector<int>{0, 1}));
  EXPECT_EQ(r.matched_gt, (std::vector<int>{-1, 0}));
  // Every t_i is reached only by the second prediction (prec 1/2): AP = 0.5.
  EXPECT_DOUBLE_EQ(r.ap, 0.5);
  // Swapping the base order: TP first -> AP 1.
  std::swap(preds[0], preds[1]);
  r = EvaluateClassAp(preds, {1}, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_DOUBLE_EQ(r.ap, 1.0);
}

TEST(ApTest, DuplicatesAreFalsePositives) {
  // Two identical predictions of the same GT: TP then FP. prec 1, 1/2; rec 1, 1 -> AP 1,
  // final precision 1/2.
  std::vector<RankedPrediction> preds = {P(0, 0.9, {0.8}), P(0, 0.8, {0.8})};
  ClassAp r = EvaluateClassAp(preds, {1}, 0.25, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(r.tp, 1);
  EXPECT_EQ(r.fp, 1);
  EXPECT_DOUBLE_EQ(r.ap, 1.0);
  EXPECT_DOUBLE_EQ(r.precision, 0.5);
}

TEST(ApTest, SmallerIsBetterUsesStrictLessAndFirstMinimum) {
  // CD-like: best = smallest; first minimum wins on ties; pass iff value < tau.
  std::vector<RankedPrediction> preds = {P(0, 0.9, {0.05, 0.05}), P(0, 0.8, {0.05, 0.05}),
                                         P(0, 0.7, {0.1, 0.1})};
  ClassAp r = EvaluateClassAp(preds, {2}, 0.1, PassTest::kLess, MatchRule::kBestOverall);
  // First takes gt 0; second also picks gt 0 (first minimum) -> FP; third 0.1 is not < 0.1.
  EXPECT_EQ(r.matched_gt, (std::vector<int>{0, -1, -1}));
  // rec 1/2 1/2 1/2, prec 1 1/2 1/3: t_0..t_5 (0.5 >= 0.5) -> 1, t_6.. -> 0: AP = 6/11.
  EXPECT_DOUBLE_EQ(r.ap, 6.0 / 11.0);
}

TEST(ApTest, PcrRuleFallsBackToUnmatchedGt) {
  std::vector<RankedPrediction> preds = {P(0, 0.9, {0.9, 0.6}), P(0, 0.8, {0.95, 0.7})};
  ClassAp voc = EvaluateClassAp(preds, {2}, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(voc.matched_gt, (std::vector<int>{0, -1}));
  EXPECT_DOUBLE_EQ(voc.ap, 6.0 / 11.0);  // rec 0.5 (prec 1) reaches t_0..t_5
  ClassAp pcr = EvaluateClassAp(preds, {2}, 0.5, PassTest::kGreater, MatchRule::kBestUnmatched);
  EXPECT_EQ(pcr.matched_gt, (std::vector<int>{0, 1}));
  EXPECT_DOUBLE_EQ(pcr.ap, 1.0);
}

TEST(ApTest, NoGtAndNoPredictions) {
  // Predictions without GT: npos 0, all FP, AP 0 (rec = 0 / eps = 0).
  std::vector<RankedPrediction> preds = {P(0, 0.9, {})};
  ClassAp r = EvaluateClassAp(preds, {0}, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(r.fp, 1);
  EXPECT_DOUBLE_EQ(r.ap, 0.0);
  // GT without predictions: AP 0.
  r = EvaluateClassAp({}, {4}, 0.5, PassTest::kGreater, MatchRule::kBestOverall);
  EXPECT_EQ(r.npos, 4);
  EXPECT_DOUBLE_EQ(r.ap, 0.0);
  EXPECT_THROW(
      EvaluateClassAp({P(0, 1.0, {0.5})}, {2}, 0.5, PassTest::kGreater, MatchRule::kBestOverall),
      InvalidArgument);
}

TEST(ApTest, TableMeansOverPresentClasses) {
  ApTable t;
  t.classes[0].npos = 2;
  t.classes[0].ap = 0.5;
  t.classes[0].precision = 1.0;
  t.classes[1].num_pred = 3;  // predictions, no GT: present with AP 0
  FinishTable(&t);
  EXPECT_TRUE(t.present[0]);
  EXPECT_TRUE(t.present[1]);
  EXPECT_FALSE(t.present[2]);
  EXPECT_DOUBLE_EQ(t.map, 0.25);
  EXPECT_DOUBLE_EQ(t.mean_precision, 0.5);
}

}  // namespace
}  // namespace dimr::eval
