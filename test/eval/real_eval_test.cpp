#include "dimr/eval/real_eval.h"

#include <gtest/gtest.h>

#include <cmath>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"

namespace dimr::eval {
namespace {

using geometry::Vec3;

TEST(RealEval, DodaMapping) {
  EXPECT_EQ(Nyu40ToDoda(1), 0);    // wall
  EXPECT_EQ(Nyu40ToDoda(2), 1);    // floor
  EXPECT_EQ(Nyu40ToDoda(10), 9);   // bookshelf
  EXPECT_EQ(Nyu40ToDoda(14), 10);  // desk
  EXPECT_EQ(Nyu40ToDoda(11), -1);  // picture
  EXPECT_EQ(Nyu40ToDoda(12), -1);  // counter
  EXPECT_EQ(Nyu40ToDoda(0), -1);
  EXPECT_EQ(Nyu40ToDoda(40), -1);
  EXPECT_EQ(RfsToDoda(labels::kWall), 0);
  EXPECT_EQ(RfsToDoda(labels::kDesk), 10);
  EXPECT_EQ(RfsToDoda(labels::kKitchenCabinet), 2);  // NYU40 cabinet
  EXPECT_EQ(RfsToDoda(labels::kOtherTable), 6);      // NYU40 table
  EXPECT_EQ(RfsToDoda(labels::kOtherShelf), -1);     // NYU40 shelves, not bookshelf
  EXPECT_EQ(RfsToDoda(labels::kCounter), -1);
  EXPECT_EQ(RfsToDoda(labels::kTrashBin), -1);
  EXPECT_EQ(RfsToDoda(-1), -1);
  EXPECT_EQ(RfsToDoda(99), -1);
  // Every DODA class is reached from its own RFS class.
  for (int d = 0; d < kNumDodaClasses; ++d)
    EXPECT_EQ(RfsToDoda(labels::RfsClassFromName(DodaClassNames()[d])), d) << d;
}

TEST(RealEval, SemanticReportPresentClassesAndConfusions) {
  // Class 0: 4 GT points, 3 right, 1 -> class 2. Class 1: 2 GT points, both -> "other" (-1).
  // Class 2: no GT, predicted once (counts as fp, not in the mean over present classes).
  const std::vector<int> gt = {0, 0, 0, 0, 1, 1, -1};
  const std::vector<int> pr = {0, 0, 0, 2, -1, 7, 0};
  const SemanticReport r = EvaluateSemantic(gt, pr, {"a", "b", "c"});
  EXPECT_EQ(r.classes_present, 2);
  EXPECT_DOUBLE_EQ(r.classes[0].iou, 0.75);  // tp 3, fn 1, fp 0 (the ignored point is not fp)
  EXPECT_DOUBLE_EQ(r.classes[1].iou, 0.0);
  EXPECT_DOUBLE_EQ(r.miou_present, 0.375);
  EXPECT_DOUBLE_EQ(r.accuracy, 0.5);
  ASSERT_EQ(r.classes[0].confusion.size(), 2u);
  EXPECT_EQ(r.classes[0].confusion[0].pred, 0);
  EXPECT_DOUBLE_EQ(r.classes[0].confusion[0].fraction, 0.75);
  EXPECT_EQ(r.classes[0].confusion[1].pred, 2);
  ASSERT_EQ(r.classes[1].confusion.size(), 1u);
  EXPECT_EQ(r.classes[1].confusion[0].pred, -1);  // 7 is outside the set too
  EXPECT_DOUBLE_EQ(r.classes[1].confusion[0].fraction, 1.0);
  EXPECT_EQ(r.classes[2].gt_points, 0);
  EXPECT_DOUBLE_EQ(r.classes[2].iou, 0.0);  // predicted but absent
  EXPECT_THROW(EvaluateSemantic({0}, {0, 1}, {"a"}), InvalidArgument);
}

TEST(RealEval, TrsComposesTranslateRotateScale) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const Eigen::Matrix4d m = TrsMatrix(Vec3(1, 2, 3), q, Vec3(2, 1, 1));
  // (1, 0, 0) -> scale (2, 0, 0) -> rotate (0, 2, 0) -> translate (1, 4, 3).
  const Eigen::Vector4d p = m * Eigen::Vector4d(1, 0, 0, 1);
  EXPECT_NEAR((p.head<3>() - Vec3(1, 4, 3)).norm(), 0.0, 1e-12);
}

// Scan frame = world shifted by (10, 0, 0): trs_scan = Translate(10, 0, 0), so
// p_scan = p_world - (10, 0, 0). The CAD box: centre (0, 0.1, 0), half extents (0.5, 0.25,
// 0.5) in CAD units, scaled by (2, 2, 2), rotated 90 degrees about z, placed at (11, 1, 0).
void RotatedScaledBox(data::Scan2CadScene* scene, data::Scan2CadModel* m) {
  scene->id_scan = "s";
  scene->translation = Vec3(10, 0, 0);
  m->translation = Vec3(11, 1, 0);
  m->rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  m->scale = Vec3(2, 2, 2);
  m->bbox = Vec3(0.5, 0.25, 0.5);
  m->center = Vec3(0, 0.1, 0);
}

TEST(RealEval, PointsInsideAnAlignedBox) {
  data::Scan2CadScene scene;
  data::Scan2CadModel m;
  RotatedScaledBox(&scene, &m);
  const Eigen::Matrix4d to_scan = Scan2CadModelToScan(scene, m);
  // Box centre in the scan: (11, 1, 0) + Rz(90)(0, 0.2, 0) - (10, 0, 0) = (0.8, 1, 0); its
  // half extents in the scan: along y 1.0 (CAD x), along x 0.5 (CAD y), along z 1.0.
  const std::vector<Vec3> pts = {
      Vec3(0.8, 1, 0),         // centre: in
      Vec3(0.8 + 0.49, 1, 0),  // inside along scan x (half 0.5)
      Vec3(0.8 + 0.51, 1, 0),  // outside
      Vec3(0.8, 1 + 0.99, 0),  // inside along scan y (half 1.0)
      Vec3(0.8, 1 + 1.01, 0),  // outside
      Vec3(0.8, 1, -0.99),     // inside along z
      Vec3(10.8, 1, 0),        // the world-frame centre: outside in the scan frame
  };
  EXPECT_EQ(PointsInScan2CadBox(pts, m, to_scan), std::vector<int>({0, 1, 3, 5}));
  // A 2 cm margin takes in the points 1 cm outside.
  EXPECT_EQ(PointsInScan2CadBox(pts, m, to_scan, 0.02), std::vector<int>({0, 1, 2, 3, 4, 5}));
  m.scale = Vec3(0, 1, 1);
  EXPECT_THROW(Scan2CadModelToScan(scene, m), InvalidArgument);
}

TEST(RealEval, AlignedCadMeshLiesInItsOwnBox) {
  // The box of PointsInsideAnAlignedBox; a CAD mesh whose 8 vertices are the corners of its
  // bbox (centre (0, 0.1, 0), half extents (0.5, 0.25, 0.5)) must land on the box's corners in
  // the scan: inside with a 1 mm margin, outside with -1 cm.
  data::Scan2CadScene scene;
  data::Scan2CadModel m;
  RotatedScaledBox(&scene, &m);
  const Eigen::Matrix4d to_scan = Scan2CadModelToScan(scene, m);
  geometry::TriangleMesh cad;
  for (int k = 0; k < 8; ++k) {
    cad.vertices.push_back(m.center +
                           Vec3(k & 1 ? 0.5 : -0.5, k & 2 ? 0.25 : -0.25, k & 4 ? 0.5 : -0.5));
  }
  cad.faces = {{0, 1, 3}, {0, 3, 2}};
  const geometry::TriangleMesh placed = AlignedCadMesh(cad, to_scan);
  ASSERT_EQ(placed.vertices.size(), 8u);
  EXPECT_EQ(placed.faces, cad.faces);
  // Corner (+0.5, +0.25, +0.5) of the CAD: x2 scale -> (1, 0.5, 1) + centre offset (0, 0.2, 0)
  // -> Rz(90): (-0.7, 1, 1) -> + (11, 1, 0) - (10, 0, 0) = (0.3, 2, 1).
  EXPECT_NEAR((placed.vertices[7] - Vec3(0.3, 2, 1)).norm(), 0.0, 1e-12);
  EXPECT_EQ(PointsInScan2CadBox(placed.vertices, m, to_scan, 0.001).size(), 8u);
  EXPECT_TRUE(PointsInScan2CadBox(placed.vertices, m, to_scan, -0.01).empty());
  Eigen::Matrix4d bad = to_scan;
  bad(0, 3) = std::nan("");
  EXPECT_THROW(AlignedCadMesh(cad, bad), InvalidArgument);
}

TEST(RealEval, InstanceLabelsFromSetsFirstObjectWins) {
  EXPECT_EQ(InstanceLabelsFromSets(6, {{0, 2}, {2, 3}, {}, {5}}),
            std::vector<int>({1, 0, 1, 2, 0, 4}));
  EXPECT_EQ(InstanceLabelsFromSets(2, {}), std::vector<int>({0, 0}));
  EXPECT_THROW(InstanceLabelsFromSets(3, {{0, 3}}), InvalidArgument);
  EXPECT_THROW(InstanceLabelsFromSets(3, {{-1}}), InvalidArgument);
}

TEST(RealEval, PointIouAndObjectMatching) {
  EXPECT_DOUBLE_EQ(PointIoU({1, 2, 3, 4}, {3, 4, 5, 6}), 2.0 / 6.0);
  EXPECT_DOUBLE_EQ(PointIoU({1, 1, 2}, {2, 2}), 0.5);  // duplicates ignored
  EXPECT_DOUBLE_EQ(PointIoU({}, {}), 0.0);
  // GT 0 (chair, points 0..9): a chair prediction with IoU 0.6 and a table one with 0.9.
  // GT 1 (table, 20..29): only a table prediction with IoU 0.4 -> not found.
  std::vector<int> g0, g1, p_chair, p_table, p_table2;
  for (int i = 0; i < 10; ++i) g0.push_back(i), g1.push_back(20 + i);
  for (int i = 0; i < 6; ++i) p_chair.push_back(i);
  for (int i = 0; i < 9; ++i) p_table.push_back(i);
  for (int i = 0; i < 4; ++i) p_table2.push_back(20 + i);
  const std::vector<PredictedInstance> preds = {{labels::kCadChair, 0.9, p_chair},
                                                {labels::kCadTable, 0.8, p_table},
                                                {labels::kCadTable, 0.7, p_table2}};
  const auto m = MatchObjects({g0, g1}, {labels::kCadChair, labels::kCadTable}, preds);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_TRUE(m[0].found);
  EXPECT_EQ(m[0].best_index, 0);
  EXPECT_DOUBLE_EQ(m[0].best_iou, 0.6);
  EXPECT_DOUBLE_EQ(m[0].best_iou_any, 0.9);
  EXPECT_EQ(m[0].best_any_class, labels::kCadTable);
  // That table prediction holds 9 of the chair's 10 points and nothing else.
  EXPECT_DOUBLE_EQ(m[0].best_any_recall, 0.9);
  EXPECT_DOUBLE_EQ(m[0].best_any_precision, 1.0);
  EXPECT_FALSE(m[1].found);
  EXPECT_DOUBLE_EQ(m[1].best_any_recall, 0.4);
  EXPECT_DOUBLE_EQ(m[1].best_any_precision, 1.0);
  EXPECT_DOUBLE_EQ(m[1].best_iou, 0.4);
  EXPECT_EQ(m[1].gt_points, 10);
  // A prediction merged with its surroundings: all 10 points of GT 1 among 25 -> precision 0.4.
  std::vector<int> merged;
  for (int i = 15; i < 40; ++i) merged.push_back(i);
  const auto mm = MatchObjects({g1}, {labels::kCadTable}, {{labels::kCadTable, 0.5, merged}});
  EXPECT_DOUBLE_EQ(mm[0].best_iou, 0.4);
  EXPECT_DOUBLE_EQ(mm[0].best_any_recall, 1.0);
  EXPECT_DOUBLE_EQ(mm[0].best_any_precision, 0.4);
  EXPECT_THROW(MatchObjects({g0}, {}, preds), InvalidArgument);
}

TEST(RealEval, DropLabelledRemovesOnlyTheGivenClasses) {
  // 6 points: floor (1), table (6), wall (0), unlabelled (-1), table, floor.
  const std::vector<int> label = {1, 6, 0, -1, 6, 1};
  EXPECT_EQ(DropLabelled({0, 1, 2, 3, 4, 5}, label, {1, 0}), (std::vector<int>{1, 3, 4}));
  EXPECT_EQ(DropLabelled({5, 4, 3}, label, {}), (std::vector<int>{5, 4, 3}));  // order kept
  EXPECT_EQ(DropLabelled({0, 5}, label, {1}), std::vector<int>{});
  // A table box holding the table (2 points) and 2 floor points: a perfect table
  // prediction scores 0.5 against the raw box, 1 once the floor is dropped.
  EXPECT_DOUBLE_EQ(PointIoU({1, 4}, {0, 1, 4, 5}), 0.5);
  EXPECT_DOUBLE_EQ(PointIoU({1, 4}, DropLabelled({0, 1, 4, 5}, label, {1})), 1.0);
  EXPECT_THROW(DropLabelled({6}, label, {1}), InvalidArgument);
  EXPECT_THROW(DropLabelled({-1}, label, {1}), InvalidArgument);
}

}  // namespace
}  // namespace dimr::eval
