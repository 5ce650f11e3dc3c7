#include "dimr/pipeline/clustering.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>

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

struct CellKeyHash {
  std::size_t operator()(const CellKey& k) const {
    // splitmix64 finaliser over a combination of the three coordinates.
    std::uint64_t h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<std::uint64_t>(k.y) + 0xBF58476D1CE4E5B9ull + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(k.z) + 0x94D049BB133111EBull + (h << 6) + (h >> 2);
    h ^= h >> 30;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 27;
    h *= 0x94D049BB133111EBull;
    h ^= h >> 31;
    return static_cast<std::size_t>(h);
  }
};

// Ball query over a uniform voxel hash of the labelled points, with the BFS's visited flags.
// The cell is a hair larger than the radius so that every pair with d < r (even after float
// rounding of d^2) lies in adjacent cells. Inside a cell the points are kept in index order,
// which lets a query stop early when the neighbour cap makes every unvisited point
// unreachable.
class BallQuery {
 public:
  BallQuery(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& labels,
            double radius, int cap)
      : cap_(static_cast<std::size_t>(cap)), visited_(points.size(), 0) {
    const float rf = static_cast<float>(radius);
    r2_ = rf * rf;  // as the reference kernel: float radius, float radius^2
    inv_cell_ = 1.0 / (radius * (1.0 + 1e-5));
    std::vector<std::pair<CellKey, int>> keyed;
    for (int i = 0; i < static_cast<int>(points.size()); ++i) {
      if (labels[i] >= 0) keyed.emplace_back(Key(points[i]), i);
    }
    // Cell-major, index order inside a cell (the input is in index order: stable sort).
    std::stable_sort(keyed.begin(), keyed.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    const std::size_t n = keyed.size();
    order_.resize(n);
    xs_.resize(n);
    ys_.resize(n);
    zs_.resize(n);
    cell_of_.assign(points.size(), -1);
    index_.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      const int k = keyed[i].second;
      order_[i] = k;
      xs_[i] = points[k].x();
      ys_[i] = points[k].y();
      zs_[i] = points[k].z();
      if (i == 0 || !(keyed[i].first == keyed[i - 1].first)) {
        index_.emplace(keyed[i].first, static_cast<int>(cells_.size()));
        const int begin = static_cast<int>(i);
        cells_.push_back({begin, begin, 0, begin});
      }
      cells_.back().end = static_cast<int>(i) + 1;
      ++cells_.back().unvisited;
      cell_of_[k] = static_cast<int>(cells_.size()) - 1;
    }
    // The occupied cells among each cell's 27 (itself included), looked up once per cell
    // instead of 27 hash probes per query (a query point is always a labelled point, whose cell
    // is known).
    near_begin_.reserve(cells_.size() + 1);
    near_begin_.push_back(0);
    std::size_t first = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (i + 1 < n && keyed[i + 1].first == keyed[i].first) continue;
      const CellKey c = keyed[first].first;
      first = i + 1;
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            const auto it = index_.find({c.x + dx, c.y + dy, c.z + dz});
            if (it != index_.end()) near_.push_back(it->second);
          }
        }
      }
      near_begin_.push_back(static_cast<int>(near_.size()));
    }
  }

  bool visited(int k) const { return visited_[k] != 0; }
  void MarkVisited(int k) {
    visited_[k] = 1;
    --cells_[cell_of_[k]].unvisited;
  }

  // The neighbours of labelled point j (at p) that may still matter to the BFS: all labelled k with
  // |x_j - x_k|^2 < r^2 (float), in arbitrary order, not yet truncated to the cap. Returns
  // false (without the full scan) if no unvisited point can be among j's first `cap`
  // neighbours in index order: every point of the 27 cells is visited, or `cap` neighbours
  // have a smaller index than the smallest unvisited one.
  bool Query(int j, const Eigen::Vector3f& p, std::vector<int>* hits) {
    hits->clear();
    const int cj = cell_of_[j];
    const int* near = near_.data() + near_begin_[cj];
    const int num_near = near_begin_[cj + 1] - near_begin_[cj];
    int unvisited = 0;
    for (int n = 0; n < num_near; ++n) unvisited += cells_[near[n]].unvisited;
    if (unvisited == 0) return false;
    // Smallest unvisited index around j (each cell's first-unvisited slot only moves forward).
    int min_unvisited = std::numeric_limits<int>::max();
    std::size_t total = 0;
    for (int n = 0; n < num_near; ++n) {
      Cell& cell = cells_[near[n]];
      while (cell.first_unvisited < cell.end && visited_[order_[cell.first_unvisited]]) {
        ++cell.first_unvisited;
      }
      if (cell.first_unvisited < cell.end) {
        min_unvisited = std::min(min_unvisited, order_[cell.first_unvisited]);
      }
      total += cell.end - cell.begin;
    }
    hits->resize(total);
    int* out = hits->data();
    const float px = p.x(), py = p.y(), pz = p.z();
    std::size_t count = 0;
    // Phase 1: the points below min_unvisited (a prefix of every cell). If they alone fill
    // the cap, no unvisited point is a neighbour of j (stop as soon as it is reached).
    int split[27];
    for (int n = 0; n < num_near; ++n) {
      const Cell& cell = cells_[near[n]];
      // Indices ascend inside a cell: the prefix below min_unvisited by binary search.
      const int s = static_cast<int>(
          std::lower_bound(order_.begin() + cell.begin, order_.begin() + cell.end, min_unvisited) -
          order_.begin());
      split[n] = s;
      count = Hits(px, py, pz, cell.begin, s, out, count, cap_);
      if (count >= cap_) return false;
    }
    // Phase 2: the rest.
    for (int n = 0; n < num_near; ++n) {
      count = Hits(px, py, pz, split[n], cells_[near[n]].end, out, count, kNoStop);
    }
    hits->resize(count);
    return true;
  }

 private:
  struct Cell {
    int begin, end;       // range in order_
    int unvisited;        // labelled points of the cell not yet visited by the BFS
    int first_unvisited;  // slots before it are all visited
  };

  // Writes the index of slot s to *out and returns 1 if it is within the radius (branch-free
  // compaction; the caller advances only on a hit). Same float expression as the reference.
  std::size_t Hit(float px, float py, float pz, int s, int* out) const {
    const float ex = px - xs_[s];
    const float ey = py - ys_[s];
    const float ez = pz - zs_[s];
    const float d2 = ex * ex + ey * ey + ez * ez;
    *out = order_[s];
    return d2 < r2_ ? 1 : 0;
  }

  static constexpr std::size_t kNoStop = std::numeric_limits<std::size_t>::max();

  // Hit over the slots [s0, s1): appends the indices within the radius to out + count in slot
  // order and returns the new count, stopping early once it reaches `stop`. Four slots at a
  // time with SSE2 (the same float operations in the same order as Hit, so the same hits).
  std::size_t Hits(float px, float py, float pz, int s0, int s1, int* out, std::size_t count,
                   std::size_t stop) const {
    const __m128 qx = _mm_set1_ps(px), qy = _mm_set1_ps(py), qz = _mm_set1_ps(pz);
    const __m128 r2 = _mm_set1_ps(r2_);
    int s = s0;
    for (; s + 4 <= s1; s += 4) {
      const __m128 ex = _mm_sub_ps(qx, _mm_loadu_ps(&xs_[s]));
      const __m128 ey = _mm_sub_ps(qy, _mm_loadu_ps(&ys_[s]));
      const __m128 ez = _mm_sub_ps(qz, _mm_loadu_ps(&zs_[s]));
      const __m128 d2 =
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(ex, ex), _mm_mul_ps(ey, ey)), _mm_mul_ps(ez, ez));
      const unsigned m = static_cast<unsigned>(_mm_movemask_ps(_mm_cmplt_ps(d2, r2)));
      // Branch-free compaction (hits are dense in the shifted passes: a bit loop mispredicts).
      for (int b = 0; b < 4; ++b) {
        out[count] = order_[s + b];
        count += (m >> b) & 1u;
      }
      if (count >= stop) return count;
    }
    for (; s < s1; ++s) count += Hit(px, py, pz, s, out + count);
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
  std::vector<float> xs_, ys_, zs_;  // coordinates in order_ order
  std::vector<int> order_;           // labelled point indices, cell-major, index order in a cell
  std::vector<int> cell_of_;         // per point: its cell, -1 if unlabelled
  std::vector<Cell> cells_;
  std::unordered_map<CellKey, int, CellKeyHash> index_;
  std::vector<int> near_;        // per cell: its occupied neighbour cells (CSR)
  std::vector<int> near_begin_;  // cells_.size() + 1
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
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (labels[i] >= 0 && !points[i].allFinite()) {
      throw InvalidArgument("BfsClusters: point " + std::to_string(i) + " is not finite");
    }
  }
}

}  // namespace

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
  const std::size_t cap = static_cast<std::size_t>(max_neighbours);
  std::vector<std::vector<int>> clusters;
  std::vector<int> cluster;
  std::vector<int> hits;
  std::vector<int> fresh;
  for (int seed = 0; seed < static_cast<int>(points.size()); ++seed) {
    if (labels[seed] < 0 || query.visited(seed)) continue;
    query.MarkVisited(seed);
    cluster.clear();
    cluster.push_back(seed);
    // `cluster` doubles as the FIFO queue: pop order == push order.
    for (std::size_t head = 0; head < cluster.size(); ++head) {
      const int j = cluster[head];
      if (!query.Query(j, points[j], &hits)) continue;
      fresh.clear();
      int min_fresh = std::numeric_limits<int>::max();
      for (int k : hits) {
        if (!query.visited(k) && labels[k] == labels[j]) {
          fresh.push_back(k);
          min_fresh = std::min(min_fresh, k);
        }
      }
      if (fresh.empty()) continue;
      if (hits.size() > cap) {
        // The reference scans in index order and stops at the cap-th hit: a fresh k is a
        // neighbour iff k <= the cap-th smallest hit index. Cheap exit first: if cap hits
        // precede the smallest fresh index, none is.
        std::size_t before = 0;
        for (int k : hits) before += k < min_fresh ? 1 : 0;
        if (before >= cap) continue;
        std::nth_element(hits.begin(), hits.begin() + (cap - 1), hits.end());
        const int last = hits[cap - 1];
        fresh.erase(std::remove_if(fresh.begin(), fresh.end(), [last](int k) { return k > last; }),
                    fresh.end());
      }
      std::sort(fresh.begin(), fresh.end());
      for (int k : fresh) {
        query.MarkVisited(k);
        cluster.push_back(k);
      }
    }
    if (static_cast<int>(cluster.size()) >= min_points) clusters.push_back(cluster);
  }
  return clusters;
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
    auto clusters = BfsClusters(pass.shifted ? shifted : points, labels, pass.radius,
                                config.min_points, config.max_neighbours);
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
                       const std::vector<float>& heading_residual) {
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
  const std::size_t n = heading_prob.size() / kHeadingBins;
  double mean[kHeadingBins] = {};
  for (int p : points) {
    if (p < 0 || static_cast<std::size_t>(p) >= n) {
      throw InvalidArgument("ProposalHeading: point index " + std::to_string(p) +
                            " out of range [0, " + std::to_string(n) + ")");
    }
    const float* row = heading_prob.data() + static_cast<std::size_t>(p) * kHeadingBins;
    for (int b = 0; b < kHeadingBins; ++b) mean[b] += row[b];
  }
  const int k = static_cast<int>(std::max_element(mean, mean + kHeadingBins) - mean);
  double residual = 0.0;
  for (int p : points) {
    residual += heading_residual[static_cast<std::size_t>(p) * kHeadingBins + k];
  }
  residual /= static_cast<double>(points.size());
  return DecodeHeading(k, residual);
}

}  // namespace dimr::pipeline
