// Exact unsigned point-to-triangle-mesh distance, accelerated by a bounding-volume hierarchy.
#pragma once

#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

struct ClosestPoint {
  Vec3 point;            // closest point on the surface
  double distance = 0;   // Euclidean distance
  int face = -1;         // face it lies on (-1 if the mesh has no faces)
};

// Closest point on triangle (a, b, c) to p (exact, handles vertex/edge/face regions and
// degenerate triangles).
Vec3 ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

class MeshDistance {
 public:
  explicit MeshDistance(const TriangleMesh& mesh);
  ClosestPoint Query(const Vec3& p) const;
  // Distances of many points (parallel over points).
  std::vector<double> Distances(const std::vector<Vec3>& points) const;
  bool empty() const { return tris_.empty(); }

 private:
  struct Tri {
    Vec3 a, b, c;
    int face;
  };
  struct Node {
    AABB box;
    int left = -1, right = -1;  // children; leaves have left == -1
    int begin = 0, end = 0;     // triangle range for leaves
  };
  std::vector<Tri> tris_;
  std::vector<Node> nodes_;
  int Build(int begin, int end);
};

}  // namespace dimr::geometry
