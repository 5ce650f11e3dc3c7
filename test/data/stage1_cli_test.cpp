// End-to-end stage-1 commands on two small SynthScan rooms: `dimr synth` -> `dimr stage1
// prepare` -> `dimr train stage1` (tiny network, a few steps) -> `dimr stage1 eval` (JSON,
// PNG) -> `dimr bench stage1`; a corrupt model file gives a clear error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
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

int CountLines(const fs::path& p) {
  std::ifstream in(p);
  int n = 0;
  std::string line;
  while (std::getline(in, line)) n += !line.empty();
  return n;
}

TEST(Stage1Cli, TrainEvalBenchOnTwoRooms) {
  if (RunCli("train stage1 --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("stage1_cli");
  const std::string d = dir.string();

  auto [rc, out] = RunCli(
      "synth --scenes 2 --seed 5 --split val --frames-per-scene 16 --quiet --out " + d + "/synth");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = RunCli("stage1 prepare --scans " + d + "/synth --out " + d + "/cache.bin");
  ASSERT_EQ(rc, 0) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex("2 scenes, ([0-9]+) points"))) << out;
  const long long points = std::stoll(m[1]);
  ASSERT_GT(points, 1000);

  const std::string model = d + "/model";
  std::tie(rc, out) =
      RunCli("train stage1 --train " + d + "/cache.bin --val " + d + "/cache.bin --out " + model +
             " --config 'scale=10 rgb=0 widths=8,16 reps=1 classes=25' --epochs 2 --batch 1 "
             "--threads 1 --quiet --seed 3 --wall-plane-weight 3 --wall-plane-context 0.3");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("after 4 steps"), std::string::npos) << out;
  // Hard examples: the windows (and closed doors) of SynthScan rooms lie in their walls' planes.
  // With --wall-plane-context 0.3 the wall around them is weighted too: wall points are counted.
  ASSERT_TRUE(std::regex_search(out, m, std::regex("wall-plane weight 3 on ([0-9]+) points")))
      << out;
  EXPECT_GT(std::stoll(m[1]), 0) << out;
  EXPECT_LT(std::stoll(m[1]), points / 3) << out;
  EXPECT_NE(out.find("and the wall within 0.3 m of them"), std::string::npos) << out;
  EXPECT_TRUE(std::regex_search(out, std::regex("by class:.* wall [1-9][0-9]*"))) << out;
  ASSERT_TRUE(fs::exists(model + "/stage1.pt"));
  EXPECT_EQ(CountLines(model + "/train_log.csv"), 1 + 4);  // header + 2 epochs x 2 scenes
  EXPECT_GE(CountLines(model + "/val_log.csv"), 2);        // header + at least one epoch
  const std::string card = ReadFileText(model + "/model.yaml");
  EXPECT_TRUE(std::regex_search(card, std::regex("sha256: [0-9a-f]{64}\n"))) << card;
  EXPECT_NE(card.find("architecture: \"scale=10 rgb=0 widths=8,16 reps=1 classes=25\""),
            std::string::npos)
      << card;
  EXPECT_NE(card.find("semantic_miou_present:"), std::string::npos) << card;
  EXPECT_NE(card.find("wall_plane_weight: 3\n"), std::string::npos) << card;
  EXPECT_NE(card.find("wall_plane_context: 0.3\n"), std::string::npos) << card;
  EXPECT_NE(RunCli("train stage1 --train " + d + "/cache.bin --out " + d +
                   "/never --wall-plane-context 0.3")
                .first,
            0);
  EXPECT_NE(
      RunCli("train stage1 --train " + d + "/cache.bin --out " + d + "/never --wall-plane-weight 0")
          .first,
      0);
  // The recorded command can be pasted back into a shell: values with spaces are quoted.
  EXPECT_NE(card.find("--config 'scale=10 rgb=0 widths=8,16 reps=1 classes=25'"), std::string::npos)
      << card;

  // Evaluation: JSON with every point counted, metrics in range, one PNG.
  std::tie(rc, out) =
      RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d + "/cache.bin --json " + d +
             "/eval.json --render 1 --render-dir " + d + "/png --min-objects 0");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json j = nlohmann::json::parse(ReadFileText(d + "/eval.json"));
  EXPECT_EQ(j["scenes"].get<int>(), 2);
  EXPECT_EQ(j["points"].get<long long>(), points);
  EXPECT_GE(j["miou_present"].get<double>(), 0.0);
  EXPECT_LE(j["miou_present"].get<double>(), 1.0);
  EXPECT_GE(j["accuracy"].get<double>(), 0.0);
  EXPECT_GT(j["classes_present"].get<int>(), 2);  // at least wall, floor and one object class
  EXPECT_TRUE(j["instance"].contains("chair"));
  // --min-objects 0: every class present is "supported", so that mean is the present mean.
  EXPECT_EQ(j["supported_min_objects"].get<int>(), 0);
  EXPECT_EQ(j["classes_supported"].get<int>(), j["classes_present"].get<int>());
  EXPECT_NEAR(j["miou_supported"].get<double>(), j["miou_present"].get<double>(), 1e-12);
  // Support: both rooms have a floor; the same rooms twice (below) count twice.
  EXPECT_EQ(j["semantic_support"]["floor"]["scenes"].get<int>(), 2);
  EXPECT_GT(j["semantic_support"]["floor"]["points"].get<long long>(), 0);
  EXPECT_EQ(j["semantic_support"]["bed"]["scenes"].get<int>() > 0,
            j["semantic_support"]["bed"]["points"].get<long long>() > 0);
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(d + "/png")) {
    EXPECT_EQ(ReadFileText(e.path()).substr(1, 3), "PNG");
    ++pngs;
  }
  EXPECT_EQ(pngs, 1);
  // --dump: the first scene as a labelled cloud, one vertex per point, GT labels as stored.
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --limit 1 --dump 1 --dump-dir " + d + "/dump");
  ASSERT_EQ(rc, 0) << out;
  std::vector<fs::path> dumps;
  for (const auto& e : fs::directory_iterator(d + "/dump")) dumps.push_back(e.path());
  ASSERT_EQ(dumps.size(), 1u);
  {
    const std::string ply = ReadFileText(dumps[0]);
    const std::size_t end = ply.find("end_header\n");
    ASSERT_NE(end, std::string::npos);
    const std::string header = ply.substr(0, end);
    for (const char* prop : {"property short gt_label", "property short pred_label",
                             "property int gt_instance", "property int pred_instance"}) {
      EXPECT_NE(header.find(prop), std::string::npos) << header;
    }
    std::smatch vm;
    ASSERT_TRUE(std::regex_search(header, vm, std::regex("element vertex ([0-9]+)"))) << header;
    const long long vertices = std::stoll(vm[1]);
    EXPECT_GT(vertices, 100);
    EXPECT_LT(vertices, points);  // one of the two rooms
    // Body: float xyz (+ uchar rgb if coloured) + short + short + int + int per vertex.
    const long long body = static_cast<long long>(ply.size() - end - 11);
    EXPECT_TRUE(body == vertices * 24 || body == vertices * 27) << body << " " << vertices;
  }
  EXPECT_EQ(j["rotations"].get<int>(), 1);  // no card recommendation yet: plain inference
  EXPECT_FALSE(j["mirror"].get<bool>());

  // Scene sets: --scans / --train repeat and concatenate, PATH@N includes a set N times (the
  // same scenes twice give the same mIoU over twice the points); a bad count is an error.
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --scans " + d + "/synth --json " + d + "/eval_sets.json");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json js = nlohmann::json::parse(ReadFileText(d + "/eval_sets.json"));
  EXPECT_EQ(js["scenes"].get<int>(), 4);
  EXPECT_EQ(js["points"].get<long long>(), 2 * points);
  EXPECT_NEAR(js["miou_present"].get<double>(), j["miou_present"].get<double>(), 1e-9);
  EXPECT_EQ(js["semantic_support"]["floor"]["scenes"].get<int>(), 4);
  // The default floor of 10 objects: only classes with that many objects in the 4 rooms count.
  EXPECT_EQ(js["supported_min_objects"].get<int>(), 10);
  int expect_supported = 0;
  for (const auto& [name, sup] : js["semantic_support"].items()) {
    if (sup["points"].get<long long>() > 0 && sup["objects"].get<int>() >= 10) ++expect_supported;
  }
  EXPECT_EQ(js["classes_supported"].get<int>(), expect_supported);
  EXPECT_EQ(js["semantic_support"]["chair"]["objects"].get<int>(),
            2 * j["semantic_support"]["chair"]["objects"].get<int>());
  EXPECT_EQ(js["instance"]["chair"]["gt_instances"].get<int>(),
            2 * j["instance"]["chair"]["gt_instances"].get<int>());
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin@3 --json " + d + "/eval_rep.json");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_EQ(nlohmann::json::parse(ReadFileText(d + "/eval_rep.json"))["scenes"].get<int>(), 6);
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --min-objects -1");
  EXPECT_NE(rc, 0) << out;
  EXPECT_NE(out.find("min-objects"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("train stage1 --train " + d + "/cache.bin@2 --train " + d +
                             "/cache.bin --out " + d + "/model_sets" +
                             " --config 'scale=10 rgb=0 widths=8,16 reps=1 classes=25' --epochs 1 "
                             "--batch 1 --threads 1 --quiet --seed 3");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("after 6 steps"), std::string::npos) << out;  // 3 x 2 scenes, batch 1
  EXPECT_NE(ReadFileText(d + "/model_sets/model.yaml").find("train_scenes: 6"), std::string::npos);
  // --init into a deeper --config (reps 1 -> 2): the added blocks start as the identity; a
  // --config that differs in anything else is refused, naming both configurations.
  auto train_from_model = [&](const std::string& out_name, const std::string& config) {
    return RunCli("train stage1 --train " + d + "/cache.bin --out " + d + "/" + out_name +
                  " --init " + model + "/stage1.pt --config '" + config +
                  "' --epochs 1 --batch 1 --threads 1 --quiet --seed 3");
  };
  std::tie(rc, out) =
      train_from_model("model_deep", "scale=10 rgb=0 widths=8,16 reps=2 classes=25");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("residual blocks per level and side 1 -> 2"), std::string::npos) << out;
  EXPECT_NE(ReadFileText(d + "/model_deep/model.yaml")
                .find("architecture: \"scale=10 rgb=0 widths=8,16 reps=2 classes=25\""),
            std::string::npos);
  std::tie(rc, out) = train_from_model("model_bad", "scale=10 rgb=0 widths=8,24 reps=2 classes=25");
  EXPECT_NE(rc, 0) << out;
  EXPECT_NE(out.find("widths=8,16 reps=1"), std::string::npos) << out;
  for (const char* bad : {"@0", "@x", "@101"}) {
    std::tie(rc, out) =
        RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d + "/cache.bin" + bad);
    EXPECT_NE(rc, 0) << bad;
    EXPECT_NE(out.find("repeat count after '@'"), std::string::npos) << out;
  }

  // The card's recommended_inference sets the defaults; flags override them; a bad value is
  // an error naming the card.
  std::ofstream(model + "/model.yaml", std::ios::app)
      << "recommended_inference: \"passes=s0.12,s0.2 rotations=2 mirror=1 vote_radius=0.05 "
         "vote_min_points=4\"   # chosen on validation\n";
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --json " + d + "/eval_card.json");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json jc = nlohmann::json::parse(ReadFileText(d + "/eval_card.json"));
  EXPECT_EQ(jc["rotations"].get<int>(), 2);
  EXPECT_TRUE(jc["mirror"].get<bool>());
  EXPECT_DOUBLE_EQ(jc["vote_radius"].get<double>(), 0.05);
  EXPECT_EQ(jc["vote_min_points"].get<int>(), 4);
  EXPECT_EQ(jc["clustering_passes"].get<std::string>(), "s0.120,s0.200");
  EXPECT_EQ(jc["points"].get<long long>(), points);
  std::tie(rc, out) =
      RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
             "/cache.bin --rotations 3 --mirror=false --json " + d + "/eval_flags.json");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json jf = nlohmann::json::parse(ReadFileText(d + "/eval_flags.json"));
  EXPECT_EQ(jf["rotations"].get<int>(), 3);
  EXPECT_FALSE(jf["mirror"].get<bool>());
  EXPECT_DOUBLE_EQ(jf["vote_radius"].get<double>(), 0.05);
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --rotations 5");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("rotations"), std::string::npos) << out;
  const std::string good_card = ReadFileText(model + "/model.yaml");
  {
    std::ofstream f(model + "/model.yaml");
    f << "recommended_inference: \"rotations=2 spin=3\"\n";
  }
  std::tie(rc, out) =
      RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d + "/cache.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("model.yaml"), std::string::npos) << out;
  EXPECT_NE(out.find("spin=3"), std::string::npos) << out;
  std::ofstream(model + "/model.yaml") << good_card;

  // Benchmark table + JSON.
  std::tie(rc, out) =
      RunCli("bench stage1 --model " + model + "/stage1.pt --rooms 1 --points 5000 " +
             "--repeats 1 --json " + d + "/bench.json");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("| U-Net convolutions |"), std::string::npos) << out;
  EXPECT_NE(out.find("| kernel maps (rulebooks) |"), std::string::npos) << out;
  const nlohmann::json b = nlohmann::json::parse(ReadFileText(d + "/bench.json"));
  EXPECT_EQ(b["points_per_room"].get<int>(), 5000);
  EXPECT_GT(b["median_ms"]["unet"].get<double>(), 0.0);
  EXPECT_GE(b["median_ms"]["total"].get<double>(), b["median_ms"]["unet"].get<double>());
  // The header names every kernel path; the heads / U-Net ratio (issue 21) is per run, so with
  // one room and one repeat it is the table's heads median over its U-Net median.
  EXPECT_NE(out.find(", heads "), std::string::npos) << out;
  EXPECT_EQ(b["heads_kernels"].get<std::string>(), b["sparse_kernels"].get<std::string>() == "gemm"
                                                       ? "generic"
                                                       : b["sparse_kernels"].get<std::string>());
  EXPECT_NE(out.find("heads / U-Net convolutions per run: median"), std::string::npos) << out;
  EXPECT_NEAR(b["median_heads_per_unet"].get<double>(),
              b["median_ms"]["heads"].get<double>() / b["median_ms"]["unet"].get<double>(), 1e-9);
  // The bench runs the settings `stage1 eval` runs (the card's: 2 rotations x mirror).
  EXPECT_EQ(b["inference"].get<std::string>(), jc["inference"].get<std::string>());
  EXPECT_NE(out.find("4 network passes per room"), std::string::npos) << out;

  // Calibration: the fitted class bias never lowers the mIoU, and `stage1 eval` with the
  // printed bias and vote exclusions reproduces exactly the mIoU calibrate reports.
  std::tie(rc, out) =
      RunCli("stage1 calibrate --model " + model + "/stage1.pt --scans " + d +
             "/cache.bin --step 0.25 --vote-radii 0.05 0.1 --json " + d + "/calib.json");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("recommended_inference: \"passes=s0.12,s0.2 rotations=2"), std::string::npos)
      << out;
  const nlohmann::json jk = nlohmann::json::parse(ReadFileText(d + "/calib.json"));
  ASSERT_EQ(jk["class_bias"].size(), 25u);
  const double radius = jk["vote_radius"].get<double>();
  EXPECT_TRUE(radius == 0.05 || radius == 0.1) << radius;
  ASSERT_EQ(jk["cross_validation"].size(), 5u);  // shrink factors 0, 0.25, ..., 1 on 2 folds
  double best_cv = -1, chosen_cv = -1;
  for (const auto& e : jk["cross_validation"]) {
    best_cv = std::max(best_cv, e["heldout_miou"].get<double>());
    if (e["shrink"].get<double>() == jk["shrink"].get<double>()) {
      chosen_cv = e["heldout_miou"].get<double>();
    }
  }
  EXPECT_DOUBLE_EQ(chosen_cv, best_cv);
  EXPECT_GE(jk["miou_argmax"]["after"].get<double>(), jk["miou_argmax"]["before"].get<double>());
  EXPECT_GE(jk["miou_vote"]["after"].get<double>(), jk["miou_vote"]["with_bias"].get<double>());
  std::string bias;
  for (const auto& v : jk["class_bias"]) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%s%.2f", bias.empty() ? "" : ",", v.get<double>());
    bias += buf;
  }
  std::string exclude = jk["vote_exclude"].get<std::string>();
  if (exclude.empty()) exclude = "none";
  std::tie(rc, out) =
      RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
             "/cache.bin --class-bias " + bias + " --vote-exclude " + exclude + " --vote-radius " +
             std::to_string(jk["vote_radius"].get<double>()) + " --json " + d + "/eval_bias.json");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json jb = nlohmann::json::parse(ReadFileText(d + "/eval_bias.json"));
  EXPECT_NEAR(jb["miou_present"].get<double>(), jk["miou_vote"]["after"].get<double>(), 1e-9);
  EXPECT_NEAR(jc["miou_present"].get<double>(), jk["miou_vote"]["before"].get<double>(), 1e-9);
  std::tie(rc, out) = RunCli("stage1 calibrate --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --folds 3");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--folds 3 exceeds the 2 scenes"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --class-bias 0.1,0.2");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("'class_bias=0.1,0.2': 2 values, expected 25"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --rotations 6x");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("'rotations=6x'"), std::string::npos) << out;
  // --preset fast: one network pass, the card's clustering and vote kept.
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --preset fast --json " + d + "/eval_fast.json");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json jq = nlohmann::json::parse(ReadFileText(d + "/eval_fast.json"));
  EXPECT_EQ(jq["rotations"].get<int>(), 1);
  EXPECT_FALSE(jq["mirror"].get<bool>());
  EXPECT_DOUBLE_EQ(jq["vote_radius"].get<double>(), 0.05);
  std::tie(rc, out) = RunCli("stage1 eval --model " + model + "/stage1.pt --scans " + d +
                             "/cache.bin --vote-exclude picture,sofa2");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("'sofa2' is not an RFS class name"), std::string::npos) << out;

  // Averaging a model with itself gives that model: same metrics (plain inference, no card).
  std::tie(rc, out) = RunCli("stage1 average --models " + model + "/stage1.pt " + model +
                             "/stage1.pt --out " + d + "/avg/avg.pt");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("averaged 2 models"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("stage1 eval --model " + d + "/avg/avg.pt --scans " + d +
                             "/cache.bin --json " + d + "/eval_avg.json");
  ASSERT_EQ(rc, 0) << out;
  const nlohmann::json ja = nlohmann::json::parse(ReadFileText(d + "/eval_avg.json"));
  EXPECT_DOUBLE_EQ(ja["miou_present"].get<double>(), j["miou_present"].get<double>());
  std::tie(rc, out) = RunCli("stage1 average --models " + model + "/stage1.pt " + d +
                             "/nope.pt --out " + d + "/avg2.pt");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("nope.pt"), std::string::npos) << out;

  // Fine-tuning from the trained weights: the card records the source, the first logged loss
  // is that of the trained model (below the fresh run's first loss); a model of another
  // configuration is refused, naming both configurations.
  std::tie(rc, out) =
      RunCli("train stage1 --train " + d + "/cache.bin --out " + d + "/tuned --init " + model +
             "/stage1.pt --config 'scale=10 rgb=0 widths=8,16 reps=1 classes=25' --epochs 1 "
             "--batch 1 --threads 1 --quiet --seed 3 --max-minutes 5 --lr-by-time");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("initialised from"), std::string::npos) << out;
  const std::string tuned_card = ReadFileText(d + "/tuned/model.yaml");
  EXPECT_NE(tuned_card.find("initialised_from: \"" + model + "/stage1.pt\""), std::string::npos)
      << tuned_card;
  EXPECT_NE(tuned_card.find("lr_schedule: by time"), std::string::npos) << tuned_card;
  std::tie(rc, out) =
      RunCli("train stage1 --train " + d + "/cache.bin --out " + d + "/tuned2 --init " + model +
             "/stage1.pt --config 'scale=10 rgb=0 widths=8,16,24 reps=1 classes=25' --epochs 1 "
             "--quiet");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("widths=8,16 "), std::string::npos) << out;
  EXPECT_NE(out.find("widths=8,16,24"), std::string::npos) << out;

  // A corrupt model file: non-zero exit, the message names the file.
  std::ofstream(d + "/junk.pt") << "definitely not a model";
  std::tie(rc, out) = RunCli("stage1 eval --model " + d + "/junk.pt --scans " + d + "/cache.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("junk.pt"), std::string::npos) << out;
  // Missing training data: non-zero exit naming the path.
  std::tie(rc, out) = RunCli("train stage1 --train " + d + "/nothing --out " + d + "/m2");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("nothing"), std::string::npos) << out;
  fs::remove_all(dir);
}
#endif

}  // namespace
