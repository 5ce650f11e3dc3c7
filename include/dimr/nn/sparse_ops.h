// Differentiable sparse operations on SparseTensor / feature rows (exact autograd through
// torch::autograd::Function subclasses). Two kernels implement every rulebook op:
//  - kFused: CPU gather-GEMM-scatter per kernel offset in cache-sized chunks, parallel over
//    chunks with at::parallel_for, thread-local buffers, GEMM by at::mm_out (BLAS);
//  - kTorchOps: plain index_select / mm / index_add_ (runs on any device, e.g. CUDA).
// kAuto picks kFused for CPU tensors and kTorchOps otherwise; SetSparseBackend overrides it.
#pragma once

#include <ATen/ATen.h>

#include <array>
#include <string>
#include <vector>

#include "dimr/nn/sparse_tensor.h"

namespace dimr::nn {

enum class SparseBackend { kAuto, kFused, kTorchOps };

// Process-wide override (for tests and benchmarks). kAuto = choose by device.
void SetSparseBackend(SparseBackend backend);
SparseBackend GetSparseBackend();
// The backend actually used for tensors on `device`.
SparseBackend ResolveSparseBackend(const at::Device& device);

// Kernel path of the fused backend's float convolutions (docs/sparse.md "Kernels"): direct
// register-tiled kernels for AVX-512 or AVX2 + FMA, or gather-GEMM-scatter (any CPU, and every
// width / dtype the direct kernels do not cover). kAuto = the environment variable
// DIMR_SPARSE_KERNELS (avx512 | avx2 | gemm | auto) when set, else the best the CPU supports:
// AVX-512 -> AVX2 + FMA -> GEMM.
enum class SparseKernelPath { kAuto, kAvx512, kAvx2, kGemm };

// Process-wide override (tests, benchmarks). Forcing a path this CPU cannot run throws
// dimr::InvalidArgument (here, and at the next convolution when it came from the environment).
void SetSparseKernelPath(SparseKernelPath path);
SparseKernelPath GetSparseKernelPath();
// The path the next fused float convolution takes (never kAuto).
SparseKernelPath ResolveSparseKernelPath();
bool SparseKernelPathSupported(SparseKernelPath path);
// "auto", "avx512", "avx2", "gemm"; Parse throws dimr::InvalidArgument on other names.
const char* SparseKernelPathName(SparseKernelPath path);
SparseKernelPath ParseSparseKernelPath(const std::string& name);
// The paths this CPU can run, best first (always ends with kGemm).
std::vector<SparseKernelPath> SupportedSparseKernelPaths();

// Rulebook convolution on feature rows: out[o] += in[i] * W[k] for every pair (i, o) of
// offset k (transpose: pairs are used reversed, out[i] += in[o] * W[k]).
// weight [K, Cin, Cout] (any contiguity); returns [n_out, Cout].
at::Tensor RulebookConv(const at::Tensor& features, const at::Tensor& weight, const Rulebook& rb,
                        bool transpose, SparseBackend backend = SparseBackend::kAuto);

// Submanifold convolution, weight [k, k, k, Cin, Cout] with k = 1 or 3 (pad = k / 2).
SparseTensor SubMConv3d(const SparseTensor& x, const at::Tensor& weight);
// Strided convolution k2 s2 (no pad), weight [2, 2, 2, Cin, Cout]; output at stride 2*s.
SparseTensor SparseConv3dDown(const SparseTensor& x, const at::Tensor& weight);
// Inverse of the paired k2 s2 conv: x at stride 2*s -> the exact active set of stride s;
// weight [2, 2, 2, Cin, Cout].
SparseTensor SparseInverseConv3d(const SparseTensor& x, const at::Tensor& weight);

SparseTensor LeakyRelu(const SparseTensor& x, double negative_slope = 0.01);
// Channel concatenation of tensors on the same sites (same context and stride).
SparseTensor Concat(const std::vector<SparseTensor>& xs);

enum class PoolMode { kMax, kMean };
// Pool rows into segments: segment[i] in [0, num_segments) (int64, any order). Empty
// segments give 0. Max: gradient to the arg-max row of each (segment, channel) (the first
// one on ties).
at::Tensor SegmentPool(const at::Tensor& features, const at::Tensor& segment, int64_t num_segments,
                       PoolMode mode, SparseBackend backend = SparseBackend::kAuto);
// Pool per batch element: [batch_size, C].
at::Tensor BatchPool(const SparseTensor& x, PoolMode mode);

// Point -> voxel map. Voxels are numbered in (b, x, y, z) lexicographic order, whatever the
// order of the points (memory locality of the sparse kernels; docs/sparse.md).
struct VoxelMap {
  at::Tensor point_to_voxel;  // [N] int64
  at::Tensor voxel_offsets;   // [M + 1] int64, CSR over voxel_points
  at::Tensor voxel_points;    // [N] int64, points grouped by voxel (ascending inside)
  at::Tensor voxel_coords;    // [M, 4] int32 (b, x, y, z)
  int64_t num_voxels() const { return voxel_coords.size(0); }
};

// Integer voxel coordinates (b, x, y, z) of metric points: floor(scale * p - min over the
// points of the same batch element of scale * p). points [N, 3] float, batch [N] int64.
at::Tensor PointVoxelCoords(const at::Tensor& points, const at::Tensor& batch, double scale);
// Unique voxels of integer point coords [N, 4] (b, x, y, z).
VoxelMap BuildVoxelMap(const at::Tensor& point_coords);
// Mean of point features per voxel ([N, C] -> [M, C]); the gradient is split equally.
at::Tensor VoxelMean(const at::Tensor& point_features, const VoxelMap& map,
                     SparseBackend backend = SparseBackend::kAuto);
// Voxel -> point gather ([M, C] -> [N, C]); the gradient sums over each voxel's points.
at::Tensor Devoxelize(const at::Tensor& voxel_features, const VoxelMap& map,
                      SparseBackend backend = SparseBackend::kAuto);

// Points -> SparseTensor at stride 1 with mean features. The spatial shape per axis is
// max(max coord + 1, min_spatial_shape).
struct Voxelized {
  SparseTensor tensor;
  VoxelMap map;
};
Voxelized Voxelize(const at::Tensor& point_coords, const at::Tensor& point_features,
                   int64_t batch_size, std::array<int64_t, 3> min_spatial_shape = {1, 1, 1});

}  // namespace dimr::nn
