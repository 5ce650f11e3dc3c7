// SynthScan scenes: ground truth against the placed meshes, labels, alignments, determinism.
#include "dimr/data/synthscan.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <set>

#include "dimr/data/labels.h"
#include "dimr/data/scan2cad_io.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/mesh_distance.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;

SynthConfig TestConfig() {
  SynthConfig c;
  c.scanner.frames = 30;
  return c;
}

const GeneratedScene& Scene() {
  static const GeneratedScene g =
      GenerateScene(TestConfig(), SceneSeed(5, "train", 3), "scene0003_00");
  return g;
}

std::string Slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

TEST(SynthScanTest, PointsLieOnTheirPlacedMeshes) {
  const GeneratedScene& g = Scene();
  const SynthScene& s = g.scene;
  ASSERT_GT(s.points.size(), 10000u);
  std::size_t total = 0, over = 0;
  for (const auto& inst : s.instances) {
    const PlacedObject& obj = g.room.objects.at(g.object_of_instance.at(inst.id));
    std::vector<Vec3> pts;
    for (std::size_t k = 0; k < s.points.size(); ++k) {
      if (s.instance[k] == inst.id) pts.push_back(s.points[k]);
    }
    ASSERT_EQ(static_cast<int>(pts.size()), inst.num_points);
    const geometry::MeshDistance md(obj.WorldMesh());
    for (double d : md.Distances(pts)) {
      EXPECT_LT(d, 0.045) << inst.category;  // hard bound: noise clip + voxel averaging
      over += d > 0.03;
      ++total;
    }
  }
  // Noise bound: fused depth noise keeps practically every point within 3 cm.
  EXPECT_LT(static_cast<double>(over), 1e-3 * total);
}

TEST(SynthScanTest, LabelsAndInstancesAreConsistent) {
  const GeneratedScene& g = Scene();
  const SynthScene& s = g.scene;
  EXPECT_NO_THROW(s.Validate());
  std::set<int> walls, floors;
  for (std::size_t i = 0; i < s.instances.size(); ++i) {
    const auto& inst = s.instances[i];
    EXPECT_EQ(inst.id, static_cast<int>(i) + 1);  // contiguous, 1-based
    EXPECT_GE(inst.num_points, TestConfig().min_instance_points);
    EXPECT_GE(inst.visible_fraction, 0.0);
    EXPECT_LE(inst.visible_fraction, 1.0);
    if (inst.category == "wall") walls.insert(inst.id);
    if (inst.category == "floor") floors.insert(inst.id);
    if (inst.cad_class >= 0) {
      EXPECT_EQ(inst.synset, CadSynsets()[inst.cad_class]);
      EXPECT_EQ(inst.model_id.size(), 32u);
    }
  }
  EXPECT_GE(walls.size(), 3u);
  EXPECT_EQ(floors.size(), 1u);
  int clutter_points = 0;
  for (std::size_t k = 0; k < s.points.size(); ++k) {
    const SynthInstance* inst = s.FindInstance(s.instance[k]);
    if (!inst) {
      EXPECT_EQ(s.semantic[k], kSemanticIgnore);
      continue;
    }
    if (walls.count(inst->id)) {
      EXPECT_EQ(s.semantic[k], kWall);
    }
    if (floors.count(inst->id)) {
      EXPECT_EQ(s.semantic[k], kFloor);
    }
    if (inst->rfs_class < 0) {
      EXPECT_EQ(s.semantic[k], kSemanticIgnore);
      ++clutter_points;
    } else {
      EXPECT_EQ(s.semantic[k], inst->rfs_class);
    }
  }
  // Segments never span two instances.
  std::map<int, int> owner;
  for (std::size_t k = 0; k < s.points.size(); ++k) {
    auto it = owner.emplace(s.segment[k], s.instance[k]).first;
    EXPECT_EQ(it->second, s.instance[k]);
  }
  // The floor hides its underside and walls their outside: partial, like real scans.
  for (const auto& inst : s.instances) {
    if (inst.category == "floor" || inst.category == "wall") {
      EXPECT_LT(inst.visible_fraction, 0.55);
    }
  }
}

