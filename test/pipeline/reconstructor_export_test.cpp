// `dimr export gt` (the evaluation GT of a SynthScan split): GT evaluated against itself gives
// 100 on every metric, and the PCR points lie on the placed GT meshes.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "../cli_run.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/pipeline/placement.h"
#include "dimr/pipeline/shape_pool.h"

#ifdef DIMR_CLI
namespace dimr {
namespace {

namespace fs = std::filesystem;

TEST(ExportGt, GroundTruthAgainstItselfScoresOneHundred) {
  const fs::path dir = testing::FreshTempDir("dimr_export_gt");
  auto [rc, out] = testing::RunCli(
      "synth --scenes 1 --seed 3 --split val --frames-per-scene 20 "
      "--quiet --out " +
      (dir / "split").string());
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = testing::RunCli("export gt --split " + (dir / "split").string() + " --out " +
                                      (dir / "gt").string());
  ASSERT_EQ(rc, 0) << out;
  int meshes = 0;
  for (const auto& e : fs::directory_iterator(dir / "gt" / "meshes")) {
    const std::string name = e.path().filename().string();
    EXPECT_EQ(name.rfind("scene5000_00_", 0), 0u) << name;
    EXPECT_EQ(name.substr(name.size() - 6), "_1.ply") << name;
    EXPECT_FALSE(geometry::ReadPlyMesh(e.path().string()).empty()) << name;
    ++meshes;
  }
  EXPECT_GE(meshes, 3);
  const auto pts = geometry::ReadPlyCloud((dir / "gt" / "points" / "scene5000_00.ply").string());
  EXPECT_GT(pts.size(), 1000u);
  EXPECT_NE(pts.FindAttribute("semantic_label"), nullptr);
  EXPECT_NE(pts.FindAttribute("instance_label"), nullptr);
  const std::string gt = (dir / "gt").string();
  std::tie(rc, out) =
      testing::RunCli("eval --quiet --metrics iou,cd,pcr --pred " + gt + "/meshes --gt " + gt +
                      "/meshes --gt-points " + gt + "/points");
  ASSERT_EQ(rc, 0) << out;
  // Table 1 (IoU@0.25, IoU@0.5, CD@0.1, CD@0.047) and the PCR mean (the last column): 100.
  EXPECT_NE(out.find("| 100.00 | 100.00 | 100.00 | 100.00 |"), std::string::npos) << out;
  const auto pcr = out.find("paper Table 2");
  ASSERT_NE(pcr, std::string::npos) << out;
  const auto row_end = out.find("\n\n", out.find("|---", pcr));
  const std::string row = out.substr(0, row_end);
  EXPECT_EQ(row.substr(row.rfind('|', row.size() - 2)), "| 100.00 |") << row;
}

TEST(ExportPoolMeshes, EveryShippedPoolModelGetsItsCadMesh) {
  const fs::path dir = testing::FreshTempDir("dimr_export_pool");
  const std::string pool = std::string(DIMR_SOURCE_DIR) + "/models/bsp/pool.bin";
  auto [rc, out] =
      testing::RunCli("export pool-meshes --pool " + pool + " --out " + (dir / "tree").string() +
                      " --write-pool " + (dir / "pool.bin").string());
  ASSERT_EQ(rc, 0) << out;
  const pipeline::ShapePool with = pipeline::ShapePool::Load((dir / "pool.bin").string());
  const pipeline::ShapePool shipped = pipeline::ShapePool::Load(pool);
  EXPECT_EQ(with.ContentHash(), shipped.ContentHash());
  EXPECT_EQ(static_cast<std::size_t>(with.NumWithMeshes()), with.size());
  // A mesh is the model it claims: a non-empty canonical mesh in the entry's own folder.
  const auto& e = with.entries()[7];
  EXPECT_NE(e.mesh_path.find(e.model_id), std::string::npos);
  EXPECT_FALSE(pipeline::ReadShapeNetMeshCanonical(e.mesh_path).empty());
  // Wrong generator arguments are refused, not silently half-attached.
  std::tie(rc, out) = testing::RunCli("export pool-meshes --pool " + pool + " --seed 2 --out " +
                                      (dir / "bad").string());
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("regenerated 0 of the"), std::string::npos) << out;
}

TEST(ExportGt, AFolderWithoutScenesIsAClearError) {
  const fs::path dir = testing::FreshTempDir("dimr_export_gt_bad");
  fs::create_directories(dir / "shapenet");
  auto [rc, out] =
      testing::RunCli("export gt --split " + dir.string() + " --out " + (dir / "gt").string());
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("holds no ScanNet scene folder"), std::string::npos) << out;
}

}  // namespace
}  // namespace dimr
#endif
