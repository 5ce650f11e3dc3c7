// Scan2CAD re-labelling of real ScanNet scenes (scan2cad_relabel.h): box conventions against
// SynthScan's own boxes, rebuilt cabinet instances, IoU linking, dropped instances, and the
// `dimr stage1 prepare --scan2cad` path.
#include "dimr/data/scan2cad_relabel.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_run.h"
#include "dimr/data/labels.h"
#include "dimr/data/scan2cad_io.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/data/synthscan.h"
#include "dimr/geometry/error.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::OrientedBox;
using geometry::Vec3;

constexpr double kPi = 3.14159265358979323846;

double AngleDiff(double a, double b) {
  double d = std::fmod(a - b, 2 * kPi);
  if (d > kPi) d -= 2 * kPi;
  if (d < -kPi) d += 2 * kPi;
  return std::abs(d);
}

void ExpectBoxNear(const OrientedBox& got, const OrientedBox& want, double tol,
                   const std::string& what) {
  EXPECT_LT((got.center - want.center).norm(), tol) << what;
  EXPECT_LT((got.size - want.size).norm(), tol)
      << what << " size " << got.size.transpose() << " vs " << want.size.transpose();
  EXPECT_LT(AngleDiff(got.heading, want.heading), tol)
      << what << " heading " << got.heading << " vs " << want.heading;
}

// A Scan2CAD model with the SynthScan alignment conventions (docs/synthscan.md "Alignment"):
// box (centre, size (forward, left, up), heading) <- R = Rz(heading) A^T, scale = |A size|,
// bbox 0.5 (a unit model_normalized box).
Scan2CadModel MakeModel(int cad, const std::string& id, const Vec3& center, const Vec3& size,
                        double heading) {
  const Eigen::Matrix3d a = CanonicalToShapeNetAxes();
  Scan2CadModel m;
  m.catid_cad = CadSynsets()[cad];
  m.id_cad = id;
  m.translation = center;
  m.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(heading, Vec3::UnitZ()).toRotationMatrix() *
                                  a.transpose());
  m.scale = (a * size).cwiseAbs();
  m.bbox = Vec3::Constant(0.5);
  return m;
}

// A scene of hand-placed points; instances are added with AddInstance.
struct HandScene {
  SynthScene s;
  explicit HandScene(const std::string& name) { s.name = name; }
  void Add(const Vec3& p, int sem, int inst) {
    s.points.push_back(p);
    s.colors.emplace_back(100, 100, 100);
    s.semantic.push_back(sem);
    s.instance.push_back(inst);
    s.segment.push_back(inst > 0 ? inst * 10 : 999);
  }
  // Points on a regular grid filling [lo, hi] (n per axis).
  void Block(const Vec3& lo, const Vec3& hi, int n, int sem, int inst) {
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        for (int k = 0; k < n; ++k) {
          const Vec3 f(i / (n - 1.0), j / (n - 1.0), k / (n - 1.0));
          Add(lo + (hi - lo).cwiseProduct(f), sem, inst);
        }
      }
    }
  }
  void AddInstance(int id, const std::string& category, int rfs) {
    SynthInstance in;
    in.id = id;
    in.category = category;
    in.rfs_class = rfs;
    in.cad_class = rfs >= 0 ? RfsToCad(rfs) : kNonCad;
    s.instances.push_back(in);
  }
  int Count(int inst) const {
    int c = 0;
    for (int i : s.instance) c += i == inst;
    return c;
  }
};

// ---------------------------------------------------------------- (a) box conventions
SynthConfig SmallConfig() {
  SynthConfig c;
  c.scanner.frames = 30;
  c.room.min_objects = 10;
  c.room.max_objects = 14;
  return c;
}

