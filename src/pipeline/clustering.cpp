#include "dimr/pipeline/clustering.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <numeric>
#include <string>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_data.h"

namespace dimr::pipeline {

using nn::DecodeHeading;
using nn::kHeadingBins;
namespace {

constexpr double kPi = 3.14159265358979323846;

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator<(const CellKey& o) const {
    if (x != o.x) return x < o.x;
    if (y != o.y) return y < o.y;
    return z < o.z;
  }
};

// Calls f(e) for every index e of the sorted `keys` among the 27 cells around keys[c] (itself
// included), in key order. For each (dx, dy) the run of keys (x + dx, y + dy, z - 1 .. z + 1)
// only moves forward with c, so nine monotone cursors replace 27 hash probes per cell: call it
// for c = 0, 1, 2, ... with the same zero-initialised `cursor`.
template <class F>
void ForEachNearCell(const std::vector<CellKey>& keys, std::size_t c, std::size_t (&cursor)[9],
                     F&& f) {
  const CellKey key = keys[c];
  for (int d = 0; d < 9; ++d) {
    const CellKey from{key.x + d / 3 - 1, key.y + d % 3 - 1, key.z - 1};
    const CellKey to{from.x, from.y, key.z + 1};
    std::size_t& q = cursor[d];
    while (q < keys.size() && keys[q] < from) ++q;
    for (std::size_t e = q; e < keys.size() && !(to < keys[e]); ++e) f(e);
  }
}

// ---------------------------------------------------------------- distance-test kernels
// The ball query's float tests, ((x_j - x_k)^2 + (y_j - y_k)^2) + (z_j - z_k)^2 < r^2, eight
// at a time with AVX2 where the CPU has it (runtime dispatch; compiled without FMA, so the
// operations and their rounding are the reference's in every path), else four at a time
// with SSE2. Ids of hits are compacted in slot order.

bool g_allow_avx2 = true;

bool CpuHasAvx2() {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
  return yes;
}

bool UseAvx2() { return g_allow_avx2 && CpuHasAvx2(); }

// For each 8-bit mask, the lanes of its set bits first (the compaction permutation).
struct CompressTable {
  alignas(32) std::int32_t lanes[256][8];
  CompressTable() {
    for (int m = 0; m < 256; ++m) {
      int k = 0;
      for (int b = 0; b < 8; ++b) {
        if ((m >> b) & 1) lanes[m][k++] = b;
      }
      for (; k < 8; ++k) lanes[m][k] = 0;
    }
  }
};
const CompressTable& Compress() {
  static const CompressTable table;
  return table;
}

// Bit i set when point s + i lies strictly within r2 (squared distance) of the query: the same
// float operations, in the same order, as the scalar path (no FMA).
__attribute__((target("avx2"))) inline unsigned WithinMaskAvx2(const float* x, const float* y,
                                                               const float* z, int s, __m256 qx,
                                                               __m256 qy, __m256 qz, __m256 rr) {
  const __m256 ex = _mm256_sub_ps(qx, _mm256_loadu_ps(x + s));
  const __m256 ey = _mm256_sub_ps(qy, _mm256_loadu_ps(y + s));
  const __m256 ez = _mm256_sub_ps(qz, _mm256_loadu_ps(z + s));
  const __m256 d2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ex, ex), _mm256_mul_ps(ey, ey)),
                                  _mm256_mul_ps(ez, ez));
  return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(d2, rr, _CMP_LT_OQ)));
}

__attribute__((target("avx2,popcnt"))) std::size_t CountWithinAvx2(const float* x, const float* y,
                                                                   const float* z, int s0, int s1,
                                                                   float px, float py, float pz,
                                                                   float r2, std::size_t stop,
                                                                   int* next) {
  const __m256 qx = _mm256_set1_ps(px), qy = _mm256_set1_ps(py), qz = _mm256_set1_ps(pz);
  const __m256 rr = _mm256_set1_ps(r2);
  std::size_t count = 0;
  int s = s0;
  for (; s + 8 <= s1; s += 8) {
    count += static_cast<std::size_t>(_mm_popcnt_u32(WithinMaskAvx2(x, y, z, s, qx, qy, qz, rr)));
    if (count >= stop) break;
  }
  *next = s;
  return count;
}

__attribute__((target("avx2,popcnt"))) std::size_t CompactWithinAvx2(const float* x, const float* y,
                                                                     const float* z, const int* id,
                                                                     int s0, int s1, float px,
                                                                     float py, float pz, float r2,
                                                                     int* out, int* next) {
  const __m256 qx = _mm256_set1_ps(px), qy = _mm256_set1_ps(py), qz = _mm256_set1_ps(pz);
  const __m256 rr = _mm256_set1_ps(r2);
  const CompressTable& table = Compress();
  std::size_t count = 0;
  int s = s0;
  for (; s + 8 <= s1; s += 8) {
    const unsigned mask = WithinMaskAvx2(x, y, z, s, qx, qy, qz, rr);
    const __m256i ids = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(id + s));
    const __m256i perm = _mm256_load_si256(reinterpret_cast<const __m256i*>(table.lanes[mask]));
    // out has room for the 8 slots of this block past count (count <= s - s0).
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + count),
                        _mm256_permutevar8x32_epi32(ids, perm));
    count += static_cast<std::size_t>(_mm_popcnt_u32(mask));
  }
  *next = s;
  return count;
}

// Whether some slot of [s0, s1) (blocks of 8) lies within r2 of the query; *next = the first
// slot not tested.
__attribute__((target("avx2"))) bool AnyWithinAvx2(const float* x, const float* y, const float* z,
                                                   int s0, int s1, float px, float py, float pz,
                                                   float r2, int* next) {
  const __m256 qx = _mm256_set1_ps(px), qy = _mm256_set1_ps(py), qz = _mm256_set1_ps(pz);
  const __m256 rr = _mm256_set1_ps(r2);
  int s = s0;
  for (; s + 8 <= s1; s += 8) {
    if (WithinMaskAvx2(x, y, z, s, qx, qy, qz, rr) != 0) return true;
  }
  *next = s;
  return false;
}

