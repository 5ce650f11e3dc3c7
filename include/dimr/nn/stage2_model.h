// Stage 2 of DIMR: the proposal-wise network (per-proposal sparse U-Net on the 20^3 grid,
// max-pooling, heads for the confidence score, the latent code [mu, logvar] and the
// class-specific box residuals) with the reference losses and a trainer. Spec:
// ../shared/reference/dimr-method.md section 4 (and 10.2, 11). LibTorch-free header (pimpl).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dimr/nn/stage2_data.h"

namespace dimr::nn {

struct Stage2Config {
  Stage2InputConfig input;  // feature_dim, point_height, grid
  // U-Net levels and residual blocks per level (reference 64,64,96,128 reps 2). The CPU default
  // (the shipped model): 16,32,48,64 reps 1 trains at ~64 proposals/s on this loaded 2-core
  // machine, against ~16/s for 32,48,64,96 and ~10/s for the reference's (docs/stage2.md).
  std::vector<std::int64_t> widths{16, 32, 48, 64};
  int reps = 1;
  int latent_dim = 128;       // mu (and logvar) size: head = 2 * latent_dim
  bool center_height = true;  // append the proposal centre's height above the floor to the pool
  static Stage2Config Reference();  // widths 64,64,96,128, reps 2 (feature_dim 16 here)
  void Validate() const;            // throws dimr::InvalidArgument naming the key
  // "features=16 height=1 grid=20 widths=16,32,48,64 reps=1 latent=128 center_height=1"
  std::string ToString() const;
  static Stage2Config FromString(const std::string& text);
  int pooled_dim() const { return static_cast<int>(widths[0]) + 3 + (center_height ? 1 : 0); }
};

struct Stage2TrainOptions {
  int epochs = 60;
  int batch_size = 32;          // proposals per step
  double learning_rate = 1e-3;  // Adam; lr = max(lr0 * decay^progress, 1e-6)
  double lr_decay = 0.1;
  Stage2Augment augment;
  std::vector<float> class_weights;  // 8 entries (Stage2ClassWeights) or empty = 1
  float fg_thresh = 0.75f, bg_thresh = 0.25f;
  std::uint64_t seed = 123;
  int threads = 0;
  std::string device = "cpu";
  std::string checkpoint_path;  // full training state; resumed when it exists (resume)
  int checkpoint_every_steps = 200;
  bool resume = true;
  double max_minutes = 0;   // stop (checkpointed) after this; 0 = no limit
  bool lr_by_time = false;  // schedule progress = max(step fraction, time fraction)
  int validate_every_epochs = 1;
  bool progress = true;  // progress bar with the loss terms on stderr
};

struct Stage2LossTerms {
  double total = 0, score = 0, latent = 0, center = 0, size = 0;
};

struct Stage2StepLog {
  int epoch = 0, step = 0;
  double lr = 0;
  Stage2LossTerms loss;
  double seconds = 0;
  double data_ms = 0, forward_ms = 0, backward_ms = 0;
};

// Network outputs of B proposals (row-major).
struct Stage2Output {
  int batch_size = 0;
  int code_dim = 0;
  std::vector<float> score_logit;  // B
  std::vector<float> code;         // B x code_dim: [mu, logvar]
  std::vector<float> box;    // B x 48: 8 x 3 centre residuals (canonical frame), then 8 x 3 size
  float score(int i) const;  // sigmoid of the logit
  Eigen::VectorXf Code(int i) const;
  Eigen::Vector3f CenterResidual(int i, int cad_class) const;
  Eigen::Vector3f SizeResidual(int i, int cad_class) const;
};

class Stage2Model {
 public:
  explicit Stage2Model(const Stage2Config& config = Stage2Config(), std::uint64_t seed = 1);
  ~Stage2Model();
  Stage2Model(Stage2Model&&) noexcept;
  Stage2Model& operator=(Stage2Model&&) noexcept;

  const Stage2Config& config() const;
  std::int64_t NumParameters() const;

  // Weights + config (float16 with `half`); Load checks config, names, shapes and finiteness and
  // throws dimr::ParseError naming the file.
  void Save(const std::string& path, bool half = false) const;
  static Stage2Model Load(const std::string& path);

  using EpochCallback =
      std::function<std::map<std::string, double>(int epoch, const Stage2Model& model)>;
  // Trains on `train` (frozen stage-1 features). `log` every step, `on_epoch` every
  // validate_every_epochs epochs and at the end (model in eval mode).
  std::vector<Stage2StepLog> Train(const std::vector<Stage2Sample>& train,
                                   const Stage2TrainOptions& options,
                                   const std::function<void(const Stage2StepLog&)>& log = {},
                                   const EpochCallback& on_epoch = {});

  // Loss terms of one batch: eval mode, no gradient (`train_mode` = BatchNorm batch statistics,
  // still no update of anything) - for tests and validation.
  Stage2LossTerms EvaluateLoss(const Stage2Batch& batch) const;
  // One optimisation step on a batch with a persistent Adam state kept in the model (tests:
  // the loss on a fixed batch must decrease). Returns the loss before the step.
  Stage2LossTerms TrainStep(const Stage2Batch& batch, double learning_rate);

  // Inference (eval mode): outputs for every proposal of the batch (targets ignored). Throws
  // dimr::InvalidArgument for an empty batch or a channel count that differs from the config.
  Stage2Output Predict(const Stage2Batch& batch) const;
  // Convenience: batches of up to `chunk` samples.
  Stage2Output Predict(const std::vector<Stage2Sample>& samples, int chunk = 64) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dimr::nn
