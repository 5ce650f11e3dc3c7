// Stage-1 metrics (eval/stage1_metrics.h): semantic IoU over the classes present, confusions,
// instance AP of perfect / wrong predictions, the heading error of matched instances, errors.
#include "dimr/eval/stage1_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "dimr/geometry/error.h"

namespace dimr::eval {
namespace {

// 340 points: 0..99 wall (0), 100..219 chair instance (RFS 4, CAD 1, heading 0.5),
// 220..339 table instance (RFS 6, CAD 0, no heading). Instances of >= 100 points count for AP.
Stage1SceneEval Scene() {
  Stage1SceneEval s;
  s.gt_instances = {{1, true, 0.5}, {0, false, 0.0}};
  for (int i = 0; i < 340; ++i) {
    s.gt_semantic.push_back(i < 100 ? 0 : i < 220 ? 4 : 6);
    s.gt_instance.push_back(i < 100 ? -1 : i < 220 ? 0 : 1);
  }
  s.pred_semantic = s.gt_semantic;
  Stage1PredInstance chair, table;
  for (int i = 100; i < 220; ++i) chair.points.push_back(i);
  for (int i = 220; i < 340; ++i) table.points.push_back(i);
  chair.cad_class = 1;
  chair.score = 0.9;
  chair.heading = 0.5 + 10.0 * M_PI / 180.0;  // 10 degrees off
  table.cad_class = 0;
  table.score = 0.8;
  s.preds = {chair, table};
  return s;
}

TEST(Stage1Metrics, PerfectScenesScoreOneAndHeadingErrorsAreMedians) {
  Stage1MetricsAccumulator acc;
  Stage1SceneEval a = Scene();
  acc.Add(a);
  a.preds[0].heading = 0.5 - 30.0 * M_PI / 180.0 + 2 * M_PI;  // 30 degrees, wrapped
  acc.Add(a);
  a.preds[0].heading = 0.5 + 20.0 * M_PI / 180.0;
  acc.Add(a);
  const Stage1Metrics m = acc.Result();
  EXPECT_EQ(m.scenes, 3);
  EXPECT_EQ(m.points, 1020);
  EXPECT_EQ(m.classes_present, 3);
  EXPECT_DOUBLE_EQ(m.miou_present, 1.0);
  EXPECT_NEAR(m.heading_error_deg, 20.0, 1e-9);  // median of 10, 30, 20
  EXPECT_DOUBLE_EQ(m.instances.class_ap50[1], 1.0);
  EXPECT_DOUBLE_EQ(m.instances.class_ap50[0], 1.0);
  EXPECT_TRUE(std::isnan(m.instances.class_ap50[3]));  // no sofa anywhere
  EXPECT_EQ(m.confused_with[4], -1);
}

TEST(Stage1Metrics, WrongLabelsLowerTheIouAndNameTheConfusion) {
  Stage1SceneEval s = Scene();
  for (int i = 100; i < 130; ++i) s.pred_semantic[i] = 0;  // 30 chair points taken for wall
  s.preds[0].cad_class = 3;                                // the chair called a sofa
  Stage1MetricsAccumulator acc;
  acc.Add(s);
  const Stage1Metrics m = acc.Result();
  EXPECT_NEAR(m.semantic.iou[4], 90.0 / 120.0, 1e-12);
  EXPECT_NEAR(m.semantic.iou[0], 100.0 / 130.0, 1e-12);
  EXPECT_EQ(m.confused_with[4], 0);
  EXPECT_NEAR(m.confused_share[4], 0.25, 1e-12);
  EXPECT_DOUBLE_EQ(m.instances.class_ap50[1], 0.0);    // the chair was missed
  EXPECT_TRUE(std::isnan(m.instances.class_ap50[3]));  // a false sofa: no GT, ScanNet's NaN
}

TEST(Stage1Metrics, SupportCountsObjectsScenesAndCadInstances) {
  Stage1SceneEval a = Scene();
  // A third instance: 50 of the wall points become a small cabinet (RFS 2, CAD 5) whose points
  // are 30 cabinet + 20 wall labels (majority cabinet); under 100 points, so the AP ignores it.
  a.gt_instances.push_back({5, false, 0.0});
  for (int i = 0; i < 50; ++i) {
    a.gt_instance[i] = 2;
    if (i < 30) a.gt_semantic[i] = 2;
  }
  a.pred_semantic = a.gt_semantic;
  // b: the same two instances, relabelled: floor everywhere but 100..159 (chair) and 160..229
  // (table), so the chair instance is a 60 / 60 tie and the table instance mostly floor.
  Stage1SceneEval b = Scene();
  b.gt_semantic.assign(340, 1);
  for (int i = 100; i < 160; ++i) b.gt_semantic[i] = 4;  // chair: 60 chair + 60 floor labels
  for (int i = 160; i < 230; ++i) b.gt_semantic[i] = 6;  // 60 chair-instance points + 10 table
  b.pred_semantic = b.gt_semantic;
  Stage1MetricsAccumulator acc;
  acc.Add(a);
  acc.Add(b);
  const Stage1Metrics m = acc.Result();
  ASSERT_EQ(m.gt_objects.size(), 25u);
  ASSERT_EQ(m.instances.gt_instances.size(), 8u);
  EXPECT_EQ(m.gt_scenes[0], 1);   // wall only in a
  EXPECT_EQ(m.gt_scenes[1], 1);   // floor only in b
  EXPECT_EQ(m.gt_scenes[2], 1);   // cabinet only in a
  EXPECT_EQ(m.gt_scenes[4], 2);   // chair in both
  EXPECT_EQ(m.gt_scenes[6], 2);   // table in both
  EXPECT_EQ(m.gt_scenes[3], 0);   // bed nowhere
  EXPECT_EQ(m.gt_objects[0], 0);  // the wall has no instance id
  EXPECT_EQ(m.gt_objects[2], 1);  // the small cabinet, by its majority
  EXPECT_EQ(m.gt_objects[4], 2);  // a's chair; b's chair (60 chair = 60 table-labelled: first max)
  EXPECT_EQ(m.gt_objects[1], 1);  // b's table instance is mostly floor labels (110 of 120)
  EXPECT_EQ(m.gt_objects[6], 1);  // a's table
  EXPECT_EQ(m.instances.gt_instances[1], 2);  // the chairs (120 points each)
  EXPECT_EQ(m.instances.gt_instances[0], 2);  // the tables
  EXPECT_EQ(m.instances.gt_instances[5], 0);  // the 50-point cabinet is below the AP's 100 points
}

TEST(Stage1Metrics, SupportedMiouAveragesOnlyClassesWithEnoughObjects) {
  Stage1Metrics m;
  m.semantic.iou = {0.9, 0.1, 0.8, 0.6, std::nan("")};
  m.semantic.tp = {100, 5, 50, 40, 0};
  m.semantic.fn = {10, 5, 10, 10, 0};
  m.semantic.fp = {0, 0, 0, 0, 0};
  m.gt_objects = {0, 1, 12, 10, 30};  // stuff without ids, one object, 12, exactly 10, absent
  int n = -1;
  // >= 10 objects: classes 2 and 3 (class 4 has objects but no GT points).
  EXPECT_NEAR(SupportedMiou(m, 10, &n), (0.8 + 0.6) / 2, 1e-12);
  EXPECT_EQ(n, 2);
  EXPECT_NEAR(SupportedMiou(m, 11, &n), 0.8, 1e-12);
  EXPECT_EQ(n, 1);
  // >= 1 object drops the stuff class; >= 0 is every class present.
  EXPECT_NEAR(SupportedMiou(m, 1, &n), (0.1 + 0.8 + 0.6) / 3, 1e-12);
  EXPECT_EQ(n, 3);
  EXPECT_NEAR(SupportedMiou(m, 0, &n), (0.9 + 0.1 + 0.8 + 0.6) / 4, 1e-12);
  EXPECT_EQ(n, 4);
  EXPECT_EQ(SupportedMiou(m, 31, &n), 0.0);
  EXPECT_EQ(n, 0);
  EXPECT_THROW(SupportedMiou(m, -1), InvalidArgument);
}

TEST(Stage1Metrics, InconsistentScenesNameTheScene) {
  Stage1MetricsAccumulator acc;
  acc.Add(Scene());
  Stage1SceneEval s = Scene();
  s.pred_semantic.pop_back();
  try {
    acc.Add(s);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("scene 1"), std::string::npos) << e.what();
  }
  s = Scene();
  s.preds[0].points.push_back(340);
  EXPECT_THROW(acc.Add(s), InvalidArgument);
  s = Scene();
  s.gt_instance[5] = 7;
  EXPECT_THROW(acc.Add(s), InvalidArgument);
}

}  // namespace
}  // namespace dimr::eval
