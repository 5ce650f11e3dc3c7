// Stage-2 proposal-wise network of DIMR in LibTorch (include/dimr/nn/stage2_model.h, spec
// dimr-method.md section 4). Module names follow the reference (z_in / z_net / z_out, z_score,
// z_linear, z_box); the box head has 48 outputs (the 8 never-used angle residuals are gone) and
// the pooled vector is [max-pooled w0, s0 (3), centre height (1)] - no absolute centre.
#include "dimr/nn/stage2_model.h"

#include <torch/cuda.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <sstream>

#include "dimr/geometry/error.h"
#include "dimr/nn/model_archive.h"
#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_unet.h"

namespace dimr::nn {

constexpr int kBoxOutputs = 6 * kStage2CadClasses;  // 8 x 3 centre, 8 x 3 size

// ---------------------------------------------------------------------------------------
// Config
// ---------------------------------------------------------------------------------------

Stage2Config Stage2Config::Reference() {
  Stage2Config c;
  c.widths = {64, 64, 96, 128};
  c.reps = 2;
  return c;
}

void Stage2Config::Validate() const {
  input.Validate();
  if (widths.empty()) throw InvalidArgument("stage2 config: 'widths' is empty");
  if (widths.size() > 5) {
    throw InvalidArgument("stage2 config: at most 5 'widths' levels on a 20^3 grid");
  }
  for (std::size_t i = 0; i < widths.size(); ++i) {
    if (widths[i] < 1 || widths[i] > 4096) {
      throw InvalidArgument("stage2 config: widths[" + std::to_string(i) +
                            "] = " + std::to_string(widths[i]) + " (1..4096 required)");
    }
  }
  if (reps < 1 || reps > 8) {
    throw InvalidArgument("stage2 config: 'reps' = " + std::to_string(reps) + " (1..8 required)");
  }
  if (latent_dim < 1 || latent_dim > 4096) {
    throw InvalidArgument("stage2 config: 'latent' = " + std::to_string(latent_dim));
  }
}

std::string Stage2Config::ToString() const {
  std::ostringstream s;
  s << "features=" << input.feature_dim << " height=" << (input.point_height ? 1 : 0)
    << " grid=" << input.grid << " widths=";
  for (std::size_t i = 0; i < widths.size(); ++i) s << (i ? "," : "") << widths[i];
  s << " reps=" << reps << " latent=" << latent_dim << " center_height=" << (center_height ? 1 : 0);
  return s.str();
}

Stage2Config Stage2Config::FromString(const std::string& text) {
  Stage2Config c;
  std::istringstream in(text);
  std::string item;
  while (in >> item) {
    const auto eq = item.find('=');
    if (eq == std::string::npos) {
      throw InvalidArgument("stage2 config: '" + item + "' is not key=value");
    }
    const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
    try {
      std::size_t used = 0;
      if (key == "features") {
        c.input.feature_dim = std::stoi(value, &used);
      } else if (key == "height") {
        c.input.point_height = std::stoi(value, &used) != 0;
      } else if (key == "grid") {
        c.input.grid = std::stoi(value, &used);
      } else if (key == "reps") {
        c.reps = std::stoi(value, &used);
      } else if (key == "latent") {
        c.latent_dim = std::stoi(value, &used);
      } else if (key == "center_height") {
        c.center_height = std::stoi(value, &used) != 0;
      } else if (key == "widths") {
        c.widths.clear();
        std::istringstream ws(value);
        std::string w;
        while (std::getline(ws, w, ',')) {
          std::size_t u = 0;
          c.widths.push_back(std::stoll(w, &u));
          if (u != w.size()) throw std::invalid_argument(w);
        }
        used = value.size();
      } else {
        throw InvalidArgument("stage2 config: unknown key '" + key + "'");
      }
      if (used != value.size()) throw std::invalid_argument(value);
    } catch (const std::logic_error&) {
      throw InvalidArgument("stage2 config: bad value '" + value + "' for '" + key + "'");
    }
  }
  c.Validate();
  return c;
}

// ---------------------------------------------------------------------------------------
// Outputs
// ---------------------------------------------------------------------------------------

float Stage2Output::score(int i) const {
  return 1.0f / (1.0f + std::exp(-score_logit.at(static_cast<std::size_t>(i))));
}

Eigen::VectorXf Stage2Output::Code(int i) const {
  if (i < 0 || i >= batch_size) throw InvalidArgument("Stage2Output: index out of range");
  return Eigen::Map<const Eigen::VectorXf>(code.data() + static_cast<std::size_t>(i) * code_dim,
                                           code_dim);
}

namespace {
Eigen::Vector3f BoxPart(const Stage2Output& o, int i, int cad_class, int part) {
  if (i < 0 || i >= o.batch_size) throw InvalidArgument("Stage2Output: index out of range");
  if (cad_class < 0 || cad_class >= kStage2CadClasses) {
    throw InvalidArgument("Stage2Output: CAD class " + std::to_string(cad_class) + " outside 0..7");
  }
  const float* p = o.box.data() + static_cast<std::size_t>(i) * kBoxOutputs +
                   part * 3 * kStage2CadClasses + 3 * cad_class;
  return Eigen::Vector3f(p[0], p[1], p[2]);
}
}  // namespace

Eigen::Vector3f Stage2Output::CenterResidual(int i, int cad_class) const {
  return BoxPart(*this, i, cad_class, 0);
}
Eigen::Vector3f Stage2Output::SizeResidual(int i, int cad_class) const {
  return BoxPart(*this, i, cad_class, 1);
}

// ---------------------------------------------------------------------------------------
// Network
// ---------------------------------------------------------------------------------------

namespace {

torch::nn::LeakyReLU LRelu() {
  return torch::nn::LeakyReLU(torch::nn::LeakyReLUOptions().negative_slope(0.01));
}

struct Heads {
  torch::Tensor score;  // [B]
  torch::Tensor code;   // [B, 2L]
  torch::Tensor box;    // [B, 48]
};

class Stage2NetImpl : public torch::nn::Module {
 public:
  explicit Stage2NetImpl(const Stage2Config& c) : config(c) {
    SparseUNetConfig u;
    u.in_channels = c.input.channels();
    u.widths = c.widths;
    u.reps = c.reps;
    u.input_name = "z_in";
    u.unet_name = "z_net";
    u.output_name = "z_out";
    backbone = register_module("backbone", SparseUNet(u));
    const int64_t d = c.pooled_dim();
    z_score = register_module("z_score", torch::nn::Linear(d, 1));
    z_linear = register_module(
        "z_linear",
        torch::nn::Sequential(torch::nn::Linear(d, 128), LRelu(), torch::nn::Linear(128, 256),
                              LRelu(), torch::nn::Linear(256, 512), LRelu(),
                              torch::nn::Linear(512, 2 * c.latent_dim)));
    z_box = register_module("z_box", torch::nn::Sequential(torch::nn::Linear(d, 128), LRelu(),
                                                           torch::nn::Linear(128, 256), LRelu(),
                                                           torch::nn::Linear(256, kBoxOutputs)));
  }

