// `dimr stats cloud INPUT`: realism statistics of a point cloud, a ScanNet scene folder (labels
// from labels.ply / the aggregation when present) or a SynthScan split (eval/cloud_stats.h).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "dimr/core/error.h"
#include "dimr/data/scannet_io.h"
#include "dimr/eval/cloud_stats.h"
#include "dimr/geometry/ply_io.h"
#include "tools/command_registry.h"
#include "tools/stats_inputs.h"

namespace dimr::tools {
namespace {

namespace fs = std::filesystem;

struct StatsArgs {
  std::string input;
  std::string json, markdown, title;
  int max_scenes = 0;
  int neighbours = 16;
  int threads = 0;
};

void RunStatsCloud(const StatsArgs& a) {
  std::vector<std::string> scenes = ListStatsInputs(a.input);
  if (a.max_scenes > 0 && static_cast<int>(scenes.size()) > a.max_scenes)
    scenes.resize(a.max_scenes);
  eval::CloudStatsOptions opt;
  opt.neighbours = a.neighbours;
  opt.threads = a.threads;
  eval::CloudStatsAccumulator acc(opt);
  for (const std::string& path : scenes) {
    const StatsCloud c = ReadStatsCloud(path);
    eval::CloudStatsInput in;
    in.name = c.name;
    in.points = &c.points;
    in.colors = &c.colors;
    in.semantic = &c.semantic;
    in.instance = &c.instance;
    acc.Add(in);
    std::fprintf(stderr, "%s: %zu points%s%s\n", c.name.c_str(), c.points.size(),
                 c.semantic.empty() ? "" : ", labels", c.instance.empty() ? "" : ", instances");
  }
  const eval::CloudStats s = acc.Finish();
  const std::string title = a.title.empty() ? a.input : a.title;
  const std::string md = eval::CloudStatsMarkdown(s, title);
  std::printf("%s\n", md.c_str());
  auto write = [](const std::string& path, const std::string& text) {
    std::ofstream f(path);
    if (!(f << text)) throw Error("cannot write " + path);
  };
  if (!a.json.empty()) write(a.json, eval::CloudStatsJson(s) + "\n");
  if (!a.markdown.empty()) write(a.markdown, md);
}

void SetupStatsCloud(CLI::App& app) {
  auto a = std::make_shared<StatsArgs>();
  app.add_option("input", a->input,
                 "a PLY cloud (a 'label' property = NYU40 ids), a ScanNet scene folder, a folder "
                 "of scene folders or a SynthScan split (a folder with scans/)")
      ->required();
  app.add_option("--json", a->json, "write the statistics as JSON");
  app.add_option("--markdown", a->markdown, "write the Markdown table");
  app.add_option("--title", a->title, "table title (default: the input path)");
  app.add_option("--max-scenes", a->max_scenes, "use only the first N scenes (0 = all)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--neighbours", a->neighbours, "k of the PCA neighbourhood (16)")
      ->check(CLI::Range(3, 256));
  app.add_option("--threads", a->threads, "threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  app.callback([a]() { RunStatsCloud(*a); });
}

const Registrar kStatsCloud("stats", "cloud",
                            "Realism statistics of a cloud, a ScanNet scene or a SynthScan split "
                            "(spacing, surface variation, colour, density, per-object counts)",
                            &SetupStatsCloud);

}  // namespace
}  // namespace dimr::tools