class Scan2CadRelabelSynthTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    generated_ =
        new GeneratedScene(GenerateScene(SmallConfig(), SceneSeed(11, "train", 7), "scene0007_00"));
  }
  static void TearDownTestSuite() {
    delete generated_;
    generated_ = nullptr;
  }
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("s2c_relabel_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The scene as a real ScanNet folder (no synthscan.json) reads it.
  SynthScene AsRealScan(const SynthScene& scene) const {
    WriteScanNetScene(dir_.string(), scene);
    fs::remove(dir_ / scene.name / (scene.name + ".synthscan.json"));
    return ReadScanNetScene((dir_ / scene.name).string());
  }

  static GeneratedScene* generated_;
  fs::path dir_;
};
GeneratedScene* Scan2CadRelabelSynthTest::generated_ = nullptr;

TEST_F(Scan2CadRelabelSynthTest, ModelBoxesReproduceSynthScanBoxes) {
  const SynthScene& scene = generated_->scene;
  const Scan2CadScene ann = ToScan2Cad(scene);
  ASSERT_GE(ann.aligned_models.size(), 3u);
  for (const Scan2CadModel& m : ann.aligned_models) {
    const SynthInstance* in = scene.FindInstance(m.id_instance);
    ASSERT_NE(in, nullptr);
    ExpectBoxNear(Scan2CadModelBox(m), in->box, 1e-6, in->category);
  }
}

TEST_F(Scan2CadRelabelSynthTest, RelabelledRealScanGetsTheOriginalBoxes) {
  const SynthScene& original = generated_->scene;
  const Scan2CadScene ann = ToScan2Cad(original);
  SynthScene real = AsRealScan(original);
  ASSERT_EQ(real.instances.size(), original.instances.size());
  const RelabelStats st = RelabelWithScan2Cad(&real, ann);

  int rebuilt_expected = 0, linked_expected = 0;
  for (const SynthInstance& in : original.instances) {
    if (in.cad_class == kCadBookshelf || in.cad_class == kCadCabinet ||
        in.cad_class == kCadBathtub) {
      ++rebuilt_expected;
    } else if (in.cad_class >= 0) {
      ++linked_expected;
    }
  }
  ASSERT_GT(linked_expected, 0);
  EXPECT_EQ(st.dropped_rebuilt, rebuilt_expected) << ToString(st);
  EXPECT_EQ(st.linked + st.unmatched, linked_expected) << ToString(st);
  EXPECT_EQ(st.non_cad_models, 0);

  // Every instance with a CAD box carries exactly the box of its original instance (the one
  // with the same model and the nearest centre), and every original CAD instance is found
  // again (linked: same id; rebuilt: >= 95 % of its original points).
  int found = 0;
  for (const SynthInstance& in : real.instances) {
    if (in.cad_class < 0) continue;
    const SynthInstance* want = nullptr;
    for (const SynthInstance& o : original.instances) {
      if (o.cad_class >= 0 && o.model_id == in.model_id &&
          (want == nullptr ||
           (o.box.center - in.box.center).norm() < (want->box.center - in.box.center).norm())) {
        want = &o;
      }
    }
    ASSERT_NE(want, nullptr) << in.model_id;
    ++found;
    EXPECT_EQ(in.cad_class, want->cad_class);
    EXPECT_EQ(in.synset, want->synset);
    ExpectBoxNear(in.box, want->box, 1e-6, want->category);
    const int count =
        static_cast<int>(std::count(real.instance.begin(), real.instance.end(), in.id));
    EXPECT_EQ(in.num_points, count);
    if (in.id == want->id) continue;  // linked ScanNet instance
    ASSERT_TRUE(want->cad_class == kCadBookshelf || want->cad_class == kCadCabinet ||
                want->cad_class == kCadBathtub)
        << want->category << " linked to instance " << in.id << " instead of " << want->id;
    int own = 0, claimed = 0;
    for (std::size_t k = 0; k < real.points.size(); ++k) {
      if (original.instance[k] != want->id) continue;
      ++own;
      claimed += real.instance[k] == in.id;
    }
    EXPECT_GE(claimed, 0.95 * own) << want->category;
  }
  EXPECT_EQ(found, st.rebuilt + st.kept_with_box);
  EXPECT_EQ(found, rebuilt_expected + linked_expected - st.rebuilt_empty - st.unmatched);
  EXPECT_EQ(st.unmatched, 0) << ToString(st);
  EXPECT_EQ(st.rebuilt_empty, 0) << ToString(st);
}

