// The Reconstructor end to end with the real default models (models/): a small generated room
// (dimr synth) and its evaluation GT (dimr export gt). Skipped, saying why, when a default model
// is missing from the checkout.
#include "dimr/pipeline/reconstructor.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>

#include "../cli_run.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/geometry/sampling.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/gravity.h"
#include "dimr/pipeline/placement.h"
#include "dimr/pipeline/shape_pool.h"

#ifdef DIMR_CLI
namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

struct GtInstance {
  int cad_class = -1;
  std::string model_id, synset;
  geometry::Vec3 center;
};

const char* const kClasses[8] = {"table",     "chair",   "bookshelf", "sofa",
                                 "trash_bin", "cabinet", "display",   "bathtub"};

int ClassId(const std::string& name) {
  for (int c = 0; c < 8; ++c) {
    if (name == kClasses[c]) return c;
  }
  return -1;
}

std::string Model(const std::string& name) {
  return std::string(DIMR_SOURCE_DIR) + "/models/" + name;
}

class ReconstructorRoom : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    for (const char* m : {"stage1/stage1.pt", "stage2/stage2.pt", "bsp/bsp.pt", "bsp/pool.bin"}) {
      if (!fs::exists(Model(m))) {
        skip_ = std::string("default model models/") + m + " is not in this checkout";
        return;
      }
    }
    dir_ = testing::FreshTempDir("dimr_reconstructor_room");
    auto [rc, out] = testing::RunCli("synth --scenes 1 --seed 11 --split test --quiet --out " +
                                     (dir_ / "split").string());
    ASSERT_EQ(rc, 0) << out;
    std::tie(rc, out) = testing::RunCli("export gt --split " + (dir_ / "split").string() +
                                        " --out " + (dir_ / "gt").string());
    ASSERT_EQ(rc, 0) << out;
    std::ifstream f(dir_ / "gt" / "instances.json");
    for (const auto& j : nlohmann::json::parse(f)) {
      GtInstance g;
      g.cad_class = ClassId(j["class"].get<std::string>());
      g.model_id = j["model_id"].get<std::string>();
      g.synset = j["synset"].get<std::string>();
      const auto& c = j["box"]["center"];
      g.center = geometry::Vec3(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
      gt_.push_back(g);
    }
    const fs::path scene = *fs::directory_iterator(dir_ / "split" / "scans");
    const std::string name = scene.filename().string();
    cloud_ = new geometry::PointCloud(
        geometry::ReadPlyCloud((scene / (name + "_vh_clean_2.ply")).string()));
    cloud_->attributes.clear();
    ReconstructorConfig cfg;
    cfg.stage1_model = Model("stage1/stage1.pt");
    cfg.stage2_model = Model("stage2/stage2.pt");
    cfg.bsp_model = Model("bsp/bsp.pt");
    cfg.pool = Model("bsp/pool.bin");
    cfg.preset = ReconstructionPreset::kFast;
    rec_ = new Reconstructor(cfg);
  }
  static void TearDownTestSuite() {
    delete rec_;
    delete cloud_;
    rec_ = nullptr;
    cloud_ = nullptr;
  }
  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_;
  }
  static PointCloudInput Input() { return PointCloudInput::FromPointCloud(*cloud_, "room"); }

  // Index of the GT instance of the same class nearest to the box centre (within 0.4 m), or -1.
  static int MatchGt(const InstanceResult& inst) {
    int best = -1;
    double best_d = 0.4;
    for (std::size_t g = 0; g < gt_.size(); ++g) {
      if (gt_[g].cad_class != inst.cad_class) continue;
      const double d = (gt_[g].center - inst.box.center).head<2>().norm();
      if (d < best_d) {
        best_d = d;
        best = static_cast<int>(g);
      }
    }
    return best;
  }

  static inline std::string skip_;
  static inline fs::path dir_;
  static inline std::vector<GtInstance> gt_;
  static inline geometry::PointCloud* cloud_ = nullptr;
  static inline Reconstructor* rec_ = nullptr;
};

