#include "dimr/eval/seg_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dimr/geometry/error.h"

namespace dimr::eval {
namespace {

TEST(SemanticIou, HandComputed) {
  // 3 classes; -100 ignored. Class 0: tp 2, fn 1 (pred 1), fp 1 (gt 2 predicted 0) -> 2/4.
  // Class 1: tp 1, fp 1 -> 1/2. Class 2: tp 0, fn 1 (-> class 0), fp 0 -> 0. mIoU = 1/3.
  std::vector<int> gt = {0, 0, 0, 1, 2, -100, -100};
  std::vector<int> pr = {0, 0, 1, 1, 0, 2, 0};
  SemanticIouResult r = SemanticIou(gt, pr, 3);
  EXPECT_DOUBLE_EQ(r.iou[0], 0.5);
  EXPECT_DOUBLE_EQ(r.iou[1], 0.5);
  EXPECT_DOUBLE_EQ(r.iou[2], 0.0);
  EXPECT_DOUBLE_EQ(r.miou, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(r.accuracy, 3.0 / 5.0);
  // A class absent from GT and predictions does not enter the mean.
  r = SemanticIou({0, 0}, {0, 0}, 4);
  EXPECT_TRUE(std::isnan(r.iou[3]));
  EXPECT_DOUBLE_EQ(r.miou, 1.0);
  EXPECT_THROW(SemanticIou({0}, {0, 1}, 2), InvalidArgument);
}

TEST(ScanNetAp, StepIntegral) {
  // One TP (score 0.9) and one FP (0.5), 1 GT: thresholds at 0.5 -> p 1/2 r 1; 0.9 -> p 1 r 1;
  // final (1, 0). Steps: 0.5*(r0 - r1) = 0, 0.5*(r0 - 0) = 0.5, 0.5*(r1 - 0) = 0.5 -> AP = 1.
  EXPECT_DOUBLE_EQ(ScanNetAp({1, 0}, {0.9, 0.5}, 0, true, true), 1.0);
  // FP ranked above TP: 0.5 -> (1/2, 1); 0.9 -> FP only above: tp 0, p 0, r 0; final (1, 0):
  // steps 0.5*(1 - 0) = 0.5, 0.5*(1 - 0) = 0.5, 0.5*(0 - 0) = 0 -> AP = 0.25.
  EXPECT_DOUBLE_EQ(ScanNetAp({1, 0}, {0.5, 0.9}, 0, true, true), 0.25);
  // A missed GT halves the recall: TP only, 1 hard FN -> (1, 1/2), (1, 0):
  // steps 0.5*(1/2 - 0) = 1/4, 0.5*(1/2 - 0) = 1/4 -> AP = 1/2.
  EXPECT_DOUBLE_EQ(ScanNetAp({1}, {0.9}, 1, true, true), 0.5);
  EXPECT_TRUE(std::isnan(ScanNetAp({}, {}, 0, false, true)));
  EXPECT_DOUBLE_EQ(ScanNetAp({}, {}, 3, true, false), 0.0);
}

// Scene of 1000 points: class 0 instance A = points [0, 200), class 0 instance B =
// [200, 500), class 1 instance C = [500, 700), class 0 tiny instance D = [700, 750) (below the
// 100-point region size), void (-1) = [750, 1000).
InstanceScene MakeScene() {
  InstanceScene s;
  s.gt_label.assign(1000, -1);
  s.gt_instance.assign(1000, -1);
  auto set = [&](int a, int b, int l, int id) {
    for (int i = a; i < b; ++i) {
      s.gt_label[i] = l;
      s.gt_instance[i] = id;
    }
  };
  set(0, 200, 0, 1);
  set(200, 500, 0, 2);
  set(500, 700, 1, 3);
  set(700, 750, 0, 4);
  return s;
}

std::vector<int> Range(int a, int b) {
  std::vector<int> r;
  for (int i = a; i < b; ++i) r.push_back(i);
  return r;
}

TEST(InstanceAp, HandMadePointSets) {
  InstanceScene s = MakeScene();
  // P1: exact A (IoU 1). P2: 180 of B's 300 points (IoU 0.6). P3: C with 50 extra void points
  // (IoU 200/250 = 0.8). P4: D plus 60 void points (110 points, overlaps only the tiny GT and
  // void -> ignored). P5: 60 points (below the region size -> dropped).
  s.preds = {{0, 0.9, Range(0, 200)},
             {0, 0.8, Range(200, 380)},
             {1, 0.7,
              [] {
                auto v = Range(500, 700);
                auto w = Range(750, 800);
                v.insert(v.end(), w.begin(), w.end());
                return v;
              }()},
             {0, 0.95,
              [] {
                auto v = Range(700, 750);
                auto w = Range(800, 860);
                v.insert(v.end(), w.begin(), w.end());
                return v;
              }()},
             {0, 0.99, Range(0, 60)}};
  InstanceApResult r = InstanceAp({s}, 2);
  ASSERT_EQ(r.overlaps.size(), 10u);
  EXPECT_DOUBLE_EQ(r.overlaps[8], 0.5 + 8 * 0.05);
  // Class 0 at overlap 0.5: P1 TP (0.9), P2 TP (0.8, IoU 0.6), P4 ignored -> AP 1.
  EXPECT_DOUBLE_EQ(r.ap[0][0], 1.0);
  // At overlaps 0.6 .. 0.9 P2 (IoU exactly 0.6, not > 0.6000000000000001) misses B: B is a
  // hard FN and P2 an FP ranked below P1: thresholds 0.8 -> (p 1/2, r 1/2), 0.9 -> (1, 1/2),
  // final (1, 0); steps 0.5*(1/2 - 1/2) = 0, 0.5*(1/2 - 0), 0.5*(1/2 - 0) -> AP = 1/2.
  EXPECT_DOUBLE_EQ(r.ap[0][2], 0.5);
  // Class 1: P3 IoU 0.8 -> TP for overlaps < 0.8, a miss (FP, hard FN) from 0.8 on.
  EXPECT_DOUBLE_EQ(r.ap[1][5], 1.0);  // 0.75
  EXPECT_DOUBLE_EQ(r.ap[1][6], 0.0);  // 0.80: not > 0.8
  EXPECT_DOUBLE_EQ(r.class_ap50[0], 1.0);
  EXPECT_DOUBLE_EQ(r.class_ap25[1], 1.0);
  // Class 0 AP over 0.50..0.90: 0.50 and 0.55 -> 1, 0.60..0.90 -> 0.5: (2 + 7 * 0.5) / 9.
  EXPECT_NEAR(r.class_ap[0], 5.5 / 9.0, 1e-12);
  // Class 1: 0.50..0.75 (6 values) -> 1, 0.80..0.90 -> 0: 6/9.
  EXPECT_NEAR(r.class_ap[1], 6.0 / 9.0, 1e-12);
  EXPECT_NEAR(r.map, (5.5 + 6.0) / 18.0, 1e-12);
  EXPECT_DOUBLE_EQ(r.map50, 1.0);
}

TEST(InstanceAp, DuplicatePredictionIsFalsePositive) {
  InstanceScene s = MakeScene();
  s.preds = {{0, 0.6, Range(0, 200)}, {0, 0.9, Range(0, 190)}, {0, 0.5, Range(200, 500)}};
  InstanceApResult r = InstanceAp({s}, 2);
  // At 0.5: A is matched by 0.6 first, then by 0.9: A keeps 0.9 and 0.6 becomes an FP; B is a TP
  // at 0.5. Ascending: 0.5 (TP), 0.6 (FP), 0.9 (TP):
  // 0.5 -> p 2/3 r 1; 0.6 -> p 1/2 r 1/2; 0.9 -> p 1 r 1/2; final (1, 0); steps 1/4 each:
  // AP = (2/3 + 1/2 + 1 + 1) / 4 = 19/24 (1 without the duplicate).
  EXPECT_DOUBLE_EQ(r.ap[0][0], 19.0 / 24.0);
  s.preds.erase(s.preds.begin() + 1);
  EXPECT_DOUBLE_EQ(InstanceAp({s}, 2).ap[0][0], 1.0);
  EXPECT_DOUBLE_EQ(r.ap[1][0], 0.0);  // class 1 has GT (C) but no prediction
}

}  // namespace
}  // namespace dimr::eval
