// Calibration of the stage-1 inference settings on labelled scenes (`dimr stage1 calibrate`):
// the per-class prior correction (class_bias.h FitClassBias) with its shrink factor chosen by
// cross-validation over scenes, the semantic-vote radius from candidates, and the thing classes
// kept out of the vote (greedy toggles). Works on the network outputs of the scenes
// (Stage1Segmenter::RunNetwork), so the network runs once. LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "dimr/pipeline/class_bias.h"
#include "dimr/pipeline/stage1_segmenter.h"

namespace dimr::pipeline {

// One labelled scene and its network outputs (not owned; they must outlive the call).
struct CalibrationScene {
  const std::vector<Eigen::Vector3f>* points = nullptr;  // N
  const std::vector<int>* labels = nullptr;              // N RFS labels, < 0 = unlabelled
  const Stage1Result* network = nullptr;                 // RunNetwork: semantic_prob, offsets
};

struct CalibrationOptions {
  ClassBiasFitOptions fit;
  // Cross-validation folds over scenes (fold k holds the scenes i with i % folds == k)
  // choosing the shrink factor of the bias among `shrinks`; 0 = use `shrink`.
  int folds = 2;
  std::vector<double> shrinks{0.0, 0.25, 0.5, 0.75, 1.0};
  double shrink = 1.0;
  // Candidate vote radii (m); empty = keep the configured one.
  std::vector<double> vote_radii;
  // Choose vote_exclude greedily (kept when the voted mIoU rises by more than 1e-4), else keep
  // the configured classes.
  bool choose_vote_exclude = true;
  // Throws dimr::InvalidArgument naming the field (folds 1 or < 0, a shrink outside [0, 1], a
  // radius negative or not finite) and the fit options' errors.
  void Validate() const;
};

struct CalibrationReport {
  ClassBiasFit fit;             // bias after the shrink; iou_after re-scored with it
  std::vector<float> raw_bias;  // before the shrink
  double shrink = 1.0;
  std::vector<std::pair<double, double>> cross_validation;  // shrink, pooled held-out mIoU
  std::vector<std::pair<double, double>> radii;             // radius, voted mIoU with the bias
  // Mean IoU over the classes present with the vote: without the bias, with the bias (the
  // configured vote), with the bias and the chosen vote.
  double miou_vote_before = 0, miou_vote_configured = 0, miou_vote_after = 0;
  std::vector<double> iou_vote_before, iou_vote_after;  // per class (NaN where absent)
  // The input config with class_bias, vote_radius and vote_exclude replaced: the card line.
  Stage1InferenceConfig config;
};

// Throws dimr::InvalidArgument for no scenes, more folds than scenes, inconsistent sizes, and
// as FitClassBias / VoteSemantics.
CalibrationReport CalibrateStage1(const std::vector<CalibrationScene>& scenes,
                                  const Stage1InferenceConfig& config,
                                  const CalibrationOptions& options);

}  // namespace dimr::pipeline
