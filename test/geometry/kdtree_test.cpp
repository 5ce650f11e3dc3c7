#include "dimr/geometry/kdtree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// 10k points: uniform in [-1,1]^3, with 500 exact duplicates of earlier points and 200
// points on a coarse grid (many equal coordinates and equal distances).
std::vector<Vec3> RandomPoints(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> pts;
  pts.reserve(n);
  for (int i = 0; i < n; ++i) {
    if (i >= 1000 && i % 20 == 0) {
      pts.push_back(pts[rng() % pts.size()]);  // duplicate
    } else if (i % 50 == 1) {
      pts.emplace_back((rng() % 5) * 0.25, (rng() % 5) * 0.25, (rng() % 5) * 0.25);
    } else {
      pts.emplace_back(u(rng), u(rng), u(rng));
    }
  }
  return pts;
}

std::vector<std::pair<int, double>> BruteSorted(const std::vector<Vec3>& pts, const Vec3& q) {
  std::vector<std::pair<int, double>> all;
  for (int i = 0; i < static_cast<int>(pts.size()); ++i) {
    all.emplace_back(i, (pts[i] - q).squaredNorm());
  }
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.second < b.second || (a.second == b.second && a.first < b.first);
  });
  return all;
}

std::vector<Vec3> Queries(std::mt19937& rng, const std::vector<Vec3>& pts, int n) {
  std::uniform_real_distribution<double> u(-1.3, 1.3);
  std::vector<Vec3> q;
  for (int i = 0; i < n; ++i) {
    if (i % 10 == 0) {
      q.push_back(pts[rng() % pts.size()]);  // exactly on a data point
    } else {
      q.emplace_back(u(rng), u(rng), u(rng));
    }
  }
  return q;
}

TEST(KdTree, EmptyTree) {
  KdTree empty;
  const auto nn = empty.Nearest(Vec3(1, 2, 3));
  EXPECT_EQ(nn.first, -1);
  EXPECT_EQ(nn.second, kInf);
  EXPECT_TRUE(empty.KNearest(Vec3::Zero(), 3).empty());
  EXPECT_TRUE(empty.RadiusSearch(Vec3::Zero(), 10.0).empty());
  KdTree built(std::vector<Vec3>{});
  EXPECT_EQ(built.Nearest(Vec3::Zero()).first, -1);
  const auto d = NearestDistances({Vec3::Zero(), Vec3::Ones()}, built);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0], kInf);
  EXPECT_EQ(d[1], kInf);
}

TEST(KdTree, RejectsBadInput) {
  EXPECT_THROW(KdTree({Vec3::Zero()}, 0), InvalidArgument);
  EXPECT_THROW(KdTree({Vec3::Zero(), Vec3(std::nan(""), 0, 0)}), InvalidArgument);
  EXPECT_THROW(KdTree({Vec3(kInf, 0, 0)}), InvalidArgument);
}

TEST(KdTree, SmallHandChecked) {
  // Points on the x axis at 0, 1, 2, ..., 39 (forces several levels with leaf_size 2).
  std::vector<Vec3> pts;
  for (int i = 0; i < 40; ++i) pts.emplace_back(i, 0, 0);
  KdTree tree(pts, 2);
  auto nn = tree.Nearest(Vec3(17.3, 1, 0));
  EXPECT_EQ(nn.first, 17);
  EXPECT_DOUBLE_EQ(nn.second, 0.3 * 0.3 + 1.0);
  // Exactly halfway between 4 and 5: the smaller index wins.
  nn = tree.Nearest(Vec3(4.5, 0, 0));
  EXPECT_EQ(nn.first, 4);
  EXPECT_DOUBLE_EQ(nn.second, 0.25);
  const auto knn = tree.KNearest(Vec3(10.25, 0, 0), 4);
  ASSERT_EQ(knn.size(), 4u);
  EXPECT_EQ(knn[0].first, 10);
  EXPECT_EQ(knn[1].first, 11);
  EXPECT_EQ(knn[2].first, 9);
  EXPECT_EQ(knn[3].first, 12);
  EXPECT_DOUBLE_EQ(knn[3].second, 1.75 * 1.75);
  // Radius 2 around 20: 19, 20, 21 (18 and 22 are exactly at distance 2: excluded).
  EXPECT_EQ(tree.RadiusSearch(Vec3(20, 0, 0), 2.0), (std::vector<int>{19, 20, 21}));
  EXPECT_EQ(tree.RadiusSearch(Vec3(20, 0, 0), 2.0000001), (std::vector<int>{18, 19, 20, 21, 22}));
  EXPECT_TRUE(tree.RadiusSearch(Vec3(20, 0, 0), 0.0).empty());
  EXPECT_TRUE(tree.RadiusSearch(Vec3(20, 0, 0), -1.0).empty());
}

