// ScanNet / Scan2CAD writers and readers: exact round trips, label mapping, errors.
#include "dimr/data/scannet_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "dimr/data/labels.h"
#include "dimr/data/scan2cad_io.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;

// A small hand-made scene (no scanning needed): 3 instances, one clutter, unlabelled points.
SynthScene HandScene() {
  SynthScene s;
  s.name = "scene0042_00";
  s.axis_alignment(0, 3) = -1.25;
  s.axis_alignment(1, 3) = 0.1 / 3.0;
  s.room_shape = "L";
  s.room_type = "office";
  s.floor_area = 17.123456789;
  s.room_height = 2.7;
  const int inst_of[] = {1, 1, 2, 2, 2, 3, 0, 1};
  for (int k = 0; k < 8; ++k) {
    s.points.push_back(Vec3(0.1f * k, -0.3f + 0.07f * k, 1.0f / 3.0f * k));
    s.colors.emplace_back(10 * k, 255 - k, 7);
    s.instance.push_back(inst_of[k]);
    s.segment.push_back(inst_of[k] * 10 + (k % 2));
  }
  SynthInstance wall;
  wall.id = 1;
  wall.category = "wall";
  wall.rfs_class = kWall;
  wall.family = "wall";
  wall.translation = Vec3(1.0 / 7, 2, 3);
  wall.scale = Vec3(0.12, 4.1, 2.7);
  wall.box.center = wall.translation;
  wall.box.size = wall.scale;
  wall.box.heading = 0.3;
  wall.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vec3::UnitZ()));
  wall.num_points = 3;
  wall.visible_fraction = 0.123456789123;
  SynthInstance chair = wall;
  chair.id = 2;
  chair.category = "chair";
  chair.rfs_class = kChair;
  chair.cad_class = kCadChair;
  chair.synset = CadSynsets()[kCadChair];
  chair.model_id = "0123456789abcdef0123456789abcdef";
  chair.family = "four_leg_chair";
  chair.scale = Vec3(0.61, 1.3, 0.2);
  chair.box.size = Vec3(0.5, 0.55, 0.9);
  chair.rotation = Eigen::Quaterniond(0.5, -0.5, 0.5, 0.5);
  chair.num_points = 3;
  SynthInstance box = wall;
  box.id = 3;
  box.category = "box";
  box.rfs_class = -1;
  box.family = "box";
  box.num_points = 1;
  s.instances = {wall, chair, box};
  for (int k = 0; k < 8; ++k) {
    const int i = s.instance[k];
    s.semantic.push_back(i == 1 ? kWall : i == 2 ? kChair : kSemanticIgnore);
  }
  return s;
}

class ScanNetIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("scannet_io_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(ScanNetIoTest, SceneRoundTripsExactly) {
  const SynthScene s = HandScene();
  WriteScanNetScene(dir_.string(), s);
  const SynthScene back = ReadScanNetScene((dir_ / s.name).string());
  EXPECT_TRUE(back == s);
  EXPECT_EQ(back.points, s.points);
  EXPECT_EQ(back.semantic, s.semantic);
  EXPECT_EQ(back.axis_alignment, s.axis_alignment);
  // labels.ply holds NYU40 ids: wall 1, chair 5, clutter 40 (otherprop), none 0.
  const geometry::PointCloud lab =
      geometry::ReadPlyCloud((dir_ / s.name / (s.name + "_vh_clean_2.labels.ply")).string());
  const auto* label = lab.FindAttribute("label");
  ASSERT_NE(label, nullptr);
  EXPECT_EQ(label->type, geometry::ScalarType::kUInt16);
  const std::vector<double> expect = {1, 1, 5, 5, 5, 40, 0, 1};
  EXPECT_EQ(label->values, expect);
}

