// Stage-1 inference after the network: mapping back, TTA averaging, copy-out
// (src/nn/stage1_heads.h). Only ATen's parallel_for, no tensors: a quick TU.
#include "stage1_heads.h"

#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>

#if defined(__x86_64__)
// GCC 12 warns inside its own AVX-512 headers (the unused source operand of an unmasked
// extract / reduce is _mm512_undefined_*): a known false positive, silenced for the header only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>
#pragma GCC diagnostic pop
#endif

#include "dimr/core/error.h"
#include "dimr/nn/sparse_ops.h"

namespace dimr::nn::stage1_heads {
namespace {

// Four floats (SSE2 on x86-64, NEON on ARM): the row loops are written in whole vectors so
// that they vectorise whatever the optimisation level (-O2 leaves a plain loop over a runtime
// length scalar). Lane-wise IEEE adds and multiplies: the same results as the scalar loops.
typedef float F4 __attribute__((vector_size(16)));

inline F4 Load(const float* p) {
  F4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
inline void Store(float* p, F4 v) { std::memcpy(p, &v, sizeof(v)); }

// Prefetches the `bytes` from p (one hint per cache line).
inline void PrefetchRange(const void* p, int bytes) {
  const char* c = static_cast<const char*>(p);
  for (int b = 0; b < bytes; b += 64) __builtin_prefetch(c + b);
  __builtin_prefetch(c + bytes - 1);
}

typedef std::int32_t I4 __attribute__((vector_size(16)));

inline F4 Splat(float v) { return F4{v, v, v, v}; }

// exp(x) for the softmax arguments x = logit - row max <= 0: Cephes' expf (x = n ln 2 + r,
// |r| <= ln 2 / 2, a degree-7 polynomial in r, times 2^n; relative error ~1e-7, i.e. within
// an ulp or two of the correctly rounded value). Below -87.3 (e^x < 1.2e-38, where 2^n would
// leave the normal range) it returns 0; NaN stays NaN.
// The constants of ExpNonPositive, shared by its 4-, 8- and 16-lane forms (the same operations
// in each, so the same bits).
struct ExpConstants {
  static constexpr float kLow = -87.3f;
  static constexpr float kMagic = 12582912.0f;  // 1.5 * 2^23
  static constexpr float kLog2e = 1.44269504088896341f;
  static constexpr float kLn2Hi = 0.693359375f;  // ln 2 = kLn2Hi + kLn2Lo, n * kLn2Hi exact
  static constexpr float kLn2Lo = -2.12194440e-4f;
  static constexpr float kPoly[6] = {1.9875691500e-4f, 1.3981999507e-3f, 8.3334519073e-3f,
                                     4.1665795894e-2f, 1.6666665459e-1f, 5.0000001201e-1f};
};

inline F4 ExpNonPositive(F4 x) {
  using K = ExpConstants;
  const F4 lo = Splat(K::kLow);
  const I4 tiny = x < lo;
  const F4 xc = tiny ? lo : x;
  // n = round(x / ln 2): adding and subtracting 1.5 * 2^23 rounds to the nearest integer.
  const F4 magic = Splat(K::kMagic);
  const F4 n = (xc * Splat(K::kLog2e) + magic) - magic;
  // r = x - n ln 2, with ln 2 split in two so that n * C1 is exact.
  F4 r = xc - n * Splat(K::kLn2Hi);
  r = r - n * Splat(K::kLn2Lo);
  F4 p = Splat(K::kPoly[0]);
#pragma GCC unroll 8
  for (int k = 1; k < 6; ++k) p = p * r + Splat(K::kPoly[k]);
  p = p * (r * r) + r + Splat(1.0f);
  const I4 bits = (__builtin_convertvector(n, I4) + 127) << 23;
  F4 two_n;
  std::memcpy(&two_n, &bits, sizeof(two_n));
  const F4 e = p * two_n;
  return tiny ? Splat(0.0f) : e;
}

inline F4 Max(F4 a, F4 b) { return a > b ? a : b; }

// Softmax of `dim` floats at x, in place: exp(x - max), then times 1 / sum, as ATen's lastdim
// softmax (the sum in four lanes, then across them); whole vectors, the last partial one
// padded with -inf. A NaN logit makes the row NaN. Returns the first index of the largest
// probability (std::max_element's answer on the written row; 0 for a NaN row).
inline int SoftmaxRow(float* x, int dim) {
  const int full = dim / 4 * 4;
  float tail[4] = {-INFINITY, -INFINITY, -INFINITY, -INFINITY};
  std::memcpy(tail, x + full, sizeof(float) * (dim - full));
  F4 vmax = Load(tail);
  for (int c = 0; c < full; c += 4) vmax = Max(vmax, Load(x + c));
  float mx = vmax[0];
  for (int q = 1; q < 4; ++q) mx = vmax[q] > mx ? vmax[q] : mx;
  // (A NaN logit gives exp(NaN - mx) = NaN, so the sum and the whole row are NaN.)
  const F4 shift = Splat(mx);
  F4 sum = Splat(0.0f);
  for (int c = 0; c < full; c += 4) {
    const F4 e = ExpNonPositive(Load(x + c) - shift);
    Store(x + c, e);
    sum += e;
  }
  F4 te = ExpNonPositive(Load(tail) - shift);
  sum += te;
  const F4 inv = Splat(1.0f / ((sum[0] + sum[1]) + (sum[2] + sum[3])));
  F4 pmax = Splat(0.0f);
  for (int c = 0; c < full; c += 4) {
    const F4 p = Load(x + c) * inv;
    Store(x + c, p);
    pmax = Max(pmax, p);
  }
  te *= inv;
  std::memcpy(x + full, &te, sizeof(float) * (dim - full));
  pmax = Max(pmax, te);
  float best = pmax[0];
  for (int q = 1; q < 4; ++q) best = pmax[q] > best ? pmax[q] : best;
  for (int c = 0; c < dim; ++c) {
    if (x[c] == best) return c;
  }
  return 0;
}

#if defined(__x86_64__)
// The same softmax on 8 (AVX2) or 16 (AVX-512) lanes for rows of at most 32 floats (the 25
// semantic and 12 bin logits of the shipped model): masked loads and stores instead of the
// 4-lane tail copies, the exp of ExpNonPositive operation by operation (no FMA: this file is
// built with -ffp-contract=off), and the 4-lane sum order kept, so the three kernels give the
// same bits: the 4-float groups are added in row order (the groups past the row hold exact
// zeros, and s + 0 = s), then (s0 + s1) + (s2 + s3). The maximum and the argmax do not depend
// on the order (max is exact; a NaN row is NaN in every lane whatever max returned).
__attribute__((target("avx512f"))) inline __m512 Exp512(__m512 x) {
  using K = ExpConstants;
  const __m512 lo = _mm512_set1_ps(K::kLow);
  const __mmask16 tiny = _mm512_cmp_ps_mask(x, lo, _CMP_LT_OQ);
  const __m512 xc = _mm512_mask_blend_ps(tiny, x, lo);
  const __m512 magic = _mm512_set1_ps(K::kMagic);
  const __m512 n =
      _mm512_sub_ps(_mm512_add_ps(_mm512_mul_ps(xc, _mm512_set1_ps(K::kLog2e)), magic), magic);
  __m512 r = _mm512_sub_ps(xc, _mm512_mul_ps(n, _mm512_set1_ps(K::kLn2Hi)));
  r = _mm512_sub_ps(r, _mm512_mul_ps(n, _mm512_set1_ps(K::kLn2Lo)));
  __m512 p = _mm512_set1_ps(K::kPoly[0]);
#pragma GCC unroll 8
  for (int k = 1; k < 6; ++k) p = _mm512_add_ps(_mm512_mul_ps(p, r), _mm512_set1_ps(K::kPoly[k]));
  p = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(p, _mm512_mul_ps(r, r)), r), _mm512_set1_ps(1.0f));
  const __m512i bits =
      _mm512_slli_epi32(_mm512_add_epi32(_mm512_cvttps_epi32(n), _mm512_set1_epi32(127)), 23);
  const __m512 e = _mm512_mul_ps(p, _mm512_castsi512_ps(bits));
  return _mm512_mask_blend_ps(tiny, e, _mm512_setzero_ps());
}

__attribute__((target("avx512f"))) inline int SoftmaxRow512(float* x, int dim) {  // dim <= 32
  const int d0 = dim < 16 ? dim : 16;
  const __mmask16 m0 = static_cast<__mmask16>((1u << d0) - 1);
  const __mmask16 m1 = static_cast<__mmask16>((1u << (dim - d0)) - 1);
  const __m512 ninf = _mm512_set1_ps(-INFINITY);
  const __m512 a = _mm512_mask_loadu_ps(ninf, m0, x);
  const __m512 b = _mm512_mask_loadu_ps(ninf, m1, x + 16);
  const __m512 shift = _mm512_set1_ps(_mm512_reduce_max_ps(_mm512_max_ps(a, b)));
  const __m512 ea = Exp512(_mm512_sub_ps(a, shift));
  __m128 s = _mm512_castps512_ps128(ea);
  s = _mm_add_ps(s, _mm512_extractf32x4_ps(ea, 1));
  s = _mm_add_ps(s, _mm512_extractf32x4_ps(ea, 2));
  s = _mm_add_ps(s, _mm512_extractf32x4_ps(ea, 3));
  __m512 eb = _mm512_setzero_ps();
  if (dim > 16) {
    eb = Exp512(_mm512_sub_ps(b, shift));
    s = _mm_add_ps(s, _mm512_castps512_ps128(eb));
    s = _mm_add_ps(s, _mm512_extractf32x4_ps(eb, 1));
    s = _mm_add_ps(s, _mm512_extractf32x4_ps(eb, 2));
    s = _mm_add_ps(s, _mm512_extractf32x4_ps(eb, 3));
  }
  alignas(16) float lane[4];
  _mm_store_ps(lane, s);
  const __m512 inv = _mm512_set1_ps(1.0f / ((lane[0] + lane[1]) + (lane[2] + lane[3])));
  const __m512 pa = _mm512_mul_ps(ea, inv);
  const __m512 pb = _mm512_mul_ps(eb, inv);
  _mm512_mask_storeu_ps(x, m0, pa);
  _mm512_mask_storeu_ps(x + 16, m1, pb);
  // The largest probability is exactly inv: the row maximum's exp is exp(0) = 1 exactly and
  // every other exp is <= 1 (ExpNonPositive never rounds above 1 for x <= 0), so max(e * inv)
  // = inv, the value the 4-lane kernel finds by a reduction (NaN rows: inv is NaN, no hit).
  const __m512 best = inv;
  const unsigned hit =
      static_cast<unsigned>(_mm512_mask_cmp_ps_mask(m0, pa, best, _CMP_EQ_OQ)) |
      (static_cast<unsigned>(_mm512_mask_cmp_ps_mask(m1, pb, best, _CMP_EQ_OQ)) << 16);
  return hit ? __builtin_ctz(hit) : 0;
}

__attribute__((target("avx2"))) inline __m256 Exp256(__m256 x) {
  using K = ExpConstants;
  const __m256 lo = _mm256_set1_ps(K::kLow);
  const __m256 tiny = _mm256_cmp_ps(x, lo, _CMP_LT_OQ);
  const __m256 xc = _mm256_blendv_ps(x, lo, tiny);
  const __m256 magic = _mm256_set1_ps(K::kMagic);
  const __m256 n =
      _mm256_sub_ps(_mm256_add_ps(_mm256_mul_ps(xc, _mm256_set1_ps(K::kLog2e)), magic), magic);
  __m256 r = _mm256_sub_ps(xc, _mm256_mul_ps(n, _mm256_set1_ps(K::kLn2Hi)));
  r = _mm256_sub_ps(r, _mm256_mul_ps(n, _mm256_set1_ps(K::kLn2Lo)));
  __m256 p = _mm256_set1_ps(K::kPoly[0]);
#pragma GCC unroll 8
  for (int k = 1; k < 6; ++k) p = _mm256_add_ps(_mm256_mul_ps(p, r), _mm256_set1_ps(K::kPoly[k]));
  p = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(p, _mm256_mul_ps(r, r)), r), _mm256_set1_ps(1.0f));
  const __m256i bits =
      _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvttps_epi32(n), _mm256_set1_epi32(127)), 23);
  const __m256 e = _mm256_mul_ps(p, _mm256_castsi256_ps(bits));
  return _mm256_andnot_ps(tiny, e);  // 0 where tiny
}

