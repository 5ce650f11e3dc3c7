// `dimr stage1 prepare` (ScanNet-format scene folders -> stage-1 sample cache) and
// `dimr stage1 inspect` (per-split statistics of a cache or a scans folder).
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "dimr/core/timing.h"
#include "dimr/data/labels.h"
#include "dimr/data/synthscan.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_data.h"
#include "tools/command_registry.h"
#include "tools/stage1_scenes.h"

namespace dimr::tools {
namespace {

namespace fs = std::filesystem;

// DIR itself or DIR/scans (a SynthScan / ScanNet root).
std::string ScansFolder(const std::string& dir) {
  if (fs::is_directory(fs::path(dir) / "scans")) return (fs::path(dir) / "scans").string();
  return dir;
}

std::vector<std::string> ReadSceneList(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ParseError(path, "cannot open scene list");
  std::vector<std::string> names;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto b = line.find_first_not_of(" \t\r");
    if (b == std::string::npos || line[b] == '#') continue;
    const auto e = line.find_last_not_of(" \t\r");
    const std::string name = line.substr(b, e - b + 1);
    if (name.find('/') != std::string::npos || name == "." || name == "..") {
      throw ParseError(
          path, "line " + std::to_string(line_no) + ": '" + name + "' is not a scene folder name");
    }
    names.push_back(name);
  }
  if (names.empty()) throw ParseError(path, "the scene list is empty");
  return names;
}

// ---------------------------------------------------------------- statistics
struct Stats {
  std::int64_t scenes = 0, points = 0, ignored_points = 0, instances = 0, cad_instances = 0;
  std::array<std::int64_t, data::kNumRfsClasses> labelled{};
  std::array<std::int64_t, data::kNumCadClasses> cad{};
  std::array<std::int64_t, nn::kHeadingBins> heading_bins{};

  void Add(const nn::Stage1Sample& s) {
    ++scenes;
    points += static_cast<std::int64_t>(s.points.size());
    for (int l : s.semantic) {
      if (l >= 0 && l < data::kNumRfsClasses) {
        ++labelled[l];
      } else {
        ++ignored_points;
      }
    }
    instances += static_cast<std::int64_t>(s.instances.size());
    for (const auto& in : s.instances) {
      if (in.cad_class < 0) continue;
      ++cad_instances;
      ++cad[in.cad_class];
      if (in.has_heading) ++heading_bins[nn::EncodeHeading(in.heading).bin];
    }
  }

  nlohmann::json Json() const {
    nlohmann::json j;
    j["scenes"] = scenes;
    j["points"] = points;
    j["ignored_points"] = ignored_points;
    j["instances"] = instances;
    j["cad_instances"] = cad_instances;
    nlohmann::json lab = nlohmann::json::object(), c = nlohmann::json::object();
    for (int k = 0; k < data::kNumRfsClasses; ++k) lab[data::RfsClassNames()[k]] = labelled[k];
    for (int k = 0; k < data::kNumCadClasses; ++k) c[data::CadClassNames()[k]] = cad[k];
    j["labelled_points"] = lab;
    j["cad_instances_per_class"] = c;
    j["heading_bins"] = heading_bins;
    return j;
  }
};

std::map<std::string, Stats> SplitStats(const std::vector<nn::Stage1Sample>& samples) {
  std::map<std::string, Stats> out;
  for (const auto& s : samples) {
    out["all"].Add(s);
    out[Stage1SplitOfScene(s.name)].Add(s);
  }
  if (out.empty()) out["all"] = Stats();
  return out;
}

void PrintCadSummary(const Stats& s) {
  std::printf("CAD instances per class:");
  for (int k = 0; k < data::kNumCadClasses; ++k) {
    std::printf(" %s %lld", data::CadClassNames()[k], static_cast<long long>(s.cad[k]));
  }
  std::printf("\n");
}

// ---------------------------------------------------------------- prepare
struct PrepareArgs {
  std::string scans, scene_list, out, scan2cad;
  bool force_scan2cad = false;
  int threads = 0;
};

void RunPrepare(const PrepareArgs& a) {
  const Stopwatch elapsed;
  const std::string dir = ScansFolder(a.scans);
  const std::vector<std::string> names =
      a.scene_list.empty() ? std::vector<std::string>() : ReadSceneList(a.scene_list);
  if (a.force_scan2cad && a.scan2cad.empty()) {
    throw InvalidArgument("--force-scan2cad needs --scan2cad full_annotations.json");
  }
  Scan2CadByScene annotations;
  if (!a.scan2cad.empty()) annotations = ReadScan2CadByScene(a.scan2cad);
  Stage1LoadReport report;
  const auto samples =
      LoadStage1Scenes(dir, names, a.threads, a.scan2cad.empty() ? nullptr : &annotations,
                       a.force_scan2cad, &report);
  if (samples.empty()) throw InvalidArgument("no scene folders in '" + dir + "'");
  nn::WriteStage1Samples(a.out, samples);
  const Stats s = SplitStats(samples).at("all");
  const double secs = elapsed.ElapsedSeconds();
  std::printf(
      "wrote %s: %lld scenes, %lld points (%lld ignored), %lld instances, %lld CAD "
      "instances (%.1f s)\n",
      a.out.c_str(), static_cast<long long>(s.scenes), static_cast<long long>(s.points),
      static_cast<long long>(s.ignored_points), static_cast<long long>(s.instances),
      static_cast<long long>(s.cad_instances), secs);
  PrintCadSummary(s);
  if (!a.scan2cad.empty()) {
    std::printf(
        "Scan2CAD (%s, %zu scans): %d scenes relabelled from Scan2CAD, %d kept their "
        "SynthScan boxes, %d real scenes without an entry\n",
        a.scan2cad.c_str(), annotations.size(), report.relabelled, report.kept_synthscan,
        report.without_scan2cad);
    if (report.relabelled > 0) {
      std::printf("relabelling: %s\n", data::ToString(report.relabel).c_str());
    }
    if (report.kept_synthscan > 0 && !a.force_scan2cad) {
      std::printf(
          "note: SynthScan scenes keep their own CAD boxes; --force-scan2cad relabels "
          "them too\n");
    }
  } else if (report.without_scan2cad > 0) {
    std::printf(
        "note: %d real ScanNet scenes without --scan2cad: instances from the "
        "aggregation, no CAD box headings\n",
        report.without_scan2cad);
  }
}

void SetupPrepare(CLI::App& app) {
  auto a = std::make_shared<PrepareArgs>();
  app.add_option("--scans", a->scans, "ScanNet-format scans folder (DIR or DIR/scans)")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--scene-list", a->scene_list,
                 "file with one scene folder name per line (default: every folder, sorted)");
  app.add_option("--threads", a->threads, "reader threads (0 = all cores)")
      ->check(CLI::Range(0, 256));
  app.add_option("--out", a->out, "output cache file (.bin)")->required();
  app.add_option("--scan2cad", a->scan2cad,
                 "Scan2CAD full_annotations.json: re-label real ScanNet scenes (no "
                 "synthscan.json) as the DIMR reference (CAD boxes, headings, rebuilt "
                 "bookshelf/cabinet/bathtub instances)")
      ->check(CLI::ExistingFile);
  app.add_flag("--force-scan2cad", a->force_scan2cad,
               "re-label SynthScan scenes from --scan2cad too (instead of their own boxes)");
  app.callback([a]() { RunPrepare(*a); });
}

