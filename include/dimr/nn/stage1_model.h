// Stage 1 of DIMR: the point-wise network (sparse U-Net backbone + semantic (25), offset (3) and
// 12-bin heading heads) with the reference losses, a trainer and inference. Spec:
// ../shared/reference/dimr-method.md sections 1-2 and 10-11. LibTorch-free header (pimpl).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dimr/core/config_fields.h"
#include "dimr/nn/stage1_data.h"

namespace dimr::nn {

struct Stage1Config {
  Stage1InputConfig input;                                    // scale (voxels per metre), rgb
  std::vector<std::int64_t> widths{16, 32, 48, 64, 96, 128};  // U-Net levels
  int reps = 1;                                               // residual blocks per level and side
  int num_classes = kStage1Classes;

  // The reference network: scale 50 (2 cm), widths 32,32,64,64,96,96,128, reps 2.
  static Stage1Config Reference();
  // The CPU-sized default (scale 20 = 5 cm, widths 16..128 in 6 levels, reps 1): 2.1x faster
  // to train than reps 2 on 2 cores (1.4 vs 3.0 s per 4-scene step), docs/models.md.
  static Stage1Config CpuDefault() { return Stage1Config(); }
  void Validate() const;         // throws dimr::InvalidArgument naming the key
  std::string ToString() const;  // "scale=20 rgb=0 widths=16,32,48,64,96,128 reps=2 classes=25"
  static Stage1Config FromString(const std::string& text);
};

struct Stage1TrainOptions {
  int epochs = 40;
  int batch_size = 4;           // scenes per step
  double learning_rate = 1e-3;  // Adam; lr = max(lr0 * decay^((epoch-1)/epochs), 1e-6)
  double lr_decay = 0.1;        // the reference's multiplier over the whole run
  AugmentConfig augment;
  std::uint64_t seed = 123;
  int threads = 0;  // intra-op threads (0 = library default)
  int loader_threads = 1;
  std::string device = "cpu";   // "cpu" or "cuda"
  std::string checkpoint_path;  // full training state (model, optimiser, position)
  int checkpoint_every_steps = 200;
  bool resume = true;      // continue from checkpoint_path when it exists
  double max_minutes = 0;  // stop (after checkpointing) when exceeded; 0 = no limit
  // With max_minutes: the schedule's progress is max(step fraction, elapsed fraction of
  // max_minutes), so the learning rate reaches its final value when the time budget ends even
  // where the speed of a host (a GPU) is not known in advance. Off: step fraction only.
  bool lr_by_time = false;
  int validate_every_epochs = 1;  // calls the epoch callback every k epochs and at the end
  bool progress = true;           // progress bar with the loss terms on stderr
  // Per-class weights of the semantic cross-entropy (num_classes entries; empty = unweighted,
  // the reference). See SemanticClassWeights.
  std::vector<float> class_weights;
};

struct Stage1LossTerms {
  double total = 0, semantic = 0, offset_norm = 0, offset_dir = 0, heading_cls = 0, heading_res = 0;
};

struct Stage1StepLog {
  int epoch = 0;  // 1-based
  int step = 0;   // global, 1-based
  double lr = 0;
  Stage1LossTerms loss;
  double seconds = 0;  // wall time since the start (this process)
  // Where the step's time went (ms): waiting for the loader, voxelisation, kernel maps (the
  // U-Net's rulebooks, built on the CPU), U-Net forward (convolutions), heads + loss, backward,
  // optimiser. On CUDA the device is synchronised
  // after backward and after the optimiser step so that the phases are not blurred by queued
  // kernels (the loss already synchronises).
  double data_ms = 0, voxelize_ms = 0, kernel_map_ms = 0, unet_ms = 0, loss_ms = 0, backward_ms = 0,
         optimizer_ms = 0;
};

// The probability tables of stage 1, stored once per row: a row is a voxel of the network's
// grid after a single pass (every point of a voxel has the voxel's outputs: the 100k points
// of a room share ~20k rows, so the tables are a fifth of a per-point copy) or, after
// test-time augmentation (each point its own mean), a point, the rows stored in the first
// pass's voxel order. point_row[i] is the row of point i; empty means row i is point i (as
// after ExpandToPoints). Read a point's values with SemanticProb(i) etc.
struct Stage1PointRows {
  std::vector<float> semantic_prob;     // R x C softmax (C = 25)
  std::vector<float> heading_prob;      // R x 12 softmax of the bin logits
  std::vector<float> heading_residual;  // R x 12 normalised residuals
  std::vector<std::int64_t> point_row;  // N rows in [0, R), or empty (R = N)