__attribute__((target("avx2"))) inline float HorizontalMax256(__m256 v) {
  __m128 m = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  m = _mm_max_ps(m, _mm_movehl_ps(m, m));
  m = _mm_max_ss(m, _mm_shuffle_ps(m, m, 1));
  return _mm_cvtss_f32(m);
}

// NV = (dim + 7) / 8 vectors, known at compile time (the vectors stay in registers).
template <int NV>
__attribute__((target("avx2"))) inline int SoftmaxRow256(float* x, int dim) {  // dim <= 8 NV
  const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 ninf = _mm256_set1_ps(-INFINITY);
  __m256i mask[NV];
  __m256 v[NV];
  __m256 vmax = ninf;
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    mask[q] = _mm256_cmpgt_epi32(_mm256_set1_epi32(dim - 8 * q), iota);
    v[q] = _mm256_blendv_ps(ninf, _mm256_maskload_ps(x + 8 * q, mask[q]),
                            _mm256_castsi256_ps(mask[q]));
    vmax = _mm256_max_ps(vmax, v[q]);
  }
  const __m256 shift = _mm256_set1_ps(HorizontalMax256(vmax));
  __m128 s = _mm_setzero_ps();
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    v[q] = Exp256(_mm256_sub_ps(v[q], shift));
    s = q == 0 ? _mm256_castps256_ps128(v[q]) : _mm_add_ps(s, _mm256_castps256_ps128(v[q]));
    s = _mm_add_ps(s, _mm256_extractf128_ps(v[q], 1));
  }
  alignas(16) float lane[4];
  _mm_store_ps(lane, s);
  const __m256 inv = _mm256_set1_ps(1.0f / ((lane[0] + lane[1]) + (lane[2] + lane[3])));
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    v[q] = _mm256_mul_ps(v[q], inv);
    _mm256_maskstore_ps(x + 8 * q, mask[q], v[q]);
  }
  const __m256 best = inv;  // the largest probability, as in SoftmaxRow512
  unsigned hit = 0;
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    const __m256 eq =
        _mm256_and_ps(_mm256_cmp_ps(v[q], best, _CMP_EQ_OQ), _mm256_castsi256_ps(mask[q]));
    hit |= static_cast<unsigned>(_mm256_movemask_ps(eq)) << (8 * q);
  }
  return hit ? __builtin_ctz(hit) : 0;
}
#endif

// The row kernel of an ISA (dim <= 32 for the wide ones; longer rows take the 4-lane one).
using SoftmaxRowFn = int (*)(float*, int);

#if defined(__x86_64__)
__attribute__((target("avx512f"))) int Row512(float* x, int dim) {
  return dim <= 32 ? SoftmaxRow512(x, dim) : SoftmaxRow(x, dim);
}
__attribute__((target("avx2"))) int Row256(float* x, int dim) {
  switch ((dim + 7) / 8) {
    case 1:
      return SoftmaxRow256<1>(x, dim);
    case 2:
      return SoftmaxRow256<2>(x, dim);
    case 3:
      return SoftmaxRow256<3>(x, dim);
    case 4:
      return SoftmaxRow256<4>(x, dim);
    default:
      return SoftmaxRow(x, dim);
  }
}
#endif
int Row128(float* x, int dim) { return SoftmaxRow(x, dim); }

bool IsaSupported(HeadsIsa isa) {
#if defined(__x86_64__)
  switch (isa) {
    case HeadsIsa::kAvx512:
      return __builtin_cpu_supports("avx512f");
    case HeadsIsa::kAvx2:
      return __builtin_cpu_supports("avx2");
    default:
      return true;
  }
#else
  return isa == HeadsIsa::kGeneric || isa == HeadsIsa::kAuto;
#endif
}