// The box test of BallQuery::Bounds for slots [s0, s1): ids whose max distance to the box is
// below r2_sure go to sure, those whose min distance is below r2_maybe to maybe.
__attribute__((target("avx2,popcnt"))) int BoxClassifyAvx2(const float* x, const float* y,
                                                           const float* z, const int* id, int s0,
                                                           int s1, const float* lo, const float* hi,
                                                           float r2_sure, float r2_maybe, int* sure,
                                                           std::size_t* num_sure, int* maybe,
                                                           std::size_t* num_maybe) {
  const __m256 lox = _mm256_set1_ps(lo[0]), loy = _mm256_set1_ps(lo[1]),
               loz = _mm256_set1_ps(lo[2]);
  const __m256 hix = _mm256_set1_ps(hi[0]), hiy = _mm256_set1_ps(hi[1]),
               hiz = _mm256_set1_ps(hi[2]);
  const __m256 zero = _mm256_setzero_ps();
  const __m256 rs = _mm256_set1_ps(r2_sure), rm = _mm256_set1_ps(r2_maybe);
  const CompressTable& table = Compress();
  std::size_t ns = *num_sure, nm = *num_maybe;
  int s = s0;
  for (; s + 8 <= s1; s += 8) {
    const __m256 vx = _mm256_loadu_ps(x + s), vy = _mm256_loadu_ps(y + s),
                 vz = _mm256_loadu_ps(z + s);
    const __m256 fx = _mm256_max_ps(_mm256_sub_ps(vx, lox), _mm256_sub_ps(hix, vx));
    const __m256 fy = _mm256_max_ps(_mm256_sub_ps(vy, loy), _mm256_sub_ps(hiy, vy));
    const __m256 fz = _mm256_max_ps(_mm256_sub_ps(vz, loz), _mm256_sub_ps(hiz, vz));
    const __m256 nx =
        _mm256_max_ps(_mm256_max_ps(_mm256_sub_ps(lox, vx), _mm256_sub_ps(vx, hix)), zero);
    const __m256 ny =
        _mm256_max_ps(_mm256_max_ps(_mm256_sub_ps(loy, vy), _mm256_sub_ps(vy, hiy)), zero);
    const __m256 nz =
        _mm256_max_ps(_mm256_max_ps(_mm256_sub_ps(loz, vz), _mm256_sub_ps(vz, hiz)), zero);
    const __m256 far2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(fx, fx), _mm256_mul_ps(fy, fy)),
                                      _mm256_mul_ps(fz, fz));
    const __m256 near2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(nx, nx), _mm256_mul_ps(ny, ny)),
                                       _mm256_mul_ps(nz, nz));
    const unsigned ms =
        static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(far2, rs, _CMP_LT_OQ)));
    const unsigned mm =
        static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(near2, rm, _CMP_LT_OQ)));
    const __m256i ids = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(id + s));
    _mm256_storeu_si256(
        reinterpret_cast<__m256i*>(sure + ns),
        _mm256_permutevar8x32_epi32(
            ids, _mm256_load_si256(reinterpret_cast<const __m256i*>(table.lanes[ms]))));
    _mm256_storeu_si256(
        reinterpret_cast<__m256i*>(maybe + nm),
        _mm256_permutevar8x32_epi32(
            ids, _mm256_load_si256(reinterpret_cast<const __m256i*>(table.lanes[mm]))));
    ns += static_cast<std::size_t>(_mm_popcnt_u32(ms));
    nm += static_cast<std::size_t>(_mm_popcnt_u32(mm));
  }
  *num_sure = ns;
  *num_maybe = nm;
  return s;
}

// Ball query over a uniform voxel hash of the labelled points, with the BFS's visited state.
// The cell is a hair larger than the radius so that every pair with d < r (even after float
// rounding of d^2) lies in adjacent cells. The points are stored cell-major, by label inside
// a cell and by index inside a (cell, label) segment; each segment also keeps its unvisited
// points in index order (visited ones dropped in batches), so a query tests only the points
// it could still add to the BFS (unvisited, same label). Where the neighbour cap can bind (more
// than cap points in the 27 cells), the cap-th neighbour index T_j of a point is bracketed by
// bounds shared by its sub-box of the cell (Bounds): candidates below the lower bound are
// neighbours, those above the upper one are not, and only the ones in between need j's exact
// ranks (its hits below them, counted in index order as the reference's scan).
class BallQuery {
 public:
  BallQuery(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& labels,
            double radius, int cap)
      : cap_(static_cast<std::size_t>(cap)),
        visited_(points.size(), 0),
        num_points_(points.size()) {
    const float rf = static_cast<float>(radius);
    r2_ = rf * rf;  // as the reference kernel: float radius, float radius^2
    inv_cell_ = 1.0 / (radius * (1.0 + 1e-5));
    struct Keyed {
      CellKey key;
      int label, index;
    };
    std::vector<Keyed> keyed;
    for (int i = 0; i < static_cast<int>(points.size()); ++i) {
      if (labels[i] >= 0) keyed.push_back({Key(points[i]), labels[i], i});
    }
    std::sort(keyed.begin(), keyed.end(), [](const Keyed& a, const Keyed& b) {
      if (!(a.key == b.key)) return a.key < b.key;
      if (a.label != b.label) return a.label < b.label;
      return a.index < b.index;
    });
    const std::size_t n = keyed.size();
    order_.resize(n);
    xs_.resize(n);
    ys_.resize(n);
    zs_.resize(n);
    slot_of_.assign(points.size(), -1);
    seg_of_.assign(points.size(), -1);
    std::vector<CellKey> cell_keys;
    for (std::size_t i = 0; i < n; ++i) {
      const int k = keyed[i].index;
      order_[i] = k;
      xs_[i] = points[k].x();
      ys_[i] = points[k].y();
      zs_[i] = points[k].z();
      const bool new_cell = i == 0 || !(keyed[i].key == keyed[i - 1].key);
      if (new_cell) {
        cell_keys.push_back(keyed[i].key);
        cell_seg_begin_.push_back(static_cast<int>(segs_.size()));
      }
      if (new_cell || keyed[i].label != keyed[i - 1].label) {
        const int begin = static_cast<int>(i);
        segs_.push_back({begin, begin, keyed[i].label, begin, 0,
                         static_cast<int>(cell_keys.size()) - 1, begin});
      }
      Segment& seg = segs_.back();
      seg.end = seg.live_end = static_cast<int>(i) + 1;
      ++seg.unvisited;
      slot_of_[k] = static_cast<int>(i);
      seg_of_[k] = static_cast<int>(segs_.size()) - 1;
    }
    cell_seg_begin_.push_back(static_cast<int>(segs_.size()));
    // The unvisited arrays start as copies (same slots).
    uorder_ = order_;
    ux_ = xs_;
    uy_ = ys_;
    uz_ = zs_;
    // The occupied cells among each cell's 27 (itself included) and the number of labelled
    // points in them (if it is <= cap the cap cannot bind).
    const std::size_t num_cells = cell_keys.size();
    near_begin_.reserve(num_cells + 1);
    near_begin_.push_back(0);
    near_total_.reserve(num_cells);
    std::size_t cursor[9] = {};
    for (std::size_t c = 0; c < num_cells; ++c) {
      const CellKey key = cell_keys[c];
      std::size_t total = 0;
      ForEachNearCell(cell_keys, c, cursor, [&](std::size_t e) {
        near_.push_back(static_cast<int>(e));
        total += segs_[cell_seg_begin_[e + 1] - 1].end - segs_[cell_seg_begin_[e]].begin;
      });
      // Nearest cells first (itself, faces, edges, corners): the count of hits below a bound
      // reaches the cap with fewer tests.
      const auto ring = [&](int e) {
        const CellKey& k = cell_keys[e];
        return std::abs(k.x - key.x) + std::abs(k.y - key.y) + std::abs(k.z - key.z);
      };
      std::stable_sort(near_.begin() + near_begin_.back(), near_.end(),
                       [&](int a, int b) { return ring(a) < ring(b); });
      near_begin_.push_back(static_cast<int>(near_.size()));
      near_total_.push_back(total);
    }
    // Sub-boxes: kSub^3 per cell, each with the bounding box of its points.
    std::vector<std::pair<std::int64_t, int>> sub(n);
    for (std::size_t i = 0; i < n; ++i) {
      const int k = order_[i];
      const CellKey key = cell_keys[segs_[seg_of_[k]].cell];
      const auto part = [&](float v, std::int64_t c) {
        const double f = (static_cast<double>(v) * inv_cell_ - static_cast<double>(c)) * kSub;
        return static_cast<std::int64_t>(std::clamp(std::floor(f), 0.0, kSub - 1.0));
      };
      const std::int64_t code =
          (part(xs_[i], key.x) * kSub + part(ys_[i], key.y)) * kSub + part(zs_[i], key.z);
      sub[i] = {static_cast<std::int64_t>(segs_[seg_of_[k]].cell) * kSub * kSub * kSub + code,
                static_cast<int>(i)};
    }
    std::sort(sub.begin(), sub.end());
    group_of_.assign(points.size(), -1);
    for (std::size_t i = 0; i < n; ++i) {
      const int slot = sub[i].second;
      if (i == 0 || sub[i].first != sub[i - 1].first) {
        Group g;
        g.first_slot = slot;
        g.lo[0] = g.hi[0] = xs_[slot];
        g.lo[1] = g.hi[1] = ys_[slot];
        g.lo[2] = g.hi[2] = zs_[slot];
        groups_.push_back(g);
      }
      Group& g = groups_.back();
      const float v[3] = {xs_[slot], ys_[slot], zs_[slot]};
      for (int a = 0; a < 3; ++a) {
        g.lo[a] = std::min(g.lo[a], v[a]);
        g.hi[a] = std::max(g.hi[a], v[a]);
      }
      group_of_[order_[slot]] = static_cast<int>(groups_.size()) - 1;
    }
  }

