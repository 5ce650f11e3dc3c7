#include "dimr/eval/cloud_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "dimr/core/error.h"

namespace dimr::eval {
namespace {

using geometry::Vec3;

// An n x n grid of spacing h in the plane through the origin spanned by u, v, shifted by
// half a cell so that no point sits on a voxel boundary.
std::vector<Vec3> Grid(int n, double h, const Vec3& u, const Vec3& v, const Vec3& origin) {
  std::vector<Vec3> p;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) p.push_back(origin + (i + 0.5) * h * u + (j + 0.5) * h * v);
  return p;
}

TEST(CloudStats, RegularGridHasKnownSpacingNoVariationAndKnownDensity) {
  const std::vector<Vec3> pts = Grid(40, 0.01, Vec3::UnitX(), Vec3::UnitY(), Vec3::Zero());
  CloudStatsInput in;
  in.name = "grid";
  in.points = &pts;
  const CloudStats s = ComputeCloudStats(in);
  EXPECT_EQ(s.points, 1600u);
  EXPECT_NEAR(s.spacing_cm.p10, 1.0, 1e-9);
  EXPECT_NEAR(s.spacing_cm.p50, 1.0, 1e-9);
  EXPECT_NEAR(s.spacing_cm.p90, 1.0, 1e-9);
  EXPECT_LT(s.spacing_cv, 1e-9);
  EXPECT_LT(s.all.surface_variation.p90, 1e-12);  // a plane
  // 1 cm grid: 2 x 2 points per 2 cm voxel, 5 x 5 per 5 cm voxel (40 cells of 1 cm = 8 x 5 cm).
  ASSERT_EQ(s.points_per_voxel.size(), 2u);
  EXPECT_NEAR(s.points_per_voxel[0], 4.0, 1e-12);
  EXPECT_NEAR(s.points_per_voxel[1], 25.0, 1e-12);
  // Horizontal plane: every normal is vertical.
  EXPECT_EQ(s.all.normal_angle.counts[0], 1600);
  EXPECT_FALSE(s.has_colors);
  EXPECT_FALSE(s.has_labels);
}

TEST(CloudStats, IrregularSpacingHasPositiveCv) {
  // Rows alternately 1 cm and 3 cm apart along y, 1 cm along x: nn spacing is 1 cm everywhere
  // -> CV 0; clumps of two points 2 mm apart 4 cm from the next clump -> CV 0 too (all 2 mm).
  // A mix of both patterns is uneven: CV > 0.5.
  std::vector<Vec3> pts = Grid(20, 0.01, Vec3::UnitX(), Vec3::UnitY(), Vec3::Zero());
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      const Vec3 c(1.0 + 0.04 * i, 0.04 * j, 0.0);
      pts.push_back(c);
      pts.push_back(c + Vec3(0.002, 0, 0));
    }
  CloudStatsInput in;
  in.name = "mixed";
  in.points = &pts;
  const CloudStats s = ComputeCloudStats(in);
  EXPECT_NEAR(s.spacing_cm.p10, 0.2, 1e-9);
  EXPECT_NEAR(s.spacing_cm.p90, 1.0, 1e-9);
  // 400 points at 1 cm, 800 at 0.2 cm: mean 1.4 / 3, std 0.8 sqrt(2) / 3 -> CV 0.8 sqrt(2) / 1.4.
  EXPECT_NEAR(s.spacing_cv, 0.8 * std::sqrt(2.0) / 1.4, 1e-9);
}

TEST(CloudStats, NoiseRaisesSurfaceVariationAndTiltGivesItsAngle) {
  // Plane tilted by 35 degrees about x: every normal is 35 degrees from z.
  const double a = 35.0 * M_PI / 180.0;
  const std::vector<Vec3> tilted =
      Grid(30, 0.02, Vec3::UnitX(), Vec3(0, std::cos(a), std::sin(a)), Vec3::Zero());
  CloudStatsInput in;
  in.name = "tilted";
  in.points = &tilted;
  const CloudStats t = ComputeCloudStats(in);
  EXPECT_EQ(t.all.normal_angle.counts[3], 900);  // [30, 40) degrees
  EXPECT_LT(t.all.surface_variation.p90, 1e-12);

  // Isotropic uniform noise in a cube: lambda_0 / sum close to 1/3 at the median.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> cube;
  for (int i = 0; i < 4000; ++i) cube.emplace_back(u(rng), u(rng), u(rng));
  in.points = &cube;
  const CloudStats c = ComputeCloudStats(in);
  EXPECT_GT(c.all.surface_variation.p50, 0.15);
  EXPECT_LE(c.all.surface_variation.p90, 1.0 / 3.0 + 1e-12);

  // A plane with 1 mm of Gaussian noise at 2 cm spacing: small but clearly not 0, and more
  // noise -> more variation.
  auto noisy = [&](double sigma) {
    std::normal_distribution<double> g(0.0, sigma);
    std::vector<Vec3> p = Grid(40, 0.02, Vec3::UnitX(), Vec3::UnitY(), Vec3::Zero());
    for (auto& q : p) q.z() += g(rng);
    CloudStatsInput ni;
    ni.name = "noisy";
    ni.points = &p;
    return ComputeCloudStats(ni).all.surface_variation.p50;
  };
  const double s1 = noisy(0.001), s4 = noisy(0.004);
  EXPECT_GT(s1, 1e-4);
  EXPECT_GT(s4, 4.0 * s1);
}

