#include "dimr/eval/evaluator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "dimr/eval/inputs.h"
#include "dimr/eval/report.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"
#include "eval/test_meshes.h"

namespace dimr::eval {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;
using testing::Box;

TEST(InputsTest, ReferenceNames) {
  MeshRecord r = ParseReferenceName("/x/scene0011_00_3_chair_0.9123.ply");
  EXPECT_EQ(r.scene, "scene0011_00");
  EXPECT_EQ(r.cls, 1);
  EXPECT_DOUBLE_EQ(r.score, 0.9123);
  EXPECT_EQ(ParseReferenceName("scene0011_00_12_trash_bin_0.5.ply").cls, 4);
  EXPECT_EQ(ParseReferenceName("scene0011_00_12_trash_0.5.ply").cls, 4);
  EXPECT_DOUBLE_EQ(ParseReferenceName("scene0011_00_1_table_1.ply").score, 1.0);
  EXPECT_THROW(ParseReferenceName("scene0011_00_3_lamp_0.9.ply"), ParseError);
  EXPECT_THROW(ParseReferenceName("scene0011_00_3_chair_high.ply"), ParseError);
  EXPECT_THROW(ParseReferenceName("scene0011_00_chair.ply"), ParseError);
}

TEST(InputsTest, PcrGtFirstVertexLabel) {
  // Instance 1: first vertex chair (4) -> chair with 3 points even though one point says table;
  // instance 2: first vertex 255 -> skipped; instance 3: wall -> non-CAD, skipped;
  // instance 5: sink (17) -> bathtub. Instance 4 is empty.
  std::vector<Vec3> p(8, Vec3::Zero());
  std::vector<int> sem = {4, 6, 255, 4, 0, 4, 17, 1};
  std::vector<int> ins = {1, 1, 2, 2, 3, 1, 5, 0};
  auto g = PcrGtFromArrays("s", p, sem, ins);
  ASSERT_EQ(g.size(), 2u);
  EXPECT_EQ(g[0].cls, 1);
  EXPECT_EQ(g[0].points.size(), 3u);
  EXPECT_EQ(g[1].cls, 7);
}

class EvalFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("dimr_eval_test_" + std::to_string(reinterpret_cast<std::uintptr_t>(this)));
    fs::remove_all(root_);
    fs::create_directories(root_ / "gt");
    fs::create_directories(root_ / "pred");
    fs::create_directories(root_ / "points");
    auto gt = [&](const std::string& name, const geometry::TriangleMesh& m) {
      geometry::WritePly((root_ / "gt" / name).string(), m);
    };
    auto pred = [&](const std::string& name, const geometry::TriangleMesh& m) {
      geometry::WritePly((root_ / "pred" / name).string(), m);
    };
    gt("scene0000_00_0_chair_1.ply", Box({0, 0, 0}, {1, 1, 1}));
    gt("scene0000_00_1_table_1.ply", Box({3, 0, 0}, {4, 1, 1}));
    gt("scene0001_00_0_chair_1.ply", Box({0, 0, 0}, {1, 1, 1}));
    pred("scene0000_00_0_chair_0.9000.ply", Box({0, 0, 0}, {1, 1, 1}));        // IoU 1
    pred("scene0000_00_1_chair_0.8000.ply", Box({10, 0, 0}, {11, 1, 1}));      // IoU 0
    pred("scene0000_00_2_table_0.7000.ply", Box({3.25, 0, 0}, {4.25, 1, 1}));  // 16/26
    pred("scene0001_00_3_chair_0.8000.ply", Box({0.5, 0, 0}, {1.5, 1, 1}));    // 11/31
    pred("scene0009_00_0_chair_0.9500.ply", Box({0, 0, 0}, {1, 1, 1}));        // no GT scene
    // PCR GT: 11 x 11 points on the top faces, labelled by RFS id and 1-based instance.
    auto points = [&](const std::string& scene,
                      const std::vector<std::tuple<double, int, int>>& insts) {
      geometry::PointCloud c;
      std::vector<double> sem, ins;
      for (const auto& [x0, label, id] : insts) {
        for (int i = 0; i <= 10; ++i) {
          for (int j = 0; j <= 10; ++j) {
            c.points.emplace_back(x0 + i / 10.0, j / 10.0, 1.0);
            sem.push_back(label);
            ins.push_back(id);
          }
        }
      }
      c.SetAttribute("semantic_label", geometry::ScalarType::kUInt8, sem);
      c.SetAttribute("instance_label", geometry::ScalarType::kUInt8, ins);
      geometry::WritePly((root_ / "points" / (scene + ".ply")).string(), c);
    };
    points("scene0000_00", {{0.0, 4, 1}, {3.0, 6, 2}, {6.0, 0, 3}});
    points("scene0001_00", {{0.0, 4, 1}});
  }
  void TearDown() override { fs::remove_all(root_); }

  EvalInputs Load() {
    EvalInputs in;
    in.gt = ListMeshFolder((root_ / "gt").string());
    in.preds = ListMeshFolder((root_ / "pred").string());
    in.pcr_gt = LoadPcrGtFolder((root_ / "points").string(), &in.pcr_scenes);
    return in;
  }

  fs::path root_;
};

