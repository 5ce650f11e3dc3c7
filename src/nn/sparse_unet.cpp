// Sparse conv modules, residual blocks and the recursive sparse U-Net.
#include "dimr/nn/sparse_unet.h"

#include <cmath>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::nn {
namespace {

std::shared_ptr<torch::nn::Module> Container(torch::nn::Module& parent, const std::string& name) {
  return parent.register_module(name, std::make_shared<torch::nn::Module>("SparseSequential"));
}

thread_local double t_scene_norm = 0.0;

SparseTensor BnAct(torch::nn::BatchNorm1d bn, const SparseTensor& x) {
  const at::Tensor& f = x.features();
  const double w = t_scene_norm;
  if (w > 0 && !bn->is_training() && f.dim() == 2 && f.size(0) >= 2) {
    // The blend of ScopedSceneNormalisation, then eval-mode batch_norm with it (one kernel).
    auto [var, mean] = at::var_mean(f, {0}, /*unbiased=*/false, /*keepdim=*/false);
    const at::Tensor m = bn->running_mean * (1.0 - w) + mean * w;
    const at::Tensor v = bn->running_var * (1.0 - w) + var * w;
    return x.WithFeatures(
        at::leaky_relu(at::batch_norm(f, bn->weight, bn->bias, m, v, /*training=*/false, 0.0,
                                      bn->options.eps(), /*cudnn_enabled=*/false),
                       0.01));
  }
  return x.WithFeatures(at::leaky_relu(bn->forward(f), 0.01));
}

}  // namespace

ScopedSceneNormalisation::ScopedSceneNormalisation(double weight) : previous_(t_scene_norm) {
  if (!(weight >= 0.0 && weight <= 1.0)) {
    throw InvalidArgument("scene normalisation weight must be in [0, 1], got " +
                          std::to_string(weight));
  }
  t_scene_norm = weight;
}
ScopedSceneNormalisation::~ScopedSceneNormalisation() { t_scene_norm = previous_; }
double ScopedSceneNormalisation::Current() { return t_scene_norm; }

torch::nn::BatchNorm1d MakeSparseBatchNorm(int64_t channels) {
  return torch::nn::BatchNorm1d(
      torch::nn::BatchNormOptions(channels).eps(1e-4).momentum(0.1).affine(true));
}

SparseConvWeightImpl::SparseConvWeightImpl(int64_t kernel_, int64_t cin_, int64_t cout_)
    : kernel(kernel_), cin(cin_), cout(cout_) {
  if (kernel < 1 || cin < 1 || cout < 1) {
    throw InvalidArgument("sparse conv: kernel " + std::to_string(kernel) + ", channels " +
                          std::to_string(cin) + " -> " + std::to_string(cout) +
                          " must be positive");
  }
  weight = register_parameter("weight", torch::empty({kernel, kernel, kernel, cin, cout}));
  reset_parameters();
}

void SparseConvWeightImpl::reset_parameters() {
  at::NoGradGuard no_grad;
  const double fan_in = static_cast<double>(kernel * kernel * kernel * cin);
  const double bound = std::sqrt(6.0 / fan_in);
  weight.uniform_(-bound, bound);
}

SubMConvLayerImpl::SubMConvLayerImpl(int64_t cin_, int64_t cout_, int64_t kernel_)
    : SparseConvWeightImpl(kernel_, cin_, cout_) {
  if (kernel != 1 && kernel != 3) {
    throw InvalidArgument("SubMConv3d: kernel size must be 1 or 3, got " + std::to_string(kernel));
  }
}
SparseTensor SubMConvLayerImpl::forward(const SparseTensor& x) { return SubMConv3d(x, weight); }

DownConvLayerImpl::DownConvLayerImpl(int64_t cin_, int64_t cout_)
    : SparseConvWeightImpl(2, cin_, cout_) {}
SparseTensor DownConvLayerImpl::forward(const SparseTensor& x) {
  return SparseConv3dDown(x, weight);
}

InverseConvLayerImpl::InverseConvLayerImpl(int64_t cin_, int64_t cout_)
    : SparseConvWeightImpl(2, cin_, cout_) {}
SparseTensor InverseConvLayerImpl::forward(const SparseTensor& x) {
  return SparseInverseConv3d(x, weight);
}

ResidualBlockImpl::ResidualBlockImpl(int64_t cin, int64_t cout) {
  if (cin != cout) {
    auto ib = Container(*this, "i_branch");
    identity_ = SubMConvLayer(cin, cout, 1);
    ib->register_module("0", identity_);
  }
  auto cb = Container(*this, "conv_branch");
  bn0_ = MakeSparseBatchNorm(cin);
  conv0_ = SubMConvLayer(cin, cout, 3);
  bn1_ = MakeSparseBatchNorm(cout);
  conv1_ = SubMConvLayer(cout, cout, 3);
  cb->register_module("0", bn0_);
  cb->register_module("2", conv0_);
  cb->register_module("3", bn1_);
  cb->register_module("5", conv1_);
}

