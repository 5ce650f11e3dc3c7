// `dimr stage1 prepare` / `dimr stage1 inspect` on a hand-made ScanNet-format scene.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_run.h"
#include "dimr/data/labels.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/synthscan.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;

#ifdef DIMR_CLI
using dimr::testing::RunCli;

// A floor (instance 1, 40 points), a wall (instance 2, 20 points), a chair (instance 3, CAD
// chair, box heading 1.0 rad = bin 2, 15 points) and 5 unlabelled points (no instance).
SynthScene HandRoom(const std::string& name) {
  SynthScene s;
  s.name = name;
  auto add = [&](const Vec3& p, int sem, int inst) {
    s.points.push_back(p);
    s.colors.emplace_back(static_cast<std::uint8_t>(40 * inst), 128, 200);
    s.semantic.push_back(sem);
    s.instance.push_back(inst);
    s.segment.push_back(inst * 10);
  };
  for (int i = 0; i < 40; ++i) add(Vec3(0.25 * (i % 8), 0.5 * (i / 8), 0.0), kFloor, 1);
  for (int i = 0; i < 20; ++i) add(Vec3(0.0, 0.25 * (i % 10), 0.5 * (i / 10)), kWall, 2);
  for (int i = 0; i < 15; ++i) add(Vec3(1.0 + 0.0625 * (i % 5), 1.0, 0.125 * (i / 5)), kChair, 3);
  for (int i = 0; i < 5; ++i) add(Vec3(1.5, 0.25 * i, 1.0), kSemanticIgnore, 0);
  auto instance = [](int id, const std::string& cat, int rfs, int cad, int n) {
    SynthInstance in;
    in.id = id;
    in.category = cat;
    in.rfs_class = rfs;
    in.cad_class = cad;
    in.family = cat;
    in.num_points = n;
    in.box.center = Vec3(1, 1, 0.5);
    in.box.size = Vec3(0.5, 0.5, 1);
    return in;
  };
  SynthInstance chair = instance(3, "chair", kChair, kCadChair, 15);
  chair.synset = CadSynsets()[kCadChair];
  chair.model_id = "0123456789abcdef0123456789abcdef";
  chair.box.heading = 1.0;
  chair.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Vec3::UnitZ()));
  s.instances = {instance(1, "floor", kFloor, kNonCad, 40), instance(2, "wall", kWall, kNonCad, 20),
                 chair};
  s.Validate();
  return s;
}

class Stage1PrepareTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stage1_prepare_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "scans");
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(Stage1PrepareTest, PrepareAndInspectReportTheScene) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  WriteScanNetScene((dir_ / "scans").string(), HandRoom("scene0042_00"));
  const std::string cache = (dir_ / "s1.bin").string();
  auto [rc, out] =
      RunCli("stage1 prepare --scans " + dir_.string() + " --threads 2 --out " + cache);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("1 scenes, 80 points (5 ignored), 3 instances, 1 CAD"), std::string::npos)
      << out;
  EXPECT_NE(out.find("chair 1"), std::string::npos) << out;

  // The cache and the scans folder give the same statistics.
  for (const std::string& input : {cache, (dir_ / "scans").string()}) {
    const std::string json = (dir_ / "inspect.json").string();
    auto [rc2, out2] = RunCli("stage1 inspect " + input + " --json " + json);
    ASSERT_EQ(rc2, 0) << out2;
    std::ifstream in(json);
    const nlohmann::json j = nlohmann::json::parse(in);
    ASSERT_TRUE(j["splits"].contains("all"));
    ASSERT_TRUE(j["splits"].contains("train"));  // scene0042 is in SynthScan's train range
    const auto& a = j["splits"]["all"];
    EXPECT_EQ(a["scenes"], 1);
    EXPECT_EQ(a["points"], 80);
    EXPECT_EQ(a["ignored_points"], 5);
    EXPECT_EQ(a["instances"], 3);
    EXPECT_EQ(a["cad_instances"], 1);
    EXPECT_EQ(a["cad_instances_per_class"]["chair"], 1);
    EXPECT_EQ(a["cad_instances_per_class"]["table"], 0);
    EXPECT_EQ(a["labelled_points"]["floor"], 40);
    EXPECT_EQ(a["labelled_points"]["wall"], 20);
    EXPECT_EQ(a["labelled_points"]["chair"], 15);
    const std::vector<int> bins = a["heading_bins"].get<std::vector<int>>();
    ASSERT_EQ(bins.size(), 12u);
    for (int b = 0; b < 12; ++b) EXPECT_EQ(bins[b], b == 2 ? 1 : 0) << "bin " << b;
    EXPECT_EQ(j["splits"]["train"], a);
  }
}

TEST_F(Stage1PrepareTest, MissingPlyFailsNamingTheFile) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  WriteScanNetScene((dir_ / "scans").string(), HandRoom("scene0042_00"));
  WriteScanNetScene((dir_ / "scans").string(), HandRoom("scene0043_00"));
  fs::remove(dir_ / "scans" / "scene0043_00" / "scene0043_00_vh_clean_2.ply");
  auto [rc, out] = RunCli("stage1 prepare --scans " + (dir_ / "scans").string() + " --out " +
                          (dir_ / "bad.bin").string());
  EXPECT_NE(rc, 0) << out;
  EXPECT_NE(out.find("scene0043_00_vh_clean_2.ply"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir_ / "bad.bin"));
  // A scene list selects the good scene only.
  std::ofstream(dir_ / "list.txt") << "# good scenes\nscene0042_00\n";
  auto [rc2, out2] =
      RunCli("stage1 prepare --scans " + (dir_ / "scans").string() + " --scene-list " +
             (dir_ / "list.txt").string() + " --out " + (dir_ / "good.bin").string());
  EXPECT_EQ(rc2, 0) << out2;
  EXPECT_NE(out2.find("1 scenes, 80 points"), std::string::npos) << out2;
}
#endif  // DIMR_CLI

}  // namespace
}  // namespace dimr::data
