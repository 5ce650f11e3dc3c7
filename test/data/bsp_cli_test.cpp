// `dimr bsp eval` with the bundled BSP-CVAE: the decoding dilation comes from --dilation, else
// from the model card beside the weights (recommended_dilation), else 0; a malformed card is a
// clear error naming it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "cli_run.h"

namespace {

namespace fs = std::filesystem;

#ifdef DIMR_CLI
using dimr::testing::FreshTempDir;
using dimr::testing::ReadFileText;
using dimr::testing::RunCli;

// The content hash `encode-pool` reports, "" if none.
std::string PoolHash(const std::string& out) {
  std::smatch m;
  return std::regex_search(out, m, std::regex("content hash ([0-9a-f]+)")) ? m[1].str()
                                                                           : std::string();
}

double AllIoU(const std::string& out) {
  std::smatch m;
  if (!std::regex_search(out, m, std::regex(R"(\| \*\*all\*\* \| 8 \| \*\*([0-9.]+)\*\*)"))) {
    return -1;
  }
  return std::stod(m[1]);
}

TEST(BspCli, DilationFromOptionOrModelCard) {
  if (RunCli("bsp eval --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("bsp_cli");
  const std::string d = dir.string();
  fs::copy_file(fs::path(DIMR_SOURCE_DIR) / "models/bsp/bsp.pt", dir / "bsp.pt");
  auto [rc, out] = RunCli("bsp prepare --per-class 1 --seed 5 --out " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;

  // No card: the reference (0).
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("dilation 0, distance dilation 0\n"), std::string::npos) << out;
  const double iou0 = AllIoU(out);
  ASSERT_GE(iou0, 0.0) << out;

  // The card's value.
  std::ofstream(d + "/model.yaml") << "name: bsp_cvae\nrecommended_dilation: 0.3   # chosen\n";
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("dilation 0.3, distance dilation 0\n"), std::string::npos) << out;
  const double iou3 = AllIoU(out);
  ASSERT_GE(iou3, 0.0) << out;
  EXPECT_LE(iou3, 1.0);
  EXPECT_NE(iou3, iou0);  // the planes moved: another shape

  // An explicit option wins over the card.
  std::tie(rc, out) =
      RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin --dilation 0");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_DOUBLE_EQ(AllIoU(out), iou0);

  // The distance dilation from the card, alone or with the plane dilation; an option wins.
  std::ofstream(d + "/model.yaml")
      << "recommended_dilation: 0\nrecommended_distance_dilation: 0.01\n";
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("dilation 0, distance dilation 0.01\n"), std::string::npos) << out;
  const double iou_dist = AllIoU(out);
  EXPECT_NE(iou_dist, iou0);
  EXPECT_NE(iou_dist, iou3);
  std::tie(rc, out) =
      RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin --distance-dilation 0");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_DOUBLE_EQ(AllIoU(out), iou0);
  std::ofstream(d + "/model.yaml") << "recommended_distance_dilation: far\n";
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("recommended_distance_dilation"), std::string::npos) << out;
  std::ofstream(d + "/model.yaml") << "name: bsp_cvae\nrecommended_dilation: 0.3   # chosen\n";

  // Latent refinement on the shapes' own occupancy samples raises the mean IoU (0.724 ->
  // 0.734 on these 8 shapes with the bundled model).
  std::tie(rc, out) =
      RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin --refine-steps 30");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_GT(AllIoU(out), iou3 + 0.003) << out;
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d +
                             "/data.bin --refine-steps 3 --refine-lr -1");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("lr"), std::string::npos) << out;

  // The pool: one entry per model; refined codes give another pool (another content hash).
  std::tie(rc, out) = RunCli("encode-pool --model " + d + "/bsp.pt --data " + d +
                             "/data.bin --out " + d + "/pool.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("encoded 8 CAD models"), std::string::npos) << out;
  const std::string plain_hash = PoolHash(out);
  ASSERT_FALSE(plain_hash.empty()) << out;
  std::tie(rc, out) = RunCli("encode-pool --model " + d + "/bsp.pt --data " + d +
                             "/data.bin --out " + d + "/pool_refined.bin --refine-steps 5");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(PoolHash(out), plain_hash) << out;
  EXPECT_NE(PoolHash(out), "") << out;

  // A malformed card: non-zero exit naming the card.
  std::ofstream(d + "/model.yaml") << "recommended_dilation: wide\n";
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("model.yaml"), std::string::npos) << out;
  fs::remove_all(dir);
}

