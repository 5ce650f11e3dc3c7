// Sparse convolution kernels (fused CPU and torch-ops), autograd functions, pooling and
// voxelisation.
#include "dimr/nn/sparse_ops.h"

#include <ATen/Parallel.h>
#include <immintrin.h>
#include <torch/csrc/autograd/custom_function.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>

#include "dimr/geometry/error.h"

namespace dimr::nn {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

std::atomic<int> g_backend{static_cast<int>(SparseBackend::kAuto)};

std::string Shape(const at::Tensor& t) {
  std::ostringstream os;
  os << t.sizes();
  return os.str();
}

// Rows of `features` used as source and rows of the result written, per kernel offset.
struct ConvPlan {
  at::Tensor src_idx;  // [P] int64 on the feature device
  at::Tensor dst_idx;
  std::vector<int64_t> offsets;
  int64_t identity = -1;
  int64_t n_src = 0;
  int64_t n_dst = 0;
  bool mirror_symmetric = false;  // see Rulebook
  at::Tensor blocks;              // Rulebook::OutBlocks() for out_sorted CPU plans, else undefined
};

ConvPlan MakePlan(const Rulebook& rb, bool transpose, const at::Device& device) {
  auto idx = rb.OnDevice(device);
  ConvPlan p;
  p.offsets = rb.offsets;
  p.identity = rb.identity_offset;
  if (!transpose) {
    p.src_idx = idx.first;
    p.dst_idx = idx.second;
    p.n_src = rb.num_in;
    p.n_dst = rb.num_out;
    p.mirror_symmetric = rb.mirror_symmetric;
    if (device.is_cpu()) p.blocks = rb.OutBlocks();
  } else {
    p.src_idx = idx.second;
    p.dst_idx = idx.first;
    p.n_src = rb.num_out;
    p.n_dst = rb.num_in;
  }
  return p;
}

int64_t ChunkRows(int64_t cin, int64_t cout) {
  return std::clamp<int64_t>(131072 / std::max<int64_t>(1, cin + cout), 256, 8192);
}

// Row gather / scatter-add of the fused kernels. The rows are scattered over a feature matrix much
// larger than the caches, so the rows a few pairs ahead are prefetched; copies go through memcpy
// (glibc picks an AVX2/AVX-512 copy at run time) and the adds are compiled for AVX-512, AVX2 and
// the baseline, chosen at load time (target_clones; this file is built with -O3 so they vectorise).
constexpr int64_t kPrefetchAhead = 6;

template <typename T>
inline void PrefetchRow(const T* row, int64_t c) {
  const char* p = reinterpret_cast<const char*>(row);
  for (int64_t b = 0; b < c * static_cast<int64_t>(sizeof(T)); b += 64) __builtin_prefetch(p + b);
}

template <typename T>
inline void GatherRows(T* __restrict dst, const T* __restrict src, const int64_t* idx, int64_t rows,
                       int64_t c) {
  for (int64_t r = 0; r < rows; ++r) {
    if (r + kPrefetchAhead < rows) PrefetchRow(src + idx[r + kPrefetchAhead] * c, c);
    std::memcpy(dst + r * c, src + idx[r] * c, static_cast<size_t>(c) * sizeof(T));
  }
}

template <typename T>
inline __attribute__((always_inline)) void ScatterAddBody(T* __restrict dst,
                                                          const T* __restrict src,
                                                          const int64_t* idx, int64_t rows,
                                                          int64_t c) {
  for (int64_t r = 0; r < rows; ++r) {
    if (r + kPrefetchAhead < rows) PrefetchRow(dst + idx[r + kPrefetchAhead] * c, c);
    T* __restrict d = dst + idx[r] * c;
    const T* __restrict s = src + r * c;
    for (int64_t j = 0; j < c; ++j) d[j] += s[j];
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void ScatterAddRowsF(
    float* dst, const float* src, const int64_t* idx, int64_t rows, int64_t c) {
  ScatterAddBody(dst, src, idx, rows, c);
}
__attribute__((target_clones("avx512f", "avx2", "default"))) void ScatterAddRowsD(
    double* dst, const double* src, const int64_t* idx, int64_t rows, int64_t c) {
  ScatterAddBody(dst, src, idx, rows, c);
}
inline void ScatterAddRows(float* dst, const float* src, const int64_t* idx, int64_t rows,
                           int64_t c) {
  ScatterAddRowsF(dst, src, idx, rows, c);
}
inline void ScatterAddRows(double* dst, const double* src, const int64_t* idx, int64_t rows,
                           int64_t c) {
  ScatterAddRowsD(dst, src, idx, rows, c);
}

// ---------------------------------------------------------------------------------------
// Direct kernels (float, AVX-512): out[dst[r]] += x[src[r]] * W for the pairs of one kernel
// offset, W row-major [cin, cout] with cout = 16 V P. A tile of R pairs keeps its R x V output
// vectors in registers while the cin loop broadcasts one input value per pair against the V
// vectors of a weight row, so rows are read from x and added to out once, without the gather /
// product buffers of the GEMM path (whose small-N GEMMs run well below peak). Wide outputs run
// in P passes of 16 V columns over the same R rows (still in L1). R V + V <= 30 zmm registers.
// Shapes (measured 2026-11-27 on Zen 5, L1-resident): the loop is bound by the V vector loads
// per step, not by the R broadcasts, so tall tiles win: R >= 6 with V <= 4 reach 205-220
// GFLOP/s, R = 4 x V = 6 only 173 and R = 4 x V = 4 161 (one core's FMA peak is ~218).
// Within one offset every dst row occurs once, so chunks of pairs (or blocks of output rows)
// run in parallel without races. Keep the accumulator loops written out in the tile: zeroing
// them with std::fill and adding them through a shared helper taking acc[r] made the stage-1
// U-Net forward ~10 % slower (measured 2026-11-27, 361 -> 410 ms).
// ---------------------------------------------------------------------------------------
template <int V, int R, int P>
__attribute__((target("avx512f"), always_inline)) inline void DirectTile(
    const float* __restrict x, int64_t cin, const float* __restrict w, const int64_t* src,
    const int64_t* dst, float* __restrict out) {
  constexpr int64_t cout = 16 * V * P;
  const float* xr[R];
  for (int r = 0; r < R; ++r) xr[r] = x + src[r] * cin;
  for (int p = 0; p < P; ++p) {
    const float* wp = w + 16 * V * p;
    __m512 acc[R][V];
    for (int r = 0; r < R; ++r) {
      for (int v = 0; v < V; ++v) acc[r][v] = _mm512_setzero_ps();
    }
    for (int64_t c = 0; c < cin; ++c) {
      __m512 wv[V];
      for (int v = 0; v < V; ++v) wv[v] = _mm512_loadu_ps(wp + c * cout + 16 * v);
      for (int r = 0; r < R; ++r) {
        const __m512 xb = _mm512_set1_ps(xr[r][c]);
        for (int v = 0; v < V; ++v) acc[r][v] = _mm512_fmadd_ps(xb, wv[v], acc[r][v]);
      }
    }
    for (int r = 0; r < R; ++r) {
      float* o = out + dst[r] * cout + 16 * V * p;
      for (int v = 0; v < V; ++v) {
        _mm512_storeu_ps(o + 16 * v, _mm512_add_ps(_mm512_loadu_ps(o + 16 * v), acc[r][v]));
      }
    }
  }
}

// The last rows < R of a pair list: one tile of exactly that many rows (a one-row tile would
// run at a quarter of the speed, and output-stationary blocks leave ~R / 2 rows per offset).
template <int V, int Q, int P>
__attribute__((target("avx512f"), always_inline)) inline void DirectRemainder(
    const float* x, int64_t cin, const float* w, const int64_t* src, const int64_t* dst,
    int64_t rows, float* out) {
  if constexpr (Q >= 1) {
    if (rows == Q) {
      DirectTile<V, Q, P>(x, cin, w, src, dst, out);
    } else {
      DirectRemainder<V, Q - 1, P>(x, cin, w, src, dst, rows, out);
    }
  }
}

template <int V, int R, int P>
__attribute__((target("avx512f"))) void DirectRows(const float* __restrict x, int64_t cin,
                                                   const float* __restrict w, const int64_t* src,
                                                   const int64_t* dst, int64_t rows,
                                                   float* __restrict out) {
  constexpr int64_t cout = 16 * V * P;
  int64_t b = 0;
  for (; b + R <= rows; b += R) {
    if (b + 2 * R <= rows) {
      for (int r = 0; r < R; ++r) {
        PrefetchRow(x + src[b + R + r] * cin, cin);
        PrefetchRow(out + dst[b + R + r] * cout, cout);
      }
    }
    DirectTile<V, R, P>(x, cin, w, src + b, dst + b, out);
  }
  if (b < rows) DirectRemainder<V, R - 1, P>(x, cin, w, src + b, dst + b, rows - b, out);
}

using DirectRowsFn = void (*)(const float*, int64_t, const float*, const int64_t*, const int64_t*,
                              int64_t, float*);

// ---------------------------------------------------------------------------------------
// Direct kernels for AVX2 + FMA (CPUs without AVX-512): the same output-stationary register
// tiles with 8-float ymm vectors and 16 registers. A tile holds R x V accumulators, V weight
// vectors and one broadcast, so R V + V + 1 <= 16 (4 x 3 takes one weight from memory).
// Shapes measured 2026-12-01 on a Zen 4 EPYC (AVX2 code, one core, FMA peak ~112 GFLOP/s;
// L1-resident / on a 100k-row room-like pattern, GFLOP/s, rows x vectors): forward 6 x 2
// 108-112 / 84-93, 4 x 3 102-112 / 80-98, 3 x 4 96-111 / 64-86, 5 x 2 95-108 / 65-93, 2 x 4
// 59-61 / 52-59, 12 x 1 (eight columns a pass) 66-87 / 52-73; weight gradient (channels x
// vectors) 6 x 2 66-76, 4 x 3 72-79, 4 x 2 52-63, 8 x 2 53-61, 3 x 4 42-46. Used: 6 rows x 2
// vectors (16 columns) in P passes, 4 rows x 3 vectors where the width is a multiple of 48;
// weight gradient 6 channels
// x 2 vectors (4 x 3 for multiples of 48), any input width (exact-size channel remainder).
// ---------------------------------------------------------------------------------------
template <int V, int R, int P>
__attribute__((target("avx2,fma"), always_inline)) inline void Avx2Tile(
    const float* __restrict x, int64_t cin, const float* __restrict w, const int64_t* src,
    const int64_t* dst, float* __restrict out) {
  constexpr int64_t cout = 8 * V * P;
  const float* xr[R];
  for (int r = 0; r < R; ++r) xr[r] = x + src[r] * cin;
  for (int p = 0; p < P; ++p) {
    const float* wp = w + 8 * V * p;
    __m256 acc[R][V];
    for (int r = 0; r < R; ++r) {
      for (int v = 0; v < V; ++v) acc[r][v] = _mm256_setzero_ps();
    }
    for (int64_t c = 0; c < cin; ++c) {
      __m256 wv[V];
      for (int v = 0; v < V; ++v) wv[v] = _mm256_loadu_ps(wp + c * cout + 8 * v);
      for (int r = 0; r < R; ++r) {
        const __m256 xb = _mm256_broadcast_ss(xr[r] + c);
        for (int v = 0; v < V; ++v) acc[r][v] = _mm256_fmadd_ps(xb, wv[v], acc[r][v]);
      }
    }
    for (int r = 0; r < R; ++r) {
      float* o = out + dst[r] * cout + 8 * V * p;
      for (int v = 0; v < V; ++v) {
        _mm256_storeu_ps(o + 8 * v, _mm256_add_ps(_mm256_loadu_ps(o + 8 * v), acc[r][v]));
      }
    }
  }
}

template <int V, int Q, int P>
__attribute__((target("avx2,fma"), always_inline)) inline void Avx2Remainder(
    const float* x, int64_t cin, const float* w, const int64_t* src, const int64_t* dst,
    int64_t rows, float* out) {
  if constexpr (Q >= 1) {
    if (rows == Q) {
      Avx2Tile<V, Q, P>(x, cin, w, src, dst, out);
    } else {
      Avx2Remainder<V, Q - 1, P>(x, cin, w, src, dst, rows, out);
    }
  }
}

template <int V, int R, int P>
__attribute__((target("avx2,fma"))) void Avx2Rows(const float* __restrict x, int64_t cin,
                                                  const float* __restrict w, const int64_t* src,
                                                  const int64_t* dst, int64_t rows,
                                                  float* __restrict out) {
  constexpr int64_t cout = 8 * V * P;
  int64_t b = 0;
  for (; b + R <= rows; b += R) {
    if (b + 2 * R <= rows) {
      for (int r = 0; r < R; ++r) {
        PrefetchRow(x + src[b + R + r] * cin, cin);
        PrefetchRow(out + dst[b + R + r] * cout, cout);
      }
    }
    Avx2Tile<V, R, P>(x, cin, w, src + b, dst + b, out);
  }
  if (b < rows) Avx2Remainder<V, R - 1, P>(x, cin, w, src + b, dst + b, rows - b, out);
}

// Weight gradient, AVX2: channels [c0, c0 + T) x V vectors of the columns at gp (row stride
// cout) in registers over all pairs of the call.
template <int V, int T>
__attribute__((target("avx2,fma"), always_inline)) inline void Avx2GradWTile(
    const float* __restrict x, int64_t cin, int64_t c0, const float* __restrict gp, int64_t cout,
    const int64_t* src, const int64_t* dst, int64_t rows, float* __restrict gw) {
  __m256 acc[T][V];
  for (int t = 0; t < T; ++t) {
    for (int v = 0; v < V; ++v) acc[t][v] = _mm256_setzero_ps();
  }
  for (int64_t r = 0; r < rows; ++r) {
    if (r + kPrefetchAhead < rows) {
      const char* gn = reinterpret_cast<const char*>(gp + dst[r + kPrefetchAhead] * cout);
      for (int v = 0; v < V; v += 2) __builtin_prefetch(gn + 32 * v);
      __builtin_prefetch(x + src[r + kPrefetchAhead] * cin + c0);
    }
    const float* gr = gp + dst[r] * cout;
    const float* xr = x + src[r] * cin + c0;
    __m256 gv[V];
    for (int v = 0; v < V; ++v) gv[v] = _mm256_loadu_ps(gr + 8 * v);
    for (int t = 0; t < T; ++t) {
      const __m256 xb = _mm256_broadcast_ss(xr + t);
      for (int v = 0; v < V; ++v) acc[t][v] = _mm256_fmadd_ps(xb, gv[v], acc[t][v]);
    }
  }
  for (int t = 0; t < T; ++t) {
    float* o = gw + (c0 + t) * cout;
    for (int v = 0; v < V; ++v) {
      _mm256_storeu_ps(o + 8 * v, _mm256_add_ps(_mm256_loadu_ps(o + 8 * v), acc[t][v]));
    }
  }
}

// The last `left` < T channels: one tile of exactly that many.
template <int V, int Q>
__attribute__((target("avx2,fma"), always_inline)) inline void Avx2GradWRemainder(
    const float* x, int64_t cin, int64_t c0, int64_t left, const float* gp, int64_t cout,
    const int64_t* src, const int64_t* dst, int64_t rows, float* gw) {
  if constexpr (Q >= 1) {
    if (left == Q) {
      Avx2GradWTile<V, Q>(x, cin, c0, gp, cout, src, dst, rows, gw);
    } else {
      Avx2GradWRemainder<V, Q - 1>(x, cin, c0, left, gp, cout, src, dst, rows, gw);
    }
  }
}

template <int V, int T, int P>
__attribute__((target("avx2,fma"))) void Avx2GradW(const float* __restrict x, int64_t cin,
                                                   const float* __restrict g, const int64_t* src,
                                                   const int64_t* dst, int64_t rows,
                                                   float* __restrict gw) {
  constexpr int64_t cout = 8 * V * P;
  for (int p = 0; p < P; ++p) {
    const float* gp = g + 8 * V * p;
    float* gwp = gw + 8 * V * p;
    int64_t c0 = 0;
    for (; c0 + T <= cin; c0 += T) Avx2GradWTile<V, T>(x, cin, c0, gp, cout, src, dst, rows, gwp);
    if (c0 < cin) {
      Avx2GradWRemainder<V, T - 1>(x, cin, c0, cin - c0, gp, cout, src, dst, rows, gwp);
    }
  }
}

// Kernels per width, index P - 1: widths 16 P (6 x 2 tiles) and 24 P (4 x 3 tiles).
constexpr int kMaxDirectWidth = 256;
template <int... I>
constexpr std::array<DirectRowsFn, sizeof...(I)> Avx2RowsBy16(std::integer_sequence<int, I...>) {
  return {&Avx2Rows<2, 6, I + 1>...};
}
template <int... I>
constexpr std::array<DirectRowsFn, sizeof...(I)> Avx2RowsBy24(std::integer_sequence<int, I...>) {
  return {&Avx2Rows<3, 4, I + 1>...};
}
template <int... I>
constexpr std::array<DirectRowsFn, sizeof...(I)> Avx2GradWBy16(std::integer_sequence<int, I...>) {
  return {&Avx2GradW<2, 6, I + 1>...};
}
template <int... I>
constexpr std::array<DirectRowsFn, sizeof...(I)> Avx2GradWBy24(std::integer_sequence<int, I...>) {
  return {&Avx2GradW<3, 4, I + 1>...};
}

DirectRowsFn Avx2KernelFor(int64_t cout) {
  static constexpr auto by16 =
      Avx2RowsBy16(std::make_integer_sequence<int, kMaxDirectWidth / 16>());
  static constexpr auto by24 =
      Avx2RowsBy24(std::make_integer_sequence<int, kMaxDirectWidth / 24>());
  if (cout < 16 || cout > kMaxDirectWidth) return nullptr;
  if (cout % 48 == 0) return by24[cout / 24 - 1];
  if (cout % 16 == 0) return by16[cout / 16 - 1];
  return nullptr;
}

DirectRowsFn Avx2GradWKernelFor(int64_t cout) {
  static constexpr auto by16 =
      Avx2GradWBy16(std::make_integer_sequence<int, kMaxDirectWidth / 16>());
  static constexpr auto by24 =
      Avx2GradWBy24(std::make_integer_sequence<int, kMaxDirectWidth / 24>());
  if (cout < 16 || cout > kMaxDirectWidth) return nullptr;
  if (cout % 48 == 0) return by24[cout / 24 - 1];
  if (cout % 16 == 0) return by16[cout / 16 - 1];
  return nullptr;
}

// The direct AVX-512 forward / input-gradient kernel for this output width, or nullptr (the
// GEMM path then runs): multiples of 16 up to 256 except 176 and 208.
DirectRowsFn Avx512KernelFor(int64_t cout) {
  if (cout % 16 != 0) return nullptr;
  switch (cout / 16) {
    case 1:
      return &DirectRows<1, 16, 1>;
    case 2:
      return &DirectRows<2, 12, 1>;
    case 3:
      return &DirectRows<3, 8, 1>;
    case 4:
      return &DirectRows<4, 6, 1>;
    case 5:
      return &DirectRows<5, 5, 1>;
    case 6:
      return &DirectRows<3, 8, 2>;
    case 7:
      return &DirectRows<7, 3, 1>;
    case 8:
      return &DirectRows<4, 6, 2>;
    case 9:
      return &DirectRows<3, 8, 3>;
    case 10:
      return &DirectRows<5, 5, 2>;
    case 12:
      return &DirectRows<4, 6, 3>;
    case 14:
      return &DirectRows<7, 3, 2>;
    case 15:
      return &DirectRows<5, 5, 3>;
    case 16:
      return &DirectRows<4, 6, 4>;
    default:
      return nullptr;
  }
}

// Weight gradient of one offset, gw[cin, cout] += sum over pairs of x[src[r]]^T g[dst[r]], with
// cout = 16 V P: a tile of T input channels x V vectors stays in registers over all pairs of the
// call (<= 1024, so float sums stay short), one pass over the pairs per tile. T is the number of
// broadcasts per step, so again tall tiles (T = 8, V <= 3) run fastest.
template <int V, int T, int P>
__attribute__((target("avx512f"))) void DirectGradW(const float* __restrict x, int64_t cin,
                                                    const float* __restrict g, const int64_t* src,
                                                    const int64_t* dst, int64_t rows,
                                                    float* __restrict gw) {
  constexpr int64_t cout = 16 * V * P;
  for (int p = 0; p < P; ++p) {
    const float* gp = g + 16 * V * p;
    for (int64_t c0 = 0; c0 < cin; c0 += T) {
      __m512 acc[T][V];
      for (int t = 0; t < T; ++t) {
        for (int v = 0; v < V; ++v) acc[t][v] = _mm512_setzero_ps();
      }
      for (int64_t r = 0; r < rows; ++r) {
        if (r + kPrefetchAhead < rows) {
          const char* gn = reinterpret_cast<const char*>(gp + dst[r + kPrefetchAhead] * cout);
          for (int v = 0; v < V; ++v) __builtin_prefetch(gn + 64 * v);
          __builtin_prefetch(x + src[r + kPrefetchAhead] * cin + c0);
        }
        const float* gr = gp + dst[r] * cout;
        const float* xr = x + src[r] * cin + c0;
        __m512 gv[V];
        for (int v = 0; v < V; ++v) gv[v] = _mm512_loadu_ps(gr + 16 * v);
        for (int t = 0; t < T; ++t) {
          const __m512 xb = _mm512_set1_ps(xr[t]);
          for (int v = 0; v < V; ++v) acc[t][v] = _mm512_fmadd_ps(xb, gv[v], acc[t][v]);
        }
      }
      for (int t = 0; t < T; ++t) {
        float* o = gw + (c0 + t) * cout + 16 * V * p;
        for (int v = 0; v < V; ++v) {
          _mm512_storeu_ps(o + 16 * v, _mm512_add_ps(_mm512_loadu_ps(o + 16 * v), acc[t][v]));
        }
      }
    }
  }
}

// The AVX-512 weight-gradient kernel for these widths, or nullptr (the GEMM path then runs):
// cout 16..128 in steps of 16 and cin a multiple of the channel tile (16 for cout 16, 4 for
// cout 80, 2 for cout 112, else 8).
DirectRowsFn Avx512GradWKernelFor(int64_t cin, int64_t cout) {
  if (cout % 16 != 0 || cout < 16 || cout > 128) return nullptr;
  const int64_t v = cout / 16;
  const int64_t tile = v == 1 ? 16 : (v == 5 ? 4 : (v == 7 ? 2 : 8));
  if (cin % tile != 0) return nullptr;
  switch (v) {
    case 1:
      return &DirectGradW<1, 16, 1>;
    case 2:
      return &DirectGradW<2, 8, 1>;
    case 3:
      return &DirectGradW<3, 8, 1>;
    case 4:
      return &DirectGradW<2, 8, 2>;
    case 5:
      return &DirectGradW<5, 4, 1>;
    case 6:
      return &DirectGradW<3, 8, 2>;
    case 7:
      return &DirectGradW<7, 2, 1>;
    default:
      return &DirectGradW<2, 8, 4>;
  }
}

// ---------------------------------------------------------------------------------------
// Kernel path (AVX-512 -> AVX2 -> GEMM) and dispatch.
// ---------------------------------------------------------------------------------------
std::atomic<int> g_kernel_path{static_cast<int>(SparseKernelPath::kAuto)};

bool CpuHasAvx512() {
  static const bool yes = __builtin_cpu_supports("avx512f");
  return yes;
}
bool CpuHasAvx2Fma() {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
}

SparseKernelPath BestKernelPath() {
  if (CpuHasAvx512()) return SparseKernelPath::kAvx512;
  if (CpuHasAvx2Fma()) return SparseKernelPath::kAvx2;
  return SparseKernelPath::kGemm;
}

// The path DIMR_SPARSE_KERNELS asks for (read once), or the error message to throw.
struct EnvKernelPath {
  SparseKernelPath path = SparseKernelPath::kAuto;
  std::string error;
};

const EnvKernelPath& EnvPath() {
  static const EnvKernelPath env = [] {
    EnvKernelPath e;
    const char* v = std::getenv("DIMR_SPARSE_KERNELS");
    if (!v || !*v) return e;
    try {
      e.path = ParseSparseKernelPath(v);
    } catch (const InvalidArgument& err) {
      e.error = std::string("DIMR_SPARSE_KERNELS: ") + err.what();
      return e;
    }
    if (!SparseKernelPathSupported(e.path)) {
      e.error = std::string("DIMR_SPARSE_KERNELS=") + v + ": this CPU cannot run the " + v +
                " kernels (supported: avx512 " + (CpuHasAvx512() ? "yes" : "no") + ", avx2+fma " +
                (CpuHasAvx2Fma() ? "yes" : "no") + ")";
    }
    return e;
  }();
  return env;
}

// Forward / input-gradient kernel for this output width on the path in force, or nullptr.
DirectRowsFn DirectKernelFor(int64_t cout) {
  switch (ResolveSparseKernelPath()) {
    case SparseKernelPath::kAvx512:
      return Avx512KernelFor(cout);
    case SparseKernelPath::kAvx2:
      return Avx2KernelFor(cout);
    default:
      return nullptr;
  }
}

DirectRowsFn DirectGradWKernelFor(int64_t cin, int64_t cout) {
  switch (ResolveSparseKernelPath()) {
    case SparseKernelPath::kAvx512:
      return Avx512GradWKernelFor(cin, cout);
    case SparseKernelPath::kAvx2:
      return Avx2GradWKernelFor(cout);
    default:
      return nullptr;
  }
}

// Runs a direct kernel over the pairs [b0, b0 + n) of one offset in parallel chunks of 1024.
// `out_stride` > 0: each thread writes to out + thread * out_stride (per-thread accumulators
// of the weight gradient); 0: all write to out (rows of out are distinct within an offset).
void DirectOffset(DirectRowsFn kernel, const float* x, int64_t cin, const float* w,
                  const int64_t* src, const int64_t* dst, int64_t b0, int64_t n, float* out,
                  int64_t out_stride = 0) {
  constexpr int64_t kChunk = 1024;
  at::parallel_for(0, (n + kChunk - 1) / kChunk, 1, [&](int64_t cb, int64_t ce) {
    float* o = out + at::get_thread_num() * out_stride;
    for (int64_t ch = cb; ch < ce; ++ch) {
      const int64_t r0 = b0 + ch * kChunk, r1 = std::min(b0 + n, r0 + kChunk);
      kernel(x, cin, w, src + r0, dst + r0, r1 - r0, o);
    }
  });
}

// ---------------------------------------------------------------------------------------
// Fused CPU kernels.
// ---------------------------------------------------------------------------------------
template <typename T>
void FusedForwardImpl(const at::Tensor& x, const at::Tensor& w, const ConvPlan& p,
                      at::Tensor& out) {
  const int64_t cin = w.size(1), cout = w.size(2);
  const int64_t rows = ChunkRows(cin, cout);
  const int nthreads = at::get_num_threads();
  const DirectRowsFn direct = std::is_same_v<T, float> ? DirectKernelFor(cout) : nullptr;
  // Per-thread gather / product buffers of the GEMM path (not needed with a direct kernel).
  const at::Tensor buffers =
      direct ? at::Tensor() : at::empty({nthreads, rows * (cin + cout)}, x.options());
  const T* xp = x.data_ptr<T>();
  T* op = out.data_ptr<T>();
  const int64_t* si = p.src_idx.data_ptr<int64_t>();
  const int64_t* di = p.dst_idx.data_ptr<int64_t>();
  const int64_t kv = static_cast<int64_t>(p.offsets.size()) - 1;
  if constexpr (std::is_same_v<T, float>) {
    if (direct && p.blocks.defined()) {
      // Output-stationary: each block of output rows takes all offsets in turn, so its rows stay
      // in cache and the input rows it needs (a few neighbouring slabs of sorted sites) are read
      // from memory about once, instead of sweeping all of x and out once per offset.
      const int64_t* bt = p.blocks.data_ptr<int64_t>();
      const float* wp = w.data_ptr<float>();
      at::parallel_for(0, p.blocks.size(0) - 1, 1, [&](int64_t bb, int64_t be) {
        for (int64_t b = bb; b < be; ++b) {
          for (int64_t k = 0; k < kv; ++k) {
            const int64_t lo = bt[b * kv + k], hi = bt[(b + 1) * kv + k];
            if (hi > lo) direct(xp, cin, wp + k * cin * cout, si + lo, di + lo, hi - lo, op);
          }
        }
      });
      return;
    }
  }
  for (int64_t k = 0; k < kv; ++k) {
    const int64_t b0 = p.offsets[k], n = p.offsets[k + 1] - b0;
    if (n == 0) continue;
    const at::Tensor wk = w.select(0, k);
    if (k == p.identity && n == p.n_src && n == p.n_dst) {
      out.addmm_(x, wk);
      continue;
    }
    if constexpr (std::is_same_v<T, float>) {
      if (direct) {
        DirectOffset(direct, xp, cin, wk.data_ptr<float>(), si, di, b0, n, op);
        continue;
      }
    }
    const int64_t nchunks = (n + rows - 1) / rows;
    at::parallel_for(0, nchunks, 1, [&](int64_t cb, int64_t ce) {
      at::NoGradGuard no_grad;
      const int tid = at::get_thread_num();
      T* abuf = buffers.data_ptr<T>() + tid * rows * (cin + cout);
      T* bbuf = abuf + rows * cin;
      for (int64_t ch = cb; ch < ce; ++ch) {
        const int64_t r0 = b0 + ch * rows;
        const int64_t m = std::min(rows, b0 + n - r0);
        GatherRows(abuf, xp, si + r0, m, cin);
        at::Tensor a = at::from_blob(abuf, {m, cin}, x.options());
        at::Tensor bt = at::from_blob(bbuf, {m, cout}, x.options());
        at::mm_out(bt, a, wk);
        ScatterAddRows(op, bbuf, di + r0, m, cout);
      }
    });
  }
}

template <typename T>
void FusedBackwardImpl(const at::Tensor& x, const at::Tensor& w, const at::Tensor& gout,
                       const ConvPlan& p, at::Tensor* gx, at::Tensor* gw) {
  const int64_t cin = w.size(1), cout = w.size(2);
  const int64_t rows = ChunkRows(cin, cout);
  const int nthreads = at::get_num_threads();
  const int64_t kv = static_cast<int64_t>(p.offsets.size()) - 1;
  // Input gradient gx[src] += g[dst] * W_k^T: the direct kernel of width cin on the transposed
  // weights where it applies, else a GEMM per chunk below.
  const DirectRowsFn direct = gx && std::is_same_v<T, float> ? DirectKernelFor(cin) : nullptr;
  // Weight gradient: the direct kernel into the per-thread accumulators, else a GEMM per chunk.
  const DirectRowsFn direct_w =
      gw && std::is_same_v<T, float> ? DirectGradWKernelFor(cin, cout) : nullptr;
  const bool all_direct = (direct || !gx) && (direct_w || !gw);
  const bool blocked =
      std::is_same_v<T, float> && all_direct && p.blocks.defined() && (!gx || p.mirror_symmetric);
  const at::Tensor wt = direct && !blocked ? w.transpose(1, 2).contiguous() : at::Tensor();
  // GEMM path, per thread: gathered grad_out [rows, cout], gathered x [rows, cin], product
  // [rows, cin].
  const at::Tensor buffers =
      all_direct ? at::Tensor() : at::empty({nthreads, rows * (cout + 2 * cin)}, x.options());
  at::Tensor acc;
  if (gw) acc = at::zeros({nthreads, kv, cin, cout}, x.options());
  const T* xp = x.data_ptr<T>();
  const T* gp = gout.data_ptr<T>();
  T* gxp = gx ? gx->data_ptr<T>() : nullptr;
  const int64_t* si = p.src_idx.data_ptr<int64_t>();
  const int64_t* di = p.dst_idx.data_ptr<int64_t>();
  if constexpr (std::is_same_v<T, float>) {
    if (blocked) {
      // Output-stationary over blocks of output rows, as in the forward. The input gradient
      // gx[s] += g[d] W_k^T of the pairs (s, d) of offset k is, by the mirror symmetry, a
      // forward over the pairs (d, s) of offset kv - 1 - k: gx[row] gathers from g through the
      // same output-sorted pairs, with the weights W_{kv-1-j}^T for offset j.
      const at::Tensor wm = gx ? w.flip(0).transpose(1, 2).contiguous() : at::Tensor();
      const float* wmp = gx ? wm.data_ptr<float>() : nullptr;
      const int64_t* bt = p.blocks.data_ptr<int64_t>();
      float* accp = gw ? acc.data_ptr<float>() : nullptr;
      at::parallel_for(0, p.blocks.size(0) - 1, 1, [&](int64_t bb, int64_t be) {
        float* acct = gw ? accp + at::get_thread_num() * kv * cin * cout : nullptr;
        for (int64_t b = bb; b < be; ++b) {
          for (int64_t k = 0; k < kv; ++k) {
            const int64_t lo = bt[b * kv + k], n = bt[(b + 1) * kv + k] - lo;
            if (n <= 0) continue;
            if (gx) direct(gp, cout, wmp + k * cin * cout, si + lo, di + lo, n, gxp);
            if (gw) direct_w(xp, cin, gp, si + lo, di + lo, n, acct + k * cin * cout);
          }
        }
      });
      if (gw) gw->add_(acc.sum(0));
      return;
    }
  }
  for (int64_t k = 0; k < kv; ++k) {
    const int64_t b0 = p.offsets[k], n = p.offsets[k + 1] - b0;
    if (n == 0) continue;
    const at::Tensor wk = w.select(0, k);
    const at::Tensor wkt = wk.t();
    if (k == p.identity && n == p.n_src && n == p.n_dst) {
      if (gx) gx->addmm_(gout, wkt);
      if (gw) gw->select(0, k).addmm_(x.t(), gout);
      continue;
    }
    if constexpr (std::is_same_v<T, float>) {
      if (direct) {
        DirectOffset(direct, gp, cout, wt.select(0, k).data_ptr<float>(), di, si, b0, n, gxp);
      }
      if (direct_w) {
        DirectOffset(direct_w, xp, cin, gp, si, di, b0, n, acc.data_ptr<float>() + k * cin * cout,
                     kv * cin * cout);
      }
      if (all_direct) continue;
    }
    const int64_t nchunks = (n + rows - 1) / rows;
    at::parallel_for(0, nchunks, 1, [&](int64_t cb, int64_t ce) {
      at::NoGradGuard no_grad;
      const int tid = at::get_thread_num();
      T* gbuf = buffers.data_ptr<T>() + tid * rows * (cout + 2 * cin);
      T* xbuf = gbuf + rows * cout;
      T* dbuf = xbuf + rows * cin;
      at::Tensor acck;
      if (gw) acck = acc.select(0, tid).select(0, k);
      for (int64_t ch = cb; ch < ce; ++ch) {
        const int64_t r0 = b0 + ch * rows;
        const int64_t m = std::min(rows, b0 + n - r0);
        GatherRows(gbuf, gp, di + r0, m, cout);
        at::Tensor g = at::from_blob(gbuf, {m, cout}, x.options());
        if (gx && !direct) {
          at::Tensor d = at::from_blob(dbuf, {m, cin}, x.options());
          at::mm_out(d, g, wkt);
          ScatterAddRows(gxp, dbuf, si + r0, m, cin);
        }
        if (gw && !direct_w) {
          GatherRows(xbuf, xp, si + r0, m, cin);
          at::Tensor a = at::from_blob(xbuf, {m, cin}, x.options());
          acck.addmm_(a.t(), g);
        }
      }
    });
  }
  if (gw) gw->add_(acc.sum(0));
}

// ---------------------------------------------------------------------------------------
// torch-ops kernels (any device).
// ---------------------------------------------------------------------------------------
at::Tensor TorchOpsForward(const at::Tensor& x, const at::Tensor& w, const ConvPlan& p) {
  at::Tensor out = at::zeros({p.n_dst, w.size(2)}, x.options());
  const int64_t kv = static_cast<int64_t>(p.offsets.size()) - 1;
  for (int64_t k = 0; k < kv; ++k) {
    const int64_t b0 = p.offsets[k], n = p.offsets[k + 1] - b0;
    if (n == 0) continue;
    at::Tensor si = p.src_idx.narrow(0, b0, n), di = p.dst_idx.narrow(0, b0, n);
    out.index_add_(0, di, x.index_select(0, si).mm(w.select(0, k)));
  }
  return out;
}

void TorchOpsBackward(const at::Tensor& x, const at::Tensor& w, const at::Tensor& gout,
                      const ConvPlan& p, at::Tensor* gx, at::Tensor* gw) {
  const int64_t kv = static_cast<int64_t>(p.offsets.size()) - 1;
  for (int64_t k = 0; k < kv; ++k) {
    const int64_t b0 = p.offsets[k], n = p.offsets[k + 1] - b0;
    if (n == 0) continue;
    at::Tensor si = p.src_idx.narrow(0, b0, n), di = p.dst_idx.narrow(0, b0, n);
    at::Tensor g = gout.index_select(0, di);
    if (gx) gx->index_add_(0, si, g.mm(w.select(0, k).t()));
    if (gw) gw->select(0, k).copy_(x.index_select(0, si).t().mm(g));
  }
}

bool UseFused(SparseBackend requested, const at::Device& device) {
  SparseBackend b = requested == SparseBackend::kAuto ? ResolveSparseBackend(device) : requested;
  if (b == SparseBackend::kFused && !device.is_cpu()) {
    throw InvalidArgument("sparse ops: the fused backend runs on CPU tensors only, got " +
                          device.str());
  }
  return b == SparseBackend::kFused;
}

class ConvFunction : public torch::autograd::Function<ConvFunction> {
 public:
  static at::Tensor forward(AutogradContext* ctx, const at::Tensor& x, const at::Tensor& w,
                            const at::Tensor& src_idx, const at::Tensor& dst_idx,
                            const at::Tensor& blocks, std::vector<int64_t> meta, bool fused) {
    // meta = [identity, n_src, n_dst, mirror_symmetric, offsets...]; blocks may be undefined.
    ConvPlan p = PlanFromMeta(src_idx, dst_idx, blocks, meta);
    at::Tensor xc = x.detach().contiguous();
    at::Tensor wc = w.detach().contiguous();
    at::Tensor out;
    if (fused) {
      out = at::zeros({p.n_dst, wc.size(2)}, xc.options());
      AT_DISPATCH_FLOATING_TYPES(xc.scalar_type(), "sparse_conv_forward",
                                 [&] { FusedForwardImpl<scalar_t>(xc, wc, p, out); });
    } else {
      out = TorchOpsForward(xc, wc, p);
    }
    ctx->save_for_backward({x, w, src_idx, dst_idx});
    ctx->saved_data["meta"] = meta;
    if (p.blocks.defined()) ctx->saved_data["blocks"] = p.blocks;
    ctx->saved_data["fused"] = fused;
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const at::Tensor x = saved[0].detach().contiguous();
    const at::Tensor w = saved[1].detach().contiguous();
    std::vector<int64_t> meta = ctx->saved_data["meta"].toIntVector();
    const bool fused = ctx->saved_data["fused"].toBool();
    const at::Tensor blocks =
        ctx->saved_data.count("blocks") ? ctx->saved_data["blocks"].toTensor() : at::Tensor();
    ConvPlan p = PlanFromMeta(saved[2], saved[3], blocks, meta);
    const at::Tensor g = grads[0].detach().contiguous();
    const bool need_x = ctx->needs_input_grad(0), need_w = ctx->needs_input_grad(1);
    at::Tensor gx, gw;
    if (need_x) gx = at::zeros_like(x);
    if (need_w) gw = at::zeros_like(w);
    if (need_x || need_w) {
      if (fused) {
        AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "sparse_conv_backward", [&] {
          FusedBackwardImpl<scalar_t>(x, w, g, p, need_x ? &gx : nullptr, need_w ? &gw : nullptr);
        });
      } else {
        TorchOpsBackward(x, w, g, p, need_x ? &gx : nullptr, need_w ? &gw : nullptr);
      }
    }
    return {gx, gw, at::Tensor(), at::Tensor(), at::Tensor(), at::Tensor(), at::Tensor()};
  }

 private:
  static ConvPlan PlanFromMeta(const at::Tensor& src, const at::Tensor& dst,
                               const at::Tensor& blocks, const std::vector<int64_t>& meta) {
    ConvPlan p;
    p.src_idx = src;
    p.dst_idx = dst;
    if (blocks.defined() && blocks.numel() > 0) p.blocks = blocks;
    p.identity = meta[0];
    p.n_src = meta[1];
    p.n_dst = meta[2];
    p.mirror_symmetric = meta[3] != 0;
    p.offsets.assign(meta.begin() + 4, meta.end());
    return p;
  }
};

void CheckFeatures(const at::Tensor& f, const char* op) {
  if (f.dim() != 2) {
    throw InvalidArgument(std::string(op) + ": features must be [N, C], got " + Shape(f));
  }
  if (!at::isFloatingType(f.scalar_type()) || f.scalar_type() == at::kHalf ||
      f.scalar_type() == at::kBFloat16) {
    throw InvalidArgument(std::string(op) + ": features must be float32 or float64");
  }
}

void CheckConvWeight(const at::Tensor& w, int64_t k, int64_t cin, const char* op) {
  if (w.dim() != 5 || w.size(0) != k || w.size(1) != k || w.size(2) != k || w.size(3) != cin) {
    std::ostringstream os;
    os << op << ": weight must be [" << k << ", " << k << ", " << k << ", " << cin
       << ", Cout], got " << w.sizes();
    throw InvalidArgument(os.str());
  }
}

// ---------------------------------------------------------------------------------------
// Segment pooling.
// ---------------------------------------------------------------------------------------
struct Csr {
  std::vector<int64_t> offsets;  // S + 1
  std::vector<int64_t> rows;
};

Csr BuildCsr(const at::Tensor& segment_cpu, int64_t num_segments) {
  const int64_t n = segment_cpu.size(0);
  const int64_t* s = segment_cpu.data_ptr<int64_t>();
  Csr csr;
  csr.offsets.assign(num_segments + 1, 0);
  for (int64_t i = 0; i < n; ++i) {
    if (s[i] < 0 || s[i] >= num_segments) {
      throw InvalidArgument("segment pool: row " + std::to_string(i) + " has segment " +
                            std::to_string(s[i]) + " outside [0, " + std::to_string(num_segments) +
                            ")");
    }
    ++csr.offsets[s[i] + 1];
  }
  for (int64_t j = 0; j < num_segments; ++j) csr.offsets[j + 1] += csr.offsets[j];
  csr.rows.resize(n);
  std::vector<int64_t> fill(csr.offsets.begin(), csr.offsets.end() - 1);
  for (int64_t i = 0; i < n; ++i) csr.rows[fill[s[i]]++] = i;
  return csr;
}

class SegmentPoolFunction : public torch::autograd::Function<SegmentPoolFunction> {
 public:
  static at::Tensor forward(AutogradContext* ctx, const at::Tensor& x, const at::Tensor& segment,
                            int64_t num_segments, bool is_max) {
    at::Tensor xc = x.detach().contiguous();
    Csr csr = BuildCsr(segment.to(at::kCPU, at::kLong).contiguous(), num_segments);
    const int64_t c = xc.size(1);
    at::Tensor out = at::zeros({num_segments, c}, xc.options());
    at::Tensor arg = at::full({num_segments, c}, -1, at::kLong);
    AT_DISPATCH_FLOATING_TYPES(xc.scalar_type(), "segment_pool_forward", [&] {
      const scalar_t* xp = xc.data_ptr<scalar_t>();
      scalar_t* op = out.data_ptr<scalar_t>();
      int64_t* ap = arg.data_ptr<int64_t>();
      at::parallel_for(0, num_segments, 16, [&](int64_t sb, int64_t se) {
        for (int64_t s = sb; s < se; ++s) {
          const int64_t r0 = csr.offsets[s], r1 = csr.offsets[s + 1];
          if (r0 == r1) continue;
          scalar_t* o = op + s * c;
          if (is_max) {
            int64_t* a = ap + s * c;
            for (int64_t j = 0; j < c; ++j) {
              o[j] = -std::numeric_limits<scalar_t>::infinity();
            }
            for (int64_t r = r0; r < r1; ++r) {
              const int64_t row = csr.rows[r];
              const scalar_t* xr = xp + row * c;
              for (int64_t j = 0; j < c; ++j) {
                if (xr[j] > o[j] || a[j] < 0) {
                  o[j] = xr[j];
                  a[j] = row;
                }
              }
            }
          } else {
            for (int64_t r = r0; r < r1; ++r) {
              const scalar_t* xr = xp + csr.rows[r] * c;
              for (int64_t j = 0; j < c; ++j) o[j] += xr[j];
            }
            const scalar_t inv = scalar_t(1) / static_cast<scalar_t>(r1 - r0);
            for (int64_t j = 0; j < c; ++j) o[j] *= inv;
          }
        }
      });
    });
    at::Tensor counts = at::empty({num_segments}, at::kLong);
    int64_t* cp = counts.data_ptr<int64_t>();
    for (int64_t s = 0; s < num_segments; ++s) cp[s] = csr.offsets[s + 1] - csr.offsets[s];
    ctx->save_for_backward({segment.to(at::kCPU, at::kLong).contiguous(), arg, counts});
    ctx->saved_data["n"] = xc.size(0);
    ctx->saved_data["is_max"] = is_max;
    return out;
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const at::Tensor seg = saved[0], arg = saved[1], counts = saved[2];
    const int64_t n = ctx->saved_data["n"].toInt();
    const bool is_max = ctx->saved_data["is_max"].toBool();
    const at::Tensor g = grads[0].detach().contiguous();
    const int64_t c = g.size(1), ns = g.size(0);
    at::Tensor gx = at::zeros({n, c}, g.options());
    AT_DISPATCH_FLOATING_TYPES(g.scalar_type(), "segment_pool_backward", [&] {
      const scalar_t* gp = g.data_ptr<scalar_t>();
      scalar_t* xp = gx.data_ptr<scalar_t>();
      if (is_max) {
        const int64_t* ap = arg.data_ptr<int64_t>();
        at::parallel_for(0, ns, 16, [&](int64_t sb, int64_t se) {
          for (int64_t s = sb; s < se; ++s) {
            for (int64_t j = 0; j < c; ++j) {
              const int64_t row = ap[s * c + j];
              if (row >= 0) xp[row * c + j] += gp[s * c + j];
            }
          }
        });
      } else {
        const int64_t* sp = seg.data_ptr<int64_t>();
        const int64_t* cp = counts.data_ptr<int64_t>();
        at::parallel_for(0, n, 256, [&](int64_t rb, int64_t re) {
          for (int64_t i = rb; i < re; ++i) {
            const scalar_t inv = scalar_t(1) / static_cast<scalar_t>(cp[sp[i]]);
            for (int64_t j = 0; j < c; ++j) xp[i * c + j] = gp[sp[i] * c + j] * inv;
          }
        });
      }
    });
    return {gx, at::Tensor(), at::Tensor(), at::Tensor()};
  }
};

// ---------------------------------------------------------------------------------------
// Voxel mean / gather over a CSR voxel map.
// ---------------------------------------------------------------------------------------
// Per voxel v: out[v] = scale_v * sum over its points of in[point]  (scale 1/count or 1).
template <typename T>
void VoxelReduce(const T* in, T* out, const int64_t* off, const int64_t* pts, int64_t m, int64_t c,
                 bool mean) {
  at::parallel_for(0, m, 64, [&](int64_t vb, int64_t ve) {
    for (int64_t v = vb; v < ve; ++v) {
      T* o = out + v * c;
      for (int64_t j = 0; j < c; ++j) o[j] = T(0);
      for (int64_t r = off[v]; r < off[v + 1]; ++r) {
        const T* x = in + pts[r] * c;
        for (int64_t j = 0; j < c; ++j) o[j] += x[j];
      }
      if (mean && off[v + 1] > off[v]) {
        const T inv = T(1) / static_cast<T>(off[v + 1] - off[v]);
        for (int64_t j = 0; j < c; ++j) o[j] *= inv;
      }
    }
  });
}

// Per point i: out[i] = scale * in[p2v[i]].
template <typename T>
void PointGather(const T* in, T* out, const int64_t* p2v, const int64_t* off, int64_t n, int64_t c,
                 bool mean) {
  at::parallel_for(0, n, 256, [&](int64_t ib, int64_t ie) {
    for (int64_t i = ib; i < ie; ++i) {
      const int64_t v = p2v[i];
      const T s = mean ? T(1) / static_cast<T>(off[v + 1] - off[v]) : T(1);
      const T* x = in + v * c;
      T* o = out + i * c;
      for (int64_t j = 0; j < c; ++j) o[j] = x[j] * s;
    }
  });
}

at::Tensor RunVoxelReduce(const at::Tensor& x, const at::Tensor& off, const at::Tensor& pts,
                          bool mean) {
  const int64_t m = off.size(0) - 1;
  at::Tensor out = at::empty({m, x.size(1)}, x.options());
  AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "voxel_reduce", [&] {
    VoxelReduce<scalar_t>(x.data_ptr<scalar_t>(), out.data_ptr<scalar_t>(), off.data_ptr<int64_t>(),
                          pts.data_ptr<int64_t>(), m, x.size(1), mean);
  });
  return out;
}

at::Tensor RunPointGather(const at::Tensor& x, const at::Tensor& p2v, const at::Tensor& off,
                          bool mean) {
  const int64_t n = p2v.size(0);
  at::Tensor out = at::empty({n, x.size(1)}, x.options());
  AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "point_gather", [&] {
    PointGather<scalar_t>(x.data_ptr<scalar_t>(), out.data_ptr<scalar_t>(), p2v.data_ptr<int64_t>(),
                          off.data_ptr<int64_t>(), n, x.size(1), mean);
  });
  return out;
}

