// Scored instances straight from the stage-1 predictions (no stage 2): multi-scale BFS
// clustering of the CAD points, a semantic score per proposal, the reference's size filter
// (points > 100) and point-IoU NMS at 0.3 (dimr-method.md sections 3.5, 3.6), and the
// proposal heading vote (section 15 fact 3). Used by the stage-1 evaluation. LibTorch-free;
// the pipeline layer does not include the data layer, so the caller passes the RFS -> CAD
// table.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "dimr/pipeline/clustering.h"

namespace dimr::pipeline {

struct SemanticVoteConfig {
  double radius = 0.0;  // BFS radius on the shifted points, metres; 0 = no vote
  int min_points = 20;  // smaller clusters keep their per-point labels (>= 1)
  // Thing classes kept out of the vote: their points neither join a cluster nor change, and no
  // cluster is given them (e.g. small wall-mounted or table-top objects whose clusters merge
  // with their larger neighbours).
  std::vector<int> excluded_classes;
  // Size plausibility of the voted class: a cluster whose footprint is shorter than
  // min_extent[c] metres cannot take class c and takes the best class it can (e.g. a
  // chair-sized cluster whose points lean to `sofa`: sofas have two seats or more, a one-seat
  // "sofa" is an armchair, which ScanNet labels chair). The footprint is the long side of the
  // cluster's original (unshifted) points on the floor plane: 2nd to 98th percentile along
  // their principal horizontal axis. Empty = no limits; else one value per class, 0 = none.
  std::vector<double> min_extent;
  // Longest plausible object (metres; 0 = no limit): a cluster whose footprint long side (as
  // min_extent measures it) exceeds it is not one object but several whose shifted points
  // joined - on real scans a sofa, its table and the bed beside them can form one component,
  // and its vote would give all of them one class. Such a cluster is split by clustering its
  // shifted points again at half the radius (at most three times, radius / 8); the parts vote
  // on their own, points of no part and parts still too long keep their per-point labels.
  double max_extent = 0.0;
  // The reference's neighbour cap in the vote's BFS (false: RadiusComponents, as
  // ClusteringConfig::neighbour_cap).
  bool neighbour_cap = true;
  // Throws dimr::InvalidArgument naming the bad field (radius negative or not finite,
  // min_points < 1, a negative excluded class, a negative or non-finite min_extent).
  void Validate() const;
};

struct Stage1InstanceConfig {
  ClusteringConfig clustering;  // default: the test-time multi-scale passes
  double nms_iou = 0.3;         // NMS drops proposals with IoU > nms_iou, in [0, 1]
  int min_points = 100;         // a proposal is kept if it has > min_points points (>= 0)
  // Instance-guided semantic vote (VoteSemantics below) applied by the stage-1 evaluation
  // before clustering; radius 0 = off.
  SemanticVoteConfig semantic_vote;
  // Per-class prior correction (pipeline/class_bias.h) applied to the network's probabilities
  // before the vote and the clustering: C natural-log offsets, empty = none.
  std::vector<float> class_bias;
  // Throws dimr::InvalidArgument naming the bad field.
  void Validate() const;
};

struct ScoredInstance {
  std::vector<int> points;  // point indices, BFS order
  int cad_class = -1;       // 0..7
  double score = 0.0;       // mean semantic probability of the class (see below)
  double heading = 0.0;     // radians, (-pi, pi]
};

// points, offsets: N predicted offsets (metres). cad_label: per point 0..7, or -1 for a
// non-CAD point. semantic_prob: R x C softmax, row-major, C = rfs_to_cad.size() (25 for the
// RFS label set). heading_prob / heading_residual: R x 12 row-major (bin probabilities,
// normalised residuals). Point i's rows are row point_row[i] (per-voxel tables,
// nn::Stage1PointRows), or row i when point_row is empty (R = N). rfs_to_cad: CAD id per semantic
// class (any value outside 0..7 means non-CAD). The score of a proposal of CAD class c is the mean
// over its points of the summed probability of the semantic classes that map to c. Proposals with >
// min_points points go through NMS; the kept ones are returned in descending score order. Throws
// dimr::InvalidArgument on size mismatches or a cad_label outside [-1, 7].
std::vector<ScoredInstance> ExtractStage1Instances(
    const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& offsets,
    const std::vector<int>& cad_label, const std::vector<float>& semantic_prob,
    const std::vector<float>& heading_prob, const std::vector<float>& heading_residual,
    const std::vector<int>& rfs_to_cad, const Stage1InstanceConfig& config,
    const std::vector<std::int64_t>& point_row = {});

// The proposals ExtractStage1Instances starts from: every pass of `clustering`
// (MultiScaleClusters' order, clusters of >= clustering.min_points points), each scored and
// with its heading vote exactly as above, but without the size filter and without NMS - what
// stage-2 training samples are drawn from (`dimr stage2 prepare`). The instances of
// ExtractStage1Instances with the same clustering are those of these proposals with
// > min_points points that survive NMS. Same inputs and errors as ExtractStage1Instances.
std::vector<ScoredInstance> ScoredStage1Proposals(
    const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& offsets,
    const std::vector<int>& cad_label, const std::vector<float>& semantic_prob,
    const std::vector<float>& heading_prob, const std::vector<float>& heading_residual,
    const std::vector<int>& rfs_to_cad, const ClusteringConfig& clustering,
    const std::vector<std::int64_t>& point_row = {});

}  // namespace dimr::pipeline

namespace dimr::pipeline {

// Footprint long side of the points `idx` (metres): the 2nd-98th percentile range of their x-y
// coordinates along the principal axis of their x-y covariance; 0 for fewer than 2 points.
double FootprintLongSide(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& idx);

// Instance-guided semantic refinement: the points whose argmax class is a "thing" class
// (is_thing[c], e.g. everything but wall and floor, less config.excluded_classes) are
// clustered class-agnostically by BFS on
// points + offsets with `config.radius`; every cluster of >= min_points points takes the
// class with the largest summed probability over its points (thing classes only, less those
// whose config.min_extent exceeds the cluster's footprint, see SemanticVoteConfig) and all its
// points get that class. Stuff points and small clusters keep their labels. semantic: N argmax
// classes in [0, C); semantic_prob: R x C row-major, point i's row point_row[i] (or i when
// point_row is empty, R = N); is_thing: C flags. Returns the refined
// labels (a copy of `semantic` if radius is 0). Throws dimr::InvalidArgument on size
// mismatches, a label outside [0, C) or non-finite probabilities of a voting point.
std::vector<int> VoteSemantics(const std::vector<Eigen::Vector3f>& points,
                               const std::vector<Eigen::Vector3f>& offsets,
                               const std::vector<int>& semantic,
                               const std::vector<float>& semantic_prob,
                               const std::vector<bool>& is_thing, const SemanticVoteConfig& config,
                               const std::vector<std::int64_t>& point_row = {});

}  // namespace dimr::pipeline
