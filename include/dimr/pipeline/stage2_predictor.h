// Stage 2 at inference: stage-1 proposals + per-point stage-1 outputs -> per proposal the
// confidence score, the decoded box and the latent code [mu, logvar]; then the test-time
// filter of dimr-method.md section 3.6 (score, size, point-IoU NMS). LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "dimr/geometry/oriented_box.h"
#include "dimr/nn/stage2_model.h"
#include "dimr/pipeline/stage1_instances.h"
#include "dimr/pipeline/stage2_proposals.h"

namespace dimr::pipeline {

struct Stage1Result;  // stage1_segmenter.h

struct Stage2FilterConfig {
  double score_threshold = 0.05;  // keep sigmoid(score) > threshold (released config; paper 0.09)
  int min_points = 100;           // keep proposals with > min_points points
  double nms_iou = 0.3;           // greedy point-IoU NMS, drop IoU > nms_iou
  void Validate() const;          // throws dimr::InvalidArgument naming the field
};

struct Stage2Detection {
  int proposal = -1;  // index into the proposals given
  int cad_class = -1;
  double score = 0;           // stage-2 confidence (sigmoid)
  double stage1_score = 0;    // the proposal's stage-1 score
  geometry::OrientedBox box;  // decoded (input frame of the points)
  Eigen::VectorXf code;       // [mu, logvar], 2 * latent_dim
  ProposalFrame frame;        // canonical frame of the proposal
  std::vector<int> points;    // the proposal's point indices
};

// The per-point stage-1 outputs stage 2 reads.
struct Stage2SceneInput {
  const std::vector<Eigen::Vector3f>* points = nullptr;  // N, input frame (metres)
  const std::vector<float>* features = nullptr;          // N x feature_dim (stage-1 features)
  int feature_dim = 0;
  float floor_z = 0;  // floor height in the input frame (stage-1 NetworkFrame::floor_z)
};

class Stage2Predictor {
 public:
  explicit Stage2Predictor(nn::Stage2Model model);
  // Loads the weights (dimr::ParseError naming the file if unreadable).
  static Stage2Predictor Load(const std::string& model_path);
  const nn::Stage2Model& model() const { return *model_; }

  // Every proposal scored (no filtering), in the input order. A proposal's cad_class and
  // heading come from the ScoredInstance (stage 1's vote). Throws dimr::InvalidArgument for
  // a feature size that does not match the model, an empty proposal or an index out of range.
  std::vector<Stage2Detection> Predict(const Stage2SceneInput& scene,
                                       const std::vector<ScoredInstance>& proposals) const;
  // Predict, then the filter: score, size, NMS; kept detections in descending score order.
  std::vector<Stage2Detection> Detect(const Stage2SceneInput& scene,
                                      const std::vector<ScoredInstance>& proposals,
                                      const Stage2FilterConfig& filter) const;
  // The same on stage 1's result for `points` (Stage1Segmenter::Segment(input, true): its
  // instances, its features, the floor = network_origin.z()). Throws dimr::InvalidArgument
  // when the result has no features (Segment without with_features).
  std::vector<Stage2Detection> Predict(const std::vector<Eigen::Vector3f>& points,
                                       const Stage1Result& stage1) const;
  std::vector<Stage2Detection> Detect(const std::vector<Eigen::Vector3f>& points,
                                      const Stage1Result& stage1,
                                      const Stage2FilterConfig& filter) const;

 private:
  std::shared_ptr<const nn::Stage2Model> model_;
};

// The filter alone (score > threshold, > min_points points, NMS) on scored detections; returns
// the kept ones in descending score order.
std::vector<Stage2Detection> FilterDetections(std::vector<Stage2Detection> detections,
                                              const Stage2FilterConfig& filter);

}  // namespace dimr::pipeline
