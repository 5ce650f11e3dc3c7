// Stage 1 of DIMR as one library call: the point-wise network (with test-time augmentation),
// the per-class prior correction, the instance-guided semantic vote, multi-scale clustering and
// NMS (dimr-method.md sections 1-3, docs/stage1.md). `dimr stage1 eval`, `dimr bench stage1`,
// the reconstructor and the ROS node all run this; a CLI verb only turns flags into a
// Stage1InferenceConfig.
//
//   auto seg = pipeline::Stage1Segmenter::Load("models/stage1/stage1.pt",
//                                              pipeline::Stage1Preset::kAccurate);
//   pipeline::Stage1Result r = seg.Segment(cloud);   // cloud: pipeline::PointCloudInput
//   for (const auto& inst : r.instances) ...          // CAD class, score, heading, points
//
// LibTorch-free header (the network lives behind nn/stage1_model.h).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "dimr/core/config_fields.h"
#include "dimr/core/timing.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/clustering.h"
#include "dimr/pipeline/colour_norm.h"
#include "dimr/pipeline/point_cloud_input.h"
#include "dimr/pipeline/stage1_instances.h"
#include "dimr/pipeline/wall_openings.h"

namespace dimr::nn {
class Stage1Model;
}

namespace dimr::pipeline {

class ModelCard;

constexpr int kStage1RfsClasses = 25;  // the network's semantic classes (RFS label set)
constexpr int kStage1HeadingBins = 12;

// RFS class names in network order ("wall", "floor", ..., "other_table") and the RFS -> CAD
// table (CAD id 0..7 or -1): dimr/core/labels.h as vectors.
const std::vector<std::string>& Stage1RfsClassNames();
const std::vector<int>& Stage1RfsToCad();
// "window,picture" <-> class ids (sorted, unique); "" and "none" are no class. Throws
// dimr::InvalidArgument naming an unknown name.
std::vector<int> ParseRfsClassList(const std::string& text);
std::string RfsClassListToString(const std::vector<int>& classes);  // "" for none
// "sofa:0.8,bathtub:0.95" <-> 25 values per RFS class (0 where not named), or empty for ""
// and "none". Throws dimr::InvalidArgument naming an unknown class, a missing ':' or a value
// that is not a finite number >= 0.
std::vector<double> ParseRfsClassValues(const std::string& text);
std::string RfsClassValuesToString(const std::vector<double>& values);  // "" for none

// fast: one network pass (no test-time augmentation), the rest as the card recommends;
// accurate: the model card's recommended_inference as it is.
enum class Stage1Preset { kFast, kAccurate };
const config::EnumNames<Stage1Preset>& Stage1PresetNames();

// Everything stage 1 does after loading the weights. Text form (model cards'
// `recommended_inference`, --inference flags): "passes=s0.12,s0.2,s0.3 rotations=6 mirror=1
// vote_radius=0.08 vote_min_points=5 class_bias=b0,...,b24 vote_exclude=window,picture".
struct Stage1InferenceConfig {
  // Test-time augmentation: the network on the scene rotated about the vertical axis by
  // 2 pi k / rotations (rotations divides 12) and, with mirror, on its mirror image too; the
  // outputs are averaged (nn::Stage1Model::PredictAugmented).
  int rotations = 1;
  bool mirror = false;
  // Per-class prior correction (class_bias.h): 25 natural-log offsets, empty = none.
  std::vector<float> class_bias;
  // Instance-guided semantic vote (stage1_instances.h): BFS radius (m) on the shifted thing
  // points, 0 = per-point argmax; clusters of fewer points keep their labels; classes kept
  // out of the vote.
  double vote_radius = 0;
  int vote_min_points = 20;
  std::vector<int> vote_exclude;
  // Size plausibility in the vote (SemanticVoteConfig::min_extent): a cluster whose footprint
  // long side is below the value of a class cannot take it (text
  // "vote_min_extent=sofa:0.8"); empty = none, else 25 values.
  std::vector<double> vote_min_extent;
  // Longest plausible object in the vote (SemanticVoteConfig::max_extent, "vote_max_extent=3"):
  // a longer cluster is split (re-clustered at half the radius); 0 = no limit.
  double vote_max_extent = 0.0;
  // Per-scene colour standardisation (colour_norm.h): a scene whose colour mean / spread lie
  // outside the training rooms' range is mapped to the nearest in-range statistics (text
  // "colour_norm=<12 values>", `dimr stage1 colour-stats`); off when colour_norm is false.
  bool colour_norm = false;
  // Structure prior (wall_planes.h): points on large vertical planes bounding the scan whose
  // label is a class that never forms one (chair, curtain, ...) become wall; text
  // "wall_planes=1", "wall_plane_area=2" (m², the smallest wall). Off by default.
  bool wall_planes = false;
  double wall_plane_area = 2.0;
  double wall_plane_distance = 0.03;  // m, "wall_plane_distance": points this close are on it
  // Structure prior (wall_openings.h, needs wall_planes): compact regions of a wall plane whose
  // door / window / curtain / picture probability is high, or weak but with colour contrast or
  // recess, take that class ("wall_openings=1"; the thresholds "wall_opening_prob",
  // "wall_opening_weak", "wall_opening_contrast", "wall_opening_area"). Off by default.
  bool wall_openings = false;
  double wall_opening_prob = 0.25;
  double wall_opening_weak = 0.05;
  double wall_opening_contrast = 3.0;
  double wall_opening_area = 0.3;
  bool wall_opening_shape = false;  // "wall_opening_shape": the class by shape (door / window)
  ColourRange colour_range;
  // Test-time adaptation of the U-Net's normalisation to the scene (text "scene_norm=w", w in
  // [0, 1]): every network pass normalises with (1 - w) x the training statistics + w x its
  // own (nn::ScopedSceneNormalisation); 0 = the training statistics alone.
  double scene_norm = 0;
  // Multi-scale clustering passes (default: the reference's o0.03,s0.01,s0.03,s0.05), the
  // smallest cluster, point-IoU NMS threshold and the smallest proposal kept (> min_points).
  std::vector<ClusterPass> passes = ClusteringConfig().passes;
  int cluster_min_points = 10;
  // The reference's ball-query neighbour cap (exact); false: the approximate, faster
  // connected-components mode (ClusteringConfig::neighbour_cap) for the passes and the vote.
  bool cluster_cap = true;
  double nms_iou = 0.3;
  int min_points = 100;
  // A cloud spanning more than this (metres, any axis) is rejected: not a room in metres
  // (e.g. one in millimetres).
  double max_extent = 200;

