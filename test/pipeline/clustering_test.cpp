#include "dimr/pipeline/clustering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <queue>
#include <random>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/stage1_instances.h"

namespace dimr::pipeline {
namespace {

using Points = std::vector<Eigen::Vector3f>;
using Clusters = std::vector<std::vector<int>>;
constexpr double kPi = 3.14159265358979323846;

// O(N^2) transcription of PointGroup's ballquery_batch_p + bfs_cluster: the query scans the
// labelled points in index order and stops at the cap-th hit; BFS with a FIFO queue.
Clusters ReferenceBfs(const Points& points, const std::vector<int>& labels, double radius,
                      int min_points, int cap) {
  std::vector<int> subset;
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    if (labels[i] >= 0) subset.push_back(i);
  }
  const float rf = static_cast<float>(radius);
  const float r2 = rf * rf;
  std::vector<std::vector<int>> neighbours(points.size());
  for (int j : subset) {
    for (int k : subset) {
      const float ex = points[j].x() - points[k].x();
      const float ey = points[j].y() - points[k].y();
      const float ez = points[j].z() - points[k].z();
      if (ex * ex + ey * ey + ez * ez < r2) {
        neighbours[j].push_back(k);
        if (static_cast<int>(neighbours[j].size()) == cap) break;
      }
    }
  }
  std::vector<bool> visited(points.size(), false);
  Clusters out;
  for (int seed : subset) {
    if (visited[seed]) continue;
    std::vector<int> cluster;
    std::queue<int> queue;
    queue.push(seed);
    visited[seed] = true;
    while (!queue.empty()) {
      const int j = queue.front();
      queue.pop();
      cluster.push_back(j);
      for (int k : neighbours[j]) {
        if (!visited[k] && labels[k] == labels[j]) {
          visited[k] = true;
          queue.push(k);
        }
      }
    }
    if (static_cast<int>(cluster.size()) >= min_points) out.push_back(cluster);
  }
  return out;
}

// Brute-force greedy NMS (numpy-style, with a stable descending sort).
std::vector<int> ReferenceNms(const std::vector<Proposal>& proposals, double threshold) {
  std::vector<int> order(proposals.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return proposals[a].score > proposals[b].score; });
  std::vector<int> kept;
  while (!order.empty()) {
    const int i = order.front();
    kept.push_back(i);
    std::vector<int> rest;
    for (std::size_t s = 1; s < order.size(); ++s) {
      if (PointIou(proposals[i].points, proposals[order[s]].points) <= threshold) {
        rest.push_back(order[s]);
      }
    }
    order = rest;
  }
  return kept;
}

std::vector<int> Range(int begin, int end) {
  std::vector<int> v(end - begin);
  std::iota(v.begin(), v.end(), begin);
  return v;
}

std::vector<int> Sorted(std::vector<int> v) {
  std::sort(v.begin(), v.end());
  return v;
}

// nx * ny * nz grid with the given spacing, starting at `origin`.
Points Grid(const Eigen::Vector3f& origin, int nx, int ny, int nz, float spacing) {
  Points p;
  for (int x = 0; x < nx; ++x) {
    for (int y = 0; y < ny; ++y) {
      for (int z = 0; z < nz; ++z) p.push_back(origin + spacing * Eigen::Vector3f(x, y, z));
    }
  }
  return p;
}

TEST(ClusterBfs, TwoSeparatedBlobsInterleavedIndices) {
  // Even indices: blob A at the origin; odd indices: blob B one metre away.
  const Points a = Grid({0, 0, 0}, 4, 3, 2, 0.01f);
  const Points b = Grid({1, 0, 0}, 4, 3, 2, 0.01f);
  Points points;
  for (std::size_t i = 0; i < a.size(); ++i) {
    points.push_back(a[i]);
    points.push_back(b[i]);
  }
  const std::vector<int> labels(points.size(), 3);
  const Clusters c = BfsClusters(points, labels, 0.03, 10);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].front(), 0);  // seed order
  EXPECT_EQ(c[1].front(), 1);
  std::vector<int> even, odd;
  for (int i = 0; i < 48; i += 2) {
    even.push_back(i);
    odd.push_back(i + 1);
  }
  EXPECT_EQ(Sorted(c[0]), even);
  EXPECT_EQ(Sorted(c[1]), odd);
  EXPECT_EQ(c, ReferenceBfs(points, labels, 0.03, 10, 1000));
}

TEST(ClusterBfs, ChainSpacingJustBelowAndAboveRadius) {
  auto chain = [](float spacing) {
    Points p;
    for (int i = 0; i < 12; ++i) p.emplace_back(i * spacing, 0.f, 0.f);
    return p;
  };
  const std::vector<int> labels(12, 0);
  const Clusters below = BfsClusters(chain(0.0299f), labels, 0.03, 1);
  ASSERT_EQ(below.size(), 1u);
  EXPECT_EQ(below[0], Range(0, 12));  // a chain is visited in order
  const Clusters above = BfsClusters(chain(0.0301f), labels, 0.03, 1);
  ASSERT_EQ(above.size(), 12u);
  for (int i = 0; i < 12; ++i) EXPECT_EQ(above[i], std::vector<int>{i});
  EXPECT_TRUE(BfsClusters(chain(0.0301f), labels, 0.03, 2).empty());
}