  bool visited(int k) const { return visited_[k] != 0; }
  void MarkVisited(int k) {
    visited_[k] = 1;
    Segment& seg = segs_[seg_of_[k]];
    --seg.unvisited;
    // Drop the visited entries of the segment's unvisited arrays once they are the majority
    // (stable: the arrays stay in index order; amortised O(1) per visit).
    const int size = seg.live_end - seg.begin;
    if (size >= 16 && size - seg.unvisited > seg.unvisited) {
      int out = seg.begin;
      for (int s = seg.begin; s < seg.live_end; ++s) {
        if (visited_[uorder_[s]]) continue;
        uorder_[out] = uorder_[s];
        ux_[out] = ux_[s];
        uy_[out] = uy_[s];
        uz_[out] = uz_[s];
        ++out;
      }
      seg.live_end = out;
    }
  }

  // The points that labelled point j (at p, label `label`, already visited) adds to the BFS,
  // in increasing index order, into *fresh: the unvisited points k of the same label with
  // |x_j - x_k|^2 < r^2 (float) that are among j's first `cap` neighbours in index order
  // (neighbours: all labelled points within the radius, j itself included).
  void Query(int j, const Eigen::Vector3f& p, int label, std::vector<int>* fresh) {
    fresh->clear();
    const int cj = segs_[seg_of_[j]].cell;
    const int* near = near_.data() + near_begin_[cj];
    const int num_near = near_begin_[cj + 1] - near_begin_[cj];
    // Smallest unvisited index of `label` around j (each segment's first-unvisited slot only
    // moves forward) and the segments holding such points.
    int m = std::numeric_limits<int>::max();
    int label_segs[27];
    int num_label_segs = 0;
    for (int n = 0; n < num_near; ++n) {
      const int c = near[n];
      for (int g = cell_seg_begin_[c]; g < cell_seg_begin_[c + 1]; ++g) {
        Segment& seg = segs_[g];
        if (seg.label != label) continue;
        if (seg.unvisited == 0) break;
        while (visited_[order_[seg.first_unvisited]]) ++seg.first_unvisited;
        m = std::min(m, order_[seg.first_unvisited]);
        label_segs[num_label_segs++] = g;
        break;
      }
    }
    if (num_label_segs == 0) return;
    const float px = p.x(), py = p.y(), pz = p.z();
    // j's cap-th neighbour index T_j (infinite if it has < cap) lies in [t_lo, t_hi], bounds
    // shared by the points of j's sub-box (see Bounds).
    int t_lo = kNone, t_hi = kNone;
    if (near_total_[cj] > cap_) {
      const Group& group = Bounds(group_of_[j], near, num_near);
      t_lo = group.t_lo;
      t_hi = group.t_hi;
      if (m > t_hi) return;  // cap neighbours precede every candidate
    }
    std::size_t below = 0;  // hits with an index < lo
    int lo = m;
    if (m > t_lo) {
      // Every candidate is undecided: if cap hits precede them, j adds nothing.
      below = CountBelow(px, py, pz, near, num_near, m);
      if (below >= cap_) return;
    }
    // The candidates: unvisited points of `label` within the radius, index <= t_hi.
    for (int t = 0; t < num_label_segs; ++t) {
      const Segment& seg = segs_[label_segs[t]];
      const int* u = uorder_.data();
      const int s0 = static_cast<int>(std::lower_bound(u + seg.begin, u + seg.live_end, m) - u);
      const int s1 = t_hi == kNone
                         ? seg.live_end
                         : static_cast<int>(std::upper_bound(u + s0, u + seg.live_end, t_hi) - u);
      const std::size_t before = fresh->size();
      fresh->resize(before + (s1 - s0));
      std::size_t got =
          CompactHits(px, py, pz, &ux_[0], &uy_[0], &uz_[0], u, s0, s1, fresh->data() + before);
      int* f = fresh->data() + before;
      std::size_t kept = 0;
      for (std::size_t i = 0; i < got; ++i) {
        f[kept] = f[i];
        kept += visited_[f[i]] ? 0 : 1;
      }
      fresh->resize(before + kept);
      if (before > 0) std::inplace_merge(fresh->begin(), fresh->begin() + before, fresh->end());
    }
    if (fresh->empty()) return;
    if (fresh->back() <= t_lo) return;  // all among the first cap
    // The undecided candidates, > t_lo: j's exact neighbour ranks. lo = the first of them.
    const auto first = std::upper_bound(fresh->begin(), fresh->end(), t_lo);
    const int max_fresh = fresh->back();
    if (*first != lo) {
      lo = *first;
      below = CountBelow(px, py, pz, near, num_near, lo);
      if (below >= cap_) {
        fresh->erase(first, fresh->end());
        return;
      }
    }
    // A candidate k >= lo is a neighbour iff k <= the (cap - below)-th smallest hit index
    // >= lo (the reference stops at the cap-th hit).
    span_hits_.clear();
    for (int n = 0; n < num_near; ++n) {
      const int c = near[n];
      for (int g = cell_seg_begin_[c]; g < cell_seg_begin_[c + 1]; ++g) {
        const Segment& seg = segs_[g];
        const int s0 = PrefixEnd(seg, lo), s1 = PrefixEnd(seg, max_fresh + 1);
        const std::size_t before = span_hits_.size();
        span_hits_.resize(before + (s1 - s0));
        const std::size_t got = CompactHits(px, py, pz, &xs_[0], &ys_[0], &zs_[0], &order_[0], s0,
                                            s1, span_hits_.data() + before);
        span_hits_.resize(before + got);
      }
    }
    const std::size_t need = cap_ - below;  // >= 1
    if (span_hits_.size() <= need) return;
    std::nth_element(span_hits_.begin(), span_hits_.begin() + (need - 1), span_hits_.end());
    const int last = span_hits_[need - 1];
    fresh->erase(std::upper_bound(fresh->begin(), fresh->end(), last), fresh->end());
  }