  int network_passes() const { return rotations * (mirror ? 2 : 1); }
  // Throws dimr::InvalidArgument naming the key ("stage1 inference: rotations = 5: ...").
  void Validate() const;
  // The text form; keys at their default value are left out except rotations, mirror,
  // vote_radius and vote_min_points.
  std::string ToString() const;
  // Keys applied on top of `base` (then validated). Strict values: "rotations=6x" is an
  // error naming the key. Throws dimr::InvalidArgument.
  static Stage1InferenceConfig FromString(const std::string& text);
  static Stage1InferenceConfig FromString(const std::string& text,
                                          const Stage1InferenceConfig& base);
  // The declarations behind the text form (also the CLI options, src/tools/config_options.h).
  static const config::Fields<Stage1InferenceConfig>& Fields();
  // The card's `recommended_inference` line (defaults when the key is absent), then single
  // keys of a `stage1_inference:` mapping (YAML: `stage1_inference: {rotations: 2}`), under
  // `preset`. Throws dimr::ParseError naming the card and the key for a bad value.
  static Stage1InferenceConfig FromModelCard(const ModelCard& card,
                                             Stage1Preset preset = Stage1Preset::kAccurate);
  // `preset` applied to this config (kFast: rotations 1, no mirror).
  Stage1InferenceConfig WithPreset(Stage1Preset preset) const;
  // The clustering / NMS / vote / bias part in the form ExtractStage1Instances takes.
  Stage1InstanceConfig InstanceConfig() const;
};

// "o0.03,s0.01" <-> passes (o = original, s = shifted coordinates, radius in metres). Throws
// dimr::InvalidArgument for a bad item.
std::vector<ClusterPass> ParseClusterPasses(const std::string& text);
std::string ClusterPassesToString(const std::vector<ClusterPass>& passes);

// Per point in the input order (N points, C = 25 classes, B = 12 heading bins). The
// probability tables (semantic_prob R x C, averaged over the passes, then biased; heading_prob
// and heading_residual R x B) are per row, nn::Stage1PointRows: one row per voxel after a
// single pass, one per point after test-time augmentation; read point i's with
// SemanticProb(i), HeadingProb(i), HeadingResidual(i), or ExpandToPoints() them.
struct Stage1Result : nn::Stage1PointRows {
  std::vector<int> semantic;             // RFS class after the bias and the vote
  std::vector<int> cad_label;            // CAD class of `semantic` (0..7) or -1
  std::vector<Eigen::Vector3f> offsets;  // predicted shift to the instance centre (m)
  std::vector<float> features;           // N x feature_dim (only when asked)
  int feature_dim = 0;                   // the network's widths[0]
  Eigen::Vector3f network_origin = Eigen::Vector3f::Zero();  // the frame the network saw
  std::vector<ScoredInstance> instances;  // after clustering + NMS, descending score
  WallOpeningResult wall_openings;        // the regions relabelled (wall_openings=1)
  // Named stages in order: "network" (all passes; its parts "voxelize", "kernel_maps",
  // "unet", "heads" follow), "class_bias", "vote", "clustering" (+ NMS), "total".
  Timings timings;
};

// Thread safety: Segment() is const but the network's modules are not safe to run from two
// threads at once - use one Stage1Segmenter per thread (Load it once per thread).
class Stage1Segmenter {
 public:
  // Loads the weights (nn::Stage1Model::Load: dimr::ParseError naming the file) and validates
  // `config`.
  static Stage1Segmenter Load(const std::string& model_path, const Stage1InferenceConfig& config);
  // The config from the model card beside the weights (defaults without a card) under `preset`.
  static Stage1Segmenter Load(const std::string& model_path,
                              Stage1Preset preset = Stage1Preset::kAccurate);
  // Runs an in-memory model (not owned: it must outlive the segmenter), e.g. validation
  // during training.
  static Stage1Segmenter Borrow(const nn::Stage1Model& model, const Stage1InferenceConfig& config);

