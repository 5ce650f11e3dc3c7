// Stage-1 point-wise network of DIMR in LibTorch (include/dimr/nn/stage1_model.h, spec
// dimr-method.md sections 2.3-2.5 and 11).
//
// Deviations from the reference, all deliberate (docs/models.md, "Stage 1"):
//  - Input features are network-frame coordinates (x-y centred, floor at z = 0; stage1_data.h),
//    not absolute ScanNet coordinates.
//  - Training does not zero the heading logits of points *predicted* as non-CAD (the reference
//    does, which gives those points a constant log 12 and no gradient early in training); the
//    heading loss covers every point of a GT CAD instance. (At inference the heading of non-CAD
//    points is never used, so there is nothing to zero.)
//  - The learning rate decays continuously per step: lr0 * decay^(step / total_steps).
#include "dimr/nn/stage1_model.h"

#include <torch/cuda.h>
#include <torch/torch.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/model_archive.h"
#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_unet.h"

namespace dimr::nn {

// ---------------------------------------------------------------------------------------
// Config
// ---------------------------------------------------------------------------------------

Stage1Config Stage1Config::Reference() {
  Stage1Config c;
  c.input.scale = 50;
  c.widths = {32, 32, 64, 64, 96, 96, 128};
  c.reps = 2;
  return c;
}

namespace {

// The text form of a Stage1Config (model archives, --config): one declaration per key.
const config::Fields<Stage1Config>& Stage1ConfigFields() {
  static const config::Fields<Stage1Config> fields =
      config::Fields<Stage1Config>("stage1 config")
          .Number(
              "scale", [](Stage1Config& c) -> double& { return c.input.scale; }, "1/m",
              "voxels per metre (20 = 5 cm)", 1e-6, 1000.0)
          .Flag(
              "rgb", [](Stage1Config& c) -> bool& { return c.input.use_rgb; },
              "feed colours besides xyz")
          .NumberList(
              "widths", [](Stage1Config& c) -> std::vector<std::int64_t>& { return c.widths; },
              "channels", "U-Net level widths", std::int64_t{1}, std::int64_t{4096})
          .Check([](const Stage1Config& c) -> std::string {
            return c.widths.size() > 12 ? "more than 12 levels" : "";
          })
          .Number(
              "reps", [](Stage1Config& c) -> int& { return c.reps; }, "",
              "residual blocks per level and side", 1, 8)
          .Number(
              "classes", [](Stage1Config& c) -> int& { return c.num_classes; }, "",
              "semantic classes", 2, 1000);
  return fields;
}

}  // namespace

void Stage1Config::Validate() const {
  input.Validate();
  Stage1ConfigFields().Validate(*this);
}

std::string Stage1Config::ToString() const { return Stage1ConfigFields().Format(*this); }

Stage1Config Stage1Config::FromString(const std::string& text) {
  const Stage1Config c = Stage1ConfigFields().Parse(text);
  c.Validate();
  return c;
}

// ---------------------------------------------------------------------------------------
// Network
// ---------------------------------------------------------------------------------------

namespace {

torch::nn::BatchNorm1d HeadNorm(int64_t c) {
  return torch::nn::BatchNorm1d(torch::nn::BatchNorm1dOptions(c).eps(1e-4).momentum(0.1));
}

struct HeadOutput {
  torch::Tensor semantic;  // [N, 25] logits
  torch::Tensor offset;    // [N, 3]
  torch::Tensor heading;   // [N, 24]: 12 bin logits, 12 normalised residuals
  torch::Tensor features;  // [N, C0]
};

class Stage1NetImpl : public torch::nn::Module {
 public:
  explicit Stage1NetImpl(const Stage1Config& c) {
    SparseUNetConfig u;
    u.in_channels = c.input.feature_channels();
    u.widths = c.widths;
    u.reps = c.reps;
    backbone = register_module("backbone", SparseUNet(u));
    const int64_t c0 = c.widths[0];
    linear = register_module("linear", torch::nn::Linear(c0, c.num_classes));
    offset = register_module(
        "offset", torch::nn::Sequential(
                      torch::nn::Linear(c0, 16), HeadNorm(16),
                      torch::nn::LeakyReLU(torch::nn::LeakyReLUOptions().negative_slope(0.01))));
    offset_linear = register_module("offset_linear", torch::nn::Linear(16, 3));
    angle = register_module(
        "angle", torch::nn::Sequential(
                     torch::nn::Linear(c0, c0), HeadNorm(c0),
                     torch::nn::LeakyReLU(torch::nn::LeakyReLUOptions().negative_slope(0.01))));
    angle_linear = register_module("angle_linear", torch::nn::Linear(c0, 2 * kHeadingBins));
  }

  HeadOutput Heads(const torch::Tensor& f) {
    HeadOutput h;
    h.features = f;
    h.semantic = linear->forward(f);
    h.offset = offset_linear->forward(offset->forward(f));
    h.heading = angle_linear->forward(angle->forward(f));
    return h;
  }