TEST_F(EvalFixture, HandComputedAp) {
  const EvalInputs in = Load();
  ASSERT_EQ(in.gt.size(), 3u);
  ASSERT_EQ(in.preds.size(), 5u);
  ASSERT_EQ(in.pcr_gt.size(), 3u);  // wall instance skipped
  EvalOptions opt;
  opt.SetMetrics("iou,lfd,pcr");
  opt.threads = 2;
  const EvalReport r = Evaluate(in, opt);
  EXPECT_EQ(r.num_scenes, 2);
  EXPECT_EQ(r.dropped_preds, 1);
  EXPECT_EQ(r.num_preds, 4);
  // Chair at IoU 0.25: ranked 0.9 TP, 0.8 FP (scene0000, far), 0.8 TP (scene0001; the tie keeps
  // scene order): rec 1/2 1/2 1, prec 1 1/2 2/3 -> AP = (6 * 1 + 5 * 2/3) / 11 = 28/33.
  const ApTable* iou25 = r.Find("iou", 0.25);
  ASSERT_NE(iou25, nullptr);
  EXPECT_NEAR(iou25->classes[1].ap, 28.0 / 33.0, 1e-12);
  EXPECT_NEAR(iou25->classes[1].precision, 2.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(iou25->classes[0].ap, 1.0);
  EXPECT_TRUE(iou25->present[0] && iou25->present[1] && !iou25->present[2]);
  EXPECT_NEAR(iou25->map, (28.0 / 33.0 + 1.0) / 2.0, 1e-12);
  EXPECT_NEAR(iou25->mean_precision, (2.0 / 3.0 + 1.0) / 2.0, 1e-12);
  // At 0.5 the shifted chair (11/31) fails: TP FP FP -> AP 6/11.
  const ApTable* iou50 = r.Find("iou", 0.5);
  EXPECT_NEAR(iou50->classes[1].ap, 6.0 / 11.0, 1e-12);
  EXPECT_DOUBLE_EQ(iou50->classes[0].ap, 1.0);  // 16/26 > 0.5
  // LFD ignores location: every chair prediction is the GT shape (distance 36 < 2500) but the
  // far copy loses its GT to the 0.9 prediction -> same sequence, 28/33.
  EXPECT_NEAR(r.Find("lfd", 2500)->classes[1].ap, 28.0 / 33.0, 1e-12);
  // PCR: exact chair covers 121/121, far chair 0, shifted chair x >= 0.5 -> 66/121 > 0.5, the
  // shifted table 88/121: same ranking again -> 28/33 and 1.
  const ApTable* pcr = r.Find("pcr", 0.5);
  ASSERT_NE(pcr, nullptr);
  EXPECT_NEAR(pcr->classes[1].ap, 28.0 / 33.0, 1e-12);
  EXPECT_DOUBLE_EQ(pcr->classes[0].ap, 1.0);
  EXPECT_EQ(pcr->classes[1].npos, 2);

  // Per GT object: its best IoU among the predictions of its scene and class (the far chair
  // and the other scene's shapes do not count), LFD asked, CD not.
  ASSERT_EQ(r.objects.size(), 3u);
  EXPECT_EQ(r.objects[0].name, "scene0000_00_0_chair_1.ply");
  EXPECT_NEAR(r.objects[0].best_iou, 1.0, 1e-12);
  EXPECT_EQ(r.objects[0].best_iou_name, "scene0000_00_0_chair_0.9000.ply");
  EXPECT_EQ(r.objects[0].best_iou_pred, 0);
  EXPECT_NEAR(r.objects[1].best_iou, 16.0 / 26.0, 1e-12);  // the table
  EXPECT_EQ(r.objects[1].cls, 0);
  EXPECT_NEAR(r.objects[2].best_iou, 11.0 / 31.0, 1e-12);  // scene0001's chair
  EXPECT_EQ(r.objects[2].best_iou_name, "scene0001_00_3_chair_0.8000.ply");
  EXPECT_TRUE(std::isnan(r.objects[2].best_cd));
  EXPECT_LT(r.objects[2].best_lfd, 2500.0);
  const std::string objects = FormatObjectsMarkdown(r);
  EXPECT_NE(objects.find("| scene0000_00 | scene0000_00_1_table_1.ply | table | 0.615 |"),
            std::string::npos)
      << objects;

  const std::string md = FormatMarkdown(r);
  EXPECT_NE(md.find("IoU@0.25"), std::string::npos);
  EXPECT_NE(md.find("84.85"), std::string::npos);  // 28/33
  const std::string js = FormatJson(r);
  EXPECT_NE(js.find("\"mAP\""), std::string::npos);
  EXPECT_NE(js.find("\"best_iou_prediction\""), std::string::npos);
  const std::string svg = PrCurveSvg(*iou25);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("polyline"), std::string::npos);
}

