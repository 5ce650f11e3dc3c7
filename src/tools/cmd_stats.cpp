// `dimr stats cloud INPUT`: realism statistics of a point cloud, a ScanNet scene folder (labels
// from labels.ply / the aggregation when present) or a SynthScan split (eval/cloud_stats.h).
// `dimr stats picture A B ... --out F.png`: the clouds side by side in their own colours.
#include <algorithm>
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
#include "tools/render.h"
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

struct PictureArgs {
  std::vector<std::string> inputs;
  std::vector<std::string> titles;
  std::string out;
  int width = 720, height = 560;
  double max_height = 0;  // > 0: drop points higher than this above the cloud's lowest point
};

// Every input is one panel: its points in their own colours, moved so that the centre of its
// bounding box's floor is at the origin (clouds from different frames share one camera).
void RunStatsPicture(const PictureArgs& a) {
  if (!a.titles.empty() && a.titles.size() != a.inputs.size())
    throw InvalidArgument("--titles: " + std::to_string(a.titles.size()) + " titles for " +
                          std::to_string(a.inputs.size()) + " inputs");
  std::vector<ScenePanel> panels;
  for (std::size_t i = 0; i < a.inputs.size(); ++i) {
    const std::vector<std::string> clouds = ListStatsInputs(a.inputs[i]);
    const StatsCloud c = ReadStatsCloud(clouds.front());
    if (c.points.empty()) throw InvalidArgument(clouds.front() + ": no points to draw");
    geometry::Vec3 lo = c.points.front(), hi = lo;
    for (const auto& p : c.points) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const geometry::Vec3 origin(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), lo.z());
    ScenePanel panel;
    for (std::size_t k = 0; k < c.points.size(); ++k) {
      const geometry::Vec3 p = c.points[k] - origin;
      if (a.max_height > 0 && p.z() > a.max_height) continue;
      panel.points.push_back(p);
      if (!c.colors.empty()) {
        const auto& col = c.colors[k];
        panel.point_colors.emplace_back(col[0] / 255.0, col[1] / 255.0, col[2] / 255.0);
      }
    }
    panel.title = a.titles.empty() ? c.name : a.titles[i];
    std::fprintf(stderr, "%s: %zu points drawn\n", c.name.c_str(), panel.points.size());
    panels.push_back(std::move(panel));
  }
  RenderScenePanels(panels, a.width, a.height, a.out);
  std::printf("picture: %s\n", a.out.c_str());
}

void SetupStatsPicture(CLI::App& app) {
  auto a = std::make_shared<PictureArgs>();
  app.add_option("inputs", a->inputs,
                 "PLY clouds, ScanNet scene folders or SynthScan splits (the first scene of each)")
      ->required();
  app.add_option("--out", a->out, "PNG to write")->required();
  app.add_option("--titles", a->titles, "one title per input (default: the scene names)")
      ->delimiter(',');
  app.add_option("--width", a->width, "panel width in pixels")->check(CLI::Range(64, 4096));
  app.add_option("--height", a->height, "panel height in pixels")->check(CLI::Range(64, 4096));
  app.add_option("--max-height", a->max_height,
                 "drop points higher than this above the lowest point (m; 0 = keep all)")
      ->check(CLI::NonNegativeNumber);
  app.callback([a]() { RunStatsPicture(*a); });
}

const Registrar kStatsPicture("stats", "picture",
                              "Clouds side by side in their own colours (a PNG; e.g. a SynthScan "
                              "room beside a real ScanNet scan)",
                              &SetupStatsPicture);

const Registrar kStatsCloud("stats", "cloud",
                            "Realism statistics of a cloud, a ScanNet scene or a SynthScan split "
                            "(spacing, surface variation, colour, density, per-object counts)",
                            &SetupStatsCloud);

}  // namespace
}  // namespace dimr::tools
