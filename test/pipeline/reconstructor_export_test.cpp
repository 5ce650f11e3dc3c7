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

// `dimr real export-gt` builds the GT of a real scene from its Scan2CAD alignment (raw ShapeNet
// OBJ mapped by inv(T_scan) T_cad). On a SynthScan room, whose full_annotations.json and
// ShapeNet tree say the same as its boxes, it must agree with `dimr export gt` (canonical mesh
// placed in the box): the box GT scored against the Scan2CAD GT gives 100 on every metric.
TEST(RealExportGt, Scan2CadAlignmentAgreesWithTheBoxPlacement) {
  const fs::path dir = testing::FreshTempDir("dimr_real_export_gt");
  const std::string split = (dir / "split").string();
  auto [rc, out] = testing::RunCli(
      "synth --scenes 1 --seed 4 --split val --frames-per-scene 20 --quiet --out " + split);
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) =
      testing::RunCli("export gt --split " + split + " --out " + (dir / "box").string());
  ASSERT_EQ(rc, 0) << out;
  std::tie(rc, out) = testing::RunCli(
      "real export-gt --scene " + split + "/scans/scene5000_00 --scan2cad " + split +
      "/full_annotations.json --shapenet " + split + "/shapenet --out " + (dir / "s2c").string());
  ASSERT_EQ(rc, 0) << out;
  // The box GT as predictions (reference names need a score).
  fs::create_directories(dir / "pred");
  int meshes = 0;
  for (const auto& e : fs::directory_iterator(dir / "box" / "meshes")) {
    std::string name = e.path().filename().string();
    ASSERT_EQ(name.substr(name.size() - 6), "_1.ply") << name;
    EXPECT_TRUE(fs::exists(dir / "s2c" / "meshes" / name)) << name;
    fs::copy_file(e.path(), dir / "pred" / (name.substr(0, name.size() - 6) + "_0.9.ply"));
    ++meshes;
  }
  EXPECT_GE(meshes, 3);
  const std::string s2c = (dir / "s2c").string();
  std::tie(rc, out) =
      testing::RunCli("eval --quiet --metrics iou,cd,pcr --pred " + (dir / "pred").string() +
                      " --gt " + s2c + "/meshes --gt-points " + s2c + "/points");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("| 100.00 | 100.00 | 100.00 | 100.00 |"), std::string::npos) << out;
  // Bad input: a missing CAD tree names the model.
  std::tie(rc, out) =
      testing::RunCli("real export-gt --scene " + split + "/scans/scene5000_00 --scan2cad " +
                      split + "/full_annotations.json --shapenet " + (dir / "nowhere").string() +
                      " --out " + (dir / "bad").string());
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("not found"), std::string::npos) << out;
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