TEST(ClusterBfs, DistanceEqualToRadiusDoesNotLink) {
  // 0.5 and 0.25 are exact in binary: d^2 == r^2 exactly, and `<` is strict.
  const Points exact = {{0, 0, 0}, {0.5f, 0, 0}, {1.0f, 0, 0}};
  const std::vector<int> labels(3, 1);
  const Clusters c = BfsClusters(exact, labels, 0.5, 1);
  EXPECT_EQ(c, (Clusters{{0}, {1}, {2}}));
  const Points inside = {{0, 0, 0}, {0.4999f, 0, 0}, {0.9998f, 0, 0}};
  EXPECT_EQ(BfsClusters(inside, labels, 0.5, 1), (Clusters{{0, 1, 2}}));
  // The same on a diagonal: (0.3, 0.4) has length 0.5 but is not exact in float.
  const Points diag = {{0, 0, 0}, {0, 0.3f, 0.4f}};
  EXPECT_EQ(BfsClusters(diag, {1, 1}, 0.5, 1), ReferenceBfs(diag, {1, 1}, 0.5, 1, 1000));
}

TEST(ClusterBfs, VisitsInBreadthFirstOrder) {
  // Chain x = 0, 0.6, 0.2, 0.4 (indices 0..3), r = 0.25: BFS from 0 goes 0, 2, 3, 1.
  const Points chain = {{0, 0, 0}, {0.6f, 0, 0}, {0.2f, 0, 0}, {0.4f, 0, 0}};
  EXPECT_EQ(BfsClusters(chain, {0, 0, 0, 0}, 0.25, 1), (Clusters{{0, 2, 3, 1}}));
  // Star around index 2: its neighbours are pushed in index order; then the far leaf.
  const Points star = {{0.2f, 0, 0}, {0, 0.2f, 0}, {0, 0, 0}, {-0.2f, 0, 0}, {0.4f, 0, 0}};
  EXPECT_EQ(BfsClusters(star, {0, 0, 0, 0, 0}, 0.25, 1), (Clusters{{0, 2, 4, 1, 3}}));
}

TEST(ClusterBfs, OnlySameLabelNeighboursLink) {
  // Two touching 3x3x3 blobs (face gap 0.01 < r) of different labels stay apart.
  Points points = Grid({0, 0, 0}, 3, 3, 3, 0.01f);
  const Points right = Grid({0.03f, 0, 0}, 3, 3, 3, 0.01f);
  points.insert(points.end(), right.begin(), right.end());
  std::vector<int> labels(54, 4);
  std::fill(labels.begin() + 27, labels.end(), 6);
  const Clusters c = BfsClusters(points, labels, 0.03, 10);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(Sorted(c[0]), Range(0, 27));
  EXPECT_EQ(Sorted(c[1]), Range(27, 54));
  // Same label: one cluster.
  const Clusters merged = BfsClusters(points, std::vector<int>(54, 4), 0.03, 10);
  ASSERT_EQ(merged.size(), 1u);
  EXPECT_EQ(Sorted(merged[0]), Range(0, 54));
}

TEST(ClusterBfs, MinPointsKeepsClustersOfAtLeastMinPoints) {
  Points points;
  for (int i = 0; i < 9; ++i) points.emplace_back(0.01f * i, 0.f, 0.f);
  for (int i = 0; i < 10; ++i) points.emplace_back(0.01f * i, 1.f, 0.f);
  const std::vector<int> labels(19, 0);
  EXPECT_EQ(BfsClusters(points, labels, 0.03, 10), (Clusters{Range(9, 19)}));
  EXPECT_EQ(BfsClusters(points, labels, 0.03, 9), (Clusters{Range(0, 9), Range(9, 19)}));
  EXPECT_TRUE(BfsClusters(points, labels, 0.03, 11).empty());
}

TEST(ClusterBfs, NegativeLabelsAreSkippedAndDoNotBridge) {
  Points points;
  for (int i = 0; i < 9; ++i) points.emplace_back(0.02f * i, 0.f, 0.f);
  std::vector<int> labels(9, 2);
  labels[4] = -1;  // the middle point: the chain breaks in two
  const Clusters c = BfsClusters(points, labels, 0.03, 1);
  EXPECT_EQ(c, (Clusters{{0, 1, 2, 3}, {5, 6, 7, 8}}));
  // All unlabelled: nothing; non-finite coordinates of unlabelled points are ignored.
  points[4] = Eigen::Vector3f::Constant(std::nanf(""));
  EXPECT_EQ(BfsClusters(points, labels, 0.03, 1), c);
  EXPECT_TRUE(BfsClusters(points, std::vector<int>(9, -1), 0.03, 1).empty());
}