HeadsIsa Resolve(HeadsIsa isa) {
  if (isa != HeadsIsa::kAuto) {
    if (!IsaSupported(isa)) {
      throw InvalidArgument(std::string("stage-1 heads: this CPU cannot run the ") +
                            HeadsIsaName(isa) + " kernel");
    }
    return isa;
  }
  static const HeadsIsa best = IsaSupported(HeadsIsa::kAvx512) ? HeadsIsa::kAvx512
                               : IsaSupported(HeadsIsa::kAvx2) ? HeadsIsa::kAvx2
                                                               : HeadsIsa::kGeneric;
  return best;
}

SoftmaxRowFn RowFor(HeadsIsa isa) {
  switch (Resolve(isa)) {
#if defined(__x86_64__)
    case HeadsIsa::kAvx512:
      return &Row512;
    case HeadsIsa::kAvx2:
      return &Row256;
#endif
    default:
      return &Row128;
  }
}

}  // namespace

const char* HeadsIsaName(HeadsIsa isa) {
  switch (isa) {
    case HeadsIsa::kAvx512:
      return "avx512";
    case HeadsIsa::kAvx2:
      return "avx2";
    case HeadsIsa::kGeneric:
      return "generic";
    default:
      return "auto";
  }
}

std::vector<HeadsIsa> SupportedHeadsIsas() {
  std::vector<HeadsIsa> out;
  for (HeadsIsa isa : {HeadsIsa::kGeneric, HeadsIsa::kAvx2, HeadsIsa::kAvx512}) {
    if (IsaSupported(isa)) out.push_back(isa);
  }
  return out;
}

HeadsIsa ResolveHeadsIsa(HeadsIsa isa) { return Resolve(isa); }

void SoftmaxRows(float* x, std::int64_t rows, int dim, std::int64_t stride, int* argmax,
                 HeadsIsa isa) {
  const SoftmaxRowFn row = RowFor(isa);
  at::parallel_for(0, rows, 2048, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t v = begin; v < end; ++v) {
      const int best = row(x + v * stride, dim);
      if (argmax != nullptr) argmax[v] = best;
    }
  });
}

void SoftmaxInPlace(const VoxelHeads& h, int* argmax, HeadsIsa isa) {
  // Both rows of a voxel in one loop (the same per-row arithmetic as SoftmaxRows): one sweep
  // over the voxels, and the two rows' exp chains are independent work for the core to overlap.
  const SoftmaxRowFn row = RowFor(isa);
  at::parallel_for(0, h.voxels, 2048, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t v = begin; v < end; ++v) {
      const int best = row(h.prob + v * h.classes, h.classes);
      if (argmax != nullptr) argmax[v] = best;
      row(h.heading + v * 2 * kHeadingBins, kHeadingBins);
    }
  });
}

RowLayout::RowLayout(int c)
    : classes(c),
      heading_prob(c),
      heading_residual(c + kHeadingBins),
      offset(c + 2 * kHeadingBins),
      stride((c + 2 * kHeadingBins + 3 + 3) / 4 * 4) {}

void InputFrameRows(const VoxelHeads& h, const RowLayout& L, bool mirror, int k, int rotations,
                    float* rows) {
  const int nc = h.classes;
  // A heading h of the input is sign * h (+ pi if mirrored) + theta in the pass's scene: bin b
  // here is bin (m * 6 + sign * b + shift) there, residual times sign.
  const int m = mirror ? 1 : 0;
  const double sign = mirror ? -1.0 : 1.0;
  const double theta = 2.0 * M_PI * k / rotations;
  const double c = std::cos(theta), s = std::sin(theta);
  const int shift = kHeadingBins * k / rotations;
  int to[kHeadingBins];
  for (int b = 0; b < kHeadingBins; ++b) {
    to[b] = ((m * kHeadingBins / 2 + (mirror ? -b : b) + shift) % kHeadingBins + kHeadingBins) %
            kHeadingBins;
  }
  const float fsign = static_cast<float>(sign);
  const int used = L.offset + 3;
  for (std::int64_t v = 0; v < h.voxels; ++v) {
    float* r = rows + v * L.stride;
    const float* p = h.prob + v * nc;
    for (int c = 0; c < nc; ++c) r[c] = p[c];
    const float* bins = h.heading + v * 2 * kHeadingBins;
    const float* res = h.heading + v * 2 * kHeadingBins + kHeadingBins;
    for (int b = 0; b < kHeadingBins; ++b) {
      r[L.heading_prob + b] = bins[to[b]];
      r[L.heading_residual + b] = fsign * res[to[b]];
    }
    // Offsets rotated back by -theta, then mirrored.
    const double ox = h.offset[3 * v], oy = h.offset[3 * v + 1];
    r[L.offset] = static_cast<float>(sign * (c * ox + s * oy));
    r[L.offset + 1] = static_cast<float>(-s * ox + c * oy);
    r[L.offset + 2] = h.offset[3 * v + 2];
    for (int c = used; c < L.stride; ++c) r[c] = 0.0f;  // padding
  }
}

void SoftmaxToInputFrameRows(const VoxelHeads& h, const RowLayout& L, bool mirror, int k,
                             int rotations, float* rows, HeadsIsa isa) {
  constexpr std::int64_t kBlock = 256;  // 256 x 49 floats of a pass: ~50 KB
  const std::int64_t blocks = (h.voxels + kBlock - 1) / kBlock;
  at::parallel_for(0, blocks, 8, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t q = first; q < last; ++q) {
      const std::int64_t begin = q * kBlock;
      VoxelHeads b = h;
      b.prob += begin * h.classes;
      b.offset += begin * 3;
      b.heading += begin * 2 * kHeadingBins;
      b.voxels = std::min(kBlock, h.voxels - begin);
      SoftmaxInPlace(b, nullptr, isa);  // (nested: runs on this thread)
      InputFrameRows(b, L, mirror, k, rotations, rows + begin * L.stride);
    }
  });
}

namespace {

void Resize(std::size_t n, int nc, Stage1Output* out) {
  out->semantic_prob.resize(n * nc);
  out->heading_prob.resize(n * kHeadingBins);
  out->heading_residual.resize(n * kHeadingBins);
  out->offsets.resize(n);
  out->semantic.resize(n);
  out->point_row.clear();
}

}  // namespace

void CopyOutOnePass(const VoxelHeads& h, const int* argmax, const std::int64_t* p2v, std::size_t n,
                    Stage1Output* out) {
  const int nc = h.classes;
  const std::size_t m = static_cast<std::size_t>(h.voxels);
  // The tables stay per voxel (Stage1PointRows): ~20k rows of 49 floats instead of 100k, and
  // read in their own order. Per point: the voxel, its class and its offset.
  out->semantic_prob.assign(h.prob, h.prob + m * nc);
  out->heading_prob.resize(m * kHeadingBins);
  out->heading_residual.resize(m * kHeadingBins);
  float* hp = out->heading_prob.data();
  float* hr = out->heading_residual.data();
  for (std::size_t v = 0; v < m; ++v) {
    const float* bins = h.heading + v * 2 * kHeadingBins;
    std::memcpy(hp + v * kHeadingBins, bins, sizeof(float) * kHeadingBins);
    std::memcpy(hr + v * kHeadingBins, bins + kHeadingBins, sizeof(float) * kHeadingBins);
  }
  out->point_row.assign(p2v, p2v + n);
  out->offsets.resize(n);
  out->semantic.resize(n);
  Eigen::Vector3f* op = out->offsets.data();
  int* sem = out->semantic.data();
  at::parallel_for(
      0, static_cast<std::int64_t>(n), 8192, [&](std::int64_t begin, std::int64_t end) {
        for (std::int64_t i = begin; i < end; ++i) {
          const std::int64_t v = p2v[i];
          op[i] = Eigen::Vector3f(h.offset[3 * v], h.offset[3 * v + 1], h.offset[3 * v + 2]);
          sem[i] = argmax[v];
        }
      });
}

