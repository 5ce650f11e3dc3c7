// End-to-end stage-2 commands on two small SynthScan rooms with the shipped stage-1 and BSP
// models: `dimr synth` -> `dimr stage2 check-gt` (the GT codes decoded and placed by the GT
// boxes reproduce the placed CAD models) -> `dimr stage2 prepare` -> `dimr train stage2` (tiny
// network) -> `dimr stage2 eval` (JSON); a corrupt model gives a clear error.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "cli_run.h"

namespace {

namespace fs = std::filesystem;

#ifdef DIMR_CLI
using dimr::testing::FreshTempDir;
using dimr::testing::ReadFileText;
using dimr::testing::RunCli;

TEST(Stage2Cli, CheckGtPrepareTrainEval) {
  if (RunCli("train stage2 --help").first != 0) GTEST_SKIP() << "dimr built without stage 2";
  const std::string models = std::string(DIMR_SOURCE_DIR) + "/models";
  const fs::path dir = FreshTempDir("stage2_cli");
  const std::string d = dir.string();
  auto [rc, out] = RunCli(
      "synth --scenes 2 --seed 5 --split val --frames-per-scene 16 --quiet --out " + d + "/synth");
  ASSERT_EQ(rc, 0) << out;

  // GT codes + GT boxes give the GT objects back.
  std::tie(rc, out) = RunCli("stage2 check-gt --scans " + d + "/synth --bsp " + models +
                             "/bsp/bsp.pt --json " + d + "/check.json");
  ASSERT_EQ(rc, 0) << out;
  const auto check = nlohmann::json::parse(ReadFileText(d + "/check.json"));
  ASSERT_GT(check["instances"].get<int>(), 2);
  EXPECT_LT(check["box_error_max"].get<double>(), 2e-3);  // the CAD model fills its box exactly
  // Decoded and placed: within a few percent of the box diagonal, and clearly closer than the
  // same mesh placed with a wrong (90 degree) heading.
  EXPECT_LT(check["chamfer_relative_median"].get<double>(), 0.05);
  EXPECT_LT(check["chamfer_median"].get<double>(),
            0.8 * check["chamfer_rotated_median"].get<double>());

  std::tie(rc, out) =
      RunCli("stage2 prepare --scans " + d + "/synth --stage1 " + models +
             "/stage1/stage1.pt --bsp " + models + "/bsp/bsp.pt --out " + d +
             "/cache.bin --quiet --stage1-inference 'passes=s0.12,s0.3 rotations=1'");
  ASSERT_EQ(rc, 0) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex("2 scenes -> ([0-9]+) proposals"))) << out;
  const int proposals = std::stoi(m[1]);  // before `out` is reassigned
  ASSERT_GT(proposals, 2);

  const std::string model = d + "/model";
  std::tie(rc, out) =
      RunCli("train stage2 --train " + d + "/cache.bin --val " + d + "/cache.bin --out " + model +
             " --config 'features=16 height=1 grid=20 widths=8,16 reps=1 latent=128 "
             "center_height=1' --epochs 2 --batch 2 --threads 1 --quiet --seed 3");
  ASSERT_EQ(rc, 0) << out;
  ASSERT_TRUE(fs::exists(model + "/stage2.pt"));
  const std::string card = ReadFileText(model + "/model.yaml");
  EXPECT_TRUE(std::regex_search(card, std::regex("sha256: [0-9a-f]{64}\n"))) << card;
  EXPECT_NE(card.find("score_ap50:"), std::string::npos) << card;

  std::tie(rc, out) = RunCli("stage2 eval --model " + model + "/stage2.pt --data " + d +
                             "/cache.bin --json " + d + "/eval.json");
  ASSERT_EQ(rc, 0) << out;
  const auto ev = nlohmann::json::parse(ReadFileText(d + "/eval.json"));
  EXPECT_EQ(ev["proposals"].get<int>(), proposals);
  EXPECT_GE(ev["box_iou"].get<double>(), 0.0);
  EXPECT_LE(ev["box_iou"].get<double>(), 1.0);

  // A corrupt model names the file.
  {
    std::ofstream f(d + "/bad.pt", std::ios::binary);
    f << "not a model";
  }
  std::tie(rc, out) = RunCli("stage2 eval --model " + d + "/bad.pt --data " + d + "/cache.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("bad.pt"), std::string::npos) << out;
  fs::remove_all(dir);
}

// `stage2 prepare` reads the stage-1 card's recommended_inference with the segmenter's own
// parser: every key of the shipped card (colour_norm, cluster_cap, ...) is accepted, and the
// proposals are those of the card's test-time augmentation; an unknown key names itself.
TEST(Stage2Cli, PrepareUsesTheShippedStage1CardAsIs) {
  if (RunCli("train stage2 --help").first != 0) GTEST_SKIP() << "dimr built without stage 2";
  const std::string models = std::string(DIMR_SOURCE_DIR) + "/models";
  const fs::path dir = FreshTempDir("stage2_cli_card");
  const std::string d = dir.string();
  auto [rc, out] = RunCli(
      "synth --scenes 1 --seed 6 --split val --frames-per-scene 16 --quiet --out " + d + "/synth");
  ASSERT_EQ(rc, 0) << out;
  const std::string card = ReadFileText(models + "/stage1/model.yaml");
  ASSERT_NE(card.find("colour_norm="), std::string::npos);  // the keys this test is about
  ASSERT_NE(card.find("cluster_cap=0"), std::string::npos);
  std::tie(rc, out) =
      RunCli("stage2 prepare --scans " + d + "/synth --stage1 " + models +
             "/stage1/stage1.pt --bsp " + models + "/bsp/bsp.pt --out " + d + "/cache.bin --quiet");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("rotations=6 mirror=1"), std::string::npos) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m,
                                std::regex("1 scenes -> ([0-9]+) proposals \\(([0-9]+) "
                                           "with IoU > 0.5")))
      << out;
  // The card's settings give few, good proposals (docs/stage2.md: almost all IoU > 0.5).
  ASSERT_GT(std::stoi(m[1]), 2);
  EXPECT_GE(std::stoi(m[2]), std::stoi(m[1]) * 7 / 10) << out;

  std::tie(rc, out) = RunCli("stage2 prepare --scans " + d + "/synth --stage1 " + models +
                             "/stage1/stage1.pt --bsp " + models + "/bsp/bsp.pt --out " + d +
                             "/bad.bin --quiet --stage1-inference 'rotations=1 spin=3'");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--stage1-inference"), std::string::npos) << out;
  EXPECT_NE(out.find("spin=3"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(d + "/bad.bin"));
  fs::remove_all(dir);
}
#endif

}  // namespace
