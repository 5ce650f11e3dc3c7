// Sparse voxel tensor with a per-stride kernel-map cache (spconv 1.x semantics, see
// docs/sparse.md and reference §2.1).
//
// A SparseTensor holds active sites (batch, x, y, z) at one tensor stride, their features
// (rows) and a shared SparseContext. The context caches, per stride level, the site list,
// a hash of the sites and the rulebooks of the submanifold k=3 convolution and of the
// strided k=2 s=2 convolution to the next level (reused reversed by the inverse conv).
// Every layer of a forward pass shares one context, so each rulebook is built once.
#pragma once

#include <ATen/ATen.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

namespace dimr::nn {

// Open-addressing hash of packed (b, x, y, z) keys -> row index.
class SiteHash {
 public:
  // coords: [N, 4] int32 CPU contiguous (b, x, y, z); all values in [0, 65535].
  explicit SiteHash(const at::Tensor& coords);
  // Row of (b, x, y, z) or -1. Coordinates outside [0, 65535] return -1.
  int64_t Find(int64_t b, int64_t x, int64_t y, int64_t z) const;
  static uint64_t Pack(int64_t b, int64_t x, int64_t y, int64_t z) {
    return (static_cast<uint64_t>(b) << 48) | (static_cast<uint64_t>(x) << 32) |
           (static_cast<uint64_t>(y) << 16) | static_cast<uint64_t>(z);
  }

 private:
  std::vector<uint64_t> keys_;  // key + 1 (0 = empty)
  std::vector<int64_t> values_;
  uint64_t mask_ = 0;
};

// The distinct values of `keys` (packed (b, x, y, z), SiteHash::Pack) in ascending order, and in
// `index` (resized to keys.size()) the position of every key among them: how voxelising and
// down-sampling number their sites ((b, x, y, z) order, whatever the input order).
std::vector<uint64_t> SortedUniqueKeys(const std::vector<uint64_t>& keys,
                                       std::vector<int64_t>* index);
// [M, 4] int32 CPU (b, x, y, z) of packed keys.
at::Tensor CoordsOfKeys(const std::vector<uint64_t>& keys);

// Input/output row pairs of one convolution, grouped by kernel offset: pairs
// offsets[k] .. offsets[k+1]-1 use weight W[k]. Within one offset every input and every
// output row occurs at most once (so scatter-adds of one offset never collide).
struct Rulebook {
  int64_t kernel_volume = 0;
  int64_t num_in = 0;            // rows of the input level
  int64_t num_out = 0;           // rows of the output level
  int64_t identity_offset = -1;  // offset whose pairs are (i, i) for every row, or -1
  at::Tensor in_idx;             // [P] int64 CPU
  at::Tensor out_idx;            // [P] int64 CPU
  std::vector<int64_t> offsets;  // kernel_volume + 1
  // Sub-manifold rulebooks: the pairs of offset k are those of offset kernel_volume - 1 - k with
  // input and output swapped (mirror_symmetric), and inside each offset the pairs ascend by output
  // row (out_sorted). The fused CPU kernels then run output-stationary (docs/sparse.md).
  bool mirror_symmetric = false;
  bool out_sorted = false;
  // Output rows per block of the output-stationary kernels.
  static constexpr int64_t kOutBlock = 512;
  // For out_sorted rulebooks: [num_blocks + 1, kernel_volume] int64 CPU; entry (b, k) is the
  // index of the first pair of offset k whose output row is >= b * kOutBlock (built on first
  // use). An undefined tensor otherwise.
  at::Tensor OutBlocks() const;
  // Index tensors on another device (e.g. CUDA), built on first use.
  std::pair<at::Tensor, at::Tensor> OnDevice(const at::Device& device) const;
  int64_t num_pairs() const { return offsets.empty() ? 0 : offsets.back(); }

 private:
  mutable std::mutex mutex_;
  mutable std::map<std::string, std::pair<at::Tensor, at::Tensor>> device_cache_;
  mutable at::Tensor out_blocks_;
};

// All stride levels of one sparse forward pass.
class SparseContext {
 public:
  struct Level {
    at::Tensor coords;  // [N, 4] int32 CPU (b, x, y, z) in this level's grid
    std::array<int64_t, 3> shape{0, 0, 0};
    // Sites in strictly ascending (b, x, y, z) order (voxelised inputs, every coarse level):
    // their packed keys, and the SubM3 rulebook is a merge of sorted lists. Otherwise (sites in
    // any order) `keys` is empty and `hash` is set.
    bool sorted = false;
    std::vector<uint64_t> keys;
    std::shared_ptr<SiteHash> hash;
    std::shared_ptr<Rulebook> subm3;
    std::shared_ptr<Rulebook> down;  // this level (fine) -> level 2*stride (coarse)
  };

  SparseContext(at::Tensor coords, std::array<int64_t, 3> spatial_shape, int64_t batch_size);
  int64_t batch_size() const { return batch_size_; }
  // The level of `stride` (must exist: 1 or created by Down()).
  const Level& level(int64_t stride) const;
  bool has_level(int64_t stride) const;
  // Submanifold 3x3x3 rulebook (pairs in -> out, offset k = 9*dx + 3*dy + dz with d in
  // {0,1,2} meaning input = output + d - 1), built once.
  const Rulebook& Subm3(int64_t stride);
  // k2 s2 rulebook from `stride` to 2*stride (pairs fine -> coarse, k = 4*rx + 2*ry + rz with
  // r = v - 2*floor(v/2)); creates the coarse level. Fine sites whose coarse index reaches
  // floor(S/2) on some axis are dropped.
  const Rulebook& Down(int64_t stride);
  // Builds every rulebook a U-Net of `levels` levels uses (Subm3 at strides 1, 2, ...,
  // 2^(levels-1) and Down between them) now, so that its forward pass finds them cached: callers
  // time or schedule the kernel maps apart from the convolutions. levels >= 1.
  void BuildKernelMaps(int levels);

 private:
  Level& MutableLevel(int64_t stride);
  int64_t batch_size_;
  std::map<int64_t, Level> levels_;
  std::mutex mutex_;
};

class SparseTensor {
 public:
  SparseTensor() = default;
  // A new context at stride 1. coords [N, 4] integer (b, x, y, z), unique sites, each in
  // [0, spatial_shape) and b in [0, batch_size); features [N, C] on any device.
  SparseTensor(const at::Tensor& coords, at::Tensor features, std::array<int64_t, 3> spatial_shape,
               int64_t batch_size);
  SparseTensor(at::Tensor features, int64_t stride, std::shared_ptr<SparseContext> context);

  const at::Tensor& features() const { return features_; }
  const at::Tensor& coords() const { return context_->level(stride_).coords; }
  const std::array<int64_t, 3>& spatial_shape() const { return context_->level(stride_).shape; }
  int64_t stride() const { return stride_; }
  int64_t batch_size() const { return context_->batch_size(); }
  int64_t num_sites() const { return features_.size(0); }
  const std::shared_ptr<SparseContext>& context() const { return context_; }
  SparseTensor WithFeatures(at::Tensor features) const;

 private:
  at::Tensor features_;
  int64_t stride_ = 1;
  std::shared_ptr<SparseContext> context_;
};

}  // namespace dimr::nn