class VoxelMeanFunction : public torch::autograd::Function<VoxelMeanFunction> {
 public:
  static at::Tensor forward(AutogradContext* ctx, const at::Tensor& x, const at::Tensor& p2v,
                            const at::Tensor& off, const at::Tensor& pts) {
    ctx->save_for_backward({p2v, off, pts});
    return RunVoxelReduce(x.detach().contiguous(), off, pts, true);
  }
  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto s = ctx->get_saved_variables();
    return {RunPointGather(grads[0].detach().contiguous(), s[0], s[1], true), at::Tensor(),
            at::Tensor(), at::Tensor()};
  }
};

class DevoxelizeFunction : public torch::autograd::Function<DevoxelizeFunction> {
 public:
  static at::Tensor forward(AutogradContext* ctx, const at::Tensor& x, const at::Tensor& p2v,
                            const at::Tensor& off, const at::Tensor& pts) {
    ctx->save_for_backward({p2v, off, pts});
    return RunPointGather(x.detach().contiguous(), p2v, off, false);
  }
  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    auto s = ctx->get_saved_variables();
    return {RunVoxelReduce(grads[0].detach().contiguous(), s[1], s[2], false), at::Tensor(),
            at::Tensor(), at::Tensor()};
  }
};

}  // namespace

void SetSparseKernelPath(SparseKernelPath path) {
  if (!SparseKernelPathSupported(path)) {
    throw InvalidArgument(std::string("sparse kernels: this CPU cannot run the ") +
                          SparseKernelPathName(path) + " kernels");
  }
  g_kernel_path = static_cast<int>(path);
}

