// Instance-guided semantic vote (pipeline::VoteSemantics): hand-made clusters in shifted
// space, majority by summed probability, stuff points and small clusters untouched, errors.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/stage1_instances.h"

namespace dimr::pipeline {
namespace {

constexpr int kClasses = 4;  // 0 = stuff (wall), 1..3 = things

struct Scene {
  std::vector<Eigen::Vector3f> points, offsets;
  std::vector<int> semantic;
  std::vector<float> prob;
  void Add(const Eigen::Vector3f& p, const Eigen::Vector3f& centre, std::vector<float> row) {
    points.push_back(p);
    offsets.push_back(centre - p);  // perfect offsets: every point lands on its centre
    int best = 0;
    for (int c = 1; c < kClasses; ++c) {
      if (row[c] > row[best]) best = c;
    }
    semantic.push_back(best);
    prob.insert(prob.end(), row.begin(), row.end());
  }
};

const std::vector<bool> kIsThing = {false, true, true, true};

TEST(VoteSemantics, ClustersTakeTheClassWithTheLargestSummedProbability) {
  Scene s;
  // Object A at (0, 0, 0.5): 6 points say class 1 weakly, 4 say class 2 strongly.
  // Summed: class 1 = 6 * 0.4 + 4 * 0.05 = 2.6, class 2 = 6 * 0.35 + 4 * 0.9 = 5.7 -> 2,
  // although a per-point majority would say 1.
  const Eigen::Vector3f a(0, 0, 0.5f), b(2, 0, 0.5f), c(5, 5, 0.5f);
  for (int i = 0; i < 6; ++i)
    s.Add(a + Eigen::Vector3f(0.1f * i, 0, 0), a, {0.0f, 0.4f, 0.35f, 0.25f});
  for (int i = 0; i < 4; ++i)
    s.Add(a + Eigen::Vector3f(0, 0.1f * i, 0), a, {0.0f, 0.05f, 0.9f, 0.05f});
  // Object B at (2, 0, 0.5): all class 3 except one point of class 1 -> all 3.
  for (int i = 0; i < 7; ++i)
    s.Add(b + Eigen::Vector3f(0, 0, 0.1f * i), b, {0.0f, 0.1f, 0.1f, 0.8f});
  s.Add(b + Eigen::Vector3f(0.3f, 0, 0), b, {0.0f, 0.7f, 0.1f, 0.2f});
  // A wall point whose offset lands on A: stuff keeps its label and does not vote.
  s.Add(Eigen::Vector3f(0, 1, 1), a, {0.9f, 0.1f, 0.0f, 0.0f});
  // A 2-point cluster (below min_points 3) keeps its mixed labels.
  s.Add(c, c, {0.0f, 0.6f, 0.4f, 0.0f});
  s.Add(c + Eigen::Vector3f(0.1f, 0, 0), c, {0.0f, 0.4f, 0.6f, 0.0f});

  SemanticVoteConfig cfg;
  cfg.radius = 0.05;
  cfg.min_points = 3;
  const std::vector<int> out =
      VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, cfg);
  ASSERT_EQ(out.size(), s.points.size());
  for (int i = 0; i < 10; ++i) EXPECT_EQ(out[i], 2) << i;
  for (int i = 10; i < 18; ++i) EXPECT_EQ(out[i], 3) << i;
  EXPECT_EQ(out[18], 0);
  EXPECT_EQ(out[19], 1);
  EXPECT_EQ(out[20], 2);
  // Before the vote object A was split 6 / 4.
  EXPECT_EQ(s.semantic[0], 1);
  EXPECT_EQ(s.semantic[6], 2);

  // Radius 0 = no vote.
  cfg.radius = 0;
  EXPECT_EQ(VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, cfg), s.semantic);
  // A radius that links A and B (2 m apart) merges them into one object: summed class 3 =
  // 6 * 0.25 + 4 * 0.05 + 7 * 0.8 + 0.2 = 7.5 beats class 2 = 5.7 + 0.8 = 6.5.
  cfg.radius = 2.5;
  const std::vector<int> merged =
      VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, cfg);
  for (int i = 0; i < 18; ++i) EXPECT_EQ(merged[i], 3) << i;
  // Class 3 kept out of the vote: B's class-3 points keep their label and do not vote, class 3
  // cannot win, so the merged cluster (A + B's class-1 point) takes class 2
  // (2: 5.7 + 0.1 = 5.8, 1: 2.6 + 0.7 = 3.3).
  cfg.excluded_classes = {3};
  const std::vector<int> excl =
      VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, cfg);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(excl[i], 2) << i;
  for (int i = 10; i < 17; ++i) EXPECT_EQ(excl[i], 3) << i;
  EXPECT_EQ(excl[17], 2);
  cfg.excluded_classes = {4};  // outside [0, C)
  EXPECT_THROW(VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, cfg),
               InvalidArgument);
  cfg.excluded_classes = {-1};
  EXPECT_THROW(cfg.Validate(), InvalidArgument);
}

