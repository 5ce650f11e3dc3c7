#include "dimr/pipeline/icp.h"

#include <cmath>
#include <string>

#include "dimr/geometry/error.h"
#include "dimr/geometry/sampling.h"

#ifdef DIMR_HAVE_PCL
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#endif

namespace dimr::pipeline {

void IcpConfig::Validate() const {
  if (!std::isfinite(max_correspondence) || max_correspondence <= 0) {
    throw InvalidArgument("icp.max_correspondence must be finite and > 0 (got " +
                          std::to_string(max_correspondence) + ")");
  }
  if (max_iterations < 1) {
    throw InvalidArgument("icp.max_iterations must be >= 1 (got " + std::to_string(max_iterations) +
                          ")");
  }
  if (samples < 3) {
    throw InvalidArgument("icp.samples must be >= 3 (got " + std::to_string(samples) + ")");
  }
  if (!std::isfinite(max_tilt_deg) || max_tilt_deg < 0 || max_tilt_deg > 90) {
    throw InvalidArgument("icp.max_tilt_deg must be in [0, 90] (got " +
                          std::to_string(max_tilt_deg) + ")");
  }
}

void DecomposeRzRyRx(const Eigen::Matrix3d& r, double* rx, double* ry, double* rz) {
  *rx = std::atan2(r(2, 1), r(2, 2));
  *ry = std::atan2(-r(2, 0), std::sqrt(r(2, 1) * r(2, 1) + r(2, 2) * r(2, 2)));
  *rz = std::atan2(r(1, 0), r(0, 0));
}

IcpResult AlignMeshToPoints(const geometry::TriangleMesh& mesh,
                            const std::vector<geometry::Vec3>& target, const IcpConfig& config) {
  config.Validate();
  IcpResult out;
  for (std::size_t i = 0; i < target.size(); ++i) {
    if (!target[i].allFinite()) {
      throw InvalidArgument("ICP: target point " + std::to_string(i) + " is not finite");
    }
  }
  if (mesh.empty() || mesh.SurfaceArea() <= 0) {
    out.note = "empty mesh";
    return out;
  }
  const geometry::SurfaceSamples samples =
      geometry::SampleSurfaceEven(mesh, static_cast<std::size_t>(config.samples), config.seed);
  out.source_points = static_cast<int>(samples.points.size());
  if (samples.points.size() < 3 || target.size() < 3) {
    out.note = "fewer than 3 source or target points";
    return out;
  }
#ifdef DIMR_HAVE_PCL
  using Cloud = pcl::PointCloud<pcl::PointXYZ>;
  // Centre both clouds on the target mean so that float precision does not depend on where the
  // room sits in the map (a robot's map coordinates can be large).
  geometry::Vec3 origin = geometry::Vec3::Zero();
  for (const auto& p : target) origin += p;
  origin /= static_cast<double>(target.size());
  auto to_cloud = [&origin](const std::vector<geometry::Vec3>& pts) {
    Cloud::Ptr c(new Cloud);
    c->reserve(pts.size());
    for (const auto& p : pts) {
      const geometry::Vec3 q = p - origin;
      c->push_back(pcl::PointXYZ(static_cast<float>(q.x()), static_cast<float>(q.y()),
                                 static_cast<float>(q.z())));
    }
    return c;
  };
  Cloud::Ptr src = to_cloud(samples.points);
  Cloud::Ptr dst = to_cloud(target);
  pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> icp;
  icp.setInputSource(src);
  icp.setInputTarget(dst);
  icp.setMaxCorrespondenceDistance(config.max_correspondence);
  icp.setMaximumIterations(config.max_iterations);
  // Open3D's defaults in the reference: relative fitness / RMSE change 1e-6.
  icp.setTransformationEpsilon(1e-12);
  icp.setEuclideanFitnessEpsilon(1e-6);
  Cloud aligned;
  icp.align(aligned);
  out.ran = true;
  out.converged = icp.hasConverged();
  out.fitness = icp.getFitnessScore(config.max_correspondence * config.max_correspondence);
  const Eigen::Matrix4d local = icp.getFinalTransformation().cast<double>();
  // Back to the input frame: T = Translate(origin) * local * Translate(-origin).
  Eigen::Matrix4d to = Eigen::Matrix4d::Identity(), from = Eigen::Matrix4d::Identity();
  to.block<3, 1>(0, 3) = origin;
  from.block<3, 1>(0, 3) = -origin;
  out.transform = to * local * from;
  if (!out.transform.allFinite()) {
    out.transform.setIdentity();
    out.note = "ICP returned a non-finite transform";
    return out;
  }
  DecomposeRzRyRx(out.transform.block<3, 3>(0, 0), &out.roll, &out.pitch, &out.yaw);
  const double limit = config.max_tilt_deg * M_PI / 180.0;
  out.accepted = std::abs(out.roll) <= limit && std::abs(out.pitch) <= limit;
  if (!out.accepted) out.note = "tilt beyond the limit";
  return out;
#else
  throw Error("ICP: this build has no PCL (configure with PCL to enable icp)");
#endif
}

IcpResult RefineMeshByIcp(geometry::TriangleMesh* mesh, const std::vector<geometry::Vec3>& target,
                          const IcpConfig& config) {
  IcpResult r = AlignMeshToPoints(*mesh, target, config);
  if (r.ran && r.accepted) {
    mesh->Transform(r.transform.block<3, 3>(0, 0), r.transform.block<3, 1>(0, 3));
  }
  return r;
}

}  // namespace dimr::pipeline