SparseKernelPath GetSparseKernelPath() {
  return static_cast<SparseKernelPath>(g_kernel_path.load());
}

SparseKernelPath ResolveSparseKernelPath() {
  const SparseKernelPath set = GetSparseKernelPath();
  if (set != SparseKernelPath::kAuto) return set;
  const EnvKernelPath& env = EnvPath();
  if (!env.error.empty()) throw InvalidArgument(env.error);
  return env.path == SparseKernelPath::kAuto ? BestKernelPath() : env.path;
}

bool SparseKernelPathSupported(SparseKernelPath path) {
  switch (path) {
    case SparseKernelPath::kAvx512:
      return CpuHasAvx512();
    case SparseKernelPath::kAvx2:
      return CpuHasAvx2Fma();
    default:
      return true;
  }
}

const char* SparseKernelPathName(SparseKernelPath path) {
  switch (path) {
    case SparseKernelPath::kAvx512:
      return "avx512";
    case SparseKernelPath::kAvx2:
      return "avx2";
    case SparseKernelPath::kGemm:
      return "gemm";
    default:
      return "auto";
  }
}

SparseKernelPath ParseSparseKernelPath(const std::string& name) {
  for (SparseKernelPath p : {SparseKernelPath::kAuto, SparseKernelPath::kAvx512,
                             SparseKernelPath::kAvx2, SparseKernelPath::kGemm}) {
    if (name == SparseKernelPathName(p)) return p;
  }
  throw InvalidArgument("sparse kernels: unknown path '" + name +
                        "' (expected auto, avx512, avx2 or gemm)");
}