TEST(ClusterBfs, NeighbourCapCountsLabelledPointsInIndexOrder) {
  // Index 0 and 3 share label 0, 1 and 2 have label 1; all four are within r of each other.
  // With cap 3 the lists of 0 and 3 are [0, 1, 2]: the 0 - 3 edge disappears.
  const Points points = {{0, 0, 0}, {0.01f, 0, 0}, {0.02f, 0, 0}, {0.025f, 0, 0}};
  const std::vector<int> labels = {0, 1, 1, 0};
  EXPECT_EQ(BfsClusters(points, labels, 0.03, 1, 4), (Clusters{{0, 3}, {1, 2}}));
  EXPECT_EQ(BfsClusters(points, labels, 0.03, 1, 3), (Clusters{{0}, {1, 2}, {3}}));
  // Unlabelled points do not count towards the cap (the reference queries CAD points only).
  const Points with_gap = {{0, 0, 0}, {0.005f, 0, 0}, {0.01f, 0, 0}, {0.02f, 0, 0}, {0.025f, 0, 0}};
  EXPECT_EQ(BfsClusters(with_gap, {0, -1, 1, 1, 0}, 0.03, 1, 3), (Clusters{{0}, {2, 3}, {4}}));

  // A dense cluster: 30 points in a 1 cm cube, cap 1. Every list is [lowest index], so only
  // point 0 links to itself: 30 singletons. Cap 2: j links to the lowest other index (0 for
  // everyone but 0, which links to 1): BFS from 0 reaches 1 only; then every other point
  // is a singleton since its partner 0 is visited.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 0.01f);
  Points dense;
  for (int i = 0; i < 30; ++i) dense.emplace_back(u(rng), u(rng), u(rng));
  const std::vector<int> same(30, 5);
  EXPECT_EQ(BfsClusters(dense, same, 0.03, 1, 1).size(), 30u);
  const Clusters cap2 = BfsClusters(dense, same, 0.03, 1, 2);
  ASSERT_EQ(cap2.size(), 29u);
  EXPECT_EQ(cap2[0], (std::vector<int>{0, 1}));
  EXPECT_EQ(cap2[1], std::vector<int>{2});
  const Clusters full = BfsClusters(dense, same, 0.03, 1);
  ASSERT_EQ(full.size(), 1u);
  EXPECT_EQ(full[0], Range(0, 30));
  for (int cap : {1, 2, 3, 7, 1000}) {
    EXPECT_EQ(BfsClusters(dense, same, 0.03, 1, cap), ReferenceBfs(dense, same, 0.03, 1, cap))
        << "cap " << cap;
  }
}

TEST(ClusterBfs, MatchesBruteForceReferenceOnRandomInputs) {
  std::mt19937 rng(42);
  int compared_clusters = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int n = 300 + 150 * (trial % 8);
    Points points;
    std::uniform_real_distribution<float> u(-0.15f, 0.15f);
    std::uniform_int_distribution<int> cell(-8, 8);
    for (int i = 0; i < n; ++i) {
      if (trial % 3 == 2) {
        // Exact multiples of r: every grid neighbour sits at d == r (float) from its cell.
        points.emplace_back(cell(rng) * 0.03f, cell(rng) * 0.03f, cell(rng) * 0.03f);
      } else {
        points.emplace_back(u(rng), u(rng), u(rng));
      }
    }
    std::uniform_int_distribution<int> lab(-1, 2);
    std::vector<int> labels(n);
    for (int& l : labels) l = lab(rng);
    const double radius = std::array<double, 3>{0.01, 0.03, 0.05}[trial % 3];
    const int cap = std::array<int, 4>{1000, 8, 3, 1}[trial % 4];
    const int min_points = trial % 2 == 0 ? 1 : 5;
    const bool before = SetClusteringAvx2(trial % 2 == 0);  // both SIMD paths
    const Clusters got = BfsClusters(points, labels, radius, min_points, cap);
    SetClusteringAvx2(before);
    const Clusters want = ReferenceBfs(points, labels, radius, min_points, cap);
    ASSERT_EQ(got, want) << "trial " << trial << " r " << radius << " cap " << cap;
    compared_clusters += static_cast<int>(got.size());
  }
  EXPECT_GT(compared_clusters, 500);
}

TEST(ClusterBfs, PairsJustInsideTheRadiusAcrossCellBoundaries) {
  // Pairs at distance r * (1 - 1e-6 .. 1e-4), axis-aligned and diagonal, whose first point
  // sits just below a multiple of r (where a voxel-hash boundary lies): the hash must find
  // every pair (none may fall two cells apart). Each pair has its own label, so the pairs can
  // overlap near the origin, where float rounding is far below the 1e-6 margin.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::uniform_int_distribution<int> cell(-3, 3);
  for (double radius : {0.01, 0.03, 0.05}) {
    Points points;
    std::vector<int> labels;
    for (int i = 0; i < 300; ++i) {
      Eigen::Vector3d dir = Eigen::Vector3d::Zero();
      Eigen::Vector3d p(u(rng), u(rng), u(rng));
      p *= radius;
      const double boundary = (cell(rng) - 0.01 * u(rng)) * radius;
      if (i % 4 == 3) {
        dir = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
        p.setConstant(boundary);
      } else {
        dir[i % 4] = (i / 4) % 2 == 0 ? 1.0 : -1.0;
        p[i % 4] = dir[i % 4] > 0 ? boundary : -boundary;
      }
      const double d = radius * (1.0 - 1e-6 - 1e-4 * u(rng));
      points.push_back(p.cast<float>());
      points.push_back((p + d * dir).cast<float>());
      labels.push_back(i);
      labels.push_back(i);
    }
    const Clusters want = ReferenceBfs(points, labels, radius, 2, 1000);
    const Clusters got = BfsClusters(points, labels, radius, 2);
    EXPECT_EQ(got, want) << radius;
    const bool before = SetClusteringAvx2(false);
    EXPECT_EQ(BfsClusters(points, labels, radius, 2), want) << radius << " sse2";
    SetClusteringAvx2(before);
    EXPECT_GT(got.size(), 290u) << radius;
  }
}

