#include "dimr/geometry/grid_key.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <unordered_set>

namespace dimr::geometry {
namespace {

TEST(GridKey, CellOfFloorsNegativeCoordinates) {
  EXPECT_EQ(CellOf(0.25, 0.1), 2);
  EXPECT_EQ(CellOf(-0.01, 0.1), -1);
  EXPECT_EQ(CellOf(-0.1, 0.1), -1);
  EXPECT_EQ(CellOf(-0.11, 0.1), -2);
  EXPECT_EQ(CellOf(0.0, 0.06), 0);
}

TEST(GridKey, TwoDimensionalKeysAreExactAndInvertible) {
  std::unordered_set<std::int64_t> keys;
  for (std::int64_t x = -3; x <= 3; ++x) {
    for (std::int64_t y = -3; y <= 3; ++y) {
      const std::int64_t k = PackCell2(x, y);
      keys.insert(k);
      const auto [ux, uy] = UnpackCell2(k);
      EXPECT_EQ(ux, x);
      EXPECT_EQ(uy, y);
    }
  }
  EXPECT_EQ(keys.size(), 49u);  // (-1, 0) and (0, -1) must not collide with anything
  const auto [bx, by] = UnpackCell2(PackCell2(-2000000000, 2000000000));
  EXPECT_EQ(bx, -2000000000);
  EXPECT_EQ(by, 2000000000);
  // A neighbour of a negative cell is the key of the neighbour's coordinates.
  EXPECT_EQ(PackCell2(-1 + 1, -1 + 1), PackCell2(0, 0));
}

TEST(GridKey, ThreeDimensionalKeysSeparateCellsWithinTheirSpan) {
  std::unordered_set<std::uint64_t> keys;
  for (std::int64_t x = -2; x <= 2; ++x)
    for (std::int64_t y = -2; y <= 2; ++y)
      for (std::int64_t z = -2; z <= 2; ++z) keys.insert(PackCell3(x, y, z));
  EXPECT_EQ(keys.size(), 125u);
  EXPECT_EQ(PackCell3(1, 0, 0), 1u);
  EXPECT_EQ(PackCell3(0, 1, 0), std::uint64_t{1} << 21);
  EXPECT_EQ(PackCell3(0, 0, 1), std::uint64_t{1} << 42);
  // Coordinates wrap modulo 2^21: cells 2^21 apart share a key (documented).
  EXPECT_EQ(PackCell3(5, 0, 0), PackCell3(5 + (std::int64_t{1} << 21), 0, 0));
}

}  // namespace
}  // namespace dimr::geometry
