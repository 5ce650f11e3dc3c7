// The approximate clustering mode (no ball-query neighbour cap): pipeline::RadiusComponents
// against an O(N^2) uncapped BFS transcription, its plumbing through ClusteringConfig,
// SemanticVoteConfig and the stage-1 inference key cluster_cap.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <numeric>
#include <queue>
#include <random>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/clustering.h"
#include "dimr/pipeline/stage1_instances.h"
#include "dimr/pipeline/stage1_segmenter.h"

namespace dimr::pipeline {
namespace {

using Points = std::vector<Eigen::Vector3f>;
using Clusters = std::vector<std::vector<int>>;

// PointGroup's BFS without the cap, O(N^2): clusters as sets (sorted), in seed order.
Clusters UncappedReference(const Points& points, const std::vector<int>& labels, double radius,
                           int min_points) {
  const float rf = static_cast<float>(radius);
  const float r2 = rf * rf;
  const int n = static_cast<int>(points.size());
  std::vector<bool> visited(n, false);
  Clusters out;
  for (int seed = 0; seed < n; ++seed) {
    if (labels[seed] < 0 || visited[seed]) continue;
    std::vector<int> cluster;
    std::queue<int> queue;
    queue.push(seed);
    visited[seed] = true;
    while (!queue.empty()) {
      const int j = queue.front();
      queue.pop();
      cluster.push_back(j);
      for (int k = 0; k < n; ++k) {
        if (visited[k] || labels[k] != labels[j]) continue;
        const float ex = points[j].x() - points[k].x();
        const float ey = points[j].y() - points[k].y();
        const float ez = points[j].z() - points[k].z();
        if (ex * ex + ey * ey + ez * ez < r2) {
          visited[k] = true;
          queue.push(k);
        }
      }
    }
    std::sort(cluster.begin(), cluster.end());
    if (static_cast<int>(cluster.size()) >= min_points) out.push_back(cluster);
  }
  return out;
}

Clusters BothPaths(const Points& points, const std::vector<int>& labels, double radius,
                   int min_points, const std::string& what) {
  const Clusters got = RadiusComponents(points, labels, radius, min_points);
  const bool before = SetClusteringAvx2(false);
  const Clusters sse2 = RadiusComponents(points, labels, radius, min_points);
  SetClusteringAvx2(before);
  EXPECT_EQ(got, sse2) << what;
  return got;
}

TEST(RadiusComponents, MatchesUncappedBfsOnRandomInputs) {
  std::mt19937 rng(42);
  int compared = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int n = 300 + 150 * (trial % 8);
    Points points;
    std::uniform_real_distribution<float> u(-0.15f, 0.15f);
    std::uniform_int_distribution<int> cell(-8, 8);
    for (int i = 0; i < n; ++i) {
      if (trial % 3 == 2) {
        // Exact multiples of r: grid neighbours at d == r (float) must not link (strict <).
        points.emplace_back(cell(rng) * 0.03f, cell(rng) * 0.03f, cell(rng) * 0.03f);
      } else {
        points.emplace_back(u(rng), u(rng), u(rng));
      }
    }
    std::uniform_int_distribution<int> lab(-1, 2);
    std::vector<int> labels(n);
    for (int& l : labels) l = lab(rng);
    const double radius = std::array<double, 3>{0.01, 0.03, 0.05}[trial % 3];
    const int min_points = trial % 2 == 0 ? 1 : 5;
    const Clusters got = BothPaths(points, labels, radius, min_points, std::to_string(trial));
    ASSERT_EQ(got, UncappedReference(points, labels, radius, min_points)) << "trial " << trial;
    compared += static_cast<int>(got.size());
  }
  EXPECT_GT(compared, 500);
}

// Dense shifted blobs (the parts' box tests settle most pairs), pairs just inside / outside
// the radius across cell and half-cell boundaries (where the box tests must not decide).
TEST(RadiusComponents, DenseBlobsAndPairsAtTheRadius) {
  std::mt19937 rng(17);
  std::normal_distribution<float> g(0.f, 1.f);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double radius : {0.03, 0.12, 0.3}) {
    Points points;
    std::vector<int> labels;
    const struct {
      float x, y, sigma;
      int label, count;
    } blobs[] = {{0.f, 0.f, 0.03f, 0, 1600},
                 {0.15f, 0.f, 0.05f, 1, 1200},
                 {0.f, 0.2f, 0.08f, 0, 1000},
                 {0.7f, 0.62f, 0.1f, 3, 700}};
    for (const auto& b : blobs) {
      for (int i = 0; i < b.count; ++i) {
        points.emplace_back(b.x + b.sigma * g(rng), b.y + b.sigma * g(rng),
                            0.3f + b.sigma * g(rng));
        labels.push_back(b.label);
      }
    }
    // Pairs at r * (1 -+ 1e-6 .. 1e-4) from a point on a (half-)cell boundary, each pair its
    // own label: inside links, outside does not.
    int inside = 0;
    for (int i = 0; i < 400; ++i) {
      const int axis = i % 3;
      Eigen::Vector3d p(1.0 + u(rng), 1.0 + u(rng), 1.0 + u(rng));
      p[axis] =
          (std::floor(p[axis] / radius) + (i % 2 == 0 ? 0.5 : 1.0)) * radius * (1.0 + 1e-5) - 1e-9;
      Eigen::Vector3d dir = Eigen::Vector3d::Zero();
      dir[axis] = 1.0;
      if (i % 5 == 4) dir = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      const bool in = i % 4 < 2;
      const double d = radius * (in ? 1.0 - 1e-6 - 1e-4 * u(rng) : 1.0 + 1e-6 + 1e-4 * u(rng));
      points.push_back(p.cast<float>());
      points.push_back((p + d * dir).cast<float>());
      labels.push_back(100 + i);
      labels.push_back(100 + i);
      inside += in ? 1 : 0;
    }
    std::vector<int> perm(points.size());
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    Points shuffled(points.size());
    std::vector<int> shuffled_labels(points.size());
    for (std::size_t i = 0; i < perm.size(); ++i) {
      shuffled[i] = points[perm[i]];
      shuffled_labels[i] = labels[perm[i]];
    }
    const Clusters want = UncappedReference(shuffled, shuffled_labels, radius, 2);
    const Clusters got = BothPaths(shuffled, shuffled_labels, radius, 2, std::to_string(radius));
    ASSERT_EQ(got, want) << "r " << radius;
    // The pairs that link are (about: float rounding of the coordinates blurs the 1e-6 ..
    // 1e-4 margins) the inside ones.
    int linked_pairs = 0;
    for (const auto& c : got) linked_pairs += shuffled_labels[c[0]] >= 100 ? 1 : 0;
    EXPECT_GT(linked_pairs, inside * 8 / 10) << radius;
    EXPECT_LT(linked_pairs, inside * 12 / 10) << radius;
  }
}

