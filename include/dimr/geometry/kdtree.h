// Static 3-D kd-tree over a point set for exact nearest / k-nearest / radius queries.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

class KdTree {
 public:
  KdTree() = default;
  explicit KdTree(std::vector<Vec3> points, int leaf_size = 16);

  std::size_t size() const { return points_.size(); }
  const std::vector<Vec3>& points() const { return points_; }

  // Index of the nearest point and its squared distance; (-1, inf) if empty.
  std::pair<int, double> Nearest(const Vec3& q) const;
  // k nearest (sorted by increasing distance): (index, squared distance).
  std::vector<std::pair<int, double>> KNearest(const Vec3& q, int k) const;
  // All points with squared distance < r*r (strict), in increasing index order.
  std::vector<int> RadiusSearch(const Vec3& q, double r) const;

 private:
  struct Node {
    int begin, end;   // range in perm_
    int left, right;  // children, -1 for leaves
    int axis;
    double split;
  };
  std::vector<Vec3> points_;
  std::vector<int> perm_;
  std::vector<Node> nodes_;
  int Build(int begin, int end, int leaf_size);
};

// For each query, the Euclidean (not squared) distance to the nearest point of `target`.
std::vector<double> NearestDistances(const std::vector<Vec3>& queries, const KdTree& target);

}  // namespace dimr::geometry