namespace {

// The mean of one point's rows src[0 .. passes) into `mean` (vectors x 4 floats), summed in
// pass order: the passes outer, the vectors inner, so that the adds of a row are independent
// (one chain per vector, not one chain of passes x vectors). V > 0: the row length known at
// compile time (the accumulators stay in registers); V = 0: `vectors` at run time.
template <int V>
inline void MeanOfRows(const float* const* src, int passes, int vectors, F4 inv, float* mean) {
  if constexpr (V > 0) {
    F4 acc[V];
    for (int q = 0; q < V; ++q) acc[q] = Load(src[0] + 4 * q);
    for (int k = 1; k < passes; ++k) {
      const float* r = src[k];
      for (int q = 0; q < V; ++q) acc[q] += Load(r + 4 * q);
    }
    for (int q = 0; q < V; ++q) Store(mean + 4 * q, acc[q] * inv);
  } else {
    for (int q = 0; q < vectors; ++q) Store(mean + 4 * q, Load(src[0] + 4 * q));
    for (int k = 1; k < passes; ++k) {
      const float* r = src[k];
      for (int q = 0; q < vectors; ++q) Store(mean + 4 * q, Load(mean + 4 * q) + Load(r + 4 * q));
    }
    for (int q = 0; q < vectors; ++q) Store(mean + 4 * q, Load(mean + 4 * q) * inv);
  }
}

// The mean of a point's rows src[0 .. passes) (L.stride floats each) into `mean` (64-byte
// aligned, L.stride floats), its semantic part also into `semantic` (L.classes floats);
// returns the first index of the largest semantic probability (std::max_element's answer).
using MeanFn = int (*)(const float* const* src, int passes, const RowLayout& L, float inv,
                       float* mean, float* semantic);

// The first index of the largest of x[0 .. n): `x[c] > x[best]` as std::max_element (a NaN
// never wins; a NaN first element stays the answer), with the best value in a register
// instead of a reload of x[best] on the compare chain.
inline int FirstMax(const float* x, int n) {
  int best = 0;
  float bv = x[0];
  for (int c = 1; c < n; ++c) {
    if (x[c] > bv) {
      bv = x[c];
      best = c;
    }
  }
  return best;
}

template <int V>
int MeanGeneric(const float* const* src, int passes, const RowLayout& L, float inv, float* mean,
                float* semantic) {
  MeanOfRows<V>(src, passes, L.stride / 4, F4{inv, inv, inv, inv}, mean);
  std::memcpy(semantic, mean, sizeof(float) * L.classes);
  return FirstMax(mean, L.classes);
}

#if defined(__x86_64__)
// The same mean in 16-lane (AVX-512, NV <= 4 vectors: rows <= 64 floats) or 8-lane (AVX2,
// NV <= 8) vectors: every lane is the 4-lane kernel's lane (the same adds in pass order, then
// the same multiply), so the bits are the same; the accumulators stay in registers (NV is
// known at compile time), the last vector is loaded under a mask (no read past the row), and
// the semantic argmax is a vector max and a compare (a NaN row takes FirstMax).
template <int NV>
__attribute__((target("avx512f"))) int Mean512(const float* const* src, int passes,
                                               const RowLayout& L, float inv, float* mean,
                                               float* semantic) {
  const int tail = L.stride - 16 * (NV - 1);  // 4 ... 16
  const __mmask16 mt = static_cast<__mmask16>((1u << tail) - 1);
  __m512 acc[NV];
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    acc[q] =
        q < NV - 1 ? _mm512_loadu_ps(src[0] + 16 * q) : _mm512_maskz_loadu_ps(mt, src[0] + 16 * q);
  }
  for (int k = 1; k < passes; ++k) {
    const float* r = src[k];
#pragma GCC unroll 4
    for (int q = 0; q < NV; ++q) {
      acc[q] = _mm512_add_ps(
          acc[q], q < NV - 1 ? _mm512_loadu_ps(r + 16 * q) : _mm512_maskz_loadu_ps(mt, r + 16 * q));
    }
  }
  const __m512 scale = _mm512_set1_ps(inv);
  __m512 top = _mm512_set1_ps(-INFINITY);
  unsigned nan = 0;
  __mmask16 in_class[NV];
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    acc[q] = _mm512_mul_ps(acc[q], scale);
    _mm512_store_ps(mean + 16 * q, acc[q]);
    const int left = L.classes - 16 * q;
    in_class[q] = static_cast<__mmask16>(left >= 16 ? 0xFFFFu : left > 0 ? (1u << left) - 1 : 0u);
    _mm512_mask_storeu_ps(semantic + 16 * q, in_class[q], acc[q]);
    top = _mm512_mask_max_ps(top, in_class[q], top, acc[q]);
    nan |= _mm512_mask_cmp_ps_mask(in_class[q], acc[q], acc[q], _CMP_UNORD_Q);
  }
  if (nan) return FirstMax(mean, L.classes);
  const __m512 best = _mm512_set1_ps(_mm512_reduce_max_ps(top));
  std::uint64_t hit = 0;
#pragma GCC unroll 4
  for (int q = 0; q < NV; ++q) {
    hit |=
        static_cast<std::uint64_t>(_mm512_mask_cmp_ps_mask(in_class[q], acc[q], best, _CMP_EQ_OQ))
        << (16 * q);
  }
  return hit ? __builtin_ctzll(hit) : 0;
}

template <int NV>
__attribute__((target("avx2"))) int Mean256(const float* const* src, int passes, const RowLayout& L,
                                            float inv, float* mean, float* semantic) {
  const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i mt = _mm256_cmpgt_epi32(_mm256_set1_epi32(L.stride - 8 * (NV - 1)), iota);
  __m256 acc[NV];
#pragma GCC unroll 8
  for (int q = 0; q < NV; ++q) {
    acc[q] = q < NV - 1 ? _mm256_loadu_ps(src[0] + 8 * q) : _mm256_maskload_ps(src[0] + 8 * q, mt);
  }
  for (int k = 1; k < passes; ++k) {
    const float* r = src[k];
#pragma GCC unroll 8
    for (int q = 0; q < NV; ++q) {
      acc[q] = _mm256_add_ps(
          acc[q], q < NV - 1 ? _mm256_loadu_ps(r + 8 * q) : _mm256_maskload_ps(r + 8 * q, mt));
    }
  }
  const __m256 scale = _mm256_set1_ps(inv);
  const __m256 ninf = _mm256_set1_ps(-INFINITY);
  __m256 top = ninf;
  int nan = 0;
  __m256 in_class[NV];
#pragma GCC unroll 8
  for (int q = 0; q < NV; ++q) {
    acc[q] = _mm256_mul_ps(acc[q], scale);
    _mm256_store_ps(mean + 8 * q, acc[q]);
    const __m256i m = _mm256_cmpgt_epi32(_mm256_set1_epi32(L.classes - 8 * q), iota);
    in_class[q] = _mm256_castsi256_ps(m);
    _mm256_maskstore_ps(semantic + 8 * q, m, acc[q]);
    top = _mm256_max_ps(top, _mm256_blendv_ps(ninf, acc[q], in_class[q]));
    nan |=
        _mm256_movemask_ps(_mm256_and_ps(_mm256_cmp_ps(acc[q], acc[q], _CMP_UNORD_Q), in_class[q]));
  }
  if (nan) return FirstMax(mean, L.classes);
  const __m256 best = _mm256_set1_ps(HorizontalMax256(top));
  std::uint64_t hit = 0;
#pragma GCC unroll 8
  for (int q = 0; q < NV; ++q) {
    const __m256 eq = _mm256_and_ps(_mm256_cmp_ps(acc[q], best, _CMP_EQ_OQ), in_class[q]);
    hit |= static_cast<std::uint64_t>(_mm256_movemask_ps(eq)) << (8 * q);
  }
  return hit ? __builtin_ctzll(hit) : 0;
}
#endif