std::vector<SparseKernelPath> SupportedSparseKernelPaths() {
  std::vector<SparseKernelPath> out;
  for (SparseKernelPath p :
       {SparseKernelPath::kAvx512, SparseKernelPath::kAvx2, SparseKernelPath::kGemm}) {
    if (SparseKernelPathSupported(p)) out.push_back(p);
  }
  return out;
}

void SetSparseBackend(SparseBackend backend) { g_backend = static_cast<int>(backend); }
SparseBackend GetSparseBackend() { return static_cast<SparseBackend>(g_backend.load()); }

SparseBackend ResolveSparseBackend(const at::Device& device) {
  const SparseBackend b = GetSparseBackend();
  if (b != SparseBackend::kAuto) return b;
  return device.is_cpu() ? SparseBackend::kFused : SparseBackend::kTorchOps;
}

at::Tensor RulebookConv(const at::Tensor& features, const at::Tensor& weight, const Rulebook& rb,
                        bool transpose, SparseBackend backend) {
  CheckFeatures(features, "sparse conv");
  const int64_t n_src = transpose ? rb.num_out : rb.num_in;
  if (weight.dim() != 3 || weight.size(0) != rb.kernel_volume ||
      weight.size(1) != features.size(1) || features.size(0) != n_src) {
    std::ostringstream os;
    os << "sparse conv: features " << features.sizes() << " / weight " << weight.sizes()
       << " do not fit a rulebook with " << rb.kernel_volume << " offsets and " << n_src
       << " input sites";
    throw InvalidArgument(os.str());
  }
  if (weight.scalar_type() != features.scalar_type() || weight.device() != features.device()) {
    throw InvalidArgument("sparse conv: weight and features differ in dtype or device");
  }
  const bool fused = UseFused(backend, features.device());
  ConvPlan p = MakePlan(rb, transpose, features.device());
  std::vector<int64_t> meta{p.identity, p.n_src, p.n_dst, p.mirror_symmetric ? 1 : 0};
  meta.insert(meta.end(), p.offsets.begin(), p.offsets.end());
  // (autograd functions take no undefined tensors: an empty one stands for "no blocks")
  const at::Tensor blocks = p.blocks.defined() ? p.blocks : at::empty({0}, at::kLong);
  return ConvFunction::apply(features, weight, p.src_idx, p.dst_idx, blocks, meta, fused);
}