 private:
  struct Segment {
    int begin, end;       // slots in order_ (and in the unvisited arrays, from begin)
    int label;            //
    int first_unvisited;  // slots of order_ before it are all visited
    int unvisited;        // number of unvisited points
    int cell;
    int live_end;  // uorder_[begin, live_end): the unvisited points and some visited ones
  };

  static constexpr int kNone = std::numeric_limits<int>::max();
  static constexpr int kSub = 4;  // sub-boxes per cell and axis

  // A sub-box of a cell: the bounding box of its points and bounds on the cap-th neighbour
  // index of each of them (kNone: fewer than cap neighbours), computed on first use.
  struct Group {
    float lo[3], hi[3];
    int first_slot;  // a slot of one of its points
    bool ready = false;
    int t_lo = kNone;  // cap-th smallest index of the points that may be within r of the box
    int t_hi = kNone;  // cap-th smallest index of the points within r of all of the box
  };

  // The points whose float distance test passes for every point of the box (max distance
  // below r with a margin far above float rounding) and those for which it may pass (min
  // distance below r, same margin): the cap-th smallest index of each bounds T_j.
  const Group& Bounds(int gid, const int* near, int num_near) {
    Group& g = groups_[gid];
    if (g.ready) return g;
    g.ready = true;
    const int gcell = segs_[seg_of_[order_[g.first_slot]]].cell;
    sure_.resize(near_total_[gcell]);
    maybe_.resize(near_total_[gcell]);
    int* sure = sure_.data();
    int* maybe = maybe_.data();
    std::size_t num_sure = 0, num_maybe = 0;
    const __m128 lox = _mm_set1_ps(g.lo[0]), loy = _mm_set1_ps(g.lo[1]), loz = _mm_set1_ps(g.lo[2]);
    const __m128 hix = _mm_set1_ps(g.hi[0]), hiy = _mm_set1_ps(g.hi[1]), hiz = _mm_set1_ps(g.hi[2]);
    const __m128 zero = _mm_setzero_ps();
    const __m128 r2_sure = _mm_set1_ps(r2_ * (1.f - 1e-5f));
    const __m128 r2_maybe = _mm_set1_ps(r2_ * (1.f + 1e-5f));
    for (int nc = 0; nc < num_near; ++nc) {
      const int c = near[nc];
      const int s0 = segs_[cell_seg_begin_[c]].begin, s1 = segs_[cell_seg_begin_[c + 1] - 1].end;
      int s = s0;
      if (UseAvx2()) {
        s = BoxClassifyAvx2(&xs_[0], &ys_[0], &zs_[0], &order_[0], s0, s1, g.lo, g.hi,
                            r2_ * (1.f - 1e-5f), r2_ * (1.f + 1e-5f), sure, &num_sure, maybe,
                            &num_maybe);
      }
      for (; s + 4 <= s1; s += 4) {
        const __m128 x = _mm_loadu_ps(&xs_[s]), y = _mm_loadu_ps(&ys_[s]),
                     z = _mm_loadu_ps(&zs_[s]);
        const __m128 fx = _mm_max_ps(_mm_sub_ps(x, lox), _mm_sub_ps(hix, x));
        const __m128 fy = _mm_max_ps(_mm_sub_ps(y, loy), _mm_sub_ps(hiy, y));
        const __m128 fz = _mm_max_ps(_mm_sub_ps(z, loz), _mm_sub_ps(hiz, z));
        const __m128 nx = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lox, x), _mm_sub_ps(x, hix)), zero);
        const __m128 ny = _mm_max_ps(_mm_max_ps(_mm_sub_ps(loy, y), _mm_sub_ps(y, hiy)), zero);
        const __m128 nz = _mm_max_ps(_mm_max_ps(_mm_sub_ps(loz, z), _mm_sub_ps(z, hiz)), zero);
        const __m128 far2 =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(fx, fx), _mm_mul_ps(fy, fy)), _mm_mul_ps(fz, fz));
        const __m128 near2 =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, nx), _mm_mul_ps(ny, ny)), _mm_mul_ps(nz, nz));
        const unsigned ms = static_cast<unsigned>(_mm_movemask_ps(_mm_cmplt_ps(far2, r2_sure)));
        const unsigned mm = static_cast<unsigned>(_mm_movemask_ps(_mm_cmplt_ps(near2, r2_maybe)));
        for (int b = 0; b < 4; ++b) {
          sure[num_sure] = maybe[num_maybe] = order_[s + b];
          num_sure += (ms >> b) & 1u;
          num_maybe += (mm >> b) & 1u;
        }
      }
      for (; s < s1; ++s) {
        const float v[3] = {xs_[s], ys_[s], zs_[s]};
        float far2 = 0.f, near2 = 0.f;
        for (int a = 0; a < 3; ++a) {
          const float f = std::max(v[a] - g.lo[a], g.hi[a] - v[a]);
          const float e = std::max(std::max(g.lo[a] - v[a], v[a] - g.hi[a]), 0.f);
          far2 += f * f;
          near2 += e * e;
        }
        sure[num_sure] = maybe[num_maybe] = order_[s];
        num_sure += far2 < r2_ * (1.f - 1e-5f) ? 1 : 0;
        num_maybe += near2 < r2_ * (1.f + 1e-5f) ? 1 : 0;
      }
    }
    const auto kth = [this](int* v, std::size_t size) {
      return size < cap_ ? kNone : KthSmallest(v, size, cap_ - 1);
    };
    g.t_hi = kth(sure, num_sure);
    g.t_lo = kth(maybe, num_maybe);
    return g;
  }

  // Hits of p with an index < bound (all labels), counting stops at cap.
  std::size_t CountBelow(float px, float py, float pz, const int* near, int num_near, int bound) {
    std::size_t below = 0;
    for (int n = 0; n < num_near && below < cap_; ++n) {
      const int c = near[n];
      for (int g = cell_seg_begin_[c]; g < cell_seg_begin_[c + 1] && below < cap_; ++g) {
        const Segment& seg = segs_[g];
        const int s1 = PrefixEnd(seg, bound);
        below += CountHits(px, py, pz, seg.begin, s1, cap_ - below);
      }
    }
    return below;
  }

  // The (k+1)-th smallest of v[0, size) (non-negative ids below the point count): a
  // 1024-bucket histogram of the high bits, then a selection inside the one bucket.
  int KthSmallest(const int* v, std::size_t size, std::size_t k) {
    int shift = 0;
    while ((num_points_ >> shift) >= 1024) ++shift;
    std::fill(std::begin(hist_), std::end(hist_), 0);
    for (std::size_t i = 0; i < size; ++i) ++hist_[v[i] >> shift];
    int bucket = 0;
    std::size_t before = 0;
    while (before + hist_[bucket] <= k) before += hist_[bucket++];
    bucket_.clear();
    for (std::size_t i = 0; i < size; ++i) {
      if ((v[i] >> shift) == bucket) bucket_.push_back(v[i]);
    }
    std::nth_element(bucket_.begin(), bucket_.begin() + (k - before), bucket_.end());
    return bucket_[k - before];
  }

  // First slot of seg whose index is >= bound (indices ascend inside a segment).
  int PrefixEnd(const Segment& seg, int bound) const {
    return static_cast<int>(
        std::lower_bound(order_.begin() + seg.begin, order_.begin() + seg.end, bound) -
        order_.begin());
  }

  // Number of slots in [s0, s1) of the full arrays within the radius, stopping once it
  // reaches `stop`. Same float expression as the reference: ((ex^2 + ey^2) + ez^2) < r^2.
  std::size_t CountHits(float px, float py, float pz, int s0, int s1, std::size_t stop) const {
    std::size_t count = 0;
    int s = s0;
    if (UseAvx2()) {
      count = CountWithinAvx2(&xs_[0], &ys_[0], &zs_[0], s0, s1, px, py, pz, r2_, stop, &s);
      if (count >= stop) return count;
    }
    const __m128 qx = _mm_set1_ps(px), qy = _mm_set1_ps(py), qz = _mm_set1_ps(pz);
    const __m128 r2 = _mm_set1_ps(r2_);
    for (; s + 4 <= s1; s += 4) {
      const __m128 ex = _mm_sub_ps(qx, _mm_loadu_ps(&xs_[s]));
      const __m128 ey = _mm_sub_ps(qy, _mm_loadu_ps(&ys_[s]));
      const __m128 ez = _mm_sub_ps(qz, _mm_loadu_ps(&zs_[s]));
      const __m128 d2 =
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(ex, ex), _mm_mul_ps(ey, ey)), _mm_mul_ps(ez, ez));
      static constexpr unsigned char kBits[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};
      count += kBits[_mm_movemask_ps(_mm_cmplt_ps(d2, r2))];
      if (count >= stop) return count;
    }
    for (; s < s1; ++s) count += Within(px, py, pz, xs_[s], ys_[s], zs_[s]) ? 1 : 0;
    return count;
  }

  bool Within(float px, float py, float pz, float x, float y, float z) const {
    const float ex = px - x;
    const float ey = py - y;
    const float ez = pz - z;
    return ex * ex + ey * ey + ez * ez < r2_;
  }

  // Writes the ids of the slots in [s0, s1) of (x, y, z, id) within the radius to out, in
  // slot order; returns their number. Four at a time, branch-free compaction.
  std::size_t CompactHits(float px, float py, float pz, const float* x, const float* y,
                          const float* z, const int* id, int s0, int s1, int* out) const {
    std::size_t count = 0;
    int s = s0;
    if (UseAvx2()) count = CompactWithinAvx2(x, y, z, id, s0, s1, px, py, pz, r2_, out, &s);
    const __m128 qx = _mm_set1_ps(px), qy = _mm_set1_ps(py), qz = _mm_set1_ps(pz);
    const __m128 r2 = _mm_set1_ps(r2_);
    for (; s + 4 <= s1; s += 4) {
      const __m128 ex = _mm_sub_ps(qx, _mm_loadu_ps(x + s));
      const __m128 ey = _mm_sub_ps(qy, _mm_loadu_ps(y + s));
      const __m128 ez = _mm_sub_ps(qz, _mm_loadu_ps(z + s));
      const __m128 d2 =
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(ex, ex), _mm_mul_ps(ey, ey)), _mm_mul_ps(ez, ez));
      const unsigned mask = static_cast<unsigned>(_mm_movemask_ps(_mm_cmplt_ps(d2, r2)));
      for (int b = 0; b < 4; ++b) {
        out[count] = id[s + b];
        count += (mask >> b) & 1u;
      }
    }
    for (; s < s1; ++s) {
      out[count] = id[s];
      count += Within(px, py, pz, x[s], y[s], z[s]) ? 1 : 0;
    }
    return count;
  }

  CellKey Key(const Eigen::Vector3f& p) const {
    return {static_cast<std::int64_t>(std::floor(static_cast<double>(p.x()) * inv_cell_)),
            static_cast<std::int64_t>(std::floor(static_cast<double>(p.y()) * inv_cell_)),
            static_cast<std::int64_t>(std::floor(static_cast<double>(p.z()) * inv_cell_))};
  }

  std::size_t cap_;
  float r2_ = 0.f;
  double inv_cell_ = 0.0;
  std::vector<char> visited_;
  // Labelled points, cell-major, by label in a cell, by index in a segment.
  std::vector<float> xs_, ys_, zs_;
  std::vector<int> order_;
  // The unvisited points of each segment, in its first slots (any order).
  std::vector<float> ux_, uy_, uz_;
  std::vector<int> uorder_;
  std::vector<int> slot_of_;  // per point: its slot in order_, -1 if unlabelled
  std::vector<int> seg_of_;   // per point: its segment, -1 if unlabelled
  std::vector<Segment> segs_;
  std::vector<int> cell_seg_begin_;      // per cell: its first segment (cells + 1 entries)
  std::vector<int> near_;                // per cell: its occupied neighbour cells (CSR)
  std::vector<int> near_begin_;          // cells + 1
  std::vector<std::size_t> near_total_;  // per cell: labelled points in its 27 cells
  std::vector<int> span_hits_;
  std::vector<Group> groups_;
  std::vector<int> group_of_;  // per point: its sub-box
  std::vector<int> sure_, maybe_, bucket_;
  std::uint32_t hist_[1024];
  std::size_t num_points_;
};