  // The heads at inference (eval mode only): Linear -> BatchNorm -> LeakyReLU folded into one
  // addmm per MLP (W' = diag(g / sqrt(var + eps)) W, b' = (b - mean) g / sqrt(var + eps) +
  // beta), the same function as Heads() up to float rounding and one op instead of three.
  HeadOutput HeadsFolded(const torch::Tensor& f) {
    auto mlp = [&](torch::nn::Sequential& seq, torch::nn::Linear& last) {
      auto lin = seq[0]->as<torch::nn::Linear>();
      auto bn = seq[1]->as<torch::nn::BatchNorm1d>();
      const torch::Tensor k = bn->weight / torch::sqrt(bn->running_var + bn->options.eps());
      const torch::Tensor w = lin->weight * k.unsqueeze(1);
      const torch::Tensor b = (lin->bias - bn->running_mean) * k + bn->bias;
      const torch::Tensor hidden = torch::leaky_relu(torch::addmm(b, f, w.t()), 0.01);
      return last->forward(hidden);
    };
    HeadOutput h;
    h.features = f;
    h.semantic = linear->forward(f);
    h.offset = mlp(offset, offset_linear);
    h.heading = mlp(angle, angle_linear);
    return h;
  }

  SparseUNet backbone{nullptr};
  torch::nn::Linear linear{nullptr}, offset_linear{nullptr}, angle_linear{nullptr};
  torch::nn::Sequential offset{nullptr}, angle{nullptr};
};
TORCH_MODULE(Stage1Net);

template <typename T>
torch::Tensor FromVector(const std::vector<T>& v, torch::Dtype dtype, std::vector<int64_t> shape) {
  if (v.empty()) return torch::zeros(shape, torch::TensorOptions().dtype(dtype));
  return torch::from_blob(const_cast<T*>(v.data()), shape, torch::TensorOptions().dtype(dtype))
      .clone();
}

struct BatchTensors {
  torch::Tensor voxel, features, semantic, offset_target, offset_valid, heading_bin,
      heading_residual;
  int64_t batch_size = 0;
};

BatchTensors ToTensors(const Stage1Batch& b, const torch::Device& device) {
  const int64_t n = b.num_points();
  if (n == 0) throw InvalidArgument("stage1: empty batch (no points)");
  if (static_cast<int64_t>(b.voxel.size()) != 4 * n ||
      static_cast<int64_t>(b.features.size()) != n * b.feature_channels ||
      static_cast<int64_t>(b.offset_target.size()) != 3 * n ||
      static_cast<int64_t>(b.offset_valid.size()) != n ||
      static_cast<int64_t>(b.heading_bin.size()) != n ||
      static_cast<int64_t>(b.heading_residual.size()) != n) {
    throw InvalidArgument("stage1: inconsistent batch array sizes");
  }
  BatchTensors t;
  t.batch_size = b.batch_size;
  t.voxel = FromVector(b.voxel, torch::kInt32, {n, 4});
  t.features = FromVector(b.features, torch::kFloat32, {n, b.feature_channels}).to(device);
  t.semantic = FromVector(b.semantic, torch::kInt64, {n}).to(device);
  t.offset_target = FromVector(b.offset_target, torch::kFloat32, {n, 3}).to(device);
  t.offset_valid = FromVector(b.offset_valid, torch::kUInt8, {n}).to(torch::kFloat32).to(device);
  t.heading_bin = FromVector(b.heading_bin, torch::kInt64, {n}).to(device);
  t.heading_residual = FromVector(b.heading_residual, torch::kFloat32, {n}).to(device);
  return t;
}

struct LossOut {
  torch::Tensor total;
  Stage1LossTerms terms;
};

// class_weight: [num_classes] or undefined (unweighted).
LossOut ComputeLoss(const HeadOutput& h, const BatchTensors& t,
                    const torch::Tensor& class_weight = {}) {
  LossOut out;
  // Semantic cross-entropy, ignore -100, (weighted) mean over the labelled points.
  torch::Tensor sem;
  if ((t.semantic != kStage1Ignore).any().item<bool>()) {
    auto options = torch::nn::functional::CrossEntropyFuncOptions().ignore_index(kStage1Ignore);
    if (class_weight.defined()) options.weight(class_weight);
    sem = torch::nn::functional::cross_entropy(h.semantic, t.semantic, options);
  } else {
    sem = h.semantic.sum() * 0;
  }
  // Offsets: L1 norm and negative cosine over points of any instance.
  const torch::Tensor valid = t.offset_valid;
  const torch::Tensor denom = valid.sum() + 1e-6;
  const torch::Tensor off_norm = ((h.offset - t.offset_target).abs().sum(1) * valid).sum() / denom;
  const torch::Tensor pred_dir = h.offset / (h.offset.norm(2, 1, true) + 1e-8);
  const torch::Tensor gt_dir = t.offset_target / (t.offset_target.norm(2, 1, true) + 1e-8);
  const torch::Tensor off_dir = -((pred_dir * gt_dir).sum(1) * valid).sum() / denom;
  // Heading: bin CE + smooth-L1 residual of the GT bin, over points of CAD-box instances.
  const torch::Tensor ang_valid = (t.heading_bin != kStage1Ignore).to(torch::kFloat32);
  const torch::Tensor ang_denom = ang_valid.sum() + 1e-6;
  const torch::Tensor bins = t.heading_bin.clamp_min(0);
  const torch::Tensor logits = h.heading.slice(1, 0, kHeadingBins);
  const torch::Tensor residuals = h.heading.slice(1, kHeadingBins, 2 * kHeadingBins);
  const torch::Tensor ce = torch::nn::functional::cross_entropy(
      logits, bins, torch::nn::functional::CrossEntropyFuncOptions().reduction(torch::kNone));
  const torch::Tensor ang_cls = (ce * ang_valid).sum() / ang_denom;
  const torch::Tensor res = residuals.gather(1, bins.unsqueeze(1)).squeeze(1);
  const torch::Tensor sl1 = torch::nn::functional::smooth_l1_loss(
      res, t.heading_residual,
      torch::nn::functional::SmoothL1LossFuncOptions().reduction(torch::kNone));
  const torch::Tensor ang_res = (sl1 * ang_valid).sum() / ang_denom;
  out.total = sem + off_norm + off_dir + ang_cls + ang_res;
  out.terms.semantic = sem.item<double>();
  out.terms.offset_norm = off_norm.item<double>();
  out.terms.offset_dir = off_dir.item<double>();
  out.terms.heading_cls = ang_cls.item<double>();
  out.terms.heading_res = ang_res.item<double>();
  out.terms.total = out.total.item<double>();
  return out;
}

double Ms(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Stage1Model
// ---------------------------------------------------------------------------------------

std::vector<float> SemanticClassWeights(const std::vector<Stage1Sample>& samples, int num_classes,
                                        double min_w, double max_w, double power) {
  if (num_classes < 1) throw InvalidArgument("SemanticClassWeights: num_classes must be >= 1");
  if (!(power > 0 && power <= 2))
    throw InvalidArgument("SemanticClassWeights: need 0 < power <= 2");
  if (!(min_w > 0 && min_w <= max_w)) {
    throw InvalidArgument("SemanticClassWeights: need 0 < min_w <= max_w");
  }
  std::vector<double> count(num_classes, 0.0);
  double total = 0;
  for (const auto& s : samples) {
    for (int c : s.semantic) {
      if (c >= 0 && c < num_classes) {
        count[c] += 1;
        total += 1;
      }
    }
  }
  std::vector<float> w(num_classes, 1.0f);
  std::vector<double> present;
  for (double n : count) {
    if (n > 0) present.push_back(n / total);
  }
  if (present.empty()) return w;
  std::sort(present.begin(), present.end());
  const std::size_t m = present.size();
  const double median = m % 2 ? present[m / 2] : 0.5 * (present[m / 2 - 1] + present[m / 2]);
  for (int c = 0; c < num_classes; ++c) {
    if (count[c] > 0) {
      w[c] = static_cast<float>(
          std::clamp(std::pow(median / (count[c] / total), power), min_w, max_w));
    }
  }
  return w;
}

std::string SparseKernelsInUse() { return SparseKernelPathName(ResolveSparseKernelPath()); }

void SetIntraOpThreads(int threads) {
  if (threads < 1) throw InvalidArgument("threads must be >= 1, got " + std::to_string(threads));
  torch::set_num_threads(threads);
}

struct Stage1Model::Impl {
  Stage1Config config;
  Stage1Net net{nullptr};
  torch::Device device = torch::kCPU;
  explicit Impl(const Stage1Config& c) : config(c), net(c) {}

  // The U-Net on voxelised points; `voxel_heads` runs the heads on its voxel rows (inference)
  // instead of the gathered point rows (training: BatchNorm statistics are per point).
  struct Pass {
    HeadOutput h;                  // [N, ...] point rows, or [M, ...] voxel rows
    torch::Tensor point_to_voxel;  // [N] int64, CPU (voxel heads only)
  };
  Pass Run(const torch::Tensor& voxel, const torch::Tensor& features, int64_t batch_size,
           bool voxel_heads, Stage1Timing* timing) {
    const auto t0 = std::chrono::steady_clock::now();
    // Every U-Net level halves the grid (k2 s2): at least 2^(levels - 1) voxels per axis, or a
    // flat room (1.37 m high at 5 cm: 28 voxels for 6 levels), a plane or one point could not
    // be down-sampled to the last level. Padding adds no sites, so wider grids are unchanged.
    const int64_t min_extent = int64_t{1} << (config.widths.size() - 1);
    Voxelized v = Voxelize(voxel, features, batch_size, {min_extent, min_extent, min_extent});
    const auto t1 = std::chrono::steady_clock::now();
    v.tensor.context()->BuildKernelMaps(static_cast<int>(config.widths.size()));
    const auto t1b = std::chrono::steady_clock::now();
    const SparseTensor y = net->backbone->forward(v.tensor);
    const auto t2 = std::chrono::steady_clock::now();
    Pass pass;
    if (voxel_heads) {
      pass.h = net->HeadsFolded(y.features());
      pass.point_to_voxel = v.map.point_to_voxel.to(torch::kCPU).to(torch::kInt64).contiguous();
    } else {
      pass.h = net->Heads(Devoxelize(y.features(), v.map));
    }
    if (timing) {
      const auto t3 = std::chrono::steady_clock::now();
      timing->voxelize_ms = Ms(t0, t1);
      timing->kernel_map_ms = Ms(t1, t1b);
      timing->unet_ms = Ms(t1b, t2);
      timing->heads_ms = Ms(t2, t3);
    }
    return pass;
  }

  HeadOutput Forward(const BatchTensors& t, Stage1Timing* timing) {
    return Run(t.voxel, t.features, t.batch_size, /*voxel_heads=*/false, timing).h;
  }

  // One network pass on a scene view (eval mode, no gradient: the caller's guard), with the
  // heads run on the voxels instead of the points. Devoxelize is a gather and every head is a
  // row-wise function of its input (eval-mode BatchNorm uses the running statistics), so a
  // point's outputs are its voxel's row: the same numbers as heads on the gathered point
  // features, for ~3-5x fewer rows at 5 cm (a 100k-point room has ~25k voxels).
  Pass ForwardSceneVoxels(const ScenePoints& scene, Stage1Timing* timing, NetworkFrame* frame) {
    const Stage1NetworkInput in = MakeStage1NetworkInput(scene, config.input);
    *frame = in.frame;
    const int64_t n = static_cast<int64_t>(scene.size);
    return Run(FromVector(in.voxel, torch::kInt32, {n, 4}),
               FromVector(in.features, torch::kFloat32, {n, in.feature_channels}).to(device), 1,
               /*voxel_heads=*/true, timing);
  }
};

Stage1Model::Stage1Model(const Stage1Config& config, std::uint64_t seed) {
  config.Validate();
  torch::manual_seed(seed);
  impl_ = std::make_unique<Impl>(config);
  impl_->net->eval();
}
Stage1Model::~Stage1Model() = default;
Stage1Model::Stage1Model(Stage1Model&&) noexcept = default;
Stage1Model& Stage1Model::operator=(Stage1Model&&) noexcept = default;

const Stage1Config& Stage1Model::config() const { return impl_->config; }

std::int64_t Stage1Model::NumParameters() const {
  std::int64_t n = 0;
  for (const auto& p : impl_->net->parameters()) n += p.numel();
  return n;
}

void Stage1Model::Save(const std::string& path, bool half) const {
  SaveModelArchive(*impl_->net, path, "stage1", impl_->config.ToString(), half);
}

Stage1Model Stage1Model::Load(const std::string& path) {
  const ModelArchiveReader archive(path, "stage1", "stage-1");
  Stage1Config config;
  try {
    config = Stage1Config::FromString(archive.config());
  } catch (const InvalidArgument& e) {
    throw ParseError(path, e.what());
  }
  Stage1Model model(config);
  archive.LoadInto(*model.impl_->net);
  return model;
}

Stage1Model Stage1Model::Average(const std::vector<std::string>& paths) {
  if (paths.empty()) throw InvalidArgument("stage1 average: no model files given");
  Stage1Model mean = Load(paths[0]);
  if (paths.size() == 1) return mean;
  torch::NoGradGuard no_grad;
  const std::string config = mean.config().ToString();
  auto floating = [](const torch::nn::Module& m) {
    std::vector<torch::Tensor> out;
    for (const auto& p : m.parameters()) out.push_back(p);
    for (const auto& b : m.buffers()) {
      if (b.is_floating_point()) out.push_back(b);
    }
    return out;
  };
  std::vector<torch::Tensor> target = floating(*mean.impl_->net);  // written in place
  std::vector<torch::Tensor> acc;                                  // double sums
  for (const auto& t : target) acc.push_back(t.to(torch::kDouble));
  for (std::size_t i = 1; i < paths.size(); ++i) {
    const Stage1Model other = Load(paths[i]);
    if (other.config().ToString() != config) {
      throw InvalidArgument("stage1 average: '" + paths[i] + "' has configuration '" +
                            other.config().ToString() + "', '" + paths[0] + "' has '" + config +
                            "'");
    }
    const std::vector<torch::Tensor> t = floating(*other.impl_->net);
    for (std::size_t k = 0; k < acc.size(); ++k) acc[k] += t[k].to(torch::kDouble);
  }
  const double n = static_cast<double>(paths.size());
  for (std::size_t k = 0; k < acc.size(); ++k) target[k].copy_((acc[k] / n).to(target[k].dtype()));
  return mean;
}

Stage1LossTerms Stage1Model::EvaluateLoss(const Stage1Batch& batch) const {
  torch::NoGradGuard no_grad;
  const bool was_training = impl_->net->is_training();
  impl_->net->eval();
  const BatchTensors t = ToTensors(batch, impl_->device);
  const HeadOutput h = impl_->Forward(t, nullptr);
  const LossOut l = ComputeLoss(h, t);
  if (was_training) impl_->net->train();
  return l.terms;
}

Stage1Output Stage1Model::Predict(const Stage1Sample& sample, bool with_features,
                                  Stage1Timing* timing) const {
  if (impl_->config.input.use_rgb && sample.colors.size() != sample.points.size()) {
    throw InvalidArgument("stage1 predict: the model uses colour but scene '" + sample.name +
                          "' has " + std::to_string(sample.colors.size()) + " colours for " +
                          std::to_string(sample.points.size()) + " points");
  }
  return Predict(ScenePoints(sample.points, &sample.colors, sample.name), with_features, timing);
}

Stage1Output Stage1Model::PredictAugmented(const Stage1Sample& sample, int rotations, bool mirror,
                                           bool with_features, Stage1Timing* timing) const {
  if (impl_->config.input.use_rgb && sample.colors.size() != sample.points.size()) {
    throw InvalidArgument("stage1 predict: the model uses colour but scene '" + sample.name +
                          "' has " + std::to_string(sample.colors.size()) + " colours for " +
                          std::to_string(sample.points.size()) + " points");
  }
  return PredictAugmented(ScenePoints(sample.points, &sample.colors, sample.name), rotations,
                          mirror, with_features, timing);
}

namespace {

// The network's outputs of one pass on the CPU, contiguous: semantic softmax N x C, offsets
// N x 3, heading bin softmax and residuals N x 12 each.
struct PassTensors {
  torch::Tensor prob, offset, heading_prob, heading_residual;
};

// dst[j] += src[j] (vectorised: the arrays never overlap).
void AddRow(float* __restrict dst, const float* __restrict src, int count) {
  for (int j = 0; j < count; ++j) dst[j] += src[j];
}

PassTensors ToPassTensors(const HeadOutput& h) {
  PassTensors p;
  p.prob = torch::softmax(h.semantic, 1).to(torch::kCPU).contiguous();
  p.offset = h.offset.to(torch::kCPU).contiguous();
  // (softmax of a contiguous copy: on the strided slice it is several times slower)
  p.heading_prob = torch::softmax(h.heading.slice(1, 0, kHeadingBins).contiguous(), 1)
                       .to(torch::kCPU)
                       .contiguous();
  p.heading_residual =
      h.heading.slice(1, kHeadingBins, 2 * kHeadingBins).to(torch::kCPU).contiguous();
  return p;
}

}  // namespace

Stage1Output Stage1Model::Predict(const ScenePoints& scene, bool with_features,
                                  Stage1Timing* timing) const {
  return PredictAugmented(scene, 1, false, with_features, timing);
}

Stage1Output Stage1Model::PredictAugmented(const ScenePoints& scene, int rotations, bool mirror,
                                           bool with_features, Stage1Timing* timing) const {
  if (rotations < 1 || kHeadingBins % rotations != 0) {
    throw InvalidArgument("stage1 predict: rotations must divide " + std::to_string(kHeadingBins) +
                          " (1, 2, 3, 4, 6, 12), got " + std::to_string(rotations));
  }
  torch::NoGradGuard no_grad;
  impl_->net->eval();
  Stage1Timing local;
  Stage1Output out;
  const std::size_t n = scene.size;
  const int nc = impl_->config.num_classes;
  // Every pass is mapped back to the input frame on its voxel rows (M, a few times fewer
  // than the points) into one row per voxel: [semantic prob (nc) | heading prob (12) |
  // heading residual (12) | offset (3)]; each point then adds its voxel's row to its own
  // row of one N x row accumulator, split into `out` at the end. The gather of voxel rows
  // is bound by memory latency (a pass's voxel rows are ~5 MB, in another order than the
  // points): the rows a few points ahead are prefetched.
  const int off_sem = 0, off_hp = nc, off_hr = nc + kHeadingBins, off_o = nc + 2 * kHeadingBins;
  const int row = off_o + 3;
  std::vector<float> acc;
  std::vector<float> vrow;
  // Adds one pass. A heading h of the input is sign * h (+ pi if mirrored) + theta in the
  // pass's scene: bin b here is bin (m * 6 + sign * b + shift) there, residual times sign;
  // offsets are rotated back by -theta, then mirrored.
  auto add_pass = [&](const Impl::Pass& pass, int m, int k, bool first) {
    const PassTensors p = ToPassTensors(pass.h);
    const int64_t mv = p.prob.size(0);
    const float* rp = p.prob.data_ptr<float>();
    const float* ro = p.offset.data_ptr<float>();
    const float* rhb = p.heading_prob.data_ptr<float>();
    const float* rhr = p.heading_residual.data_ptr<float>();
    const double sign = m == 1 ? -1.0 : 1.0;
    const double theta = 2.0 * M_PI * k / rotations;
    const double c = std::cos(theta), s = std::sin(theta);
    const int shift = kHeadingBins * k / rotations;
    int to[kHeadingBins];
    for (int b = 0; b < kHeadingBins; ++b) {
      to[b] = ((m * kHeadingBins / 2 + (m == 1 ? -b : b) + shift) % kHeadingBins + kHeadingBins) %
              kHeadingBins;
    }
    const float fsign = static_cast<float>(sign);
    vrow.resize(static_cast<std::size_t>(mv) * row);
    for (int64_t v = 0; v < mv; ++v) {
      float* r = vrow.data() + v * row;
      std::copy_n(rp + v * nc, nc, r + off_sem);
      const float* rhbi = rhb + v * kHeadingBins;
      const float* rhri = rhr + v * kHeadingBins;
      for (int b = 0; b < kHeadingBins; ++b) {
        r[off_hp + b] = rhbi[to[b]];
        r[off_hr + b] = fsign * rhri[to[b]];
      }
      const double ox = ro[3 * v], oy = ro[3 * v + 1];
      r[off_o] = static_cast<float>(sign * (c * ox + s * oy));
      r[off_o + 1] = static_cast<float>(-s * ox + c * oy);
      r[off_o + 2] = ro[3 * v + 2];
    }
    const int64_t* p2v = pass.point_to_voxel.data_ptr<int64_t>();
    float* __restrict a = acc.data();
    const float* __restrict src = vrow.data();
    constexpr std::size_t kAhead = 16;
    for (std::size_t i = 0; i < n; ++i) {
      if (i + kAhead < n) {
        const float* ahead = src + p2v[i + kAhead] * row;
        for (int j = 0; j < row; j += 16) __builtin_prefetch(ahead + j);
        __builtin_prefetch(ahead + row - 1);
      }
      if (first) {
        std::copy_n(src + p2v[i] * row, row, a + i * row);
      } else {
        AddRow(a + i * row, src + p2v[i] * row, row);
      }
    }
  };
  acc.resize(n * row);
  {
    const Impl::Pass pass = impl_->ForwardSceneVoxels(scene, &local, &out.frame);
    const auto t0 = std::chrono::steady_clock::now();
    add_pass(pass, 0, 0, /*first=*/true);
    if (with_features) {
      const torch::Tensor f = pass.h.features.to(torch::kCPU).contiguous();
      const int64_t c0 = f.size(1);
      const float* pf = f.data_ptr<float>();
      const int64_t* p2v = pass.point_to_voxel.data_ptr<int64_t>();
      out.features.resize(n * c0);
      for (std::size_t i = 0; i < n; ++i) {
        std::copy_n(pf + p2v[i] * c0, c0, out.features.data() + i * c0);
      }
    }
    local.heads_ms += Ms(t0, std::chrono::steady_clock::now());
  }
  int passes = 1;
  if (rotations > 1 || mirror) {
    // Every further pass runs on the moved points (one buffer, colours shared).
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < n; ++i) centre += scene.points[i].head<2>().cast<double>();
    centre /= static_cast<double>(n);
    std::vector<Eigen::Vector3f> moved(n);
    ScenePoints view = scene;
    view.points = moved.data();
    for (int m = 0; m < (mirror ? 2 : 1); ++m) {
      const double sign = m == 1 ? -1.0 : 1.0;  // x -> sign * x before the rotation
      for (int k = 0; k < rotations; ++k) {
        if (k == 0 && m == 0) continue;  // the plain pass above
        const double theta = 2.0 * M_PI * k / rotations;
        const double c = std::cos(theta), s = std::sin(theta);
        for (std::size_t i = 0; i < n; ++i) {
          const double x = sign * (scene.points[i].x() - centre.x());
          const double y = scene.points[i].y() - centre.y();
          moved[i] =
              Eigen::Vector3f(static_cast<float>(centre.x() + c * x - s * y),
                              static_cast<float>(centre.y() + s * x + c * y), scene.points[i].z());
        }
        Stage1Timing t;
        NetworkFrame unused;
        const Impl::Pass pass = impl_->ForwardSceneVoxels(view, &t, &unused);
        const auto t0 = std::chrono::steady_clock::now();
        add_pass(pass, m, k, /*first=*/false);
        ++passes;
        t.heads_ms += Ms(t0, std::chrono::steady_clock::now());
        local.voxelize_ms += t.voxelize_ms;
        local.kernel_map_ms += t.kernel_map_ms;
        local.unet_ms += t.unet_ms;
        local.heads_ms += t.heads_ms;
      }
    }
  }
  // Means and the split into `out`.
  const auto t0 = std::chrono::steady_clock::now();
  const float inv = 1.0f / static_cast<float>(passes);
  out.semantic_prob.resize(n * nc);
  out.heading_prob.resize(n * kHeadingBins);
  out.heading_residual.resize(n * kHeadingBins);
  out.offsets.resize(n);
  out.semantic.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float* a = acc.data() + i * row;
    float* sp = out.semantic_prob.data() + i * nc;
    for (int j = 0; j < nc; ++j) sp[j] = a[off_sem + j] * inv;
    float* hp = out.heading_prob.data() + i * kHeadingBins;
    float* hr = out.heading_residual.data() + i * kHeadingBins;
    for (int b = 0; b < kHeadingBins; ++b) {
      hp[b] = a[off_hp + b] * inv;
      hr[b] = a[off_hr + b] * inv;
    }
    out.offsets[i] = Eigen::Vector3f(a[off_o], a[off_o + 1], a[off_o + 2]) * inv;
    out.semantic[i] = static_cast<int>(std::max_element(sp, sp + nc) - sp);
  }
  local.heads_ms += Ms(t0, std::chrono::steady_clock::now());
  if (timing) *timing = local;
  return out;
}

// ---------------------------------------------------------------------------------------
// Training
// ---------------------------------------------------------------------------------------

std::vector<Stage1StepLog> Stage1Model::Train(const std::vector<Stage1Sample>& train,
                                              const Stage1TrainOptions& opt,
                                              const std::function<void(const Stage1StepLog&)>& log,
                                              const EpochCallback& on_epoch) {
  if (train.empty()) throw InvalidArgument("stage1 train: no training scenes");
  if (opt.epochs < 1) throw InvalidArgument("stage1 train: 'epochs' must be >= 1");
  if (opt.batch_size < 1) throw InvalidArgument("stage1 train: 'batch_size' must be >= 1");
  if (!(opt.learning_rate > 0)) throw InvalidArgument("stage1 train: 'learning_rate' must be > 0");
  if (!(opt.lr_decay > 0 && opt.lr_decay <= 1)) {
    throw InvalidArgument("stage1 train: 'lr_decay' must be in (0, 1]");
  }
  opt.augment.Validate();
  if (opt.threads > 0) torch::set_num_threads(opt.threads);
  if (opt.device == "cuda") {
    if (!torch::cuda::is_available()) {
      throw InvalidArgument("stage1 train: device 'cuda' requested but not available");
    }
    impl_->device = torch::Device(torch::kCUDA);
  } else if (opt.device != "cpu") {
    throw InvalidArgument("stage1 train: unknown device '" + opt.device + "' (cpu or cuda)");
  }
  auto& net = impl_->net;
  net->to(impl_->device);

  torch::Tensor class_weight;
  if (!opt.class_weights.empty()) {
    if (static_cast<int>(opt.class_weights.size()) != impl_->config.num_classes) {
      throw InvalidArgument("stage1 train: class_weights has " +
                            std::to_string(opt.class_weights.size()) + " entries for " +
                            std::to_string(impl_->config.num_classes) + " classes");
    }
    for (float w : opt.class_weights) {
      if (!(w > 0) || !std::isfinite(w)) {
        throw InvalidArgument("stage1 train: class weights must be finite and > 0");
      }
    }
    class_weight = FromVector(opt.class_weights, torch::kFloat32,
                              {static_cast<int64_t>(opt.class_weights.size())})
                       .to(impl_->device);
  }
  const int batch_size = std::min<int>(opt.batch_size, static_cast<int>(train.size()));
  Stage1Loader loader(&train, impl_->config.input, opt.augment, batch_size, opt.seed,
                      std::max(1, opt.loader_threads));
  const int per_epoch = loader.batches_per_epoch();
  const int64_t total_steps = static_cast<int64_t>(per_epoch) * opt.epochs;

  torch::optim::Adam optimizer(net->parameters(), torch::optim::AdamOptions(opt.learning_rate));
  int64_t step = 0;  // completed steps
  const std::vector<int64_t> resumed =
      opt.resume ? ResumeTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "stage1",
                                            "stage-1", impl_->config.ToString(), 2)
                 : std::vector<int64_t>{};
  if (!resumed.empty()) {
    step = resumed[0];
    if (step < 0) throw ParseError(opt.checkpoint_path + ".state", "negative step");
    if (resumed[1] != per_epoch) {
      std::fprintf(stderr,
                   "warning: %s: %lld batches per epoch before, %d now (other data or batch "
                   "size); continuing at step %lld\n",
                   opt.checkpoint_path.c_str(), static_cast<long long>(resumed[1]), per_epoch,
                   static_cast<long long>(step));
    }
    std::fprintf(stderr, "resuming from %s at step %lld\n", opt.checkpoint_path.c_str(),
                 static_cast<long long>(step));
  }

