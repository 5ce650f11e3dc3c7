// `dimr bench reconstruct`: the whole Reconstructor per room of a fixed size (default 100k
// points: a room with fewer gets the next rooms of the split placed beside it, then a seeded
// random subset of exactly that many points), per-stage split, median over rooms, peak RSS,
// for each preset and thread count. Prints the CPU model and the sparse kernel path.
//
//   dimr bench reconstruct --rooms data/test60 --count 5 --points 100000
//       --presets fast,accurate --threads 1,2 --json out/bench_reconstruct.json
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/core/timing.h"
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
  std::string icp_backend = "own";
  int max_tiles = 4;
  std::string icp_metric = "point_to_point";
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
      {"vote", {"stage1.class_bias", "stage1.vote", "stage1.wall_planes"}},
      {"clustering", {"stage1.clustering"}},
      {"stage2", {"stage2"}},
      {"decode", {"decode", "pool"}},
      {"mesh", {"mesh"}},
      {"icp", {"icp"}},
  };
  return kStages;
}

void RunBench(BenchArgs& a) {
  if (a.rooms.empty())
    throw dimr::InvalidArgument("--rooms DIR (e.g. a SynthScan split) is required");
  if (a.points < 1000) throw dimr::InvalidArgument("--points must be >= 1000");
  a.config.icp.backend = dimr::pipeline::ParseIcpBackend(a.icp_backend);
  a.config.icp.metric = dimr::pipeline::ParseIcpMetric(a.icp_metric);
  a.config.icp.Validate();
  std::vector<dimr::tools::InputScene> scenes = dimr::tools::ListInputScenes(a.rooms);
  if (scenes.empty()) throw dimr::InvalidArgument("--rooms: no rooms in '" + a.rooms + "'");
  std::vector<dimr::pipeline::PointCloudInput> loaded;
  const std::size_t wanted = std::min(
      scenes.size(), static_cast<std::size_t>(a.count) * static_cast<std::size_t>(a.max_tiles));
  for (std::size_t i = 0; i < wanted; ++i) {
    dimr::tools::LoadInputScene(&scenes[i]);
    loaded.push_back(
        dimr::pipeline::PointCloudInput::FromPointCloud(scenes[i].cloud, scenes[i].name));
    scenes[i].cloud = {};
  }
  // Bench room b: room b alone if it has `points` points; otherwise rooms b, b+1, ... (cyclic)
  // side by side along x with a 0.5 m gap (an apartment of several rooms at the scan density
  // the models were trained on) until it does, at most max_tiles rooms. Then a seeded random
  // subset of exactly `points` points (colours / normals alike).
  std::vector<dimr::pipeline::PointCloudInput> inputs;
  std::vector<int> tiles_used;
  const int count = std::min<int>(a.count, static_cast<int>(loaded.size()));
  for (int b = 0; b < count; ++b) {
    dimr::pipeline::PointCloudInput in;
    in.name = loaded[static_cast<std::size_t>(b)].name;
    float x_end = 0;
    int tiles = 0;
    while (static_cast<int>(in.size()) < a.points && tiles < a.max_tiles &&
           tiles < static_cast<int>(loaded.size())) {
      const auto& r = loaded[(static_cast<std::size_t>(b) + tiles) % loaded.size()];
      float x_min = std::numeric_limits<float>::max(), x_max = -x_min;
      for (const auto& p : r.points) {
        x_min = std::min(x_min, p.x());
        x_max = std::max(x_max, p.x());
      }
      const float shift = tiles == 0 ? 0.0f : x_end + 0.5f - x_min;
      for (std::size_t i = 0; i < r.size(); ++i) {
        in.points.push_back(r.points[i] + Eigen::Vector3f(shift, 0, 0));
      }
      const bool colours = r.has_colors() && (tiles == 0 || in.has_colors());
      if (colours)
        in.colors.insert(in.colors.end(), r.colors.begin(), r.colors.end());
      else
        in.colors.clear();
      const bool normals = r.has_normals() && (tiles == 0 || in.has_normals());
      if (normals)
        in.normals.insert(in.normals.end(), r.normals.begin(), r.normals.end());
      else
        in.normals.clear();
      x_end = x_max + shift;
      ++tiles;
      if (tiles > 1) in.name += "+" + r.name;
    }
    tiles_used.push_back(tiles);
    if (static_cast<int>(in.size()) > a.points) {
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
  loaded.clear();
  std::vector<double> sizes;
  for (const auto& in : inputs) sizes.push_back(static_cast<double>(in.size()));
  std::printf(
      "CPU: %s\nsparse kernel path: %s\nrooms: %zu from %s, at most %d points each (median "
      "%.0f; each of up to %d rooms side by side, median %.0f)\nICP: %s %s, <= %d iterations, "
      "%d samples; proposals with > %d points\n",
      CpuModel().c_str(), KernelPath().c_str(), inputs.size(), a.rooms.c_str(), a.points,
      Median(sizes), a.max_tiles, Median(std::vector<double>(tiles_used.begin(), tiles_used.end())),
      dimr::pipeline::IcpBackendName(a.config.icp.backend),
      dimr::pipeline::IcpMetricName(a.config.icp.metric), a.config.icp.max_iterations,
      a.config.icp.samples, a.config.min_points);
  nlohmann::json out;
  out["cpu"] = CpuModel();
  out["kernel_path"] = KernelPath();
  out["points"] = a.points;
  out["points_median"] = Median(sizes);
  out["rooms_side_by_side_median"] =
      Median(std::vector<double>(tiles_used.begin(), tiles_used.end()));
  out["icp_backend"] = dimr::pipeline::IcpBackendName(a.config.icp.backend);
  out["icp_metric"] = dimr::pipeline::IcpMetricName(a.config.icp.metric);
  out["icp_max_iterations"] = a.config.icp.max_iterations;
  out["icp_samples"] = a.config.icp.samples;
  out["min_points"] = a.config.min_points;
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
        // End to end = the wall time of the call (the per-object mesh and ICP stages run on
        // several threads: their columns are summed over objects, i.e. over threads).
        const dimr::Stopwatch clock;
        const auto r = rec.Reconstruct(in);
        totals.push_back(clock.ElapsedMs());
        for (const auto& [name, keys] : Stages()) {
          double ms = 0;
          for (const auto& k : keys) ms += r.timings.ms(k);
          stage_ms[name].push_back(ms);
        }
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
      "\n(median over rooms; total = wall time of Reconstruct, mesh and icp = summed over the "
      "objects, which run on the threads in parallel; peak RSS is the process high-water mark "
      "so far; goals on 2 cores: fast <= 500 ms, accurate <= 2000 ms, peak RSS <= 2048 MB)\n");
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
  app.add_option("--max-rooms-side-by-side", a->max_tiles,
                 "a room with fewer than --points points gets the next rooms placed beside it "
                 "(up to this many rooms in all; 1 = never)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--min-points", a->config.min_points,
                 "keep proposals with more points (as dimr reconstruct --min-points; fixes the "
                 "object count when comparing binaries with other defaults)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--json", a->json_out, "write the results as JSON here");
  app.add_option("--icp-backend", a->icp_backend, "ICP: own or pcl")->capture_default_str();
  app.add_option("--icp-metric", a->icp_metric, "ICP (own): point_to_point or point_to_plane")
      ->capture_default_str();
  app.add_option("--icp-iterations", a->config.icp.max_iterations, "ICP: at most this many")
      ->capture_default_str();
  app.add_option("--icp-samples", a->config.icp.samples, "ICP: mesh surface samples")
      ->capture_default_str();
  app.callback([a]() { RunBench(*a); });
}

const dimr::tools::Registrar kReg("bench", "reconstruct",
                                  "End-to-end Reconstructor time per room with a per-stage split",
                                  &SetupBench);

}  // namespace