TEST(SynthScanTest, AlignmentMapsTheShapeNetModelOntoThePlacedMesh) {
  const GeneratedScene& g = Scene();
  int cad = 0;
  for (const auto& inst : g.scene.instances) {
    const PlacedObject& obj = g.room.objects.at(g.object_of_instance.at(inst.id));
    const geometry::TriangleMesh world = obj.WorldMesh();
    Eigen::Matrix3d to_model = Eigen::Matrix3d::Identity();
    if (inst.cad_class >= 0) {
      ++cad;
      to_model = CanonicalToShapeNet(obj.model->nominal_size);
    }
    for (std::size_t v = 0; v < world.vertices.size(); v += 7) {
      const Vec3 q = to_model * obj.mesh.vertices[v];  // model_normalized / canonical vertex
      const Vec3 p = inst.translation + inst.rotation * inst.scale.cwiseProduct(q);
      EXPECT_LT((p - world.vertices[v]).norm(), 1e-9);
    }
    EXPECT_NEAR(inst.rotation.norm(), 1.0, 1e-12);
    EXPECT_EQ(inst.box.center, obj.translation);
    EXPECT_EQ(inst.box.size, obj.scale);
    EXPECT_EQ(inst.box.heading, obj.yaw);
  }
  EXPECT_GE(cad, 2);
  // Scan2CAD: bbox * scale = metric half size in ShapeNet axes (-y, z, -x).
  const Scan2CadScene s2c = ToScan2Cad(g.scene);
  EXPECT_EQ(static_cast<int>(s2c.aligned_models.size()), cad);
  for (const auto& m : s2c.aligned_models) {
    const SynthInstance* inst = g.scene.FindInstance(m.id_instance);
    ASSERT_NE(inst, nullptr);
    const Vec3 half = m.bbox.cwiseProduct(m.scale);
    EXPECT_NEAR(half.x(), inst->box.size.y() / 2, 1e-9);
    EXPECT_NEAR(half.y(), inst->box.size.z() / 2, 1e-9);
    EXPECT_NEAR(half.z(), inst->box.size.x() / 2, 1e-9);
  }
}

TEST(SynthScanTest, SameSeedSameBytes) {
  const GeneratedScene again =
      GenerateScene(TestConfig(), SceneSeed(5, "train", 3), "scene0003_00");
  EXPECT_TRUE(again.scene == Scene().scene);
  const fs::path root = fs::temp_directory_path() / ("synth_det_" + std::to_string(::getpid()));
  WriteScanNetScene((root / "a").string(), Scene().scene);
  WriteScanNetScene((root / "b").string(), again.scene);
  int files = 0;
  for (const auto& e : fs::directory_iterator(root / "a" / "scene0003_00")) {
    const fs::path other = root / "b" / "scene0003_00" / e.path().filename();
    EXPECT_EQ(Slurp(e.path()), Slurp(other)) << e.path();
    ++files;
  }
  EXPECT_EQ(files, 6);
  fs::remove_all(root);
  // Scene seeds depend on (seed, split, index) only; splits and indices differ.
  EXPECT_EQ(SceneSeed(5, "train", 3), SceneSeed(5, "train", 3));
  EXPECT_NE(SceneSeed(5, "train", 3), SceneSeed(5, "val", 3));
  EXPECT_NE(SceneSeed(5, "train", 3), SceneSeed(5, "train", 4));
  EXPECT_EQ(SceneName("val", 2), "scene5002_00");
  EXPECT_THROW(SceneName("dev", 0), InvalidArgument);
}

// Window panes (RoomConfig::window_pane) are scanned: their points are labelled window, lie on the
// pane (within the noise bound of PointsLieOnTheirPlacedMeshes) and sit behind the wall's face.
TEST(SynthScanTest, WindowPanesAreScannedAsWindow) {
  SynthConfig cfg = TestConfig();
  cfg.room.window_pane = 1.0;
  int pane_points = 0, panes_seen = 0;
  for (int index = 0; index < 6 && panes_seen == 0; ++index) {
    const GeneratedScene g = GenerateScene(cfg, SceneSeed(5, "train", index), "scene0000_00");
    const SynthScene& s = g.scene;
    for (const auto& inst : s.instances) {
      const PlacedObject& obj = g.room.objects.at(g.object_of_instance.at(inst.id));
      if (!IsWindowPane(obj)) continue;
      EXPECT_EQ(inst.category, "window");
      EXPECT_EQ(inst.rfs_class, kWindow);
      std::vector<Vec3> pts;
      for (std::size_t k = 0; k < s.points.size(); ++k) {
        if (s.instance[k] != inst.id) continue;
        EXPECT_EQ(s.semantic[k], kWindow);
        pts.push_back(s.points[k]);
      }
      const geometry::MeshDistance md(obj.WorldMesh());
      for (double d : md.Distances(pts)) EXPECT_LT(d, 0.045);
      pane_points += static_cast<int>(pts.size());
      ++panes_seen;
    }
  }
  EXPECT_GT(panes_seen, 0);
  EXPECT_GT(pane_points, 100);
}