TEST_F(Scan2CadRelabelSynthTest, AxisAlignmentAndScanTrsBringBoxesAndPointsTogether) {
  const SynthScene& original = generated_->scene;
  // Store the scan in a raw frame: raw = A^-1 p, axisAlignment = A; Scan2CAD's world frame is
  // the aligned one, the scan sits at M_scan = A in it (so inv(M_scan) M_cad maps to raw).
  const double yaw = 0.7;
  Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
  a.topLeftCorner<3, 3>() = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  a.topRightCorner<3, 1>() = Vec3(1.5, -2.0, 0.25);
  SynthScene raw = original;
  raw.axis_alignment = a;
  const Eigen::Matrix4d inv = a.inverse();
  for (Vec3& p : raw.points) {
    p = (inv.topLeftCorner<3, 3>() * p + inv.topRightCorner<3, 1>()).cast<float>().cast<double>();
  }
  SynthScene real = AsRealScan(raw);
  EXPECT_TRUE(real.axis_alignment.isApprox(a, 1e-12));
  Scan2CadScene ann = ToScan2Cad(original);
  ann.translation = a.topRightCorner<3, 1>();
  ann.rotation = Eigen::Quaterniond(Eigen::Matrix3d(a.topLeftCorner<3, 3>()));
  EXPECT_TRUE(Scan2CadToAlignedScene(real.axis_alignment, ann).isIdentity(1e-12));

  const RelabelStats st = RelabelWithScan2Cad(&real, ann);
  EXPECT_TRUE(real.axis_alignment.isIdentity(0.0));
  double worst = 0;
  for (std::size_t k = 0; k < real.points.size(); ++k) {
    worst = std::max(worst, (real.points[k] - original.points[k]).norm());
  }
  EXPECT_LT(worst, 1e-5);
  int with_box = 0;
  for (const SynthInstance& in : real.instances) {
    if (in.cad_class < 0) continue;
    ++with_box;
    for (const SynthInstance& o : original.instances) {
      if (o.model_id == in.model_id) ExpectBoxNear(in.box, o.box, 1e-6, o.category);
    }
  }
  EXPECT_EQ(with_box, st.rebuilt + st.kept_with_box);
  EXPECT_GT(with_box, 2);
  EXPECT_EQ(st.unmatched, 0);
}

