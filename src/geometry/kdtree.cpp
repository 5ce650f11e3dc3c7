#include "dimr/geometry/kdtree.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <queue>
#include <string>

#include "dimr/core/parallel.h"
#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Depth of a median-split tree over < 2^31 points is < 32; every descent pushes at most one
// far child per level.
constexpr int kMaxStack = 96;

struct StackEntry {
  int node;
  double bound;  // lower bound of the squared distance from the query to the node's points
};

}  // namespace

KdTree::KdTree(std::vector<Vec3> points, int leaf_size) : points_(std::move(points)) {
  if (leaf_size < 1) {
    throw InvalidArgument("KdTree: leaf_size must be >= 1, got " + std::to_string(leaf_size));
  }
  if (points_.size() > static_cast<std::size_t>(INT_MAX)) {
    throw InvalidArgument("KdTree: too many points (" + std::to_string(points_.size()) + ")");
  }
  for (std::size_t i = 0; i < points_.size(); ++i) {
    if (!points_[i].allFinite()) {
      throw InvalidArgument("KdTree: point " + std::to_string(i) + " is not finite");
    }
  }
  if (points_.empty()) return;
  const int n = static_cast<int>(points_.size());
  perm_.resize(n);
  for (int i = 0; i < n; ++i) perm_[i] = i;
  nodes_.reserve(2 * (n / leaf_size + 1));
  Build(0, n, leaf_size);
  sorted_.resize(n);
  for (int i = 0; i < n; ++i) sorted_[i] = points_[perm_[i]];
}

int KdTree::Build(int begin, int end, int leaf_size) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{begin, end, -1, -1, 0, 0.0});
  if (end - begin <= leaf_size) return id;
  AABB box;
  for (int i = begin; i < end; ++i) box.Extend(points_[perm_[i]]);
  const Vec3 extent = box.max - box.min;
  int axis = 0;
  if (extent.y() > extent[axis]) axis = 1;
  if (extent.z() > extent[axis]) axis = 2;
  if (!(extent[axis] > 0.0)) return id;  // all points identical: keep as one (large) leaf
  const int mid = begin + (end - begin) / 2;
  std::nth_element(perm_.begin() + begin, perm_.begin() + mid, perm_.begin() + end,
                   [&](int a, int b) { return points_[a][axis] < points_[b][axis]; });
  // Invariant: points in [begin, mid) have coordinate <= split, those in [mid, end) >= split.
  const double split = points_[perm_[mid]][axis];
  const int left = Build(begin, mid, leaf_size);
  const int right = Build(mid, end, leaf_size);
  Node& node = nodes_[id];
  node.left = left;
  node.right = right;
  node.axis = axis;
  node.split = split;
  return id;
}

std::pair<int, double> KdTree::Nearest(const Vec3& q) const {
  int best_i = -1;
  double best_d = kInf;
  if (nodes_.empty()) return {best_i, best_d};
  StackEntry stack[kMaxStack];
  int top = 0;
  stack[top++] = {0, 0.0};
  while (top > 0) {
    const StackEntry e = stack[--top];
    if (e.bound > best_d) continue;
    int node = e.node;
    const double bound = e.bound;
    while (nodes_[node].left >= 0) {
      const Node& nd = nodes_[node];
      const double diff = q[nd.axis] - nd.split;
      const int near_child = diff < 0 ? nd.left : nd.right;
      const int far_child = diff < 0 ? nd.right : nd.left;
      const double far_bound = std::max(bound, diff * diff);
      if (far_bound <= best_d) stack[top++] = {far_child, far_bound};
      node = near_child;
    }
    const Node& leaf = nodes_[node];
    for (int i = leaf.begin; i < leaf.end; ++i) {
      const double d = (sorted_[i] - q).squaredNorm();
      if (d < best_d || (d == best_d && perm_[i] < best_i)) {
        best_d = d;
        best_i = perm_[i];
      }
    }
  }
  return {best_i, best_d};
}