// The mean kernel for this row length on `isa` (rows of <= 64 floats on the wide ISAs).
MeanFn MeanFor(HeadsIsa isa, const RowLayout& L) {
  const int stride = L.stride;
  const HeadsIsa use = Resolve(isa);  // an unsupported request is refused for any row length
#if defined(__x86_64__)
  if (stride <= 64) {
    switch (use) {
      case HeadsIsa::kAvx512:
        switch ((stride + 15) / 16) {
          case 1:
            return &Mean512<1>;
          case 2:
            return &Mean512<2>;
          case 3:
            return &Mean512<3>;
          default:
            return &Mean512<4>;
        }
      case HeadsIsa::kAvx2:
        switch ((stride + 7) / 8) {
          case 1:
            return &Mean256<1>;
          case 2:
            return &Mean256<2>;
          case 3:
            return &Mean256<3>;
          case 4:
            return &Mean256<4>;
          case 5:
            return &Mean256<5>;
          case 6:
            return &Mean256<6>;
          case 7:
            return &Mean256<7>;
          default:
            return &Mean256<8>;
        }
      default:
        break;
    }
  }
#else
  (void)use;
#endif
  return stride == 52 ? &MeanGeneric<13> : &MeanGeneric<0>;  // 52: the 25 RFS classes
}

void AverageRange(std::int64_t begin, std::int64_t end, const std::int64_t* off,
                  const std::int64_t* pts, const std::vector<const float*>& table,
                  const std::vector<const std::int32_t*>& index, const RowLayout& L, MeanFn mean_of,
                  Stage1Output* out) {
  const int passes = static_cast<int>(table.size());
  const int nc = L.classes, stride = L.stride;
  const float inv = 1.0f / static_cast<float>(passes);
  // Row j of the tables is the j-th point in the first pass's voxel order (point_row[pts[j]] =
  // j): the table writes are sequential, only the class and the offset go to point order.
  float* sp = out->semantic_prob.data();
  float* hp = out->heading_prob.data();
  float* hr = out->heading_residual.data();
  Eigen::Vector3f* op = out->offsets.data();
  int* sem = out->semantic.data();
  std::int64_t* row_of = out->point_row.data();
  // Points ahead whose rows (every pass) are prefetched: the reads are local but not
  // predictable for the hardware prefetcher (each pass's voxels are numbered along its own
  // rotated axes); and the per-point writes (class, offset, row), which are scattered.
  constexpr std::int64_t ahead = 8;
  const std::int64_t j_end = off[end];
  std::vector<const float*> src(passes);
  alignas(64) float mean[64];
  std::vector<float> wide;  // rows longer than 64 floats (the generic kernel)
  float* m = mean;
  if (stride > 64) {
    wide.resize(stride);
    m = wide.data();
  }
  for (std::int64_t v = begin; v < end; ++v) {
    const std::int64_t ja = std::min(off[v] + ahead, j_end);
    const std::int64_t jb = std::min(off[v + 1] + ahead, j_end);
    for (std::int64_t j = ja; j < jb; ++j) {
      for (int k = 1; k < passes; ++k) {
        PrefetchRange(table[k] + static_cast<std::int64_t>(index[k][j]) * stride, stride * 4);
      }
      const std::int64_t i = pts[j];
      __builtin_prefetch(op + i, 1);
      __builtin_prefetch(sem + i, 1);
      __builtin_prefetch(row_of + i, 1);
    }
    src[0] = table[0] + v * stride;
    for (std::int64_t j = off[v]; j < off[v + 1]; ++j) {
      for (int k = 1; k < passes; ++k) {
        src[k] = table[k] + static_cast<std::int64_t>(index[k][j]) * stride;
      }
      const std::int64_t i = pts[j];
      sem[i] = mean_of(src.data(), passes, L, inv, m, sp + j * nc);
      row_of[i] = j;
      std::memcpy(hp + j * kHeadingBins, m + L.heading_prob, sizeof(float) * kHeadingBins);
      std::memcpy(hr + j * kHeadingBins, m + L.heading_residual, sizeof(float) * kHeadingBins);
      op[i] = Eigen::Vector3f(m[L.offset], m[L.offset + 1], m[L.offset + 2]);
    }
  }
}

}  // namespace

void AverageInVoxelOrder(const std::int64_t* off, std::int64_t m0, const std::int64_t* pts,
                         std::size_t n, const std::vector<const float*>& table,
                         const std::vector<const std::int32_t*>& index, const RowLayout& L,
                         Stage1Output* out, HeadsIsa isa) {
  const MeanFn mean_of = MeanFor(isa, L);
  Resize(n, L.classes, out);
  out->point_row.resize(n);
  // Voxel by voxel of the first pass: neighbouring points have neighbouring voxels in every
  // pass, so the row reads stay local; each point's mean is written once (the only scatter
  // into point order).
  at::parallel_for(0, m0, 1024, [&](std::int64_t begin, std::int64_t end) {
    AverageRange(begin, end, off, pts, table, index, L, mean_of, out);
  });
}

// ---------------------------------------------------------------------------------------
// Moved scenes of the test-time augmentation
// ---------------------------------------------------------------------------------------

namespace {

// The reference arithmetic, point by point (the tails of the wide kernels and the generic path).
void MoveRange(const Eigen::Vector3f* p, std::size_t begin, std::size_t end, double cx, double cy,
               double sign, double c, double s, MovedPoints* out) {
  float* X = out->x.data();
  float* Y = out->y.data();
  float* Z = out->z.data();
  for (std::size_t i = begin; i < end; ++i) {
    const double dx = sign * (p[i].x() - cx);
    const double dy = p[i].y() - cy;
    X[i] = static_cast<float>(cx + c * dx - s * dy);
    Y[i] = static_cast<float>(cy + s * dx + c * dy);
    Z[i] = p[i].z();
    const float v[3] = {X[i], Y[i], Z[i]};
    for (int a = 0; a < 3; ++a) {
      out->lo[a] = std::min(out->lo[a], v[a]);
      out->hi[a] = std::max(out->hi[a], v[a]);
    }
  }
}

// Where the points of the network input come from: the moved scene's SoA rows, or the
// scene's own AoS points.
struct SoaPoints {
  const float* x;
  const float* y;
  const float* z;
  float At(std::size_t i, int a) const { return (a == 0 ? x : a == 1 ? y : z)[i]; }
};
struct AosPoints {
  const float* p;  // 3 floats per point
  float At(std::size_t i, int a) const { return p[3 * i + a]; }
};

template <class Points>
void InputRange(const Points& src, const Eigen::Vector3f* colors, std::size_t begin,
                std::size_t end, const float origin[3], float scale, const double q0[3], float* f,
                std::int32_t* vx) {
  const int C = colors ? 6 : 3;
  for (std::size_t i = begin; i < end; ++i) {
    vx[4 * i] = 0;
    for (int a = 0; a < 3; ++a) {
      const float p = src.At(i, a) - origin[a];
      const float q = p * scale;
      f[C * i + a] = p;
      // trunc(q - qmin) of a non-negative difference is its floor.
      vx[4 * i + 1 + a] = static_cast<std::int32_t>(static_cast<double>(q) - q0[a]);
    }
    if (colors) {
      for (int a = 0; a < 3; ++a) f[C * i + 3 + a] = colors[i][a] - 0.5f;
    }
  }
}

// Folds the per-lane minima l and maxima h (`lanes` each) of coordinate a into out's box.
inline void FoldBox(const float* l, const float* h, int lanes, int a, MovedPoints* out) {
  for (int k = 0; k < lanes; ++k) {
    out->lo[a] = std::min(out->lo[a], l[k]);
    out->hi[a] = std::max(out->hi[a], h[k]);
  }
}

#if defined(__x86_64__)
// Lane l of a permutation over `sources` 16-lane vectors: index and whether it reads the
// second pair (flat >= 32). The AoS <-> SoA moves below are two permutes per vector.
struct Gather16 {
  alignas(64) std::int32_t first[16];   // permutex2var over (v0, v1)
  alignas(64) std::int32_t second[16];  // permutexvar over v2, where `mask` is set
  std::uint16_t mask = 0;
};

// SoA lane i of coordinate a <- AoS flat 3 i + a of 48 floats in three vectors.
Gather16 AosToSoa(int a) {
  Gather16 g;
  for (int i = 0; i < 16; ++i) {
    const int flat = 3 * i + a;
    g.first[i] = flat < 32 ? flat : 0;
    g.second[i] = flat < 32 ? 0 : flat - 32;
    if (flat >= 32) g.mask = static_cast<std::uint16_t>(g.mask | (1u << i));
  }
  return g;
}

__attribute__((target("avx512f"))) inline __m256 High256(__m512 v) {
  return _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(0xFF, _mm512_castps_pd(v), 1));
}

