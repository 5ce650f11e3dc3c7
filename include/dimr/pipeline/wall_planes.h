// Structure prior for stage 1's labels: large vertical planes that bound the scan are walls.
// On real rooms stage 1 takes stretches of wall for curtain or for the chair in front of it
// (scene0470_00: 10 % / 12 % of the wall points; the acceptance apartment of issue 22: 33 %
// curtain), surfaces no SynthScan wall looks like. A plane of a few square metres with (almost)
// nothing behind it is a wall whatever its colour, so points on it whose label is a class that
// never forms such a plane (chair, sofa, bed, table, desk, curtain, ...) become wall. Flat
// objects that sit in or on walls (door, window, picture, display, cabinets, shelves, counter,
// refrigerator) keep their labels.
//
// The rule (gravity-aligned cloud, z up; docs/real.md "Wall planes"):
//   1. PCA normals from the k nearest neighbours; candidates are points whose normal is within
//      ~15 degrees of horizontal on a locally flat surface (smallest eigenvalue share < 0.03);
//   2. sequential RANSAC on the candidates for vertical planes (a candidate's own horizontal
//      normal through it; inliers within `distance` and with a normal within ~25 degrees),
//      refit by least squares on the inliers' x-y;
//   3. a plane is a wall when its inliers cover >= `min_area` m² of 10 cm cells in the plane and
//      at most `max_behind` of the cloud lies more than 10 cm behind it (the room is on one
//      side); planes are searched until one covers less than `min_area`;
//   4. every point within `distance` of a wall plane, inside the cells its inliers cover (grown
//      by one), whose own normal is within ~25 degrees of the plane's (part of its surface, not
//      an object touching it), with an overridable label, is relabelled wall.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace dimr::pipeline {

struct WallPlaneConfig {
  double distance = 0.03;    // m, inlier distance to the plane
  double min_area = 2.0;     // m², smallest wall
  double max_behind = 0.03;  // share of the cloud allowed more than 10 cm behind a wall
  int neighbours = 12;       // PCA normals
  int max_planes = 24;
  int hypotheses = 400;  // RANSAC draws per plane
  std::uint64_t seed = 1;
  void Validate() const;  // throws dimr::InvalidArgument naming the field
};

// True for the RFS classes a wall plane overrides (bed, chair, sofa, table, desk, curtain,
// toilet, sink, bathtub, otherfurniture, trash_bin, other_table).
bool WallPlaneOverrides(int rfs_class);

struct WallPlaneResult {
  // (nx, ny, 0, d): nx x + ny y + d = 0, unit normal pointing into the room (the side that
  // holds the more of the cloud).
  std::vector<Eigen::Vector4f> planes;
  std::vector<double> areas;  // m² per plane
  // Per plane the span of its inliers: (u0, u1, z0, z1), u = -ny x + nx y along the plane.
  std::vector<Eigen::Vector4f> extents;
  std::size_t relabelled = 0;
};

// Relabels `semantic` (RFS classes, one per point) in place. Deterministic for a seed.
// Throws dimr::InvalidArgument for sizes that differ or a non-finite point (its index).
WallPlaneResult ApplyWallPlanes(const std::vector<Eigen::Vector3f>& points,
                                const WallPlaneConfig& config, std::vector<int>* semantic);

}  // namespace dimr::pipeline
