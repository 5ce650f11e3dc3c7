// The input of the stage-1 segmenter and the reconstructor: one scene's points (metres, gravity
// aligned with z up, any origin), optionally per-point colours in [0, 1] and normals. Nothing
// else (no labels: a training sample is nn::Stage1Sample). LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::pipeline {

struct PointCloudInput {
  std::string name;                      // for error messages ("" = "point cloud")
  std::vector<Eigen::Vector3f> points;   // metres, z up, any origin
  std::vector<Eigen::Vector3f> colors;   // empty or one per point, RGB in [0, 1]
  std::vector<Eigen::Vector3f> normals;  // empty or one per point (unit length, or zero = unknown)

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_colors() const { return !colors.empty(); }
  bool has_normals() const { return !normals.empty(); }

  // Throws dimr::InvalidArgument naming the cloud and, for a bad point, its index: no points;
  // a coordinate not finite; colours or normals present with another count than the points; a
  // colour component outside [0, 1] or not finite; a normal not finite or of length neither 0
  // nor within 1 +- 0.01.
  void Validate() const;
  // The structural part of Validate, for steps that run before it and accept an empty cloud:
  // colours or normals with another count than the points, a coordinate not finite. Same
  // messages.
  void ValidateShape() const;

  // p -> r p for every point and normal (a rotation about the origin: levelling, up axes).
  void Rotate(const Eigen::Matrix3f& r);

  // From a geometry::PointCloud (double coordinates, 8-bit colours -> [0, 1], normals as
  // given). Does not validate.
  static PointCloudInput FromPointCloud(const geometry::PointCloud& cloud,
                                        const std::string& name = "");
};

}  // namespace dimr::pipeline
