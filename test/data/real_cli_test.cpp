// `dimr real import` (a real scene as per-vertex .npy arrays -> a ScanNet scene folder) and
// `dimr real eval` over a folder of such scenes: each scene scored on its own object annotation,
// then the pooled numbers (IoU over all points, instance AP over all objects).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_run.h"
#include "npy_bytes.h"

namespace {

namespace fs = std::filesystem;

#ifdef DIMR_CLI
using dimr::testing::FreshTempDir;
using dimr::testing::ReadFileText;
using dimr::testing::RunCli;

// numpy.save of a C-order array of 4-byte values ("<f4" or "<u4").
template <typename T>
void WriteNpy(const fs::path& path, const std::string& descr, const std::vector<long long>& shape,
              const std::vector<T>& values) {
  std::ofstream(path, std::ios::binary)
      << dimr::testing::NpyBytes(descr, shape, values.data(), values.size() * sizeof(T));
}

// A small labelled room: a 3 x 3 m floor (NYU40 2), a wall (1), a chair-sized box (5) and a
// table-sized box (7), each an object; `dx` moves the furniture. Files
// <dir>/<name>_{vert,sem,ins}.npy.
int WriteRoom(const fs::path& dir, const std::string& name, float dx) {
  std::vector<float> v;
  std::vector<std::uint32_t> sem, ins;
  auto add = [&](float x, float y, float z, std::uint32_t label, std::uint32_t object) {
    v.insert(v.end(), {x, y, z, 120.0f + 40.0f * (label % 3), 110.0f, 100.0f + 10.0f * object});
    sem.push_back(label);
    ins.push_back(object);
  };
  for (int i = 0; i < 75; ++i)
    for (int k = 0; k < 75; ++k) add(0.04f * i, 0.04f * k, 0, 2, 1);  // 75 x 75 floor points
  for (int i = 0; i < 75; ++i)
    for (int k = 1; k < 60; ++k) add(0.04f * i, 0, 0.04f * k, 1, 2);
  // Boxes: the surface of [x0, x0 + sx] x [y0, y0 + sy] x [0, sz] without the bottom.
  auto box = [&](float x0, float y0, float sx, float sy, float sz, std::uint32_t label,
                 std::uint32_t object) {
    for (float a = 0; a <= sx; a += 0.03f)
      for (float b = 0; b <= sy; b += 0.03f) add(x0 + a, y0 + b, sz, label, object);
    for (float a = 0; a <= sx; a += 0.03f)
      for (float z = 0.03f; z < sz; z += 0.03f) {
        add(x0 + a, y0, z, label, object);
        add(x0 + a, y0 + sy, z, label, object);
      }
    for (float b = 0; b <= sy; b += 0.03f)
      for (float z = 0.03f; z < sz; z += 0.03f) {
        add(x0, y0 + b, z, label, object);
        add(x0 + sx, y0 + b, z, label, object);
      }
  };
  box(0.5f + dx, 1.2f, 0.45f, 0.45f, 0.85f, 5, 3);
  box(1.5f + dx, 1.0f, 1.2f, 0.7f, 0.75f, 7, 4);
  const int n = static_cast<int>(sem.size());
  WriteNpy(dir / (name + "_vert.npy"), "<f4", {n, 6}, v);
  WriteNpy(dir / (name + "_sem.npy"), "<u4", {n}, sem);
  WriteNpy(dir / (name + "_ins.npy"), "<u4", {n}, ins);
  return n;
}

TEST(RealCli, ImportArraysThenEvaluateAFolderOfScenesPooled) {
  const fs::path dir = FreshTempDir("real_cli");
  const std::string d = dir.string();
  const int n0 = WriteRoom(dir, "a", 0.0f);
  const int n1 = WriteRoom(dir, "b", 0.3f);
  for (const auto& [file, name] : {std::pair{"a", "scene9100_00"}, {"b", "scene9101_00"}}) {
    const std::string f = d + "/" + file;
    auto [rc, out] =
        RunCli("real import --vertices " + f + "_vert.npy --labels " + f + "_sem.npy --instances " +
               f + "_ins.npy --name " + name + " --out " + d + "/scans");
    ASSERT_EQ(rc, 0) << out;
    EXPECT_NE(out.find("4 objects"), std::string::npos) << out;
    EXPECT_NE(out.find("CAD-class objects (instance AP ground truth): table 1, chair 1"),
              std::string::npos)
        << out;
  }
  ASSERT_TRUE(fs::exists(dir / "scans/scene9100_00/scene9100_00.aggregation.json"));

  // A bad array is refused with its file named.
  WriteNpy(dir / "bad_sem.npy", "<u4", {3}, std::vector<std::uint32_t>{1, 2, 3});
  auto [rc, out] =
      RunCli("real import --vertices " + d + "/a_vert.npy --labels " + d +
             "/bad_sem.npy --instances " + d + "/a_ins.npy --name s --out " + d + "/x");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("bad_sem.npy"), std::string::npos) << out;

