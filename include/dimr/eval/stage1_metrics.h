// The numbers of `dimr stage1 eval` (and of the validation passes of `dimr train stage1`):
// semantic IoU over the 25 RFS classes (mean over the classes present), each class's most
// frequent confusion, the ScanNet instance AP of the 8 CAD classes, and the median heading
// error of matched CAD instances. Scenes are added one at a time; the per-point arrays of a
// scene are not kept (only its labels for the AP). Plain arrays, no pipeline or nn types.
#pragma once

#include <vector>

#include "dimr/eval/seg_metrics.h"

namespace dimr::eval {

struct Stage1GtInstance {
  int cad_class = -1;        // 0..7, or -1 for a non-CAD instance
  bool has_heading = false;  // matched to a CAD box
  double heading = 0;        // radians
};

struct Stage1PredInstance {
  std::vector<int> points;  // point indices
  int cad_class = -1;       // 0..7
  double score = 0;
  double heading = 0;  // radians
};

// One scene: N points.
struct Stage1SceneEval {
  std::vector<int> gt_semantic;  // N RFS labels, outside [0, 25) = ignored
  std::vector<int> gt_instance;  // N indices into gt_instances, or -1
  std::vector<Stage1GtInstance> gt_instances;
  std::vector<int> pred_semantic;  // N RFS classes
  std::vector<Stage1PredInstance> preds;
};

struct Stage1Metrics {
  SemanticIouResult semantic;  // 25 classes
  InstanceApResult instances;  // 8 CAD classes
  double miou_present = 0;     // mean IoU over the classes with ground-truth points
  int classes_present = 0;
  // Per GT class: the most frequent wrong prediction (-1: none) and its share of the points.
  std::vector<int> confused_with;
  std::vector<double> confused_share;
  int scenes = 0;
  long long points = 0;
  // Support, so that a class mean can be read with its sampling noise in mind: per RFS class,
  // the GT instances whose points are mostly that class (stuff without instance ids counts
  // none) and the scenes holding any of its points (per CAD class: instances.gt_instances).
  std::vector<int> gt_objects;
  std::vector<int> gt_scenes;
  // Median |heading error| (degrees) over the predictions whose best GT instance (most shared
  // points) has a heading and point IoU > 0.5; 0 when there is none.
  double heading_error_deg = 0;
};

// The semantic mean over the classes with at least `min_objects` GT objects (gt_objects; stuff
// without instance ids has none and is left out for min_objects > 0): a class resting on one or
// two objects weighs as much in miou_present as one with fifty, so this mean tracks a model
// with less sampling noise (docs/stage1.md). `classes` (optional) receives how many classes it
// averages; 0 classes give 0. Throws dimr::InvalidArgument for min_objects < 0.
double SupportedMiou(const Stage1Metrics& m, int min_objects, int* classes = nullptr);

class Stage1MetricsAccumulator {
 public:
  explicit Stage1MetricsAccumulator(int num_semantic = 25, int num_cad = 8);
  // Throws dimr::InvalidArgument naming the scene (its index) and the field on inconsistent
  // sizes or an index out of range.
  void Add(const Stage1SceneEval& scene);
  Stage1Metrics Result() const;

 private:
  int num_semantic_, num_cad_;
  int scenes_ = 0;
  std::vector<int> gt_sem_, pred_sem_;
  std::vector<InstanceScene> inst_scenes_;
  std::vector<double> heading_errors_;
  std::vector<int> gt_objects_, gt_scenes_;
};

}  // namespace dimr::eval
