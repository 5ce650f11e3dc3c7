// The named-tensor checkpoint format ("DIMRCKPT"), byte for byte: a file built here by hand
// from the format description reads, WriteCheckpoint writes the same bytes, and corruption is
// a ParseError naming the file.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "dimr/core/error.h"
#include "dimr/core/hash.h"
#include "dimr/nn/checkpoint.h"

namespace dimr::nn {
namespace {

namespace fs = std::filesystem;

template <typename T>
void Le(std::string* out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    out->push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
  }
}

// "DIMRCKPT" | u32 version 1 | u64 count | count x { u32 name length | name | u8 dtype
// (0 f32, 1 f64, 2 f16, 3 i64) | u32 ndim | i64 dims | u64 byte count | data } | u64 FNV-1a
// (project basis) of every preceding byte.
TEST(CheckpointFormat, HandBuiltFileMatchesWriteCheckpoint) {
  std::string bytes = "DIMRCKPT";
  Le<std::uint32_t>(&bytes, 1);
  Le<std::uint64_t>(&bytes, 2);
  const float w[6] = {1.f, -2.f, 0.5f, 4.f, 0.f, 3.25f};
  Le<std::uint32_t>(&bytes, 1);
  bytes += "w";
  Le<std::uint8_t>(&bytes, 0);
  Le<std::uint32_t>(&bytes, 2);
  Le<std::int64_t>(&bytes, 2);
  Le<std::int64_t>(&bytes, 3);
  Le<std::uint64_t>(&bytes, sizeof(w));
  bytes.append(reinterpret_cast<const char*>(w), sizeof(w));
  Le<std::uint32_t>(&bytes, 5);
  bytes += "steps";
  Le<std::uint8_t>(&bytes, 3);
  Le<std::uint32_t>(&bytes, 1);
  Le<std::int64_t>(&bytes, 1);
  Le<std::uint64_t>(&bytes, 8);
  Le<std::int64_t>(&bytes, 41);
  Le<std::uint64_t>(&bytes, Fnv1a(bytes.data(), bytes.size()));

  const fs::path dir = fs::temp_directory_path() / "dimr_checkpoint_format_test";
  fs::create_directories(dir);
  const std::string path = (dir / "hand.ckpt").string();
  std::ofstream(path, std::ios::binary) << bytes;
  const NamedTensors t = ReadCheckpoint(path);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].first, "w");
  ASSERT_EQ(t[0].second.sizes(), (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(t[0].second[1][2].item<float>(), 3.25f);
  EXPECT_EQ(t[1].first, "steps");
  EXPECT_EQ(t[1].second.scalar_type(), at::kLong);
  EXPECT_EQ(t[1].second[0].item<int64_t>(), 41);

  const std::string again = (dir / "again.ckpt").string();
  WriteCheckpoint(t, again);
  std::ifstream in(again, std::ios::binary);
  const std::string written((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(written == bytes);

  for (std::size_t n = 0; n < bytes.size(); n += 5) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes.substr(0, n);
    try {
      ReadCheckpoint(path);
      ADD_FAILURE() << "truncated to " << n << " bytes and read";
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  std::string flipped = bytes;
  flipped[60] ^= 1;  // inside the data of "w": the checksum catches it
  std::ofstream(path, std::ios::binary | std::ios::trunc) << flipped;
  EXPECT_THROW(ReadCheckpoint(path), ParseError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace dimr::nn