TEST(SynthScanTest, IndexShapeNetTreeAndSummary) {
  const GeneratedScene& g = Scene();
  const fs::path root = fs::temp_directory_path() / ("synth_idx_" + std::to_string(::getpid()));
  fs::create_directories(root);
  std::vector<CadModel> models;
  for (const auto& m : g.cad_models) models.push_back(*m);
  ASSERT_FALSE(models.empty());
  WriteShapeNetTree((root / "shapenet").string(), models);
  EXPECT_TRUE(
      fs::exists(root / "shapenet" / ShapeNetRelativePath(models[0].synset, models[0].model_id)));
  SceneSummary sum = Summarize(g);
  EXPECT_EQ(sum.num_points, g.scene.points.size());
  EXPECT_EQ(sum.objects.size(), g.scene.instances.size());
  WriteSynthIndex((root / "synthscan.yaml").string(), TestConfig(), 5, "train", 0, 1, {sum});
  const std::string yaml = Slurp(root / "synthscan.yaml");
  EXPECT_NE(yaml.find("name: scene0003_00"), std::string::npos);
  EXPECT_NE(yaml.find("points: " + std::to_string(sum.num_points)), std::string::npos);
  const std::string report = RealismReport({sum});
  EXPECT_NE(report.find("| wall |"), std::string::npos);
  EXPECT_THROW(
      WriteSynthIndex("/proc/nonexistent/synthscan.yaml", TestConfig(), 5, "train", 0, 1, {sum}),
      Error);
  fs::remove_all(root);
}

#ifdef DIMR_CLI
std::string RunCli(const std::string& args, int* status) {
  std::string out;
  FILE* p = popen((std::string(DIMR_CLI) + " " + args + " 2>&1").c_str(), "r");
  if (!p) return out;
  char buf[512];
  while (fgets(buf, sizeof(buf), p)) out += buf;
  *status = pclose(p);
  return out;
}