  ~Stage1Segmenter();
  Stage1Segmenter(Stage1Segmenter&&) noexcept;
  Stage1Segmenter& operator=(Stage1Segmenter&&) noexcept;

  const Stage1InferenceConfig& config() const;
  void set_config(const Stage1InferenceConfig& config);  // validates
  std::string model_config() const;                      // the network's "scale=20 rgb=0 ..."
  int feature_dim() const;
  bool uses_color() const;

  // The whole of stage 1. Validates the input (PointCloudInput::Validate, colours when the
  // model needs them, the extent against max_extent); throws dimr::InvalidArgument naming the
  // cloud. An empty result (no instances) is a valid answer, e.g. for one point or a plane.
  Stage1Result Segment(const PointCloudInput& input, bool with_features = false) const;

  // The two halves of Segment, for callers that re-run the cheap part with other settings
  // (calibration): RunNetwork fills the per-point network outputs (argmax semantic, no bias,
  // no vote, no instances; timings "network" and its parts); Finish applies bias, vote,
  // clustering and NMS of `config` to them in place. `colours` (the input's, 0..1) serve the
  // wall-openings prior's colour contrast; without them it uses probability and depth only.
  Stage1Result RunNetwork(const PointCloudInput& input, bool with_features = false) const;
  static void Finish(const std::vector<Eigen::Vector3f>& points,
                     const Stage1InferenceConfig& config, Stage1Result* result,
                     const std::vector<Eigen::Vector3f>* colours = nullptr);
  // The first part of Finish: the class bias, the vote and cad_label (timings "class_bias",
  // "vote"), no clustering - for callers that cluster differently, e.g. `dimr stage2 prepare`,
  // which takes every pass's proposals without NMS (ScoredStage1Proposals).
  static void FinishLabels(const std::vector<Eigen::Vector3f>& points,
                           const Stage1InferenceConfig& config, Stage1Result* result,
                           const std::vector<Eigen::Vector3f>* colours = nullptr);

 private:
  struct Impl;
  explicit Stage1Segmenter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace dimr::pipeline