// ---------------------------------------------------------------- (b)-(d) hand-made scenes
TEST(Scan2CadRelabelTest, SplitCabinetBecomesTwoInstancesAndOutsidePointsLoseTheirs) {
  HandScene h("scene0100_00");
  h.Block(Vec3(0, 0, 0), Vec3(0.6, 0.4, 0.8), 4, kCabinet, 1);      // 64 points, box 1
  h.Block(Vec3(2, 0, 0), Vec3(2.6, 0.4, 0.8), 3, kCabinet, 1);      // 27 points, box 2
  h.Block(Vec3(1.1, 0, 0.2), Vec3(1.3, 0.4, 0.4), 2, kCabinet, 1);  // 8 points in no box
  h.Add(Vec3(0.64, 0.2, 0.4), kCabinet, 1);  // 4 cm outside box 1: inside the 5 cm margin
  h.Add(Vec3(0.66, 0.2, 0.4), kCabinet, 1);  // 6 cm outside: lost
  h.Block(Vec3(-1, -1, -0.01), Vec3(4, 2, -0.01), 5, kFloor, 2);  // 125 floor points (z -0.01)
  h.Add(Vec3(0.3, 0.2, 0.84), kSemanticIgnore, 0);  // unassigned, in box 1 (+5 cm): claimed
  h.Block(Vec3(2.1, 0.1, 0.1), Vec3(2.2, 0.2, 0.2), 2, kCounter, 3);  // 8 "counter" points
  h.AddInstance(1, "cabinet", kCabinet);
  h.AddInstance(2, "floor", kFloor);
  h.AddInstance(3, "counter", kCounter);  // counter -> CAD cabinet: dropped and rebuilt too
  h.s.Validate();

  Scan2CadScene ann;
  ann.id_scan = h.s.name;
  // Box 1: [0, 0.6] x [0, 0.4] x [0, 0.8] with heading pi/2 (forward +y, size 0.4 x 0.6).
  ann.aligned_models.push_back(
      MakeModel(kCadCabinet, "cab1", Vec3(0.3, 0.2, 0.4), Vec3(0.4, 0.6, 0.8), kPi / 2));
  // Box 2: [2, 2.6] x [0, 0.4] x [0, 0.8] heading 0.
  ann.aligned_models.push_back(
      MakeModel(kCadCabinet, "cab2", Vec3(2.3, 0.2, 0.4), Vec3(0.6, 0.4, 0.8), 0.0));
  // A bathtub box over nothing unassigned (only floor points under it): no instance.
  ann.aligned_models.push_back(
      MakeModel(kCadBathtub, "tub", Vec3(3.5, 1.5, -0.05), Vec3(0.6, 0.6, 0.02), 0.0));
  // A non-CAD synset (lamp) is skipped.
  Scan2CadModel lamp = MakeModel(kCadChair, "lamp", Vec3(0, 0, 0), Vec3(1, 1, 1), 0);
  lamp.catid_cad = "03636649";
  ann.aligned_models.push_back(lamp);

  const RelabelStats st = RelabelWithScan2Cad(&h.s, ann);
  EXPECT_EQ(st.kept, 1);
  EXPECT_EQ(st.dropped_rebuilt, 2);
  EXPECT_EQ(st.dropped_ignored, 0);
  EXPECT_EQ(st.rebuilt, 2);
  EXPECT_EQ(st.rebuilt_empty, 1);
  EXPECT_EQ(st.non_cad_models, 1);
  EXPECT_EQ(st.points_lost, 8 + 1);
  ASSERT_EQ(h.s.instances.size(), 3u);
  const SynthInstance& floor = h.s.instances[0];
  EXPECT_EQ(floor.id, 2);
  EXPECT_EQ(floor.cad_class, kNonCad);
  EXPECT_EQ(h.Count(2), 125);
  const SynthInstance& c1 = h.s.instances[1];
  const SynthInstance& c2 = h.s.instances[2];
  EXPECT_EQ(c1.id, 4);  // largest id 3 + 1
  EXPECT_EQ(c2.id, 5);
  EXPECT_EQ(c1.model_id, "cab1");
  EXPECT_EQ(c2.model_id, "cab2");
  EXPECT_EQ(h.Count(4), 64 + 1 + 1);  // block, the 4 cm point, the unassigned point
  EXPECT_EQ(c1.num_points, 66);
  EXPECT_EQ(h.Count(5), 27 + 8);  // block + the counter points (their instance was dropped)
  EXPECT_EQ(h.Count(1), 0);
  EXPECT_EQ(h.Count(3), 0);
  EXPECT_EQ(c1.cad_class, kCadCabinet);
  EXPECT_EQ(c1.rfs_class, kCabinet);  // majority label cabinet maps to CAD cabinet
  EXPECT_EQ(c2.rfs_class, kCabinet);  // 27 cabinet vs 8 counter points
  EXPECT_NEAR(c1.box.heading, kPi / 2, 1e-12);
  EXPECT_LT((c1.box.size - Vec3(0.4, 0.6, 0.8)).norm(), 1e-12);
  EXPECT_EQ(c1.synset, CadSynsets()[kCadCabinet]);
  // Per-point labels are kept: the claimed unassigned point stays ignore, counters stay counter.
  const std::size_t unassigned = 64 + 27 + 8 + 2 + 125;
  EXPECT_EQ(h.s.semantic[unassigned], kSemanticIgnore);
  EXPECT_EQ(h.s.instance[unassigned], 4);
  EXPECT_EQ(h.s.semantic[unassigned + 1], kCounter);
  // The 6 cm point and the middle block lost their instance.
  EXPECT_EQ(h.s.instance[64 + 27 + 8 + 1], 0);
  EXPECT_EQ(h.s.instance[64 + 27], 0);
}

