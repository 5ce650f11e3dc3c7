// Mesh extraction from BSP planes (dimr-method.md section 6): evaluate every convex on a
// grid of cell centres in [-1, 1]^3, drop empty convexes and greedily drop redundant ones
// (every grid point they hold is also held by another still-counted convex, convex index
// order), then build each kept convex as an exact polytope from its planes
// (geometry::IntersectHalfSpaces) and concatenate them (closed, possibly overlapping convex
// parts; no boolean union, as the reference). LibTorch-free.
//
// The grid test subdivides the grid per convex and bounds every plane over a block of cells
// (docs/architecture.md, pipeline): planes positive nowhere in a block are dropped for it,
// blocks whose summed minimum excess reaches the threshold are skipped, and only the cells of
// small undecided blocks are tested, with the planes left in plane order. The result is that
// of testing every cell with every plane, bit for bit (test/pipeline/bsp_mesher_reference.h
// keeps that straightforward implementation; ~1.5 ms instead of ~12 ms per shipped-model
// shape).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "dimr/geometry/polytope.h"
#include "dimr/geometry/types.h"

namespace dimr::pipeline {

struct BspMeshOptions {
  int grid = 32;                   // evaluation grid (reference: 32^3)
  float inside_threshold = 0.01f;  // inside convex iff sum of plane excesses < threshold
  double bound = 1.0;              // polytopes are clipped to [-bound, bound]^3 (> 0)
  // Every plane moved outwards by this much (plane units: a x + b y + c z + d <= dilation) for
  // both the grid test and the polytopes, so meshes and occupancy stay one shape. 0 = the
  // reference. The decoder under-covers thin parts; a dilation chosen on validation shapes
  // counters that (docs/models.md).
  float dilation = 0.0f;
  // Every face moved outwards by this Euclidean distance in the normalised cube [-1, 1]^3
  // (a x + b y + c z + d <= distance_dilation * |(a, b, c)|), in addition to `dilation`. Unlike
  // the plane-unit dilation it grows steep and shallow planes alike (docs/models.md).
  float distance_dilation = 0.0f;
};

struct BspMeshResult {
  geometry::TriangleMesh mesh;  // canonical frame, concatenation of closed convex polytopes
  std::vector<int> kept_convexes;
  int nonempty_convexes = 0;     // convexes holding >= 1 grid point
  std::vector<int> face_convex;  // per triangle, the convex it belongs to
};

// planes: P x 4 (a, b, c, d), inside a plane iff a x + b y + c z + d <= 0.
// convex_planes[k]: the plane indices of convex k. Throws dimr::InvalidArgument on a plane
// index out of range, non-finite planes of a used convex, or bad options (grid outside
// [2, 256], a negative or non-finite dilation, bound not finite and > 0).
BspMeshResult ExtractBspMesh(const Eigen::MatrixXf& planes,
                             const std::vector<std::vector<int>>& convex_planes,
                             const BspMeshOptions& options = BspMeshOptions());

// Occupancy of the discrete BSP shape at points (N x 3): inside iff some convex has all its
// planes' summed excess (over the planes moved outwards by `dilation`) below the threshold.
std::vector<std::uint8_t> BspOccupancy(const Eigen::MatrixXf& planes,
                                       const std::vector<std::vector<int>>& convex_planes,
                                       const Eigen::MatrixX3f& points,
                                       float inside_threshold = 0.01f, float dilation = 0.0f);
// The same with the threshold and both dilations of `options`.
std::vector<std::uint8_t> BspOccupancy(const Eigen::MatrixXf& planes,
                                       const std::vector<std::vector<int>>& convex_planes,
                                       const Eigen::MatrixX3f& points,
                                       const BspMeshOptions& options);
// planes with every face moved outwards by `distance` (d -= distance * |(a, b, c)|).
Eigen::MatrixXf DistanceDilatedPlanes(const Eigen::MatrixXf& planes, float distance);

// Cell centres of an R^3 grid over [-1, 1]^3 (x fastest), the points the BSP occupancy and
// the IoU@R^3 are evaluated at.
Eigen::MatrixX3f BspGridCenters(int resolution);
// Intersection over union of two occupancy vectors of equal length (1 if both are empty).
double OccupancyIoU(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b);

}  // namespace dimr::pipeline
