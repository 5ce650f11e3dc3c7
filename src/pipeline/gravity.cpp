#include "dimr/pipeline/gravity.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "dimr/core/error.h"
#include "dimr/core/quantile.h"
#include "dimr/geometry/grid_key.h"

namespace dimr::pipeline {
namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

Eigen::Matrix3f UpAxisRotation(const std::string& axis) {
  std::string a = axis;
  if (!a.empty() && a[0] == '+') a = a.substr(1);
  Eigen::Matrix3f r;
  // Rows: the new x, y, z as combinations of the input's.
  if (a == "z") {
    r.setIdentity();
  } else if (a == "-z") {
    r << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // half turn about x
  } else if (a == "y") {
    r << 1, 0, 0, 0, 0, -1, 0, 1, 0;  // (x, -z, y)
  } else if (a == "-y") {
    r << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // (x, z, -y): a camera's optical frame
  } else if (a == "x") {
    r << 0, 0, -1, 0, 1, 0, 1, 0, 0;  // (-z, y, x)
  } else if (a == "-x") {
    r << 0, 0, 1, 0, 1, 0, -1, 0, 0;  // (z, y, -x)
  } else {
    throw InvalidArgument("up axis: expected x, -x, y, -y, z or -z, got '" + axis + "'");
  }
  return r;
}

FloorCheck CheckFloor(const PointCloudInput& input, const FloorCheckConfig& config) {
  if (!(config.floor_quantile >= 0 && config.floor_quantile < 0.5 && config.layer > 0 &&
        config.cell > 0 && config.flat_range > 0 && config.min_fraction >= 0 &&
        config.min_fraction <= 1)) {
    throw InvalidArgument("CheckFloor: a config value is out of range");
  }
  if (input.empty()) throw InvalidArgument("CheckFloor: the cloud has no points");
  input.ValidateShape();
  const std::size_t n = input.points.size();
  std::vector<float> z(n);
  for (std::size_t i = 0; i < n; ++i) z[i] = input.points[i].z();
  FloorCheck out;
  out.floor_z = NearestRankQuantile(&z, config.floor_quantile);
  // Per x-y cell: the z range of its points in the bottom layer. A floor cell is flat there;
  // a wall's or a leg's cell runs through the whole layer.
  struct Range {
    float lo = 0, hi = 0;
    int n = 0;
  };
  std::unordered_set<std::int64_t> footprint;
  std::unordered_map<std::int64_t, Range> bottom;
  footprint.reserve(n / 8 + 1);
  for (const auto& p : input.points) {
    const std::int64_t key = geometry::PackCell2(geometry::CellOf(p.x(), config.cell),
                                                 geometry::CellOf(p.y(), config.cell));
    footprint.insert(key);
    if (p.z() > out.floor_z + config.layer) continue;
    Range& r = bottom[key];
    r.lo = r.n == 0 ? p.z() : std::min(r.lo, p.z());
    r.hi = r.n == 0 ? p.z() : std::max(r.hi, p.z());
    ++r.n;
  }
  std::size_t flat = 0;
  for (const auto& kv : bottom) {
    if (kv.second.n >= 2 && kv.second.hi - kv.second.lo <= config.flat_range) ++flat;
  }
  out.area_fraction =
      static_cast<double>(flat) / static_cast<double>(std::max<std::size_t>(1, footprint.size()));
  out.found = out.area_fraction >= config.min_fraction;
  return out;
}

FloorPlane FindFloorPlane(const PointCloudInput& input, const LevelConfig& config) {
  if (!(config.max_tilt_deg > 0 && config.max_tilt_deg < 90 && config.distance > 0 &&
        config.below_margin >= 0 && config.max_below >= 0 && config.max_below <= 1 &&
        config.min_inliers >= 0 && config.min_inliers <= 1 && config.iterations > 0 &&
        config.sample >= 3)) {
    throw InvalidArgument("FindFloorPlane: a config value is out of range");
  }
  if (input.empty()) throw InvalidArgument("FindFloorPlane: the cloud has no points");
  input.ValidateShape();
  // An evenly strided sample (deterministic, spread over the whole cloud).
  const std::size_t n = input.points.size();
  const std::size_t stride = std::max<std::size_t>(1, n / config.sample);
  std::vector<Eigen::Vector3f> pts;
  pts.reserve(n / stride + 1);
  for (std::size_t i = 0; i < n; i += stride) pts.push_back(input.points[i]);
  FloorPlane best;
  if (pts.size() < 3) return best;
  const float min_nz = static_cast<float>(std::cos(config.max_tilt_deg * kPi / 180.0));
  std::mt19937 rng(config.seed);
  std::uniform_int_distribution<std::size_t> pick(0, pts.size() - 1);
  std::size_t best_count = 0;
  const double m = static_cast<double>(pts.size());
  for (int it = 0; it < config.iterations; ++it) {
    const Eigen::Vector3f& a = pts[pick(rng)];
    const Eigen::Vector3f& b = pts[pick(rng)];
    const Eigen::Vector3f& c = pts[pick(rng)];
    Eigen::Vector3f nrm = (b - a).cross(c - a);
    const float len = nrm.norm();
    if (!(len > 1e-6f)) continue;
    nrm /= len;
    if (nrm.z() < 0) nrm = -nrm;
    if (nrm.z() < min_nz) continue;
    const float d = -nrm.dot(a);
    std::size_t on = 0, below = 0;
    for (const auto& p : pts) {
      const float s = nrm.dot(p) + d;
      if (std::abs(s) <= config.distance) ++on;
      if (s < -config.below_margin) ++below;
    }
    if (static_cast<double>(below) > config.max_below * m) continue;
    if (on > best_count) {
      best_count = on;
      best.normal = nrm;
      best.offset = d;
    }
  }
  if (best_count == 0 || static_cast<double>(best_count) < config.min_inliers * m) return best;
  // Least-squares refit on the inliers (centroid + smallest principal axis).
  std::vector<Eigen::Vector3d> inliers;
  inliers.reserve(best_count);
  for (const auto& p : pts) {
    if (std::abs(best.normal.dot(p) + best.offset) <= config.distance)
      inliers.push_back(p.cast<double>());
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& q : inliers) mean += q;
  mean /= static_cast<double>(inliers.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& q : inliers) cov += (q - mean) * (q - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d nd = eig.eigenvectors().col(0);
  if (nd.z() < 0) nd = -nd;
  best.found = true;
  best.normal = nd.normalized().cast<float>();
  best.offset = static_cast<float>(-nd.dot(mean));
  best.tilt_deg = std::acos(std::min(1.0, std::max(-1.0, nd.normalized().z()))) * 180.0 / kPi;
  best.inliers = static_cast<double>(best_count) / m;
  return best;
}

Eigen::Matrix3f LevellingRotation(const Eigen::Vector3f& up) {
  if (!(up.allFinite() && up.norm() > 0)) {
    throw InvalidArgument("LevellingRotation: the up vector must be finite and non-zero");
  }
  return Eigen::Quaternionf::FromTwoVectors(up.normalized(), Eigen::Vector3f::UnitZ())
      .toRotationMatrix();
}

}  // namespace dimr::pipeline
