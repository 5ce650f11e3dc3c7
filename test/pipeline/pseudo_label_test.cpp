// Pseudo-labels for self-training (pipeline::PseudoLabelSample): class-balanced selection of
// the confident points, the probability floor, instances from the proposals in score order,
// probabilities read through per-voxel rows, and every bad input named.
#include "dimr/pipeline/pseudo_label.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "dimr/core/labels.h"
#include "dimr/geometry/error.h"

namespace dimr::pipeline {
namespace {

constexpr int kC = kStage1RfsClasses;
const int kWall = 0, kChair = 4, kTable = 6, kBookshelf = 9;

// A result with one probability row per point: point i's final class `label[i]` has
// probability prob[i] (the rest spread over class 24 so that rows sum to one).
struct Fixture {
  PointCloudInput cloud;
  Stage1Result result;
  void Add(int label, float prob) {
    const float x = static_cast<float>(cloud.points.size());
    cloud.points.emplace_back(x * 0.1f, 0.0f, 0.5f);
    cloud.colors.emplace_back(0.5f, 0.4f, 0.3f);
    result.semantic.push_back(label);
    std::vector<float> row(kC, 0.0f);
    if (label >= 0) row[static_cast<std::size_t>(label)] = prob;
    row[kC - 1] += 1.0f - prob;
    result.semantic_prob.insert(result.semantic_prob.end(), row.begin(), row.end());
    result.heading_prob.insert(result.heading_prob.end(), kStage1HeadingBins,
                               1.0f / kStage1HeadingBins);
    result.heading_residual.insert(result.heading_residual.end(), kStage1HeadingBins, 0.0f);
  }
};

TEST(PseudoLabel, EachClassKeepsItsMostConfidentShare) {
  Fixture f;
  f.cloud.name = "room";
  // Ten wall points, probabilities 0.95, 0.90, ..., 0.50 (points 0..9).
  for (int i = 0; i < 10; ++i) f.Add(kWall, 0.95f - 0.05f * static_cast<float>(i));
  // Four bookshelf points of low confidence, in mixed order (points 10..13).
  f.Add(kBookshelf, 0.30f);
  f.Add(kBookshelf, 0.10f);
  f.Add(kBookshelf, 0.25f);
  f.Add(kBookshelf, 0.20f);
  f.Add(-1, 0.0f);  // no class (a removed ceiling): stays ignored (point 14)

  PseudoLabelConfig cfg;
  cfg.keep_fraction = 0.5;
  PseudoLabelSummary sum;
  const nn::Stage1Sample s = PseudoLabelSample(f.cloud, f.result, cfg, &sum);
  ASSERT_EQ(s.semantic.size(), 15u);
  EXPECT_EQ(s.name, "room");
  // Walls: the first five (0.95 .. 0.75) keep their class, the others are ignored.
  for (int i = 0; i < 10; ++i) EXPECT_EQ(s.semantic[i], i < 5 ? kWall : nn::kStage1Ignore) << i;
  // Bookshelf: the two most confident of its own points (0.30, 0.25), although every one of
  // them is below every wall point a global threshold would keep.
  EXPECT_EQ(s.semantic[10], kBookshelf);
  EXPECT_EQ(s.semantic[11], nn::kStage1Ignore);
  EXPECT_EQ(s.semantic[12], kBookshelf);
  EXPECT_EQ(s.semantic[13], nn::kStage1Ignore);
  EXPECT_EQ(s.semantic[14], nn::kStage1Ignore);
  EXPECT_EQ(sum.points, 15u);
  EXPECT_EQ(sum.labelled, 7u);
  EXPECT_EQ(sum.predicted[kWall], 10u);
  EXPECT_EQ(sum.kept[kWall], 5u);
  EXPECT_EQ(sum.kept[kBookshelf], 2u);
  EXPECT_FLOAT_EQ(sum.threshold[kWall], 0.75f);
  EXPECT_FLOAT_EQ(sum.threshold[kBookshelf], 0.25f);
  // Points and colours as given, no instances without proposals.
  EXPECT_EQ(s.points, f.cloud.points);
  EXPECT_EQ(s.colors, f.cloud.colors);
  EXPECT_TRUE(s.instances.empty());
  for (int k : s.instance) EXPECT_EQ(k, -1);

  // The probability floor cuts within a class's share: >= 0.28 leaves one bookshelf point and
  // the walls' five; keep 1 keeps every wall point.
  cfg.min_prob = 0.28;
  cfg.keep_fraction = 1.0;
  const nn::Stage1Sample t = PseudoLabelSample(f.cloud, f.result, cfg, &sum);
  EXPECT_EQ(sum.kept[kWall], 10u);
  EXPECT_EQ(sum.kept[kBookshelf], 1u);
  EXPECT_EQ(t.semantic[10], kBookshelf);
  EXPECT_EQ(t.semantic[12], nn::kStage1Ignore);
}

TEST(PseudoLabel, ConfidenceIsReadThroughPerVoxelRows) {
  // Two rows shared by four points: points 0, 2 -> row 1 (chair 0.9), points 1, 3 -> row 0
  // (chair 0.4). With keep 0.5 the two points of row 1 stay.
  Fixture f;
  f.Add(kChair, 0.4f);
  f.Add(kChair, 0.9f);
  f.result.semantic.assign(4, kChair);
  f.result.point_row = {1, 0, 1, 0};
  f.cloud.points.resize(4, Eigen::Vector3f::Zero());
  f.cloud.colors.clear();
  const nn::Stage1Sample s = PseudoLabelSample(f.cloud, f.result, PseudoLabelConfig{});
  EXPECT_EQ(s.semantic, (std::vector<int>{kChair, nn::kStage1Ignore, kChair, nn::kStage1Ignore}));
  EXPECT_TRUE(s.colors.empty());
}

TEST(PseudoLabel, InstancesComeFromTheProposalsInScoreOrder) {
  Fixture f;
  // Points 0..5: chair, chair, chair, table, chair, table; 6..7 wall.
  for (int c : {kChair, kChair, kChair, kTable, kChair, kTable}) f.Add(c, 0.8f);
  f.Add(kWall, 0.9f);
  f.Add(kWall, 0.9f);
  const int chair = labels::RfsToCad(kChair), table = labels::RfsToCad(kTable);
  ASSERT_GE(chair, 0);
  ASSERT_GE(table, 0);
  ScoredInstance a, b, weak;
  a.points = {0, 1, 2, 3};  // a chair proposal that also holds table point 3
  a.cad_class = chair;
  a.score = 0.9;
  b.points = {3, 4, 5};  // a table proposal; point 3 is already a's, point 4 is a chair point
  b.cad_class = table;
  b.score = 0.7;
  weak.points = {6, 7};
  weak.cad_class = chair;
  weak.score = 0.1;
  f.result.instances = {a, b, weak};

  PseudoLabelConfig cfg;
  cfg.keep_fraction = 1.0;
  cfg.min_instance_score = 0.2;  // drops `weak`
  PseudoLabelSummary sum;
  const nn::Stage1Sample s = PseudoLabelSample(f.cloud, f.result, cfg, &sum);
  ASSERT_EQ(s.instances.size(), 2u);
  EXPECT_EQ(s.instance, (std::vector<int>{0, 0, 0, 0, 1, 1, -1, -1}));
  // Each instance's class: the RFS class most of its points carry among its CAD class's.
  EXPECT_EQ(s.instances[0].semantic, kChair);
  EXPECT_EQ(s.instances[0].cad_class, chair);
  EXPECT_EQ(s.instances[1].semantic, kTable);
  EXPECT_EQ(s.instances[1].cad_class, table);
  EXPECT_FALSE(s.instances[0].has_heading);  // a real scan has no CAD box
  // Point labels stay per point (point 3 is table inside the chair instance).
  EXPECT_EQ(s.semantic[3], kTable);
  EXPECT_EQ(sum.instances, 2);
  EXPECT_EQ(sum.instance_points, 6u);
}

TEST(PseudoLabel, BadInputIsNamed) {
  Fixture f;
  f.cloud.name = "lab";
  f.Add(kWall, 0.9f);
  f.Add(kChair, 0.9f);
  const auto expect_error = [&](const Stage1Result& r, const PseudoLabelConfig& cfg,
                                const std::string& part) {
    try {
      PseudoLabelSample(f.cloud, r, cfg);
      ADD_FAILURE() << "expected an error containing '" << part << "'";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  Stage1Result r = f.result;
  r.semantic.pop_back();
  expect_error(r, {}, "1 labels for 2 points");
  r = f.result;
  r.semantic[1] = kC;
  expect_error(r, {}, "point 1 has class 25");
  r = f.result;
  ScoredInstance bad;
  bad.points = {0, 7};
  bad.cad_class = labels::RfsToCad(kChair);
  r.instances = {bad};
  expect_error(r, {}, "holds point 7 of 2");
  PseudoLabelConfig cfg;
  cfg.keep_fraction = 0;
  expect_error(f.result, cfg, "keep_fraction");
  cfg = {};
  cfg.min_prob = 1.0;
  expect_error(f.result, cfg, "min_prob");
  r = f.result;
  r.semantic_prob.pop_back();
  expect_error(r, {}, "lab");  // the probability table's shape, named by the cloud
}

}  // namespace
}  // namespace dimr::pipeline
