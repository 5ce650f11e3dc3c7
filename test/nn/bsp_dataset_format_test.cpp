// The BSP dataset file format, byte for byte (datasets made by earlier builds must still read):
// a file built here by hand from the format description reads, and Save writes the same bytes.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "dimr/core/error.h"
#include "dimr/nn/bsp_dataset.h"

namespace dimr::nn {
namespace {

namespace fs = std::filesystem;

template <typename T>
void Le(std::string* out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    out->push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
  }
}

// "DIMRBSPD" | u32 version 2 | i32 R | u64 count | count x { i32 class | u32 id length | id |
// grid bits (R^3, bit i of byte i/8, x fastest) | target bits | u64 K | 3K u16 inside points |
// u64 L | 3L u16 outside points }, coordinates q = round((c + 1) / 2 * 65535).
TEST(BspDatasetFormat, HandBuiltFileMatchesSave) {
  const int R = 2;  // 8 cells: one byte per grid
  std::string bytes = "DIMRBSPD";
  Le<std::uint32_t>(&bytes, 2);
  Le<std::int32_t>(&bytes, R);
  Le<std::uint64_t>(&bytes, 1);
  Le<std::int32_t>(&bytes, 6);
  Le<std::uint32_t>(&bytes, 2);
  bytes += "id";
  bytes.push_back(static_cast<char>(0x81));  // cells 0 and 7
  bytes.push_back(static_cast<char>(0x01));  // cell 0
  Le<std::uint64_t>(&bytes, 1);
  for (std::uint16_t q : {0, 32768, 65535}) Le<std::uint16_t>(&bytes, q);  // (-1, ~0, 1)
  Le<std::uint64_t>(&bytes, 0);

  const fs::path dir = fs::temp_directory_path() / "dimr_bsp_dataset_format_test";
  fs::create_directories(dir);
  const std::string path = (dir / "hand.bin").string();
  std::ofstream(path, std::ios::binary) << bytes;
  const BspDataset data = BspDataset::Load(path);
  EXPECT_EQ(data.resolution, 2);
  ASSERT_EQ(data.samples.size(), 1u);
  const BspSample& s = data.samples[0];
  EXPECT_EQ(s.cad_class, 6);
  EXPECT_EQ(s.model_id, "id");
  EXPECT_EQ(s.grid, (std::vector<std::uint8_t>{1, 0, 0, 0, 0, 0, 0, 1}));
  EXPECT_EQ(s.iou_grid, (std::vector<std::uint8_t>{1, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_EQ(s.inside_points.size(), 3u);
  EXPECT_FLOAT_EQ(s.inside_points[0], -1.0f);
  EXPECT_NEAR(s.inside_points[1], 0.0f, 2e-5f);
  EXPECT_FLOAT_EQ(s.inside_points[2], 1.0f);
  EXPECT_TRUE(s.outside_points.empty());
  data.Save((dir / "saved.bin").string());
  std::ifstream in((dir / "saved.bin").string(), std::ios::binary);
  const std::string saved((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(saved == bytes);

  for (std::size_t n = 0; n < bytes.size(); ++n) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes.substr(0, n);
    try {
      BspDataset::Load(path);
      ADD_FAILURE() << "truncated to " << n << " bytes and loaded";
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  std::string more = bytes + "x";
  std::ofstream(path, std::ios::binary | std::ios::trunc) << more;
  EXPECT_THROW(BspDataset::Load(path), ParseError);  // trailing bytes
  std::string huge = bytes;
  huge[16 + 7] = '\x10';  // sample count 2^60
  std::ofstream(path, std::ios::binary | std::ios::trunc) << huge;
  EXPECT_THROW(BspDataset::Load(path), ParseError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace dimr::nn
