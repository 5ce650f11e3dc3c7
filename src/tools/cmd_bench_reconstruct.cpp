// `dimr bench reconstruct`: the whole Reconstructor per room of a fixed size (default 100k
// points, a seeded random subset of each room), per-stage split, median over rooms, peak RSS,
// for each preset and thread count. Prints the CPU model and the sparse kernel path.
//
//   dimr bench reconstruct --rooms data/test60 --count 5 --points 100000
//       --presets fast,accurate --threads 1,2 --json out/bench_reconstruct.json
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/reconstructor.h"
#include "tools/command_registry.h"
#include "tools/reconstruct_io.h"

namespace {

struct BenchArgs {
  std::string rooms;
  int count = 5;
  int points = 100000;
  std::string presets = "fast,accurate";
  std::string threads = "1,2";
  std::string mode = "generation";
  dimr::pipeline::ReconstructorConfig config;
  std::uint64_t seed = 1;
  std::string json_out;
};

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double PeakRssMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;
}

std::string CpuModel() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto c = line.find(':');
      return c == std::string::npos ? line : line.substr(c + 2);
    }
  }
  return "unknown";
}

std::string KernelPath() { return dimr::nn::SparseKernelsInUse(); }

// The reported stages: name in the table -> timing keys summed.
const std::vector<std::pair<std::string, std::vector<std::string>>>& Stages() {
  static const std::vector<std::pair<std::string, std::vector<std::string>>> kStages = {
      {"validate", {"validate"}},
      {"voxelise", {"stage1.voxelize", "stage1.kernel_maps"}},
      {"unet", {"stage1.unet"}},
      {"heads", {"stage1.heads"}},
      {"vote", {"stage1.class_bias", "stage1.vote"}},
      {"clustering", {"stage1.clustering"}},
      {"stage2", {"stage2"}},
      {"decode", {"decode", "pool"}},
      {"mesh", {"mesh"}},
      {"icp", {"icp"}},
  };
  return kStages;
}