// Shifted-offset blobs as the card's passes see them: thousands of points of a few labels
// within a radius of each other, interleaved indices, so the cap binds and the labels compete
// for the neighbour slots. Every pass and cap must give the reference's clusters exactly.
TEST(ClusterBfs, DenseBlobsWithBindingCapMatchReference) {
  std::mt19937 rng(17);
  std::normal_distribution<float> g(0.f, 1.f);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Points points;
  std::vector<int> labels;
  const struct {
    float x, y, sigma;
    int label, count;
  } blobs[] = {{0.f, 0.f, 0.03f, 0, 1600},  {0.15f, 0.f, 0.05f, 1, 1200},
               {0.f, 0.2f, 0.08f, 0, 1000}, {0.6f, 0.6f, 0.02f, 2, 900},
               {0.7f, 0.62f, 0.1f, 3, 700}, {0.35f, 0.3f, 0.15f, 2, 600}};
  for (const auto& b : blobs) {
    for (int i = 0; i < b.count; ++i) {
      points.emplace_back(b.x + b.sigma * g(rng), b.y + b.sigma * g(rng), 0.3f + b.sigma * g(rng));
      labels.push_back(b.label);
    }
  }
  for (int i = 0; i < 300; ++i) {  // sparse background, some unlabelled
    points.emplace_back(1.2f * u(rng) - 0.2f, 1.2f * u(rng) - 0.2f, 0.6f * u(rng));
    labels.push_back(static_cast<int>(u(rng) * 5.f) - 1);
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
  int cap_binding = 0;
  for (double radius : {0.05, 0.12, 0.2, 0.3}) {
    const Clusters uncapped = ReferenceBfs(shuffled, shuffled_labels, radius, 1, 1 << 30);
    for (int cap : {500, 80}) {
      const Clusters want = ReferenceBfs(shuffled, shuffled_labels, radius, 1, cap);
      // Every SIMD path this CPU can run (the AVX2 one is skipped where there is none).
      for (bool avx2 : {true, false}) {
        const bool before = SetClusteringAvx2(avx2);
        const Clusters got = BfsClusters(shuffled, shuffled_labels, radius, 1, cap);
        SetClusteringAvx2(before);
        ASSERT_EQ(got, want) << "r " << radius << " cap " << cap << " avx2 " << avx2;
        cap_binding += got != uncapped ? 1 : 0;
      }
    }
  }
  EXPECT_GE(cap_binding, 12);  // the test exercises the cap, not only plain BFS
}

TEST(ClusterBfs, RejectsBadArguments) {
  const Points points = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(BfsClusters(points, {0}, 0.03, 1), InvalidArgument);
  EXPECT_THROW(BfsClusters(points, {0, 0}, 0.0, 1), InvalidArgument);
  EXPECT_THROW(BfsClusters(points, {0, 0}, std::nan(""), 1), InvalidArgument);
  EXPECT_THROW(BfsClusters(points, {0, 0}, 0.03, 0), InvalidArgument);
  EXPECT_THROW(BfsClusters(points, {0, 0}, 0.03, 1, 0), InvalidArgument);
  const Points bad = {{0, 0, 0}, {std::nanf(""), 0, 0}};
  EXPECT_THROW(BfsClusters(bad, {0, 0}, 0.03, 1), InvalidArgument);
  // Far beyond the 64-bit cell keys: an error, not an overflowed key.
  const Points far = {{0, 0, 0}, {0, 3e37f, 0}};
  EXPECT_THROW(BfsClusters(far, {0, 0}, 0.03, 1), InvalidArgument);
  EXPECT_NO_THROW(BfsClusters(far, {0, -1}, 0.03, 1));  // unlabelled points are not hashed
}

TEST(ClusterConfig, DefaultsTrainingAndValidate) {
  const ClusteringConfig test;
  ASSERT_EQ(test.passes.size(), 4u);
  const double radii[] = {0.03, 0.01, 0.03, 0.05};
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(test.passes[i].shifted, i > 0);
    EXPECT_EQ(test.passes[i].radius, radii[i]);
  }
  EXPECT_EQ(test.min_points, 10);
  EXPECT_EQ(test.max_neighbours, 1000);
  const ClusteringConfig train = ClusteringConfig::Training();
  ASSERT_EQ(train.passes.size(), 2u);
  EXPECT_FALSE(train.passes[0].shifted);
  EXPECT_TRUE(train.passes[1].shifted);
  EXPECT_EQ(train.passes[0].radius, 0.03);
  EXPECT_EQ(train.passes[1].radius, 0.03);
  EXPECT_NO_THROW(test.Validate());

  auto message = [](const ClusteringConfig& c) {
    try {
      c.Validate();
    } catch (const InvalidArgument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  ClusteringConfig c;
  c.passes[2].radius = -1;
  EXPECT_NE(message(c).find("passes[2].radius"), std::string::npos);
  c = ClusteringConfig();
  c.min_points = 0;
  EXPECT_NE(message(c).find("min_points"), std::string::npos);
  c = ClusteringConfig();
  c.max_neighbours = 0;
  EXPECT_NE(message(c).find("max_neighbours"), std::string::npos);
  c = ClusteringConfig();
  c.passes.clear();
  EXPECT_NE(message(c).find("passes"), std::string::npos);
}

TEST(ClusterMultiScale, PassOrderAndShiftedCoordinates) {
  // Object A (indices 0..11): points 0.1 m apart with perfect offsets to their centre, so
  // only the shifted passes find it. Object B (12..23): compact (0.02 m spacing) with zero
  // offsets, so every pass with r > 0.02 finds it and r = 0.01 does not.
  Points points;
  Points offsets;
  const Eigen::Vector3f centre(0.55f, 0.f, 0.f);
  for (int i = 0; i < 12; ++i) {
    points.emplace_back(0.1f * i, 0.f, 0.f);
    offsets.push_back(centre - points.back());
  }
  for (int i = 0; i < 12; ++i) {
    points.emplace_back(0.02f * i, 2.f, 0.f);
    offsets.emplace_back(0.f, 0.f, 0.f);
  }
  std::vector<int> labels(24, 1);
  std::fill(labels.begin() + 12, labels.end(), 7);
  const std::vector<Proposal> props = MultiScaleClusters(points, offsets, labels, {});
  ASSERT_EQ(props.size(), 6u);
  const int want_pass[] = {0, 1, 2, 2, 3, 3};
  const bool want_a[] = {false, true, true, false, true, false};
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(props[i].pass, want_pass[i]) << i;
    EXPECT_EQ(props[i].label, want_a[i] ? 1 : 7) << i;
    EXPECT_EQ(Sorted(props[i].points), want_a[i] ? Range(0, 12) : Range(12, 24)) << i;
    EXPECT_EQ(props[i].score, 0.0);
  }
  // The training config: original then shifted at 0.03.
  const std::vector<Proposal> train =
      MultiScaleClusters(points, offsets, labels, ClusteringConfig::Training());
  ASSERT_EQ(train.size(), 3u);
  EXPECT_EQ(train[0].label, 7);
  EXPECT_EQ(train[1].label, 1);
  EXPECT_EQ(train[2].label, 7);
  EXPECT_EQ(train[0].pass, 0);
  EXPECT_EQ(train[1].pass, 1);
  // Offsets are only needed by shifted passes.
  ClusteringConfig original_only;
  original_only.passes = {{false, 0.03}};
  EXPECT_EQ(MultiScaleClusters(points, {}, labels, original_only).size(), 1u);
  EXPECT_THROW(MultiScaleClusters(points, {}, labels, {}), InvalidArgument);
}

Proposal Make(std::vector<int> points, double score) {
  Proposal p;
  p.points = std::move(points);
  p.score = score;
  return p;
}

TEST(PointIouNms, ThresholdIsStrictAndOrderIsByScore) {
  // A = [0, 100). B1 = 31 of A's points (IoU 0.31 -> dropped), B2 = 30 (IoU 0.30 -> kept,
  // not > 0.3), B3 = 29 (0.29 -> kept). The B's are disjoint.
  std::vector<Proposal> p = {Make(Range(31, 61), 0.5), Make(Range(0, 31), 0.8),
                             Make(Range(61, 90), 0.7), Make(Range(0, 100), 0.9)};
  EXPECT_DOUBLE_EQ(PointIou(p[3].points, p[1].points), 0.31);
  EXPECT_DOUBLE_EQ(PointIou(p[3].points, p[0].points), 0.30);
  EXPECT_EQ(PointIouNms(p, 0.3), (std::vector<int>{3, 2, 0}));
  // A higher threshold keeps all, in score order.
  EXPECT_EQ(PointIouNms(p, 0.31), (std::vector<int>{3, 1, 2, 0}));
  // Without A the three are disjoint.
  p[3].score = 0.1;
  p[3].points = Range(500, 600);
  EXPECT_EQ(PointIouNms(p, 0.3), (std::vector<int>{1, 2, 0, 3}));
}

TEST(PointIouNms, SuppressedProposalsDoNotSuppressAndTiesAreStable) {
  // A (0.9) suppresses B (0.8); B would suppress C (0.7) but is gone, and C barely touches A.
  const std::vector<Proposal> chain = {Make(Range(100, 200), 0.7), Make(Range(40, 140), 0.8),
                                       Make(Range(0, 100), 0.9)};
  EXPECT_EQ(PointIouNms(chain, 0.3), (std::vector<int>{2, 0}));
  // Identical proposals with equal scores: the first index wins.
  const std::vector<Proposal> twins = {Make(Range(0, 50), 0.4), Make(Range(0, 50), 0.6),
                                       Make(Range(0, 50), 0.6)};
  EXPECT_EQ(PointIouNms(twins, 0.3), std::vector<int>{1});
  EXPECT_TRUE(PointIouNms({}, 0.3).empty());
  EXPECT_THROW(PointIouNms({Make({1, 2, 1}, 0.5)}, 0.3), InvalidArgument);
  EXPECT_THROW(PointIouNms({Make({-1}, 0.5)}, 0.3), InvalidArgument);
  EXPECT_THROW(PointIouNms({Make({1}, std::nan(""))}, 0.3), InvalidArgument);
}

TEST(PointIouNms, MatchesBruteForceOnRandomProposalsAndIsFast) {
  std::mt19937 rng(7);
  // 1000 proposals over 100k points: random windows of a shuffled order, so that many
  // overlap partially.
  const int num_points = 100000;
  std::vector<int> perm = Range(0, num_points);
  std::shuffle(perm.begin(), perm.end(), rng);
  std::uniform_int_distribution<int> start(0, num_points - 3000);
  std::uniform_int_distribution<int> len(100, 3000);
  std::uniform_real_distribution<double> score(0.0, 1.0);
  std::vector<Proposal> proposals;
  for (int i = 0; i < 1000; ++i) {
    const int s = start(rng) / 50;  // concentrate starts to get overlaps
    proposals.push_back(Make({perm.begin() + s, perm.begin() + s + len(rng)}, score(rng)));
  }
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<int> kept = PointIouNms(proposals, 0.3);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ timing   ] PointIouNms: 1000 proposals over 100k points, %zu kept: %.1f ms\n",
              kept.size(), ms);
  EXPECT_GT(kept.size(), 5u);
  EXPECT_LT(kept.size(), 900u);
  // Brute force on a subset (the full O(P^2 N) reference is too slow for a unit test).
  proposals.resize(200);
  EXPECT_EQ(PointIouNms(proposals, 0.3), ReferenceNms(proposals, 0.3));
}