TEST_F(ReconstructorRoom, FindsTheObjectsWithTheirClassesAndMeshesNearThePoints) {
  rec_->SetMode(ReconstructionMode::kGeneration, 1);
  const SceneResult r = rec_->Reconstruct(Input());
  ASSERT_FALSE(r.instances.empty());
  EXPECT_EQ(r.input_points, cloud_->size());
  for (const char* stage : {"validate", "stage1", "stage2", "decode", "mesh", "icp"}) {
    EXPECT_TRUE(r.timings.has(stage)) << stage;
  }
  EXPECT_NE(r.config.find("mode: generation"), std::string::npos);
  // Recall: most GT objects are found with the right class.
  std::vector<bool> found(gt_.size(), false);
  int matched = 0, on_points = 0;
  double prev_score = 2;
  for (const auto& inst : r.instances) {
    EXPECT_LE(inst.score, prev_score);  // descending score
    prev_score = inst.score;
    EXPECT_GT(inst.score, 0.05);
    EXPECT_GT(inst.support.size(), static_cast<std::size_t>(rec_->config().min_points));
    EXPECT_GE(rec_->config().min_points, 1);
    EXPECT_EQ(inst.source, MeshSource::kGenerated);
    EXPECT_EQ(inst.latent.size(), 256);
    const int g = MatchGt(inst);
    if (g >= 0) {
      ++matched;
      found[static_cast<std::size_t>(g)] = true;
    }
    // The mesh lies on the object's points: median distance of its support points to the
    // mesh surface below 5 cm (for most objects; a proposal merging two objects cannot).
    ASSERT_FALSE(inst.mesh.empty());
    const geometry::KdTree surface(geometry::SampleSurface(inst.mesh, 20000, 3).points);
    std::vector<geometry::Vec3> pts;
    for (int i : inst.support) pts.push_back(cloud_->points[static_cast<std::size_t>(i)]);
    auto d = geometry::NearestDistances(pts, surface);
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
    if (d[d.size() / 2] < 0.05) ++on_points;
  }
  EXPECT_GE(on_points, static_cast<int>(0.7 * static_cast<double>(r.instances.size())))
      << on_points << " of " << r.instances.size() << " meshes lie on their points";
  const int recalled = static_cast<int>(std::count(found.begin(), found.end(), true));
  EXPECT_GE(recalled, static_cast<int>(0.6 * static_cast<double>(gt_.size())))
      << recalled << " of " << gt_.size() << " GT objects found";
  EXPECT_GE(matched, static_cast<int>(0.6 * static_cast<double>(r.instances.size())))
      << matched << " of " << r.instances.size() << " predictions match a GT object";
}

TEST_F(ReconstructorRoom, EachModeGivesItsSource) {
  rec_->SetMode(ReconstructionMode::kProjection, 3);
  const SceneResult p = rec_->Reconstruct(Input());
  ASSERT_FALSE(p.instances.empty());
  const ShapePool& pool = *rec_->pool();
  std::map<std::string, int> class_of;
  for (const auto& e : pool.entries()) class_of[e.model_id] = e.cad_class;
  for (const auto& inst : p.instances) {
    EXPECT_EQ(inst.source, MeshSource::kProjected);
    ASSERT_EQ(inst.neighbours.size(), 3u);
    for (const auto& n : inst.neighbours) EXPECT_EQ(class_of.at(n), inst.cad_class);
    EXPECT_EQ(inst.pool_model_id, inst.neighbours[0]);
    EXPECT_EQ(inst.shape_code.size(), 256);
    EXPECT_GT((inst.shape_code - inst.latent).norm(), 1e-6);
  }
  EXPECT_THROW(rec_->SetMode(ReconstructionMode::kRetrieval, 1), InvalidArgument)
      << "the shipped pool has no mesh paths: retrieval must be refused, not faked";
  rec_->SetMode(ReconstructionMode::kGeneration, 1);
  rec_->SetSamples(2);
  const SceneResult g = rec_->Reconstruct(Input());
  rec_->SetSamples(0);
  for (const auto& inst : g.instances) {
    EXPECT_EQ(inst.source, MeshSource::kGenerated);
    EXPECT_TRUE(inst.pool_model_id.empty());
    ASSERT_EQ(inst.alternatives.size(), 2u);
    for (const auto& h : inst.alternatives) {
      EXPECT_GT(h.score, 0.0);
      EXPECT_LT(h.score, inst.score);
      EXPECT_GT((h.latent - inst.latent).head(128).norm(), 1e-3);
    }
  }
}