// ---------------------------------------------------------------- inspect
struct InspectArgs {
  std::string input, json;
  int threads = 0;
};

void RunInspect(const InspectArgs& a) {
  std::vector<nn::Stage1Sample> samples;
  if (fs::is_regular_file(a.input)) {
    samples = nn::ReadStage1Samples(a.input);
  } else if (fs::is_directory(a.input)) {
    samples = LoadStage1Scenes(ScansFolder(a.input), {}, a.threads);
  } else {
    throw InvalidArgument("'" + a.input + "' is neither a stage-1 cache file nor a scans folder");
  }
  const auto stats = SplitStats(samples);
  std::printf("%-6s %7s %11s %11s %10s %8s\n", "split", "scenes", "points", "ignored", "instances",
              "cad");
  for (const auto& [split, s] : stats) {
    std::printf("%-6s %7lld %11lld %11lld %10lld %8lld\n", split.c_str(),
                static_cast<long long>(s.scenes), static_cast<long long>(s.points),
                static_cast<long long>(s.ignored_points), static_cast<long long>(s.instances),
                static_cast<long long>(s.cad_instances));
  }
  const Stats& all = stats.at("all");
  std::printf("\nlabelled points per RFS class (all):\n");
  for (int k = 0; k < data::kNumRfsClasses; ++k) {
    std::printf("  %2d %-16s %11lld\n", k, data::RfsClassNames()[k],
                static_cast<long long>(all.labelled[k]));
  }
  PrintCadSummary(all);
  std::printf("heading bins (CAD instances, 30 deg each):");
  for (auto c : all.heading_bins) std::printf(" %lld", static_cast<long long>(c));
  std::printf("\n");
  if (!a.json.empty()) {
    nlohmann::json j;
    j["source"] = a.input;
    j["splits"] = nlohmann::json::object();
    for (const auto& [split, s] : stats) j["splits"][split] = s.Json();
    std::ofstream out(a.json);
    if (!out) throw Error("cannot open '" + a.json + "' for writing");
    out << j.dump(2) << "\n";
    if (!out) throw Error("failed writing '" + a.json + "'");
    std::printf("wrote %s\n", a.json.c_str());
  }
}

void SetupInspect(CLI::App& app) {
  auto a = std::make_shared<InspectArgs>();
  app.add_option("input", a->input, "stage-1 cache (.bin) or ScanNet-format scans folder")
      ->required();
  app.add_option("--json", a->json, "write the statistics as JSON");
  app.add_option("--threads", a->threads, "reader threads for a scans folder (0 = all cores)")
      ->check(CLI::Range(0, 256));
  app.callback([a]() { RunInspect(*a); });
}

const Registrar kPrepare("stage1", "prepare",
                         "Read ScanNet-format scene folders into a stage-1 sample cache",
                         &SetupPrepare);
const Registrar kInspect("stage1", "inspect",
                         "Per-split statistics of a stage-1 cache or a scans folder",
                         &SetupInspect);

}  // namespace
}  // namespace dimr::tools
