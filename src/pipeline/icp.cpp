#include "dimr/pipeline/icp.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <limits>
#include <string>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/sampling.h"

#ifdef DIMR_HAVE_PCL
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#endif

namespace dimr::pipeline {
namespace {

void CheckFinite(const std::vector<geometry::Vec3>& pts, const char* what) {
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!pts[i].allFinite()) {
      throw InvalidArgument(std::string("ICP: ") + what + " point " + std::to_string(i) +
                            " is not finite");
    }
  }
}

// Pairs of (transformed source, target) closer than max_correspondence: sums for the rigid fit.
struct Pairs {
  int n = 0;
  double sum_sq = 0;
  geometry::Vec3 mean_src = geometry::Vec3::Zero();
  geometry::Vec3 mean_dst = geometry::Vec3::Zero();
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();  // sum (p - mean_p)(q - mean_q)^T
};

Pairs Correspond(const std::vector<geometry::Vec3>& src, const Eigen::Matrix3d& r,
                 const geometry::Vec3& t, const geometry::KdTree& tree, double max_sq,
                 std::vector<geometry::Vec3>* moved, std::vector<int>* match) {
  Pairs p;
  moved->resize(src.size());
  match->assign(src.size(), -1);
  for (std::size_t i = 0; i < src.size(); ++i) {
    const geometry::Vec3 q = r * src[i] + t;
    (*moved)[i] = q;
    const auto [j, d2] = tree.Nearest(q);
    if (j < 0 || !(d2 < max_sq)) continue;
    (*match)[i] = j;
    ++p.n;
    p.sum_sq += d2;
    p.mean_src += q;
    p.mean_dst += tree.points()[static_cast<std::size_t>(j)];
  }
  if (p.n == 0) return p;
  p.mean_src /= p.n;
  p.mean_dst /= p.n;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const int j = (*match)[i];
    if (j < 0) continue;
    p.cross += ((*moved)[i] - p.mean_src) *
               (tree.points()[static_cast<std::size_t>(j)] - p.mean_dst).transpose();
  }
  return p;
}

// Unit normal of target point j: the eigenvector of the smallest eigenvalue of the covariance of
// its 8 nearest target points (computed on first use, cached); zero when degenerate.
class TargetNormals {
 public:
  explicit TargetNormals(const geometry::KdTree& tree)
      : tree_(tree), normals_(tree.size()), done_(tree.size(), 0) {}
  const geometry::Vec3& operator()(int j) {
    const std::size_t u = static_cast<std::size_t>(j);
    if (!done_[u]) {
      done_[u] = 1;
      const geometry::NeighbourhoodPca pca =
          geometry::PcaOfNeighbours(tree_.points(), tree_.KNearest(tree_.points()[u], 8));
      normals_[u] = pca.ok ? pca.normal : geometry::Vec3::Zero();
    }
    return normals_[u];
  }

 private:
  const geometry::KdTree& tree_;
  std::vector<geometry::Vec3> normals_;
  std::vector<char> done_;
};

// One linearised point-to-plane step: minimises sum ((p + w x p + t - q) . n)^2 over (w, t)
// for the matched pairs; returns false when there are fewer than 6 usable pairs.
bool PointToPlaneStep(const std::vector<geometry::Vec3>& moved, const std::vector<int>& match,
                      const geometry::KdTree& tree, TargetNormals* normals, Eigen::Matrix3d* dr,
                      geometry::Vec3* dt) {
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
  int used = 0;
  for (std::size_t i = 0; i < moved.size(); ++i) {
    if (match[i] < 0) continue;
    const geometry::Vec3& n = (*normals)(match[i]);
    if (n.squaredNorm() < 0.5) continue;
    const geometry::Vec3& q = tree.points()[static_cast<std::size_t>(match[i])];
    Eigen::Matrix<double, 6, 1> a;
    a.head<3>() = moved[i].cross(n);
    a.tail<3>() = n;
    const double b = (q - moved[i]).dot(n);
    ata += a * a.transpose();
    atb += a * b;
    ++used;
  }
  if (used < 6) return false;
  ata.diagonal().array() += 1e-9 * std::max(1.0, ata.trace());
  const Eigen::Matrix<double, 6, 1> x = ata.ldlt().solve(atb);
  if (!x.allFinite()) return false;
  const geometry::Vec3 w = x.head<3>();
  const double angle = w.norm();
  *dr = angle > 0 ? Eigen::AngleAxisd(angle, w / angle).toRotationMatrix()
                  : Eigen::Matrix3d::Identity();
  *dt = x.tail<3>();
  return true;
}