SparseTensor SubMConv3d(const SparseTensor& x, const at::Tensor& weight) {
  const at::Tensor& f = x.features();
  CheckFeatures(f, "SubMConv3d");
  const int64_t k = weight.dim() == 5 ? weight.size(0) : -1;
  if (k != 1 && k != 3) {
    throw InvalidArgument("SubMConv3d: kernel size must be 1 or 3, weight " + Shape(weight));
  }
  CheckConvWeight(weight, k, f.size(1), "SubMConv3d");
  const int64_t cin = weight.size(3), cout = weight.size(4);
  if (k == 1) return x.WithFeatures(f.mm(weight.reshape({cin, cout})));
  const Rulebook& rb = x.context()->Subm3(x.stride());
  return x.WithFeatures(RulebookConv(f, weight.reshape({27, cin, cout}), rb, false));
}

SparseTensor SparseConv3dDown(const SparseTensor& x, const at::Tensor& weight) {
  const at::Tensor& f = x.features();
  CheckFeatures(f, "SparseConv3d");
  CheckConvWeight(weight, 2, f.size(1), "SparseConv3d");
  const Rulebook& rb = x.context()->Down(x.stride());
  at::Tensor out = RulebookConv(f, weight.reshape({8, weight.size(3), weight.size(4)}), rb, false);
  return SparseTensor(out, 2 * x.stride(), x.context());
}