// A rectangle of points on the floor plane, rotated by `angle`: side x side_y metres, n x n grid.
std::vector<Eigen::Vector3f> Footprint(double side_x, double side_y, double angle, int n) {
  std::vector<Eigen::Vector3f> p;
  const double c = std::cos(angle), s = std::sin(angle);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = side_x * (i / (n - 1.0) - 0.5), y = side_y * (j / (n - 1.0) - 0.5);
      p.emplace_back(static_cast<float>(c * x - s * y + 3.0), static_cast<float>(s * x + c * y),
                     static_cast<float>(0.1 * ((i + j) % 5)));
    }
  }
  return p;
}

TEST(VoteSemantics, FootprintLongSideIsThePrincipalExtent) {
  // 51 x 51 grid: the 2nd-98th percentile range of a uniform grid of side L is 0.96 L.
  for (double angle : {0.0, 0.4, 1.3, -2.2}) {
    const auto p = Footprint(1.5, 0.5, angle, 51);
    std::vector<int> idx(p.size());
    for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
    EXPECT_NEAR(FootprintLongSide(p, idx), 0.96 * 1.5, 0.01) << angle;
    const auto q = Footprint(0.4, 0.6, angle, 51);
    EXPECT_NEAR(FootprintLongSide(q, idx), 0.96 * 0.6, 0.01) << angle;
  }
  // An outlier does not stretch it (percentiles), a single point has none.
  auto p = Footprint(0.5, 0.5, 0.0, 21);
  p.emplace_back(13.0f, 0.0f, 0.0f);
  std::vector<int> idx(p.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  EXPECT_LT(FootprintLongSide(p, idx), 0.75);
  EXPECT_EQ(FootprintLongSide(p, {3}), 0.0);
}

TEST(VoteSemantics, ClustersTooSmallForTheirClassTakeTheBestClassTheyCan) {
  // Two objects whose points lean to class 2 ("sofa") over class 1 ("chair"): a 0.6 m one and
  // a 1.6 m one. With min_extent 0.8 m for class 2 the small one becomes class 1, the large one
  // stays class 2; class 3 (no limit, smallest sum) never wins.
  Scene s;
  const Eigen::Vector3f small_centre(3, 0, 0.4f), large_centre(8, 0, 0.4f);
  for (const auto& p : Footprint(0.6, 0.55, 0.3, 8)) {
    s.Add(p, small_centre, {0.0f, 0.3f, 0.6f, 0.1f});
  }
  const std::size_t n_small = s.points.size();
  for (auto p : Footprint(1.6, 0.8, -0.7, 8)) {
    p.x() += 5.0f;
    s.Add(p, large_centre, {0.0f, 0.3f, 0.6f, 0.1f});
  }
  SemanticVoteConfig cfg;
  cfg.radius = 0.1;
  cfg.min_points = 3;
  auto run = [&](const SemanticVoteConfig& c) {
    return VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, c);
  };
  const std::vector<int> plain = run(cfg);
  for (std::size_t i = 0; i < s.points.size(); ++i) EXPECT_EQ(plain[i], 2) << i;
  cfg.min_extent = {0.0, 0.0, 0.8, 0.0};
  const std::vector<int> gated = run(cfg);
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_EQ(gated[i], i < n_small ? 1 : 2) << i;
  }
  // When no class fits, the winner stays.
  cfg.min_extent = {0.0, 5.0, 5.0, 5.0};
  EXPECT_EQ(run(cfg), plain);
  // An excluded class is never the fallback: class 1 out of the vote -> class 3.
  cfg.min_extent = {0.0, 0.0, 0.8, 0.0};
  cfg.excluded_classes = {1};
  const std::vector<int> excl = run(cfg);
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_EQ(excl[i], i < n_small ? 3 : 2) << i;
  }
  // Wrong length and bad values are errors.
  cfg.excluded_classes.clear();
  cfg.min_extent = {0.0, 0.8};
  EXPECT_THROW(run(cfg), InvalidArgument);
  cfg.min_extent = {0.0, 0.0, -0.8, 0.0};
  EXPECT_THROW(cfg.Validate(), InvalidArgument);
  cfg.min_extent = {0.0, 0.0, std::numeric_limits<double>::infinity(), 0.0};
  EXPECT_THROW(cfg.Validate(), InvalidArgument);
}