TEST(Scan2CadRelabelTest, RebuiltInstanceTakesAMatchingMajorityLabelOrTheClassDefault) {
  HandScene h("scene0101_00");
  h.Block(Vec3(0, 0, 0), Vec3(1, 1, 1), 3, kCounter, 1);         // 27 counters (CAD cabinet)
  h.Block(Vec3(3, 0, 0), Vec3(4, 1, 1), 3, kSemanticIgnore, 0);  // 27 unlabelled points
  h.AddInstance(1, "counter", kCounter);
  Scan2CadScene ann;
  ann.id_scan = h.s.name;
  ann.aligned_models.push_back(
      MakeModel(kCadCabinet, "a", Vec3(0.5, 0.5, 0.5), Vec3(1.5, 1.5, 1), 0.3));
  ann.aligned_models.push_back(
      MakeModel(kCadBookshelf, "b", Vec3(3.5, 0.5, 0.5), Vec3(1, 1, 1), 0.0));
  const RelabelStats st = RelabelWithScan2Cad(&h.s, ann);
  EXPECT_EQ(st.rebuilt, 2);
  ASSERT_EQ(h.s.instances.size(), 2u);
  EXPECT_EQ(h.s.instances[0].rfs_class, kCounter);    // counter -> cabinet matches
  EXPECT_EQ(h.s.instances[1].rfs_class, kBookshelf);  // ignore majority -> CadToRfs
  EXPECT_EQ(h.s.instances[1].cad_class, kCadBookshelf);
  EXPECT_EQ(h.Count(h.s.instances[1].id), 27);
}

TEST(Scan2CadRelabelTest, ModelsLinkToTheInstanceWithTheLargestIouAndTheLastWins) {
  HandScene h("scene0102_00");
  h.Block(Vec3(0, 0, 0), Vec3(1, 1, 1), 3, kChair, 1);      // chair AABB [0,1]^3
  h.Block(Vec3(1.5, 0, 0), Vec3(3, 1, 0.8), 3, kTable, 2);  // table AABB [1.5,3]x[0,1]x[0,.8]
  h.AddInstance(1, "chair", kChair);
  h.AddInstance(2, "table", kTable);
  Scan2CadScene ann;
  ann.id_scan = h.s.name;
  // x [0.8, 2.8]: IoU 0.16 / 2.44 with the chair, 1.04 / 1.76 with the table.
  ann.aligned_models.push_back(
      MakeModel(kCadTable, "t", Vec3(1.8, 0.5, 0.4), Vec3(2.0, 1.0, 0.8), 0.0));
  ann.aligned_models.push_back(
      MakeModel(kCadChair, "far", Vec3(10, 10, 0.5), Vec3(1, 1, 1), 0.0));  // IoU 0
  // Two models on the chair: the later one (a display, no class check) wins.
  ann.aligned_models.push_back(
      MakeModel(kCadChair, "c", Vec3(0.5, 0.5, 0.5), Vec3(0.9, 0.9, 0.9), 0.3));
  ann.aligned_models.push_back(
      MakeModel(kCadDisplay, "d", Vec3(0.5, 0.5, 0.6), Vec3(0.8, 0.8, 0.8), 1.0));
  const RelabelStats st = RelabelWithScan2Cad(&h.s, ann);
  EXPECT_EQ(st.linked, 3);
  EXPECT_EQ(st.unmatched, 1);
  EXPECT_EQ(st.kept, 2);
  EXPECT_EQ(st.kept_with_box, 2);
  ASSERT_EQ(h.s.instances.size(), 2u);
  const SynthInstance& chair = h.s.instances[0];
  const SynthInstance& table = h.s.instances[1];
  EXPECT_EQ(table.model_id, "t");
  EXPECT_EQ(table.cad_class, kCadTable);
  EXPECT_LT((table.box.center - Vec3(1.8, 0.5, 0.4)).norm(), 1e-12);
  EXPECT_EQ(chair.model_id, "d");
  EXPECT_EQ(chair.cad_class, kCadDisplay);
  EXPECT_EQ(chair.rfs_class, kChair);  // the semantic class is the aggregation's
  EXPECT_NEAR(chair.box.heading, 1.0, 1e-12);
  EXPECT_LT((chair.box.size - Vec3(0.8, 0.8, 0.8)).norm(), 1e-12);
  EXPECT_EQ(h.Count(1), 27);
  EXPECT_EQ(h.Count(2), 27);
  // The BEV IoU uses the model's heading: a (0.4 forward, 3.0 left) box turned by 90 degrees
  // spans x [-0.25, 2.75], y [0.3, 0.7]: IoU 0.32 / 1.64 with the chair, 0.4 / 1.76 with the
  // table. Ignoring the heading (x [1.05, 1.45], y [-1, 2]) it would overlap neither.
  HandScene h2("scene0102_00");
  h2.Block(Vec3(0, 0, 0), Vec3(1, 1, 1), 3, kChair, 1);
  h2.Block(Vec3(1.5, 0, 0), Vec3(3, 1, 0.8), 3, kTable, 2);
  h2.AddInstance(1, "chair", kChair);
  h2.AddInstance(2, "table", kTable);
  Scan2CadScene ann2;
  ann2.id_scan = h2.s.name;
  ann2.aligned_models.push_back(
      MakeModel(kCadTable, "t90", Vec3(1.25, 0.5, 0.4), Vec3(0.4, 3.0, 0.8), kPi / 2));
  RelabelWithScan2Cad(&h2.s, ann2);
  EXPECT_EQ(h2.s.instances[1].model_id, "t90");
  EXPECT_EQ(h2.s.instances[0].cad_class, kNonCad);
}