  auto checkpoint = [&]() {
    if (opt.checkpoint_path.empty()) return;
    SaveTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "stage1", impl_->config.ToString(),
                           {step, per_epoch});
  };
  auto run_epoch_callback = [&](int epoch) {
    if (!on_epoch) return;
    net->eval();
    const auto saved_device = impl_->device;
    const auto metrics = on_epoch(epoch, *this);
    impl_->device = saved_device;
    if (!metrics.empty()) {
      std::fprintf(stderr, "\nepoch %d:", epoch);
      for (const auto& [k, v] : metrics) std::fprintf(stderr, " %s=%.4f", k.c_str(), v);
      std::fprintf(stderr, "\n");
    }
  };

  std::vector<Stage1StepLog> logs;
  const auto t_start = std::chrono::steady_clock::now();
  auto elapsed_s = [&]() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  };
  Stage1LossTerms running;
  int running_n = 0;
  std::array<double, 3> running_ms{0, 0, 0};  // data, forward (+ loss), backward (+ optimiser)
  bool out_of_time = false;
  while (step < total_steps && !out_of_time) {
    const int epoch = static_cast<int>(step / per_epoch);  // 0-based
    const int first = static_cast<int>(step % per_epoch);
    loader.StartEpoch(epoch, first);
    net->train();
    Stage1Batch batch;
    auto t_wait = std::chrono::steady_clock::now();
    while (step < total_steps && loader.Next(&batch)) {
      const auto t_data = std::chrono::steady_clock::now();
      double progress = static_cast<double>(step) / static_cast<double>(total_steps);
      if (opt.lr_by_time && opt.max_minutes > 0) {
        progress = std::min(1.0, std::max(progress, elapsed_s() / (60.0 * opt.max_minutes)));
      }
      const double lr = std::max(opt.learning_rate * std::pow(opt.lr_decay, progress), 1e-6);
      for (auto& group : optimizer.param_groups()) {
        static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
      }
      const BatchTensors t = ToTensors(batch, impl_->device);
      optimizer.zero_grad();
      Stage1Timing timing;
      const HeadOutput h = impl_->Forward(t, &timing);
      const auto t_fwd = std::chrono::steady_clock::now();
      LossOut l = ComputeLoss(h, t, class_weight);
      if (!std::isfinite(l.terms.total)) {
        throw Error("stage1 train: the loss became non-finite at step " + std::to_string(step + 1) +
                    " (batch " + batch.names.front() + "...); lower the learning rate");
      }
      const auto t_loss = std::chrono::steady_clock::now();
      const bool cuda = impl_->device.is_cuda();
      l.total.backward();
      if (cuda) torch::cuda::synchronize();
      const auto t_bwd = std::chrono::steady_clock::now();
      optimizer.step();
      if (cuda) torch::cuda::synchronize();
      const auto t_opt = std::chrono::steady_clock::now();
      ++step;
      Stage1StepLog s;
      s.data_ms = Ms(t_wait, t_data);
      s.voxelize_ms = timing.voxelize_ms;
      s.kernel_map_ms = timing.kernel_map_ms;
      s.unet_ms = timing.unet_ms;
      s.loss_ms = timing.heads_ms + Ms(t_fwd, t_loss);
      s.backward_ms = Ms(t_loss, t_bwd);
      s.optimizer_ms = Ms(t_bwd, t_opt);
      s.epoch = epoch + 1;
      s.step = static_cast<int>(step);
      s.lr = lr;
      s.loss = l.terms;
      s.seconds = elapsed_s();
      logs.push_back(s);
      if (log) log(s);
      running.total += l.terms.total;
      running.semantic += l.terms.semantic;
      running.offset_norm += l.terms.offset_norm;
      running.offset_dir += l.terms.offset_dir;
      running.heading_cls += l.terms.heading_cls;
      running.heading_res += l.terms.heading_res;
      ++running_n;
      running_ms[0] += s.data_ms;
      running_ms[1] += s.voxelize_ms + s.kernel_map_ms + s.unet_ms + s.loss_ms;
      running_ms[2] += s.backward_ms + s.optimizer_ms;
      if (opt.progress) {
        const double k = 1.0 / running_n;
        const int in_epoch = static_cast<int>((step - 1) % per_epoch) + 1;
        std::fprintf(stderr,
                     "\r[epoch %d/%d %4d/%d] loss %.3f sem %.3f off %.3f dir %.3f hcls %.3f "
                     "hres %.3f lr %.1e %.2f s/it (data %.0f fwd %.0f bwd %.0f ms)   ",
                     epoch + 1, opt.epochs, in_epoch, per_epoch, running.total * k,
                     running.semantic * k, running.offset_norm * k, running.offset_dir * k,
                     running.heading_cls * k, running.heading_res * k, lr,
                     s.seconds / std::max<double>(1, static_cast<double>(logs.size())),
                     running_ms[0] * k, running_ms[1] * k, running_ms[2] * k);
        std::fflush(stderr);
      }
      if (opt.checkpoint_every_steps > 0 && step % opt.checkpoint_every_steps == 0) checkpoint();
      t_wait = std::chrono::steady_clock::now();
      if (opt.max_minutes > 0 && elapsed_s() / 60.0 >= opt.max_minutes) {
        out_of_time = true;
        break;
      }
    }
    const bool epoch_done = step % per_epoch == 0 || step >= total_steps;
    if (epoch_done) {
      running = Stage1LossTerms();
      running_n = 0;
      running_ms = {0, 0, 0};
      const int finished = static_cast<int>((step + per_epoch - 1) / per_epoch);
      const bool last = step >= total_steps;
      checkpoint();
      if (last || (opt.validate_every_epochs > 0 && finished % opt.validate_every_epochs == 0)) {
        run_epoch_callback(finished);
      }
    }
  }
  if (out_of_time) {
    checkpoint();
    std::fprintf(stderr, "\ntime budget of %.1f min reached at step %lld\n", opt.max_minutes,
                 static_cast<long long>(step));
    run_epoch_callback(static_cast<int>((step + per_epoch - 1) / per_epoch));
  }
  if (opt.progress) std::fprintf(stderr, "\n");
  net->eval();
  return logs;
}

}  // namespace dimr::nn
