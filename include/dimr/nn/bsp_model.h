// BSP-CVAE: the class-conditioned variational shape autoencoder of DIMR (encoder: 3-D conv
// over the occupancy grid + class one-hot -> latent mu, log-variance; decoder: latent +
// class one-hot -> planes; BSP layers: planes -> convexes -> shape). Spec:
// ../shared/reference/dimr-method.md sections 5 and 6. This header is LibTorch-free (pimpl)
// so that the CLI and the pipeline can use the model without compiling torch headers.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "dimr/nn/bsp_dataset.h"

namespace dimr::nn {

struct BspConfig {
  int resolution = 32;     // encoder input grid R (a power of two >= 8)
  int latent_dim = 128;    // dimension of mu (and of log-variance)
  int encoder_width = 32;  // channels of the first encoder conv (doubles per level)
  int num_planes = 1024;   // P
  int num_convexes = 128;  // C
  int num_classes = 8;
  std::vector<int> decoder_widths = {256, 512, 1024};

  // The reference configuration (64^3 input, 128-d latent, 4096 planes, 256 convexes).
  static BspConfig Reference();
  // The CPU-sized default (32^3, 128-d latent, 1024 planes, 128 convexes, decoder 256-512-1024).
  static BspConfig CpuDefault() { return BspConfig(); }
  // Throws dimr::InvalidArgument naming the offending key.
  void Validate() const;
  std::string ToString() const;  // "resolution=32 latent_dim=128 ..."
  static BspConfig FromString(const std::string& text);
};

struct BspTrainOptions {
  // Epochs of the three phases: 0 continuous, 1 discrete, 2 discrete + overlap loss.
  int epochs_phase0 = 60;
  int epochs_phase1 = 30;
  int epochs_phase2 = 0;
  int batch_size = 16;
  int points_per_sample = 1024;  // half inside, half outside, drawn with replacement
  double learning_rate = 1e-4;
  int lr_step_epochs = 200;  // StepLR(step, 0.5) as the reference
  double kl_weight = 0.01;   // beta reached at the end of training (linear annealing)
  // Epochs over which beta rises linearly to kl_weight: < 0 the whole run (the default), 0 a
  // constant beta from the first epoch (fine-tuning a model trained with the same weight).
  int kl_warmup_epochs = -1;
  std::uint64_t seed = 1;
  int threads = 0;              // 0 = library default
  std::string device = "cpu";   // "cpu" or "cuda"
  std::string checkpoint_path;  // written every `checkpoint_every` epochs (and at the end)
  int checkpoint_every = 5;
  bool resume = true;         // continue from checkpoint_path if it exists
  double max_minutes = 0;     // stop (after checkpointing) when exceeded; 0 = no limit
  double phase0_minutes = 0;  // end phase 0 early after this many minutes; 0 = no limit
  // Train the encoder only: the decoder (in inference mode, BatchNorm running statistics) and
  // the convex/union weights stay fixed, so the encoder learns codes the shipped decoder turns
  // into the shapes (amortised latent refinement). Weights of a frozen part are bit-identical
  // after training.
  bool freeze_decoder = false;
  // Decode the sampled z = mu + eps * sigma (the VAE objective, default) or mu itself (the code
  // that inference decodes; the KL term still regularises mu and sigma).
  bool sample_latent = true;
  // Move every plane outwards by this much in the reconstruction loss, as decoding with
  // BspMeshOptions::dilation does (train for the decoding rule that is shipped); 0 = reference.
  double loss_dilation = 0.0;
  // Latent distillation: target codes (rows = training samples in order, latent_dim columns),
  // e.g. the encoder's mu refined on each shape's own occupancy (RefineLatent, the CAD pool).
  // Adds latent_target_weight * mean((mu - target)^2) to the loss, so the encoder learns what
  // refinement finds (amortised refinement). Empty = no targets.
  Eigen::MatrixXf latent_targets;
  double latent_target_weight = 1.0;
  // Weight of the reconstruction term. 0 (only with latent targets and a frozen decoder) skips
  // decoding altogether: the encoder is trained by regression alone, a fraction of the cost.
  double recon_weight = 1.0;
  // Decoding dilation of the validation IoU logged during training (the decoding that is
  // shipped, e.g. the init model card's recommended_dilation); 0 = reference.
  double val_dilation = 0.0;
  double val_distance_dilation = 0.0;
  // Model selection: whenever the logged validation IoU beats every earlier one of the run,
  // the weights are saved here (fp32, loadable by Load) and "<epoch> <iou>" to
  // `best_path + ".txt"` (ReadKeptEpoch). A run resumed from its checkpoint keeps competing
  // with the kept epoch; a fresh run discards both files first. Empty = not kept.
  std::string best_path;
};

// The epoch kept under `best_path` by BspTrainOptions::best_path and its validation IoU;
// false when nothing was kept (or the record is unreadable).
bool ReadKeptEpoch(const std::string& best_path, int* epoch, double* val_iou);

struct BspEpochLog {
  int epoch = 0;  // 1-based over all phases
  int phase = 0;
  double recon_loss = 0;  // reconstruction term (without the weight regularisers)
  double kl = 0;          // KL term (unweighted)
  double latent_mse = 0;  // mean squared distance of mu to its latent target (0 if none)
  double beta = 0;
  double val_iou = -1;  // mean occupancy IoU on the validation points (-1 if no val set)
  double seconds = 0;
};

class BspModel {
 public:
  explicit BspModel(const BspConfig& config = BspConfig(), std::uint64_t seed = 1);
  ~BspModel();
  BspModel(BspModel&&) noexcept;
  BspModel& operator=(BspModel&&) noexcept;