  const std::string model = std::string(DIMR_SOURCE_DIR) + "/models/stage1/stage1.pt";
  std::tie(rc, out) = RunCli("real eval --model " + model + " --preset fast --scene " + d +
                             "/scans --json " + d + "/eval.json");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("### all 2 scenes (pooled)"), std::string::npos) << out;
  EXPECT_NE(out.find("annotated objects"), std::string::npos) << out;
  const auto j = nlohmann::json::parse(ReadFileText(dir / "eval.json"));
  ASSERT_EQ(j["scenes"].size(), 2u);
  EXPECT_EQ(j["scenes"][0]["points"].get<int>(), n0);
  EXPECT_EQ(j["scenes"][1]["points"].get<int>(), n1);
  // Both CAD objects of each scene are ground truth; the pooled count is their sum.
  EXPECT_EQ(j["scenes"][0]["objects_total"].get<int>(), 2);
  EXPECT_EQ(j["pooled"]["objects_total"].get<int>(), 4);
  EXPECT_EQ(j["pooled"]["found"].get<int>(),
            j["scenes"][0]["found"].get<int>() + j["scenes"][1]["found"].get<int>());
  // Pooled IoU counts every point of both scenes: the floor's GT points add up.
  const long long floor0 =
      j["scenes"][0]["semantic_doda11"]["classes"]["floor"]["gt_points"].get<long long>();
  const long long floor1 =
      j["scenes"][1]["semantic_doda11"]["classes"]["floor"]["gt_points"].get<long long>();
  EXPECT_EQ(floor0, 75 * 75);
  EXPECT_EQ(j["pooled"]["semantic_doda11"]["classes"]["floor"]["gt_points"].get<long long>(),
            floor0 + floor1);
  EXPECT_TRUE(j["pooled"].contains("instance_ap50_cad"));
  // The flat floor of a 3 x 3 m room is labelled floor by any working stage 1.
  EXPECT_GT(j["pooled"]["semantic_doda11"]["classes"]["floor"]["iou"].get<double>(), 0.5);

  // Self-training data: the same two rooms as unlabelled scans -> a stage-1 training cache in
  // which each predicted class keeps its most confident 30 % (class-balanced).
  std::tie(rc, out) =
      RunCli("real pseudo-label --model " + model + " --preset fast --scene " + d +
             "/scans --keep 0.3 --out " + d + "/pseudo.bin --json " + d + "/pseudo.json");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("against the scans' own labels (diagnostic"), std::string::npos) << out;
  const auto p = nlohmann::json::parse(ReadFileText(dir / "pseudo.json"));
  ASSERT_EQ(p["scenes"].size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const auto& s = p["scenes"][k];
    // Denser than the training rooms: the network saw (and the sample holds) voxel means.
    EXPECT_LT(s["points"].get<int>(), k == 0 ? n0 : n1);
    EXPECT_GT(s["points"].get<int>(), (k == 0 ? n0 : n1) / 4);
    EXPECT_NE(s["note"].get<std::string>().find("voxel means"), std::string::npos);
    long long kept = 0, predicted = 0;
    for (const auto& [name, c] : s["classes"].items()) {
      const long long pr = c["predicted"].get<long long>(), ke = c["kept"].get<long long>();
      EXPECT_EQ(ke, (3 * pr + 9) / 10) << name;  // ceil(0.3 x predicted)
      kept += ke;
      predicted += pr;
    }
    EXPECT_EQ(predicted, s["points"].get<long long>());  // every point has a class (no ceiling)
    EXPECT_EQ(s["labelled"].get<long long>(), kept);
    EXPECT_GT(s["classes"]["floor"]["kept"].get<long long>(), 0);
  }
  // The cache is a stage-1 training set: two scenes, about 30 % of their points labelled.
  std::tie(rc, out) = RunCli("stage1 inspect " + d + "/pseudo.bin --json " + d + "/inspect.json");
  ASSERT_EQ(rc, 0) << out;
  const auto q = nlohmann::json::parse(ReadFileText(dir / "inspect.json"))["splits"]["all"];
  EXPECT_EQ(q["scenes"].get<int>(), 2) << q.dump();
  const long long points =
      p["scenes"][0]["points"].get<long long>() + p["scenes"][1]["points"].get<long long>();
  EXPECT_EQ(q["points"].get<long long>(), points);
  EXPECT_EQ(q["ignored_points"].get<long long>(), points -
                                                      p["scenes"][0]["labelled"].get<long long>() -
                                                      p["scenes"][1]["labelled"].get<long long>());
  // A bad selection is refused by name.
  std::tie(rc, out) = RunCli("real pseudo-label --model " + model + " --scene " + d +
                             "/scans --keep 1.5 --out " + d + "/x.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("keep_fraction"), std::string::npos) << out;
}
#endif

}  // namespace