TEST(CloudStats, ColoursLabelsAndObjects) {
  // A floor (label 1) and a wall (label 0), 2 instances, two colours half and half.
  std::vector<Vec3> pts = Grid(20, 0.02, Vec3::UnitX(), Vec3::UnitY(), Vec3::Zero());
  const std::vector<Vec3> wall = Grid(20, 0.02, Vec3::UnitX(), Vec3::UnitZ(), Vec3(0, -0.5, 0));
  pts.insert(pts.end(), wall.begin(), wall.end());
  std::vector<geometry::Color> colors(pts.size());
  std::vector<int> sem(pts.size()), inst(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    colors[i] = i % 2 ? geometry::Color(200, 100, 50) : geometry::Color(0, 0, 0);
    sem[i] = i < 400 ? 1 : 0;
    inst[i] = i < 400 ? 1 : (i < 700 ? 2 : 3);
  }
  CloudStatsInput in;
  in.name = "room";
  in.points = &pts;
  in.colors = &colors;
  in.semantic = &sem;
  in.instance = &inst;
  const CloudStats s = ComputeCloudStats(in);
  ASSERT_TRUE(s.has_colors);
  EXPECT_NEAR(s.color_std[0], 100.0, 1e-9);
  EXPECT_NEAR(s.color_std[1], 50.0, 1e-9);
  EXPECT_NEAR(s.color_std[2], 25.0, 1e-9);
  EXPECT_NEAR(s.color_mean[0], 100.0, 1e-9);
  EXPECT_EQ(s.color_hist[0].counts[0], 400);   // value 0
  EXPECT_EQ(s.color_hist[0].counts[12], 400);  // 200 / 16 = bin 12
  ASSERT_TRUE(s.has_labels);
  EXPECT_EQ(s.floor.points, 400u);
  EXPECT_EQ(s.wall.points, 400u);
  EXPECT_EQ(s.floor.normal_angle.counts[0], 400);
  EXPECT_EQ(s.wall.normal_angle.counts[8], 400);  // 90 degrees: the last bin
  ASSERT_EQ(s.objects.count("floor"), 1u);
  ASSERT_EQ(s.objects.count("wall"), 1u);
  EXPECT_EQ(s.objects.at("floor").counts, std::vector<int>({400}));
  EXPECT_EQ(s.objects.at("wall").counts, std::vector<int>({300, 100}));
  const std::string json = CloudStatsJson(s);
  EXPECT_NE(json.find("\"spacing_cv\""), std::string::npos);
  EXPECT_NE(CloudStatsMarkdown(s, "t").find("| colour std R / G / B | 100.0 / 50.0 / 25.0 |"),
            std::string::npos);
}

TEST(CloudStats, PoolsCloudsAndRejectsBadInput) {
  const std::vector<Vec3> a = Grid(10, 0.01, Vec3::UnitX(), Vec3::UnitY(), Vec3::Zero());
  const std::vector<Vec3> b = Grid(10, 0.03, Vec3::UnitX(), Vec3::UnitY(), Vec3::Zero());
  CloudStatsAccumulator acc;
  CloudStatsInput in;
  in.name = "a";
  in.points = &a;
  acc.Add(in);
  in.points = &b;
  acc.Add(in);
  const CloudStats s = acc.Finish();
  EXPECT_EQ(s.clouds, 2u);
  EXPECT_EQ(s.points, 200u);
  EXPECT_NEAR(s.spacing_cm.p10, 1.0, 1e-9);
  EXPECT_NEAR(s.spacing_cm.p90, 3.0, 1e-9);
  EXPECT_NEAR(s.spacing_cv, 0.5, 1e-9);  // mean 2, std 1

  std::vector<Vec3> few(5, Vec3::Zero());
  in.points = &few;
  EXPECT_THROW(acc.Add(in), InvalidArgument);
  std::vector<Vec3> nan = a;
  nan[3].x() = std::nan("");
  in.points = &nan;
  EXPECT_THROW(acc.Add(in), InvalidArgument);
  std::vector<int> short_labels(3, 0);
  in.points = &a;
  in.semantic = &short_labels;
  EXPECT_THROW(acc.Add(in), InvalidArgument);
  CloudStatsOptions bad;
  bad.neighbours = 1;
  EXPECT_THROW(CloudStatsAccumulator{bad}, InvalidArgument);
}

}  // namespace
}  // namespace dimr::eval