const config::EnumNames<IcpMetric>& IcpMetricNames() {
  static const config::EnumNames<IcpMetric> names(
      "icp.metric",
      {{IcpMetric::kPointToPoint, "point_to_point"}, {IcpMetric::kPointToPlane, "point_to_plane"}});
  return names;
}

const config::EnumNames<IcpBackend>& IcpBackendNames() {
  static const config::EnumNames<IcpBackend> names(
      "icp.backend", {{IcpBackend::kOwn, "own"}, {IcpBackend::kPcl, "pcl"}});
  return names;
}

}  // namespace

const char* IcpMetricName(IcpMetric m) { return IcpMetricNames().Name(m).c_str(); }
IcpMetric ParseIcpMetric(const std::string& s) { return IcpMetricNames().Parse(s); }
const char* IcpBackendName(IcpBackend b) { return IcpBackendNames().Name(b).c_str(); }
IcpBackend ParseIcpBackend(const std::string& s) { return IcpBackendNames().Parse(s); }

bool IcpBackendAvailable(IcpBackend b) {
#ifdef DIMR_HAVE_PCL
  (void)b;
  return true;
#else
  return b == IcpBackend::kOwn;
#endif
}

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
  if (!std::isfinite(relative_rms_change) || relative_rms_change < 0 || relative_rms_change >= 1) {
    throw InvalidArgument("icp.relative_rms_change must be in [0, 1) (got " +
                          std::to_string(relative_rms_change) + ")");
  }
}

void DecomposeRzRyRx(const Eigen::Matrix3d& r, double* rx, double* ry, double* rz) {
  *rx = std::atan2(r(2, 1), r(2, 2));
  *ry = std::atan2(-r(2, 0), std::sqrt(r(2, 1) * r(2, 1) + r(2, 2) * r(2, 2)));
  *rz = std::atan2(r(1, 0), r(0, 0));
}

