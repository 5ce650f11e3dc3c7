#include "dimr/pipeline/stage1_instances.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_data.h"
#include "dimr/nn/stage1_model.h"

namespace dimr::pipeline {
namespace {

constexpr int kNumCadClasses = 8;

void CheckSize(const char* name, std::size_t got, std::size_t want) {
  if (got != want) {
    throw InvalidArgument(std::string("ExtractStage1Instances: ") + name + " has " +
                          std::to_string(got) + " values, expected " + std::to_string(want));
  }
}

inline std::size_t RowOf(const std::vector<std::int64_t>& point_row, int i) {
  return point_row.empty() ? static_cast<std::size_t>(i)
                           : static_cast<std::size_t>(point_row[static_cast<std::size_t>(i)]);
}

}  // namespace

void Stage1InstanceConfig::Validate() const {
  clustering.Validate();
  semantic_vote.Validate();
  if (!(nms_iou >= 0.0 && nms_iou <= 1.0)) {
    throw InvalidArgument("Stage1InstanceConfig.nms_iou: must be in [0, 1], got " +
                          std::to_string(nms_iou));
  }
  if (min_points < 0) {
    throw InvalidArgument("Stage1InstanceConfig.min_points: must be >= 0, got " +
                          std::to_string(min_points));
  }
  for (std::size_t c = 0; c < class_bias.size(); ++c) {
    if (!std::isfinite(class_bias[c])) {
      throw InvalidArgument("Stage1InstanceConfig.class_bias: value of class " + std::to_string(c) +
                            " is not finite");
    }
  }
}

namespace {

// The input checks shared by ExtractStage1Instances and ScoredStage1Proposals (messages name
// the first).
void CheckStage1Inputs(const std::vector<Eigen::Vector3f>& points,
                       const std::vector<Eigen::Vector3f>& offsets,
                       const std::vector<int>& cad_label, const std::vector<float>& semantic_prob,
                       const std::vector<float>& heading_prob,
                       const std::vector<float>& heading_residual,
                       const std::vector<int>& rfs_to_cad,
                       const std::vector<std::int64_t>& point_row) {
  const std::size_t n = points.size();
  const std::size_t num_sem = rfs_to_cad.size();
  if (num_sem == 0) throw InvalidArgument("ExtractStage1Instances: rfs_to_cad is empty");
  CheckSize("offsets", offsets.size(), n);
  CheckSize("cad_label", cad_label.size(), n);
  const std::size_t rows = nn::CheckPointRows("ExtractStage1Instances", "semantic_prob",
                                              semantic_prob.size(), num_sem, n, point_row);
  CheckSize("heading_prob", heading_prob.size(), rows * nn::kHeadingBins);
  CheckSize("heading_residual", heading_residual.size(), rows * nn::kHeadingBins);
  for (std::size_t i = 0; i < n; ++i) {
    if (cad_label[i] < -1 || cad_label[i] >= kNumCadClasses) {
      throw InvalidArgument("ExtractStage1Instances: cad_label[" + std::to_string(i) +
                            "] = " + std::to_string(cad_label[i]) + " is not in [-1, 7]");
    }
  }
}

// The score of proposal p: the mean over its points of the summed probability of the semantic
// classes of its CAD class (classes_of[label], ascending: the order of the sums).
double ProposalScore(const Proposal& p, const std::vector<std::vector<std::size_t>>& classes_of,
                     const std::vector<float>& semantic_prob, std::size_t num_sem,
                     const std::vector<std::int64_t>& point_row) {
  double sum = 0.0;
  const std::vector<std::size_t>& classes = classes_of[p.label];
  for (int i : p.points) {
    const float* row = semantic_prob.data() + RowOf(point_row, i) * num_sem;
    for (std::size_t c : classes) sum += row[c];
  }
  const double score = sum / static_cast<double>(p.points.size());
  if (!std::isfinite(score)) {
    throw InvalidArgument("ExtractStage1Instances: semantic_prob has non-finite values");
  }
  return score;
}

std::vector<std::vector<std::size_t>> ClassesOfCad(const std::vector<int>& rfs_to_cad) {
  std::vector<std::vector<std::size_t>> classes_of(kNumCadClasses);
  for (std::size_t c = 0; c < rfs_to_cad.size(); ++c) {
    if (rfs_to_cad[c] >= 0 && rfs_to_cad[c] < kNumCadClasses)
      classes_of[rfs_to_cad[c]].push_back(c);
  }
  return classes_of;
}

}  // namespace

std::vector<ScoredInstance> ExtractStage1Instances(
    const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& offsets,
    const std::vector<int>& cad_label, const std::vector<float>& semantic_prob,
    const std::vector<float>& heading_prob, const std::vector<float>& heading_residual,
    const std::vector<int>& rfs_to_cad, const Stage1InstanceConfig& config,
    const std::vector<std::int64_t>& point_row) {
  config.Validate();
  CheckStage1Inputs(points, offsets, cad_label, semantic_prob, heading_prob, heading_residual,
                    rfs_to_cad, point_row);
  std::vector<Proposal> proposals =
      MultiScaleClusters(points, offsets, cad_label, config.clustering);
  // Size filter before NMS, as the reference (section 3.6, steps 2 and 3).
  const std::vector<std::vector<std::size_t>> classes_of = ClassesOfCad(rfs_to_cad);
  std::vector<Proposal> large;
  for (auto& p : proposals) {
    if (static_cast<int>(p.points.size()) <= config.min_points) continue;
    p.score = ProposalScore(p, classes_of, semantic_prob, rfs_to_cad.size(), point_row);
    large.push_back(std::move(p));
  }
  const std::vector<int> kept = PointIouNms(large, config.nms_iou);
  std::vector<ScoredInstance> instances;
  instances.reserve(kept.size());
  for (int k : kept) {
    ScoredInstance inst;
    inst.cad_class = large[k].label;
    inst.score = large[k].score;
    inst.heading = ProposalHeading(large[k].points, heading_prob, heading_residual, point_row);
    inst.points = std::move(large[k].points);
    instances.push_back(std::move(inst));
  }
  return instances;
}

std::vector<ScoredInstance> ScoredStage1Proposals(
    const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& offsets,
    const std::vector<int>& cad_label, const std::vector<float>& semantic_prob,
    const std::vector<float>& heading_prob, const std::vector<float>& heading_residual,
    const std::vector<int>& rfs_to_cad, const ClusteringConfig& clustering,
    const std::vector<std::int64_t>& point_row) {
  clustering.Validate();
  CheckStage1Inputs(points, offsets, cad_label, semantic_prob, heading_prob, heading_residual,
                    rfs_to_cad, point_row);
  std::vector<Proposal> proposals = MultiScaleClusters(points, offsets, cad_label, clustering);
  const std::vector<std::vector<std::size_t>> classes_of = ClassesOfCad(rfs_to_cad);
  std::vector<ScoredInstance> out;
  out.reserve(proposals.size());
  for (auto& p : proposals) {
    ScoredInstance inst;
    inst.cad_class = p.label;
    inst.score = ProposalScore(p, classes_of, semantic_prob, rfs_to_cad.size(), point_row);
    inst.heading = ProposalHeading(p.points, heading_prob, heading_residual, point_row);
    inst.points = std::move(p.points);
    out.push_back(std::move(inst));
  }
  return out;
}

void SemanticVoteConfig::Validate() const {
  if (!(std::isfinite(radius) && radius >= 0.0)) {
    throw InvalidArgument("SemanticVoteConfig.radius: must be finite and >= 0, got " +
                          std::to_string(radius));
  }
  if (min_points < 1) {
    throw InvalidArgument("SemanticVoteConfig.min_points: must be >= 1, got " +
                          std::to_string(min_points));
  }
  for (int c : excluded_classes) {
    if (c < 0) {
      throw InvalidArgument("SemanticVoteConfig.excluded_classes: class " + std::to_string(c) +
                            " is negative");
    }
  }
  if (!(std::isfinite(max_extent) && max_extent >= 0.0)) {
    throw InvalidArgument("SemanticVoteConfig.max_extent: must be finite and >= 0, got " +
                          std::to_string(max_extent));
  }
  for (std::size_t c = 0; c < min_extent.size(); ++c) {
    if (!(std::isfinite(min_extent[c]) && min_extent[c] >= 0.0)) {
      throw InvalidArgument("SemanticVoteConfig.min_extent: class " + std::to_string(c) +
                            " must be finite and >= 0, got " + std::to_string(min_extent[c]));
    }
  }
}

double FootprintLongSide(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& idx) {
  if (idx.size() < 2) return 0.0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int i : idx) mean += points[i].head<2>().cast<double>();
  mean /= static_cast<double>(idx.size());
  double cxx = 0, cxy = 0, cyy = 0;
  for (int i : idx) {
    const Eigen::Vector2d d = points[i].head<2>().cast<double>() - mean;
    cxx += d.x() * d.x();
    cxy += d.x() * d.y();
    cyy += d.y() * d.y();
  }
  // Principal axis of the 2 x 2 covariance.
  const double angle = 0.5 * std::atan2(2.0 * cxy, cxx - cyy);
  const Eigen::Vector2d axis(std::cos(angle), std::sin(angle));
  std::vector<double> t;
  t.reserve(idx.size());
  for (int i : idx) t.push_back(axis.dot(points[i].head<2>().cast<double>() - mean));
  const auto at = [&t](double q) {
    const std::size_t k = static_cast<std::size_t>(std::lround(q * (t.size() - 1)));
    std::nth_element(t.begin(), t.begin() + k, t.end());
    return t[k];
  };
  const double lo = at(0.02);
  const double hi = at(0.98);
  return hi - lo;
}