SparseTensor SparseInverseConv3d(const SparseTensor& x, const at::Tensor& weight) {
  const at::Tensor& f = x.features();
  CheckFeatures(f, "SparseInverseConv3d");
  CheckConvWeight(weight, 2, f.size(1), "SparseInverseConv3d");
  if (x.stride() < 2 || x.stride() % 2 != 0 || !x.context()->has_level(x.stride() / 2)) {
    throw InvalidArgument("SparseInverseConv3d: input stride " + std::to_string(x.stride()) +
                          " has no paired finer level");
  }
  const int64_t fine = x.stride() / 2;
  const Rulebook& rb = x.context()->Down(fine);
  at::Tensor out = RulebookConv(f, weight.reshape({8, weight.size(3), weight.size(4)}), rb, true);
  return SparseTensor(out, fine, x.context());
}

SparseTensor LeakyRelu(const SparseTensor& x, double negative_slope) {
  return x.WithFeatures(at::leaky_relu(x.features(), negative_slope));
}

SparseTensor Concat(const std::vector<SparseTensor>& xs) {
  if (xs.empty()) throw InvalidArgument("sparse concat: no tensors");
  std::vector<at::Tensor> fs;
  for (const auto& x : xs) {
    if (x.context() != xs[0].context() || x.stride() != xs[0].stride()) {
      throw InvalidArgument("sparse concat: tensors are not on the same sites");
    }
    fs.push_back(x.features());
  }
  return xs[0].WithFeatures(at::cat(fs, 1));
}

