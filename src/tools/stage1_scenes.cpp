#include "tools/stage1_scenes.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <filesystem>
#include <map>
#include <thread>

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
    out.has_heading = out.cad_class >= 0;
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

std::vector<nn::Stage1Sample> LoadStage1Scenes(const std::string& scans_dir,
                                               const std::vector<std::string>& scene_names,
                                               int threads) {
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
  std::vector<std::exception_ptr> errors(names.size());
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i = next++; i < names.size(); i = next++) {
      const std::string dir = (fs::path(scans_dir) / names[i]).string();
      try {
        out[i] = Stage1SampleFromScene(data::ReadScanNetScene(dir));
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
  return out;
}

std::string Stage1SplitOfScene(const std::string& name) {
  if (name.size() < 9 || name.compare(0, 5, "scene") != 0) return "other";
  int id = 0;
  for (int k = 5; k < 9; ++k) {
    if (name[k] < '0' || name[k] > '9') return "other";
    id = id * 10 + (name[k] - '0');
  }
  return id < 5000 ? "train" : id < 8000 ? "val" : "test";
}

}  // namespace dimr::tools