__attribute__((target("avx512f"))) inline __m512 Join256(__m256 lo, __m256 hi) {
  return _mm512_castpd_ps(
      _mm512_insertf64x4(_mm512_castps_pd(_mm512_castps256_ps512(lo)), _mm256_castps_pd(hi), 1));
}

// 16 points per step: the x / y rows gathered from the AoS points, moved in two 8-lane double
// halves with the reference's operations in its order (no FMA: -ffp-contract=off), rounded.
__attribute__((target("avx512f"))) void Move512(const Eigen::Vector3f* p, std::size_t n, double cx,
                                                double cy, double sign, double c, double s,
                                                MovedPoints* out) {
  const Gather16 gx = AosToSoa(0), gy = AosToSoa(1), gz = AosToSoa(2);
  const __m512i x1 = _mm512_load_si512(gx.first), x2 = _mm512_load_si512(gx.second);
  const __m512i y1 = _mm512_load_si512(gy.first), y2 = _mm512_load_si512(gy.second);
  const __m512i z1 = _mm512_load_si512(gz.first), z2 = _mm512_load_si512(gz.second);
  const __m512d vcx = _mm512_set1_pd(cx), vcy = _mm512_set1_pd(cy);
  const __m512d vsign = _mm512_set1_pd(sign), vc = _mm512_set1_pd(c), vs = _mm512_set1_pd(s);
  __m512 lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = _mm512_set1_ps(out->lo[a]);
    hi[a] = _mm512_set1_ps(out->hi[a]);
  }
  const float* src = reinterpret_cast<const float*>(p);  // 3 floats per point
  const std::size_t blocks = n / 16;
  for (std::size_t b = 0; b < blocks; ++b) {
    const float* q = src + 48 * b;
    const __m512 a0 = _mm512_loadu_ps(q), a1 = _mm512_loadu_ps(q + 16),
                 a2 = _mm512_loadu_ps(q + 32);
    const __m512 x =
        _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(a0, x1, a1), gx.mask, x2, a2);
    const __m512 y =
        _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(a0, y1, a1), gy.mask, y2, a2);
    const __m512 z =
        _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(a0, z1, a1), gz.mask, z2, a2);
    __m256 mx[2], my[2];
    for (int h = 0; h < 2; ++h) {
      const __m512d xd = _mm512_cvtps_pd(h == 0 ? _mm512_castps512_ps256(x) : High256(x));
      const __m512d yd = _mm512_cvtps_pd(h == 0 ? _mm512_castps512_ps256(y) : High256(y));
      const __m512d dx = _mm512_mul_pd(vsign, _mm512_sub_pd(xd, vcx));
      const __m512d dy = _mm512_sub_pd(yd, vcy);
      mx[h] = _mm512_cvtpd_ps(
          _mm512_sub_pd(_mm512_add_pd(vcx, _mm512_mul_pd(vc, dx)), _mm512_mul_pd(vs, dy)));
      my[h] = _mm512_cvtpd_ps(
          _mm512_add_pd(_mm512_add_pd(vcy, _mm512_mul_pd(vs, dx)), _mm512_mul_pd(vc, dy)));
    }
    const __m512 v[3] = {Join256(mx[0], mx[1]), Join256(my[0], my[1]), z};
    float* dst[3] = {out->x.data(), out->y.data(), out->z.data()};
    for (int a = 0; a < 3; ++a) {
      _mm512_storeu_ps(dst[a] + 16 * b, v[a]);
      lo[a] = _mm512_min_ps(lo[a], v[a]);
      hi[a] = _mm512_max_ps(hi[a], v[a]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    alignas(64) float l[16], h[16];
    _mm512_store_ps(l, lo[a]);
    _mm512_store_ps(h, hi[a]);
    FoldBox(l, h, 16, a, out);
  }
  MoveRange(p, 16 * blocks, n, cx, cy, sign, c, s, out);
}

// 16 points per step: p = moved - origin and its voxel in SoA, then interleaved with
// permutes: voxel rows (0, ix, iy, iz), the AoS positions, and with colours the 6-float rows.
template <class Points>
__attribute__((target("avx512f"))) void Input512(const Points& points,
                                                 const Eigen::Vector3f* colors, std::size_t n,
                                                 const float origin[3], float scale,
                                                 const double q0[3], float* f, std::int32_t* vx) {
  constexpr bool kAos = std::is_same_v<Points, AosPoints>;
  const Gather16 g[3] = {AosToSoa(0), AosToSoa(1), AosToSoa(2)};
  __m512i g1[3], g2[3];
  for (int a = 0; a < 3; ++a) {
    g1[a] = _mm512_load_si512(g[a].first);
    g2[a] = _mm512_load_si512(g[a].second);
  }
  // Voxel vector j (ints 16 j ...): point 4 j + l / 4, slot l % 4 (0 | x | y | z).
  alignas(64) std::int32_t vidx[4][16];
  std::uint16_t vxy = 0, vz = 0;
  for (int l = 0; l < 16; ++l) {
    const int slot = l % 4;
    if (slot == 1 || slot == 2) vxy = static_cast<std::uint16_t>(vxy | (1u << l));
    if (slot == 3) vz = static_cast<std::uint16_t>(vz | (1u << l));
  }
  for (int j = 0; j < 4; ++j) {
    for (int l = 0; l < 16; ++l) {
      const int point = 4 * j + l / 4, slot = l % 4;
      vidx[j][l] = slot == 2 ? 16 + point : point;  // y from the second source
    }
  }
  // Position vector b (floats 16 b ...): flat 16 b + l = 3 i + a.
  alignas(64) std::int32_t pidx[3][16];
  std::uint16_t pz[3] = {0, 0, 0};
  for (int b = 0; b < 3; ++b) {
    for (int l = 0; l < 16; ++l) {
      const int flat = 16 * b + l, i = flat / 3, a = flat % 3;
      pidx[b][l] = a == 1 ? 16 + i : i;
      if (a == 2) pz[b] = static_cast<std::uint16_t>(pz[b] | (1u << l));
    }
  }
  // Feature vector j (floats 16 j ... of the 6-float rows): position flat 3 i + a or colour
  // flat 3 i + a - 3, from the pair of AoS vectors starting at vector base[j].
  alignas(64) std::int32_t fp[6][16], fc[6][16];
  std::uint16_t from_colour[6] = {0, 0, 0, 0, 0, 0};
  int base[6];
  for (int j = 0; j < 6; ++j) {
    base[j] = std::min((16 * j / 6) * 3 / 16, 1);
    for (int l = 0; l < 16; ++l) {
      const int flat = 16 * j + l, i = flat / 6, a = flat % 6;
      const int src = 3 * i + (a < 3 ? a : a - 3) - 16 * base[j];
      fp[j][l] = a < 3 ? src : 0;
      fc[j][l] = a < 3 ? 0 : src;
      if (a >= 3) from_colour[j] = static_cast<std::uint16_t>(from_colour[j] | (1u << l));
    }
  }
  const __m512 o[3] = {_mm512_set1_ps(origin[0]), _mm512_set1_ps(origin[1]),
                       _mm512_set1_ps(origin[2])};
  const __m512d vq0[3] = {_mm512_set1_pd(q0[0]), _mm512_set1_pd(q0[1]), _mm512_set1_pd(q0[2])};
  const __m512 vscale = _mm512_set1_ps(scale), half = _mm512_set1_ps(0.5f);
  const float* col = reinterpret_cast<const float*>(colors);
  const int C = colors ? 6 : 3;
  const std::size_t blocks = n / 16;
  for (std::size_t b = 0; b < blocks; ++b) {
    __m512 in[3];
    if constexpr (kAos) {
      const float* q = points.p + 48 * b;
      const __m512 a0 = _mm512_loadu_ps(q), a1 = _mm512_loadu_ps(q + 16),
                   a2 = _mm512_loadu_ps(q + 32);
      for (int a = 0; a < 3; ++a) {
        in[a] =
            _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(a0, g1[a], a1), g[a].mask, g2[a], a2);
      }
    } else {
      in[0] = _mm512_loadu_ps(points.x + 16 * b);
      in[1] = _mm512_loadu_ps(points.y + 16 * b);
      in[2] = _mm512_loadu_ps(points.z + 16 * b);
    }
    __m512 pos[3];
    __m512i iv[3];
    for (int a = 0; a < 3; ++a) {
      pos[a] = _mm512_sub_ps(in[a], o[a]);
      const __m512 q = _mm512_mul_ps(pos[a], vscale);
      const __m256i lo =
          _mm512_cvttpd_epi32(_mm512_sub_pd(_mm512_cvtps_pd(_mm512_castps512_ps256(q)), vq0[a]));
      const __m256i hi = _mm512_cvttpd_epi32(_mm512_sub_pd(_mm512_cvtps_pd(High256(q)), vq0[a]));
      iv[a] = _mm512_inserti64x4(_mm512_castsi256_si512(lo), hi, 1);
    }
    std::int32_t* vo = vx + 64 * b;
    for (int j = 0; j < 4; ++j) {
      const __m512i idx = _mm512_load_si512(vidx[j]);
      const __m512i xy = _mm512_maskz_permutex2var_epi32(vxy, iv[0], idx, iv[1]);
      _mm512_storeu_si512(vo + 16 * j, _mm512_mask_permutexvar_epi32(xy, vz, idx, iv[2]));
    }
    __m512 aos[4];
    for (int k = 0; k < 3; ++k) {
      const __m512i idx = _mm512_load_si512(pidx[k]);
      aos[k] = _mm512_mask_permutexvar_ps(_mm512_permutex2var_ps(pos[0], idx, pos[1]), pz[k], idx,
                                          pos[2]);
    }
    float* fo = f + static_cast<std::size_t>(C) * 16 * b;
    if (!colors) {
      for (int k = 0; k < 3; ++k) _mm512_storeu_ps(fo + 16 * k, aos[k]);
      continue;
    }
    aos[3] = aos[2];
    __m512 rgb[4];
    for (int k = 0; k < 3; ++k)
      rgb[k] = _mm512_sub_ps(_mm512_loadu_ps(col + 48 * b + 16 * k), half);
    rgb[3] = rgb[2];
    for (int j = 0; j < 6; ++j) {
      const int k = base[j];
      const __m512 tp = _mm512_permutex2var_ps(aos[k], _mm512_load_si512(fp[j]), aos[k + 1]);
      const __m512 tc = _mm512_permutex2var_ps(rgb[k], _mm512_load_si512(fc[j]), rgb[k + 1]);
      _mm512_storeu_ps(fo + 16 * j, _mm512_mask_blend_ps(from_colour[j], tp, tc));
    }
  }
  InputRange(points, colors, 16 * blocks, n, origin, scale, q0, f, vx);
}