// Per-point rows: probabilities `prob` (12) and residuals `res` (12).
struct HeadingRows {
  std::vector<float> prob, res;
  void Add(std::vector<float> p, std::vector<float> r) {
    prob.insert(prob.end(), p.begin(), p.end());
    res.insert(res.end(), r.begin(), r.end());
  }
};

std::vector<float> Bins(std::initializer_list<std::pair<int, float>> values, float rest = 0.f) {
  std::vector<float> v(12, rest);
  for (const auto& [k, x] : values) v[k] = x;
  return v;
}

TEST(ClusterHeading, ArgmaxOfMeanProbabilityPlusMeanResidual) {
  HeadingRows rows;
  // Point 0 prefers bin 1 (0.6 vs 0.4), point 1 prefers bin 2; the mean prefers bin 2
  // (0.45 vs 0.35). Residuals of bin 2: 0.2 and -0.6 -> mean -0.2; other bins are decoys.
  rows.Add(Bins({{1, 0.6f}, {2, 0.4f}}), Bins({{2, 0.2f}}, 0.9f));
  rows.Add(Bins({{1, 0.1f}, {2, 0.5f}, {5, 0.4f}}), Bins({{2, -0.6f}}, -0.9f));
  // A decoy point (index 2) that is not part of the proposal.
  rows.Add(Bins({{7, 1.f}}), Bins({}, 0.f));
  EXPECT_NEAR(ProposalHeading({0, 1}, rows.prob, rows.res), 2 * kPi / 6 - 0.2 * kPi / 12, 1e-6);
  EXPECT_NEAR(ProposalHeading({0}, rows.prob, rows.res), kPi / 6 + 0.9 * kPi / 12, 1e-6);
  EXPECT_NEAR(ProposalHeading({2}, rows.prob, rows.res), 7 * kPi / 6 - 2 * kPi, 1e-6);
  EXPECT_THROW(ProposalHeading({}, rows.prob, rows.res), InvalidArgument);
  EXPECT_THROW(ProposalHeading({3}, rows.prob, rows.res), InvalidArgument);
  EXPECT_THROW(ProposalHeading({0}, rows.prob, {}), InvalidArgument);
  // Shared rows (per-voxel tables): points 0..3 read rows 1, 0, 1, 2 - the proposal {0, 1, 2}
  // is rows {1, 0, 1}: bin 2 wins ((0.5 + 0.4 + 0.5) / 3 against 0.8 / 3 at bins 1 and 5), its
  // residual the mean of -0.6, 0.2, -0.6.
  const std::vector<std::int64_t> point_row = {1, 0, 1, 2};
  EXPECT_NEAR(ProposalHeading({0, 1, 2}, rows.prob, rows.res, point_row),
              2 * kPi / 6 + (-0.6 + 0.2 - 0.6) / 3 * kPi / 12, 1e-6);
  EXPECT_NEAR(ProposalHeading({3}, rows.prob, rows.res, point_row), 7 * kPi / 6 - 2 * kPi, 1e-6);
  EXPECT_THROW(ProposalHeading({4}, rows.prob, rows.res, point_row), InvalidArgument);
  EXPECT_THROW(ProposalHeading({0}, rows.prob, rows.res, {3}), InvalidArgument);  // row 3 of 3
}