// Connected components of the uncapped ball-query graph (RadiusComponents): the labelled
// points in cells a hair larger than the radius, each (cell, label) segment split into its
// octants ("parts", half a cell wide: the points of a part are all within the radius of each
// other). Parts are the union-find nodes; two parts of one label in neighbouring cells are
// joined if some pair of their points passes the reference's float test, decided by their
// bounding boxes where those settle it (every pair within r, or none), else by the pairs.
class Components {
 public:
  Components(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& labels,
             double radius)
      : points_(points) {
    const float rf = static_cast<float>(radius);
    r2_ = rf * rf;
    const double inv_cell = 1.0 / (radius * (1.0 + 1e-5));
    struct Keyed {
      CellKey key;
      int label, part, index;
      Eigen::Vector3f p;
    };
    std::vector<Keyed> keyed;
    for (int i = 0; i < static_cast<int>(points.size()); ++i) {
      if (labels[i] < 0) continue;
      const double f[3] = {static_cast<double>(points[i].x()) * inv_cell,
                           static_cast<double>(points[i].y()) * inv_cell,
                           static_cast<double>(points[i].z()) * inv_cell};
      CellKey key;
      std::int64_t* k[3] = {&key.x, &key.y, &key.z};
      int part = 0;
      for (int a = 0; a < 3; ++a) {
        const double c = std::floor(f[a]);
        *k[a] = static_cast<std::int64_t>(c);
        part = part * 2 + (f[a] - c >= 0.5 ? 1 : 0);
      }
      keyed.push_back({key, labels[i], part, i, points[i]});
    }
    const std::vector<int> sorted = SortKeyed(keyed);
    const std::size_t n = keyed.size();
    xs_.resize(n);
    ys_.resize(n);
    zs_.resize(n);
    part_of_.assign(points.size(), -1);
    std::vector<CellKey> cell_keys;
    for (std::size_t i = 0; i < n; ++i) {
      const Keyed& e = keyed[sorted[i]];
      const Eigen::Vector3f& p = e.p;
      xs_[i] = p.x();
      ys_[i] = p.y();
      zs_[i] = p.z();
      const bool new_cell = i == 0 || !(e.key == keyed[sorted[i - 1]].key);
      const bool new_seg = new_cell || e.label != keyed[sorted[i - 1]].label;
      if (new_cell) {
        cell_keys.push_back(e.key);
        cell_seg_begin_.push_back(static_cast<int>(segs_.size()));
      }
      if (new_seg) segs_.push_back({static_cast<int>(parts_.size()), 0, e.label});
      if (new_seg || e.part != keyed[sorted[i - 1]].part) {
        Part part;
        part.begin = static_cast<int>(i);
        part.lo[0] = part.hi[0] = p.x();
        part.lo[1] = part.hi[1] = p.y();
        part.lo[2] = part.hi[2] = p.z();
        parts_.push_back(part);
      }
      Part& part = parts_.back();
      part.end = static_cast<int>(i) + 1;
      const float v[3] = {p.x(), p.y(), p.z()};
      for (int a = 0; a < 3; ++a) {
        part.lo[a] = std::min(part.lo[a], v[a]);
        part.hi[a] = std::max(part.hi[a], v[a]);
      }
      segs_.back().parts_end = static_cast<int>(parts_.size());
      part_of_[e.index] = static_cast<int>(parts_.size()) - 1;
    }
    cell_seg_begin_.push_back(static_cast<int>(segs_.size()));
    parent_.resize(parts_.size());
    std::iota(parent_.begin(), parent_.end(), 0);
    // Every pair of cells (c, e) with e >= c among each other's 27.
    std::size_t cursor[9] = {};
    for (std::size_t c = 0; c < cell_keys.size(); ++c) {
      ForEachNearCell(cell_keys, c, cursor, [&](std::size_t e) {
        if (e >= c) JoinCells(static_cast<int>(c), static_cast<int>(e));
      });
    }
  }

