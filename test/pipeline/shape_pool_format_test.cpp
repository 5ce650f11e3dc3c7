// The shape-pool file format, byte for byte: the shipped models/bsp/pool.bin and files built
// here by hand from the format description must read, and Save must write the same bytes.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "dimr/core/error.h"
#include "dimr/core/hash.h"
#include "dimr/pipeline/shape_pool.h"

namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

template <typename T>
void Le(std::string* out, T v) {  // little-endian, independent of the code under test
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    out->push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
  }
}

TEST(ShapePoolFormat, ShippedPoolReadsAndRewritesIdentically) {
  const std::string shipped = std::string(DIMR_SOURCE_DIR) + "/models/bsp/pool.bin";
  const ShapePool pool = ShapePool::Load(shipped);
  EXPECT_EQ(pool.size(), 2000u);  // models/bsp/model.yaml pool.entries
  EXPECT_EQ(pool.latent_dim(), 128);
  EXPECT_EQ(pool.ContentHash(), "3c0f82a31dca527c");  // pool.content_hash of the card
  const std::string copy = (fs::temp_directory_path() / "dimr_pool_format_test.bin").string();
  pool.Save(copy);
  EXPECT_TRUE(ReadAll(copy) == ReadAll(shipped));
  fs::remove(copy);
}

// "DIMRPOOL" | u32 version 1 | i32 latent_dim | u64 count | 16 hex chars content hash |
// count x { i32 class | u32 id length | id | 2 * latent_dim f32 }.
TEST(ShapePoolFormat, HandBuiltFileMatchesSave) {
  const int dim = 2;
  const float codes[2][4] = {{0.5f, -1.0f, 0.25f, 2.0f}, {1.5f, 0.0f, -0.5f, -2.0f}};
  const char* ids[2] = {"abc", "model_2"};
  const int classes[2] = {3, 7};
  // Content hash: FNV-1a (project basis) over latent_dim, then per entry id, class, code bytes.
  std::uint64_t h = Fnv1a(&dim, sizeof(dim));
  for (int i = 0; i < 2; ++i) {
    h = Fnv1a(ids[i], std::strlen(ids[i]), h);
    h = Fnv1a(&classes[i], sizeof(int), h);
    h = Fnv1a(codes[i], sizeof(codes[i]), h);
  }
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(h));
  std::string bytes = "DIMRPOOL";
  Le<std::uint32_t>(&bytes, 1);
  Le<std::int32_t>(&bytes, dim);
  Le<std::uint64_t>(&bytes, 2);
  bytes += hex;
  for (int i = 0; i < 2; ++i) {
    Le<std::int32_t>(&bytes, classes[i]);
    Le<std::uint32_t>(&bytes, static_cast<std::uint32_t>(std::strlen(ids[i])));
    bytes += ids[i];
    bytes.append(reinterpret_cast<const char*>(codes[i]), sizeof(codes[i]));
  }
  const fs::path dir = fs::temp_directory_path() / "dimr_pool_format_test";
  fs::create_directories(dir);
  const std::string path = (dir / "hand.bin").string();
  std::ofstream(path, std::ios::binary) << bytes;
  const ShapePool pool = ShapePool::Load(path);
  ASSERT_EQ(pool.size(), 2u);
  EXPECT_EQ(pool.entries()[1].model_id, "model_2");
  EXPECT_EQ(pool.entries()[1].cad_class, 7);
  EXPECT_EQ(pool.entries()[1].code[3], -2.0f);
  EXPECT_EQ(pool.ContentHash(), hex);
  pool.Save((dir / "saved.bin").string());
  EXPECT_TRUE(ReadAll((dir / "saved.bin").string()) == bytes);

  // Every truncation is a ParseError naming the file, never a crash or a huge allocation.
  for (std::size_t n = 0; n < bytes.size(); n += 3) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes.substr(0, n);
    try {
      ShapePool::Load(path);
      ADD_FAILURE() << "truncated to " << n << " bytes and loaded";
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  std::string huge = bytes;
  huge[16] = '\xff';  // entry count 0xff.. : more than the file holds
  huge[23] = '\x7f';
  std::ofstream(path, std::ios::binary | std::ios::trunc) << huge;
  EXPECT_THROW(ShapePool::Load(path), ParseError);
  std::string flipped = bytes;
  flipped[flipped.size() - 1] ^= 0x40;  // a code bit: the content hash no longer matches
  std::ofstream(path, std::ios::binary | std::ios::trunc) << flipped;
  EXPECT_THROW(ShapePool::Load(path), ParseError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace dimr::pipeline
