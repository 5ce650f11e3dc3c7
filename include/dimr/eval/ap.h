// The detection-AP machinery shared by the four DIMR mesh metrics (spec
// ../shared/reference/dimr-metrics.md section 2): per-class matching of score-ranked
// predictions to ground truth, VOC07 11-point AP, final precision/recall, class means.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "dimr/eval/classes.h"

namespace dimr::eval {

// How a prediction picks its ground-truth partner.
enum class MatchRule {
  // IoU / CD / LFD (VOC style): best value over ALL GT of the scene (first best wins); TP iff
  // it passes and that GT is still unmatched, otherwise FP (no fallback to the second best).
  kBestOverall,
  // PCR: best value over the still-UNMATCHED GT of the scene (first best wins); TP iff it passes.
  kBestUnmatched,
};

// Direction of the metric: larger is better (IoU, PCR; pass iff value > tau) or smaller is
// better (CD, LFD; pass iff value < tau).
enum class PassTest { kGreater, kLess };

// One prediction of one class. `values[j]` = metric of this prediction against the j-th GT item
// of the same class in the same scene (GT file order); NaN values never win.
struct RankedPrediction {
  int scene = 0;
  double score = 0.0;
  std::vector<double> values;
};

struct ClassAp {
  int npos = 0;      // number of GT items
  int num_pred = 0;  // number of predictions
  int tp = 0;
  int fp = 0;
  double ap = 0.0;              // VOC07 11-point
  double precision = 0.0;       // final tp / (tp + fp) (0 without predictions)
  double recall = 0.0;          // final tp / npos (0 without predictions)
  std::vector<int> order;       // prediction indices in ranking order
  std::vector<int> matched_gt;  // per ranked prediction: GT index it matched, -1 for an FP
  std::vector<double> rec;      // per ranked prediction (cumulative)
  std::vector<double> prec;
};

// The 11 recall thresholds t_i = i * 0.1 computed as a double product (what numpy's
// arange(0, 1.1, 0.1) yields: t_3 = 0.30000000000000004).
double ElevenPointThreshold(int i);

// VOC07 11-point AP: sum over i of (max prec[k] with rec[k] >= t_i, else 0) / 11, accumulated
// in the reference's order.
double Voc07Ap(const std::vector<double>& rec, const std::vector<double>& prec);

// Ranking: indices sorted by descending score; ties keep the base order (a stable sort - the
// reference's numpy argsort(-score) is an unstable introsort, spec section 7.1).
std::vector<int> RankByScore(const std::vector<double>& scores);

// Runs the matching for one class and one threshold. `gt_per_scene[s]` = number of GT items
// of this class in scene s; every prediction's values must have gt_per_scene[scene] entries.
// Throws dimr::InvalidArgument on inconsistent sizes.
ClassAp EvaluateClassAp(const std::vector<RankedPrediction>& preds,
                        const std::vector<int>& gt_per_scene, double threshold, PassTest test,
                        MatchRule rule);

// All classes of one metric at one threshold.
struct ApTable {
  std::string metric;  // "iou", "cd", "lfd", "pcr"
  double threshold = 0.0;
  std::array<ClassAp, kNumClasses> classes;
  // A class enters the means iff it has GT or predictions (the reference's dict keys).
  std::array<bool, kNumClasses> present{};
  double map = 0.0;
  double mean_precision = 0.0;
  double mean_recall = 0.0;
};

// Fills present[] and the class means from classes[].
void FinishTable(ApTable* table);

}  // namespace dimr::eval