void RunBench(const BenchArgs& a) {
  if (a.rooms.empty())
    throw dimr::InvalidArgument("--rooms DIR (e.g. a SynthScan split) is required");
  if (a.points < 1000) throw dimr::InvalidArgument("--points must be >= 1000");
  std::vector<dimr::tools::InputScene> scenes = dimr::tools::ListInputScenes(a.rooms);
  if (static_cast<int>(scenes.size()) > a.count) scenes.resize(a.count);
  std::vector<dimr::pipeline::PointCloudInput> inputs;
  for (auto& s : scenes) {
    dimr::tools::LoadInputScene(&s);
    auto in = dimr::pipeline::PointCloudInput::FromPointCloud(s.cloud, s.name);
    if (static_cast<int>(in.size()) > a.points) {
      // A seeded random subset of exactly `points` points (colours / normals alike).
      std::vector<std::size_t> idx(in.size());
      std::iota(idx.begin(), idx.end(), 0);
      std::mt19937_64 rng(a.seed);
      std::shuffle(idx.begin(), idx.end(), rng);
      idx.resize(static_cast<std::size_t>(a.points));
      std::sort(idx.begin(), idx.end());
      dimr::pipeline::PointCloudInput sub;
      sub.name = in.name;
      for (std::size_t i : idx) {
        sub.points.push_back(in.points[i]);
        if (in.has_colors()) sub.colors.push_back(in.colors[i]);
        if (in.has_normals()) sub.normals.push_back(in.normals[i]);
      }
      in = std::move(sub);
    }
    inputs.push_back(std::move(in));
  }
  std::printf(
      "CPU: %s\nsparse kernel path: %s\nrooms: %zu from %s, %d points each (fewer if a "
      "room has fewer)\n",
      CpuModel().c_str(), KernelPath().c_str(), inputs.size(), a.rooms.c_str(), a.points);
  nlohmann::json out;
  out["cpu"] = CpuModel();
  out["kernel_path"] = KernelPath();
  out["points"] = a.points;
  out["rooms"] = inputs.size();
  out["runs"] = nlohmann::json::array();
  std::printf("\n%-9s %3s %9s", "preset", "thr", "total ms");
  for (const auto& [name, keys] : Stages()) std::printf(" %10s", name.c_str());
  std::printf(" %8s %9s\n", "objects", "peak MB");
  for (const std::string& preset : Split(a.presets)) {
    for (const std::string& th : Split(a.threads)) {
      dimr::pipeline::ReconstructorConfig cfg = a.config;
      cfg.preset = dimr::pipeline::ParseReconstructionPreset(preset);
      cfg.mode = dimr::pipeline::ParseReconstructionMode(a.mode);
      cfg.threads = std::stoi(th);
      dimr::pipeline::Reconstructor rec(cfg);
      rec.Reconstruct(inputs.front());  // warm-up (allocator, first-call costs)
      std::vector<double> totals, objects;
      std::map<std::string, std::vector<double>> stage_ms;
      for (const auto& in : inputs) {
        const auto r = rec.Reconstruct(in);
        double total = 0;
        for (const auto& [name, keys] : Stages()) {
          double ms = 0;
          for (const auto& k : keys) ms += r.timings.ms(k);
          stage_ms[name].push_back(ms);
        }
        // End to end = the stages the Reconstructor timed at top level.
        for (const char* k : {"validate", "stage1", "stage2", "decode", "pool", "mesh", "icp"}) {
          total += r.timings.ms(k);
        }
        totals.push_back(total);
        objects.push_back(static_cast<double>(r.instances.size()));
      }
      const double rss = PeakRssMb();
      std::printf("%-9s %3s %9.0f", preset.c_str(), th.c_str(), Median(totals));
      nlohmann::json run;
      run["preset"] = preset;
      run["threads"] = cfg.threads;
      run["total_ms_median"] = Median(totals);
      run["total_ms"] = totals;
      for (const auto& [name, keys] : Stages()) {
        std::printf(" %10.1f", Median(stage_ms[name]));
        run["stages_ms_median"][name] = Median(stage_ms[name]);
      }
      std::printf(" %8.1f %9.0f\n", Median(objects), rss);
      run["objects_median"] = Median(objects);
      run["peak_rss_mb"] = rss;
      out["runs"].push_back(run);
    }
  }
  std::printf(
      "\n(median over rooms; peak RSS is the process high-water mark so far; goals on 2 "
      "cores: fast <= 500 ms, accurate <= 2000 ms, peak RSS <= 2048 MB)\n");
  if (!a.json_out.empty()) {
    std::ofstream f(a.json_out);
    f << out.dump(1) << "\n";
    if (!f) throw dimr::Error("cannot write '" + a.json_out + "'");
  }
}

void SetupBench(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  app.add_option("--rooms", a->rooms, "rooms: SynthScan split, scans folder or a cloud")
      ->required();
  app.add_option("--count", a->count, "rooms to time")->capture_default_str();
  app.add_option("--points", a->points, "points per room (seeded random subset)")
      ->capture_default_str();
  app.add_option("--presets", a->presets, "comma-separated presets")->capture_default_str();
  app.add_option("--threads", a->threads, "comma-separated network thread counts")
      ->capture_default_str();
  app.add_option("--mode", a->mode, "generation | projection | retrieval")->capture_default_str();
  app.add_option("--stage1", a->config.stage1_model, "stage-1 weights")->capture_default_str();
  app.add_option("--stage2", a->config.stage2_model, "stage-2 weights")->capture_default_str();
  app.add_option("--bsp", a->config.bsp_model, "BSP weights")->capture_default_str();
  app.add_option("--pool", a->config.pool, "pool")->capture_default_str();
  app.add_option("--pool-meshes", a->config.pool_meshes, "retrieval: pool CAD tree");
  app.add_option("--seed", a->seed, "subset seed")->capture_default_str();
  app.add_option("--json", a->json_out, "write the results as JSON here");
  app.callback([a]() { RunBench(*a); });
}

const dimr::tools::Registrar kReg("bench", "reconstruct",
                                  "End-to-end Reconstructor time per room with a per-stage split",
                                  &SetupBench);

}  // namespace
