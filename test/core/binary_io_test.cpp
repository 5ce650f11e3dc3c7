#include "dimr/core/binary_io.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "dimr/core/error.h"

namespace dimr {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ParseError& e) {
    return e.what();
  }
  return "";
}

TEST(BinaryIo, RoundTripsValuesInHostOrderWithoutPadding) {
  BinaryWriter w;
  w.PutString("DIMRTEST");
  w.Put<std::uint32_t>(0x01020304u);
  w.Put<std::int64_t>(-5);
  w.Put<std::uint8_t>(7);
  const std::vector<float> f = {1.5f, -2.0f, 3.25f};
  w.PutArray(f.data(), f.size());
  w.Put<double>(0.125);
  ASSERT_EQ(w.size(), 8u + 4 + 8 + 1 + 12 + 8);
  // Little-endian bytes of the u32 right after the magic.
  EXPECT_EQ(static_cast<unsigned char>(w.bytes()[8]), 0x04);
  EXPECT_EQ(static_cast<unsigned char>(w.bytes()[11]), 0x01);

  BinaryReader r("mem", w.bytes());
  r.ExpectMagic("DIMRTEST", "a test file");
  EXPECT_EQ(r.Get<std::uint32_t>("u32"), 0x01020304u);
  EXPECT_EQ(r.Get<std::int64_t>("i64"), -5);
  EXPECT_EQ(r.Get<std::uint8_t>("u8"), 7);
  std::vector<float> back;
  r.GetArray(3, &back, "floats");
  EXPECT_EQ(back, f);
  EXPECT_EQ(r.remaining(), 8u);
  EXPECT_EQ(r.Get<double>("f64"), 0.125);
  EXPECT_TRUE(r.at_end());
  r.ExpectEnd("the test record");
}

TEST(BinaryIo, TruncationAndCorruptCountsNameSourceFieldAndOffset) {
  BinaryWriter w;
  w.PutString("MAGIC");
  w.Put<std::uint64_t>(1000000000000ull);  // a claimed count
  w.Put<std::uint16_t>(3);
  BinaryReader r("dir/file.bin", w.bytes());
  EXPECT_NE(ErrorOf([&] { r.ExpectMagic("OTHER", "a pool"); }).find("dir/file.bin: not a pool"),
            std::string::npos);
  r.ExpectMagic("MAGIC", "x");
  const std::uint64_t n = r.Get<std::uint64_t>("count");
  std::string e = ErrorOf([&] { r.Count(n, 4, "entries"); });
  EXPECT_NE(e.find("dir/file.bin"), std::string::npos) << e;
  EXPECT_NE(e.find("1000000000000 entries"), std::string::npos) << e;
  EXPECT_NE(e.find("offset 13"), std::string::npos) << e;
  EXPECT_EQ(r.Count(2, 1, "bytes"), 2u);
  EXPECT_THROW(r.Count(3, 1, "bytes"), ParseError);
  EXPECT_THROW(r.Count(1, 3, "triples"), ParseError);
  std::vector<std::uint32_t> big;
  e = ErrorOf([&] { r.GetArray(n, &big, "values"); });  // no allocation of 4 TB
  EXPECT_NE(e.find("values"), std::string::npos) << e;
  EXPECT_TRUE(big.empty());
  e = ErrorOf([&] { r.Get<std::uint32_t>("version"); });
  EXPECT_NE(e.find("truncated: version needs 4 bytes, only 2 left"), std::string::npos) << e;
  EXPECT_EQ(r.pos(), 13u);  // a failed read consumes nothing
  EXPECT_NE(ErrorOf([&] { r.ExpectEnd("header"); }).find("2 trailing bytes"), std::string::npos);
  EXPECT_EQ(r.Get<std::uint16_t>("short"), 3);
}

TEST(BinaryIo, FilesRoundTripAndMissingFilesAreNamed) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "dimr_binary_io_test.bin").string();
  BinaryWriter w;
  for (int i = 0; i < 300; ++i) w.Put<std::uint8_t>(static_cast<std::uint8_t>(i));
  w.WriteFile(path);
  const std::string bytes = ReadFileBytes(path);
  EXPECT_EQ(bytes, w.bytes());
  EXPECT_NE(ErrorOf([&] { ReadFileBytes(path, 100); }).find("larger than"), std::string::npos);
  std::filesystem::remove(path);
  EXPECT_NE(ErrorOf([&] { ReadFileBytes(path); }).find(path), std::string::npos);
  EXPECT_THROW(w.WriteFile("/nonexistent_dir_dimr/x.bin"), ParseError);
  EXPECT_EQ(BinaryWriter().Release(), "");
}

}  // namespace
}  // namespace dimr