TEST(RadiusComponents, OrderSizesHugeCoordinatesAndErrors) {
  // Seed order (smallest index first), indices ascending, min_points inclusive.
  const Points points = {{1, 0, 0}, {0, 0, 0}, {1.01f, 0, 0}, {0.01f, 0, 0}, {0.02f, 0, 0}};
  const std::vector<int> labels = {4, 2, 4, 2, 2};
  EXPECT_EQ(RadiusComponents(points, labels, 0.015, 1), (Clusters{{0, 2}, {1, 3, 4}}));
  EXPECT_EQ(RadiusComponents(points, labels, 0.015, 3), (Clusters{{1, 3, 4}}));
  EXPECT_EQ(RadiusComponents(points, {4, -1, 4, 2, 2}, 0.015, 1), (Clusters{{0, 2}, {3, 4}}));
  // Coordinates where the float spacing is 8 (at 1e8), radius 10: the float tests decide.
  Points far;
  std::vector<int> far_labels;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> step(0, 3);
  for (int i = 0; i < 200; ++i) {
    far.emplace_back(1e8f + 8.f * step(rng), 8.f * step(rng), 0.f);
    far_labels.push_back(i % 2);
  }
  EXPECT_EQ(RadiusComponents(far, far_labels, 10.0, 1),
            UncappedReference(far, far_labels, 10.0, 1));
  EXPECT_THROW(RadiusComponents(points, {0}, 0.03, 1), InvalidArgument);
  EXPECT_THROW(RadiusComponents(points, labels, 0.0, 1), InvalidArgument);
  EXPECT_THROW(RadiusComponents(points, labels, 0.03, 0), InvalidArgument);
  const Points bad = {{0, 0, 0}, {std::nanf(""), 0, 0}};
  EXPECT_THROW(RadiusComponents(bad, {0, 0}, 0.03, 1), InvalidArgument);
  EXPECT_TRUE(RadiusComponents({}, {}, 0.03, 1).empty());
}

