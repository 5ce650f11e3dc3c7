// Sparse conv engine: values and gradients against dense conv3d references, fused vs
// torch-ops, finite differences, pooling, voxelisation, U-Net structure, checkpoints.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include "dimr/geometry/error.h"
#include "dimr/nn/checkpoint.h"
#include "dimr/nn/sparse_bench.h"
#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_unet.h"

namespace dimr::nn {
namespace {

using Shape3 = std::array<int64_t, 3>;

double RelErr(const at::Tensor& a, const at::Tensor& b) {
  if (a.numel() == 0 && b.numel() == 0) return 0.0;
  const double denom = std::max(b.abs().max().item<double>(), 1e-30);
  return (a - b).abs().max().item<double>() / denom;
}

double Tol(at::ScalarType t) { return t == at::kDouble ? 1e-10 : 1e-4; }

// n_per_batch unique random sites per batch element.
at::Tensor RandomSites(int64_t batch, Shape3 shape, int64_t n_per_batch, uint64_t seed) {
  at::manual_seed(seed);
  const int64_t vol = shape[0] * shape[1] * shape[2];
  std::vector<at::Tensor> parts;
  for (int64_t b = 0; b < batch; ++b) {
    at::Tensor lin = at::randperm(vol, at::kLong).narrow(0, 0, n_per_batch);
    at::Tensor c =
        at::stack({at::full({n_per_batch}, b, at::kLong), lin.div(shape[1] * shape[2], "floor"),
                   lin.div(shape[2], "floor").remainder(shape[1]), lin.remainder(shape[2])},
                  1);
    parts.push_back(c);
  }
  return at::cat(parts, 0).to(at::kInt);
}

at::Tensor LinearIndex(const at::Tensor& coords, Shape3 shape) {
  at::Tensor c = coords.to(at::kLong);
  return ((c.select(1, 0) * shape[0] + c.select(1, 1)) * shape[1] + c.select(1, 2)) * shape[2] +
         c.select(1, 3);
}

// [N, C] rows at coords -> dense [B, C, X, Y, Z] (differentiable).
at::Tensor ToDense(const at::Tensor& coords, const at::Tensor& feats, int64_t batch, Shape3 shape) {
  const int64_t c = feats.size(1);
  at::Tensor flat = at::zeros({batch * shape[0] * shape[1] * shape[2], c}, feats.options());
  flat = flat.index_copy(0, LinearIndex(coords, shape), feats);
  return flat.view({batch, shape[0], shape[1], shape[2], c}).permute({0, 4, 1, 2, 3});
}

// Dense [B, C, X, Y, Z] -> rows at coords.
at::Tensor FromDense(const at::Tensor& dense, const at::Tensor& coords) {
  Shape3 shape{dense.size(2), dense.size(3), dense.size(4)};
  at::Tensor rows = dense.permute({0, 2, 3, 4, 1}).reshape({-1, dense.size(1)});
  return rows.index_select(0, LinearIndex(coords, shape));
}

struct Grads {
  at::Tensor out, gx, gw;
};

// Runs f(x, w), loss = sum(out * r), returns out and the gradients.
template <typename F>
Grads RunWithGrad(F f, const at::Tensor& x0, const at::Tensor& w0, const at::Tensor& r) {
  at::Tensor x = x0.clone().set_requires_grad(true);
  at::Tensor w = w0.clone().set_requires_grad(true);
  at::Tensor out = f(x, w);
  (out * r).sum().backward();
  return {out.detach(), x.grad(), w.grad()};
}

void ExpectClose(const Grads& a, const Grads& b, double tol, const std::string& what) {
  EXPECT_EQ(a.out.sizes(), b.out.sizes()) << what;
  EXPECT_LT(RelErr(a.out, b.out), tol) << what << " value";
  EXPECT_LT(RelErr(a.gx, b.gx), tol) << what << " grad features";
  EXPECT_LT(RelErr(a.gw, b.gw), tol) << what << " grad weight";
}

// 3x3x3 submanifold conv of (coords, x) with weights w [3, 3, 3, cin, cout] (batch 2), and the
// gradients of sum(out * r): through a dense conv3d (the reference) and through SubMConv3d
// (the backend in force).
Grads DenseSubM3(const at::Tensor& coords, const Shape3& shape, const at::Tensor& x,
                 const at::Tensor& w, const at::Tensor& r) {
  return RunWithGrad(
      [&](const at::Tensor& xf, const at::Tensor& wf) {
        at::Tensor d = ToDense(coords, xf, 2, shape);
        return FromDense(at::conv3d(d, wf.permute({4, 3, 0, 1, 2}), {}, at::IntArrayRef({1, 1, 1}),
                                    at::IntArrayRef({1, 1, 1})),
                         coords);
      },
      x, w, r);
}
Grads SparseSubM3(const at::Tensor& coords, const Shape3& shape, const at::Tensor& x,
                  const at::Tensor& w, const at::Tensor& r) {
  return RunWithGrad(
      [&](const at::Tensor& xf, const at::Tensor& wf) {
        return SubMConv3d(SparseTensor(coords, xf, shape, 2), wf).features();
      },
      x, w, r);
}

class BackendGuard {
 public:
  explicit BackendGuard(SparseBackend b) : old_(GetSparseBackend()) { SetSparseBackend(b); }
  ~BackendGuard() { SetSparseBackend(old_); }

 private:
  SparseBackend old_;
};

class KernelPathGuard {
 public:
  explicit KernelPathGuard(SparseKernelPath p) : old_(GetSparseKernelPath()) {
    SetSparseKernelPath(p);
  }
  ~KernelPathGuard() { SetSparseKernelPath(old_); }

