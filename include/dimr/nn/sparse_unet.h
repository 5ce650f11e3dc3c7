// Sparse convolution modules and the residual sparse U-Net (reference §2.2, §2.3, §4.2).
//
// Parameter names follow the reference state_dict (§14), e.g. for SparseUNet with the
// default names:
//   input_conv.0.weight                         [3, 3, 3, Cin, C0]
//   unet.blocks.block0.conv_branch.{0,3}.*      BatchNorm (weight, bias, running_mean, ...)
//   unet.blocks.block0.conv_branch.{2,5}.weight [3, 3, 3, C, C]
//   unet.conv.0.* / unet.conv.2.weight          BN(C0) / [2, 2, 2, C0, C1]
//   unet.u.…                                    the next level (recursion)
//   unet.deconv.0.* / unet.deconv.2.weight      BN(C1) / [2, 2, 2, C1, C0]
//   unet.blocks_tail.block0.i_branch.0.weight   [1, 1, 1, 2*C0, C0]
//   output_layer.0.*                            BN(C0)
#pragma once

#include <torch/nn/module.h>
#include <torch/nn/modules/batchnorm.h>

#include <string>
#include <vector>

#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_tensor.h"

namespace dimr::nn {

// BatchNorm1d over active-site rows, eps 1e-4, momentum 0.1 (reference).
torch::nn::BatchNorm1d MakeSparseBatchNorm(int64_t channels);

// Test-time normalisation with the input's own statistics (AdaBN; Schneider et al. 2020,
// "covariate shift adaptation"). While a guard is alive on this thread, every BatchNorm of a
// sparse U-Net in eval mode normalises its rows with
//   mean = (1 - w) running_mean + w mean(rows),  var = (1 - w) running_var + w var(rows)
// (biased variance over the active sites of the whole input), each layer on the output of the
// layers before it as they were normalised with the blend; w = 0 is plain eval mode, w = 1
// uses only the input's statistics. A layer with fewer than 2 rows keeps its running
// statistics. Training mode and the weights are not touched: the statistics are computed per
// forward, so nothing has to be restored and other threads are unaffected. Guards nest (the
// inner weight wins until it ends). Throws dimr::InvalidArgument for w outside [0, 1].
class ScopedSceneNormalisation {
 public:
  explicit ScopedSceneNormalisation(double weight);
  ~ScopedSceneNormalisation();
  ScopedSceneNormalisation(const ScopedSceneNormalisation&) = delete;
  ScopedSceneNormalisation& operator=(const ScopedSceneNormalisation&) = delete;
  static double Current();  // this thread's weight (0 without a guard)

 private:
  double previous_;
};

// A convolution weight [k, k, k, Cin, Cout] (kaiming-uniform init, fan-in k^3 * Cin).
class SparseConvWeightImpl : public torch::nn::Module {
 public:
  SparseConvWeightImpl(int64_t kernel, int64_t cin, int64_t cout);
  void reset_parameters();
  at::Tensor weight;
  int64_t kernel, cin, cout;
};

// Submanifold conv (k = 1 or 3).
class SubMConvLayerImpl : public SparseConvWeightImpl {
 public:
  SubMConvLayerImpl(int64_t cin, int64_t cout, int64_t kernel);
  SparseTensor forward(const SparseTensor& x);
};
TORCH_MODULE(SubMConvLayer);

// k2 s2 conv (stride s -> 2s).
class DownConvLayerImpl : public SparseConvWeightImpl {
 public:
  DownConvLayerImpl(int64_t cin, int64_t cout);
  SparseTensor forward(const SparseTensor& x);
};
TORCH_MODULE(DownConvLayer);

// Inverse conv k2 (stride 2s -> s, onto the paired fine sites).
class InverseConvLayerImpl : public SparseConvWeightImpl {
 public:
  InverseConvLayerImpl(int64_t cin, int64_t cout);
  SparseTensor forward(const SparseTensor& x);
};
TORCH_MODULE(InverseConvLayer);

// Pre-activation residual block: BN-LReLU-SubM3-BN-LReLU-SubM3 + (identity | SubM1).
class ResidualBlockImpl : public torch::nn::Module {
 public:
  ResidualBlockImpl(int64_t cin, int64_t cout);
  SparseTensor forward(const SparseTensor& x);

 private:
  torch::nn::BatchNorm1d bn0_{nullptr}, bn1_{nullptr};
  SubMConvLayer conv0_{nullptr}, conv1_{nullptr}, identity_{nullptr};
};
TORCH_MODULE(ResidualBlock);

// Recursive UBlock(planes, reps).
class UBlockImpl : public torch::nn::Module {
 public:
  UBlockImpl(const std::vector<int64_t>& planes, int64_t reps);
  SparseTensor forward(const SparseTensor& x);

 private:
  std::vector<ResidualBlock> blocks_, tail_;
  torch::nn::BatchNorm1d down_bn_{nullptr}, up_bn_{nullptr};
  DownConvLayer down_{nullptr};
  InverseConvLayer up_{nullptr};
  std::shared_ptr<UBlockImpl> inner_;
};
TORCH_MODULE(UBlock);

struct SparseUNetConfig {
  int64_t in_channels = 3;
  std::vector<int64_t> widths{32, 32, 64, 64, 96, 96, 128};
  int64_t reps = 2;
  // Module names (stage 1: input_conv / unet / output_layer; stage 2: z_in / z_net / z_out).
  std::string input_name = "input_conv";
  std::string unet_name = "unet";
  std::string output_name = "output_layer";

  static SparseUNetConfig Stage1();  // 3 -> [32, 32, 64, 64, 96, 96, 128]
  static SparseUNetConfig Stage2();  // 35 -> [64, 64, 96, 128], z_* names
  void validate() const;             // throws InvalidArgument naming the bad field
};

// input SubM3 -> UBlock -> BN -> LReLU; output features have widths[0] channels.
class SparseUNetImpl : public torch::nn::Module {
 public:
  explicit SparseUNetImpl(SparseUNetConfig config);
  SparseTensor forward(const SparseTensor& x);
  const SparseUNetConfig& config() const { return config_; }

 private:
  SparseUNetConfig config_;
  SubMConvLayer input_{nullptr};
  UBlock unet_{nullptr};
  torch::nn::BatchNorm1d out_bn_{nullptr};
};
TORCH_MODULE(SparseUNet);

}  // namespace dimr::nn