  std::size_t Row(std::size_t i) const {
    return point_row.empty() ? i : static_cast<std::size_t>(point_row[i]);
  }
  std::size_t NumRows(int classes = kStage1Classes) const {
    return semantic_prob.size() / static_cast<std::size_t>(classes);
  }
  const float* SemanticProb(std::size_t i, int classes = kStage1Classes) const {
    return semantic_prob.data() + Row(i) * static_cast<std::size_t>(classes);
  }
  const float* HeadingProb(std::size_t i) const {
    return heading_prob.data() + Row(i) * kHeadingBins;
  }
  const float* HeadingResidual(std::size_t i) const {
    return heading_residual.data() + Row(i) * kHeadingBins;
  }
  // Per-row values spread to `points` points (identity for per-point rows): out[i] = v[Row(i)].
  template <typename T>
  std::vector<T> PerPoint(const std::vector<T>& per_row, std::size_t points) const {
    if (point_row.empty()) return per_row;
    std::vector<T> out(points);
    for (std::size_t i = 0; i < points; ++i) out[i] = per_row[point_row[i]];
    return out;
  }
  // Rewrites the tables with one row per point (point_row becomes empty): for callers that
  // concatenate rooms or edit single points.
  void ExpandToPoints(std::size_t points, int classes = kStage1Classes);
  // Throws dimr::InvalidArgument (prefixed by `who`) unless the tables hold whole rows of C,
  // 12 and 12 floats, the same count R of each, and point_row has `points` entries in [0, R)
  // (or is empty with R == points).
  void CheckShape(const std::string& who, std::size_t points, int classes = kStage1Classes) const;
};

// The number of rows R of a table of `table_size` floats in rows of `dim` that `points` points
// index through `point_row` (entries in [0, R)), or `points` when point_row is empty (then the
// table must hold points x dim floats). Throws dimr::InvalidArgument prefixed by `who`, naming
// `table` or the first bad entry. The one check of a point -> row map (Stage1PointRows::
// CheckShape and the pipeline's consumers of per-row tables call it).
std::size_t CheckPointRows(const std::string& who, const char* table, std::size_t table_size,
                           std::size_t dim, std::size_t points,
                           const std::vector<std::int64_t>& point_row);

// Per-point results of one scene (in the input point order); the probability tables per row
// (Stage1PointRows).
struct Stage1Output : Stage1PointRows {
  std::vector<int> semantic;             // N argmax RFS class
  std::vector<Eigen::Vector3f> offsets;  // N predicted shifts to the instance centre (m)
  std::vector<float> features;           // N x widths[0] point features (if requested)
  NetworkFrame frame;                    // the frame the network saw
};

struct Stage1Timing {
  double voxelize_ms = 0, kernel_map_ms = 0, unet_ms = 0, heads_ms = 0;  // unet: convolutions only
};

// Class weights w_c = clamp((median_f / f_c)^power, min_w, max_w) (power 0.5: sqrt) from the
// labelled points of `samples` (f_c = share of class c among the labelled points, median over the
// classes present); classes without points get 1. Counters the wall/floor majority in short CPU
// schedules.
std::vector<float> SemanticClassWeights(const std::vector<Stage1Sample>& samples,
                                        int num_classes = kStage1Classes, double min_w = 0.25,
                                        double max_w = 4.0, double power = 0.5);

// How `dimr train stage1 --class-weights` weights the semantic loss: none (the reference),
// sqrt-inverse (SemanticClassWeights defaults) or inverse (power 1, clamped to [0.1, 10]).
enum class ClassWeighting { kNone, kSqrtInverse, kInverse };
inline const config::EnumNames<ClassWeighting>& ClassWeightingNames() {
  static const config::EnumNames<ClassWeighting> names(
      "class weighting", {{ClassWeighting::kNone, "none"},
                          {ClassWeighting::kSqrtInverse, "sqrt-inverse"},
                          {ClassWeighting::kInverse, "inverse"}});
  return names;
}
// The weights of `weighting` (empty for kNone).
inline std::vector<float> SemanticClassWeights(const std::vector<Stage1Sample>& samples,
                                               ClassWeighting weighting, int num_classes) {
  switch (weighting) {
    case ClassWeighting::kSqrtInverse:
      return SemanticClassWeights(samples, num_classes);
    case ClassWeighting::kInverse:
      return SemanticClassWeights(samples, num_classes, 0.1, 10.0, 1.0);
    case ClassWeighting::kNone:
      break;
  }
  return {};
}

// Where training runs (Stage1TrainOptions::device, BspTrainOptions::device hold the name).
enum class Device { kCpu, kCuda };
inline const config::EnumNames<Device>& DeviceNames() {
  static const config::EnumNames<Device> names("device",
                                               {{Device::kCpu, "cpu"}, {Device::kCuda, "cuda"}});
  return names;
}

// The sparse-convolution kernel path the network takes on this CPU ("avx512", "avx2",
// "gemm"), for benchmark headers.
std::string SparseKernelsInUse();
// The stage-1 heads' kernels, softmax and TTA mean ("avx512", "avx2", "generic": the
// sparse-kernel path's ISA, the 4-lane kernels for the GEMM path; the same bits on every
// path), for benchmark headers.
std::string Stage1HeadsKernelsInUse();

// Intra-op threads of the network (at::set_num_threads), for torch-free callers.
void SetIntraOpThreads(int threads);

class Stage1Model {
 public:
  explicit Stage1Model(const Stage1Config& config = Stage1Config(), std::uint64_t seed = 1);
  ~Stage1Model();
  Stage1Model(Stage1Model&&) noexcept;
  Stage1Model& operator=(Stage1Model&&) noexcept;