TEST_F(ScanNetIoTest, RealScanNetFallbacks) {
  const SynthScene s = HandScene();
  WriteScanNetScene(dir_.string(), s);
  const fs::path scene = dir_ / s.name;
  // Without SynthScan metadata: instances from the aggregation, boxes from the points.
  fs::remove(scene / (s.name + ".synthscan.json"));
  SynthScene back = ReadScanNetScene(scene.string());
  ASSERT_EQ(back.instances.size(), 3u);
  EXPECT_EQ(back.instances[1].cad_class, kCadChair);
  EXPECT_EQ(back.instances[0].num_points, 3);
  EXPECT_EQ(back.semantic, s.semantic);
  EXPECT_EQ(back.instances[0].box.size.x(), s.points[7].x() - s.points[0].x());
  // Without the aggregation: semantics from the NYU40 labels (clutter becomes ignore).
  fs::remove(scene / (s.name + ".aggregation.json"));
  back = ReadScanNetScene(scene.string());
  EXPECT_EQ(back.semantic, s.semantic);
  EXPECT_TRUE(back.instances.empty());
}

TEST_F(ScanNetIoTest, ErrorsNameTheFile) {
  const SynthScene s = HandScene();
  WriteScanNetScene(dir_.string(), s);
  const fs::path segs = dir_ / s.name / (s.name + "_vh_clean_2.0.010000.segs.json");
  { std::ofstream(segs) << R"({"segIndices": [1, 2]})"; }
  try {
    ReadScanNetScene((dir_ / s.name).string());
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("segs.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("2 entries for 8 vertices"), std::string::npos);
  }
  { std::ofstream(segs) << "{ not json"; }
  EXPECT_THROW(ReadScanNetScene((dir_ / s.name).string()), ParseError);
  EXPECT_THROW(ReadScanNetScene((dir_ / "scene9999_00").string()), ParseError);
  // Unwritable output.
  { std::ofstream(dir_ / "file") << "x"; }
  try {
    WriteScanNetScene((dir_ / "file").string(), s);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((dir_ / "file").string()), std::string::npos);
  }
  // Inconsistent scene.
  SynthScene bad = s;
  bad.semantic[0] = kChair;
  EXPECT_THROW(WriteScanNetScene(dir_.string(), bad), InvalidArgument);
}

TEST_F(ScanNetIoTest, Scan2CadRoundTrip) {
  const SynthScene s = HandScene();
  Scan2CadScene a = ToScan2Cad(s);
  ASSERT_EQ(a.aligned_models.size(), 1u);
  EXPECT_EQ(a.aligned_models[0].catid_cad, "03001627");
  EXPECT_EQ(a.aligned_models[0].id_instance, 2);
  Scan2CadScene b = a;
  b.id_scan = "scene0001_00";
  b.translation = Vec3(0.1, 0.2, 1.0 / 3);
  b.aligned_models[0].sym = "__SYM_ROTATE_UP_INF";
  const std::string path = (dir_ / "full_annotations.json").string();
  WriteScan2CadAnnotations(path, {a, b});
  const auto back = ReadScan2CadAnnotations(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_TRUE(back[0] == a);
  EXPECT_TRUE(back[1] == b);
  { std::ofstream(path) << R"([{"id_scan": "x", "trs": {"translation": [0, 0]}}])"; }
  try {
    ReadScan2CadAnnotations(path);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("translation"), std::string::npos);
  }
  EXPECT_THROW(WriteScan2CadAnnotations((dir_ / "no" / "x.json").string(), {a}), Error);
}

TEST(LabelMapTest, CategoriesAndNyu40) {
  EXPECT_EQ(RfsFromCategory("trash can"), kTrashBin);
  EXPECT_EQ(RfsFromCategory("Couch"), kSofa);
  EXPECT_EQ(RfsFromCategory("kitchen cabinets"), kCabinet);
  EXPECT_EQ(RfsFromCategory("kitchen cabinet"), kKitchenCabinet);
  EXPECT_EQ(RfsFromCategory("box"), -1);
  for (int r = 0; r < kNumRfsClasses; ++r) {
    const int n = RfsToNyu40(r);
    EXPECT_GT(n, 0);
    const int back = Nyu40ToRfs(n);
    // NYU40 merges a few RFS classes (kitchen_cabinet -> cabinet, trash bin -> otherfurniture).
    if (r != kKitchenCabinet && r != kTrashBin && r != kOtherTable) {
      EXPECT_EQ(back, r) << r;
    }
  }
  EXPECT_EQ(RfsToNyu40(-1), 0);
  EXPECT_EQ(Nyu40ToRfs(40), -1);
}

}  // namespace
}  // namespace dimr::data
