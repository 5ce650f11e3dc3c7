// Stage-1 inference after the network (private to the nn layer, LibTorch-free): the head
// outputs of each test-time-augmentation pass mapped back to the input frame, averaged over the
// passes and copied out per point (Stage1Model::PredictAugmented, src/nn/stage1_model.cpp).
#pragma once

#include <cstdint>
#include <vector>

#include "dimr/nn/stage1_model.h"

namespace dimr::nn::stage1_heads {

// One pass's head outputs on its M voxels (row-major, CPU): semantic logits [M, classes],
// offsets [M, 3], heading [M, 24] (12 bin logits | 12 normalised residuals). SoftmaxInPlace
// turns the semantic logits and the bin logits into probabilities where they are; the other
// functions read probabilities.
struct VoxelHeads {
  float* prob = nullptr;
  const float* offset = nullptr;
  float* heading = nullptr;
  std::int64_t voxels = 0;
  int classes = 0;
};

// The kernels of the softmax and of the TTA mean: 4-lane generic vectors (SSE2 / NEON, any
// CPU), 8-lane AVX2 or 16-lane AVX-512 with masked loads (softmax rows of <= 32 floats, mean
// rows of <= 64; longer rows take the 4-lane kernels). All three give the same bits (the same
// operations lane by lane, the 4-lane sum order); kAuto picks the widest this CPU runs. A
// kernel the CPU cannot run throws InvalidArgument.
enum class HeadsIsa { kAuto, kGeneric, kAvx2, kAvx512 };
const char* HeadsIsaName(HeadsIsa isa);
std::vector<HeadsIsa> SupportedHeadsIsas();  // kGeneric first
HeadsIsa ResolveHeadsIsa(HeadsIsa isa);

// Softmax of each `dim`-float row x + v * stride (v < rows), in place; argmax (if given, one
// per row) gets the first index of the row's largest probability.
void SoftmaxRows(float* x, std::int64_t rows, int dim, std::int64_t stride, int* argmax = nullptr,
                 HeadsIsa isa = HeadsIsa::kAuto);
// The semantic rows (argmax: the class of each voxel, if given) and the bin logits.
void SoftmaxInPlace(const VoxelHeads& h, int* argmax = nullptr, HeadsIsa isa = HeadsIsa::kAuto);

// A pass's voxel rows in the input frame: [semantic prob (classes) | heading prob (12) |
// heading residual (12) | offset (3)], `stride` floats apart (a multiple of 4: whole vectors).
struct RowLayout {
  int classes, heading_prob, heading_residual, offset, stride;
  explicit RowLayout(int classes);
};

// The voxel rows of pass (mirror, k) of `rotations` (the pass saw the scene mirrored x -> -x
// about the centroid if `mirror`, then rotated by 2 pi k / rotations about the vertical axis):
// heading bins and residuals permuted / negated back, offsets rotated back then mirrored.
// Writes h.voxels x layout.stride floats to `rows`.
void InputFrameRows(const VoxelHeads& h, const RowLayout& layout, bool mirror, int k, int rotations,
                    float* rows);
// SoftmaxInPlace and InputFrameRows block by block (a block's probabilities are still in cache
// when its rows are written): the same numbers as the two calls.
void SoftmaxToInputFrameRows(const VoxelHeads& h, const RowLayout& layout, bool mirror, int k,
                             int rotations, float* rows, HeadsIsa isa = HeadsIsa::kAuto);

// One pass: the probability tables per voxel (rows = voxels, out->point_row = point_to_voxel
// [n]); every point gets its voxel's class (argmax, from SoftmaxInPlace) and offset. Sizes
// `out`'s arrays.
void CopyOutOnePass(const VoxelHeads& h, const int* argmax, const std::int64_t* point_to_voxel,
                    std::size_t n, Stage1Output* out);

// Several passes: the mean of every point's voxel rows over the passes, summed in pass order;
// one row per point, stored in the first pass's voxel order (out->point_row[voxel_points[j]]
// = j: the table writes are sequential, ~10 % of the 12-pass heads).
// The points are walked in the first pass's voxel order (voxel_offsets [m0 + 1] CSR over
// voxel_points [n]); rows[0] (InputFrameRows of the first pass) is indexed by that voxel,
// rows[k] (k >= 1) by voxel_of[k][j] for the j-th point of that order (voxel_of[0] unused).
// Sizes `out`'s arrays.
void AverageInVoxelOrder(const std::int64_t* voxel_offsets, std::int64_t m0,
                         const std::int64_t* voxel_points, std::size_t n,
                         const std::vector<const float*>& rows,
                         const std::vector<const std::int32_t*>& voxel_of, const RowLayout& layout,
                         Stage1Output* out, HeadsIsa isa = HeadsIsa::kAuto);

// The moved scene of a test-time-augmentation pass, structure of arrays (n floats each).
struct MovedPoints {
  std::vector<float> x, y, z;
  float lo[3], hi[3];  // bounding box of the moved points
};
// Moves every point by (x, y) -> centre + R(theta) (sign (x - cx), y - cy), z kept: in double,
// rounded to float, per point exactly `float(cx + cos * dx - sin * dy)` and `float(cy + sin * dx
// + cos * dy)` with dx = sign * (x - cx), dy = y - cy (so every kernel gives the same bits).
// Sizes `out`; the box of non-finite moved points is not finite.
void MoveScenePoints(const Eigen::Vector3f* points, std::size_t n, double cx, double cy,
                     double sign, double cos_theta, double sin_theta, MovedPoints* out,
                     HeadsIsa isa = HeadsIsa::kAuto);
// The network input of moved points, MakeStage1NetworkInput's arithmetic: p = moved - origin
// (float), features [n, 3 or 6] = (p [, colour - 0.5]), voxel [n, 4] = (0, trunc(double(p *
// scale) - qmin)) per axis (qmin = the box corner's (lo - origin) * scale, so every
// difference is >= 0). `colors` null: 3 channels.
void WriteMovedNetworkInput(const MovedPoints& moved, const Eigen::Vector3f* colors, std::size_t n,
                            const float origin[3], float scale, const float qmin[3],
                            float* features, std::int32_t* voxel, HeadsIsa isa = HeadsIsa::kAuto);
// The same for the scene's own points (WriteStage1NetworkInput's writing pass).
void WriteNetworkInput(const Eigen::Vector3f* points, const Eigen::Vector3f* colors, std::size_t n,
                       const float origin[3], float scale, const float qmin[3], float* features,
                       std::int32_t* voxel, HeadsIsa isa = HeadsIsa::kAuto);
// The heads' kernels follow the sparse convolutions' path (DIMR_SPARSE_KERNELS=avx2 times an
// AVX2 machine's whole pass): AVX-512 -> kAvx512, AVX2 -> kAvx2, GEMM -> kGeneric.
HeadsIsa HeadsIsaOfSparsePath();
}  // namespace dimr::nn::stage1_heads
