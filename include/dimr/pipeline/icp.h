// ICP post-processing of a placed object mesh (dimr-method.md section 7): PCL's point-to-point
// pcl::IterativeClosestPoint of `samples` even surface samples of the mesh (source) to the
// observed points of the proposal (target), rigid, identity start, correspondences within
// `max_correspondence` metres, at most `max_iterations` iterations. The result is accepted iff
// the roll and pitch of R = Rz Ry Rx are both within `max_tilt_deg`; then the full transform
// (small tilt, any yaw, any translation) applies, otherwise the mesh stays as it was. Fitness
// is reported, not used (as the reference). LibTorch-free; needs PCL (DIMR_HAVE_PCL).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::pipeline {

struct IcpConfig {
  bool enabled = true;
  double max_correspondence = 0.04;  // metres (> 0)
  int max_iterations = 300;          // >= 1
  int samples = 2048;                // even surface samples of the mesh (>= 3)
  double max_tilt_deg = 10.0;        // acceptance limit of |roll| and |pitch|, degrees, [0, 90]
  std::uint64_t seed = 0;            // surface sampling seed
  // Throws dimr::InvalidArgument naming the bad key (e.g. "icp.max_correspondence").
  void Validate() const;
};

struct IcpResult {
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();  // what ICP found
  bool ran = false;                     // false: nothing to align (empty mesh / too few points)
  bool converged = false;               // PCL's hasConverged()
  bool accepted = false;                // within the tilt limit: `transform` applies
  double roll = 0, pitch = 0, yaw = 0;  // radians, R = Rz(yaw) Ry(pitch) Rx(roll)
  double fitness = 0;                   // PCL fitness score (mean squared distance, m^2)
  int source_points = 0;                // mesh samples used
  std::string note;                     // why it did not run / was rejected
};

// Rz * Ry * Rx decomposition of section 7: rx = atan2(R21, R22),
// ry = atan2(-R20, sqrt(R21^2 + R22^2)), rz = atan2(R10, R00).
void DecomposeRzRyRx(const Eigen::Matrix3d& rotation, double* rx, double* ry, double* rz);

// Aligns `mesh` to `target` (both in the same metric frame). Returns the ICP outcome; does not
// modify the mesh. Throws dimr::InvalidArgument for an invalid config or non-finite input,
// dimr::Error when the build has no PCL.
IcpResult AlignMeshToPoints(const geometry::TriangleMesh& mesh,
                            const std::vector<geometry::Vec3>& target, const IcpConfig& config);

// AlignMeshToPoints, then applies the transform to `mesh` when it is accepted.
IcpResult RefineMeshByIcp(geometry::TriangleMesh* mesh, const std::vector<geometry::Vec3>& target,
                          const IcpConfig& config);

}  // namespace dimr::pipeline
