// Per-class prior correction of a semantic classifier ("logit adjustment"): the network's
// class probabilities p_c are re-weighted to p'_c = p_c exp(b_c) / sum_j p_j exp(b_j) before
// the argmax, the semantic vote and the instance scores. A network trained with class weights
// w_c (inverse frequency) learns posteriors inflated by about w_c, which buys recall of the
// rare classes with their precision (a rare class then takes points of its common look-alike);
// b_c = -log w_c undoes that in theory, and FitClassBias picks b on validation data to
// maximise the mean IoU directly. LibTorch-free.
#pragma once

#include <vector>

namespace dimr::pipeline {

// Re-weights every row of `prob` (N x C row-major, C = bias.size()) in place and returns the
// per-row argmax. An empty bias leaves `prob` unchanged (the plain argmax is returned). Rows of
// all zeros keep class 0. Throws dimr::InvalidArgument if prob.size() is not a multiple of C,
// a bias is not finite, or a probability is negative or not finite (naming the row).
std::vector<int> ApplyClassBias(const std::vector<float>& bias, std::vector<float>* prob,
                                int num_classes);

struct ClassBiasFitOptions {
  double min_bias = -4.0;  // the search grid of every b_c, natural-log units
  double max_bias = 4.0;
  double step = 0.05;
  int max_sweeps = 8;  // coordinate-ascent sweeps over the classes (stops early when stable)
  // Throws dimr::InvalidArgument naming the bad field.
  void Validate() const;
};

struct ClassBiasFit {
  std::vector<float> bias;  // C values; classes absent from the labels may move too
  double miou_before = 0;   // mean IoU over the classes present in `labels`, b = 0
  double miou_after = 0;    // the same with the fitted bias
  std::vector<double> iou_before, iou_after;  // per class (NaN where absent)
  int sweeps = 0;
};

// Coordinate ascent on the mean IoU (over the classes with labelled points) of the biased
// argmax: for one class at a time, every grid value of its bias is scored exactly in
// O(N C + grid C) by bucketing each point at the bias where it flips to that class. `labels`:
// N ground-truth classes (< 0 = unlabelled, ignored); prob: N x C row-major probabilities.
// The fit never lowers the objective (b = 0 is kept unless beaten). Throws
// dimr::InvalidArgument on size mismatches, a label >= C or non-finite / negative
// probabilities, or if no point is labelled.
ClassBiasFit FitClassBias(const std::vector<int>& labels, const std::vector<float>& prob,
                          int num_classes, const ClassBiasFitOptions& options = {});

// Mean IoU over the classes with labelled points, and per class IoU (NaN where absent), of the
// predictions `pred` against `labels` (< 0 ignored). Throws dimr::InvalidArgument on a size
// mismatch or a value >= num_classes.
double MeanIouPresent(const std::vector<int>& labels, const std::vector<int>& pred, int num_classes,
                      std::vector<double>* per_class = nullptr);

}  // namespace dimr::pipeline
