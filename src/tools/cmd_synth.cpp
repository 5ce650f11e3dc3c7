// `dimr synth`: generate a SynthScan split (ScanNet scene folders, Scan2CAD annotations, the
// ShapeNet tree, optional rosbags, the synthscan.yaml index).
// `dimr bench synth`: the same pipeline timed, reporting scenes per minute and the realism
// statistics next to ScanNet's.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "dimr/core/parallel.h"
#include "dimr/core/timing.h"
#include "dimr/data/labels.h"
#include "dimr/data/real_furniture.h"
#include "dimr/data/scan2cad_io.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/data/synthscan.h"
#include "dimr/geometry/error.h"
#include "tools/command_registry.h"
#include "tools/render.h"
#ifdef DIMR_HAVE_ROS
#include "dimr/ros/bag_writer.h"
#endif

namespace {

namespace fs = std::filesystem;
using dimr::data::GeneratedScene;
using dimr::data::SceneSummary;

struct SynthOptions {
  int scenes = 10;
  std::uint64_t seed = 0;
  std::string split = "train";
  std::string out;
  std::string shard = "0/1";
  std::string density = "mesh";
  std::string realism = "auto";  // auto = v2 for --density scannet, off otherwise
  bool bags = false;
  int frames = 60;
  int jobs = 0;
  double drift = 0.0;  // translation drift per frame (m); rotation = drift * 40 deg/m
  int map_cloud_every = 10;
  double real_furniture = 0.0;  // fraction of CAD objects / distractors from the import
  std::string real_furniture_dir = "data/sh3d";
  double window_pane = 0.0;   // RoomConfig::window_pane
  double studio = 0.0;        // RoomConfig::studio
  double door_closed = 0.35;  // RoomConfig::door_closed
  bool quiet = false;
  bool render = false;
  std::string scanner;  // 'key=value ...' on top of the mode's ScannerConfig (ScannerFields)
};

struct RunResult {
  std::vector<SceneSummary> summaries;
  double seconds = 0;
  std::size_t bytes = 0;
  // Scanner stages summed over every scene (ray_cast; scannet mode: integrate, marching_cubes,
  // clean, decimate, colour, labels) and the whole of GenerateScene ("scene"), in thread ms.
  dimr::Timings stages;
};

void ParseShard(const std::string& s, int* index, int* count) {
  const auto slash = s.find('/');
  try {
    if (slash == std::string::npos) throw std::invalid_argument("no slash");
    std::size_t used = 0;
    *index = std::stoi(s.substr(0, slash), &used);
    if (used != slash) throw std::invalid_argument("index");
    const std::string n = s.substr(slash + 1);
    *count = std::stoi(n, &used);
    if (used != n.size()) throw std::invalid_argument("count");
  } catch (const std::exception&) {
    throw dimr::InvalidArgument("--shard: expected i/n (e.g. 0/4), got '" + s + "'");
  }
  if (*count < 1 || *index < 0 || *index >= *count)
    throw dimr::InvalidArgument("--shard: need 0 <= i < n, got '" + s + "'");
}

void EnsureWritableDir(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw dimr::Error("cannot create the output folder '" + dir.string() + "'" +
                      (ec ? ": " + ec.message() : std::string()));
  const fs::path probe = dir / ".dimr_write_test";
  {
    std::ofstream f(probe);
    if (!f) throw dimr::Error("the output folder '" + dir.string() + "' is not writable");
  }
  fs::remove(probe, ec);
}

std::size_t FolderBytes(const fs::path& dir) {
  std::size_t total = 0;
  std::error_code ec;
  for (const auto& e : fs::recursive_directory_iterator(dir, ec)) {
    if (e.is_regular_file(ec)) total += e.file_size(ec);
  }
  return total;
}

class Progress {
 public:
  Progress(int total, bool quiet) : total_(total), quiet_(quiet) {}
  void Tick() {
    std::lock_guard<std::mutex> lock(mu_);
    ++done_;
    if (quiet_) return;
    const double s = elapsed_.ElapsedSeconds();
    const int width = 30;
    const int fill = total_ ? width * done_ / total_ : width;
    std::string bar(fill, '#');
    bar.resize(width, '.');
    const double eta = done_ ? s / done_ * (total_ - done_) : 0.0;
    std::fprintf(stderr, "\r[%s] %d/%d scenes  %.1f s elapsed  ETA %.0f s ", bar.c_str(), done_,
                 total_, s, eta);
    if (done_ == total_) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  int total_, done_ = 0;
  bool quiet_;
  dimr::Stopwatch elapsed_;
  std::mutex mu_;
};

RunResult RunSynth(const SynthOptions& o) {
  // Validate everything before any work.
  const int max = dimr::data::MaxScenes(o.split);  // throws for a bad split
  if (o.scenes < 1 || o.scenes > max)
    throw dimr::InvalidArgument("--scenes must be in [1, " + std::to_string(max) + "] for split " +
                                o.split + ", got " + std::to_string(o.scenes));
  if (o.frames < 1 || o.frames > 2000)
    throw dimr::InvalidArgument("--frames-per-scene must be in [1, 2000], got " +
                                std::to_string(o.frames));
  if (o.jobs < 0) throw dimr::InvalidArgument("--jobs must be >= 0");
  if (!(o.drift >= 0 && o.drift <= 0.05))
    throw dimr::InvalidArgument("--drift must be in [0, 0.05] m per frame");
  if (o.out.empty()) throw dimr::InvalidArgument("--out is required");
  if (!(o.real_furniture >= 0 && o.real_furniture <= 1))
    throw dimr::InvalidArgument("--real-furniture must be in [0, 1], got " +
                                std::to_string(o.real_furniture));
  // Real furniture (docs/cad_library.md): only the train split of the import, whatever --split.
  dimr::data::ModelSource source = dimr::data::DefaultModelSource();
  if (o.real_furniture > 0) {
    auto lib = std::make_shared<const dimr::data::RealFurnitureLibrary>(
        dimr::data::LoadRealFurniture(o.real_furniture_dir, "train"));
    if (lib->size() == 0)
      throw dimr::InvalidArgument("--real-furniture-dir " + o.real_furniture_dir +
                                  ": the train split has no models");
    source = dimr::data::MixedModelSource(lib, o.real_furniture);
  }
  int shard = 0, shards = 1;
  ParseShard(o.shard, &shard, &shards);
#ifndef DIMR_HAVE_ROS
  if (o.bags) throw dimr::InvalidArgument("--bags needs a build with the ROS layer");
#endif
  dimr::data::SynthConfig config;
  config.scanner.frames = o.frames;
  config.scanner.density = dimr::data::ScanDensityFromName(o.density);
  config.room.window_pane = o.window_pane;
  config.room.door_closed = o.door_closed;
  config.room.studio = o.studio;
  config.scanner.keep_frames = o.bags;
  config.scanner.threads = 1;  // parallel over scenes instead
  config.scanner.drift_translation = o.drift;
  config.scanner.drift_rotation_deg = o.drift * 40.0;
  if (o.realism != "auto" && o.realism != "off" && o.realism != "v2")
    throw dimr::InvalidArgument("--realism: expected auto, off or v2, got '" + o.realism + "'");
  if (o.realism == "v2" ||
      (o.realism == "auto" && config.scanner.density == dimr::data::ScanDensity::kScanNet))
    config.scanner.EnableRealism();
  if (!o.scanner.empty())
    config.scanner = dimr::data::ScannerFields().Parse(o.scanner, config.scanner);
  config.Validate();

  const fs::path out(o.out);
  EnsureWritableDir(out / "scans");
  if (o.bags) EnsureWritableDir(out / "bags");
  if (o.render) EnsureWritableDir(out / "renders");

  std::vector<int> indices;
  for (int i = shard; i < o.scenes; i += shards) indices.push_back(i);
  const int jobs =
      std::max(1, std::min<int>(static_cast<int>(indices.size()), dimr::ResolveThreads(o.jobs)));
  std::vector<SceneSummary> summaries(indices.size());
  std::vector<dimr::data::Scan2CadScene> s2c(indices.size());
  std::map<std::string, dimr::data::CadModel> models;
  std::mutex mu;
  dimr::Timings stages;
  Progress progress(static_cast<int>(indices.size()), o.quiet);
  const dimr::Stopwatch elapsed;
  // Every scene writes its own files and slots; a failure stops the others after their scene.
  dimr::ParallelFor(indices.size(), jobs, [&](std::size_t k) {
    const int i = indices[k];
    const dimr::Stopwatch scene_time;
    const std::uint64_t seed = dimr::data::SceneSeed(o.seed, o.split, i);
    const std::string name = dimr::data::SceneName(o.split, i);
    const dimr::Stopwatch generate_time;
    const GeneratedScene g = dimr::data::GenerateScene(config, seed, name, source);
    const double generate_ms = generate_time.ElapsedMs();
    dimr::data::WriteScanNetScene((out / "scans").string(), g.scene);
#ifdef DIMR_HAVE_ROS
    if (o.bags) {
      dimr::ros1::BagWriterOptions bo;
      bo.map_cloud_every = o.map_cloud_every;
      dimr::ros1::WriteScanBag((out / "bags" / (name + ".bag")).string(), g.scan, bo);
    }
#endif
    if (o.render) {
      const fs::path dir = out / "renders";
      for (const bool inst : {false, true}) {
        const std::string stem = (dir / (name + (inst ? "_instances" : ""))).string();
        const dimr::data::RgbImage img = dimr::data::RenderTopDown(g.scene, 0.01, inst);
        dimr::tools::WritePng(stem + ".png", img.width, img.height, img.rgb);
      }
    }
    SceneSummary sum = dimr::data::Summarize(g);
    sum.seed = seed;
    sum.seconds = scene_time.ElapsedSeconds();
    summaries[k] = std::move(sum);
    s2c[k] = dimr::data::ToScan2Cad(g.scene);
    {
      std::lock_guard<std::mutex> lock(mu);
      for (const auto& m : g.cad_models) models.emplace(m->model_id, *m);
      stages.Add("scene", generate_ms);
      stages.Merge(g.scan.timings);
    }
    progress.Tick();
  });

  const std::string suffix =
      shards == 1 ? "" : ".shard-" + std::to_string(shard) + "-of-" + std::to_string(shards);
  dimr::data::WriteScan2CadAnnotations((out / ("full_annotations" + suffix + ".json")).string(),
                                       s2c);
  std::vector<dimr::data::CadModel> model_list;
  for (auto& [id, m] : models) model_list.push_back(std::move(m));
  if (!model_list.empty()) dimr::data::WriteShapeNetTree((out / "shapenet").string(), model_list);
  dimr::data::WriteSynthIndex((out / ("synthscan" + suffix + ".yaml")).string(), config, o.seed,
                              o.split, shard, shards, summaries);
  RunResult r;
  r.seconds = elapsed.ElapsedSeconds();
  r.summaries = std::move(summaries);
  r.bytes = FolderBytes(out);
  r.stages = std::move(stages);
  return r;
}

void PrintSummary(const RunResult& r) {
  std::map<std::string, int> per_class;
  std::size_t points = 0;
  for (const auto& s : r.summaries) {
    points += s.num_points;
    for (const auto& o : s.objects) {
      if (o.cad_class >= 0) ++per_class[dimr::data::CadClassNames()[o.cad_class]];
    }
  }
  std::printf("scenes: %zu  points: %zu (%.0f per scene)  time: %.1f s (%.1f scenes/min)\n",
              r.summaries.size(), points,
              r.summaries.empty() ? 0.0 : static_cast<double>(points) / r.summaries.size(),
              r.seconds, r.seconds > 0 ? 60.0 * r.summaries.size() / r.seconds : 0.0);
  std::printf("CAD objects per class:");
  for (const auto& [name, n] : per_class) std::printf(" %s=%d", name.c_str(), n);
  std::printf("\n\n%s", dimr::data::RealismReport(r.summaries).c_str());
}

// Where a scene's time goes: per-scene milliseconds of each scanner stage, and its share of
// GenerateScene ("scene" = room composition + scan + labels; the rest is composition and the
// scene's bookkeeping). Wall time of each stage in its own thread, so it adds up to
// jobs x the run's wall time.
void PrintStages(const RunResult& r) {
  if (r.summaries.empty() || r.stages.empty()) return;
  const double n = static_cast<double>(r.summaries.size());
  const double scene = r.stages.ms("scene");
  std::printf("\n| stage | ms per scene | share of the scene |\n|---|---:|---:|\n");
  double staged = 0;
  for (const auto& [name, ms] : r.stages) {
    if (name == "scene") continue;
    staged += ms;
    std::printf("| %s | %.0f | %.1f %% |\n", name.c_str(), ms / n,
                scene > 0 ? 100.0 * ms / scene : 0.0);
  }
  std::printf("| rest (room, shading set-up, bookkeeping) | %.0f | %.1f %% |\n",
              (scene - staged) / n, scene > 0 ? 100.0 * (scene - staged) / scene : 0.0);
  std::printf("| **GenerateScene** | %.0f | 100 %% |\n", scene / n);
}

void AddCommon(CLI::App& app, SynthOptions* o) {
  app.add_option("--scenes", o->scenes, "Number of scenes in the split")->capture_default_str();
  app.add_option("--seed", o->seed, "Dataset seed (scene i uses hash(seed, split, i))")
      ->capture_default_str();
  app.add_option("--split", o->split, "train | val | test")->capture_default_str();
  app.add_option("--shard", o->shard, "Generate only scenes i with i % n == shard (i/n)")
      ->capture_default_str();
  app.add_option("--density", o->density,
                 "mesh (ScanNet vertex-like, ~1 point per 2 cm voxel) | raw (accumulated scan) | "
                 "scannet (TSDF fusion, marching cubes, decimation: ScanNet's vh_clean_2 chain)")
      ->capture_default_str();
  app.add_option("--realism", o->realism,
                 "SynthScan v2 sensor / trajectory / colour realism: auto (on for scannet) | off "
                 "| v2")
      ->capture_default_str();
  app.add_option("--frames-per-scene", o->frames, "Depth frames per scene")->capture_default_str();
  app.add_option("--jobs", o->jobs, "Scenes generated in parallel (0 = all cores)")
      ->capture_default_str();
  app.add_option("--drift", o->drift, "Registration drift per frame in metres (0 = none)")
      ->capture_default_str();
  app.add_option("--real-furniture", o->real_furniture,
                 "Fraction of CAD objects and distractors drawn from the imported real furniture "
                 "(train split of `dimr cad import`; 0 = procedural only)")
      ->capture_default_str();
  app.add_option("--real-furniture-dir", o->real_furniture_dir,
                 "Folder written by `dimr cad import`")
      ->capture_default_str();
  app.add_option("--window-pane", o->window_pane,
                 "Probability that a window has a pane the scanner sees (glass or closed blinds "
                 "set back 1-7 cm from the wall face, labelled window; 0 = open frames, the rooms "
                 "of earlier versions)")
      ->capture_default_str();
  app.add_option("--studio", o->studio,
                 "Probability that a room is a studio apartment: sofa group, floor units (beds, "
                 "kitchen units with real furniture), a run of cabinets, desk or dining table, "
                 "bookshelf in one open room of >= 18 objects (0 = the rooms of earlier versions)")
      ->capture_default_str();
  app.add_option("--door-closed", o->door_closed,
                 "Probability that a door's leaf is closed, flush in its frame (else open by "
                 "0.4-1.6 rad)")
      ->capture_default_str();
  app.add_option("--scanner", o->scanner,
                 "Scanner / sensor-model overrides 'key=value ...' applied after --realism "
                 "(keys: " +
                     dimr::data::ScannerFields().Keys() + ")");
}

void SetupSynth(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  AddCommon(app, o.get());
  app.add_option("--out", o->out, "Output folder (scans/, shapenet/, bags/, index)")->required();
  app.add_flag("--bags", o->bags, "Also write one rosbag per scene (bags/<scene>.bag)");
  app.add_option("--map-cloud-every", o->map_cloud_every,
                 "Frames between accumulated /map_cloud messages in bags")
      ->capture_default_str();
  app.add_flag("--quiet", o->quiet, "No progress bar");
  app.add_flag("--render", o->render,
               "Also write top-down renders (renders/<scene>.png and _instances.png)");
  app.callback([o]() { PrintSummary(RunSynth(*o)); });
}

void SetupBench(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  o->scenes = 100;
  AddCommon(app, o.get());
  auto json_out = std::make_shared<std::string>();
  auto keep = std::make_shared<std::string>();
  app.add_option("--json", *json_out, "Write the results as JSON to this file");
  app.add_option("--out", *keep, "Keep the generated data here (default: a temporary folder)");
  app.callback([o, json_out, keep]() {
    const bool temp = keep->empty();
    o->out = temp ? (fs::temp_directory_path() /
                     ("dimr_bench_synth_" +
                      std::to_string(std::chrono::steady_clock::now().time_since_epoch().count())))
                        .string()
                  : *keep;
    o->quiet = false;
    const RunResult r = RunSynth(*o);
    std::printf("benchmark synth: %d scenes, %d frames/scene, density %s, %u hardware threads\n",
                o->scenes, o->frames, o->density.c_str(), std::thread::hardware_concurrency());
    PrintSummary(r);
    std::printf("\noutput: %.1f MB\n", r.bytes / 1e6);
    PrintStages(r);
    if (!json_out->empty()) {
      nlohmann::json j;
      j["scenes"] = r.summaries.size();
      j["seconds"] = r.seconds;
      j["scenes_per_minute"] = 60.0 * r.summaries.size() / r.seconds;
      j["frames_per_scene"] = o->frames;
      j["density"] = o->density;
      j["output_bytes"] = r.bytes;
      std::size_t pts = 0, v2 = 0;
      for (const auto& s : r.summaries) {
        pts += s.num_points;
        v2 += s.occupied_2cm;
      }
      j["points_per_scene"] = static_cast<double>(pts) / r.summaries.size();
      j["points_per_occupied_2cm_voxel"] = v2 ? static_cast<double>(pts) / v2 : 0.0;
      j["realism_markdown"] = dimr::data::RealismReport(r.summaries);
      nlohmann::json st = nlohmann::json::object();
      for (const auto& [name, ms] : r.stages) st[name] = ms / r.summaries.size();
      j["stage_ms_per_scene"] = st;
      std::ofstream f(*json_out);
      if (!f) throw dimr::Error("cannot write '" + *json_out + "'");
      f << j.dump(1) << "\n";
    }
    if (temp) fs::remove_all(o->out);
  });
}

const dimr::tools::Registrar kReg(
    "", "synth",
    "Generate SynthScan scenes (ScanNet / Scan2CAD / ShapeNet formats, optional rosbags)",
    &SetupSynth);
const dimr::tools::Registrar kBenchReg("bench", "synth",
                                       "Time SynthScan generation (scenes per minute) and report "
                                       "realism statistics vs ScanNet",
                                       &SetupBench);

}  // namespace
