// Pseudo-labels for self-training on unlabelled real scans (issue 22, "self-training on
// unlabelled real scans"; DODA's second step, after virtual-scan simulation). Stage 1 runs on
// a real scan as the product runs it; its labels become a training sample in which only the
// confident points carry a class:
//
//  - class-balanced selection (as in class-balanced self-training, CBST): for each predicted
//    class the `keep_fraction` most confident of its points keep the class, the rest are
//    ignored by the loss - so a class the network predicts everywhere (on real scans often
//    `bookshelf`) does not drown the others, and rare classes keep their best points;
//  - `min_prob`: no point below this probability keeps a class, whatever its rank;
//  - instances (for the offset loss) are the segmenter's own proposals after NMS (highest
//    score first, each point in at most one), with the RFS class most of their points carry;
//    they carry no heading label (a real scan has no CAD box).
//
// The confidence of a point is the probability of its final class (after the class bias, the
// vote and the structure priors) in the averaged test-time-augmented softmax. LibTorch-free.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "dimr/nn/stage1_data.h"
#include "dimr/pipeline/point_cloud_input.h"
#include "dimr/pipeline/stage1_segmenter.h"

namespace dimr::pipeline {

struct PseudoLabelConfig {
  double keep_fraction = 0.5;     // per predicted class, the most confident share kept, (0, 1]
  double min_prob = 0.0;          // a kept point's probability is at least this, [0, 1)
  double min_instance_score = 0;  // proposals scoring below are no instance, [0, 1]
  // Throws dimr::InvalidArgument naming the field.
  void Validate() const;
};

struct PseudoLabelSummary {
  std::size_t points = 0, labelled = 0;  // all points, points that keep a class
  std::size_t instance_points = 0;       // points in a pseudo instance
  int instances = 0;                     // pseudo instances
  std::array<std::size_t, kStage1RfsClasses> predicted{}, kept{};  // per RFS class
  std::array<float, kStage1RfsClasses> threshold{};  // per class: lowest kept probability
};

// The training sample of `cloud` (its points and colours as given: pass the cloud the network
// saw) from the segmenter's result on it. `result` must be per point of `cloud` (semantic,
// probabilities through point_row, instances' point indices). Throws dimr::InvalidArgument
// naming the cloud for a result of another size, a class or instance point out of range.
nn::Stage1Sample PseudoLabelSample(const PointCloudInput& cloud, const Stage1Result& result,
                                   const PseudoLabelConfig& config,
                                   PseudoLabelSummary* summary = nullptr);

}  // namespace dimr::pipeline