  const BspConfig& config() const;
  int phase() const;

  // Loads a model saved by Save (config, phase and every named tensor are checked; a name or
  // shape mismatch, a truncated or corrupt file gives dimr::ParseError naming the file).
  static BspModel Load(const std::string& path);
  // `half` stores float tensors as fp16 (loaded back as fp32).
  void Save(const std::string& path, bool half = false) const;

  // Trains on `train` (and reports IoU on `val` if not empty). Calls `log` after each epoch.
  std::vector<BspEpochLog> Train(const BspDataset& train, const BspDataset& val,
                                 const BspTrainOptions& options,
                                 const std::function<void(const BspEpochLog&)>& log = {});

  // Encoder in eval mode: (mu, log-variance) of one occupancy grid (R^3, x fastest).
  std::pair<Eigen::VectorXf, Eigen::VectorXf> Encode(const std::vector<std::uint8_t>& grid,
                                                     int cad_class) const;
  // Batched encoding of a whole dataset: rows = samples, columns = [mu, logvar] (2*latent).
  Eigen::MatrixXf EncodeAll(const BspDataset& data) const;
  // Decoder in eval mode: P x 4 plane coefficients (a, b, c, d); inside a plane iff
  // a*x + b*y + c*z + d <= 0.
  Eigen::MatrixXf DecodePlanes(const Eigen::VectorXf& latent, int cad_class) const;
  // DecodePlanes of many codes in one network call: latents B x latent_dim (one mu per row),
  // classes[b] the class of row b. Entry b equals DecodePlanes(row b, classes[b]) up to float
  // rounding (a batched matrix product may sum in another order than a single row's).
  // Throws dimr::InvalidArgument for mismatched sizes, a non-finite code or a bad class.
  std::vector<Eigen::MatrixXf> DecodePlanesBatch(const Eigen::MatrixXf& latents,
                                                 const std::vector<int>& classes) const;
  // For each convex, the planes it uses (convex_layer_weights > 0.01).
  std::vector<std::vector<int>> ConvexPlanes() const;
  // Occupancy (discrete BSP, inside iff min over convexes of the summed plane excess < 0.01)
  // of query points (N x 3) for a latent code.
  // `dilation` moves every plane outwards (BspMeshOptions::dilation; 0 = the reference),
  // `distance_dilation` every face by that Euclidean distance (::distance_dilation).
  std::vector<std::uint8_t> Occupancy(const Eigen::VectorXf& latent, int cad_class,
                                      const Eigen::MatrixX3f& points, double dilation = 0.0,
                                      double distance_dilation = 0.0) const;
  // Mean IoU between decoded (mu) and true occupancy on the grid of cell centres of `data`,
  // decoding with both dilations.
  double EvaluateIoU(const BspDataset& data, double dilation = 0.0,
                     double distance_dilation = 0.0) const;
  // Latent refinement (auto-decoder style, for shapes whose occupancy is known, e.g. the CAD
  // pool): starting from `latent` (mu), `steps` Adam steps (learning rate `lr`) on the
  // discrete-phase reconstruction loss of the sample's inside/outside points, plus
  // prior_weight * mean((z - latent)^2) to stay near the encoder's code. Decoder weights are
  // untouched. Returns the refined mu and the reconstruction loss (inside/outside balanced)
  // before and after. Throws dimr::InvalidArgument for a bad latent size, class, steps < 0,
  // lr <= 0, prior_weight < 0 or a sample without inside or outside points.
  struct Refined {
    Eigen::VectorXf mu;
    double loss_before = 0, loss_after = 0;
  };
  Refined RefineLatent(const Eigen::VectorXf& latent, const BspSample& sample, int steps,
                       double lr = 0.01, double prior_weight = 0.0) const;
  std::int64_t NumParameters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dimr::nn