std::vector<std::pair<int, double>> KdTree::KNearest(const Vec3& q, int k) const {
  std::vector<std::pair<int, double>> out;
  if (k <= 0 || nodes_.empty()) return out;
  const std::size_t kk = std::min<std::size_t>(static_cast<std::size_t>(k), points_.size());
  // Max-heap on (distance, index): the top is the current k-th best.
  using Item = std::pair<double, int>;
  std::vector<Item> heap;
  heap.reserve(kk + 1);
  auto worst = [&]() { return heap.size() < kk ? kInf : heap.front().first; };
  StackEntry stack[kMaxStack];
  int top = 0;
  stack[top++] = {0, 0.0};
  while (top > 0) {
    const StackEntry e = stack[--top];
    if (e.bound > worst()) continue;
    int node = e.node;
    const double bound = e.bound;
    while (nodes_[node].left >= 0) {
      const Node& nd = nodes_[node];
      const double diff = q[nd.axis] - nd.split;
      const int near_child = diff < 0 ? nd.left : nd.right;
      const int far_child = diff < 0 ? nd.right : nd.left;
      const double far_bound = std::max(bound, diff * diff);
      if (far_bound <= worst()) stack[top++] = {far_child, far_bound};
      node = near_child;
    }
    const Node& leaf = nodes_[node];
    for (int i = leaf.begin; i < leaf.end; ++i) {
      const Item item{(sorted_[i] - q).squaredNorm(), perm_[i]};
      if (heap.size() < kk) {
        heap.push_back(item);
        std::push_heap(heap.begin(), heap.end());
      } else if (item < heap.front()) {
        std::pop_heap(heap.begin(), heap.end());
        heap.back() = item;
        std::push_heap(heap.begin(), heap.end());
      }
    }
  }
  std::sort_heap(heap.begin(), heap.end());
  out.reserve(heap.size());
  for (const Item& it : heap) out.emplace_back(it.second, it.first);
  return out;
}

std::vector<int> KdTree::RadiusSearch(const Vec3& q, double r) const {
  std::vector<int> out;
  if (nodes_.empty() || !(r > 0.0)) return out;
  const double r2 = r * r;
  StackEntry stack[kMaxStack];
  int top = 0;
  stack[top++] = {0, 0.0};
  while (top > 0) {
    const StackEntry e = stack[--top];
    if (e.bound >= r2) continue;
    int node = e.node;
    const double bound = e.bound;
    while (nodes_[node].left >= 0) {
      const Node& nd = nodes_[node];
      const double diff = q[nd.axis] - nd.split;
      const int near_child = diff < 0 ? nd.left : nd.right;
      const int far_child = diff < 0 ? nd.right : nd.left;
      const double far_bound = std::max(bound, diff * diff);
      if (far_bound < r2) stack[top++] = {far_child, far_bound};
      node = near_child;
    }
    const Node& leaf = nodes_[node];
    for (int i = leaf.begin; i < leaf.end; ++i) {
      if ((sorted_[i] - q).squaredNorm() < r2) out.push_back(perm_[i]);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<double> NearestDistances(const std::vector<Vec3>& queries, const KdTree& target) {
  std::vector<double> out(queries.size(), kInf);
  if (target.empty() || queries.empty()) return out;
  auto work = [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) out[i] = std::sqrt(target.Nearest(queries[i]).second);
  };
  constexpr std::size_t kMinChunk = 2048;
  ParallelRanges(queries.size(), 0, kMinChunk, work);
  return out;
}

NeighbourhoodPca PcaOfNeighbours(const std::vector<Vec3>& points,
                                 const std::vector<std::pair<int, double>>& neighbours) {
  NeighbourhoodPca out;
  if (neighbours.empty()) return out;
  Vec3 mean = Vec3::Zero();
  for (const auto& [j, d2] : neighbours) mean += points[static_cast<std::size_t>(j)];
  mean /= static_cast<double>(neighbours.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& [j, d2] : neighbours) {
    const Vec3 e = points[static_cast<std::size_t>(j)] - mean;
    cov += e * e.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  out.eigenvalues = eig.eigenvalues();
  out.normal = eig.eigenvectors().col(0);
  out.ok = neighbours.size() >= 3 && eig.info() == Eigen::Success && out.normal.allFinite();
  return out;
}

}  // namespace dimr::geometry