IcpResult AlignPoints(const std::vector<geometry::Vec3>& source,
                      const std::vector<geometry::Vec3>& target, const IcpConfig& config) {
  config.Validate();
  CheckFinite(source, "source");
  CheckFinite(target, "target");
  IcpResult out;
  out.source_points = static_cast<int>(source.size());
  if (source.size() < 3 || target.size() < 3) {
    out.note = "fewer than 3 source or target points";
    return out;
  }
  // Work relative to the target mean so that precision does not depend on where the room sits
  // in the map (a robot's map coordinates can be large).
  geometry::Vec3 origin = geometry::Vec3::Zero();
  for (const auto& p : target) origin += p;
  origin /= static_cast<double>(target.size());
  std::vector<geometry::Vec3> dst(target.size()), src(source.size());
  for (std::size_t i = 0; i < target.size(); ++i) dst[i] = target[i] - origin;
  for (std::size_t i = 0; i < source.size(); ++i) src[i] = source[i] - origin;
  const geometry::KdTree tree(std::move(dst));
  const double max_sq = config.max_correspondence * config.max_correspondence;

  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  geometry::Vec3 t = geometry::Vec3::Zero();
  std::vector<geometry::Vec3> moved;
  std::vector<int> match;
  TargetNormals normals(tree);
  // Point-to-plane steps settle in a few iterations while the point-to-point RMS can still
  // drift: it stops on a 1e-5 rad / 1e-5 m step; point-to-point on 1e-7 or the RMS change.
  const double step_tolerance = config.metric == IcpMetric::kPointToPlane ? 1e-5 : 1e-7;
  double prev_rms = -1;
  out.ran = true;
  for (int it = 0; it < config.max_iterations; ++it) {
    const Pairs p = Correspond(src, r, t, tree, max_sq, &moved, &match);
    if (p.n < 3) {
      if (it == 0) out.note = "fewer than 3 correspondences within max_correspondence";
      break;
    }
    const double rms = std::sqrt(p.sum_sq / p.n);
    Eigen::Matrix3d dr;
    geometry::Vec3 dt;
    if (config.metric == IcpMetric::kPointToPlane) {
      if (!PointToPlaneStep(moved, match, tree, &normals, &dr, &dt)) {
        if (it == 0) out.note = "fewer than 6 point-to-plane pairs with a normal";
        break;
      }
    } else {
      // Kabsch: the rotation maximising sum q^T R p of the centred pairs, reflection-corrected.
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(p.cross,
                                                  Eigen::ComputeFullU | Eigen::ComputeFullV);
      Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
      if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0) d(2, 2) = -1;
      dr = svd.matrixV() * d * svd.matrixU().transpose();
      dt = p.mean_dst - dr * p.mean_src;
    }
    if (!dr.allFinite() || !dt.allFinite()) {
      out.note = "ICP step is not finite";
      break;
    }
    r = dr * r;
    t = dr * t + dt;
    ++out.iterations;
    const double angle = Eigen::AngleAxisd(dr).angle();
    const bool small_step = angle < step_tolerance && dt.norm() < step_tolerance;
    const bool flat_rms =
        prev_rms >= 0 && std::abs(prev_rms - rms) <= config.relative_rms_change * prev_rms;
    if (small_step || flat_rms) {
      out.converged = true;
      break;
    }
    prev_rms = rms;
  }
  const Pairs final_pairs = Correspond(src, r, t, tree, max_sq, &moved, &match);
  out.correspondences = final_pairs.n;
  out.fitness = final_pairs.n > 0 ? final_pairs.sum_sq / final_pairs.n : 0.0;
  // Back to the input frame: x -> r (x - origin) + t + origin.
  out.transform.setIdentity();
  out.transform.block<3, 3>(0, 0) = r;
  out.transform.block<3, 1>(0, 3) = t + origin - r * origin;
  if (!out.transform.allFinite()) {
    out.transform.setIdentity();
    out.note = "ICP returned a non-finite transform";
  }
  return out;
}

IcpResult AlignMeshToPoints(const geometry::TriangleMesh& mesh,
                            const std::vector<geometry::Vec3>& target, const IcpConfig& config) {
  config.Validate();
  IcpResult out;
  CheckFinite(target, "target");
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
  if (config.backend == IcpBackend::kOwn) {
    out = AlignPoints(samples.points, target, config);
    if (out.iterations == 0) return out;  // nothing to apply (note says why)
  } else {
#ifdef DIMR_HAVE_PCL
    using Cloud = pcl::PointCloud<pcl::PointXYZ>;
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
    Eigen::Matrix4d to = Eigen::Matrix4d::Identity(), from = Eigen::Matrix4d::Identity();
    to.block<3, 1>(0, 3) = origin;
    from.block<3, 1>(0, 3) = -origin;
    out.transform = to * local * from;
    if (!out.transform.allFinite()) {
      out.transform.setIdentity();
      out.note = "ICP returned a non-finite transform";
      return out;
    }
#else
    throw Error("ICP: this build has no PCL (icp.backend pcl needs PCL; use icp.backend own)");
#endif
  }
  DecomposeRzRyRx(out.transform.block<3, 3>(0, 0), &out.roll, &out.pitch, &out.yaw);
  const double limit = config.max_tilt_deg * M_PI / 180.0;
  out.accepted = std::abs(out.roll) <= limit && std::abs(out.pitch) <= limit;
  if (!out.accepted) out.note = "tilt beyond the limit";
  return out;
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