TEST(Scan2CadRelabelTest, IgnoredInstancesAreDroppedAndUnlinkedOnesLoseTheirCadClass) {
  HandScene h("scene0103_00");
  h.Block(Vec3(0, 0, 0), Vec3(1, 1, 1), 3, kSemanticIgnore, 1);  // "box": ignored class
  h.Block(Vec3(2, 0, 0), Vec3(3, 1, 1), 3, kChair, 2);           // chair, no model
  h.Block(Vec3(0, 2, 0), Vec3(3, 2.1, 2), 3, kWall, 3);          // wall
  h.AddInstance(1, "box", -1);
  h.AddInstance(2, "chair", kChair);
  h.AddInstance(3, "wall", kWall);
  Scan2CadScene ann;
  ann.id_scan = h.s.name;
  const RelabelStats st = RelabelWithScan2Cad(&h.s, ann);
  EXPECT_EQ(st.dropped_ignored, 1);
  EXPECT_EQ(st.points_lost, 27);
  EXPECT_EQ(st.kept, 2);
  EXPECT_EQ(st.kept_with_box, 0);
  ASSERT_EQ(h.s.instances.size(), 2u);
  EXPECT_EQ(h.s.instances[0].id, 2);
  EXPECT_EQ(h.s.instances[0].cad_class, kNonCad);  // no Scan2CAD box -> no heading supervision
  EXPECT_EQ(h.s.instances[0].num_points, 27);
  EXPECT_LT((h.s.instances[0].box.center - Vec3(2.5, 0.5, 0.5)).norm(), 1e-12);
  EXPECT_EQ(h.s.instances[1].id, 3);
  EXPECT_EQ(h.Count(1), 0);
  EXPECT_EQ(h.s.semantic[0], kSemanticIgnore);
}

TEST(Scan2CadRelabelTest, BadInputsThrowNamingSceneOrModel) {
  HandScene h("scene0104_00");
  h.Add(Vec3(0, 0, 0), kFloor, 0);
  Scan2CadScene ann;
  ann.id_scan = "scene9999_00";
  try {
    RelabelWithScan2Cad(&h.s, ann);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("scene9999_00"), std::string::npos) << e.what();
  }
  Scan2CadModel m = MakeModel(kCadChair, "flat", Vec3(0, 0, 0), Vec3(1, 1, 1), 0);
  m.scale.z() = 0;
  try {
    Scan2CadModelBox(m);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("flat"), std::string::npos) << e.what();
  }
  h.s.axis_alignment(0, 0) = 2.0;  // not a rotation
  ann.id_scan = h.s.name;
  EXPECT_THROW(RelabelWithScan2Cad(&h.s, ann), InvalidArgument);
}

