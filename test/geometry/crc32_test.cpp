#include "dimr/geometry/crc32.h"

#include <gtest/gtest.h>

#include <string>

namespace dimr::geometry {
namespace {

TEST(Crc32, CheckValueAndContinuation) {
  const std::string s = "123456789";
  EXPECT_EQ(Crc32(s.data(), s.size()), 0xCBF43926u);  // the standard CRC-32 check value
  EXPECT_EQ(Crc32(s.data(), 0), 0u);
  // Continuing over a split gives the CRC of the whole.
  EXPECT_EQ(Crc32(s.data() + 4, 5, Crc32(s.data(), 4)), 0xCBF43926u);
  const std::string iend = "IEND";  // PNG's IEND chunk CRC
  EXPECT_EQ(Crc32(iend.data(), iend.size()), 0xAE426082u);
}

}  // namespace
}  // namespace dimr::geometry