TEST(ClusterHeading, WrapsToMinusPiPi) {
  HeadingRows rows;
  rows.Add(Bins({{11, 1.f}}), Bins({{11, 0.5f}}));  // 330 + 7.5 deg -> -22.5 deg
  rows.Add(Bins({{6, 1.f}}), Bins({{6, 0.2f}}));    // 180 + 3 deg -> -177 deg
  rows.Add(Bins({{6, 1.f}}), Bins({{6, -0.2f}}));   // 177 deg
  rows.Add(Bins({{0, 1.f}}), Bins({{0, -0.5f}}));   // -7.5 deg
  rows.Add(Bins({{6, 1.f}}), Bins({{6, 0.f}}));     // exactly 180 deg
  EXPECT_NEAR(ProposalHeading({0}, rows.prob, rows.res), -kPi / 8, 1e-6);
  EXPECT_NEAR(ProposalHeading({1}, rows.prob, rows.res), -kPi + 0.2 * kPi / 12, 1e-6);
  EXPECT_NEAR(ProposalHeading({2}, rows.prob, rows.res), kPi - 0.2 * kPi / 12, 1e-6);
  EXPECT_NEAR(ProposalHeading({3}, rows.prob, rows.res), -kPi / 24, 1e-6);
  const double h = ProposalHeading({4}, rows.prob, rows.res);
  EXPECT_NEAR(std::abs(h), kPi, 1e-12);
  EXPECT_GT(h, -kPi);
  EXPECT_LE(h, kPi);
}

