#include "dimr/pipeline/calibration.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "dimr/core/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/pipeline/stage1_instances.h"

namespace dimr::pipeline {
namespace {

const std::vector<bool>& ThingClasses() {
  static const std::vector<bool> t = [] {
    std::vector<bool> v(kStage1RfsClasses, true);
    v[labels::kWall] = v[labels::kFloor] = false;
    return v;
  }();
  return t;
}

SemanticVoteConfig VoteOf(const Stage1InferenceConfig& c) {
  return c.InstanceConfig().semantic_vote;
}

// Labels and predictions (bias, then the semantic vote) of the scenes `idx`, appended.
void VotedLabels(const std::vector<CalibrationScene>& scenes, const std::vector<int>& idx,
                 const std::vector<float>& bias, const SemanticVoteConfig& vote,
                 std::vector<int>* gt, std::vector<int>* pred) {
  for (int k : idx) {
    const CalibrationScene& s = scenes[k];
    std::vector<float> prob = s.network->semantic_prob;  // per row (Stage1PointRows)
    std::vector<int> sem =
        s.network->PerPoint(ApplyClassBias(bias, &prob, kStage1RfsClasses), s.points->size());
    if (vote.radius > 0) {
      sem = VoteSemantics(*s.points, s.network->offsets, sem, prob, ThingClasses(), vote,
                          s.network->point_row);
    }
    gt->insert(gt->end(), s.labels->begin(), s.labels->end());
    pred->insert(pred->end(), sem.begin(), sem.end());
  }
}

std::vector<int> AllScenes(std::size_t n) {
  std::vector<int> idx(n);
  std::iota(idx.begin(), idx.end(), 0);
  return idx;
}

double VotedMiou(const std::vector<CalibrationScene>& scenes, const std::vector<float>& bias,
                 const SemanticVoteConfig& vote, std::vector<double>* per_class) {
  std::vector<int> gt, pred;
  VotedLabels(scenes, AllScenes(scenes.size()), bias, vote, &gt, &pred);
  return MeanIouPresent(gt, pred, kStage1RfsClasses, per_class);
}

// Fits the bias on the scenes `idx` (biased argmax, no vote).
ClassBiasFit FitOn(const std::vector<CalibrationScene>& scenes, const std::vector<int>& idx,
                   const ClassBiasFitOptions& options) {
  std::vector<int> labels;
  std::vector<float> prob;
  for (int k : idx) {
    labels.insert(labels.end(), scenes[k].labels->begin(), scenes[k].labels->end());
    const nn::Stage1PointRows& rows = *scenes[k].network;
    for (std::size_t i = 0; i < scenes[k].points->size(); ++i) {  // one row per labelled point
      const float* row = rows.SemanticProb(i, kStage1RfsClasses);
      prob.insert(prob.end(), row, row + kStage1RfsClasses);
    }
  }
  return FitClassBias(labels, prob, kStage1RfsClasses, options);
}

// The bias times `factor`, rounded to the 0.05 grid.
std::vector<float> Scaled(std::vector<float> bias, double factor) {
  for (float& b : bias) b = static_cast<float>(std::round(b * factor / 0.05) * 0.05);
  return bias;
}

}  // namespace

void CalibrationOptions::Validate() const {
  fit.Validate();
  if (folds == 1 || folds < 0) {
    throw InvalidArgument("calibration: folds must be 0 or >= 2, got " + std::to_string(folds));
  }
  for (double f : shrinks) {
    if (!(f >= 0.0 && f <= 1.0)) {
      throw InvalidArgument("calibration: shrinks: " + std::to_string(f) + " is not in [0, 1]");
    }
  }
  if (folds >= 2 && shrinks.empty()) throw InvalidArgument("calibration: shrinks is empty");
  if (!(shrink >= 0.0 && shrink <= 1.0)) {
    throw InvalidArgument("calibration: shrink " + std::to_string(shrink) + " is not in [0, 1]");
  }
  for (double r : vote_radii) {
    if (!(r >= 0.0 && std::isfinite(r))) {
      throw InvalidArgument("calibration: vote radius " + std::to_string(r) +
                            " is negative or not finite");
    }
  }
}

CalibrationReport CalibrateStage1(const std::vector<CalibrationScene>& scenes,
                                  const Stage1InferenceConfig& config,
                                  const CalibrationOptions& c) {
  c.Validate();
  config.Validate();
  if (scenes.empty()) throw InvalidArgument("calibration: no scenes");
  if (c.folds > static_cast<int>(scenes.size())) {
    throw InvalidArgument("calibration: folds " + std::to_string(c.folds) + " exceeds the " +
                          std::to_string(scenes.size()) + " scenes");
  }
  for (std::size_t k = 0; k < scenes.size(); ++k) {
    const CalibrationScene& s = scenes[k];
    if (!s.points || !s.labels || !s.network || s.labels->size() != s.points->size() ||
        s.network->offsets.size() != s.points->size()) {
      throw InvalidArgument("calibration: scene " + std::to_string(k) +
                            " has missing or inconsistent points / labels / network outputs");
    }
    s.network->CheckShape("calibration: scene " + std::to_string(k), s.points->size(),
                          kStage1RfsClasses);
  }
  CalibrationReport rep;
  const SemanticVoteConfig configured_vote = VoteOf(config);
  // Shrinkage of the fitted bias towards 0, chosen by cross-validation over scenes: each
  // fold's bias is fitted on the other folds, and the held-out predictions of all folds (bias
  // x factor, the configured vote) are pooled into one mIoU per factor. A fit on few rooms
  // over-corrects; the factor says by how much.
  rep.shrink = c.shrink;
  if (c.folds >= 2) {
    std::vector<std::vector<int>> gt(c.shrinks.size()), pred(c.shrinks.size());
    for (int f = 0; f < c.folds; ++f) {
      std::vector<int> train, held;
      for (int k = 0; k < static_cast<int>(scenes.size()); ++k) {
        (k % c.folds == f ? held : train).push_back(k);
      }
      const ClassBiasFit fold_fit = FitOn(scenes, train, c.fit);
      for (std::size_t s = 0; s < c.shrinks.size(); ++s) {
        VotedLabels(scenes, held, Scaled(fold_fit.bias, c.shrinks[s]), configured_vote, &gt[s],
                    &pred[s]);
      }
    }
    double best = -1;
    for (std::size_t s = 0; s < c.shrinks.size(); ++s) {
      const double m = MeanIouPresent(gt[s], pred[s], kStage1RfsClasses);
      rep.cross_validation.emplace_back(c.shrinks[s], m);
      if (m > best + 1e-9) {
        best = m;
        rep.shrink = c.shrinks[s];
      }
    }
  }
  rep.fit = FitOn(scenes, AllScenes(scenes.size()), c.fit);
  rep.raw_bias = rep.fit.bias;
  if (rep.shrink != 1.0) {
    rep.fit.bias = Scaled(rep.fit.bias, rep.shrink);
    // Re-score the argmax with the shrunk bias so that the table shows what is shipped.
    std::vector<int> gt, pred;
    VotedLabels(scenes, AllScenes(scenes.size()), rep.fit.bias, SemanticVoteConfig(), &gt,
                &pred);  // default config: radius 0, no vote
    rep.fit.miou_after = MeanIouPresent(gt, pred, kStage1RfsClasses, &rep.fit.iou_after);
  }
  // The vote as configured, without and with the bias.
  SemanticVoteConfig vote = configured_vote;
  rep.miou_vote_before = VotedMiou(scenes, {}, vote, &rep.iou_vote_before);
  rep.miou_vote_after = VotedMiou(scenes, rep.fit.bias, vote, &rep.iou_vote_after);
  rep.miou_vote_configured = rep.miou_vote_after;
  // The vote radius from the candidates (largest voted mIoU with the bias).
  for (double r : c.vote_radii) {
    SemanticVoteConfig trial = vote;
    trial.radius = r;
    std::vector<double> per;
    const double m = VotedMiou(scenes, rep.fit.bias, trial, &per);
    rep.radii.emplace_back(r, m);
    if (m > rep.miou_vote_after + 1e-9) {
      vote = trial;
      rep.miou_vote_after = m;
      rep.iou_vote_after = per;
    }
  }
  // Then which thing classes stay out of the vote: greedy toggles, kept when the voted mIoU
  // rises by more than 1e-4 (a vote merges small objects into their larger neighbours).
  if (vote.radius > 0 && c.choose_vote_exclude) {
    for (int round = 0; round < 3; ++round) {
      bool changed = false;
      for (int k = 0; k < kStage1RfsClasses; ++k) {
        if (!ThingClasses()[k] || std::isnan(rep.fit.iou_before[k])) continue;
        SemanticVoteConfig trial = vote;
        auto& ex = trial.excluded_classes;
        const auto it = std::find(ex.begin(), ex.end(), k);
        if (it == ex.end()) {
          ex.push_back(k);
        } else {
          ex.erase(it);
        }
        std::sort(ex.begin(), ex.end());
        std::vector<double> per;
        const double m = VotedMiou(scenes, rep.fit.bias, trial, &per);
        if (m > rep.miou_vote_after + 1e-4) {
          vote = trial;
          rep.miou_vote_after = m;
          rep.iou_vote_after = per;
          changed = true;
        }
      }
      if (!changed) break;
    }
  }
  rep.config = config;
  rep.config.class_bias = rep.fit.bias;
  rep.config.vote_exclude = vote.excluded_classes;
  rep.config.vote_radius = vote.radius;
  return rep;
}

}  // namespace dimr::pipeline