// The same in 8-lane AVX2 (no two-source permutes there): the x, y or z of 8 AoS points sit
// at 8 distinct lanes of the three vectors, so two blends and one lane permute gather them
// (and the inverse permute and two blends put them back).
struct Aos8 {
  int blend1, blend2;  // lanes taken from the second / third vector
  int lane[8];         // point i's lane
};
constexpr Aos8 kAos8[3] = {{0x92, 0x24, {0, 3, 6, 1, 4, 7, 2, 5}},
                           {0x24, 0x49, {1, 4, 7, 2, 5, 0, 3, 6}},
                           {0x49, 0x92, {2, 5, 0, 3, 6, 1, 4, 7}}};
// Back to AoS: the lane permute of each coordinate (P[lane] = the point stored there), and
// per output vector b the lanes holding y / z.
constexpr int kSoaPerm[3][8] = {
    {0, 3, 6, 1, 4, 7, 2, 5}, {5, 0, 3, 6, 1, 4, 7, 2}, {2, 5, 0, 3, 6, 1, 4, 7}};
constexpr int kSoaY[3] = {0x92, 0x24, 0x49}, kSoaZ[3] = {0x24, 0x49, 0x92};

template <int kB1, int kB2>
__attribute__((target("avx2"))) inline __m256 Gather8(__m256 a0, __m256 a1, __m256 a2,
                                                      __m256i lanes) {
  return _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a0, a1, kB1), a2, kB2), lanes);
}

__attribute__((target("avx2"))) inline void LoadAos8(const float* q, __m256 v[3]) {
  const __m256 a0 = _mm256_loadu_ps(q), a1 = _mm256_loadu_ps(q + 8), a2 = _mm256_loadu_ps(q + 16);
  v[0] = Gather8<kAos8[0].blend1, kAos8[0].blend2>(
      a0, a1, a2, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kAos8[0].lane)));
  v[1] = Gather8<kAos8[1].blend1, kAos8[1].blend2>(
      a0, a1, a2, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kAos8[1].lane)));
  v[2] = Gather8<kAos8[2].blend1, kAos8[2].blend2>(
      a0, a1, a2, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kAos8[2].lane)));
}

__attribute__((target("avx2"))) inline __m256 Join128(__m128 lo, __m128 hi) {
  return _mm256_insertf128_ps(_mm256_castps128_ps256(lo), hi, 1);
}