  Heads forward(const torch::Tensor& voxel, const torch::Tensor& features,
                const torch::Tensor& extent, const torch::Tensor& center_height,
                int64_t batch_size) {
    const int64_t g = config.input.grid;
    Voxelized v = Voxelize(voxel, features, batch_size, {g, g, g});
    v.tensor.context()->BuildKernelMaps(static_cast<int>(config.widths.size()));
    SparseTensor y = backbone->forward(v.tensor);
    torch::Tensor pooled = BatchPool(y, PoolMode::kMax);  // [B, w0]
    std::vector<torch::Tensor> parts{pooled, extent};
    if (config.center_height) parts.push_back(center_height.unsqueeze(1));
    torch::Tensor h = torch::cat(parts, 1);
    Heads out;
    out.score = z_score->forward(h).squeeze(1);
    out.code = z_linear->forward(h);
    out.box = z_box->forward(h);
    return out;
  }

  Stage2Config config;
  SparseUNet backbone{nullptr};
  torch::nn::Linear z_score{nullptr};
  torch::nn::Sequential z_linear{nullptr}, z_box{nullptr};
};
TORCH_MODULE(Stage2Net);

template <typename T>
torch::Tensor FromVector(const std::vector<T>& v, torch::Dtype dtype, std::vector<int64_t> shape) {
  if (v.empty()) return torch::zeros(shape, torch::TensorOptions().dtype(dtype));
  return torch::from_blob(const_cast<T*>(v.data()), shape, torch::TensorOptions().dtype(dtype))
      .clone();
}

struct BatchTensors {
  torch::Tensor voxel, features, extent, center_height;
  torch::Tensor score_target, box_weight, class_weight, gt_class, center_target, size_target, code;
  int64_t batch_size = 0;
  int code_dim = 0;
};

BatchTensors ToTensors(const Stage2Batch& b, const Stage2Config& config,
                       const torch::Device& device) {
  const int64_t n = b.num_points();
  const int64_t bs = b.batch_size;
  if (bs <= 0 || n == 0) throw InvalidArgument("stage2: empty batch (no proposals / points)");
  if (b.channels != config.input.channels()) {
    throw InvalidArgument("stage2: batch has " + std::to_string(b.channels) +
                          " input channels, the model expects " +
                          std::to_string(config.input.channels()));
  }
  const std::size_t ubs = static_cast<std::size_t>(bs);
  if (b.voxel.size() != static_cast<std::size_t>(4 * n) ||
      b.features.size() != static_cast<std::size_t>(n * b.channels) || b.extent.size() != 3 * ubs ||
      b.center_height.size() != ubs || b.score_target.size() != ubs || b.box_weight.size() != ubs ||
      b.class_weight.size() != ubs || b.gt_class.size() != ubs ||
      b.center_target.size() != 3 * ubs || b.size_target.size() != 3 * ubs ||
      b.code.size() != ubs * static_cast<std::size_t>(b.code_dim)) {
    throw InvalidArgument("stage2: inconsistent batch array sizes");
  }
  if (b.code_dim != 0 && b.code_dim != 2 * config.latent_dim) {
    throw InvalidArgument("stage2: target codes have " + std::to_string(b.code_dim) +
                          " values, the model predicts " + std::to_string(2 * config.latent_dim));
  }
  BatchTensors t;
  t.batch_size = bs;
  t.code_dim = b.code_dim;
  t.voxel = FromVector(b.voxel, torch::kInt32, {n, 4});
  t.features = FromVector(b.features, torch::kFloat32, {n, b.channels}).to(device);
  t.extent = FromVector(b.extent, torch::kFloat32, {bs, 3}).to(device);
  t.center_height = FromVector(b.center_height, torch::kFloat32, {bs}).to(device);
  t.score_target = FromVector(b.score_target, torch::kFloat32, {bs}).to(device);
  t.box_weight = FromVector(b.box_weight, torch::kFloat32, {bs}).to(device);
  t.class_weight = FromVector(b.class_weight, torch::kFloat32, {bs}).to(device);
  t.gt_class = FromVector(b.gt_class, torch::kInt64, {bs}).to(device);
  t.center_target = FromVector(b.center_target, torch::kFloat32, {bs, 3}).to(device);
  t.size_target = FromVector(b.size_target, torch::kFloat32, {bs, 3}).to(device);
  if (b.code_dim > 0) t.code = FromVector(b.code, torch::kFloat32, {bs, b.code_dim}).to(device);
  return t;
}

struct LossOut {
  torch::Tensor total;
  Stage2LossTerms terms;
};

torch::Tensor SmoothL1(const torch::Tensor& a, const torch::Tensor& b) {
  return torch::nn::functional::smooth_l1_loss(
      a, b, torch::nn::functional::SmoothL1LossFuncOptions().reduction(torch::kNone));
}

// Section 4.4: BCE on the soft targets; latent / centre / size smooth-L1 weighted by class
// weight x soft target x valid over Z = sum(soft target x valid).
LossOut ComputeLoss(const Heads& h, const BatchTensors& t) {
  LossOut out;
  const torch::Tensor score =
      torch::nn::functional::binary_cross_entropy_with_logits(h.score, t.score_target);
  const torch::Tensor z = t.box_weight.sum() + 1e-6;
  const torch::Tensor w = t.box_weight * t.class_weight;
  const int64_t bs = t.batch_size;
  const torch::Tensor idx = t.gt_class.view({bs, 1, 1}).expand({bs, 1, 3});
  const torch::Tensor dc =
      h.box.slice(1, 0, 3 * kStage2CadClasses).view({bs, kStage2CadClasses, 3}).gather(1, idx);
  const torch::Tensor ds = h.box.slice(1, 3 * kStage2CadClasses, kBoxOutputs)
                               .view({bs, kStage2CadClasses, 3})
                               .gather(1, idx);
  const torch::Tensor center = (w * SmoothL1(dc.squeeze(1), t.center_target).mean(1)).sum() / z;
  const torch::Tensor size =
      (w * SmoothL1(t.extent + ds.squeeze(1), t.size_target).mean(1)).sum() / z;
  torch::Tensor latent;
  if (t.code_dim > 0) {
    latent = (w * SmoothL1(h.code, t.code).mean(1)).sum() / z;
  } else {
    latent = h.code.sum() * 0;
  }
  out.total = score + latent + center + size;
  out.terms.score = score.item<double>();
  out.terms.latent = latent.item<double>();
  out.terms.center = center.item<double>();
  out.terms.size = size.item<double>();
  out.terms.total = out.total.item<double>();
  return out;
}

double Ms(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Stage2Model
// ---------------------------------------------------------------------------------------

struct Stage2Model::Impl {
  Stage2Config config;
  Stage2Net net{nullptr};
  torch::Device device = torch::kCPU;
  std::unique_ptr<torch::optim::Adam> step_optimizer;  // TrainStep's
  explicit Impl(const Stage2Config& c) : config(c), net(c) {}

  Heads Forward(const BatchTensors& t) {
    return net->forward(t.voxel, t.features, t.extent, t.center_height, t.batch_size);
  }
};

Stage2Model::Stage2Model(const Stage2Config& config, std::uint64_t seed) {
  config.Validate();
  torch::manual_seed(seed);
  impl_ = std::make_unique<Impl>(config);
  impl_->net->eval();
}
Stage2Model::~Stage2Model() = default;
Stage2Model::Stage2Model(Stage2Model&&) noexcept = default;
Stage2Model& Stage2Model::operator=(Stage2Model&&) noexcept = default;

const Stage2Config& Stage2Model::config() const { return impl_->config; }

std::int64_t Stage2Model::NumParameters() const {
  std::int64_t n = 0;
  for (const auto& p : impl_->net->parameters()) n += p.numel();
  return n;
}

void Stage2Model::Save(const std::string& path, bool half) const {
  SaveModelArchive(*impl_->net, path, "stage2", impl_->config.ToString(), half);
}

Stage2Model Stage2Model::Load(const std::string& path) {
  const ModelArchiveReader archive(path, "stage2", "stage-2");
  Stage2Config config;
  try {
    config = Stage2Config::FromString(archive.config());
  } catch (const InvalidArgument& e) {
    throw ParseError(path, e.what());
  }
  Stage2Model model(config);
  archive.LoadInto(*model.impl_->net);
  return model;
}

Stage2LossTerms Stage2Model::EvaluateLoss(const Stage2Batch& batch) const {
  torch::NoGradGuard no_grad;
  const bool was_training = impl_->net->is_training();
  impl_->net->eval();
  const BatchTensors t = ToTensors(batch, impl_->config, impl_->device);
  const LossOut l = ComputeLoss(impl_->Forward(t), t);
  if (was_training) impl_->net->train();
  return l.terms;
}

Stage2LossTerms Stage2Model::TrainStep(const Stage2Batch& batch, double learning_rate) {
  if (!(learning_rate > 0)) throw InvalidArgument("stage2 TrainStep: learning rate must be > 0");
  if (!impl_->step_optimizer) {
    impl_->step_optimizer = std::make_unique<torch::optim::Adam>(
        impl_->net->parameters(), torch::optim::AdamOptions(learning_rate));
  }
  for (auto& group : impl_->step_optimizer->param_groups()) {
    static_cast<torch::optim::AdamOptions&>(group.options()).lr(learning_rate);
  }
  impl_->net->train();
  const BatchTensors t = ToTensors(batch, impl_->config, impl_->device);
  impl_->step_optimizer->zero_grad();
  LossOut l = ComputeLoss(impl_->Forward(t), t);
  l.total.backward();
  impl_->step_optimizer->step();
  impl_->net->eval();
  return l.terms;
}

Stage2Output Stage2Model::Predict(const Stage2Batch& batch) const {
  torch::NoGradGuard no_grad;
  impl_->net->eval();
  const BatchTensors t = ToTensors(batch, impl_->config, impl_->device);
  const Heads h = impl_->Forward(t);
  Stage2Output out;
  out.batch_size = batch.batch_size;
  out.code_dim = 2 * impl_->config.latent_dim;
  const torch::Tensor s = h.score.to(torch::kCPU).contiguous();
  const torch::Tensor c = h.code.to(torch::kCPU).contiguous();
  const torch::Tensor b = h.box.to(torch::kCPU).contiguous();
  out.score_logit.assign(s.data_ptr<float>(), s.data_ptr<float>() + s.numel());
  out.code.assign(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
  out.box.assign(b.data_ptr<float>(), b.data_ptr<float>() + b.numel());
  for (float v : out.score_logit) {
    if (!std::isfinite(v)) throw Error("stage2 predict: non-finite score (corrupt weights?)");
  }
  return out;
}

Stage2Output Stage2Model::Predict(const std::vector<Stage2Sample>& samples, int chunk) const {
  if (chunk < 1) throw InvalidArgument("stage2 predict: chunk must be >= 1");
  Stage2Output out;
  out.code_dim = 2 * impl_->config.latent_dim;
  for (std::size_t first = 0; first < samples.size(); first += chunk) {
    std::vector<const Stage2Sample*> part;
    for (std::size_t i = first; i < std::min(samples.size(), first + chunk); ++i) {
      part.push_back(&samples[i]);
    }
    // Targets are ignored here: strip them so that missing codes never matter.
    std::vector<Stage2Sample> stripped;
    stripped.reserve(part.size());
    std::vector<const Stage2Sample*> ptrs;
    for (const Stage2Sample* p : part) {
      Stage2Sample s = *p;
      s.code.clear();
      s.gt_class = -1;
      stripped.push_back(std::move(s));
    }
    for (const auto& s : stripped) ptrs.push_back(&s);
    const Stage2Output o = Predict(MakeStage2Batch(ptrs, impl_->config.input));
    out.batch_size += o.batch_size;
    out.score_logit.insert(out.score_logit.end(), o.score_logit.begin(), o.score_logit.end());
    out.code.insert(out.code.end(), o.code.begin(), o.code.end());
    out.box.insert(out.box.end(), o.box.begin(), o.box.end());
  }
  return out;
}

// ---------------------------------------------------------------------------------------
// Training
// ---------------------------------------------------------------------------------------

std::vector<Stage2StepLog> Stage2Model::Train(const std::vector<Stage2Sample>& train,
                                              const Stage2TrainOptions& opt,
                                              const std::function<void(const Stage2StepLog&)>& log,
                                              const EpochCallback& on_epoch) {
  if (train.empty()) throw InvalidArgument("stage2 train: no training proposals");
  if (opt.epochs < 1) throw InvalidArgument("stage2 train: 'epochs' must be >= 1");
  if (opt.batch_size < 1) throw InvalidArgument("stage2 train: 'batch_size' must be >= 1");
  if (!(opt.learning_rate > 0)) throw InvalidArgument("stage2 train: 'learning_rate' must be > 0");
  if (!(opt.lr_decay > 0 && opt.lr_decay <= 1)) {
    throw InvalidArgument("stage2 train: 'lr_decay' must be in (0, 1]");
  }
  opt.augment.Validate();
  if (!opt.class_weights.empty() && opt.class_weights.size() != kStage2CadClasses) {
    throw InvalidArgument("stage2 train: class_weights needs 8 entries");
  }
  for (const auto& s : train) {
    if (s.feature_dim != impl_->config.input.feature_dim) {
      throw InvalidArgument("stage2 train: proposals of '" + s.scene + "' have " +
                            std::to_string(s.feature_dim) + "-d features, the config " +
                            std::to_string(impl_->config.input.feature_dim));
    }
  }
  if (opt.threads > 0) torch::set_num_threads(opt.threads);
  if (opt.device == "cuda") {
    if (!torch::cuda::is_available()) {
      throw InvalidArgument("stage2 train: device 'cuda' requested but not available");
    }
    impl_->device = torch::Device(torch::kCUDA);
  } else if (opt.device != "cpu") {
    throw InvalidArgument("stage2 train: unknown device '" + opt.device + "' (cpu or cuda)");
  }
  auto& net = impl_->net;
  net->to(impl_->device);
  const int batch_size = std::min<int>(opt.batch_size, static_cast<int>(train.size()));
  const int per_epoch = static_cast<int>(train.size() / batch_size);  // drop_last
  const int64_t total_steps = static_cast<int64_t>(per_epoch) * opt.epochs;

  torch::optim::Adam optimizer(net->parameters(), torch::optim::AdamOptions(opt.learning_rate));
  int64_t step = 0;
  const std::vector<int64_t> resumed =
      opt.resume ? ResumeTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "stage2",
                                            "stage-2", impl_->config.ToString(), 2)
                 : std::vector<int64_t>{};
  if (!resumed.empty()) {
    step = resumed[0];
    if (step < 0) throw ParseError(opt.checkpoint_path + ".state", "negative step");
    if (resumed[1] != per_epoch) {
      std::fprintf(stderr,
                   "warning: %s: %lld batches per epoch before, %d now; continuing at step %lld\n",
                   opt.checkpoint_path.c_str(), static_cast<long long>(resumed[1]), per_epoch,
                   static_cast<long long>(step));
    }
    std::fprintf(stderr, "resuming from %s at step %lld\n", opt.checkpoint_path.c_str(),
                 static_cast<long long>(step));
  }
  auto checkpoint = [&]() {
    if (opt.checkpoint_path.empty()) return;
    SaveTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "stage2", impl_->config.ToString(),
                           {step, per_epoch});
  };
  auto run_epoch_callback = [&](int epoch) {
    if (!on_epoch) return;
    net->eval();
    const auto saved = impl_->device;
    const auto metrics = on_epoch(epoch, *this);
    impl_->device = saved;
    net->to(impl_->device);
    if (!metrics.empty()) {
      std::fprintf(stderr, "\nepoch %d:", epoch);
      for (const auto& [k, v] : metrics) std::fprintf(stderr, " %s=%.4f", k.c_str(), v);
      std::fprintf(stderr, "\n");
    }
  };

  std::vector<Stage2StepLog> logs;
  const auto t_start = std::chrono::steady_clock::now();
  auto elapsed_s = [&]() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  };
  Stage2LossTerms running;
  int running_n = 0;
  bool out_of_time = false;
  while (step < total_steps && !out_of_time) {
    const int epoch = static_cast<int>(step / per_epoch);
    // The epoch's order depends only on (seed, epoch): resuming mid-epoch continues it.
    std::vector<std::size_t> order(train.size());
    std::iota(order.begin(), order.end(), 0);
    std::mt19937_64 shuffle_rng(opt.seed * 1000003ull + static_cast<std::uint64_t>(epoch));
    std::shuffle(order.begin(), order.end(), shuffle_rng);
    net->train();
    for (int k = static_cast<int>(step % per_epoch); k < per_epoch && step < total_steps; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<Stage2Sample> augmented;
      augmented.reserve(batch_size);
      for (int j = 0; j < batch_size; ++j) {
        const std::size_t idx = order[static_cast<std::size_t>(k) * batch_size + j];
        std::mt19937_64 rng(opt.seed ^ (0x9e3779b97f4a7c15ull * (step + 1)) ^ (idx * 7919ull));
        augmented.push_back(AugmentStage2Sample(train[idx], opt.augment, &rng));
      }
      std::vector<const Stage2Sample*> ptrs;
      for (const auto& s : augmented) ptrs.push_back(&s);
      const Stage2Batch batch = MakeStage2Batch(ptrs, impl_->config.input, opt.class_weights,
                                                opt.fg_thresh, opt.bg_thresh);
      double progress = static_cast<double>(step) / static_cast<double>(total_steps);
      if (opt.lr_by_time && opt.max_minutes > 0) {
        progress = std::min(1.0, std::max(progress, elapsed_s() / (60.0 * opt.max_minutes)));
      }
      const double lr = std::max(opt.learning_rate * std::pow(opt.lr_decay, progress), 1e-6);
      for (auto& group : optimizer.param_groups()) {
        static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
      }
      const BatchTensors t = ToTensors(batch, impl_->config, impl_->device);
      const auto t1 = std::chrono::steady_clock::now();
      optimizer.zero_grad();
      LossOut l = ComputeLoss(impl_->Forward(t), t);
      if (!std::isfinite(l.terms.total)) {
        throw Error("stage2 train: the loss became non-finite at step " + std::to_string(step + 1) +
                    "; lower the learning rate");
      }
      const auto t2 = std::chrono::steady_clock::now();
      l.total.backward();
      optimizer.step();
      if (impl_->device.is_cuda()) torch::cuda::synchronize();
      const auto t3 = std::chrono::steady_clock::now();
      ++step;
      Stage2StepLog s;
      s.epoch = epoch + 1;
      s.step = static_cast<int>(step);
      s.lr = lr;
      s.loss = l.terms;
      s.seconds = elapsed_s();
      s.data_ms = Ms(t0, t1);
      s.forward_ms = Ms(t1, t2);
      s.backward_ms = Ms(t2, t3);
      logs.push_back(s);
      if (log) log(s);
      running.total += l.terms.total;
      running.score += l.terms.score;
      running.latent += l.terms.latent;
      running.center += l.terms.center;
      running.size += l.terms.size;
      ++running_n;
      if (opt.progress) {
        const double f = 1.0 / running_n;
        std::fprintf(stderr,
                     "\r[epoch %d/%d %4d/%d] loss %.4f score %.4f z %.4f ctr %.4f size %.4f lr "
                     "%.1e %.0f ms/it (data %.0f fwd %.0f bwd %.0f)   ",
                     epoch + 1, opt.epochs, k + 1, per_epoch, running.total * f, running.score * f,
                     running.latent * f, running.center * f, running.size * f, lr, Ms(t0, t3),
                     s.data_ms, s.forward_ms, s.backward_ms);
        std::fflush(stderr);
      }
      if (opt.checkpoint_every_steps > 0 && step % opt.checkpoint_every_steps == 0) checkpoint();
      if (opt.max_minutes > 0 && elapsed_s() / 60.0 >= opt.max_minutes) {
        out_of_time = true;
        break;
      }
    }
    if (step % per_epoch == 0 || step >= total_steps) {
      running = Stage2LossTerms();
      running_n = 0;
      const int finished = static_cast<int>((step + per_epoch - 1) / per_epoch);
      checkpoint();
      if (step >= total_steps ||
          (opt.validate_every_epochs > 0 && finished % opt.validate_every_epochs == 0)) {
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