TEST(SynthCliTest, ShardsReproduceTheFullRunAndBadArgumentsFail) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  const fs::path root = fs::temp_directory_path() / ("synth_cli_" + std::to_string(::getpid()));
  const std::string common = " --scenes 3 --seed 9 --split test --frames-per-scene 6 --quiet";
  int status = 0;
  const std::string out = RunCli("synth --out " + (root / "all").string() + common, &status);
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("scenes: 3"), std::string::npos) << out;
  RunCli("synth --out " + (root / "s1").string() + common + " --shard 1/2", &status);
  ASSERT_EQ(status, 0);
  for (const char* scene : {"scene8001_00"}) {
    for (const auto& e : fs::directory_iterator(root / "all" / "scans" / scene)) {
      EXPECT_EQ(Slurp(e.path()), Slurp(root / "s1" / "scans" / scene / e.path().filename()))
          << e.path();
    }
  }
  EXPECT_FALSE(fs::exists(root / "s1" / "scans" / "scene8000_00"));
  EXPECT_TRUE(fs::exists(root / "s1" / "synthscan.shard-1-of-2.yaml"));
  EXPECT_TRUE(fs::exists(root / "all" / "full_annotations.json"));
  const auto s2c = ReadScan2CadAnnotations((root / "all" / "full_annotations.json").string());
  EXPECT_EQ(s2c.size(), 3u);
  const std::string bad = RunCli("synth --out " + (root / "x").string() + " --split dev", &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(bad.find("split"), std::string::npos) << bad;
  const std::string bad_pane =
      RunCli("synth --out " + (root / "x").string() + " --window-pane 1.5", &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(bad_pane.find("window_pane"), std::string::npos) << bad_pane;
  // The pane and door options are recorded with the run.
  const std::string panes = RunCli("synth --out " + (root / "p").string() +
                                       " --scenes 1 --seed 9 --split test --frames-per-scene 6"
                                       " --quiet --window-pane 0.5 --door-closed 0.9",
                                   &status);
  ASSERT_EQ(status, 0) << panes;
  const std::string yaml = Slurp(root / "p" / "synthscan.yaml");
  EXPECT_NE(yaml.find("window_pane: 0.5"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("door_closed: 0.9"), std::string::npos) << yaml;
  { std::ofstream(root / "file") << "x"; }
  const std::string unwritable =
      RunCli("synth --scenes 1 --out " + (root / "file").string(), &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(unwritable.find((root / "file").string()), std::string::npos) << unwritable;
  fs::remove_all(root);
}

TEST(SynthCliTest, ScannerOverridesAreAppliedAndRecordedAndPicturesWritten) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  const fs::path root = fs::temp_directory_path() / ("synth_knobs_" + std::to_string(::getpid()));
  const std::string common = " --scenes 1 --seed 9 --split test --frames-per-scene 4 --quiet";
  int status = 0;
  std::string out = RunCli("synth --out " + (root / "a").string() + common +
                               " --realism v2 --scanner 'sensor_frames=3 dropout=0.1'",
                           &status);
  ASSERT_EQ(status, 0) << out;
  const std::string index = Slurp(root / "a" / "synthscan.yaml");
  EXPECT_NE(index.find("sensor_frames=3 "), std::string::npos) << index;
  EXPECT_NE(index.find("dropout=0.1 "), std::string::npos) << index;
  EXPECT_NE(index.find("shadow_strength=0.8"), std::string::npos) << index;  // v2 kept
  // Bad keys / values fail before any work, naming the key.
  out = RunCli("synth --out " + (root / "b").string() + common + " --scanner 'nope=1'", &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("nope"), std::string::npos) << out;
  out = RunCli("synth --out " + (root / "b").string() + common + " --scanner 'sensor_frames=0'",
               &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("sensor_frames"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "b" / "scans" / "scene8000_00"));
  // Two clouds side by side.
  const fs::path png = root / "pic.png";
  out = RunCli("stats picture " + (root / "a").string() + " " + (root / "a").string() +
                   " --width 96 --height 80 --out " + png.string(),
               &status);
  ASSERT_EQ(status, 0) << out;
  const std::string bytes = Slurp(png);
  ASSERT_GT(bytes.size(), 100u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
  out = RunCli("stats picture " + (root / "a").string() + " --titles x,y --out " + png.string(),
               &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(out.find("titles"), std::string::npos) << out;
  fs::remove_all(root);
}
TEST(SynthCliTest, BenchReportsWhereTheSceneTimeGoes) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  const fs::path root = fs::temp_directory_path() / ("synth_bench_" + std::to_string(::getpid()));
  fs::create_directories(root);
  int status = 0;
  for (const std::string density : {"mesh", "scannet"}) {
    const fs::path json = root / (density + ".json");
    const std::string out = RunCli(
        "bench synth --scenes 1 --seed 9 --split test --frames-per-scene 3 --jobs 1 "
        "--density " +
            density + " --json " + json.string(),
        &status);
    if (density == "scannet" && status != 0 && out.find("Open3D") != std::string::npos)
      continue;  // a build without Open3D
    ASSERT_EQ(status, 0) << out;
    EXPECT_NE(out.find("| ray_cast |"), std::string::npos) << out;
    EXPECT_NE(out.find("| **GenerateScene** |"), std::string::npos) << out;
    const nlohmann::json j = nlohmann::json::parse(Slurp(json));
    const auto& st = j.at("stage_ms_per_scene");
    const double scene = st.at("scene").get<double>();
    EXPECT_GT(st.at("ray_cast").get<double>(), 0.0);
    EXPECT_LE(st.at("ray_cast").get<double>(), scene);
    double staged = 0;
    for (const auto& [name, ms] : st.items()) {
      if (name != "scene") staged += ms.get<double>();
    }
    EXPECT_LE(staged, scene * 1.001 + 1.0);  // the stages are parts of GenerateScene
    if (density == "scannet") {
      for (const char* k : {"integrate", "marching_cubes", "clean", "decimate", "colour", "labels"})
        EXPECT_TRUE(st.contains(k)) << k << " missing: " << st.dump();
    } else {
      EXPECT_FALSE(st.contains("decimate")) << st.dump();
    }
  }
  fs::remove_all(root);
}
#endif

}  // namespace
}  // namespace dimr::data