 private:
  SparseKernelPath old_;
};

const SparseBackend kBackends[] = {SparseBackend::kFused, SparseBackend::kTorchOps};
const char* Name(SparseBackend b) { return b == SparseBackend::kFused ? "fused" : "torch-ops"; }

// ---------------------------------------------------------------------------------------
TEST(SparseConv, SubmanifoldMatchesDenseConv3d) {
  // Odd shape, batch 2, sparse enough for many empty neighbourhoods.
  const Shape3 shape{7, 6, 5};
  for (auto dtype : {at::kDouble, at::kFloat}) {
    for (int64_t n : {1, 12, 90}) {
      at::Tensor coords = RandomSites(2, shape, n, 7 + n);
      const int64_t cin = 3, cout = 4;
      at::Tensor x = at::randn({coords.size(0), cin}, at::dtype(dtype));
      at::Tensor w = at::randn({3, 3, 3, cin, cout}, at::dtype(dtype));
      at::Tensor r = at::randn({coords.size(0), cout}, at::dtype(dtype));
      const Grads ref = DenseSubM3(coords, shape, x, w, r);
      for (auto be : kBackends) {
        BackendGuard g(be);
        ExpectClose(SparseSubM3(coords, shape, x, w, r), ref, Tol(dtype),
                    std::string("subm3 ") + Name(be) + " n=" + std::to_string(n));
      }
    }
  }
}

// Widths of the direct kernels on every kernel path this CPU runs (AVX-512: outputs in multiples
// of 16 up to 256 but 176 / 208, weight gradient with input tiles of 16 / 8 / 4 / 2; AVX2: 6 x 2
// tiles in 16-column passes, 4 x 3 tiles for multiples of 48, weight-gradient channel remainders
// of every size; GEMM: all of them), and the GEMM fallbacks around them (an input width that is no
// multiple of the tile, an output width that is no multiple of 16, an input gradient wider than
// the tables), against dense conv3d in float32: value, input and weight gradients.
TEST(SparseConv, SubmanifoldAllKernelWidthsMatchDenseConv3d) {
  const Shape3 shape{9, 7, 6};
  at::Tensor coords = RandomSites(2, shape, 150, 77);
  const std::vector<std::pair<int64_t, int64_t>> widths = {
      {16, 16},  {32, 32},  {24, 48},  {20, 64},  {12, 80},  {64, 96}, {6, 112}, {8, 128},
      {32, 40},  {7, 48},   {13, 32},  {11, 144}, {5, 160},  {3, 192}, {9, 240}, {10, 256},
      {160, 16}, {192, 16}, {224, 24}, {256, 32}, {272, 16}, {48, 176}};
  ASSERT_FALSE(SupportedSparseKernelPaths().empty());
  EXPECT_EQ(SupportedSparseKernelPaths().back(), SparseKernelPath::kGemm);
  for (const SparseKernelPath path : SupportedSparseKernelPaths()) {
    KernelPathGuard kp(path);
    for (const auto& [cin, cout] : widths) {
      at::Tensor x = at::randn({coords.size(0), cin});
      at::Tensor w = at::randn({3, 3, 3, cin, cout}) * 0.2;
      at::Tensor r = at::randn({coords.size(0), cout});
      const Grads ref = DenseSubM3(coords, shape, x, w, r);
      BackendGuard g(SparseBackend::kFused);
      ExpectClose(SparseSubM3(coords, shape, x, w, r), ref, 1e-4,
                  std::string("subm3 fused ") + SparseKernelPathName(path) + " " +
                      std::to_string(cin) + "->" + std::to_string(cout));
    }
  }
}

TEST(SparseConv, KernelPathSelection) {
  EXPECT_EQ(ParseSparseKernelPath("avx512"), SparseKernelPath::kAvx512);
  EXPECT_EQ(ParseSparseKernelPath("avx2"), SparseKernelPath::kAvx2);
  EXPECT_EQ(ParseSparseKernelPath("gemm"), SparseKernelPath::kGemm);
  EXPECT_EQ(ParseSparseKernelPath("auto"), SparseKernelPath::kAuto);
  EXPECT_THROW(ParseSparseKernelPath("sse"), InvalidArgument);
  EXPECT_THROW(ParseSparseKernelPath("AVX2 "), InvalidArgument);
  EXPECT_TRUE(SparseKernelPathSupported(SparseKernelPath::kGemm));
  const std::vector<SparseKernelPath> paths = SupportedSparseKernelPaths();
  // AVX-512 implies AVX2 + FMA on every x86 CPU that has it.
  if (SparseKernelPathSupported(SparseKernelPath::kAvx512)) {
    EXPECT_TRUE(SparseKernelPathSupported(SparseKernelPath::kAvx2));
  }
  for (SparseKernelPath p : {SparseKernelPath::kAvx512, SparseKernelPath::kAvx2}) {
    if (!SparseKernelPathSupported(p)) {
      EXPECT_THROW(SetSparseKernelPath(p), InvalidArgument);
    }
  }
  KernelPathGuard g(SparseKernelPath::kGemm);
  EXPECT_EQ(ResolveSparseKernelPath(), SparseKernelPath::kGemm);
  SetSparseKernelPath(SparseKernelPath::kAuto);
  if (std::getenv("DIMR_SPARSE_KERNELS") == nullptr) {
    EXPECT_EQ(ResolveSparseKernelPath(), paths.front());
  }
}

// The fused float path runs sub-manifold convs output-stationary: blocks of
// Rulebook::kOutBlock output rows, each taking all 27 offsets, in parallel; the input gradient
// through the mirrored offsets. Several blocks (the last one partial), two threads, tile
// remainders of every size, wide outputs in two passes, and the weight gradient alone.
TEST(SparseConv, OutputStationaryBlocksAndThreadsMatchDenseConv3d) {
  const Shape3 shape{20, 18, 16};
  at::Tensor coords = RandomSites(2, shape, 1400, 91);
  SparseTensor probe(coords, at::zeros({coords.size(0), 1}), shape, 2);
  const Rulebook& rb = probe.context()->Subm3(1);
  ASSERT_TRUE(rb.out_sorted && rb.mirror_symmetric);
  const at::Tensor blocks = rb.OutBlocks();
  const int64_t nb = (coords.size(0) + Rulebook::kOutBlock - 1) / Rulebook::kOutBlock;
  ASSERT_EQ(nb, 6);
  ASSERT_EQ(blocks.sizes(), (std::vector<int64_t>{nb + 1, 27}));
  for (int64_t k = 0; k < 27; ++k) {
    EXPECT_EQ(blocks[0][k].item<int64_t>(), rb.offsets[k]);
    EXPECT_EQ(blocks[nb][k].item<int64_t>(), rb.offsets[k + 1]);
    // Mirror symmetry: offset 26 - k holds the pairs of offset k reversed.
    EXPECT_EQ(rb.offsets[k + 1] - rb.offsets[k], rb.offsets[27 - k] - rb.offsets[26 - k]);
  }
  const int saved_threads = at::get_num_threads();
  at::set_num_threads(2);
  BackendGuard g(SparseBackend::kFused);
  const std::vector<std::pair<int64_t, int64_t>> widths = {{16, 32}, {64, 96},  {32, 128},
                                                           {96, 64}, {128, 64}, {3, 32}};
  for (const auto& [cin, cout] : widths) {
    at::Tensor x = at::randn({coords.size(0), cin});
    at::Tensor w = at::randn({3, 3, 3, cin, cout}) * 0.2;
    at::Tensor r = at::randn({coords.size(0), cout});
    const Grads ref = DenseSubM3(coords, shape, x, w, r);
    for (const SparseKernelPath path : SupportedSparseKernelPaths()) {
      KernelPathGuard kp(path);
      const std::string what = std::string(SparseKernelPathName(path)) + " " + std::to_string(cin) +
                               "->" + std::to_string(cout);
      ExpectClose(SparseSubM3(coords, shape, x, w, r), ref, 1e-4, "blocked subm3 " + what);
      // Weight gradient only (input without grad, as for a network's first layer).
      at::Tensor wg = w.clone().set_requires_grad(true);
      (SubMConv3d(SparseTensor(coords, x, shape, 2), wg).features() * r).sum().backward();
      EXPECT_LT(RelErr(wg.grad(), ref.gw), 1e-4) << "blocked subm3 weight grad only " << what;
    }
  }
  at::set_num_threads(saved_threads);
}

TEST(SparseConv, SingleSiteUsesOnlyCentreTap) {
  at::Tensor coords = at::tensor({0, 3, 3, 3}, at::kInt).view({1, 4});
  at::Tensor x = at::randn({1, 2}, at::kDouble);
  at::Tensor w = at::randn({3, 3, 3, 2, 5}, at::kDouble);
  at::Tensor y = SubMConv3d(SparseTensor(coords, x, {8, 8, 8}, 1), w).features();
  EXPECT_LT(RelErr(y, x.mm(w[1][1][1])), 1e-12);
  // Two isolated sites, far apart: again only the centre tap.
  at::Tensor c2 = at::tensor({0, 0, 0, 0, 0, 5, 5, 5}, at::kInt).view({2, 4});
  at::Tensor x2 = at::randn({2, 2}, at::kDouble);
  at::Tensor y2 = SubMConv3d(SparseTensor(c2, x2, {8, 8, 8}, 1), w).features();
  EXPECT_LT(RelErr(y2, x2.mm(w[1][1][1])), 1e-12);
}

TEST(SparseConv, KernelOffsetOrderIsRowMajorXYZ) {
  // Site (1,1,1) with a neighbour at (2,1,1): out[(1,1,1)] gets x[(2,1,1)] * W[2][1][1].
  at::Tensor coords = at::tensor({0, 1, 1, 1, 0, 2, 1, 1}, at::kInt).view({2, 4});
  at::Tensor x = at::tensor({0.0, 1.0}, at::kDouble).view({2, 1});
  at::Tensor w = at::zeros({3, 3, 3, 1, 1}, at::kDouble);
  w[2][1][1][0][0] = 5.0;  // dx = +1
  w[1][2][1][0][0] = 7.0;  // dy = +1 (must not fire)
  at::Tensor y = SubMConv3d(SparseTensor(coords, x, {4, 4, 4}, 1), w).features();
  EXPECT_DOUBLE_EQ(y[0][0].item<double>(), 5.0);
  EXPECT_DOUBLE_EQ(y[1][0].item<double>(), 0.0);
}

TEST(SparseConv, SubM1IsMatmul) {
  at::Tensor coords = RandomSites(1, {5, 5, 5}, 20, 3);
  at::Tensor x = at::randn({20, 4}, at::kDouble);
  at::Tensor w = at::randn({1, 1, 1, 4, 6}, at::kDouble);
  at::Tensor y = SubMConv3d(SparseTensor(coords, x, {5, 5, 5}, 1), w).features();
  EXPECT_LT(RelErr(y, x.mm(w.view({4, 6}))), 1e-12);
}

TEST(SparseConv, DownConvMatchesDenseAndDropsOddBorder) {
  const Shape3 shape{7, 5, 6};  // floor(S/2) = 3, 2, 3; x = 6 and y = 4 sites are dropped
  for (auto dtype : {at::kDouble, at::kFloat}) {
    at::Tensor coords = RandomSites(3, shape, 60, 11);
    const int64_t cin = 3, cout = 5;
    at::Tensor x = at::randn({coords.size(0), cin}, at::dtype(dtype));
    at::Tensor w = at::randn({2, 2, 2, cin, cout}, at::dtype(dtype));
    // Expected coarse site set.
    std::set<std::tuple<int, int, int, int>> expect;
    auto ca = coords.accessor<int, 2>();
    for (int64_t i = 0; i < coords.size(0); ++i) {
      if (ca[i][1] / 2 < 3 && ca[i][2] / 2 < 2 && ca[i][3] / 2 < 3) {
        expect.insert({ca[i][0], ca[i][1] / 2, ca[i][2] / 2, ca[i][3] / 2});
      }
    }
    SparseTensor probe = SparseConv3dDown(SparseTensor(coords, x, shape, 3), w);
    EXPECT_EQ(probe.stride(), 2);
    EXPECT_EQ(probe.spatial_shape(), (Shape3{3, 2, 3}));
    at::Tensor cc = probe.coords();
    std::set<std::tuple<int, int, int, int>> got;
    auto cca = cc.accessor<int, 2>();
    for (int64_t i = 0; i < cc.size(0); ++i)
      got.insert({cca[i][0], cca[i][1], cca[i][2], cca[i][3]});
    EXPECT_EQ(got, expect);
    EXPECT_EQ(static_cast<size_t>(cc.size(0)), expect.size());
    at::Tensor r = at::randn({cc.size(0), cout}, at::dtype(dtype));
    Grads ref = RunWithGrad(
        [&](const at::Tensor& xf, const at::Tensor& wf) {
          at::Tensor d = ToDense(coords, xf, 3, shape);
          return FromDense(at::conv3d(d, wf.permute({4, 3, 0, 1, 2}), {},
                                      at::IntArrayRef({2, 2, 2}), at::IntArrayRef({0, 0, 0})),
                           cc);
        },
        x, w, r);
    for (auto be : kBackends) {
      BackendGuard g(be);
      Grads got_g = RunWithGrad(
          [&](const at::Tensor& xf, const at::Tensor& wf) {
            return SparseConv3dDown(SparseTensor(coords, xf, shape, 3), wf).features();
          },
          x, w, r);
      ExpectClose(got_g, ref, Tol(dtype), std::string("down ") + Name(be));
    }
  }
}

TEST(SparseConv, InverseConvMatchesConvTranspose3d) {
  const Shape3 shape{7, 6, 5};
  for (auto dtype : {at::kDouble, at::kFloat}) {
    at::Tensor coords = RandomSites(2, shape, 70, 5);
    const int64_t cc_ch = 4, cf_ch = 3;
    SparseTensor fine(coords, at::zeros({coords.size(0), 1}, at::dtype(dtype)), shape, 2);
    SparseTensor coarse = SparseConv3dDown(fine, at::zeros({2, 2, 2, 1, 1}, at::dtype(dtype)));
    at::Tensor ccoords = coarse.coords();
    at::Tensor x = at::randn({ccoords.size(0), cc_ch}, at::dtype(dtype));
    at::Tensor w = at::randn({2, 2, 2, cc_ch, cf_ch}, at::dtype(dtype));
    at::Tensor r = at::randn({coords.size(0), cf_ch}, at::dtype(dtype));
    Grads ref = RunWithGrad(
        [&](const at::Tensor& xf, const at::Tensor& wf) {
          at::Tensor d = ToDense(ccoords, xf, 2, coarse.spatial_shape());
          at::Tensor up =
              at::conv_transpose3d(d, wf.permute({3, 4, 0, 1, 2}), {}, at::IntArrayRef({2, 2, 2}));
          // Pad back to the odd fine shape: the dropped border sites get 0.
          up = at::constant_pad_nd(
              up, {0, shape[2] - up.size(4), 0, shape[1] - up.size(3), 0, shape[0] - up.size(2)});
          return FromDense(up, coords);
        },
        x, w, r);
    for (auto be : kBackends) {
      BackendGuard g(be);
      Grads got = RunWithGrad(
          [&](const at::Tensor& xf, const at::Tensor& wf) {
            SparseTensor out = SparseInverseConv3d(coarse.WithFeatures(xf), wf);
            EXPECT_EQ(out.stride(), 1);
            return out.features();
          },
          x, w, r);
      ExpectClose(got, ref, Tol(dtype), std::string("inverse ") + Name(be));
    }
    // Dropped fine sites (x == 6 or z == 4) receive exactly zero.
    at::Tensor y = SparseInverseConv3d(coarse.WithFeatures(x), w).features();
    auto ca = coords.accessor<int, 2>();
    int dropped = 0;
    for (int64_t i = 0; i < coords.size(0); ++i) {
      if (ca[i][1] == 6 || ca[i][3] == 4) {
        ++dropped;
        EXPECT_EQ(y[i].abs().sum().item<double>(), 0.0);
      }
    }
    EXPECT_GT(dropped, 0);
  }
}

TEST(SparseConv, FusedEqualsTorchOpsOnLargerInput) {
  at::Tensor coords = RandomSites(2, {24, 24, 24}, 3000, 21);
  const int64_t c = 32;
  at::Tensor x = at::randn({coords.size(0), c});
  at::Tensor w3 = at::randn({3, 3, 3, c, c}) * 0.1;
  at::Tensor w2 = at::randn({2, 2, 2, c, c}) * 0.1;
  at::Tensor wi = at::randn({2, 2, 2, c, c}) * 0.1;
  at::Tensor r = at::randn({coords.size(0), c});
  auto run = [&]() {
    return RunWithGrad(
        [&](const at::Tensor& xf, const at::Tensor& wf) {
          SparseTensor s(coords, xf, {24, 24, 24}, 2);
          SparseTensor a = SubMConv3d(s, wf);
          SparseTensor d = SparseConv3dDown(a, w2);
          return SparseInverseConv3d(SubMConv3d(d, wf), wi).features();
        },
        x, w3, r);
  };
  Grads ref;
  {
    BackendGuard g(SparseBackend::kTorchOps);
    ref = run();
  }
  // Down / inverse convs run the direct kernels offset-major (width 32 on every path).
  for (const SparseKernelPath path : SupportedSparseKernelPaths()) {
    BackendGuard g(SparseBackend::kFused);
    KernelPathGuard kp(path);
    ExpectClose(run(), ref, 1e-5,
                std::string("fused ") + SparseKernelPathName(path) + " vs torch-ops");
  }
}

TEST(SparseConv, FiniteDifferenceGradients) {
  at::Tensor coords = RandomSites(2, {6, 5, 7}, 25, 31);
  at::Tensor x = at::randn({coords.size(0), 2}, at::kDouble);
  at::Tensor w3 = at::randn({3, 3, 3, 2, 3}, at::kDouble);
  at::Tensor w2 = at::randn({2, 2, 2, 3, 2}, at::kDouble);
  at::Tensor wi = at::randn({2, 2, 2, 2, 3}, at::kDouble);
  at::Tensor r = at::randn({coords.size(0), 3}, at::kDouble);
  auto loss = [&](const at::Tensor& xf, const at::Tensor& wf) {
    SparseTensor s(coords, xf, {6, 5, 7}, 2);
    SparseTensor a = LeakyRelu(SubMConv3d(s, wf));
    SparseTensor u = SparseInverseConv3d(SparseConv3dDown(a, w2), wi);
    return (Concat({a, u}).features().narrow(1, 0, 3) * u.features() * r).sum();
  };
  at::Tensor xv = x.clone().set_requires_grad(true);
  at::Tensor wv = w3.clone().set_requires_grad(true);
  loss(xv, wv).backward();
  const double eps = 1e-6;
  at::manual_seed(5);
  for (int t = 0; t < 12; ++t) {
    const bool on_x = t % 2 == 0;
    at::Tensor base = on_x ? x : w3;
    const int64_t idx = at::randint(base.numel(), {1}, at::kLong).item<int64_t>();
    at::Tensor plus = base.clone(), minus = base.clone();
    plus.view(-1)[idx] += eps;
    minus.view(-1)[idx] -= eps;
    const double fd = on_x ? (loss(plus, w3) - loss(minus, w3)).item<double>() / (2 * eps)
                           : (loss(x, plus) - loss(x, minus)).item<double>() / (2 * eps);
    const double an = (on_x ? xv.grad() : wv.grad()).view(-1)[idx].item<double>();
    EXPECT_NEAR(an, fd, 1e-6 * std::max(1.0, std::abs(fd))) << (on_x ? "x" : "w") << idx;
  }
}

// Prebuilt kernel maps are the ones a lazy forward builds: same levels, same pairs.
TEST(SparseContext, BuildKernelMapsEqualsLazyBuild) {
  const at::Tensor coords = RandomSites(2, {21, 17, 19}, 900, 33);
  SparseContext eager(coords, {21, 17, 19}, 2), lazy(coords, {21, 17, 19}, 2);
  eager.BuildKernelMaps(4);
  EXPECT_TRUE(eager.has_level(8));
  EXPECT_FALSE(eager.has_level(16));  // no Down below the last level
  int64_t stride = 1;
  for (int l = 0; l < 4; ++l, stride *= 2) {
    const Rulebook& a = eager.Subm3(stride);
    const Rulebook& b = lazy.Subm3(stride);
    EXPECT_EQ(a.offsets, b.offsets) << "stride " << stride;
    EXPECT_TRUE(at::equal(a.in_idx, b.in_idx)) << "stride " << stride;
    EXPECT_TRUE(at::equal(a.out_idx, b.out_idx)) << "stride " << stride;
    EXPECT_GT(a.num_pairs(), a.num_in);  // neighbours beyond the centre tap
    if (l < 3) {
      const Rulebook& da = eager.Down(stride);
      const Rulebook& db = lazy.Down(stride);
      EXPECT_EQ(da.num_out, db.num_out);
      EXPECT_TRUE(at::equal(da.in_idx, db.in_idx) && at::equal(da.out_idx, db.out_idx));
    }
  }
  EXPECT_EQ(eager.level(8).shape, (Shape3{2, 2, 2}));  // 21 -> 10 -> 5 -> 2 (odd borders dropped)
  EXPECT_THROW(eager.BuildKernelMaps(0), InvalidArgument);
  // 6 levels would halve a 1-voxel axis (17 -> 8 -> 4 -> 2 -> 1 -> 0): a clear error.
  EXPECT_THROW(eager.BuildKernelMaps(6), InvalidArgument);
}

// Sites given in (b, x, y, z) order get their SubM3 rulebook by merging sorted key lists; sites
// in any other order by hash probes. Both must give the same pairs (compared as coordinates), and
// every coarse level is numbered in sorted order whatever the order of the fine sites.
TEST(SparseContext, SortedSitesMergeRulebookEqualsHashRulebook) {
  const Shape3 shape{13, 11, 9};
  // Sites touching the lower and upper borders (neighbour keys leaving the grid) included.
  const at::Tensor shuffled = RandomSites(2, shape, 600, 12);
  const at::Tensor key = LinearIndex(shuffled, shape);
  const at::Tensor sorted = shuffled.index_select(0, std::get<1>(key.sort()));
  SparseContext hashed(shuffled, shape, 2), merged(sorted, shape, 2);
  ASSERT_FALSE(hashed.level(1).sorted);
  ASSERT_TRUE(merged.level(1).sorted);
  auto pair_set = [](SparseContext& ctx, int64_t stride) {
    const Rulebook& rb = ctx.Subm3(stride);
    const at::Tensor c = ctx.level(stride).coords;
    std::set<std::tuple<int64_t, int, int, int, int, int, int, int>> pairs;
    auto in = rb.in_idx.accessor<int64_t, 1>();
    auto out = rb.out_idx.accessor<int64_t, 1>();
    auto ca = c.accessor<int, 2>();
    for (int64_t k = 0; k < 27; ++k) {
      for (int64_t p = rb.offsets[k]; p < rb.offsets[k + 1]; ++p) {
        pairs.emplace(k, ca[in[p]][0], ca[in[p]][1], ca[in[p]][2], ca[in[p]][3], ca[out[p]][1],
                      ca[out[p]][2], ca[out[p]][3]);
        if (p > rb.offsets[k]) {
          EXPECT_GT(out[p], out[p - 1]);  // ascending output rows
        }
      }
    }
    EXPECT_TRUE(rb.out_sorted && rb.mirror_symmetric);
    return pairs;
  };
  const auto a = pair_set(hashed, 1), b = pair_set(merged, 1);
  EXPECT_GT(a.size(), 1200u);
  EXPECT_EQ(a, b);
  // Coarse levels: sorted in both contexts, hence identical, with the same rulebooks.
  hashed.Down(1);
  merged.Down(1);
  ASSERT_TRUE(hashed.level(2).sorted && merged.level(2).sorted);
  EXPECT_TRUE(at::equal(hashed.level(2).coords, merged.level(2).coords));
  const at::Tensor ck = LinearIndex(merged.level(2).coords, hashed.level(2).shape);
  EXPECT_TRUE(
      at::all(ck.narrow(0, 1, ck.size(0) - 1) > ck.narrow(0, 0, ck.size(0) - 1)).item<bool>());
  EXPECT_EQ(pair_set(hashed, 2), pair_set(merged, 2));
}

TEST(SparseConv, EmptyTensor) {
  at::Tensor coords = at::zeros({0, 4}, at::kInt);
  SparseTensor s(coords, at::zeros({0, 3}), {4, 4, 4}, 1);
  EXPECT_EQ(SubMConv3d(s, at::randn({3, 3, 3, 3, 5})).features().sizes(), (at::IntArrayRef{0, 5}));
  SparseTensor d = SparseConv3dDown(s, at::randn({2, 2, 2, 3, 5}));
  EXPECT_EQ(d.num_sites(), 0);
  EXPECT_EQ(SparseInverseConv3d(d, at::randn({2, 2, 2, 5, 2})).features().size(1), 2);
}

TEST(SparseConv, BadInputsThrow) {
  at::Tensor coords = at::tensor({0, 1, 1, 1, 0, 1, 1, 1}, at::kInt).view({2, 4});
  EXPECT_THROW(SparseTensor(coords, at::zeros({2, 1}), {4, 4, 4}, 1), InvalidArgument);
  at::Tensor out_of_range = at::tensor({0, 4, 1, 1}, at::kInt).view({1, 4});
  EXPECT_THROW(SparseTensor(out_of_range, at::zeros({1, 1}), {4, 4, 4}, 1), InvalidArgument);
  SparseTensor ok(coords.narrow(0, 0, 1), at::zeros({1, 2}), {4, 4, 4}, 1);
  EXPECT_THROW(SubMConv3d(ok, at::zeros({3, 3, 3, 3, 2})), InvalidArgument);
  EXPECT_THROW(SparseInverseConv3d(ok, at::zeros({2, 2, 2, 2, 2})), InvalidArgument);
}

// ---------------------------------------------------------------------------------------
TEST(SparsePool, SegmentMaxAndMeanWithGradients) {
  at::manual_seed(2);
  const int64_t n = 40, c = 5, s = 6;  // segment 5 stays empty
  at::Tensor x = at::randn({n, c}, at::kDouble);
  at::Tensor seg = at::randint(0, 5, {n}, at::kLong);
  at::Tensor r = at::randn({s, c}, at::kDouble);
  for (auto mode : {PoolMode::kMax, PoolMode::kMean}) {
    // Reference by loops.
    at::Tensor ref = at::zeros({s, c}, at::kDouble);
    at::Tensor gref = at::zeros({n, c}, at::kDouble);
    for (int64_t k = 0; k < s; ++k) {
      at::Tensor rows = (seg == k).nonzero().view(-1);
      if (rows.numel() == 0) continue;
      at::Tensor xs = x.index_select(0, rows);
      if (mode == PoolMode::kMax) {
        auto [v, a] = xs.max(0);
        ref[k] = v;
        for (int64_t j = 0; j < c; ++j) {
          gref[rows[a[j].item<int64_t>()].item<int64_t>()][j] += r[k][j];
        }
      } else {
        ref[k] = xs.mean(0);
        gref.index_add_(0, rows, r[k].unsqueeze(0).expand({rows.numel(), c}) / rows.numel());
      }
    }
    for (auto be : kBackends) {
      at::Tensor xv = x.clone().set_requires_grad(true);
      at::Tensor y = SegmentPool(xv, seg, s, mode, be);
      (y * r).sum().backward();
      EXPECT_LT(RelErr(y.detach(), ref), 1e-12) << Name(be);
      EXPECT_LT(RelErr(xv.grad(), gref), 1e-12) << Name(be);
      EXPECT_EQ(y[5].abs().sum().item<double>(), 0.0);
    }
  }
}

TEST(SparsePool, BatchPoolUsesBatchColumn) {
  at::Tensor coords = at::tensor({0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0}, at::kInt).view({3, 4});
  at::Tensor f = at::tensor({1.0, 2.0, 6.0}, at::kDouble).view({3, 1});
  SparseTensor s(coords, f, {2, 2, 2}, 2);
  EXPECT_DOUBLE_EQ(BatchPool(s, PoolMode::kMean)[1][0].item<double>(), 4.0);
  EXPECT_DOUBLE_EQ(BatchPool(s, PoolMode::kMax)[0][0].item<double>(), 1.0);
}

TEST(Voxelize, MeanFeaturesGatherAndGradients) {
  // 6 points, 3 voxels (order of first occurrence), two batch elements.
  at::Tensor pts = at::tensor({0.011, 0.0, 0.0, 0.019, 0.001, 0.0, 0.05, 0.0, 0.0, 0.012, 0.003,
                               0.0, 0.0, 0.0, 0.0, 0.001, 0.0, 0.0},
                              at::kDouble)
                       .view({6, 3});
  at::Tensor batch = at::tensor({0, 0, 0, 0, 1, 1}, at::kLong);
  at::Tensor vc = PointVoxelCoords(pts, batch, 50.0);
  // Batch 0: min x = 0.011 -> 0.55; (0.55, 0.95, 0.6) -> 0, (2.5 - 0.55) -> 1.
  EXPECT_EQ(vc[0][1].item<int>(), 0);
  EXPECT_EQ(vc[2][1].item<int>(), 1);
  EXPECT_EQ(vc[4][0].item<int>(), 1);
  for (auto be : kBackends) {
    at::Tensor f = pts.clone().set_requires_grad(true);
    VoxelMap map = BuildVoxelMap(vc);
    ASSERT_EQ(map.num_voxels(), 3);
    EXPECT_EQ(map.point_to_voxel[3].item<int64_t>(), 0);
    at::Tensor v = VoxelMean(f, map, be);
    EXPECT_LT(RelErr(v[0], (pts[0] + pts[1] + pts[3]) / 3), 1e-12);
    EXPECT_LT(RelErr(v[2], (pts[4] + pts[5]) / 2), 1e-12);
    at::Tensor back = Devoxelize(v, map, be);
    EXPECT_LT(RelErr(back[5], v[2].detach()), 1e-12);
    at::Tensor r = at::arange(18, at::kDouble).view({6, 3});
    (back * r).sum().backward();
    // d/dp_i of sum_j r_j . mean(v(j)) = (sum of r over the voxel's points) / count.
    at::Tensor expect0 = (r[0] + r[1] + r[3]) / 3;
    EXPECT_LT(RelErr(f.grad()[1], expect0), 1e-12) << Name(be);
    EXPECT_LT(RelErr(f.grad()[2], r[2]), 1e-12) << Name(be);
  }
  Voxelized vox = Voxelize(vc, pts, 2, {128, 128, 128});
  EXPECT_EQ(vox.tensor.num_sites(), 3);
  // Voxels are numbered in (b, x, y, z) order whatever the point order (kernel locality).
  at::Tensor many = at::randint(0, 6, {400, 4}, at::kInt);
  many.select(1, 0).remainder_(2);
  VoxelMap mm = BuildVoxelMap(many);
  const at::Tensor keys =
      (((mm.voxel_coords.select(1, 0).to(at::kLong) * 8 + mm.voxel_coords.select(1, 1)) * 8 +
        mm.voxel_coords.select(1, 2)) *
           8 +
       mm.voxel_coords.select(1, 3));
  EXPECT_GT(mm.num_voxels(), 200);
  EXPECT_TRUE(
      at::all(keys.narrow(0, 1, mm.num_voxels() - 1) > keys.narrow(0, 0, mm.num_voxels() - 1))
          .item<bool>());
  EXPECT_TRUE(at::equal(mm.voxel_coords.index_select(0, mm.point_to_voxel), many));
  EXPECT_EQ(vox.tensor.spatial_shape(), (Shape3{128, 128, 128}));
}

// ---------------------------------------------------------------------------------------
TEST(SparseUNet, ReferenceParameterNamesShapesAndCount) {
  SparseUNet net(SparseUNetConfig::Stage1());
  std::map<std::string, std::vector<int64_t>> shapes;
  int64_t learnable = 0;
  for (const auto& p : net->named_parameters()) {
    shapes[p.key()] = p.value().sizes().vec();
    learnable += p.value().numel();
  }
  EXPECT_EQ(learnable, 9363488);  // reference backbone ~9.36 M (§14)
  EXPECT_EQ(shapes["input_conv.0.weight"], (std::vector<int64_t>{3, 3, 3, 3, 32}));
  EXPECT_EQ(shapes["unet.blocks.block0.conv_branch.2.weight"],
            (std::vector<int64_t>{3, 3, 3, 32, 32}));
  EXPECT_EQ(shapes["unet.blocks.block1.conv_branch.3.weight"], (std::vector<int64_t>{32}));
  EXPECT_EQ(shapes["unet.conv.2.weight"], (std::vector<int64_t>{2, 2, 2, 32, 32}));
  EXPECT_EQ(shapes["unet.u.conv.2.weight"], (std::vector<int64_t>{2, 2, 2, 32, 64}));
  EXPECT_EQ(shapes["unet.u.deconv.2.weight"], (std::vector<int64_t>{2, 2, 2, 64, 32}));
  EXPECT_EQ(shapes["unet.blocks_tail.block0.i_branch.0.weight"],
            (std::vector<int64_t>{1, 1, 1, 64, 32}));
  EXPECT_EQ(shapes["unet.blocks_tail.block0.conv_branch.2.weight"],
            (std::vector<int64_t>{3, 3, 3, 64, 32}));
  EXPECT_EQ(shapes["unet.u.u.u.u.u.conv.2.weight"], (std::vector<int64_t>{2, 2, 2, 96, 128}));
  EXPECT_EQ(shapes["unet.u.u.u.u.u.u.blocks.block0.conv_branch.5.weight"],
            (std::vector<int64_t>{3, 3, 3, 128, 128}));
  EXPECT_EQ(shapes.count("unet.u.u.u.u.u.u.conv.2.weight"), 0u);
  EXPECT_EQ(shapes["output_layer.0.weight"], (std::vector<int64_t>{32}));
  std::set<std::string> buffers;
  for (const auto& b : net->named_buffers()) buffers.insert(b.key());
  EXPECT_TRUE(buffers.count("unet.conv.0.running_var"));
  EXPECT_TRUE(buffers.count("unet.blocks.block0.conv_branch.0.num_batches_tracked"));

  SparseUNet s2(SparseUNetConfig::Stage2());
  int64_t n2 = 0;
  for (const auto& p : s2->parameters()) n2 += p.numel();
  EXPECT_EQ(n2, 6461568);
  EXPECT_EQ(s2->named_parameters()["z_in.0.weight"].sizes(), (at::IntArrayRef{3, 3, 3, 35, 64}));
}

SparseUNetConfig SmallConfig() {
  SparseUNetConfig c;
  c.in_channels = 3;
  c.widths = {8, 12, 16};
  c.reps = 2;
  return c;
}

TEST(SparseUNet, ForwardBackwardFusedEqualsTorchOps) {
  at::manual_seed(1);
  SparseUNet net(SmallConfig());
  at::Tensor coords = RandomSites(2, {20, 18, 17}, 500, 41);
  at::Tensor x = at::randn({coords.size(0), 3});
  at::Tensor r = at::randn({coords.size(0), 8});
  std::vector<at::Tensor> outs, grads;
  for (auto be : kBackends) {
    BackendGuard g(be);
    net->zero_grad();
    SparseTensor y = net->forward(SparseTensor(coords, x, {20, 18, 17}, 2));
    ASSERT_EQ(y.features().sizes(), (at::IntArrayRef{coords.size(0), 8}));
    (y.features() * r).sum().backward();
    outs.push_back(y.features().detach());
    std::vector<at::Tensor> gs;
    for (const auto& p : net->parameters()) {
      ASSERT_TRUE(p.grad().defined());
      gs.push_back(p.grad().reshape(-1));
    }
    grads.push_back(at::cat(gs));
  }
  EXPECT_LT(RelErr(outs[0], outs[1]), 1e-5);
  EXPECT_LT(RelErr(grads[0], grads[1]), 1e-4);
  EXPECT_GT(grads[0].abs().sum().item<double>(), 0.0);
}

TEST(SparseUNet, TranslationByCoarsestStrideIsEquivariant) {
  at::manual_seed(3);
  SparseUNet net(SmallConfig());  // 3 levels: coarsest stride 4
  net->eval();
  at::Tensor coords = RandomSites(1, {12, 12, 12}, 300, 8);
  at::Tensor x = at::randn({coords.size(0), 3});
  at::Tensor shifted = coords.clone();
  shifted.select(1, 1) += 8;
  shifted.select(1, 3) += 4;
  at::NoGradGuard ng;
  at::Tensor a = net->forward(SparseTensor(coords, x, {24, 16, 20}, 1)).features();
  at::Tensor b = net->forward(SparseTensor(shifted, x, {24, 16, 20}, 1)).features();
  EXPECT_LT(RelErr(a, b), 1e-5);
  // A shift by 1 changes the coarse grouping, hence the output.
  at::Tensor odd = coords.clone();
  odd.select(1, 1) += 1;
  at::Tensor c = net->forward(SparseTensor(odd, x, {24, 16, 20}, 1)).features();
  EXPECT_GT(RelErr(a, c), 1e-3);
}

TEST(SparseUNet, SceneNormalisationBlendsTrainingAndInputStatistics) {
  at::manual_seed(5);
  SparseUNet net(SmallConfig());
  // Running statistics far from any input's, so that using them or not matters.
  {
    at::NoGradGuard ng;
    for (auto& b : net->buffers()) {
      if (b.is_floating_point() && b.dim() == 1) b.copy_(at::rand_like(b) * 4.0 + 0.5);
    }
  }
  at::Tensor coords = RandomSites(1, {14, 12, 10}, 400, 9);
  at::Tensor x = at::randn({coords.size(0), 3}) * 2.0 + 1.0;
  auto run = [&](double w) {
    at::NoGradGuard ng;
    const ScopedSceneNormalisation guard(w);
    return net->forward(SparseTensor(coords, x, {14, 12, 10}, 1)).features().clone();
  };
  net->eval();
  const at::Tensor eval0 = run(0.0);
  const at::Tensor half = run(0.5);
  const at::Tensor full = run(1.0);
  at::Tensor plain;
  {
    at::NoGradGuard ng;
    plain = net->forward(SparseTensor(coords, x, {14, 12, 10}, 1)).features().clone();
  }
  EXPECT_EQ(ScopedSceneNormalisation::Current(), 0.0);  // every guard ended
  EXPECT_TRUE(at::equal(eval0, plain));                 // w = 0 is eval mode
  // w = 1 is training-mode BatchNorm (batch statistics, biased variance, layer after layer),
  // computed on a copy so that the running statistics of `net` are not moved.
  SparseUNet train_copy(SmallConfig());
  {
    at::NoGradGuard ng;
    auto src = net->named_parameters();
    for (auto& p : train_copy->named_parameters()) p.value().copy_(src[p.key()]);
    auto srcb = net->named_buffers();
    for (auto& b : train_copy->named_buffers()) b.value().copy_(srcb[b.key()]);
  }
  train_copy->train();
  at::Tensor batch_stats;
  {
    at::NoGradGuard ng;
    batch_stats = train_copy->forward(SparseTensor(coords, x, {14, 12, 10}, 1)).features();
  }
  EXPECT_LT(RelErr(full, batch_stats), 1e-4);
  EXPECT_GT(RelErr(full, eval0), 0.1);
  // The blend lies strictly between the two and is neither.
  EXPECT_GT(RelErr(half, eval0), 1e-3);
  EXPECT_GT(RelErr(half, full), 1e-3);
  // The weights and running statistics are untouched: eval mode gives the same numbers again.
  EXPECT_TRUE(at::equal(run(0.0), eval0));
  // Nesting: the inner weight wins, the outer one comes back.
  {
    const ScopedSceneNormalisation outer(0.25);
    {
      const ScopedSceneNormalisation inner(1.0);
      EXPECT_EQ(ScopedSceneNormalisation::Current(), 1.0);
    }
    EXPECT_EQ(ScopedSceneNormalisation::Current(), 0.25);
  }
  EXPECT_THROW(ScopedSceneNormalisation(1.5), InvalidArgument);
  EXPECT_THROW(ScopedSceneNormalisation(-0.1), InvalidArgument);
  EXPECT_THROW(ScopedSceneNormalisation(std::nan("")), InvalidArgument);
  // One active site: no statistics to take (a layer with < 2 rows keeps its running ones).
  at::Tensor one = coords.slice(0, 0, 1);
  at::NoGradGuard ng;
  at::Tensor single_eval =
      net->forward(SparseTensor(one, x.slice(0, 0, 1), {14, 12, 10}, 1)).features().clone();
  const ScopedSceneNormalisation guard(1.0);
  at::Tensor single_adapted =
      net->forward(SparseTensor(one, x.slice(0, 0, 1), {14, 12, 10}, 1)).features();
  EXPECT_TRUE(at::equal(single_eval, single_adapted));
}

// ---------------------------------------------------------------------------------------
std::string TempPath(const std::string& name) {
  return std::string(DIMR_BINARY_DIR) + "/test_nn_" + name;
}

TEST(Checkpoint, RoundTripAndHalf) {
  SparseUNet a(SmallConfig()), b(SmallConfig());
  {
    at::NoGradGuard ng;
    for (auto& buf : a->buffers()) {
      if (buf.is_floating_point()) buf.uniform_(0.5, 1.5);
    }
  }
  const std::string path = TempPath("ckpt.bin");
  SaveCheckpoint(*a, path);
  LoadCheckpoint(*b, path);
  auto sa = ModuleState(*a), sb = ModuleState(*b);
  ASSERT_EQ(sa.size(), sb.size());
  for (size_t i = 0; i < sa.size(); ++i) {
    EXPECT_EQ(sa[i].first, sb[i].first);
    EXPECT_TRUE(sa[i].second.equal(sb[i].second)) << sa[i].first;
  }
  SaveCheckpoint(*a, path, /*half=*/true);
  SparseUNet c(SmallConfig());
  LoadCheckpoint(*c, path);
  auto sc = ModuleState(*c);
  for (size_t i = 0; i < sa.size(); ++i) {
    EXPECT_LT(RelErr(sc[i].second.to(at::kDouble), sa[i].second.to(at::kDouble)), 1e-3);
  }
  std::remove(path.c_str());
}

std::string LoadError(torch::nn::Module& m, const std::string& path) {
  try {
    LoadCheckpoint(m, path);
  } catch (const ParseError& e) {
    return e.what();
  }
  return "";
}

TEST(Checkpoint, MismatchedKeysAndShapesNameTheKey) {
  SparseUNet small(SmallConfig());
  const std::string path = TempPath("ckpt_mismatch.bin");
  SaveCheckpoint(*small, path);
  SparseUNetConfig wider = SmallConfig();
  wider.widths = {8, 12, 20};
  SparseUNet w(wider);
  const std::string e1 = LoadError(*w, path);
  EXPECT_NE(e1.find("shape mismatch for key 'unet.u.conv.2.weight'"), std::string::npos) << e1;
  EXPECT_NE(e1.find("[2, 2, 2, 12, 16]"), std::string::npos) << e1;
  EXPECT_NE(e1.find("[2, 2, 2, 12, 20]"), std::string::npos) << e1;
  SparseUNetConfig deeper = SmallConfig();
  deeper.widths = {8, 12, 16, 24};
  SparseUNet d(deeper);
  EXPECT_NE(LoadError(*d, path).find("missing key 'unet.u.u.conv.0.weight'"), std::string::npos);
  SparseUNetConfig shallow = SmallConfig();
  shallow.widths = {8, 12};
  SparseUNet s(shallow);
  EXPECT_NE(LoadError(*s, path).find("unexpected key 'unet.u.conv.0.weight'"), std::string::npos);
  std::remove(path.c_str());
}

TEST(Checkpoint, TruncatedOrCorruptFilesGiveParseErrors) {
  SparseUNetConfig cfg;
  cfg.widths = {4, 6};
  cfg.reps = 1;
  SparseUNet net(cfg);
  const std::string path = TempPath("ckpt_corrupt.bin");
  SaveCheckpoint(*net, path);
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  ASSERT_GT(bytes.size(), 100u);
  int errors = 0;
  const std::string bad = TempPath("ckpt_bad.bin");
  for (size_t len = 0; len < bytes.size(); len += 1 + len / 7) {
    std::ofstream(bad, std::ios::binary | std::ios::trunc).write(bytes.data(), len);
    errors += !LoadError(*net, bad).empty();
  }
  int tried = 0;
  for (size_t len = 0; len < bytes.size(); len += 1 + len / 7) ++tried;
  EXPECT_EQ(errors, tried);
  for (size_t pos : {size_t{3}, size_t{12}, size_t{30}, bytes.size() / 2, bytes.size() - 3}) {
    std::string flipped = bytes;
    flipped[pos] = static_cast<char>(flipped[pos] ^ 0x5a);
    std::ofstream(bad, std::ios::binary | std::ios::trunc).write(flipped.data(), flipped.size());
    EXPECT_FALSE(LoadError(*net, bad).empty()) << "flip at " << pos;
  }
  EXPECT_NE(LoadError(*net, TempPath("does_not_exist.bin")).find("cannot open"), std::string::npos);
  std::remove(path.c_str());
  std::remove(bad.c_str());
}

// ---------------------------------------------------------------------------------------
TEST(SparseBench, RoomIsASurfaceNotRandomPoints) {
  RoomCloud room = GenerateRoomCloud(100000, 7);
  const int64_t voxels = RoomVoxelCount(room, 0.02);
  EXPECT_NEAR(static_cast<double>(voxels), 100000.0, 5000.0);
  // About one point per voxel.
  EXPECT_LT(static_cast<double>(room.points.size()), 1.5 * voxels);
  // Voxelised at 2 cm, each point should mostly sit alone (about one point per voxel) and
  // the voxel set should be a 2-manifold-like surface: a typical voxel has ~8 face/edge
  // neighbours in its 3x3x3 block, far more than random points (~0) and far fewer than 26.
  const double mean_nb = RoomMeanNeighbours(room, 0.02);
  EXPECT_GT(mean_nb, 5.0);
  EXPECT_LT(mean_nb, 14.0);
  RoomCloud again = GenerateRoomCloud(100000, 7);
  EXPECT_EQ(room.points, again.points);  // deterministic
}

}  // namespace
}  // namespace dimr::nn