  // Sorts by cell key, label, part, index: one 64-bit code per point where the cell ranges
  // and labels fit (the usual case; ~3x faster than comparing the fields), else the fields.
  // The order of `keyed` by cell key, label, part, index: one 64-bit code per point where
  // the cell ranges and labels fit (the usual case; ~3x faster than comparing the fields),
  // else the fields.
  template <class Keyed>
  static std::vector<int> SortKeyed(const std::vector<Keyed>& keyed) {
    std::int64_t lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    int max_label = 0;
    for (std::size_t i = 0; i < keyed.size(); ++i) {
      const Keyed& e = keyed[i];
      const std::int64_t v[3] = {e.key.x, e.key.y, e.key.z};
      for (int a = 0; a < 3; ++a) {
        lo[a] = i == 0 ? v[a] : std::min(lo[a], v[a]);
        hi[a] = i == 0 ? v[a] : std::max(hi[a], v[a]);
      }
      max_label = std::max(max_label, e.label);
    }
    bool packable = max_label < (1 << 12);
    for (int a = 0; a < 3; ++a) {
      // hi - lo in unsigned arithmetic: the keys may span the whole int64 range.
      packable = packable && static_cast<std::uint64_t>(hi[a]) - static_cast<std::uint64_t>(lo[a]) <
                                 (std::uint64_t{1} << 16);
    }
    std::vector<int> order(keyed.size());
    if (!packable) {
      std::iota(order.begin(), order.end(), 0);
      std::sort(order.begin(), order.end(), [&](int i, int j) {
        const Keyed& a = keyed[i];
        const Keyed& b = keyed[j];
        if (!(a.key == b.key)) return a.key < b.key;
        if (a.label != b.label) return a.label < b.label;
        if (a.part != b.part) return a.part < b.part;
        return a.index < b.index;
      });
      return order;
    }
    std::vector<std::pair<std::uint64_t, int>> codes(keyed.size());
    for (std::size_t i = 0; i < keyed.size(); ++i) {
      const Keyed& e = keyed[i];
      const auto d = [&](std::int64_t v, int a) {
        return static_cast<std::uint64_t>(v) - static_cast<std::uint64_t>(lo[a]);
      };
      const std::uint64_t code =
          ((((d(e.key.x, 0) << 16 | d(e.key.y, 1)) << 16 | d(e.key.z, 2)) << 12 |
            static_cast<std::uint64_t>(e.label))
           << 3) |
          static_cast<std::uint64_t>(e.part);
      codes[i] = {code, static_cast<int>(i)};
    }
    std::sort(codes.begin(), codes.end());  // ties: the input order (= index order)
    for (std::size_t i = 0; i < codes.size(); ++i) order[i] = codes[i].second;
    return order;
  }

  // False if some part's points may not all be within the radius of each other (float
  // rounding of huge coordinates): the caller then takes another path.
  bool PartsAreCliques() const {
    for (const Part& p : parts_) {
      if (BoxFar2(p, p) >= r2_ * (1.f - 1e-5f)) return false;
    }
    return true;
  }

  // The components with at least min_points points: each in increasing index order, ordered
  // by their smallest index (the seed order of the BFS).
  std::vector<std::vector<int>> Clusters(int min_points) {
    std::vector<int> id(parts_.size(), -1);
    std::vector<std::vector<int>> all;
    for (int i = 0; i < static_cast<int>(points_.size()); ++i) {
      if (part_of_[i] < 0) continue;
      const int root = Find(part_of_[i]);
      if (id[root] < 0) {
        id[root] = static_cast<int>(all.size());
        all.emplace_back();
      }
      all[id[root]].push_back(i);
    }
    std::vector<std::vector<int>> kept;
    for (auto& c : all) {
      if (static_cast<int>(c.size()) >= min_points) kept.push_back(std::move(c));
    }
    return kept;
  }

 private:
  struct Part {
    int begin, end;  // slots
    float lo[3], hi[3];
  };
  struct Seg {
    int parts_begin, parts_end;
    int label;
  };

  int Find(int a) {
    while (parent_[a] != a) {
      parent_[a] = parent_[parent_[a]];
      a = parent_[a];
    }
    return a;
  }

  // Largest / smallest squared distance between points of two boxes.
  static float BoxFar2(const Part& a, const Part& b) {
    float d2 = 0.f;
    for (int k = 0; k < 3; ++k) {
      const float f = std::max(a.hi[k] - b.lo[k], b.hi[k] - a.lo[k]);
      d2 += f * f;
    }
    return d2;
  }
  static float BoxNear2(const Part& a, const Part& b) {
    float d2 = 0.f;
    for (int k = 0; k < 3; ++k) {
      const float e = std::max(std::max(a.lo[k] - b.hi[k], b.lo[k] - a.hi[k]), 0.f);
      d2 += e * e;
    }
    return d2;
  }

