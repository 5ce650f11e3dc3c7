// ICP post-processing of a placed object mesh (dimr-method.md section 7): rigid point-to-point
// ICP of `samples` even surface samples of the mesh (source) to the observed points of the
// proposal (target), identity start, correspondences within `max_correspondence` metres, at most
// `max_iterations` iterations. The result is accepted iff the roll and pitch of R = Rz Ry Rx are
// both within `max_tilt_deg`; then the full transform (small tilt, any yaw, any translation)
// applies, otherwise the mesh stays as it was. Fitness is reported, not used (as the reference).
//
// Two backends compute the same kind of transform:
//  - kOwn (default): this file's ICP. The target kd-tree (geometry::KdTree) is built once per
//    call; each iteration pairs every transformed source sample with its nearest target point
//    closer than max_correspondence and solves the rigid fit in closed form (Kabsch / SVD of
//    the cross-covariance, reflection-corrected). It stops early when the RMS of the pairs
//    changes by less than `relative_rms_change` (relative) between iterations, or the step is
//    below 1e-7 rad / 1e-7 m. Cost: O(iterations * samples * log(target)).
//  - kPcl: PCL's pcl::IterativeClosestPoint (what the first pipeline used; the reference's
//    Open3D-like stop criteria), kept for comparisons; needs PCL (DIMR_HAVE_PCL).
// LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::pipeline {

enum class IcpBackend { kOwn, kPcl };
// kOwn's error metric: point-to-point (the reference's; linear convergence) or point-to-plane
// (target normals from the PCA of each target point's 8 nearest target points; the linearised
// 6-DoF least squares, Tikhonov-damped by 1e-9 so unconstrained directions stay put).
enum class IcpMetric { kPointToPoint, kPointToPlane };
const char* IcpMetricName(IcpMetric m);            // "point_to_point" / "point_to_plane"
IcpMetric ParseIcpMetric(const std::string& s);    // throws dimr::InvalidArgument
const char* IcpBackendName(IcpBackend b);          // "own" / "pcl"
IcpBackend ParseIcpBackend(const std::string& s);  // throws dimr::InvalidArgument
bool IcpBackendAvailable(IcpBackend b);            // kPcl: only in a build with PCL

struct IcpConfig {
  bool enabled = true;
  IcpBackend backend = IcpBackend::kOwn;
  IcpMetric metric = IcpMetric::kPointToPoint;
  double max_correspondence = 0.04;   // metres (> 0)
  int max_iterations = 30;            // >= 1
  int samples = 1024;                 // even surface samples of the mesh (>= 3)
  double max_tilt_deg = 10.0;         // acceptance limit of |roll| and |pitch|, degrees, [0, 90]
  double relative_rms_change = 1e-4;  // kOwn early stop, [0, 1)
  std::uint64_t seed = 0;             // surface sampling seed
  // Throws dimr::InvalidArgument naming the bad key (e.g. "icp.max_correspondence").
  void Validate() const;
};

struct IcpResult {
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();  // what ICP found
  bool ran = false;                     // false: nothing to align (empty mesh / too few points)
  bool converged = false;               // kOwn: stopped by a stop criterion; kPcl: hasConverged()
  bool accepted = false;                // within the tilt limit: `transform` applies
  double roll = 0, pitch = 0, yaw = 0;  // radians, R = Rz(yaw) Ry(pitch) Rx(roll)
  double fitness = 0;       // mean squared distance of the final pairs (m^2), as PCL's score
  int source_points = 0;    // mesh samples used
  int iterations = 0;       // kOwn: rigid updates made (kPcl: not reported, 0)
  int correspondences = 0;  // kOwn: pairs in the final transform's evaluation
  std::string note;         // why it did not run / was rejected
};

// Rz * Ry * Rx decomposition of section 7: rx = atan2(R21, R22),
// ry = atan2(-R20, sqrt(R21^2 + R22^2)), rz = atan2(R10, R00).
void DecomposeRzRyRx(const Eigen::Matrix3d& rotation, double* rx, double* ry, double* rz);

// Point-to-point ICP of `source` to `target` (the kOwn backend without the mesh sampling and
// the tilt rule). `transform`, `ran`, `converged`, `fitness`, `iterations`, `correspondences`
// of the result are set. Throws dimr::InvalidArgument for non-finite input.
IcpResult AlignPoints(const std::vector<geometry::Vec3>& source,
                      const std::vector<geometry::Vec3>& target, const IcpConfig& config);

// Aligns `mesh` to `target` (both in the same metric frame). Returns the ICP outcome; does not
// modify the mesh. Throws dimr::InvalidArgument for an invalid config or non-finite input,
// dimr::Error for the kPcl backend when the build has no PCL.
IcpResult AlignMeshToPoints(const geometry::TriangleMesh& mesh,
                            const std::vector<geometry::Vec3>& target, const IcpConfig& config);

// AlignMeshToPoints, then applies the transform to `mesh` when it is accepted.
IcpResult RefineMeshByIcp(geometry::TriangleMesh* mesh, const std::vector<geometry::Vec3>& target,
                          const IcpConfig& config);

}  // namespace dimr::pipeline
