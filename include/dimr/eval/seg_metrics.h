// Point-wise stage-1 metrics, as plain functions over per-point arrays: semantic IoU and the
// ScanNet benchmark's instance AP (evaluate_semantic_instance.py rules: overlaps
// np.arange(0.5, 0.95, 0.05) = 0.50..0.90 for AP plus 0.25, minimum region size, void points
// and too-small GT regions ignored, confidence-ranked matching, AP by the step integral over the
// precision-recall curve).
#pragma once

#include <vector>

namespace dimr::eval {

struct SemanticIouResult {
  std::vector<double> iou;  // per class; NaN when the class has tp + fp + fn = 0
  std::vector<long long> tp, fp, fn;
  double miou = 0.0;      // mean over classes with tp + fp + fn > 0 ("present")
  double accuracy = 0.0;  // over points with a valid GT label
};

// `gt` and `pred` hold one label per point; labels in [0, num_classes) are valid, any other GT
// value (e.g. -100 or 255) is ignored. A prediction outside the range counts as a miss (fn).
// Throws dimr::InvalidArgument on size mismatch.
SemanticIouResult SemanticIou(const std::vector<int>& gt, const std::vector<int>& pred,
                              int num_classes);

struct InstancePrediction {
  int label = -1;
  double score = 0.0;
  std::vector<int> points;  // indices into the scene's points (duplicates are ignored)
};

struct InstanceScene {
  std::vector<int> gt_label;              // per point: class in [0, num_classes) or ignored (void)
  std::vector<int> gt_instance;           // per point: instance id >= 0, or < 0 for none
  std::vector<InstancePrediction> preds;  // in file order
};

struct InstanceApOptions {
  int min_region_size = 100;  // points; smaller GT regions and predictions are ignored
  // AP thresholds (0.50..0.90) followed by 0.25, as numpy builds them.
  std::vector<double> overlaps;
  InstanceApOptions();
};

struct InstanceApResult {
  std::vector<double> overlaps;
  std::vector<std::vector<double>> ap;  // [class][overlap]; NaN: no GT and no prediction
  std::vector<double> class_ap;         // mean over the overlaps except 0.25 (NaN if any is NaN)
  std::vector<double> class_ap50;       // at 0.5
  std::vector<double> class_ap25;       // at 0.25
  double map = 0.0;                     // nanmean over classes x overlaps except 0.25
  double map50 = 0.0;                   // nanmean over classes
  double map25 = 0.0;
  std::vector<int> gt_instances;  // per class: the GT regions scored (>= min_region_size points)
};

InstanceApResult InstanceAp(const std::vector<InstanceScene>& scenes, int num_classes,
                            const InstanceApOptions& options = InstanceApOptions());

// The ScanNet AP of one (class, overlap): y_true / y_score of the ranked candidates, the number
// of unmatched GT ("hard false negatives"), has_gt / has_pred. Exposed for tests.
double ScanNetAp(const std::vector<double>& y_true, const std::vector<double>& y_score,
                 int hard_false_negatives, bool has_gt, bool has_pred);

}  // namespace dimr::eval