// `bsp prepare --shapenet` / `encode-pool --shapenet`: BSP samples and pool codes straight from a
// ShapeNet-format tree (here one `dimr cad generate` writes; a real ShapeNetCore v2 has the
// same layout): every model once, the 80/10/10 split by model id partitions the tree, the
// bundled model reconstructs the read shapes as well as procedural ones (a reader with the
// wrong axes would not), and bad trees are clear errors naming the file.
TEST(BspCli, PrepareAndPoolFromAShapeNetTree) {
  if (RunCli("bsp prepare --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("bsp_shapenet");
  const std::string d = dir.string();
  auto [rc, out] = RunCli("cad generate --class all --count 3 --seed 40 --out " + d + "/tree");
  ASSERT_EQ(rc, 0) << out;
  auto written = [](const std::string& text) {
    std::smatch m;
    return std::regex_search(text, m, std::regex("wrote ([0-9]+) samples")) ? std::stoi(m[1]) : -1;
  };
  std::tie(rc, out) =
      RunCli("bsp prepare --shapenet " + d + "/tree --jobs 2 --out " + d + "/all.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_EQ(written(out), 24) << out;
  EXPECT_NE(out.find("split all: table 3, chair 3, bookshelf 3, sofa 3"), std::string::npos) << out;
  int split_total = 0;
  for (const char* split : {"train", "val", "test"}) {
    std::tie(rc, out) = RunCli("bsp prepare --shapenet " + d + "/tree --split " + split +
                               " --out " + d + "/" + split + ".bin");
    if (rc == 0) {
      split_total += written(out);
    } else {  // a split this small tree has no model of
      EXPECT_NE(out.find("no model_normalized.obj"), std::string::npos) << out;
    }
  }
  EXPECT_EQ(split_total, 24);
  std::tie(rc, out) = RunCli("bsp prepare --shapenet " + d +
                             "/tree --per-class 1 --classes chair,sofa --out " + d + "/two.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_EQ(written(out), 2) << out;
  EXPECT_NE(out.find("split all: chair 1, sofa 1"), std::string::npos) << out;

  // The bundled model on the read shapes: the test split's level (0.76), not a wrong frame's.
  const std::string model = (fs::path(DIMR_SOURCE_DIR) / "models/bsp/bsp.pt").string();
  std::tie(rc, out) = RunCli("bsp eval --model " + model + " --data " + d + "/all.bin");
  ASSERT_EQ(rc, 0) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex(R"(\| \*\*all\*\* \| 24 \| \*\*([0-9.]+)\*\*)")))
      << out;
  EXPECT_GT(std::stod(m[1]), 0.65) << out;

  // The pool from the tree equals the pool from the prepared file (same codes, same order).
  std::tie(rc, out) = RunCli("encode-pool --model " + model + " --shapenet " + d + "/tree --out " +
                             d + "/pool_tree.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("encoded 24 CAD models"), std::string::npos) << out;
  const std::string tree_hash = PoolHash(out);
  std::tie(rc, out) = RunCli("encode-pool --model " + model + " --data " + d + "/all.bin --out " +
                             d + "/pool_data.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_FALSE(tree_hash.empty());
  EXPECT_EQ(PoolHash(out), tree_hash) << out;

  // --append: an existing pool first, then the new models (a real-furniture import on top of
  // the shipped pool); a model already in the pool is an error naming it.
  std::tie(rc, out) =
      RunCli("cad generate --class chair --count 2 --seed 7001 --out " + d + "/more");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) =
      RunCli("encode-pool --model " + model + " --shapenet " + d + "/more --append " + d +
             "/pool_data.bin --out " + d + "/pool_more.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("encoded 2 CAD models"), std::string::npos) << out;
  EXPECT_NE(out.find("after the 24 entries of " + d + "/pool_data.bin: 26 in all"),
            std::string::npos)
      << out;
  EXPECT_NE(PoolHash(out), tree_hash);
  std::tie(rc, out) = RunCli("encode-pool --model " + model + " --shapenet " + d +
                             "/more --append " + d + "/pool_more.bin --out " + d + "/p2.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("encode-pool: model "), std::string::npos) << out;
  std::tie(rc, out) = RunCli("encode-pool --model " + model + " --shapenet " + d +
                             "/more --append " + d + "/none.bin --out " + d + "/p3.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find(d + "/none.bin"), std::string::npos) << out;

  // Errors: no tree, both sources, a split without a tree, a corrupt model (named).
  std::tie(rc, out) = RunCli("bsp prepare --shapenet " + d + "/none --out " + d + "/x.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find(d + "/none"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("encode-pool --model " + model + " --shapenet " + d + "/tree --data " +
                             d + "/all.bin --out " + d + "/p.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("either --data"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("bsp prepare --per-class 1 --split val --out " + d + "/x.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--split"), std::string::npos) << out;
  std::string victim;
  for (const auto& e : fs::recursive_directory_iterator(dir / "tree")) {
    if (e.path().filename() == "model_normalized.obj") victim = e.path().string();
  }
  ASSERT_FALSE(victim.empty());
  std::ofstream(victim) << "v 0 0 0\nv 1 0 0\nf 1 2 9\n";
  std::tie(rc, out) = RunCli("bsp prepare --shapenet " + d + "/tree --out " + d + "/x.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find(victim), std::string::npos) << out;
  fs::remove_all(dir);
}

// `bsp prepare --jobs`: the same bytes for any number of worker threads.
TEST(BspCli, PrepareIsIndependentOfJobs) {
  if (RunCli("bsp prepare --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("bsp_jobs");
  const std::string d = dir.string();
  auto [rc, out] = RunCli("bsp prepare --per-class 2 --seed 9 --jobs 1 --out " + d + "/a.bin");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = RunCli("bsp prepare --per-class 2 --seed 9 --jobs 3 --out " + d + "/b.bin");
  ASSERT_EQ(rc, 0) << out;
  const std::string a = ReadFileText(dir / "a.bin"), b = ReadFileText(dir / "b.bin");
  EXPECT_GT(a.size(), 16u * 1000u);  // 16 shapes of a 32^3 grid and query points
  EXPECT_TRUE(a == b) << "outputs differ with the job count";
  fs::remove_all(dir);
}

// `train bsp --init`: continues the bundled model in the discrete phase; the model card names
// the start and records a command line that runs again as written (flags without values).
TEST(BspCli, TrainInitContinuesAModel) {
  if (RunCli("train bsp --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("bsp_init");
  const std::string d = dir.string();
  const std::string init = (fs::path(DIMR_SOURCE_DIR) / "models/bsp/bsp.pt").string();
  auto [rc, out] = RunCli("bsp prepare --per-class 1 --seed 5 --jobs 2 --out " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  const std::string train = "train bsp --train " + d + "/data.bin --epochs 0,1,0 --batch 4 " +
                            "--points 256 --threads 1 --fp32 --init " + init;
  std::tie(rc, out) = RunCli(train + " --out " + d + "/run");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("initialised from"), std::string::npos) << out;
  EXPECT_NE(out.find("phase 1"), std::string::npos) << out;  // no continuous epoch ran
  const std::string card = ReadFileText(dir / "run/model.yaml");
  EXPECT_NE(card.find("initialised_from: \"" + init + "\""), std::string::npos) << card;
  EXPECT_NE(card.find("phase: 1"), std::string::npos) << card;
  EXPECT_NE(card.find("dtype: float32"), std::string::npos) << card;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(card, m, std::regex("command: \"dimr ([^\"]*)\"")));
  const std::string again = m[1];
  EXPECT_NE(again.find(" --fp32"), std::string::npos) << again;
  EXPECT_EQ(again.find("--fp32 true"), std::string::npos) << again;
  // The recorded line runs as written (into another folder).
  std::tie(rc, out) =
      RunCli(std::regex_replace(again, std::regex("--out \\S+"), "--out " + d + "/again"));
  EXPECT_EQ(rc, 0) << again << "\n" << out;
  // The trained weights load and decode.
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/run/bsp.pt --data " + d + "/data.bin");
  EXPECT_EQ(rc, 0) << out;
  EXPECT_GE(AllIoU(out), 0.0) << out;
  // A --config that differs from the --init model is refused, naming both.
  std::tie(rc, out) = RunCli(train + " --out " + d + "/bad --config reference");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--init"), std::string::npos) << out;
  fs::remove_all(dir);
}
// `train bsp --latent-targets`: the encoder regresses the pool's codes (matched by model id) with
// a frozen decoder; the card records the targets; a pool without a training model's id, or
// --recon-weight 0 without targets, is refused naming the cause.
TEST(BspCli, TrainDistilsPoolCodes) {
  if (RunCli("train bsp --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("bsp_distill");
  const std::string d = dir.string();
  const std::string init = (fs::path(DIMR_SOURCE_DIR) / "models/bsp/bsp.pt").string();
  auto [rc, out] = RunCli("bsp prepare --per-class 1 --seed 5 --jobs 2 --out " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = RunCli("encode-pool --model " + init + " --data " + d + "/data.bin --out " +
                             d + "/pool.bin --refine-steps 5");
  ASSERT_EQ(rc, 0) << out;
  const std::string train = "train bsp --train " + d + "/data.bin --epochs 0,3,0 --batch 8 " +
                            "--threads 1 --fp32 --freeze-decoder --kl 0 --init " + init;
  std::tie(rc, out) =
      RunCli(train + " --out " + d + "/run --latent-targets " + d + "/pool.bin --recon-weight 0");
  ASSERT_EQ(rc, 0) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex(R"(epoch +3 .*latent_mse ([0-9.]+))"))) << out;
  EXPECT_GT(std::stod(m[1]), 0.0) << out;  // refined codes differ from the encoder's mu
  EXPECT_NE(out.find("recon 0.00000"), std::string::npos) << out;  // nothing decoded
  const std::string card = ReadFileText(dir / "run/model.yaml");
  EXPECT_NE(card.find("latent_targets: \"" + d + "/pool.bin\""), std::string::npos) << card;
  // A pool of other models: the missing id is named.
  std::tie(rc, out) =
      RunCli("bsp prepare --per-class 1 --seed 6 --jobs 2 --out " + d + "/other.bin");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = RunCli("encode-pool --model " + init + " --data " + d + "/other.bin --out " +
                             d + "/other_pool.bin");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) =
      RunCli(train + " --out " + d + "/bad --latent-targets " + d + "/other_pool.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("has no code for training model"), std::string::npos) << out;
  std::tie(rc, out) = RunCli(train + " --out " + d + "/bad2 --recon-weight 0");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--latent-targets"), std::string::npos) << out;
  fs::remove_all(dir);
}
// Real-furniture helpers: `bsp prepare --mirror` adds a mirrored copy of every tree model,
// `train bsp --train A --train B@N` concatenates with B repeated N times (bad counts refused,
// the card names the sets), and `real bsp` reports both IoUs of every model with its cell counts.
TEST(BspCli, MirrorOversampleAndCellIoU) {
  if (RunCli("train bsp --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = FreshTempDir("bsp_oversample");
  const std::string d = dir.string();
  const std::string model = (fs::path(DIMR_SOURCE_DIR) / "models/bsp/bsp.pt").string();
  auto [rc, out] = RunCli("cad generate --class all --count 1 --seed 41 --out " + d + "/tree");
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = RunCli("bsp prepare --shapenet " + d + "/tree --classes chair,sofa --out " +
                             d + "/plain.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("wrote 2 samples"), std::string::npos) << out;
  std::tie(rc, out) = RunCli("bsp prepare --shapenet " + d +
                             "/tree --classes chair,sofa --mirror --out " + d + "/mirror.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("wrote 4 samples"), std::string::npos) << out;
  EXPECT_NE(ReadFileText(dir / "mirror.bin").find("~mirror"), std::string::npos);
  std::tie(rc, out) = RunCli("bsp prepare --per-class 1 --mirror --out " + d + "/x.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("--mirror"), std::string::npos) << out;

  const std::string train = "train bsp --epochs 0,1,0 --batch 4 --points 256 --threads 1 --fp32 " +
                            std::string("--init ") + model + " --train " + d + "/plain.bin";
  std::tie(rc, out) = RunCli(train + " --train " + d + "/mirror.bin@3 --out " + d + "/run");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("14 training shapes"), std::string::npos) << out;  // 2 + 3 x 4
  EXPECT_NE(ReadFileText(dir / "run/model.yaml").find("plain.bin + " + d + "/mirror.bin@3"),
            std::string::npos);
  for (const char* bad : {"@0", "@x", "@101", "@"}) {
    std::tie(rc, out) =
        RunCli(train + " --train " + d + "/mirror.bin" + bad + " --out " + d + "/bad");
    EXPECT_NE(rc, 0) << bad;
    EXPECT_NE(out.find("repeat count"), std::string::npos) << bad << ": " << out;
  }

  // `real bsp` on procedural models: both IoUs per model, cell IoU at the procedural level.
  std::tie(rc, out) = RunCli("real bsp --model " + model + " --shapenet " + d + "/tree");
  ASSERT_EQ(rc, 0) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      out, m, std::regex(R"(\| \*\*all\*\* \| 8 \| \*\*([0-9.]+)\*\* \| \*\*([0-9.]+)\*\* \|)")))
      << out;
  EXPECT_GT(std::stod(m[1]), 0.6) << out;
  EXPECT_GT(std::stod(m[2]), 0.6) << out;
  EXPECT_TRUE(std::regex_search(
      out,
      std::regex(
          R"(\| chair \| [0-9a-f]{8} \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \| [0-9]+ / [0-9]+ \|)")))
      << out;
  fs::remove_all(dir);
}
#endif

}  // namespace
