// Static 3-D kd-tree over a point set for exact nearest / k-nearest / radius queries.
//
// Why a hand-written tree rather than PCL/FLANN/nanoflann: the geometry layer depends on
// Eigen only (it is linked by every other layer, the trainer host included); the queries
// here are exact (no approximate-search epsilon, deterministic tie-breaking by index, radius
// results in index order as the DIMR clustering expects); and a 3-D median-split tree over
// contiguous, leaf-ordered points is as fast as the general-purpose libraries for the
// sizes we handle (10^4..10^6 points).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

class KdTree {
 public:
  KdTree() = default;
  // Builds the tree in O(n log n) (median splits on the axis of largest spread, found with
  // std::nth_element). Throws dimr::InvalidArgument if leaf_size < 1, a point is not
  // finite, or there are more than INT_MAX points.
  explicit KdTree(std::vector<Vec3> points, int leaf_size = 16);

  std::size_t size() const { return points_.size(); }
  bool empty() const { return points_.empty(); }
  // The points in their original order (indices returned by the queries refer to it).
  const std::vector<Vec3>& points() const { return points_; }

  // Index of the nearest point and its squared distance; (-1, inf) if empty. Among points
  // at exactly the same distance the smallest index wins.
  std::pair<int, double> Nearest(const Vec3& q) const;
  // min(k, size()) nearest points, sorted by increasing squared distance (ties: increasing
  // index): (index, squared distance). Empty if k <= 0.
  std::vector<std::pair<int, double>> KNearest(const Vec3& q, int k) const;
  // All points with squared distance < r*r (strict), in increasing index order. Empty if
  // r <= 0 or r is NaN.
  std::vector<int> RadiusSearch(const Vec3& q, double r) const;

 private:
  struct Node {
    int begin, end;   // range in perm_ / sorted_
    int left, right;  // children, -1 for leaves
    int axis;
    double split;
  };
  std::vector<Vec3> points_;
  std::vector<int> perm_;     // perm_[i]: original index of the i-th point in tree order
  std::vector<Vec3> sorted_;  // points_ in tree order (contiguous leaves)
  std::vector<Node> nodes_;
  int Build(int begin, int end, int leaf_size);
};

// For each query, the Euclidean (not squared) distance to the nearest point of `target`
// (+inf if the target is empty). Parallel over chunks of queries (dimr::ParallelRanges).
std::vector<double> NearestDistances(const std::vector<Vec3>& queries, const KdTree& target);

// Principal components of a neighbourhood (points[i] for every index of `neighbours`, e.g.
// KdTree::KNearest's answer): eigenvalues of its covariance in ascending order and the unit
// eigenvector of the smallest (a surface normal, up to sign). `ok` is false for fewer than 3
// points or a failed solve (the fields are then what the solver gave, or zero).
struct NeighbourhoodPca {
  Vec3 eigenvalues = Vec3::Zero();
  Vec3 normal = Vec3::Zero();
  bool ok = false;
};
NeighbourhoodPca PcaOfNeighbours(const std::vector<Vec3>& points,
                                 const std::vector<std::pair<int, double>>& neighbours);

}  // namespace dimr::geometry
