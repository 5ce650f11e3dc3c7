// `dimr real pseudo-label`: stage 1 on unlabelled real scans, as the product runs it (ceiling
// removal, the input density rule, the model card's inference), and its confident labels
// written as a stage-1 training cache (pipeline/pseudo_label.h) for self-training:
// `dimr train stage1 --train <synthetic rooms> --train <cache>@N` (docs/real.md).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "dimr/core/error.h"
#include "dimr/nn/stage1_data.h"
#include "dimr/pipeline/ceiling.h"
#include "dimr/pipeline/colour_norm.h"
#include "dimr/pipeline/point_cloud_input.h"
#include "dimr/pipeline/pseudo_label.h"
#include "dimr/pipeline/stage1_segmenter.h"
#include "tools/command_registry.h"
#include "tools/real_scan.h"
#include "tools/stage1_inference_args.h"
#include "tools/stats_inputs.h"

namespace dimr::tools {
namespace {

using nlohmann::json;

struct PseudoArgs {
  std::vector<std::string> scenes;
  std::string out, json_path;
  InferenceArgs inference;
  std::string ceiling = "auto";
  pipeline::PseudoLabelConfig config;
};

void RunPseudo(const PseudoArgs& a) {
  a.config.Validate();
  std::string source;
  const pipeline::Stage1InferenceConfig inf = ResolveInference(a.inference, &source);
  const pipeline::Stage1Segmenter seg = pipeline::Stage1Segmenter::Load(a.inference.model, inf);
  const pipeline::CeilingConfig ceiling = CeilingFromFlag(a.ceiling);
  std::vector<std::string> paths;
  for (const std::string& s : a.scenes) {
    auto part = ListStatsInputs(s);
    paths.insert(paths.end(), part.begin(), part.end());
  }
  if (paths.empty()) throw InvalidArgument("--scene: no scans found");
  std::printf("model %s (%s), inference from %s: %s\n", a.inference.model.c_str(),
              seg.model_config().c_str(), source.c_str(), inf.ToString().c_str());
  std::printf("selection: the most confident %.0f %% of each class's points, probability >= %.2f\n",
              100.0 * a.config.keep_fraction, a.config.min_prob);

  std::vector<nn::Stage1Sample> samples;
  pipeline::PseudoLabelSummary total;
  std::size_t total_kept_right = 0, total_kept_n = 0, total_all_right = 0, total_all_n = 0;
  json j_scenes = json::array();
  const auto& names = pipeline::Stage1RfsClassNames();
  for (const std::string& path : paths) {
    const StatsCloud c = ReadStatsCloud(path);
    if (seg.uses_color() && c.colors.empty())
      throw ParseError(c.name, "the scan has no colours and the model needs them");
    const RealScanInput prepared = PrepareRealScan(c, ceiling, "auto");
    std::string note = prepared.cut.found
                           ? "ceiling removed (" + std::to_string(prepared.cut.removed) + " points)"
                           : "no ceiling";
    if (prepared.voxel > 0)
      note += ", voxel means at the training density (" +
              std::to_string(prepared.reduced.cloud.points.size()) + " of " +
              std::to_string(prepared.cut.cloud.points.size()) + " points)";
    pipeline::PointCloudInput cloud = prepared.network();
    const std::vector<std::vector<int>> source = prepared.ScanPointsOfNetworkPoints();
    const pipeline::Stage1Result r = seg.Segment(cloud);
    // The colours the network saw (the card's per-scene standardisation).
    if (seg.uses_color() && inf.colour_norm)
      cloud.colors = pipeline::StandardiseColours(cloud.colors, inf.colour_range);
    pipeline::PseudoLabelSummary s;
    samples.push_back(pipeline::PseudoLabelSample(cloud, r, a.config, &s));
    std::printf(
        "%s: %zu points (%s); %zu labelled (%.0f %%), %d instances over %zu points, %.1f s\n",
        c.name.c_str(), s.points, note.c_str(), s.labelled,
        s.points ? 100.0 * static_cast<double>(s.labelled) / static_cast<double>(s.points) : 0.0,
        s.instances, s.instance_points, r.timings.ms("total") / 1000.0);
    // Diagnostic only, where the scan happens to have labels (they are not otherwise read):
    // how often the kept labels and all labels agree with them (each network point against
    // the majority label of the scan points it stands for; unlabelled points left out).
    if (!c.semantic.empty()) {
      std::size_t kept_right = 0, kept_n = 0, all_right = 0, all_n = 0;
      for (std::size_t j = 0; j < source.size(); ++j) {
        std::array<int, pipeline::kStage1RfsClasses> votes{};
        for (const int i : source[j]) {
          const int g = c.semantic[static_cast<std::size_t>(i)];
          if (g >= 0 && g < pipeline::kStage1RfsClasses) ++votes[static_cast<std::size_t>(g)];
        }
        const auto best = std::max_element(votes.begin(), votes.end());
        if (*best == 0 || r.semantic[j] < 0) continue;
        const int gt = static_cast<int>(best - votes.begin());
        ++all_n;
        all_right += r.semantic[j] == gt;
        if (samples.back().semantic[j] >= 0) {
          ++kept_n;
          kept_right += samples.back().semantic[j] == gt;
        }
      }
      const double acc_kept = kept_n ? static_cast<double>(kept_right) / kept_n : 0.0;
      const double acc_all = all_n ? static_cast<double>(all_right) / all_n : 0.0;
      std::printf(
          "  against the scan's own labels (diagnostic): kept labels %.1f %% right (%zu "
          "points), all labels %.1f %% (%zu)\n",
          100.0 * acc_kept, kept_n, 100.0 * acc_all, all_n);
      total_kept_right += kept_right, total_kept_n += kept_n;
      total_all_right += all_right, total_all_n += all_n;
    }
    json js = {{"scene", c.name},          {"path", path},
               {"points", s.points},       {"labelled", s.labelled},
               {"instances", s.instances}, {"note", note}};
    for (int k = 0; k < pipeline::kStage1RfsClasses; ++k) {
      if (s.predicted[k] == 0) continue;
      js["classes"][names[k]] = {
          {"predicted", s.predicted[k]}, {"kept", s.kept[k]}, {"threshold", s.threshold[k]}};
      total.predicted[k] += s.predicted[k];
      total.kept[k] += s.kept[k];
    }
    total.points += s.points;
    total.labelled += s.labelled;
    total.instances += s.instances;
    total.instance_points += s.instance_points;
    j_scenes.push_back(js);
  }

  std::printf(
      "\n| class | predicted points | kept | share of the kept labels |\n|---|---|---|---|\n");
  for (int k = 0; k < pipeline::kStage1RfsClasses; ++k) {
    if (total.predicted[k] == 0) continue;
    std::printf(
        "| %s | %zu | %zu | %.1f %% |\n", names[k].c_str(), total.predicted[k], total.kept[k],
        total.labelled
            ? 100.0 * static_cast<double>(total.kept[k]) / static_cast<double>(total.labelled)
            : 0.0);
  }
  if (total_all_n > 0) {
    std::printf(
        "against the scans' own labels (diagnostic, %zu labelled points): kept labels "
        "%.1f %% right, all labels %.1f %%\n",
        total_all_n,
        100.0 * static_cast<double>(total_kept_right) / std::max<std::size_t>(1, total_kept_n),
        100.0 * static_cast<double>(total_all_right) / static_cast<double>(total_all_n));
  }
  if (const auto dir = std::filesystem::path(a.out).parent_path(); !dir.empty())
    std::filesystem::create_directories(dir);
  nn::WriteStage1Samples(a.out, samples);
  std::printf("%zu scans, %zu points, %zu labelled, %d instances -> %s\n", samples.size(),
              total.points, total.labelled, total.instances, a.out.c_str());
  if (!a.json_path.empty()) {
    std::ofstream f(a.json_path);
    if (!f) throw Error("cannot write '" + a.json_path + "'");
    f << json{{"model", a.inference.model},
              {"inference", inf.ToString()},
              {"keep_fraction", a.config.keep_fraction},
              {"min_prob", a.config.min_prob},
              {"min_instance_score", a.config.min_instance_score},
              {"out", a.out},
              {"scenes", j_scenes}}
             .dump(2)
      << "\n";
  }
}

void SetupPseudo(CLI::App& app) {
  auto a = std::make_shared<PseudoArgs>();
  app.add_option("--scene", a->scenes,
                 "unlabelled real scans: a .ply, a ScanNet scene folder or a folder of them "
                 "(labels, if any, are not read); repeatable")
      ->required();
  app.add_option("--out", a->out, "stage-1 training cache to write (dimr train stage1 --train)")
      ->required();
  app.add_option("--keep", a->config.keep_fraction,
                 "share of each predicted class's points that keep their label, most confident "
                 "first (class-balanced), (0, 1]")
      ->capture_default_str();
  app.add_option("--min-prob", a->config.min_prob,
                 "no point below this probability keeps a label, [0, 1)")
      ->capture_default_str();
  app.add_option("--min-instance-score", a->config.min_instance_score,
                 "proposals scoring below this are no pseudo instance")
      ->capture_default_str();
  app.add_option("--json", a->json_path, "write the per-scene and per-class counts as JSON");
  AddCeilingFlag(app, &a->ceiling);
  AddInferenceFlags(app, &a->inference);
  app.callback([a]() { RunPseudo(*a); });
}

const Registrar kRealPseudo("real", "pseudo-label",
                            "Stage 1's confident labels on unlabelled real scans -> a stage-1 "
                            "training cache for self-training (class-balanced selection)",
                            &SetupPseudo);

}  // namespace
}  // namespace dimr::tools