at::Tensor SegmentPool(const at::Tensor& features, const at::Tensor& segment, int64_t num_segments,
                       PoolMode mode, SparseBackend backend) {
  CheckFeatures(features, "segment pool");
  if (segment.dim() != 1 || segment.size(0) != features.size(0) || num_segments < 0) {
    throw InvalidArgument("segment pool: segment ids must be [N] for features " + Shape(features));
  }
  const bool is_max = mode == PoolMode::kMax;
  if (UseFused(backend, features.device())) {
    return SegmentPoolFunction::apply(features, segment, num_segments, is_max);
  }
  at::Tensor seg = segment.to(features.device(), at::kLong);
  at::Tensor zeros = at::zeros({num_segments, features.size(1)}, features.options());
  if (is_max) {
    at::Tensor idx = seg.unsqueeze(1).expand_as(features);
    return zeros.scatter_reduce(0, idx, features, "amax", /*include_self=*/false);
  }
  at::Tensor counts = at::zeros({num_segments}, features.options())
                          .index_add_(0, seg, at::ones({seg.size(0)}, features.options()));
  return zeros.index_add(0, seg, features) / counts.clamp_min(1).unsqueeze(1);
}

at::Tensor BatchPool(const SparseTensor& x, PoolMode mode) {
  at::Tensor seg = x.coords().select(1, 0).to(at::kLong);
  return SegmentPool(x.features(), seg, x.batch_size(), mode);
}

