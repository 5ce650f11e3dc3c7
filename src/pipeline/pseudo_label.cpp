#include "dimr/pipeline/pseudo_label.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"

namespace dimr::pipeline {

void PseudoLabelConfig::Validate() const {
  if (!(keep_fraction > 0 && keep_fraction <= 1))
    throw InvalidArgument("pseudo labels: keep_fraction = " + std::to_string(keep_fraction) +
                          " must be in (0, 1]");
  if (!(min_prob >= 0 && min_prob < 1))
    throw InvalidArgument("pseudo labels: min_prob = " + std::to_string(min_prob) +
                          " must be in [0, 1)");
  if (!(min_instance_score >= 0 && min_instance_score <= 1))
    throw InvalidArgument("pseudo labels: min_instance_score = " +
                          std::to_string(min_instance_score) + " must be in [0, 1]");
}

nn::Stage1Sample PseudoLabelSample(const PointCloudInput& cloud, const Stage1Result& result,
                                   const PseudoLabelConfig& config, PseudoLabelSummary* summary) {
  config.Validate();
  const std::string who =
      "pseudo labels of '" + (cloud.name.empty() ? "point cloud" : cloud.name) + "'";
  const std::size_t n = cloud.points.size();
  if (result.semantic.size() != n)
    throw InvalidArgument(who + ": the result has " + std::to_string(result.semantic.size()) +
                          " labels for " + std::to_string(n) + " points");
  if (!cloud.colors.empty() && cloud.colors.size() != n)
    throw InvalidArgument(who + ": " + std::to_string(cloud.colors.size()) + " colours for " +
                          std::to_string(n) + " points");
  result.CheckShape(who, n, kStage1RfsClasses);

  PseudoLabelSummary s;
  s.points = n;
  // Confidence of each point's final class; the points of each class by confidence.
  std::vector<float> conf(n, 0.0f);
  std::vector<std::vector<std::size_t>> of_class(kStage1RfsClasses);
  for (std::size_t i = 0; i < n; ++i) {
    const int c = result.semantic[i];
    if (c < 0) continue;  // no class (e.g. a removed ceiling)
    if (c >= kStage1RfsClasses)
      throw InvalidArgument(who + ": point " + std::to_string(i) + " has class " +
                            std::to_string(c) + " outside [0, " +
                            std::to_string(kStage1RfsClasses) + ")");
    const float p = result.SemanticProb(i, kStage1RfsClasses)[c];
    if (!std::isfinite(p))
      throw InvalidArgument(who + ": point " + std::to_string(i) + " has a non-finite probability");
    conf[i] = p;
    of_class[static_cast<std::size_t>(c)].push_back(i);
  }

  nn::Stage1Sample out;
  out.name = cloud.name;
  out.points = cloud.points;
  out.colors = cloud.colors;
  out.semantic.assign(n, nn::kStage1Ignore);
  out.instance.assign(n, -1);
  for (int c = 0; c < kStage1RfsClasses; ++c) {
    auto& idx = of_class[static_cast<std::size_t>(c)];
    s.predicted[static_cast<std::size_t>(c)] = idx.size();
    if (idx.empty()) continue;
    // Most confident first; ties by index, so the selection is deterministic.
    std::sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) {
      return conf[a] != conf[b] ? conf[a] > conf[b] : a < b;
    });
    const auto want = static_cast<std::size_t>(
        std::ceil(config.keep_fraction * static_cast<double>(idx.size()) - 1e-9));
    std::size_t kept = 0;
    for (std::size_t k = 0; k < idx.size() && kept < want; ++k) {
      if (conf[idx[k]] < config.min_prob) break;
      out.semantic[idx[k]] = c;
      s.threshold[static_cast<std::size_t>(c)] = conf[idx[k]];
      ++kept;
    }
    s.kept[static_cast<std::size_t>(c)] = kept;
    s.labelled += kept;
  }

  // Instances: the proposals in score order, each point in the first that holds it.
  for (const ScoredInstance& inst : result.instances) {
    if (inst.score < config.min_instance_score) continue;
    if (inst.cad_class < 0 || inst.cad_class >= labels::kNumCadClasses)
      throw InvalidArgument(who + ": an instance has CAD class " + std::to_string(inst.cad_class));
    std::vector<std::size_t> mine;
    std::array<int, kStage1RfsClasses> votes{};
    for (const int p : inst.points) {
      if (p < 0 || static_cast<std::size_t>(p) >= n)
        throw InvalidArgument(who + ": an instance holds point " + std::to_string(p) + " of " +
                              std::to_string(n));
      const auto i = static_cast<std::size_t>(p);
      if (out.instance[i] >= 0) continue;
      mine.push_back(i);
      const int c = result.semantic[i];
      if (c >= 0 && labels::RfsToCad(c) == inst.cad_class) ++votes[static_cast<std::size_t>(c)];
    }
    if (mine.empty()) continue;
    int rfs = labels::CadToRfs(inst.cad_class);
    int best = 0;
    for (int c = 0; c < kStage1RfsClasses; ++c) {
      if (votes[static_cast<std::size_t>(c)] > best)
        best = votes[static_cast<std::size_t>(c)], rfs = c;
    }
    nn::Stage1Instance meta;
    meta.semantic = rfs;
    meta.cad_class = inst.cad_class;
    meta.has_heading = false;
    const int index = static_cast<int>(out.instances.size());
    out.instances.push_back(meta);
    for (const std::size_t i : mine) out.instance[i] = index;
    s.instance_points += mine.size();
  }
  s.instances = static_cast<int>(out.instances.size());
  out.Validate();
  if (summary != nullptr) *summary = s;
  return out;
}

}  // namespace dimr::pipeline