// ---------------------------------------------------------------- (e) the CLI path
#ifdef DIMR_CLI
using dimr::testing::RunCli;

nlohmann::json InspectAll(const fs::path& cache, const fs::path& json) {
  auto [rc, out] = RunCli("stage1 inspect " + cache.string() + " --json " + json.string());
  EXPECT_EQ(rc, 0) << out;
  std::ifstream in(json);
  return nlohmann::json::parse(in)["splits"]["all"];
}

class Scan2CadRelabelCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("s2c_relabel_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "scans");
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(Scan2CadRelabelCliTest, PrepareRelabelsARealScanNetFolder) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  // Aligned-frame content: floor, a chair (heading 1.0 = bin 2), a cabinet (heading -2.0 =
  // bin 8); stored raw (p_raw = A^-1 p) with axisAlignment A, Scan2CAD world = aligned frame.
  HandScene h("scene0200_00");
  h.Block(Vec3(-1, -1, 0), Vec3(4, 4, 0), 6, kFloor, 1);           // 216 points (z all 0)
  h.Block(Vec3(0, 0, 0.05), Vec3(0.5, 0.5, 0.9), 3, kChair, 2);    // 27
  h.Block(Vec3(2, 2, 0.05), Vec3(2.8, 2.4, 1.0), 3, kCabinet, 3);  // 27
  h.AddInstance(1, "floor", kFloor);
  h.AddInstance(2, "chair", kChair);
  h.AddInstance(3, "cabinet", kCabinet);
  Eigen::Matrix4d a = Eigen::Matrix4d::Identity();
  a.topLeftCorner<3, 3>() = Eigen::AngleAxisd(-1.2, Vec3::UnitZ()).toRotationMatrix();
  a.topRightCorner<3, 1>() = Vec3(-3, 5, 0.1);
  const Eigen::Matrix4d inv = a.inverse();
  SynthScene raw = h.s;
  raw.axis_alignment = a;
  for (Vec3& p : raw.points) {
    p = (inv.topLeftCorner<3, 3>() * p + inv.topRightCorner<3, 1>()).cast<float>().cast<double>();
  }
  WriteScanNetScene((dir_ / "scans").string(), raw);
  fs::remove(dir_ / "scans" / raw.name / (raw.name + ".synthscan.json"));

  Scan2CadScene ann;
  ann.id_scan = raw.name;
  ann.translation = a.topRightCorner<3, 1>();
  ann.rotation = Eigen::Quaterniond(Eigen::Matrix3d(a.topLeftCorner<3, 3>()));
  ann.aligned_models.push_back(
      MakeModel(kCadChair, "chair0", Vec3(0.25, 0.25, 0.45), Vec3(0.5, 0.5, 0.9), 1.0));
  // A 1 x 1 footprint turned by -2.0 rad around (2.4, 2.2) covers the 0.8 x 0.4 cabinet.
  ann.aligned_models.push_back(
      MakeModel(kCadCabinet, "cab0", Vec3(2.4, 2.2, 0.525), Vec3(1.0, 1.0, 0.95), -2.0));
  Scan2CadScene other;  // an entry for a scene that is not in the folder: ignored
  other.id_scan = "scene0999_00";
  const fs::path ann_path = dir_ / "full_annotations.json";
  WriteScan2CadAnnotations(ann_path.string(), {ann, other});

  // Without Scan2CAD: 2 CAD instances, neither with an aligned model, so no heading labels.
  const fs::path plain = dir_ / "plain.bin";
  auto [rc0, out0] = RunCli("stage1 prepare --scans " + dir_.string() + " --out " + plain.string());
  ASSERT_EQ(rc0, 0) << out0;
  EXPECT_NE(out0.find("1 real ScanNet scenes without --scan2cad"), std::string::npos) << out0;
  auto j0 = InspectAll(plain, dir_ / "plain.json");
  EXPECT_EQ(j0["cad_instances"], 2);
  for (int b = 0; b < 12; ++b) EXPECT_EQ(j0["heading_bins"][b], 0) << "bin " << b;

  const fs::path cache = dir_ / "s2c.bin";
  auto [rc, out] = RunCli("stage1 prepare --scans " + dir_.string() + " --scan2cad " +
                          ann_path.string() + " --out " + cache.string());
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("1 scenes relabelled from Scan2CAD, 0 kept their SynthScan boxes"),
            std::string::npos)
      << out;
  auto j = InspectAll(cache, dir_ / "s2c.json");
  EXPECT_EQ(j["instances"], 3);  // floor, chair, rebuilt cabinet
  EXPECT_EQ(j["cad_instances"], 2);
  EXPECT_EQ(j["cad_instances_per_class"]["chair"], 1);
  EXPECT_EQ(j["cad_instances_per_class"]["cabinet"], 1);
  const std::vector<int> bins = j["heading_bins"].get<std::vector<int>>();
  ASSERT_EQ(bins.size(), 12u);
  for (int b = 0; b < 12; ++b) EXPECT_EQ(bins[b], b == 2 || b == 8 ? 1 : 0) << "bin " << b;
  EXPECT_EQ(j["labelled_points"]["floor"], 216);
  EXPECT_EQ(j["points"], 216 + 27 + 27);
}