// The per-object shape work (one batched decode, then mesh extraction and ICP per object on the
// config's threads) gives the same scene at 1 and 2 threads, bit for bit: meshes, alternatives,
// ICP decisions, warnings and the timed stages; also under Remesh (projection). The networks
// run on one intra-op thread in both runs: LibTorch's CPU kernels may split a reduction by the
// thread count (on an AMD EPYC with AVX-512 the scores and meshes of the room differed in
// the last bits between 1 and 2 threads), which is LibTorch's behaviour, not the shape work's.
TEST_F(ReconstructorRoom, ShapesDoNotDependOnTheThreadCount) {
  ReconstructorConfig cfg = rec_->config();
  cfg.samples = 1;
  std::vector<SceneResult> runs, remeshed;
  for (int threads : {1, 2}) {
    cfg.threads = threads;
    const Reconstructor rec(cfg);
    nn::SetIntraOpThreads(1);  // the constructor set `threads`; the shape work still uses them
    runs.push_back(rec.Reconstruct(Input()));
    remeshed.push_back(rec.Remesh(runs.back(), Input(), ReconstructionMode::kProjection, 2));
  }
  for (const auto* pair : {&runs, &remeshed}) {
    const SceneResult& a = (*pair)[0];
    const SceneResult& b = (*pair)[1];
    ASSERT_GE(a.instances.size(), 3u);
    ASSERT_EQ(a.instances.size(), b.instances.size());
    EXPECT_EQ(a.warnings, b.warnings);
    for (const char* stage : {"decode", "mesh", "icp"}) {
      EXPECT_TRUE(a.timings.has(stage) && b.timings.has(stage)) << stage;
    }
    int accepted = 0;
    for (std::size_t i = 0; i < a.instances.size(); ++i) {
      const InstanceResult& x = a.instances[i];
      const InstanceResult& y = b.instances[i];
      EXPECT_EQ(x.cad_class, y.cad_class);
      EXPECT_EQ(x.score, y.score);
      EXPECT_EQ(x.neighbours, y.neighbours);
      EXPECT_EQ(x.icp_accepted, y.icp_accepted);
      EXPECT_TRUE(x.icp_transform.isApprox(y.icp_transform, 0.0)) << i;
      accepted += x.icp_accepted;
      ASSERT_FALSE(x.mesh.empty()) << i;
      EXPECT_EQ(x.mesh.vertices, y.mesh.vertices) << i;
      EXPECT_EQ(x.mesh.faces, y.mesh.faces) << i;
      ASSERT_EQ(x.alternatives.size(), 1u);
      ASSERT_EQ(y.alternatives.size(), 1u);
      EXPECT_EQ(x.alternatives[0].mesh.vertices, y.alternatives[0].mesh.vertices) << i;
    }
    EXPECT_GT(accepted, 0);
  }
}

TEST_F(ReconstructorRoom, RetrievalReturnsTheRoomsOwnCadModelWhenItIsInThePool) {
  // A pool of the room's own CAD models (encoded by the BSP encoder, meshes from the split's
  // ShapeNet tree) plus the shipped pool as distractors.
  const BspDecoder decoder = BspDecoder::Load(Model("bsp/bsp.pt"));
  ShapePool pool = ShapePool::Load(Model("bsp/pool.bin"));
  std::map<std::string, bool> added;
  for (const auto& g : gt_) {
    if (added[g.model_id]) continue;
    added[g.model_id] = true;
    const std::string obj =
        (dir_ / "split" / "shapenet" / g.synset / g.model_id / "models" / "model_normalized.obj")
            .string();
    PoolEntry e;
    e.model_id = g.model_id;
    e.cad_class = g.cad_class;
    BspEncodeOptions enc;
    enc.refine_steps = 30;
    e.code = decoder.EncodeMesh(ReadShapeNetMeshCanonical(obj), g.cad_class, enc);
    e.mesh_path = obj;
    pool.Add(e);
  }
  const fs::path pool_file = dir_ / "room_pool.bin";
  pool.Save(pool_file.string());
  ReconstructorConfig cfg = rec_->config();
  cfg.pool = pool_file.string();
  cfg.mode = ReconstructionMode::kRetrieval;
  const Reconstructor rec(cfg);
  const SceneResult r = rec.Reconstruct(Input());
  int matched = 0, same = 0;
  for (const auto& inst : r.instances) {
    EXPECT_EQ(inst.source, MeshSource::kRetrieved);
    EXPECT_FALSE(inst.pool_model_id.empty());
    EXPECT_FALSE(inst.mesh.empty());
    const int g = MatchGt(inst);
    if (g < 0) continue;
    ++matched;
    if (inst.pool_model_id == gt_[static_cast<std::size_t>(g)].model_id) ++same;
  }
  ASSERT_GT(matched, 0);
  // Most matched objects retrieve exactly their own model out of 2000+ candidates.
  EXPECT_GE(same, (matched + 1) / 2) << same << " of " << matched;
}

