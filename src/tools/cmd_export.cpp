// `dimr export gt`: the evaluation ground truth of a SynthScan split (or any ScanNet-format
// scans folder with <scene>.synthscan.json and a ShapeNet tree): per CAD instance the CAD
// mesh placed like the reference's GT meshes (dimr-metrics.md section 1.2: axes remapped,
// per-axis normalised, scaled to the box, rotated by its heading, translated) written as
// `meshes/{scene}_{k}_{class}_1.ply`, and the PCR point files `points/{scene}.ply` (x y z,
// semantic_label, instance_label; eval/inputs.h). Then
//   dimr reconstruct SPLIT --out PRED && dimr eval --pred PRED --gt GT/meshes --gt-points GT/points
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/pipeline/placement.h"
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
  for (const auto& c : counts) {
    meshes += c.meshes;
    missing += c.missing_models;
    points += c.points;
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
}

const dimr::tools::Registrar kReg("", "export", "Export evaluation ground truth (`export gt`)",
                                  &SetupExport);

}  // namespace