// A scene of four boxes (three large, one of exactly 100 points) and an unlabelled floor,
// stored in a shuffled point order; perfect offsets; toy 25-class table in which RFS classes
// 4 and 10 both map to CAD 2, RFS 7 to CAD 5, RFS 3 to CAD 1.
TEST(Stage1Instances, ThreeObjectsWithPerfectOffsets) {
  struct Object {
    Eigen::Vector3f origin;
    int nx, ny, nz;
    int cad;
    std::vector<std::pair<int, float>> sem;  // RFS class probabilities
    int bin;
    float residual;
  };
  const std::vector<Object> objects = {
      {{0.f, 0.f, 0.f}, 8, 8, 4, 2, {{4, 0.5f}, {10, 0.2f}, {0, 0.3f}}, 3, 0.25f},
      {{1.5f, 0.f, 0.f}, 6, 6, 6, 5, {{7, 0.9f}, {0, 0.1f}}, 11, 0.5f},
      {{0.f, 1.5f, 0.f}, 10, 5, 3, 2, {{4, 0.6f}, {1, 0.4f}}, 6, 0.4f},
      {{1.5f, 1.5f, 0.f}, 5, 5, 4, 1, {{3, 1.f}}, 0, 0.f},  // 100 points: not > 100
  };
  std::vector<int> rfs_to_cad(25, -1);
  for (int c = 2; c < 10; ++c) rfs_to_cad[c] = c - 2;
  rfs_to_cad[10] = 2;

  struct Row {
    Eigen::Vector3f p, o;
    int cad, object;
    std::vector<float> sem, prob, res;
  };
  std::vector<Row> rows;
  for (int k = 0; k < static_cast<int>(objects.size()); ++k) {
    const Object& ob = objects[k];
    const Points pts = Grid(ob.origin, ob.nx, ob.ny, ob.nz, 0.02f);
    const Eigen::Vector3f centre =
        ob.origin + 0.01f * Eigen::Vector3f(ob.nx - 1, ob.ny - 1, ob.nz - 1);
    std::vector<float> sem(25, 0.f);
    for (const auto& [c, p] : ob.sem) sem[c] = p;
    for (const auto& p : pts) {
      rows.push_back({p, centre - p, ob.cad, k, sem, Bins({{ob.bin, 0.7f}}, 0.3f / 11),
                      Bins({{ob.bin, ob.residual}}, -0.9f)});
    }
  }
  for (int i = 0; i < 400; ++i) {  // floor below the objects, far enough (z = -0.1)
    std::vector<float> sem(25, 0.f);
    sem[1] = 1.f;
    rows.push_back({Eigen::Vector3f(0.05f * (i % 20), 0.05f * (i / 20), -0.1f),
                    Eigen::Vector3f::Zero(), -1, -1, sem, Bins({}, 1.f / 12), Bins({})});
  }
  std::mt19937 rng(11);
  std::shuffle(rows.begin(), rows.end(), rng);
  Points points, offsets;
  std::vector<int> cad;
  std::vector<float> sem, prob, res;
  std::vector<std::vector<int>> members(objects.size());
  for (int i = 0; i < static_cast<int>(rows.size()); ++i) {
    points.push_back(rows[i].p);
    offsets.push_back(rows[i].o);
    cad.push_back(rows[i].cad);
    sem.insert(sem.end(), rows[i].sem.begin(), rows[i].sem.end());
    prob.insert(prob.end(), rows[i].prob.begin(), rows[i].prob.end());
    res.insert(res.end(), rows[i].res.begin(), rows[i].res.end());
    if (rows[i].object >= 0) members[rows[i].object].push_back(i);
  }

  const std::vector<ScoredInstance> out =
      ExtractStage1Instances(points, offsets, cad, sem, prob, res, rfs_to_cad, {});
  ASSERT_EQ(out.size(), 3u);
  // Score order: object 1 (0.9), object 0 (0.5 + 0.2), object 2 (0.6).
  const int want_object[] = {1, 0, 2};
  const double want_score[] = {0.9, 0.7, 0.6};
  const double want_heading[] = {-kPi / 8, kPi / 2 + 0.25 * kPi / 12, -kPi + 0.4 * kPi / 12};
  for (int i = 0; i < 3; ++i) {
    const int k = want_object[i];
    EXPECT_EQ(out[i].cad_class, objects[k].cad) << i;
    EXPECT_EQ(Sorted(out[i].points), members[k]) << i;
    EXPECT_NEAR(out[i].score, want_score[i], 1e-6) << i;
    EXPECT_NEAR(out[i].heading, want_heading[i], 1e-6) << i;
  }

  // min_points 99 keeps the 100-point object too (strict >), score 1.
  Stage1InstanceConfig loose;
  loose.min_points = 99;
  const auto with_small =
      ExtractStage1Instances(points, offsets, cad, sem, prob, res, rfs_to_cad, loose);
  ASSERT_EQ(with_small.size(), 4u);
  EXPECT_EQ(with_small[0].cad_class, 1);
  EXPECT_EQ(Sorted(with_small[0].points), members[3]);

  // Every pass's proposals before the size filter and NMS (stage-2 training samples): each of
  // the 4 objects once per pass (exact offsets), with its score; the instances above are among
  // them with the same score and heading.
  const ClusteringConfig passes;
  const std::vector<ScoredInstance> all =
      ScoredStage1Proposals(points, offsets, cad, sem, prob, res, rfs_to_cad, passes);
  ASSERT_EQ(all.size(), objects.size() * passes.passes.size());
  const double score_of[] = {0.7, 0.9, 0.6, 1.0};
  std::vector<int> per_object(objects.size(), 0);
  for (const auto& p : all) {
    int k = -1;
    for (int j = 0; j < static_cast<int>(members.size()); ++j) {
      if (Sorted(p.points) == members[j]) k = j;
    }
    ASSERT_GE(k, 0);
    ++per_object[k];
    EXPECT_EQ(p.cad_class, objects[k].cad) << k;
    EXPECT_NEAR(p.score, score_of[k], 1e-6) << k;
  }
  for (int count : per_object) EXPECT_EQ(count, static_cast<int>(passes.passes.size()));
  for (const auto& inst : out) {
    bool found = false;
    for (const auto& p : all) {
      if (p.points != inst.points) continue;
      found = true;
      EXPECT_EQ(p.score, inst.score);
      EXPECT_EQ(p.heading, inst.heading);
    }
    EXPECT_TRUE(found);
  }
  EXPECT_THROW(ScoredStage1Proposals(points, offsets, cad, sem, prob, res, {0, 1}, passes),
               InvalidArgument);

  // Bad inputs.
  std::vector<int> bad_cad = cad;
  bad_cad[5] = 8;
  EXPECT_THROW(ExtractStage1Instances(points, offsets, bad_cad, sem, prob, res, rfs_to_cad, {}),
               InvalidArgument);
  EXPECT_THROW(ExtractStage1Instances(points, offsets, cad, sem, prob, res, {0, 1}, {}),
               InvalidArgument);
  Stage1InstanceConfig bad;
  bad.nms_iou = 1.5;
  EXPECT_THROW(bad.Validate(), InvalidArgument);
}

