// Stage 2 at inference (include/dimr/pipeline/stage2_predictor.h).
#include "dimr/pipeline/stage2_predictor.h"

#include <algorithm>
#include <cmath>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/clustering.h"
#include "dimr/pipeline/stage1_segmenter.h"

namespace dimr::pipeline {

void Stage2FilterConfig::Validate() const {
  if (!(score_threshold >= 0 && score_threshold <= 1)) {
    throw InvalidArgument("stage2 filter: score_threshold must be in [0, 1]");
  }
  if (min_points < 0) throw InvalidArgument("stage2 filter: min_points must be >= 0");
  if (!(nms_iou >= 0 && nms_iou <= 1)) throw InvalidArgument("stage2 filter: nms_iou in [0, 1]");
}

Stage2Predictor::Stage2Predictor(nn::Stage2Model model)
    : model_(std::make_shared<const nn::Stage2Model>(std::move(model))) {}

Stage2Predictor Stage2Predictor::Load(const std::string& model_path) {
  return Stage2Predictor(nn::Stage2Model::Load(model_path));
}

std::vector<Stage2Detection> Stage2Predictor::Predict(
    const Stage2SceneInput& scene, const std::vector<ScoredInstance>& proposals) const {
  if (scene.points == nullptr || scene.features == nullptr) {
    throw InvalidArgument("stage2 predict: points and features are required");
  }
  const int fd = model_->config().input.feature_dim;
  if (scene.feature_dim != fd) {
    throw InvalidArgument("stage2 predict: " + std::to_string(scene.feature_dim) +
                          "-d point features given, the stage-2 model expects " +
                          std::to_string(fd) + " (the stage-1 model's widths[0])");
  }
  std::vector<Stage2Detection> out(proposals.size());
  if (proposals.empty()) return out;
  std::vector<nn::Stage2Sample> samples;
  samples.reserve(proposals.size());
  for (std::size_t k = 0; k < proposals.size(); ++k) {
    const ScoredInstance& p = proposals[k];
    Stage2Detection& d = out[k];
    d.proposal = static_cast<int>(k);
    d.cad_class = p.cad_class;
    d.stage1_score = p.score;
    d.points = p.points;
    try {
      samples.push_back(CanonicaliseProposal(*scene.points, *scene.features, fd, scene.floor_z,
                                             p.points, p.cad_class, p.heading, &d.frame));
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("stage2 predict: proposal " + std::to_string(k) + ": " + e.what());
    }
  }
  const nn::Stage2Output o = model_->Predict(samples);
  for (std::size_t k = 0; k < out.size(); ++k) {
    Stage2Detection& d = out[k];
    const int i = static_cast<int>(k);
    d.score = o.score(i);
    d.code = o.Code(i);
    d.box = DecodeBox(d.frame, o.CenterResidual(i, d.cad_class), o.SizeResidual(i, d.cad_class));
  }
  return out;
}

std::vector<Stage2Detection> FilterDetections(std::vector<Stage2Detection> detections,
                                              const Stage2FilterConfig& filter) {
  filter.Validate();
  std::vector<Stage2Detection> kept;
  for (auto& d : detections) {
    if (d.score > filter.score_threshold && static_cast<int>(d.points.size()) > filter.min_points) {
      kept.push_back(std::move(d));
    }
  }
  std::vector<Proposal> props(kept.size());
  for (std::size_t k = 0; k < kept.size(); ++k) {
    props[k].points = kept[k].points;
    props[k].label = kept[k].cad_class;
    props[k].score = kept[k].score;
  }
  std::vector<Stage2Detection> out;
  for (int k : PointIouNms(props, filter.nms_iou)) out.push_back(std::move(kept[k]));
  return out;
}

std::vector<Stage2Detection> Stage2Predictor::Detect(const Stage2SceneInput& scene,
                                                     const std::vector<ScoredInstance>& proposals,
                                                     const Stage2FilterConfig& filter) const {
  return FilterDetections(Predict(scene, proposals), filter);
}

std::vector<Stage2Detection> Stage2Predictor::Predict(const std::vector<Eigen::Vector3f>& points,
                                                      const Stage1Result& stage1) const {
  if (stage1.features.empty() && !stage1.instances.empty()) {
    throw InvalidArgument(
        "stage2 predict: the stage-1 result has no point features (Segment(input, "
        "with_features = true))");
  }
  Stage2SceneInput in{&points, &stage1.features, stage1.feature_dim, stage1.network_origin.z()};
  return Predict(in, stage1.instances);
}

std::vector<Stage2Detection> Stage2Predictor::Detect(const std::vector<Eigen::Vector3f>& points,
                                                     const Stage1Result& stage1,
                                                     const Stage2FilterConfig& filter) const {
  return FilterDetections(Predict(points, stage1), filter);
}

}  // namespace dimr::pipeline