TEST_F(EvalFixture, CorrectedProtocolAndChamfer) {
  const EvalInputs in = Load();
  EvalOptions opt;
  opt.SetMetrics("cd,lfd");
  opt.protocol = Protocol::kCorrected;
  opt.threads = 1;
  const EvalReport r = Evaluate(in, opt);
  // Corrected CD: one sample set per mesh keyed by content, so the exact copy has CD 0 and is a
  // TP at both thresholds; the far copy (CD ~ 10) is an FP.
  const ApTable* cd = r.Find("cd", 0.047);
  ASSERT_NE(cd, nullptr);
  EXPECT_EQ(cd->classes[1].matched_gt.front(), 0);
  EXPECT_EQ(cd->classes[1].matched_gt[1], -1);
  // Deterministic: the same numbers twice.
  const EvalReport r2 = Evaluate(in, opt);
  EXPECT_EQ(r2.Find("cd", 0.1)->classes[0].ap, r.Find("cd", 0.1)->classes[0].ap);
  EXPECT_NEAR(r.Find("lfd", 2500)->classes[1].ap, 28.0 / 33.0, 1e-12);
}

TEST_F(EvalFixture, Errors) {
  EvalInputs in = Load();
  EvalOptions opt;
  opt.SetMetrics("iou");
  in.preds.push_back(in.preds.front());
  in.preds.back().path = (root_ / "pred" / "missing.ply").string();
  in.preds.back().scene = "scene0000_00";
  try {
    Evaluate(in, opt);
    FAIL() << "expected a ParseError";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.ply"), std::string::npos);
  }
  EXPECT_THROW(opt.SetMetrics("iou,xyz"), InvalidArgument);
  EXPECT_THROW(ListMeshFolder((root_ / "nope").string()), ParseError);
  // An unknown class in a file name names the file.
  geometry::WritePly((root_ / "pred" / "scene0000_00_9_lamp_0.5.ply").string(),
                     Box({0, 0, 0}, {1, 1, 1}));
  EXPECT_THROW(ListMeshFolder((root_ / "pred").string()), ParseError);
  fs::remove(root_ / "pred" / "scene0000_00_9_lamp_0.5.ply");
  // PCR without point GT.
  EvalInputs no_pts = Load();
  no_pts.pcr_scenes.clear();
  opt.SetMetrics("pcr");
  EXPECT_THROW(Evaluate(no_pts, opt), InvalidArgument);
}

TEST_F(EvalFixture, SceneResultJsonRoundTrip) {
  MeshRecord a;
  a.cls = 1;
  a.score = 0.9;
  a.path = (root_ / "pred" / "scene0000_00_0_chair_0.9000.ply").string();
  MeshRecord b = a;
  b.cls = 0;
  b.score = 0.7;
  b.path = (root_ / "pred" / "scene0000_00_2_table_0.7000.ply").string();
  fs::create_directories(root_ / "json");
  const std::string path = (root_ / "pred" / "scene0000_00.json").string();
  WriteSceneResultJson(path, "scene0000_00", {a, b}, {{1, 2, 3}});
  auto recs = ReadSceneResultJson(path);
  ASSERT_EQ(recs.size(), 2u);
  EXPECT_EQ(recs[0].scene, "scene0000_00");
  EXPECT_EQ(recs[0].cls, 1);
  EXPECT_DOUBLE_EQ(recs[1].score, 0.7);
  EXPECT_EQ(fs::canonical(recs[1].path), fs::canonical(b.path));
}

#ifdef DIMR_CLI
TEST_F(EvalFixture, CommandLine) {
  const std::string json = (root_ / "out.json").string();
  const std::string svg = (root_ / "svg").string();
  const std::string cmd = std::string(DIMR_CLI) + " eval --quiet --pred " +
                          (root_ / "pred").string() + " --gt " + (root_ / "gt").string() +
                          " --gt-points " + (root_ / "points").string() +
                          " --metrics iou,pcr --json " + json + " --svg-dir " + svg + " > " +
                          (root_ / "stdout.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream in(json);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_NE(ss.str().find("\"protocol\": \"reference\""), std::string::npos);
  EXPECT_TRUE(fs::exists(fs::path(svg) / "iou_0.25.svg"));
  EXPECT_TRUE(fs::exists(fs::path(svg) / "pcr_0.5.svg"));
  // A missing folder is a clear error with a non-zero exit.
  const std::string bad = std::string(DIMR_CLI) + " eval --quiet --pred /nonexistent --gt " +
                          (root_ / "gt").string() + " > /dev/null 2>&1";
  EXPECT_NE(std::system(bad.c_str()), 0);
}
#endif

}  // namespace
}  // namespace dimr::eval