__attribute__((target("avx2"))) void Move256(const Eigen::Vector3f* p, std::size_t n, double cx,
                                             double cy, double sign, double c, double s,
                                             MovedPoints* out) {
  const __m256d vcx = _mm256_set1_pd(cx), vcy = _mm256_set1_pd(cy);
  const __m256d vsign = _mm256_set1_pd(sign), vc = _mm256_set1_pd(c), vs = _mm256_set1_pd(s);
  __m256 lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = _mm256_set1_ps(out->lo[a]);
    hi[a] = _mm256_set1_ps(out->hi[a]);
  }
  const float* src = reinterpret_cast<const float*>(p);
  float* dst[3] = {out->x.data(), out->y.data(), out->z.data()};
  const std::size_t blocks = n / 8;
  for (std::size_t b = 0; b < blocks; ++b) {
    __m256 in[3];
    LoadAos8(src + 24 * b, in);
    __m128 mx[2], my[2];
    for (int h = 0; h < 2; ++h) {
      const __m256d xd =
          _mm256_cvtps_pd(h == 0 ? _mm256_castps256_ps128(in[0]) : _mm256_extractf128_ps(in[0], 1));
      const __m256d yd =
          _mm256_cvtps_pd(h == 0 ? _mm256_castps256_ps128(in[1]) : _mm256_extractf128_ps(in[1], 1));
      const __m256d dx = _mm256_mul_pd(vsign, _mm256_sub_pd(xd, vcx));
      const __m256d dy = _mm256_sub_pd(yd, vcy);
      mx[h] = _mm256_cvtpd_ps(
          _mm256_sub_pd(_mm256_add_pd(vcx, _mm256_mul_pd(vc, dx)), _mm256_mul_pd(vs, dy)));
      my[h] = _mm256_cvtpd_ps(
          _mm256_add_pd(_mm256_add_pd(vcy, _mm256_mul_pd(vs, dx)), _mm256_mul_pd(vc, dy)));
    }
    const __m256 v[3] = {Join128(mx[0], mx[1]), Join128(my[0], my[1]), in[2]};
    for (int a = 0; a < 3; ++a) {
      _mm256_storeu_ps(dst[a] + 8 * b, v[a]);
      lo[a] = _mm256_min_ps(lo[a], v[a]);
      hi[a] = _mm256_max_ps(hi[a], v[a]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    alignas(32) float l[8], h[8];
    _mm256_store_ps(l, lo[a]);
    _mm256_store_ps(h, hi[a]);
    FoldBox(l, h, 8, a, out);
  }
  MoveRange(p, 8 * blocks, n, cx, cy, sign, c, s, out);
}

template <class Points>
__attribute__((target("avx2"))) void Input256(const Points& points, const Eigen::Vector3f* colors,
                                              std::size_t n, const float origin[3], float scale,
                                              const double q0[3], float* f, std::int32_t* vx) {
  constexpr bool kAos = std::is_same_v<Points, AosPoints>;
  const __m256 o[3] = {_mm256_set1_ps(origin[0]), _mm256_set1_ps(origin[1]),
                       _mm256_set1_ps(origin[2])};
  const __m256d vq0[3] = {_mm256_set1_pd(q0[0]), _mm256_set1_pd(q0[1]), _mm256_set1_pd(q0[2])};
  const __m256 vscale = _mm256_set1_ps(scale), half = _mm256_set1_ps(0.5f);
  __m256i perm[3];
  for (int a = 0; a < 3; ++a) {
    perm[a] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kSoaPerm[a]));
  }
  const float* col = reinterpret_cast<const float*>(colors);
  const int C = colors ? 6 : 3;
  const std::size_t blocks = n / 8;
  for (std::size_t b = 0; b < blocks; ++b) {
    __m256 in[3];
    if constexpr (kAos) {
      LoadAos8(points.p + 24 * b, in);
    } else {
      in[0] = _mm256_loadu_ps(points.x + 8 * b);
      in[1] = _mm256_loadu_ps(points.y + 8 * b);
      in[2] = _mm256_loadu_ps(points.z + 8 * b);
    }
    __m256 pos[3];
    __m256i iv[3];
    for (int a = 0; a < 3; ++a) {
      pos[a] = _mm256_sub_ps(in[a], o[a]);
      const __m256 q = _mm256_mul_ps(pos[a], vscale);
      const __m128i lo =
          _mm256_cvttpd_epi32(_mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(q)), vq0[a]));
      const __m128i hi =
          _mm256_cvttpd_epi32(_mm256_sub_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(q, 1)), vq0[a]));
      iv[a] = _mm256_inserti128_si256(_mm256_castsi128_si256(lo), hi, 1);
    }
    // Voxel rows (0, x, y, z): points (0, 1, 4, 5) and (2, 3, 6, 7) by 32- and 64-bit unpacks.
    const __m256i zero = _mm256_setzero_si256();
    const __m256i zx_lo = _mm256_unpacklo_epi32(zero, iv[0]),
                  yz_lo = _mm256_unpacklo_epi32(iv[1], iv[2]);
    const __m256i zx_hi = _mm256_unpackhi_epi32(zero, iv[0]),
                  yz_hi = _mm256_unpackhi_epi32(iv[1], iv[2]);
    const __m256i r0 = _mm256_unpacklo_epi64(zx_lo, yz_lo),
                  r1 = _mm256_unpackhi_epi64(zx_lo, yz_lo);
    const __m256i r2 = _mm256_unpacklo_epi64(zx_hi, yz_hi),
                  r3 = _mm256_unpackhi_epi64(zx_hi, yz_hi);
    __m256i* vo = reinterpret_cast<__m256i*>(vx + 32 * b);
    _mm256_storeu_si256(vo + 0, _mm256_permute2x128_si256(r0, r1, 0x20));  // points 0, 1
    _mm256_storeu_si256(vo + 1, _mm256_permute2x128_si256(r2, r3, 0x20));  // 2, 3
    _mm256_storeu_si256(vo + 2, _mm256_permute2x128_si256(r0, r1, 0x31));  // 4, 5
    _mm256_storeu_si256(vo + 3, _mm256_permute2x128_si256(r2, r3, 0x31));  // 6, 7
    // Positions back to AoS.
    const __m256 px = _mm256_permutevar8x32_ps(pos[0], perm[0]);
    const __m256 py = _mm256_permutevar8x32_ps(pos[1], perm[1]);
    const __m256 pz = _mm256_permutevar8x32_ps(pos[2], perm[2]);
    const __m256 aos[3] = {_mm256_blend_ps(_mm256_blend_ps(px, py, kSoaY[0]), pz, kSoaZ[0]),
                           _mm256_blend_ps(_mm256_blend_ps(px, py, kSoaY[1]), pz, kSoaZ[1]),
                           _mm256_blend_ps(_mm256_blend_ps(px, py, kSoaY[2]), pz, kSoaZ[2])};
    float* fo = f + static_cast<std::size_t>(C) * 8 * b;
    if (!colors) {
      for (int k = 0; k < 3; ++k) _mm256_storeu_ps(fo + 8 * k, aos[k]);
      continue;
    }
    // With colours: 6-float rows (position | colour - 0.5) through a small buffer.
    alignas(32) float pa[24], ca[24];
    for (int k = 0; k < 3; ++k) {
      _mm256_store_ps(pa + 8 * k, aos[k]);
      _mm256_store_ps(ca + 8 * k, _mm256_sub_ps(_mm256_loadu_ps(col + 24 * b + 8 * k), half));
    }
    for (int i = 0; i < 8; ++i) {
      std::memcpy(fo + 6 * i, pa + 3 * i, 3 * sizeof(float));
      std::memcpy(fo + 6 * i + 3, ca + 3 * i, 3 * sizeof(float));
    }
  }
  InputRange(points, colors, 8 * blocks, n, origin, scale, q0, f, vx);
}
#endif

}  // namespace

void MoveScenePoints(const Eigen::Vector3f* points, std::size_t n, double cx, double cy,
                     double sign, double cos_theta, double sin_theta, MovedPoints* out,
                     HeadsIsa isa) {
  out->x.resize(n);
  out->y.resize(n);
  out->z.resize(n);
  for (int a = 0; a < 3; ++a) {
    out->lo[a] = INFINITY;
    out->hi[a] = -INFINITY;
  }
#if defined(__x86_64__)
  switch (Resolve(isa)) {
    case HeadsIsa::kAvx512:
      Move512(points, n, cx, cy, sign, cos_theta, sin_theta, out);
      return;
    case HeadsIsa::kAvx2:
      Move256(points, n, cx, cy, sign, cos_theta, sin_theta, out);
      return;
    default:
      break;
  }
#else
  (void)Resolve(isa);
#endif
  MoveRange(points, 0, n, cx, cy, sign, cos_theta, sin_theta, out);
}

namespace {

template <class Points>
void WriteInput(const Points& points, const Eigen::Vector3f* colors, std::size_t n,
                const float origin[3], float scale, const float qmin[3], float* features,
                std::int32_t* voxel, HeadsIsa isa) {
  const double q0[3] = {qmin[0], qmin[1], qmin[2]};
#if defined(__x86_64__)
  switch (Resolve(isa)) {
    case HeadsIsa::kAvx512:
      Input512(points, colors, n, origin, scale, q0, features, voxel);
      return;
    case HeadsIsa::kAvx2:
      Input256(points, colors, n, origin, scale, q0, features, voxel);
      return;
    default:
      break;
  }
#else
  (void)Resolve(isa);
#endif
  InputRange(points, colors, 0, n, origin, scale, q0, features, voxel);
}

}  // namespace

void WriteMovedNetworkInput(const MovedPoints& moved, const Eigen::Vector3f* colors, std::size_t n,
                            const float origin[3], float scale, const float qmin[3],
                            float* features, std::int32_t* voxel, HeadsIsa isa) {
  WriteInput(SoaPoints{moved.x.data(), moved.y.data(), moved.z.data()}, colors, n, origin, scale,
             qmin, features, voxel, isa);
}

void WriteNetworkInput(const Eigen::Vector3f* points, const Eigen::Vector3f* colors, std::size_t n,
                       const float origin[3], float scale, const float qmin[3], float* features,
                       std::int32_t* voxel, HeadsIsa isa) {
  WriteInput(AosPoints{reinterpret_cast<const float*>(points)}, colors, n, origin, scale, qmin,
             features, voxel, isa);
}

HeadsIsa HeadsIsaOfSparsePath() {
  switch (ResolveSparseKernelPath()) {
    case SparseKernelPath::kAvx512:
      return HeadsIsa::kAvx512;
    case SparseKernelPath::kAvx2:
      return HeadsIsa::kAvx2;
    default:
      return HeadsIsa::kGeneric;
  }
}

}  // namespace dimr::nn::stage1_heads
