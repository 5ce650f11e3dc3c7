// Convex polytope from a set of half-spaces {x : n_i . x + d_i <= 0}: exact vertices and
// faces, robust to redundant, duplicate and near-parallel planes; an empty or degenerate
// (zero-volume) intersection yields an empty polytope. Unbounded intersections are clipped
// to a bounding box given by the caller.
//
// Why not CGAL / qhull (halfspace intersection through the dual hull): the geometry layer
// must stay light (Eigen only); this is the hot path of the BSP mesh decoder (hundreds of
// convexes per object, each from up to ~50 effective planes), where successive clipping of
// a box polyhedron takes a few microseconds per convex without the setup cost of a general
// hull library; and the result keeps, for each face, the index of the plane that produced
// it, with a consistent watertight topology by construction (no angular sorting of
// near-coincident vertices), which a dual-hull approach does not give for free.
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
  // Enclosed volume (divergence theorem over the fan-triangulated faces); 0 if empty.
  double Volume() const;
  // Fan-triangulated, outward-oriented, closed (watertight) mesh.
  TriangleMesh ToMesh() const;
};

struct PolytopeOptions {
  AABB bounds;  // clipping box (required if the half-spaces may be unbounded); default [-1,1]^3
  double eps = 1e-9;  // relative tolerance for on-plane classification
  PolytopeOptions() {
    bounds.min = Vec3::Constant(-1.0);
    bounds.max = Vec3::Constant(1.0);
  }
};

// The polytope {x in options.bounds : n_i . x + d_i <= 0 for all i}, built by clipping the
// bounds box successively by each plane. Planes are normalised internally, so n need not be
// unit length. Vertices closer than options.eps * scale (scale = the largest absolute
// coordinate of the bounds, 1 for the default box) to a plane count as lying on it: a plane
// that cuts off
// nothing beyond that tolerance (redundant, duplicate or near-parallel) adds no face, and a
// plane that leaves nothing strictly inside empties the result. A plane with n == 0 keeps
// everything if d <= 0 and nothing if d > 0. An input plane that coincides with a face of
// the bounds box takes over that face (face_plane = its index). Every vertex satisfies every
// plane within the tolerance. Empty or zero-volume intersections give an empty Polytope.
// Throws dimr::InvalidArgument if a plane or the bounds are not finite, or the bounds are
// empty (min > max).
Polytope IntersectHalfSpaces(const std::vector<HalfSpace>& planes,
                             const PolytopeOptions& options = PolytopeOptions());

}  // namespace dimr::geometry