SparseTensor ResidualBlockImpl::forward(const SparseTensor& x) {
  SparseTensor y = conv0_->forward(BnAct(bn0_, x));
  y = conv1_->forward(BnAct(bn1_, y));
  const at::Tensor id = identity_ ? identity_->forward(x).features() : x.features();
  return y.WithFeatures(y.features() + id);
}

UBlockImpl::UBlockImpl(const std::vector<int64_t>& planes, int64_t reps) {
  if (planes.empty() || reps < 1) {
    throw InvalidArgument("UBlock: need at least one level and reps >= 1");
  }
  const int64_t c0 = planes[0];
  auto blocks = Container(*this, "blocks");
  for (int64_t i = 0; i < reps; ++i) {
    blocks_.push_back(ResidualBlock(c0, c0));
    blocks->register_module("block" + std::to_string(i), blocks_.back());
  }
  if (planes.size() > 1) {
    const int64_t c1 = planes[1];
    auto conv = Container(*this, "conv");
    down_bn_ = MakeSparseBatchNorm(c0);
    down_ = DownConvLayer(c0, c1);
    conv->register_module("0", down_bn_);
    conv->register_module("2", down_);
    inner_ = register_module(
        "u",
        std::make_shared<UBlockImpl>(std::vector<int64_t>(planes.begin() + 1, planes.end()), reps));
    auto deconv = Container(*this, "deconv");
    up_bn_ = MakeSparseBatchNorm(c1);
    up_ = InverseConvLayer(c1, c0);
    deconv->register_module("0", up_bn_);
    deconv->register_module("2", up_);
    auto tail = Container(*this, "blocks_tail");
    for (int64_t i = 0; i < reps; ++i) {
      tail_.push_back(ResidualBlock(i == 0 ? 2 * c0 : c0, c0));
      tail->register_module("block" + std::to_string(i), tail_.back());
    }
  }
}

SparseTensor UBlockImpl::forward(const SparseTensor& x) {
  SparseTensor y = x;
  for (auto& b : blocks_) y = b->forward(y);
  if (!inner_) return y;
  SparseTensor skip = y;
  SparseTensor d = down_->forward(BnAct(down_bn_, y));
  d = inner_->forward(d);
  SparseTensor up = up_->forward(BnAct(up_bn_, d));
  y = Concat({skip, up});
  for (auto& b : tail_) y = b->forward(y);
  return y;
}

SparseUNetConfig SparseUNetConfig::Stage1() { return SparseUNetConfig(); }

SparseUNetConfig SparseUNetConfig::Stage2() {
  SparseUNetConfig c;
  c.in_channels = 35;
  c.widths = {64, 64, 96, 128};
  c.input_name = "z_in";
  c.unet_name = "z_net";
  c.output_name = "z_out";
  return c;
}

void SparseUNetConfig::validate() const {
  if (in_channels < 1) {
    throw InvalidArgument("sparse unet config: in_channels must be >= 1, got " +
                          std::to_string(in_channels));
  }
  if (widths.empty()) throw InvalidArgument("sparse unet config: widths is empty");
  for (size_t i = 0; i < widths.size(); ++i) {
    if (widths[i] < 1) {
      throw InvalidArgument("sparse unet config: widths[" + std::to_string(i) +
                            "] must be >= 1, got " + std::to_string(widths[i]));
    }
  }
  if (reps < 1) {
    throw InvalidArgument("sparse unet config: reps must be >= 1, got " + std::to_string(reps));
  }
  for (const std::string* n : {&input_name, &unet_name, &output_name}) {
    if (n->empty() || n->find('.') != std::string::npos) {
      throw InvalidArgument("sparse unet config: module name '" + *n +
                            "' must be non-empty and contain no '.'");
    }
  }
}

SparseUNetImpl::SparseUNetImpl(SparseUNetConfig config) : config_(std::move(config)) {
  config_.validate();
  auto in = Container(*this, config_.input_name);
  input_ = SubMConvLayer(config_.in_channels, config_.widths[0], 3);
  in->register_module("0", input_);
  unet_ = register_module(config_.unet_name, UBlock(config_.widths, config_.reps));
  auto out = Container(*this, config_.output_name);
  out_bn_ = MakeSparseBatchNorm(config_.widths[0]);
  out->register_module("0", out_bn_);
}

SparseTensor SparseUNetImpl::forward(const SparseTensor& x) {
  if (x.features().size(1) != config_.in_channels) {
    throw InvalidArgument("sparse unet: input has " + std::to_string(x.features().size(1)) +
                          " channels, config in_channels = " + std::to_string(config_.in_channels));
  }
  SparseTensor y = input_->forward(x);
  y = unet_->forward(y);
  return BnAct(out_bn_, y);
}

}  // namespace dimr::nn
