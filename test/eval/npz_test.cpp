#include "dimr/eval/npz.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "dimr/eval/inputs.h"
#include "dimr/geometry/error.h"

namespace dimr::eval {
namespace {

namespace fs = std::filesystem;

// A processed-data scene: 6 vertices; instance 1 = chair (RFS 4 -> CAD 1, 3 vertices),
// instance 2 = wall (RFS 0, non-CAD: skipped), instance 3 starts with an ignored label (255:
// skipped), one vertex without instance.
std::map<std::string, NpyArray> SceneArrays() {
  NpyArray v{"f8", {6, 6}, {}};
  for (int i = 0; i < 6; ++i) {
    v.values.insert(v.values.end(), {0.1 * i, 0.2 * i, 0.3 * i, 100, 110, 120});
  }
  NpyArray sem{"u1", {6}, {4, 4, 4, 0, 255, 6}};
  NpyArray inst{"u1", {6}, {1, 1, 1, 2, 3, 0}};
  return {{"mesh_vertices", v}, {"semantic_labels", sem}, {"instance_labels", inst}};
}

TEST(Npz, RoundTripAndReferencePcrGt) {
  const fs::path dir = fs::path(::testing::TempDir()) / "npz_gt";
  fs::remove_all(dir);
  fs::create_directories(dir / "scene0001_00");
  fs::create_directories(dir / "scene0002_00");
  const auto arrays = SceneArrays();
  WriteNpz((dir / "scene0001_00" / "data.npz").string(), arrays);
  WriteNpz((dir / "scene0002_00" / "data.npz").string(), arrays);
  const auto back = ReadNpz((dir / "scene0001_00" / "data.npz").string());
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(back.at("mesh_vertices").shape, (std::vector<std::int64_t>{6, 6}));
  EXPECT_EQ(back.at("mesh_vertices").values, arrays.at("mesh_vertices").values);
  EXPECT_EQ(back.at("semantic_labels").dtype, "u1");
  EXPECT_EQ(back.at("instance_labels").values, arrays.at("instance_labels").values);

  const auto gt = ReadPcrGtNpz((dir / "scene0001_00" / "data.npz").string(), "scene0001_00");
  ASSERT_EQ(gt.size(), 1u);  // only the chair survives
  EXPECT_EQ(gt[0].cls, 1);
  ASSERT_EQ(gt[0].points.size(), 3u);
  EXPECT_DOUBLE_EQ(gt[0].points[2].z(), 0.6);

  std::vector<std::string> scenes;
  EXPECT_EQ(LoadPcrGtFolder(dir.string(), &scenes).size(), 2u);
  EXPECT_EQ(scenes, (std::vector<std::string>{"scene0001_00", "scene0002_00"}));
  std::ofstream(dir / "val.txt") << "scene0002_00\n";
  EXPECT_EQ(LoadPcrGtFolder(dir.string(), &scenes, (dir / "val.txt").string()).size(), 1u);
  EXPECT_EQ(scenes, (std::vector<std::string>{"scene0002_00"}));
  std::ofstream(dir / "bad.txt") << "scene0002_00\nscene0404_00\n";
  try {
    LoadPcrGtFolder(dir.string(), &scenes, (dir / "bad.txt").string());
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("scene0404_00"), std::string::npos);
  }
}

TEST(Npz, MalformedFilesNameTheProblem) {
  const fs::path dir = fs::path(::testing::TempDir()) / "npz_bad";
  fs::create_directories(dir);
  const std::string good = (dir / "good.npz").string();
  WriteNpz(good, SceneArrays());
  std::ifstream in(good, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (std::size_t cut : {std::size_t{0}, std::size_t{30}, bytes.size() / 2, bytes.size() - 3}) {
    const std::string p = (dir / ("cut" + std::to_string(cut) + ".npz")).string();
    std::ofstream(p, std::ios::binary) << bytes.substr(0, cut);
    try {
      ReadNpz(p);
      FAIL() << "cut " << cut;
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find("cut"), std::string::npos) << e.what();
    }
  }
  // An npy whose shape claims more data than it holds.
  const std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000,), }\n";
  const std::string npy = std::string("\x93NUMPY\x01\x00", 8) + static_cast<char>(header.size()) +
                          std::string(1, '\0') + header + std::string(16, '\0');
  try {
    ParseNpy(reinterpret_cast<const std::uint8_t*>(npy.data()), npy.size(), "x.npy");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("shorter than its shape"), std::string::npos) << e.what();
  }
  // Missing arrays.
  WriteNpz((dir / "partial.npz").string(), {{"mesh_vertices", SceneArrays().at("mesh_vertices")}});
  try {
    ReadPcrGtNpz((dir / "partial.npz").string(), "s");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("semantic_labels"), std::string::npos);
  }
}

}  // namespace
}  // namespace dimr::eval
