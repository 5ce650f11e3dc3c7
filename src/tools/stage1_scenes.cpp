#include "tools/stage1_scenes.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <filesystem>
#include <map>
#include <thread>

#include "dimr/data/scan2cad_io.h"
#include "dimr/data/scan2cad_relabel.h"
#include "dimr/data/scannet_io.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_data.h"

namespace dimr::tools {

nn::Stage1Sample Stage1SampleFromScene(const data::SynthScene& scene) {
  const std::size_t n = scene.points.size();
  if (scene.semantic.size() != n || scene.instance.size() != n ||
      (!scene.colors.empty() && scene.colors.size() != n)) {
    throw InvalidArgument("scene '" + scene.name + "': per-point arrays disagree in length");
  }
  nn::Stage1Sample s;
  s.name = scene.name;
  std::map<int, int> index_of;  // 1-based id -> compact index
  for (const data::SynthInstance& in : scene.instances) {
    if (!index_of.emplace(in.id, static_cast<int>(s.instances.size())).second) {
      throw InvalidArgument("scene '" + scene.name + "': duplicate instance id " +
                            std::to_string(in.id));
    }
    nn::Stage1Instance out;
    out.semantic =
        in.rfs_class >= 0 && in.rfs_class < nn::kStage1Classes ? in.rfs_class : nn::kStage1Ignore;
    out.cad_class = in.cad_class >= 0 && in.cad_class < 8 ? in.cad_class : -1;
    // A heading exists only where a CAD model is aligned (SynthScan, or a Scan2CAD model linked
    // by RelabelWithScan2Cad); real ScanNet instances without one carry no heading label.
    out.has_heading = out.cad_class >= 0 && !in.model_id.empty();
    out.heading = in.box.heading;
    s.instances.push_back(out);
  }
  s.points.resize(n);
  s.semantic.resize(n);
  s.instance.resize(n);
  if (!scene.colors.empty()) s.colors.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    s.points[i] = scene.points[i].cast<float>();
    if (!scene.colors.empty()) s.colors[i] = scene.colors[i].cast<float>() / 255.0f;
    const int sem = scene.semantic[i];
    s.semantic[i] = sem >= 0 && sem < nn::kStage1Classes ? sem : nn::kStage1Ignore;
    const int id = scene.instance[i];
    if (id == 0) {
      s.instance[i] = -1;
      continue;
    }
    auto it = index_of.find(id);
    if (it == index_of.end()) {
      throw InvalidArgument("scene '" + scene.name + "': point " + std::to_string(i) +
                            " has instance id " + std::to_string(id) +
                            " that is not in the instance list");
    }
    s.instance[i] = it->second;
  }
  s.Validate();
  return s;
}

Scan2CadByScene ReadScan2CadByScene(const std::string& path) {
  Scan2CadByScene out;
  for (data::Scan2CadScene& s : data::ReadScan2CadAnnotations(path)) {
    const std::string id = s.id_scan;
    if (!out.emplace(id, std::move(s)).second) {
      throw ParseError(path, "scan '" + id + "' is listed twice");
    }
  }
  return out;
}

namespace {

enum class SceneSource { kSynthScan, kRelabelled, kKeptSynthScan, kRealWithoutScan2Cad };

// Boxes of real ScanNet instances: the axis-aligned box of their points (heading 0).
void PointBoxes(data::SynthScene* scene) {
  std::map<int, geometry::AABB> bounds;
  for (std::size_t k = 0; k < scene->points.size(); ++k) {
    if (scene->instance[k] > 0) bounds[scene->instance[k]].Extend(scene->points[k]);
  }
  for (data::SynthInstance& in : scene->instances) {
    in.box = geometry::OrientedBox();
    auto it = bounds.find(in.id);
    if (it == bounds.end()) continue;
    in.box.center = it->second.Center();
    in.box.size = it->second.Extent();
  }
}

data::SynthScene ReadStage1Scene(const std::string& dir, const std::string& name,
                                 const Scan2CadByScene* scan2cad, bool force_scan2cad,
                                 SceneSource* source, data::RelabelStats* stats) {
  namespace fs = std::filesystem;
  data::SynthScene scene = data::ReadScanNetScene(dir);
  const bool synthscan = fs::exists(fs::path(dir) / (name + ".synthscan.json"));
  const data::Scan2CadScene* annotation = nullptr;
  if (scan2cad != nullptr) {
    auto it = scan2cad->find(scene.name);
    if (it != scan2cad->end()) annotation = &it->second;
  }
  if (annotation != nullptr && (!synthscan || force_scan2cad)) {
    *stats = data::RelabelWithScan2Cad(&scene, *annotation);
    *source = SceneSource::kRelabelled;
  } else if (synthscan) {
    *source = annotation != nullptr ? SceneSource::kKeptSynthScan : SceneSource::kSynthScan;
  } else {
    data::AxisAlignScene(&scene);
    PointBoxes(&scene);
    *source = SceneSource::kRealWithoutScan2Cad;
  }
  return scene;
}

}  // namespace