std::vector<int> VoteSemantics(const std::vector<Eigen::Vector3f>& points,
                               const std::vector<Eigen::Vector3f>& offsets,
                               const std::vector<int>& semantic,
                               const std::vector<float>& semantic_prob,
                               const std::vector<bool>& is_thing, const SemanticVoteConfig& config,
                               const std::vector<std::int64_t>& point_row) {
  config.Validate();
  const std::size_t n = points.size();
  const std::size_t num_classes = is_thing.size();
  if (num_classes == 0) throw InvalidArgument("VoteSemantics: is_thing is empty");
  auto check = [](const char* name, std::size_t got, std::size_t want) {
    if (got != want) {
      throw InvalidArgument(std::string("VoteSemantics: ") + name + " has " + std::to_string(got) +
                            " values, expected " + std::to_string(want));
    }
  };
  check("offsets", offsets.size(), n);
  check("semantic", semantic.size(), n);
  nn::CheckPointRows("VoteSemantics", "semantic_prob", semantic_prob.size(), num_classes, n,
                     point_row);
  std::vector<bool> votes = is_thing;
  for (int c : config.excluded_classes) {
    if (static_cast<std::size_t>(c) >= num_classes) {
      throw InvalidArgument("VoteSemantics: excluded class " + std::to_string(c) +
                            " is not in [0, " + std::to_string(num_classes) + ")");
    }
    votes[c] = false;
  }
  if (!config.min_extent.empty() && config.min_extent.size() != num_classes) {
    throw InvalidArgument("VoteSemantics: min_extent has " +
                          std::to_string(config.min_extent.size()) + " values, expected " +
                          std::to_string(num_classes) + " (one per class) or none");
  }
  std::vector<int> thing_label(n, -1);
  std::vector<Eigen::Vector3f> shifted(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int c = semantic[i];
    if (c < 0 || static_cast<std::size_t>(c) >= num_classes) {
      throw InvalidArgument("VoteSemantics: semantic[" + std::to_string(i) +
                            "] = " + std::to_string(c) + " is not in [0, " +
                            std::to_string(num_classes) + ")");
    }
    shifted[i] = points[i] + offsets[i];
    if (votes[c]) thing_label[i] = 0;
  }
  std::vector<int> out = semantic;
  if (config.radius == 0.0) return out;
  const auto cluster_at = [&config](const std::vector<Eigen::Vector3f>& p,
                                    const std::vector<int>& label, double radius) {
    return config.neighbour_cap ? BfsClusters(p, label, radius, config.min_points)
                                : RadiusComponents(p, label, radius, config.min_points);
  };
  std::vector<std::vector<int>> clusters;
  {
    // Oversized clusters (max_extent) split at half the radius, up to three times; a part
    // still too long after that keeps its per-point labels.
    constexpr int kMaxSplits = 3;
    std::vector<std::pair<std::vector<int>, int>> todo;  // cluster, splits so far
    for (auto& c : cluster_at(shifted, thing_label, config.radius))
      todo.emplace_back(std::move(c), 0);
    while (!todo.empty()) {
      auto [cluster, splits] = std::move(todo.back());
      todo.pop_back();
      if (config.max_extent <= 0.0 || FootprintLongSide(points, cluster) <= config.max_extent) {
        clusters.push_back(std::move(cluster));
        continue;
      }
      if (splits == kMaxSplits) continue;
      const double radius = config.radius / static_cast<double>(2 << splits);
      std::vector<Eigen::Vector3f> sub(cluster.size());
      for (std::size_t k = 0; k < cluster.size(); ++k) sub[k] = shifted[cluster[k]];
      for (auto& part : cluster_at(sub, std::vector<int>(cluster.size(), 0), radius)) {
        for (int& i : part) i = cluster[i];
        todo.emplace_back(std::move(part), splits + 1);
      }
    }
  }
  std::vector<double> sum(num_classes);
  for (const auto& cluster : clusters) {
    std::fill(sum.begin(), sum.end(), 0.0);
    for (int i : cluster) {
      const float* row = semantic_prob.data() + RowOf(point_row, i) * num_classes;
      for (std::size_t c = 0; c < num_classes; ++c) {
        if (!std::isfinite(row[c])) {
          throw InvalidArgument("VoteSemantics: semantic_prob of point " + std::to_string(i) +
                                " is not finite");
        }
        if (votes[c]) sum[c] += row[c];
      }
    }
    int best = static_cast<int>(std::max_element(sum.begin(), sum.end()) - sum.begin());
    if (!config.min_extent.empty() && config.min_extent[best] > 0.0) {
      // Too small for the winner: the best class the footprint allows (the winner if none).
      const double side = FootprintLongSide(points, cluster);
      int allowed = -1;
      for (std::size_t c = 0; c < num_classes; ++c) {
        if (!votes[c] || config.min_extent[c] > side) continue;
        if (allowed < 0 || sum[c] > sum[allowed]) allowed = static_cast<int>(c);
      }
      if (config.min_extent[best] > side && allowed >= 0) best = allowed;
    }
    for (int i : cluster) out[i] = best;
  }
  return out;
}

}  // namespace dimr::pipeline