TEST_F(ReconstructorRoom, BadInputsGetAClearResultOrError) {
  rec_->SetMode(ReconstructionMode::kGeneration, 1);
  PointCloudInput empty;
  empty.name = "empty";
  SceneResult r = rec_->Reconstruct(empty);
  EXPECT_TRUE(r.instances.empty());
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings.back().find("nothing to reconstruct"), std::string::npos);

  PointCloudInput one;
  one.points = {Eigen::Vector3f(1, 2, 0.5f)};
  r = rec_->Reconstruct(one);
  EXPECT_TRUE(r.instances.empty());
  EXPECT_FALSE(r.warnings.empty());

  // NaN / Inf points are dropped with a warning; the rest is reconstructed.
  PointCloudInput nan = Input();
  const float inf = std::numeric_limits<float>::infinity();
  nan.points[5] = Eigen::Vector3f(std::nanf(""), 0, 0);
  nan.points[9] = Eigen::Vector3f(0, inf, 0);
  r = rec_->Reconstruct(nan);
  EXPECT_EQ(r.used_points, nan.size() - 2);
  EXPECT_FALSE(r.instances.empty());
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings[0].find("2 points with NaN/Inf"), std::string::npos);
  for (const auto& inst : r.instances) {
    for (int i : inst.support) EXPECT_TRUE(nan.points[static_cast<std::size_t>(i)].allFinite());
  }
  // The frame: the room itself has its floor at the bottom; the far half of it as a depth
  // camera in its middle sees it, in the camera's optical frame (z forward, y down), does not.
  for (const auto& w : rec_->Reconstruct(Input()).warnings) {
    EXPECT_EQ(w.find("no floor"), std::string::npos) << w;
  }
  const PointCloudInput room = Input();
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  for (const auto& p : room.points) centre += p;
  centre /= static_cast<float>(room.size());
  centre.z() = 1.3f;
  const Eigen::Matrix3f to_camera = UpAxisRotation("-y").transpose();
  PointCloudInput camera;
  camera.name = "camera";
  for (std::size_t i = 0; i < room.size(); ++i) {
    if (room.points[i].y() < centre.y() + 0.3f) continue;
    camera.points.push_back(to_camera * (room.points[i] - centre));
    if (room.has_colors()) camera.colors.push_back(room.colors[i]);
  }
  const SceneResult cam = rec_->Reconstruct(camera);
  bool warned = false;
  for (const auto& w : cam.warnings) {
    warned = warned || w.find("camera: no floor at the bottom of the cloud") != std::string::npos;
  }
  EXPECT_TRUE(warned) << (cam.warnings.empty() ? std::string("no warning") : cam.warnings[0]);

  PointCloudInput all_nan;
  all_nan.points.assign(500, Eigen::Vector3f(std::nanf(""), 0, 0));
  EXPECT_TRUE(rec_->Reconstruct(all_nan).instances.empty());

  // 10 M points: refused at once, naming the limit.
  PointCloudInput huge;
  huge.name = "huge";
  huge.points.assign(10000000, Eigen::Vector3f(0, 0, 0));
  try {
    rec_->Reconstruct(huge);
    FAIL() << "10 M points accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("max_points"), std::string::npos) << e.what();
  }

  // A cloud in millimetres.
  PointCloudInput mm = Input();
  for (auto& p : mm.points) p *= 1000.f;
  try {
    rec_->Reconstruct(mm);
    FAIL() << "a millimetre cloud was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("millimetres"), std::string::npos) << e.what();
  }

  // All points on a plane (a bare floor): no object, no crash.
  PointCloudInput plane;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.f, 5.f);
  for (int i = 0; i < 50000; ++i) plane.points.emplace_back(u(rng), u(rng), 0.f);
  r = rec_->Reconstruct(plane);
  EXPECT_LE(r.instances.size(), 1u);

  // No floor visible (everything below 0.4 m cut away) and a room only 1.37 m high.
  PointCloudInput no_floor, low;
  for (const auto& p : Input().points) {
    if (p.z() > 0.4f) no_floor.points.push_back(p);
    if (p.z() < 1.37f) low.points.push_back(p);
  }
  EXPECT_NO_THROW(rec_->Reconstruct(no_floor));
  r = rec_->Reconstruct(low);
  EXPECT_FALSE(r.instances.empty()) << "the furniture of a 1.37 m slice is still there";
}

