// Convex polytope from a set of half-spaces {x : n_i . x + d_i <= 0}: exact vertices and
// faces, robust to redundant, duplicate and near-parallel planes; an empty or degenerate
// (zero-volume) intersection yields an empty polytope. Unbounded intersections are clipped
// to a bounding box given by the caller.
#pragma once

#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

// a*x + b*y + c*z + d <= 0 is inside.
struct HalfSpace {
  Vec3 normal;
  double offset = 0.0;
};

struct Polytope {
  std::vector<Vec3> vertices;
  // Each face: vertex indices in counter-clockwise order seen from outside, and the index of
  // the input half-space it lies on (-1 for the bounding box).
  std::vector<std::vector<int>> faces;
  std::vector<int> face_plane;

  bool empty() const { return faces.empty(); }
  double Volume() const;
  // Fan-triangulated, outward-oriented, closed (watertight) mesh.
  TriangleMesh ToMesh() const;
};

struct PolytopeOptions {
  AABB bounds;        // clipping box (required if the half-spaces may be unbounded); default [-1,1]^3
  double eps = 1e-9;  // relative tolerance for on-plane classification
  PolytopeOptions() {
    bounds.min = Vec3::Constant(-1.0);
    bounds.max = Vec3::Constant(1.0);
  }
};

Polytope IntersectHalfSpaces(const std::vector<HalfSpace>& planes,
                             const PolytopeOptions& options = PolytopeOptions());

}  // namespace dimr::geometry
