// The frame dimr expects: metres, gravity aligned, z up (floor below everything). A cloud in a
// camera's optical frame (z forward, y down: a depth camera's PCD) or a y-up mesh export
// breaks that silently: stage 1 then segments a room lying on its side. Two helpers:
//
//   UpAxisRotation("−y") etc.: the proper rotation that maps the named input axis to +z
//     (`dimr reconstruct --up`; results are in the rotated frame, like --scale's);
//   CheckFloor: does the cloud have a floor at its bottom? The lowest layer (from the
//     `floor_quantile` quantile of z to `layer` above it) must be flat (its points in a cell
//     span <= `flat_range` in z: walls and legs run through the layer) in at least
//     `min_fraction` of the x-y footprint's `cell` cells. Measured (docs/real.md "Frames"):
//     20 SynthScan rooms 73-91 %, scene0470_00 69 %; PCL's office1.pcd (one depth frame) in
//     its optical frame taken as z up 0 %, with the wrong up axes 3-8 %, with --up -y 23 %
//     (the camera is pitched down, so its floor is not level: FindFloorPlane levels it).
//     A warning, not an error: a map may lack its floor.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>

#include "dimr/pipeline/point_cloud_input.h"

namespace dimr::pipeline {

// "z", "-z", "y", "-y", "x", "-x" (also with "+"): the rotation R (det +1) with R · axis = +z.
// Throws dimr::InvalidArgument naming the text otherwise.
Eigen::Matrix3f UpAxisRotation(const std::string& axis);

struct FloorCheckConfig {
  double floor_quantile = 0.01;
  double layer = 0.1;        // m above the floor level
  double cell = 0.1;         // m, x-y cells
  double flat_range = 0.04;  // m, a floor cell's bottom-layer points span at most this in z
  double min_fraction = 0.15;
};

struct FloorCheck {
  bool found = false;
  double floor_z = 0;        // m, the floor level tested
  double area_fraction = 0;  // bottom layer's cells / the footprint's cells
};

// Throws dimr::InvalidArgument for an empty or non-finite cloud or a bad config.
FloorCheck CheckFloor(const PointCloudInput& input, const FloorCheckConfig& config = {});

// Levelling (`dimr reconstruct --level`): a camera pitched down, a hand-held scan or a map
// whose frame is a few degrees off has its floor tilted. The floor plane is found by RANSAC
// on up to `sample` points: planes through 3 random points whose normal lies within
// `max_tilt_deg` of +z, scored by the points within `distance`; a candidate is the floor only
// if at most `max_below` of the points lie more than `below_margin` below it (a table top has
// the floor under it, a ceiling everything). Deterministic for a seed.
struct LevelConfig {
  double max_tilt_deg = 40;
  double distance = 0.03;     // m
  double below_margin = 0.1;  // m
  double max_below = 0.03;
  double min_inliers = 0.02;  // share of the sampled points on the plane
  int iterations = 400;
  std::size_t sample = 20000;
  unsigned seed = 1;
};

struct FloorPlane {
  bool found = false;
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();  // unit, pointing up (n.z > 0)
  float offset = 0;                                   // plane: normal . p + offset = 0
  double tilt_deg = 0;                                // angle between normal and +z
  double inliers = 0;                                 // share of the sampled points on it
};

// Throws dimr::InvalidArgument for an empty or non-finite cloud or a bad config.
FloorPlane FindFloorPlane(const PointCloudInput& input, const LevelConfig& config = {});

// The smallest rotation that turns `up` (any length > 0) into +z.
Eigen::Matrix3f LevellingRotation(const Eigen::Vector3f& up);

}  // namespace dimr::pipeline