TEST_F(Scan2CadRelabelCliTest, SynthScanFoldersKeepTheirBoxesUnlessForced) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  HandScene h("scene0201_00");
  h.Block(Vec3(0, 0, 0.05), Vec3(0.5, 0.5, 0.9), 3, kChair, 1);
  h.AddInstance(1, "chair", kChair);
  h.s.instances[0].synset = CadSynsets()[kCadChair];
  h.s.instances[0].model_id = "own";
  h.s.instances[0].box.heading = 1.0;  // bin 2 (SynthScan's own box)
  WriteScanNetScene((dir_ / "scans").string(), h.s);
  Scan2CadScene ann;
  ann.id_scan = h.s.name;
  ann.aligned_models.push_back(
      MakeModel(kCadChair, "s2c", Vec3(0.25, 0.25, 0.45), Vec3(0.5, 0.5, 0.9), kPi));  // bin 6
  const fs::path ann_path = dir_ / "full_annotations.json";
  WriteScan2CadAnnotations(ann_path.string(), {ann});

  auto [rc, out] = RunCli("stage1 prepare --scans " + dir_.string() + " --scan2cad " +
                          ann_path.string() + " --out " + (dir_ / "a.bin").string());
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("0 scenes relabelled from Scan2CAD, 1 kept their SynthScan boxes"),
            std::string::npos)
      << out;
  EXPECT_EQ(InspectAll(dir_ / "a.bin", dir_ / "a.json")["heading_bins"][2], 1);

  auto [rc2, out2] =
      RunCli("stage1 prepare --scans " + dir_.string() + " --scan2cad " + ann_path.string() +
             " --force-scan2cad --out " + (dir_ / "b.bin").string());
  ASSERT_EQ(rc2, 0) << out2;
  EXPECT_NE(out2.find("1 scenes relabelled from Scan2CAD, 0 kept"), std::string::npos) << out2;
  EXPECT_EQ(InspectAll(dir_ / "b.bin", dir_ / "b.json")["heading_bins"][6], 1);

  auto [rc3, out3] = RunCli("stage1 prepare --scans " + dir_.string() + " --force-scan2cad --out " +
                            (dir_ / "c.bin").string());
  EXPECT_NE(rc3, 0) << out3;
  EXPECT_NE(out3.find("--scan2cad"), std::string::npos) << out3;
}
#endif  // DIMR_CLI

}  // namespace
}  // namespace dimr::data
