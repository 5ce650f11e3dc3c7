// `dimr export gt`: the evaluation ground truth of a SynthScan split (or any ScanNet-format
// scans folder with <scene>.synthscan.json and a ShapeNet tree): per CAD instance the CAD
// mesh placed like the reference's GT meshes (dimr-metrics.md section 1.2: axes remapped,
// per-axis normalised, scaled to the box, rotated by its heading, translated) written as
// `meshes/{scene}_{k}_{class}_1.ply`, and the PCR point files `points/{scene}.ply` (x y z,
// semantic_label, instance_label; eval/inputs.h), and `instances.json` (per GT mesh: scene,
// file, class, instance id, CAD model id, box, point count). Then
//   dimr reconstruct SPLIT --out PRED && dimr eval --pred PRED --gt GT/meshes --gt-points GT/points
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/labels.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/pipeline/placement.h"
#include "dimr/pipeline/shape_pool.h"
#include "tools/command_registry.h"

namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string split;
  std::string shapenet;  // default: <split>/shapenet
  std::string out;
  int jobs = 0;
};

struct SceneCount {
  nlohmann::json instances = nlohmann::json::array();  // one per GT mesh
  int meshes = 0;
  int missing_models = 0;
  std::size_t points = 0;
};

SceneCount ExportScene(const fs::path& scene_dir, const fs::path& shapenet, const fs::path& out) {
  const dimr::data::SynthScene scene = dimr::data::ReadScanNetScene(scene_dir.string());
  SceneCount count;
  int k = 0;
  for (const auto& inst : scene.instances) {
    if (inst.cad_class < 0 || inst.cad_class >= dimr::data::kNumCadClasses) continue;
    if (inst.model_id.empty()) {
      ++count.missing_models;
      continue;
    }
    const std::string synset =
        inst.synset.empty() ? dimr::data::CadSynsets()[inst.cad_class] : inst.synset;
    const fs::path obj = shapenet / dimr::data::ShapeNetRelativePath(synset, inst.model_id);
    std::error_code ec;
    if (!fs::is_regular_file(obj, ec)) {
      throw dimr::ParseError(obj.string(), "CAD model of instance " + std::to_string(inst.id) +
                                               " of " + scene.name + " not found");
    }
    const dimr::geometry::TriangleMesh placed = dimr::pipeline::PlaceRetrievedMesh(
        dimr::pipeline::ReadShapeNetMeshCanonical(obj.string()), inst.box);
    const std::string name = scene.name + "_" + std::to_string(k) + "_" +
                             dimr::data::CadClassNames()[inst.cad_class] + "_1.ply";
    dimr::geometry::WritePly((out / "meshes" / name).string(), placed);
    count.instances.push_back(
        {{"scene", scene.name},
         {"mesh", "meshes/" + name},
         {"class", dimr::data::CadClassNames()[inst.cad_class]},
         {"instance", inst.id},
         {"model_id", inst.model_id},
         {"synset", synset},
         {"box",
          {{"center", {inst.box.center.x(), inst.box.center.y(), inst.box.center.z()}},
           {"size", {inst.box.size.x(), inst.box.size.y(), inst.box.size.z()}},
           {"heading", inst.box.heading}}},
         {"num_points", inst.num_points}});
    ++count.meshes;
    ++k;
  }
  dimr::geometry::PointCloud pts;
  pts.points = scene.points;
  std::vector<double> sem(scene.points.size()), ins(scene.points.size());
  for (std::size_t i = 0; i < scene.points.size(); ++i) {
    const int s = scene.semantic[i];
    sem[i] = s >= 0 && s < 255 ? s : 255;
    ins[i] = scene.instance[i];
  }
  pts.SetAttribute("semantic_label", dimr::geometry::ScalarType::kUInt8, std::move(sem));
  pts.SetAttribute("instance_label", dimr::geometry::ScalarType::kUInt16, std::move(ins));
  dimr::geometry::WritePly((out / "points" / (scene.name + ".ply")).string(), pts);
  count.points = scene.points.size();
  return count;
}