// A 100k-point synthetic room: 40 boxes of ~2000 surface points with noisy offsets, plus an
// unlabelled floor. Prints the time of the four test-time passes (not asserted).
TEST(ClusterTiming, HundredThousandPointRoom) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::normal_distribution<float> noise(0.f, 0.01f);
  Points points, offsets;
  std::vector<int> labels;
  for (int b = 0; b < 40; ++b) {
    const Eigen::Vector3f centre(0.8f + 1.2f * (b % 8), 0.8f + 1.2f * (b / 8), 0.4f);
    const Eigen::Vector3f half(0.2f + 0.2f * u(rng), 0.2f + 0.2f * u(rng), 0.2f + 0.2f * u(rng));
    const int cad = b % 8;
    for (int i = 0; i < 2000; ++i) {
      Eigen::Vector3f q(2 * u(rng) - 1, 2 * u(rng) - 1, 2 * u(rng) - 1);
      const int axis = i % 3;
      q[axis] = q[axis] < 0 ? -1.f : 1.f;  // on a face
      const Eigen::Vector3f p = centre + q.cwiseProduct(half);
      points.push_back(p);
      offsets.push_back(centre - p + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)));
      labels.push_back(cad);
    }
  }
  while (points.size() < 100000) {
    points.emplace_back(10.f * u(rng), 6.f * u(rng), 0.f);
    offsets.emplace_back(0.f, 0.f, 0.f);
    labels.push_back(-1);
  }
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Proposal> props = MultiScaleClusters(points, offsets, labels, {});
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf(
      "[ timing   ] MultiScaleClusters: %zu points (80k labelled), 4 passes, %zu "
      "proposals: %.1f ms (%s)\n",
      points.size(), props.size(), ms, ClusteringSimdPath());
  EXPECT_GE(props.size(), 40u);
}

}  // namespace
}  // namespace dimr::pipeline
