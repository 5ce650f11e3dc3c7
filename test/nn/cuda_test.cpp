// Device checks: the torch-ops sparse path and the BSP-CVAE on CUDA LibTorch must give the
// CPU results. Skipped (not failed) on hosts without a CUDA device, e.g. CI.
#include <ATen/Context.h>
#include <gtest/gtest.h>
#include <torch/cuda.h>

#include <cmath>
#include <random>
#include <set>
#include <tuple>

#include "dimr/nn/bsp_model.h"
#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_unet.h"

namespace dimr::nn {
namespace {

bool HaveCuda() { return torch::cuda::is_available(); }

at::Tensor Sites(int64_t batch, int64_t n, int64_t size, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int64_t> u(0, size - 1);
  std::set<std::tuple<int64_t, int64_t, int64_t, int64_t>> seen;
  std::vector<int32_t> flat;
  while (static_cast<int64_t>(seen.size()) < n) {
    const auto key =
        std::make_tuple(static_cast<int64_t>(seen.size() % batch), u(rng), u(rng), u(rng));
    if (!seen.insert(key).second) continue;
    flat.insert(flat.end(),
                {static_cast<int32_t>(std::get<0>(key)), static_cast<int32_t>(std::get<1>(key)),
                 static_cast<int32_t>(std::get<2>(key)), static_cast<int32_t>(std::get<3>(key))});
  }
  return at::tensor(flat, at::kInt).view({n, 4});
}

double RelErr(const at::Tensor& a, const at::Tensor& b) {
  return ((a - b).abs().max() / (b.abs().max() + 1e-12)).item<double>();
}

TEST(Cuda, SparseUNetTorchOpsOnCudaMatchesCpuFused) {
  if (!HaveCuda()) GTEST_SKIP() << "no CUDA device";
  at::manual_seed(3);
  SparseUNetConfig config;
  config.in_channels = 3;
  config.widths = {16, 24, 32};
  SparseUNet net(config);
  const at::Tensor coords = Sites(2, 3000, 40, 7);
  const at::Tensor x = at::randn({coords.size(0), 3});
  const at::Tensor r = at::randn({coords.size(0), 16});
  net->zero_grad();
  SparseTensor y_cpu = net->forward(SparseTensor(coords, x, {40, 40, 40}, 2));
  (y_cpu.features() * r).sum().backward();
  std::vector<at::Tensor> g_cpu;
  for (const auto& p : net->parameters()) g_cpu.push_back(p.grad().clone());
  net->zero_grad();
  net->to(at::kCUDA);
  ASSERT_EQ(ResolveSparseBackend(at::Device(at::kCUDA)), SparseBackend::kTorchOps);
  SparseTensor y_gpu = net->forward(SparseTensor(coords, x.cuda(), {40, 40, 40}, 2));
  EXPECT_TRUE(y_gpu.features().is_cuda());
  (y_gpu.features() * r.cuda()).sum().backward();
  EXPECT_LT(RelErr(y_gpu.features().cpu(), y_cpu.features()), 1e-4);
  const auto params = net->parameters();
  for (std::size_t i = 0; i < params.size(); ++i) {
    EXPECT_LT(RelErr(params[i].grad().cpu(), g_cpu[i]), 1e-3) << "parameter " << i;
  }
}

TEST(Cuda, BspModelTrainsOnCuda) {
  if (!HaveCuda()) GTEST_SKIP() << "no CUDA device";
  BspConfig c;
  c.resolution = 8;
  c.latent_dim = 8;
  c.encoder_width = 4;
  c.num_planes = 16;
  c.num_convexes = 4;
  c.num_classes = 1;
  c.decoder_widths = {16};
  BspDataset d;
  d.resolution = 8;
  for (int s = 0; s < 4; ++s) {
    BspSample sample;
    sample.cad_class = 0;
    sample.model_id = std::to_string(s);
    sample.grid.assign(512, 0);
    for (int i = 0; i < 512; i += 3 + s) sample.grid[i] = 1;
    sample.iou_grid = sample.grid;
    sample.inside_points = {0.1f, 0.2f, 0.3f, -0.1f, 0.0f, 0.2f};
    sample.outside_points = {0.9f, 0.9f, 0.9f, -0.9f, 0.8f, -0.7f};
    d.samples.push_back(sample);
  }
  BspModel model(c, 1);
  BspTrainOptions opt;
  opt.epochs_phase0 = 2;
  opt.epochs_phase1 = 1;
  opt.batch_size = 4;
  opt.points_per_sample = 64;
  opt.device = "cuda";
  const auto logs = model.Train(d, d, opt);
  ASSERT_EQ(logs.size(), 3u);
  for (const auto& l : logs) EXPECT_TRUE(std::isfinite(l.recon_loss));
  EXPECT_GE(model.EvaluateIoU(d), 0.0);
}

}  // namespace
}  // namespace dimr::nn