void RunExportGt(const ExportArgs& a) {
  const fs::path split(a.split);
  std::error_code ec;
  fs::path scans = split / "scans";
  if (!fs::is_directory(scans, ec)) scans = split;
  const fs::path shapenet = a.shapenet.empty() ? split / "shapenet" : fs::path(a.shapenet);
  if (!fs::is_directory(shapenet, ec)) {
    throw dimr::ParseError(shapenet.string(), "no ShapeNet-style CAD tree (pass --shapenet)");
  }
  std::vector<fs::path> scenes;
  for (const auto& e : fs::directory_iterator(scans, ec)) {
    const fs::path d = e.path();
    if (e.is_directory() &&
        fs::is_regular_file(d / (d.filename().string() + "_vh_clean_2.ply"), ec)) {
      scenes.push_back(d);
    }
  }
  std::sort(scenes.begin(), scenes.end());
  if (scenes.empty()) throw dimr::ParseError(scans.string(), "holds no ScanNet scene folder");
  const fs::path out(a.out);
  for (const char* sub : {"meshes", "points"}) {
    fs::create_directories(out / sub, ec);
    if (!fs::is_directory(out / sub)) {
      throw dimr::Error("cannot create the output folder '" + (out / sub).string() + "'");
    }
  }
  std::vector<SceneCount> counts(scenes.size());
  std::vector<std::string> errors(scenes.size());
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i = next++; i < scenes.size(); i = next++) {
      try {
        counts[i] = ExportScene(scenes[i], shapenet, out);
      } catch (const std::exception& e) {
        errors[i] = e.what();
      }
    }
  };
  const int hw = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int jobs = std::max(1, std::min<int>(a.jobs > 0 ? a.jobs : hw, scenes.size()));
  std::vector<std::thread> threads;
  for (int t = 1; t < jobs; ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  for (std::size_t i = 0; i < scenes.size(); ++i) {
    if (!errors[i].empty()) throw dimr::Error(scenes[i].string() + ": " + errors[i]);
  }
  int meshes = 0, missing = 0;
  std::size_t points = 0;
  nlohmann::json index = nlohmann::json::array();
  for (const auto& c : counts) {
    for (const auto& i : c.instances) index.push_back(i);
    meshes += c.meshes;
    missing += c.missing_models;
    points += c.points;
  }
  {
    std::ofstream f(out / "instances.json");
    f << index.dump(1) << "\n";
    if (!f) throw dimr::Error("cannot write '" + (out / "instances.json").string() + "'");
  }
  std::printf("exported %zu scenes: %d GT meshes in %s, %zu PCR points in %s\n", scenes.size(),
              meshes, (out / "meshes").string().c_str(), points, (out / "points").string().c_str());
  if (missing > 0) {
    std::fprintf(stderr,
                 "dimr export gt: warning: %d CAD instances have no CAD model id (real ScanNet "
                 "without Scan2CAD?) and no GT mesh\n",
                 missing);
  }
}

struct PoolMeshArgs {
  std::string pool = "models/bsp/pool.bin";
  std::uint64_t seed = 1;
  int per_class = 250;
  std::string out;
  std::string write_pool;
};

// The model seeds of `dimr bsp prepare` (src/tools/cmd_bsp_prepare.cpp ModelSeed): the shipped
// pool encodes `bsp prepare --per-class 250 --seed 1`. A drift between the two is caught below:
// every pool id must be regenerated.
std::uint64_t PrepareModelSeed(std::uint64_t seed, int cad_class, int i) {
  return seed * 1000003ull + static_cast<std::uint64_t>(cad_class) * 7919ull * 1000003ull +
         static_cast<std::uint64_t>(i);
}

void RunExportPoolMeshes(const PoolMeshArgs& a) {
  dimr::pipeline::ShapePool pool = dimr::pipeline::ShapePool::Load(a.pool);
  std::map<std::string, std::size_t> index;
  for (std::size_t i = 0; i < pool.size(); ++i) index[pool.entries()[i].model_id] = i;
  std::vector<dimr::data::CadModel> models;
  for (int c = 0; c < dimr::data::kNumCadClasses; ++c) {
    for (int i = 0; i < a.per_class; ++i) {
      dimr::data::CadModel m = dimr::data::GenerateCadModel(c, PrepareModelSeed(a.seed, c, i));
      if (index.count(m.model_id) != 0) models.push_back(std::move(m));
    }
  }
  if (models.size() != pool.size()) {
    throw dimr::InvalidArgument(
        "export pool-meshes: regenerated " + std::to_string(models.size()) + " of the " +
        std::to_string(pool.size()) + " pool models from --seed " + std::to_string(a.seed) +
        " --per-class " + std::to_string(a.per_class) +
        " (pass the `dimr bsp prepare` arguments the pool was encoded from)");
  }
  dimr::data::WriteShapeNetTree(a.out, models);
  const int attached = pool.AttachMeshTree(a.out);
  std::printf("wrote %zu pool CAD models to %s (%d pool entries have a mesh)\n", models.size(),
              a.out.c_str(), attached);
  if (!a.write_pool.empty()) {
    pool.Save(a.write_pool);
    std::printf("wrote the pool with mesh paths to %s\n", a.write_pool.c_str());
  }
}

void SetupExport(CLI::App& app) {
  app.require_subcommand(1);
  auto* gt = app.add_subcommand("gt",
                                "Evaluation GT of a SynthScan split: placed CAD meshes per "
                                "instance and PCR point files");
  auto a = std::make_shared<ExportArgs>();
  gt->add_option("--split", a->split, "SynthScan split (with scans/ and shapenet/) or scans folder")
      ->required();
  gt->add_option("--shapenet", a->shapenet, "CAD tree (default: <split>/shapenet)");
  gt->add_option("--out", a->out, "output folder (meshes/, points/)")->required();
  gt->add_option("--jobs", a->jobs, "threads (0 = all cores)")->capture_default_str();
  gt->callback([a]() { RunExportGt(*a); });
  auto* pm = app.add_subcommand(
      "pool-meshes",
      "The CAD meshes of a procedural shape pool as a ShapeNet-style tree (retrieval)");
  auto p = std::make_shared<PoolMeshArgs>();
  pm->add_option("--pool", p->pool, "shape pool (dimr encode-pool)")->capture_default_str();
  pm->add_option("--seed", p->seed, "the `dimr bsp prepare --seed` of the pool's models")
      ->capture_default_str();
  pm->add_option("--per-class", p->per_class, "the `dimr bsp prepare --per-class`")
      ->capture_default_str();
  pm->add_option("--out", p->out, "output ShapeNet-style tree")->required();
  pm->add_option("--write-pool", p->write_pool, "also write the pool with these mesh paths here");
  pm->callback([p]() { RunExportPoolMeshes(*p); });
}

const dimr::tools::Registrar kReg("", "export", "Export evaluation ground truth (`export gt`)",
                                  &SetupExport);

}  // namespace