  // Joins the parts of equal labels of cells c <= e that are linked.
  void JoinCells(int c, int e) {
    int g = cell_seg_begin_[c], h = cell_seg_begin_[e];
    const int g_end = cell_seg_begin_[c + 1], h_end = cell_seg_begin_[e + 1];
    while (g < g_end && h < h_end) {
      if (segs_[g].label < segs_[h].label) {
        ++g;
      } else if (segs_[h].label < segs_[g].label) {
        ++h;
      } else {
        const Seg& sa = segs_[g];
        const Seg& sb = segs_[h];
        for (int a = sa.parts_begin; a < sa.parts_end; ++a) {
          for (int b = c == e ? a + 1 : sb.parts_begin; b < sb.parts_end; ++b) {
            const int ra = Find(a), rb = Find(b);
            if (ra == rb || !Linked(parts_[a], parts_[b])) continue;
            parent_[std::max(ra, rb)] = std::min(ra, rb);
          }
        }
        ++g;
        ++h;
      }
    }
  }

  // Whether some point of a and some point of b pass the float test (|x_a - x_b|^2 < r^2, the
  // reference's expression); the boxes decide with a 1e-5 relative margin where they can.
  bool Linked(const Part& a, const Part& b) const {
    if (BoxNear2(a, b) >= r2_ * (1.f + 1e-5f)) return false;
    if (BoxFar2(a, b) < r2_ * (1.f - 1e-5f)) return true;
    const Part& small = a.end - a.begin <= b.end - b.begin ? a : b;
    const Part& large = &small == &a ? b : a;
    for (int s = small.begin; s < small.end; ++s) {
      if (AnyWithin(xs_[s], ys_[s], zs_[s], large.begin, large.end)) return true;
    }
    return false;
  }

  bool AnyWithin(float px, float py, float pz, int s0, int s1) const {
    int s = s0;
    if (UseAvx2()) {
      if (AnyWithinAvx2(&xs_[0], &ys_[0], &zs_[0], s0, s1, px, py, pz, r2_, &s)) return true;
    }
    for (; s < s1; ++s) {
      const float ex = px - xs_[s];
      const float ey = py - ys_[s];
      const float ez = pz - zs_[s];
      if (ex * ex + ey * ey + ez * ez < r2_) return true;
    }
    return false;
  }

  const std::vector<Eigen::Vector3f>& points_;
  float r2_ = 0.f;
  std::vector<float> xs_, ys_, zs_;  // labelled points by cell, label, part, index
  std::vector<int> part_of_;         // per point: its part, -1 if unlabelled
  std::vector<Part> parts_;
  std::vector<Seg> segs_;
  std::vector<int> cell_seg_begin_;  // cells + 1
  std::vector<int> parent_;          // union-find over parts
};

void CheckClusterArgs(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& labels,
                      double radius, int min_points, int max_neighbours) {
  if (labels.size() != points.size()) {
    throw InvalidArgument("BfsClusters: labels has " + std::to_string(labels.size()) +
                          " entries for " + std::to_string(points.size()) + " points");
  }
  if (points.size() > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw InvalidArgument("BfsClusters: more than INT_MAX points");
  }
  if (!std::isfinite(radius) || radius <= 0.0) {
    throw InvalidArgument("BfsClusters: radius must be finite and > 0, got " +
                          std::to_string(radius));
  }
  if (min_points < 1) {
    throw InvalidArgument("BfsClusters: min_points must be >= 1, got " +
                          std::to_string(min_points));
  }
  if (max_neighbours < 1) {
    throw InvalidArgument("BfsClusters: max_neighbours must be >= 1, got " +
                          std::to_string(max_neighbours));
  }
  // The voxel hash keys are 64-bit cell coordinates: |coordinate| / radius must stay far
  // below 2^63.
  const double limit = 1e15 * radius;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (labels[i] < 0) continue;
    if (!points[i].allFinite()) {
      throw InvalidArgument("BfsClusters: point " + std::to_string(i) + " is not finite");
    }
    if (points[i].cast<double>().cwiseAbs().maxCoeff() > limit) {
      throw InvalidArgument("BfsClusters: point " + std::to_string(i) +
                            " is more than 1e15 radii from the origin");
    }
  }
}

}  // namespace

const char* ClusteringSimdPath() { return UseAvx2() ? "avx2" : "sse2"; }

bool SetClusteringAvx2(bool enabled) {
  const bool before = g_allow_avx2;
  g_allow_avx2 = enabled;
  return before;
}

void ClusteringConfig::Validate() const {
  if (passes.empty()) throw InvalidArgument("ClusteringConfig.passes: must not be empty");
  for (std::size_t i = 0; i < passes.size(); ++i) {
    if (!std::isfinite(passes[i].radius) || passes[i].radius <= 0.0) {
      throw InvalidArgument("ClusteringConfig.passes[" + std::to_string(i) +
                            "].radius: must be finite and > 0 (metres), got " +
                            std::to_string(passes[i].radius));
    }
  }
  if (min_points < 1) {
    throw InvalidArgument("ClusteringConfig.min_points: must be >= 1, got " +
                          std::to_string(min_points));
  }
  if (max_neighbours < 1) {
    throw InvalidArgument("ClusteringConfig.max_neighbours: must be >= 1, got " +
                          std::to_string(max_neighbours));
  }
}

ClusteringConfig ClusteringConfig::Training() {
  ClusteringConfig config;
  config.passes = {{false, 0.03}, {true, 0.03}};
  return config;
}

std::vector<std::vector<int>> BfsClusters(const std::vector<Eigen::Vector3f>& points,
                                          const std::vector<int>& labels, double radius,
                                          int min_points, int max_neighbours) {
  CheckClusterArgs(points, labels, radius, min_points, max_neighbours);
  BallQuery query(points, labels, radius, max_neighbours);
  std::vector<std::vector<int>> clusters;
  std::vector<int> cluster;
  std::vector<int> fresh;
  for (int seed = 0; seed < static_cast<int>(points.size()); ++seed) {
    if (labels[seed] < 0 || query.visited(seed)) continue;
    query.MarkVisited(seed);
    cluster.clear();
    cluster.push_back(seed);
    // `cluster` doubles as the FIFO queue: pop order == push order.
    for (std::size_t head = 0; head < cluster.size(); ++head) {
      const int j = cluster[head];
      query.Query(j, points[j], labels[j], &fresh);
      for (int k : fresh) {
        query.MarkVisited(k);
        cluster.push_back(k);
      }
    }
    if (static_cast<int>(cluster.size()) >= min_points) clusters.push_back(cluster);
  }
  return clusters;
}

