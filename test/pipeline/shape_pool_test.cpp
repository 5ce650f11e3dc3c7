#include "dimr/pipeline/shape_pool.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {
namespace {

ShapePool RandomPool(int n_per_class, int dim, unsigned seed) {
  ShapePool pool(dim);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.f, 1.f);
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < n_per_class; ++i) {
      Eigen::VectorXf code(2 * dim);
      for (int d = 0; d < 2 * dim; ++d) code[d] = g(rng);
      pool.Add({"m" + std::to_string(c) + "_" + std::to_string(i), c, code});
    }
  }
  return pool;
}

TEST(ShapePool, OwnCodeRetrievesItselfAtDistanceZero) {
  const ShapePool pool = RandomPool(20, 6, 1);
  for (std::size_t i = 0; i < pool.size(); ++i) {
    const auto& e = pool.entries()[i];
    const auto nn = pool.Nearest(e.code, e.cad_class, 3);
    ASSERT_EQ(nn.size(), 3u);
    EXPECT_EQ(nn[0].index, static_cast<int>(i));
    EXPECT_EQ(nn[0].distance, 0.0);
    EXPECT_LE(nn[1].distance, nn[2].distance);
    // Only entries of the queried class.
    for (const auto& m : nn) EXPECT_EQ(pool.entries()[m.index].cad_class, e.cad_class);
  }
  EXPECT_TRUE(pool.Nearest(pool.entries()[0].code, 7, 3).empty());
}

TEST(ShapePool, ProjectionK1IsNearestAndKgt1LiesInTheAffineHull) {
  const ShapePool pool = RandomPool(30, 5, 2);
  std::mt19937 rng(9);
  std::normal_distribution<float> g(0.f, 1.f);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXf z(10);
    for (int d = 0; d < 10; ++d) z[d] = g(rng);
    const int cls = trial % 3;
    const auto nn = pool.Nearest(z, cls, 1);
    const Projection p1 = pool.Project(z, cls, 1);
    EXPECT_EQ(p1.neighbors[0], nn[0].index);
    EXPECT_EQ((p1.code - pool.entries()[nn[0].index].code).norm(), 0.f);
    for (int k : {2, 4, 8}) {
      const Projection p = pool.Project(z, cls, k);
      ASSERT_EQ(p.neighbors.size(), static_cast<std::size_t>(k));
      // Weights reproduce the projected code and sum to 1 (affine combination).
      Eigen::VectorXd combo = Eigen::VectorXd::Zero(10);
      double wsum = 0;
      for (int j = 0; j < k; ++j) {
        combo += p.weights[j] * pool.entries()[p.neighbors[j]].code.cast<double>();
        wsum += p.weights[j];
      }
      EXPECT_NEAR(wsum, 1.0, 1e-9);
      EXPECT_LT((combo.cast<float>() - p.code).norm(), 1e-4f);
      // Residual is orthogonal to the hull directions (least squares) ...
      const Eigen::VectorXf r = z - p.code;
      const Eigen::VectorXf x0 = pool.entries()[p.neighbors[0]].code;
      for (int j = 1; j < k; ++j) {
        EXPECT_NEAR(r.dot(pool.entries()[p.neighbors[j]].code - x0), 0.0f, 1e-3f);
      }
      // ... so the projection is closer to z than any of its neighbours.
      for (int j = 0; j < k; ++j) {
        EXPECT_LE(p.residual, (z - pool.entries()[p.neighbors[j]].code).norm() + 1e-5);
      }
    }
  }
}

TEST(ShapePool, DuplicateNeighboursDoNotBreakProjection) {
  ShapePool pool(2);
  Eigen::VectorXf a(4), b(4);
  a << 0, 0, 0, 0;
  b << 1, 0, 0, 0;
  pool.Add({"a", 0, a});
  pool.Add({"a2", 0, a});
  pool.Add({"b", 0, b});
  Eigen::VectorXf z(4);
  z << 0.25f, 1, 0, 0;
  const Projection p = pool.Project(z, 0, 3);
  EXPECT_TRUE(p.code.allFinite());
  EXPECT_NEAR(p.code[0], 0.25f, 1e-5f);
  EXPECT_NEAR(p.code[1], 0.0f, 1e-5f);
  EXPECT_NEAR(p.residual, 1.0, 1e-5);
}

TEST(ShapePool, SaveLoadAndCorruption) {
  const std::string dir = ::testing::TempDir() + "/pool";
  std::filesystem::create_directories(dir);
  const ShapePool pool = RandomPool(5, 4, 3);
  pool.Save(dir + "/p.bin");
  const ShapePool back = ShapePool::Load(dir + "/p.bin");
  EXPECT_EQ(back.ContentHash(), pool.ContentHash());
  ASSERT_EQ(back.size(), pool.size());
  EXPECT_EQ(back.entries()[7].model_id, pool.entries()[7].model_id);
  std::ifstream in(dir + "/p.bin", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string flipped = bytes;
  flipped[flipped.size() - 3] ^= 0x40;  // a code byte: hash mismatch
  std::ofstream(dir + "/f.bin", std::ios::binary) << flipped;
  try {
    ShapePool::Load(dir + "/f.bin");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("hash mismatch"), std::string::npos);
  }
  std::ofstream(dir + "/t.bin", std::ios::binary) << bytes.substr(0, bytes.size() - 5);
  EXPECT_THROW(ShapePool::Load(dir + "/t.bin"), ParseError);
  ShapePool p(4);
  EXPECT_THROW(p.Add({"x", 0, Eigen::VectorXf::Zero(5)}), InvalidArgument);
  Eigen::VectorXf nan = Eigen::VectorXf::Zero(8);
  nan[2] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(p.Add({"y", 0, nan}), InvalidArgument);
}

TEST(ShapePool, InterpolationAndSampling) {
  Eigen::VectorXf a(4), b(4);
  a << 0, 2, -10, -10;
  b << 4, 6, -10, -10;
  const Eigen::VectorXf mid = InterpolateCodes(a, b, 0.25);
  EXPECT_FLOAT_EQ(mid[0], 1.0f);
  EXPECT_FLOAT_EQ(mid[1], 3.0f);
  // logvar -10 -> std ~ 0.0067: samples stay close to mu, deterministic per seed.
  const Eigen::VectorXf s1 = SampleCode(a, 4), s2 = SampleCode(a, 4), s3 = SampleCode(a, 5);
  EXPECT_EQ((s1 - s2).norm(), 0.f);
  EXPECT_GT((s1 - s3).norm(), 0.f);
  EXPECT_LT(std::abs(s1[0] - a[0]), 0.05f);
}

}  // namespace
}  // namespace dimr::pipeline