at::Tensor PointVoxelCoords(const at::Tensor& points, const at::Tensor& batch, double scale) {
  if (points.dim() != 2 || points.size(1) != 3 || batch.dim() != 1 ||
      batch.size(0) != points.size(0) || !(scale > 0)) {
    throw InvalidArgument("voxelise: need points [N, 3], batch [N] and scale > 0, got points " +
                          Shape(points) + ", batch " + Shape(batch));
  }
  at::Tensor p = points.detach().to(at::kCPU, at::kDouble).contiguous();
  at::Tensor b = batch.to(at::kCPU, at::kLong).contiguous();
  const int64_t n = p.size(0);
  const double* pp = p.data_ptr<double>();
  const int64_t* bp = b.data_ptr<int64_t>();
  int64_t nb = 0;
  for (int64_t i = 0; i < n; ++i) {
    if (bp[i] < 0)
      throw InvalidArgument("voxelise: negative batch index at point " + std::to_string(i));
    nb = std::max(nb, bp[i] + 1);
  }
  std::vector<double> mins(3 * nb, std::numeric_limits<double>::infinity());
  for (int64_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double q = scale * pp[3 * i + a];
      if (!std::isfinite(q)) {
        throw InvalidArgument("voxelise: point " + std::to_string(i) + " is not finite");
      }
      mins[3 * bp[i] + a] = std::min(mins[3 * bp[i] + a], q);
    }
  }
  at::Tensor out = at::empty({n, 4}, at::kInt);
  int32_t* op = out.data_ptr<int32_t>();
  for (int64_t i = 0; i < n; ++i) {
    op[4 * i] = static_cast<int32_t>(bp[i]);
    for (int a = 0; a < 3; ++a) {
      const double v = std::floor(scale * pp[3 * i + a] - mins[3 * bp[i] + a]);
      if (v > 65535) {
        throw InvalidArgument("voxelise: point " + std::to_string(i) +
                              " lies more than 65535 voxels from the scene minimum");
      }
      op[4 * i + 1 + a] = static_cast<int32_t>(v);
    }
  }
  return out;
}

VoxelMap BuildVoxelMap(const at::Tensor& point_coords) {
  if (point_coords.dim() != 2 || point_coords.size(1) != 4) {
    throw InvalidArgument("voxelise: point coords must be [N, 4] (b, x, y, z), got " +
                          Shape(point_coords));
  }
  at::Tensor c = point_coords.to(at::kCPU, at::kInt).contiguous();
  const int64_t n = c.size(0);
  const int32_t* cp = c.data_ptr<int32_t>();
  for (int64_t i = 0; i < 4 * n; ++i) {
    if (cp[i] < 0 || cp[i] > 65535) {
      throw InvalidArgument("voxelise: point " + std::to_string(i / 4) +
                            " has a coordinate outside [0, 65535]");
    }
  }
  VoxelMap map;
  map.point_to_voxel = at::empty({n}, at::kLong);
  int64_t* p2v = map.point_to_voxel.data_ptr<int64_t>();
  // Voxels numbered in (b, x, y, z) order (the packed key's order): neighbouring sites get nearby
  // rows, so the sparse kernels' row gathers / scatters stream through memory instead of jumping
  // (the fused SubM3 forward on a 2 cm room: 1.3x faster than first-occurrence order).
  std::vector<uint64_t> keys(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) {
    const int32_t* s = cp + 4 * i;
    keys[i] = SiteHash::Pack(s[0], s[1], s[2], s[3]);
  }
  std::vector<int64_t> voxel_of_point;
  const std::vector<uint64_t> voxels = SortedUniqueKeys(keys, &voxel_of_point);
  const int64_t m = static_cast<int64_t>(voxels.size());
  std::copy(voxel_of_point.begin(), voxel_of_point.end(), p2v);
  map.voxel_coords = CoordsOfKeys(voxels);
  map.voxel_offsets = at::zeros({m + 1}, at::kLong);
  int64_t* off = map.voxel_offsets.data_ptr<int64_t>();
  for (int64_t i = 0; i < n; ++i) ++off[p2v[i] + 1];
  for (int64_t v = 0; v < m; ++v) off[v + 1] += off[v];
  map.voxel_points = at::empty({n}, at::kLong);
  int64_t* pts = map.voxel_points.data_ptr<int64_t>();
  std::vector<int64_t> fill(off, off + m);
  for (int64_t i = 0; i < n; ++i) pts[fill[p2v[i]]++] = i;
  return map;
}

at::Tensor VoxelMean(const at::Tensor& point_features, const VoxelMap& map, SparseBackend backend) {
  CheckFeatures(point_features, "voxel mean");
  if (point_features.size(0) != map.point_to_voxel.size(0)) {
    throw InvalidArgument("voxel mean: " + std::to_string(point_features.size(0)) +
                          " feature rows for a map of " +
                          std::to_string(map.point_to_voxel.size(0)) + " points");
  }
  if (UseFused(backend, point_features.device())) {
    return VoxelMeanFunction::apply(point_features, map.point_to_voxel, map.voxel_offsets,
                                    map.voxel_points);
  }
  const auto dev = point_features.device();
  at::Tensor p2v = map.point_to_voxel.to(dev);
  at::Tensor counts = (map.voxel_offsets.narrow(0, 1, map.num_voxels()) -
                       map.voxel_offsets.narrow(0, 0, map.num_voxels()))
                          .to(dev, point_features.scalar_type());
  at::Tensor sums = at::zeros({map.num_voxels(), point_features.size(1)}, point_features.options())
                        .index_add(0, p2v, point_features);
  return sums / counts.unsqueeze(1);
}

at::Tensor Devoxelize(const at::Tensor& voxel_features, const VoxelMap& map,
                      SparseBackend backend) {
  CheckFeatures(voxel_features, "devoxelise");
  if (voxel_features.size(0) != map.num_voxels()) {
    throw InvalidArgument("devoxelise: " + std::to_string(voxel_features.size(0)) +
                          " voxel rows for a map of " + std::to_string(map.num_voxels()) +
                          " voxels");
  }
  if (UseFused(backend, voxel_features.device())) {
    return DevoxelizeFunction::apply(voxel_features, map.point_to_voxel, map.voxel_offsets,
                                     map.voxel_points);
  }
  return voxel_features.index_select(0, map.point_to_voxel.to(voxel_features.device()));
}

Voxelized Voxelize(const at::Tensor& point_coords, const at::Tensor& point_features,
                   int64_t batch_size, std::array<int64_t, 3> min_spatial_shape) {
  VoxelMap map = BuildVoxelMap(point_coords);
  std::array<int64_t, 3> shape = min_spatial_shape;
  if (map.num_voxels() > 0) {
    at::Tensor mx = std::get<0>(map.voxel_coords.max(0));
    for (int a = 0; a < 3; ++a) shape[a] = std::max<int64_t>(shape[a], mx[a + 1].item<int>() + 1);
  }
  at::Tensor feats = VoxelMean(point_features, map);
  Voxelized out{SparseTensor(map.voxel_coords, feats, shape, batch_size), map};
  return out;
}

}  // namespace dimr::nn