// 1500 points of one label within r of each other: with the cap every neighbour list is the
// 1000 lowest indices, so BFS from 0 takes those and the other 500 are singletons; without it
// they are one cluster. The switch must reach MultiScaleClusters and VoteSemantics.
TEST(RadiusComponents, TheCapSwitchReachesThePassesAndTheVote) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(0.f, 0.01f);
  Points points, offsets;
  for (int i = 0; i < 1500; ++i) {
    points.emplace_back(u(rng), u(rng), u(rng));
    offsets.emplace_back(0.f, 0.f, 0.f);
  }
  const std::vector<int> labels(1500, 3);
  ClusteringConfig config;
  config.passes = {{false, 0.05}, {true, 0.05}};
  config.min_points = 1;
  const std::vector<Proposal> capped = MultiScaleClusters(points, offsets, labels, config);
  ASSERT_EQ(capped.size(), 2u * 501u);
  EXPECT_EQ(capped[0].points.size(), 1000u);
  config.neighbour_cap = false;
  const std::vector<Proposal> free = MultiScaleClusters(points, offsets, labels, config);
  ASSERT_EQ(free.size(), 2u);
  for (const Proposal& p : free) {
    std::vector<int> all(1500);
    std::iota(all.begin(), all.end(), 0);
    EXPECT_EQ(p.points, all);
    EXPECT_EQ(p.label, 3);
  }
  EXPECT_EQ(free[1].pass, 1);

  // The vote: classes 0 (stuff), 1, 2; points 0..999 say 1 strongly, the rest 2 weakly.
  std::vector<int> semantic(1500);
  std::vector<float> prob;
  for (int i = 0; i < 1500; ++i) {
    semantic[i] = i < 1000 ? 1 : 2;
    const std::vector<float> row =
        i < 1000 ? std::vector<float>{0.f, 0.9f, 0.1f} : std::vector<float>{0.f, 0.4f, 0.6f};
    prob.insert(prob.end(), row.begin(), row.end());
  }
  SemanticVoteConfig vote;
  vote.radius = 0.05;
  vote.min_points = 5;
  const std::vector<bool> is_thing = {false, true, true};
  const std::vector<int> with_cap = VoteSemantics(points, offsets, semantic, prob, is_thing, vote);
  vote.neighbour_cap = false;
  const std::vector<int> without = VoteSemantics(points, offsets, semantic, prob, is_thing, vote);
  EXPECT_EQ(std::count(with_cap.begin(), with_cap.end(), 2), 500);  // singletons keep 2
  EXPECT_EQ(std::count(without.begin(), without.end(), 1), 1500);   // one cluster votes 1
}

TEST(RadiusComponents, InferenceKeyClusterCap) {
  const Stage1InferenceConfig d;
  EXPECT_TRUE(d.cluster_cap);
  EXPECT_EQ(d.ToString().find("cluster_cap"), std::string::npos);  // default: not written
  const Stage1InferenceConfig c = Stage1InferenceConfig::FromString("cluster_cap=0");
  EXPECT_FALSE(c.cluster_cap);
  EXPECT_NE(c.ToString().find("cluster_cap=0"), std::string::npos);
  EXPECT_FALSE(Stage1InferenceConfig::FromString(c.ToString()).cluster_cap);
  const Stage1InstanceConfig inst = c.InstanceConfig();
  EXPECT_FALSE(inst.clustering.neighbour_cap);
  EXPECT_FALSE(inst.semantic_vote.neighbour_cap);
  EXPECT_TRUE(d.InstanceConfig().clustering.neighbour_cap);
  EXPECT_TRUE(d.InstanceConfig().semantic_vote.neighbour_cap);
  EXPECT_THROW(Stage1InferenceConfig::FromString("cluster_cap=2"), InvalidArgument);
}

}  // namespace
}  // namespace dimr::pipeline
