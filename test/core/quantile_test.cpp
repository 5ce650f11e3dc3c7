#include "dimr/core/quantile.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace dimr {
namespace {

TEST(NearestRankQuantile, RankIsFloorOfQTimesNClampedToTheLast) {
  // 10 values in shuffled order: rank floor(q * 10) of the sorted 1..10.
  const std::vector<float> v = {7, 3, 10, 1, 9, 2, 8, 5, 4, 6};
  auto at = [&](double q) {
    std::vector<float> w = v;
    return NearestRankQuantile(&w, q);
  };
  EXPECT_EQ(at(0.0), 1.f);
  EXPECT_EQ(at(0.01), 1.f);    // rank 0
  EXPECT_EQ(at(0.1), 2.f);     // rank 1
  EXPECT_EQ(at(0.55), 6.f);    // rank 5
  EXPECT_EQ(at(0.999), 10.f);  // rank 9
  EXPECT_EQ(at(1.0), 10.f);    // rank 10, clamped to 9
  std::vector<double> one = {4.5};
  EXPECT_EQ(NearestRankQuantile(&one, 0.7), 4.5);
}

TEST(NearestRankQuantile, EmptyOrBadQIsAnError) {
  std::vector<float> empty;
  EXPECT_THROW(NearestRankQuantile(&empty, 0.5), InvalidArgument);
  std::vector<float> v = {1, 2};
  EXPECT_THROW(NearestRankQuantile(&v, -0.1), InvalidArgument);
  EXPECT_THROW(NearestRankQuantile(&v, 1.5), InvalidArgument);
  EXPECT_THROW(NearestRankQuantile(&v, std::nan("")), InvalidArgument);
}

}  // namespace
}  // namespace dimr