  const Stage1Config& config() const;
  std::int64_t NumParameters() const;

  // Weights + config (float16 with `half`); Load checks config, names and shapes and throws
  // dimr::ParseError naming the file for truncated / corrupt / mismatching files.
  void Save(const std::string& path, bool half = false) const;
  static Stage1Model Load(const std::string& path);

  // Checkpoint averaging (a "model soup" of fine-tunes from one ancestor, or the last checkpoints
  // of one run): loads every file and returns the element-wise mean of all parameters and
  // floating buffers (BatchNorm running statistics); integer buffers come from the first file.
  // Throws dimr::InvalidArgument for an empty list or files of different configurations
  // (naming both), dimr::ParseError for an unreadable file.
  static Stage1Model Average(const std::vector<std::string>& paths);

  // A geometry-only copy of a colour model: the model of `path` (rgb=1) as a model of the same
  // configuration with rgb=0, every parameter and buffer copied and the input convolution cut
  // to its first three (xyz) input channels. Exact for grey input: the colour features are
  // colour - 0.5, so the colour model on a cloud whose colours are all 0.5 and the copy on
  // its points compute the same outputs (up to float summation order). The start of a
  // geometry-only fine-tune (`dimr train stage1 --config '... rgb=0' --init COLOUR_MODEL`).
  // Throws dimr::InvalidArgument for a model without colour input, dimr::ParseError as Load.
  static Stage1Model LoadWithoutColour(const std::string& path);

  // The model of `path` at another input resolution (`scale` voxels per metre): every parameter
  // and buffer as stored, only the voxel size of the configuration changed (no tensor's shape
  // depends on it). The start of a fine-tune at a finer or coarser grid (`dimr train stage1
  // --config 'scale=33 ...' --init SCALE_20_MODEL`): the 3x3x3 kernels then span a smaller
  // neighbourhood, which the fine-tune has to adapt to. Throws dimr::InvalidArgument for a
  // scale outside (0, 1000], dimr::ParseError as Load.
  static Stage1Model LoadAtScale(const std::string& path, double scale);