std::vector<std::vector<int>> RadiusComponents(const std::vector<Eigen::Vector3f>& points,
                                               const std::vector<int>& labels, double radius,
                                               int min_points) {
  CheckClusterArgs(points, labels, radius, min_points, 1);
  Components components(points, labels, radius);
  if (!components.PartsAreCliques()) {
    // Coordinates so large that float rounding blurs the half-cell parts: the BFS without a
    // cap gives the same components.
    auto clusters =
        BfsClusters(points, labels, radius, min_points, std::numeric_limits<int>::max());
    for (auto& c : clusters) std::sort(c.begin(), c.end());
    return clusters;
  }
  return components.Clusters(min_points);
}

std::vector<Proposal> MultiScaleClusters(const std::vector<Eigen::Vector3f>& points,
                                         const std::vector<Eigen::Vector3f>& offsets,
                                         const std::vector<int>& labels,
                                         const ClusteringConfig& config) {
  config.Validate();
  const bool any_shifted = std::any_of(config.passes.begin(), config.passes.end(),
                                       [](const ClusterPass& p) { return p.shifted; });
  if (any_shifted && offsets.size() != points.size()) {
    throw InvalidArgument("MultiScaleClusters: offsets has " + std::to_string(offsets.size()) +
                          " entries for " + std::to_string(points.size()) + " points");
  }
  std::vector<Eigen::Vector3f> shifted;
  if (any_shifted) {
    shifted.resize(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) shifted[i] = points[i] + offsets[i];
  }
  std::vector<Proposal> proposals;
  for (std::size_t p = 0; p < config.passes.size(); ++p) {
    const ClusterPass& pass = config.passes[p];
    const std::vector<Eigen::Vector3f>& where = pass.shifted ? shifted : points;
    auto clusters =
        config.neighbour_cap
            ? BfsClusters(where, labels, pass.radius, config.min_points, config.max_neighbours)
            : RadiusComponents(where, labels, pass.radius, config.min_points);
    for (auto& c : clusters) {
      Proposal proposal;
      proposal.label = labels[c.front()];
      proposal.points = std::move(c);
      proposal.pass = static_cast<int>(p);
      proposals.push_back(std::move(proposal));
    }
  }
  return proposals;
}

double PointIou(const std::vector<int>& a, const std::vector<int>& b) {
  std::vector<int> sa(a), sb(b);
  std::sort(sa.begin(), sa.end());
  std::sort(sb.begin(), sb.end());
  std::vector<int> common;
  std::set_intersection(sa.begin(), sa.end(), sb.begin(), sb.end(), std::back_inserter(common));
  const double inter = static_cast<double>(common.size());
  const double uni = static_cast<double>(a.size() + b.size()) - inter;
  return uni > 0.0 ? inter / uni : 0.0;
}

std::vector<int> PointIouNms(const std::vector<Proposal>& proposals, double iou_threshold) {
  if (std::isnan(iou_threshold)) throw InvalidArgument("PointIouNms: iou_threshold is NaN");
  const int n = static_cast<int>(proposals.size());
  int max_point = -1;
  std::size_t incidences = 0;
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(proposals[i].score)) {
      throw InvalidArgument("PointIouNms: proposal " + std::to_string(i) +
                            " has a non-finite score");
    }
    for (int p : proposals[i].points) {
      if (p < 0) {
        throw InvalidArgument("PointIouNms: proposal " + std::to_string(i) +
                              " has a negative point index");
      }
      max_point = std::max(max_point, p);
    }
    incidences += proposals[i].points.size();
  }
  // Inverted index (CSR): for every point, the proposals that contain it.
  const std::size_t num_points = static_cast<std::size_t>(max_point + 1);
  std::vector<std::size_t> start(num_points + 1, 0);
  std::vector<int> stamp(num_points, -1);
  for (int i = 0; i < n; ++i) {
    for (int p : proposals[i].points) {
      if (stamp[p] == i) {
        throw InvalidArgument("PointIouNms: proposal " + std::to_string(i) + " lists point " +
                              std::to_string(p) + " twice");
      }
      stamp[p] = i;
      ++start[p + 1];
    }
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<int> members(incidences);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (int i = 0; i < n; ++i) {
      for (int p : proposals[i].points) members[fill[p]++] = i;
    }
  }

  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return proposals[a].score > proposals[b].score; });
  std::vector<char> done(n, 0);  // kept or suppressed
  std::vector<int> inter(n, 0);
  std::vector<int> touched;
  std::vector<int> kept;
  for (int i : order) {
    if (done[i]) continue;
    done[i] = 1;
    kept.push_back(i);
    touched.clear();
    for (int p : proposals[i].points) {
      for (std::size_t s = start[p]; s < start[p + 1]; ++s) {
        const int q = members[s];
        if (done[q]) continue;
        if (inter[q]++ == 0) touched.push_back(q);
      }
    }
    const double size_i = static_cast<double>(proposals[i].points.size());
    for (int q : touched) {
      const double in = inter[q];
      const double iou = in / (size_i + static_cast<double>(proposals[q].points.size()) - in);
      if (iou > iou_threshold) done[q] = 1;
      inter[q] = 0;
    }
  }
  return kept;
}

double ProposalHeading(const std::vector<int>& points, const std::vector<float>& heading_prob,
                       const std::vector<float>& heading_residual,
                       const std::vector<std::int64_t>& point_row) {
  if (points.empty()) throw InvalidArgument("ProposalHeading: the proposal has no points");
  if (heading_prob.size() % kHeadingBins != 0) {
    throw InvalidArgument("ProposalHeading: heading_prob size " +
                          std::to_string(heading_prob.size()) + " is not a multiple of 12");
  }
  if (heading_residual.size() != heading_prob.size()) {
    throw InvalidArgument("ProposalHeading: heading_residual has " +
                          std::to_string(heading_residual.size()) + " values, heading_prob " +
                          std::to_string(heading_prob.size()));
  }
  const std::size_t rows = heading_prob.size() / kHeadingBins;
  const std::size_t n = point_row.empty() ? rows : point_row.size();
  // The row of each point (checked once; the residual loop reads the same rows).
  std::vector<std::size_t> row_of(points.size());
  double mean[kHeadingBins] = {};
  for (std::size_t j = 0; j < points.size(); ++j) {
    const int p = points[j];
    if (p < 0 || static_cast<std::size_t>(p) >= n) {
      throw InvalidArgument("ProposalHeading: point index " + std::to_string(p) +
                            " out of range [0, " + std::to_string(n) + ")");
    }
    const std::int64_t r = point_row.empty() ? p : point_row[static_cast<std::size_t>(p)];
    if (r < 0 || static_cast<std::size_t>(r) >= rows) {
      throw InvalidArgument("ProposalHeading: point " + std::to_string(p) + " has row " +
                            std::to_string(r) + ", not in [0, " + std::to_string(rows) + ")");
    }
    row_of[j] = static_cast<std::size_t>(r);
    const float* row = heading_prob.data() + row_of[j] * kHeadingBins;
    for (int b = 0; b < kHeadingBins; ++b) mean[b] += row[b];
  }
  const int k = static_cast<int>(std::max_element(mean, mean + kHeadingBins) - mean);
  double residual = 0.0;
  for (std::size_t r : row_of) residual += heading_residual[r * kHeadingBins + k];
  residual /= static_cast<double>(points.size());
  return DecodeHeading(k, residual);
}

}  // namespace dimr::pipeline