std::vector<nn::Stage1Sample> LoadStage1Scenes(const std::string& scans_dir,
                                               const std::vector<std::string>& scene_names,
                                               int threads, const Scan2CadByScene* scan2cad,
                                               bool force_scan2cad, Stage1LoadReport* report) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(scans_dir)) {
    throw ParseError(scans_dir, "not a folder of ScanNet scene folders");
  }
  std::vector<std::string> names = scene_names;
  if (names.empty()) {
    for (const auto& e : fs::directory_iterator(scans_dir)) {
      if (e.is_directory()) names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
  }
  std::vector<nn::Stage1Sample> out(names.size());
  std::vector<SceneSource> sources(names.size(), SceneSource::kSynthScan);
  std::vector<data::RelabelStats> stats(names.size());
  std::vector<std::exception_ptr> errors(names.size());
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i = next++; i < names.size(); i = next++) {
      const std::string dir = (fs::path(scans_dir) / names[i]).string();
      try {
        out[i] = Stage1SampleFromScene(
            ReadStage1Scene(dir, names[i], scan2cad, force_scan2cad, &sources[i], &stats[i]));
      } catch (const std::exception& e) {
        errors[i] = std::make_exception_ptr(ParseError(dir, e.what()));
      }
    }
  };
  int n_threads = threads > 0 ? threads : static_cast<int>(std::thread::hardware_concurrency());
  n_threads = std::max(1, std::min<int>(n_threads, static_cast<int>(names.size())));
  std::vector<std::thread> pool;
  for (int t = 1; t < n_threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  if (report != nullptr) {
    *report = Stage1LoadReport();
    for (std::size_t i = 0; i < names.size(); ++i) {
      switch (sources[i]) {
        case SceneSource::kRelabelled: {
          ++report->relabelled;
          data::RelabelStats& t = report->relabel;
          const data::RelabelStats& s = stats[i];
          t.kept += s.kept;
          t.dropped_ignored += s.dropped_ignored;
          t.dropped_rebuilt += s.dropped_rebuilt;
          t.rebuilt += s.rebuilt;
          t.rebuilt_empty += s.rebuilt_empty;
          t.linked += s.linked;
          t.unmatched += s.unmatched;
          t.non_cad_models += s.non_cad_models;
          t.kept_with_box += s.kept_with_box;
          t.points_lost += s.points_lost;
          break;
        }
        case SceneSource::kKeptSynthScan:
          ++report->kept_synthscan;
          break;
        case SceneSource::kRealWithoutScan2Cad:
          ++report->without_scan2cad;
          break;
        case SceneSource::kSynthScan:
          break;
      }
    }
  }
  return out;
}

const config::EnumNames<SceneSplit>& SceneSplitNames() {
  static const config::EnumNames<SceneSplit> names("split", {{SceneSplit::kTrain, "train"},
                                                             {SceneSplit::kVal, "val"},
                                                             {SceneSplit::kTest, "test"},
                                                             {SceneSplit::kOther, "other"}});
  return names;
}

SceneSplit Stage1SplitOf(const std::string& name) {
  if (name.size() < 9 || name.compare(0, 5, "scene") != 0) return SceneSplit::kOther;
  int id = 0;
  for (int k = 5; k < 9; ++k) {
    if (name[k] < '0' || name[k] > '9') return SceneSplit::kOther;
    id = id * 10 + (name[k] - '0');
  }
  return id < 5000 ? SceneSplit::kTrain : id < 8000 ? SceneSplit::kVal : SceneSplit::kTest;
}

std::string Stage1SplitOfScene(const std::string& name) {
  return SceneSplitNames().Name(Stage1SplitOf(name));
}

}  // namespace dimr::tools