TEST_F(ReconstructorRoom, CliReconstructsAScanNetFolderWithoutLabelsAndEvalReadsTheOutput) {
  // A scene folder with only the cloud (no segs.json, no aggregation, no labels).
  const fs::path scene = *fs::directory_iterator(dir_ / "split" / "scans");
  const std::string name = scene.filename().string();
  const fs::path bare = dir_ / "bare" / name;
  fs::create_directories(bare);
  fs::copy_file(scene / (name + "_vh_clean_2.ply"), bare / (name + "_vh_clean_2.ply"));
  const fs::path out = dir_ / "pred";
  auto [rc, log] = testing::RunCli("reconstruct " + bare.string() + " --preset fast --out " +
                                   out.string() + " --stage1 " + Model("stage1/stage1.pt") +
                                   " --stage2 " + Model("stage2/stage2.pt") + " --bsp " +
                                   Model("bsp/bsp.pt") + " --pool " + Model("bsp/pool.bin"));
  ASSERT_EQ(rc, 0) << log;
  EXPECT_TRUE(fs::exists(out / (name + ".json")));
  EXPECT_TRUE(fs::exists(out / "vis" / (name + ".ply")));
  EXPECT_GT(fs::file_size(out / "vis" / (name + ".png")), 10000u);
  EXPECT_FALSE(fs::is_empty(out / "meshes"));
  const std::string gt = (dir_ / "gt").string();
  std::tie(rc, log) = testing::RunCli("eval --quiet --metrics iou,cd --pred " + out.string() +
                                      " --gt " + gt + "/meshes");
  ASSERT_EQ(rc, 0) << log;
  EXPECT_NE(log.find("Completion quality"), std::string::npos) << log;
  // A bad INPUT is an error naming it.
  std::tie(rc, log) =
      testing::RunCli("reconstruct " + (dir_ / "nothing_here").string() + " --out " + out.string());
  EXPECT_NE(rc, 0);
  EXPECT_NE(log.find("nothing_here"), std::string::npos) << log;
}

TEST_F(ReconstructorRoom, CliTurnsATiltedCameraFrameCloudBackWithUpAndLevel) {
  // The room as a depth camera pitched down by 8 degrees would give it: tilted about x, then in
  // the optical frame (up = -y). --up=-y undoes the frame, --level the tilt; the objects must
  // then come out where the GT has them (the levelling rotation is the inverse of the tilt).
  const Eigen::Matrix3d tilt =
      Eigen::AngleAxisd(8.0 * M_PI / 180.0, geometry::Vec3::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d to_camera = UpAxisRotation("-y").transpose().cast<double>();
  geometry::PointCloud camera = *cloud_;
  camera.Transform(to_camera * tilt);
  const fs::path file = dir_ / "tilted_camera.ply";
  geometry::WritePly(file.string(), camera);
  const fs::path out = dir_ / "pred_tilted";
  const std::string models = " --stage1 " + Model("stage1/stage1.pt") + " --stage2 " +
                             Model("stage2/stage2.pt") + " --bsp " + Model("bsp/bsp.pt") +
                             " --pool " + Model("bsp/pool.bin");
  auto [rc, log] =
      testing::RunCli("reconstruct " + file.string() +
                      " --up=-y --level --preset fast --no-picture --out " + out.string() + models);
  ASSERT_EQ(rc, 0) << log;
  const std::string said = "levelled by its floor plane (tilt ";
  const auto at = log.find(said);
  ASSERT_NE(at, std::string::npos) << log;
  EXPECT_NEAR(std::stod(log.substr(at + said.size())), 8.0, 0.5) << log.substr(at, 60);
  std::ifstream f(out / "tilted_camera.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  int matched = 0, total = 0;
  for (const auto& o : j["instances"]) {
    InstanceResult inst;
    inst.cad_class = ClassId(o["class"].get<std::string>());
    const auto& c = o["box"]["center"];
    inst.box.center = geometry::Vec3(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
    ++total;
    if (MatchGt(inst) >= 0) ++matched;
  }
  ASSERT_GT(total, 0) << log;
  EXPECT_GE(matched, static_cast<int>(0.6 * total)) << matched << " of " << total;
}

}  // namespace
}  // namespace dimr::pipeline
#endif