TEST(KdTree, AllIdenticalPoints) {
  std::vector<Vec3> pts(100, Vec3(0.5, 0.5, 0.5));
  KdTree tree(pts);
  const auto nn = tree.Nearest(Vec3(0.5, 0.5, 1.5));
  EXPECT_EQ(nn.first, 0);
  EXPECT_DOUBLE_EQ(nn.second, 1.0);
  const auto knn = tree.KNearest(Vec3::Zero(), 5);
  ASSERT_EQ(knn.size(), 5u);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(knn[i].first, i);
  EXPECT_EQ(tree.RadiusSearch(Vec3::Zero(), 1.0).size(), 100u);
}

TEST(KdTree, NearestMatchesBruteForce) {
  std::mt19937 rng(1234);
  const auto pts = RandomPoints(rng, 10000);
  KdTree tree(pts);
  ASSERT_EQ(tree.size(), pts.size());
  const auto queries = Queries(rng, pts, 2000);
  for (const Vec3& q : queries) {
    int bi = -1;
    double bd = kInf;
    for (int i = 0; i < static_cast<int>(pts.size()); ++i) {
      const double d = (pts[i] - q).squaredNorm();
      if (d < bd) {
        bd = d;
        bi = i;
      }
    }
    const auto nn = tree.Nearest(q);
    ASSERT_EQ(nn.first, bi);
    ASSERT_EQ(nn.second, bd);
  }
}

TEST(KdTree, KNearestMatchesBruteForce) {
  std::mt19937 rng(99);
  const auto pts = RandomPoints(rng, 10000);
  KdTree tree(pts);
  const auto queries = Queries(rng, pts, 300);
  const int ks[] = {1, 2, 7, 16, 50};
  for (std::size_t qi = 0; qi < queries.size(); ++qi) {
    const auto brute = BruteSorted(pts, queries[qi]);
    const int k = ks[qi % 5];
    const auto knn = tree.KNearest(queries[qi], k);
    ASSERT_EQ(knn.size(), static_cast<std::size_t>(k));
    for (int j = 0; j < k; ++j) {
      ASSERT_EQ(knn[j].first, brute[j].first) << "query " << qi << " rank " << j;
      ASSERT_EQ(knn[j].second, brute[j].second);
    }
  }
  // k > n returns every point, sorted.
  std::vector<Vec3> few(pts.begin(), pts.begin() + 37);
  KdTree small(few, 4);
  const auto all = small.KNearest(Vec3(0.1, 0.2, 0.3), 100);
  const auto brute = BruteSorted(few, Vec3(0.1, 0.2, 0.3));
  ASSERT_EQ(all.size(), 37u);
  for (int j = 0; j < 37; ++j) EXPECT_EQ(all[j].first, brute[j].first);
  EXPECT_TRUE(small.KNearest(Vec3::Zero(), 0).empty());
  EXPECT_TRUE(small.KNearest(Vec3::Zero(), -3).empty());
}

TEST(KdTree, RadiusSearchMatchesBruteForce) {
  std::mt19937 rng(7);
  const auto pts = RandomPoints(rng, 10000);
  KdTree tree(pts);
  const auto queries = Queries(rng, pts, 300);
  const double radii[] = {0.05, 0.1, 0.25, 0.6};
  std::size_t total = 0;
  for (std::size_t qi = 0; qi < queries.size(); ++qi) {
    const double r = radii[qi % 4];
    std::vector<int> brute;
    for (int i = 0; i < static_cast<int>(pts.size()); ++i) {
      if ((pts[i] - queries[qi]).squaredNorm() < r * r) brute.push_back(i);
    }
    const auto got = tree.RadiusSearch(queries[qi], r);
    ASSERT_EQ(got, brute) << "query " << qi;
    total += got.size();
  }
  EXPECT_GT(total, 10000u);  // the radii are not trivially small
  // Grid points exactly at the radius are excluded: around (0.25,0.25,0.25) with r = 0.25 the
  // six grid neighbours at distance exactly 0.25 must not appear.
  const Vec3 c(0.25, 0.25, 0.25);
  const auto got = tree.RadiusSearch(c, 0.25);
  for (int i : got) EXPECT_LT((pts[i] - c).squaredNorm(), 0.0625);
  int at_radius = 0;
  for (const Vec3& p : pts) at_radius += (p - c).squaredNorm() == 0.0625;
  EXPECT_GT(at_radius, 0);  // the data set really contains such points
}

TEST(KdTree, NearestDistancesParallel) {
  std::mt19937 rng(5);
  const auto pts = RandomPoints(rng, 5000);
  KdTree tree(pts);
  const auto queries = Queries(rng, pts, 20000);
  const auto d = NearestDistances(queries, tree);
  ASSERT_EQ(d.size(), queries.size());
  for (std::size_t i = 0; i < queries.size(); ++i) {
    ASSERT_EQ(d[i], std::sqrt(tree.Nearest(queries[i]).second));
    if (i % 10 == 0) {
      ASSERT_EQ(d[i], 0.0);  // query taken from the data
    }
  }
}

}  // namespace
}  // namespace dimr::geometry