TEST(VoteSemantics, ClustersLongerThanAnyObjectAreSplitBeforeTheyVote) {
  // Two objects side by side in the room (X: x in [0, 1.2], Y: x in [2, 3.2]) whose shifted
  // points (poor offsets, as on real scans) form one chain at the vote radius 0.1: X's land on
  // x in [0, 0.28], Y's on [0.36, 0.68], 8 cm apart. X's points say class 2, Y's (more of them)
  // class 1: one vote gives both class 1. With max_extent 2 m the 3.2 m cluster is split at
  // radius 0.05 and each object keeps its own class.
  Scene s;
  for (int i = 0; i < 8; ++i) {
    s.Add(Eigen::Vector3f(0.15f * i, 0, 0.4f), Eigen::Vector3f(0.04f * i, 0, 0.4f),
          {0.0f, 0.3f, 0.6f, 0.1f});
  }
  const std::size_t n_x = s.points.size();
  for (int i = 0; i < 9; ++i) {
    s.Add(Eigen::Vector3f(2.0f + 0.15f * i, 0, 0.4f), Eigen::Vector3f(0.36f + 0.04f * i, 0, 0.4f),
          {0.0f, 0.7f, 0.2f, 0.1f});
  }
  // A third object, 3.2 m long whose shifted points are one dense run (1 cm apart): no split
  // separates it, so its mixed per-point labels stay.
  for (int i = 0; i < 17; ++i) {
    const std::vector<float> row = i % 3 == 0 ? std::vector<float>{0.0f, 0.1f, 0.1f, 0.8f}
                                              : std::vector<float>{0.0f, 0.6f, 0.3f, 0.1f};
    s.Add(Eigen::Vector3f(0.2f * i, 5, 0.4f), Eigen::Vector3f(0.01f * i, 5, 0.4f), row);
  }
  SemanticVoteConfig cfg;
  cfg.radius = 0.1;
  cfg.min_points = 3;
  auto run = [&](const SemanticVoteConfig& c) {
    return VoteSemantics(s.points, s.offsets, s.semantic, s.prob, kIsThing, c);
  };
  const std::vector<int> merged = run(cfg);
  for (std::size_t i = 0; i < n_x + 9; ++i) EXPECT_EQ(merged[i], 1) << i;
  for (std::size_t i = n_x + 9; i < s.points.size(); ++i) EXPECT_EQ(merged[i], 1) << i;
  cfg.max_extent = 2.0;
  const std::vector<int> split = run(cfg);
  for (std::size_t i = 0; i < n_x + 9; ++i) EXPECT_EQ(split[i], i < n_x ? 2 : 1) << i;
  for (std::size_t i = n_x + 9; i < s.points.size(); ++i) EXPECT_EQ(split[i], s.semantic[i]) << i;
  // A limit above every cluster changes nothing; a bad one is refused.
  cfg.max_extent = 4.0;
  EXPECT_EQ(run(cfg), merged);
  cfg.max_extent = -1.0;
  EXPECT_THROW(cfg.Validate(), InvalidArgument);
  cfg.max_extent = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(cfg.Validate(), InvalidArgument);
}

TEST(VoteSemantics, BadInputsGiveClearErrors) {
  Scene s;
  s.Add(Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(0, 0, 0), {0.0f, 1.0f, 0.0f, 0.0f});
  SemanticVoteConfig cfg;
  cfg.radius = 0.1;
  auto run = [&](const Scene& t, const SemanticVoteConfig& c) {
    return VoteSemantics(t.points, t.offsets, t.semantic, t.prob, kIsThing, c);
  };
  EXPECT_NO_THROW(run(s, cfg));
  Scene t = s;
  t.offsets.clear();
  EXPECT_THROW(run(t, cfg), InvalidArgument);
  t = s;
  t.prob.pop_back();
  EXPECT_THROW(run(t, cfg), InvalidArgument);
  t = s;
  t.semantic[0] = 4;
  EXPECT_THROW(run(t, cfg), InvalidArgument);
  t = s;
  t.prob[2] = std::numeric_limits<float>::quiet_NaN();
  cfg.min_points = 1;
  EXPECT_THROW(run(t, cfg), InvalidArgument);
  SemanticVoteConfig bad;
  bad.radius = -1;
  EXPECT_THROW(run(s, bad), InvalidArgument);
  bad.radius = 0.1;
  bad.min_points = 0;
  EXPECT_THROW(run(s, bad), InvalidArgument);
  try {
    bad.Validate();
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("min_points"), std::string::npos);
  }
}

}  // namespace
}  // namespace dimr::pipeline