  // The model of `path` with `reps` residual blocks per level and side instead of its stored
  // (smaller) number, computing exactly the same function: the stored blocks keep their
  // tensors, every added block (index >= the stored reps, on the way down and up of every
  // level) gets its last convolution zeroed, so its residual branch adds nothing and the
  // block is the identity until training moves it (the function-preserving deepening of
  // Net2DeeperNet). The start of a fine-tune with more capacity (`dimr train stage1 --config
  // '... reps=2 ...' --init REPS_1_MODEL`). Throws dimr::InvalidArgument for `reps` not above
  // the stored number, or a stored tensor the deeper network lacks or shapes differently;
  // dimr::ParseError as Load.
  static Stage1Model LoadDeeper(const std::string& path, int reps);

  // Trains on `train`. `log` is called every step; `on_epoch` every validate_every_epochs epochs
  // (and after the last) with the model in eval mode; the metrics it returns are printed with
  // the epoch (the caller logs them). Returns the step logs of this call.
  using EpochCallback =
      std::function<std::map<std::string, double>(int epoch, const Stage1Model& model)>;
  std::vector<Stage1StepLog> Train(const std::vector<Stage1Sample>& train,
                                   const Stage1TrainOptions& options,
                                   const std::function<void(const Stage1StepLog&)>& log = {},
                                   const EpochCallback& on_epoch = {});

  // Loss terms of one batch (eval-mode BN, no gradient) - for tests and validation.
  Stage1LossTerms EvaluateLoss(const Stage1Batch& batch) const;

  // Inference on one scene (eval mode). Points only are read from `sample` (labels ignored).
  // Throws dimr::InvalidArgument for an empty cloud or non-finite points.
  Stage1Output Predict(const Stage1Sample& sample, bool with_features = false,
                       Stage1Timing* timing = nullptr) const;

  // Test-time augmentation: Predict on the scene rotated about the vertical axis through its
  // centroid by 2 pi k / rotations, k = 0 .. rotations-1, and (mirror) also on its mirror
  // image (x -> -x about the centroid) under the same rotations; every result is mapped back
  // to the input frame (offsets rotated / mirrored back, heading bins shifted back by
  // 12 k / rotations, mirrored bins b -> 6 - b with negated residuals) and averaged: semantic
  // and heading probabilities, heading residuals and offsets are means, `semantic` is the
  // argmax of the mean. `features` and `frame` come from the plain pass; timing sums all
  // passes. rotations must divide 12 (1, 2, 3, 4, 6, 12) so the heading bins map exactly;
  // (1, false) is Predict. Throws dimr::InvalidArgument for another count and as Predict.
  Stage1Output PredictAugmented(const Stage1Sample& sample, int rotations, bool mirror,
                                bool with_features = false, Stage1Timing* timing = nullptr) const;

  // The same on a label-free view of the points (and colours): no training sample is built
  // and no per-point array is copied besides the network input and, per augmented pass, the
  // moved points. The voxel grid is padded to at least 2^(levels - 1) voxels per axis so that
  // every U-Net level can down-sample (a flat room, a plane or a single point). Throws
  // dimr::InvalidArgument naming the scene (MakeStage1NetworkInput) and for a bad rotations.
  Stage1Output Predict(const ScenePoints& scene, bool with_features = false,
                       Stage1Timing* timing = nullptr) const;
  // `scene_norm` in [0, 1]: every pass normalises the U-Net's BatchNorm layers with that blend
  // of the training statistics and the pass's own (test-time adaptation to a scene unlike the
  // training rooms: nn::ScopedSceneNormalisation in sparse_unet.h; 0 = the training statistics
  // alone). The heads keep their training statistics.
  Stage1Output PredictAugmented(const ScenePoints& scene, int rotations, bool mirror,
                                bool with_features = false, Stage1Timing* timing = nullptr,
                                double scene_norm = 0.0) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dimr::nn
