#include <gtest/gtest.h>

#include <string>

#include "dimr/geometry/crc32.h"
#include "dimr/geometry/hash.h"

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

// 64-bit FNV-1a: the published test vectors with the published basis; the project's basis
// (pinned: shipped checkpoints and pools depend on it); continuing a hash equals hashing the
// concatenation (what the pool content hash and the checkpoint checksum rely on).
TEST(Fnv1a, KnownVectorsProjectBasisAndContinuation) {
  using dimr::geometry::Fnv1a;
  using dimr::geometry::kFnv1aStandardOffset;
  EXPECT_EQ(Fnv1a("", 0, kFnv1aStandardOffset), 0xcbf29ce484222325ull);
  EXPECT_EQ(Fnv1a("a", 1, kFnv1aStandardOffset), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(Fnv1a("foobar", 6, kFnv1aStandardOffset), 0x85944171f73967e8ull);
  EXPECT_EQ(Fnv1a("", 0), 1469598103934665603ull);
  EXPECT_EQ(Fnv1a("foobar", 6), 9870438755804841970ull);
  EXPECT_EQ(Fnv1a("bar", 3, Fnv1a("foo", 3)), Fnv1a("foobar", 6));
}
