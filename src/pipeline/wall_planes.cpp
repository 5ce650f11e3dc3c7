#include "dimr/pipeline/wall_planes.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <unordered_set>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"
#include "dimr/core/parallel.h"
#include "dimr/geometry/grid_key.h"
#include "dimr/geometry/kdtree.h"

namespace dimr::pipeline {
namespace {

constexpr double kCell = 0.1;          // m, in-plane cells (area, extent)
constexpr double kBehind = 0.1;        // m, "behind the wall"
constexpr double kMaxNormalZ = 0.26;   // candidates: normal within ~15 deg of horizontal
constexpr double kMaxFlatness = 0.03;  // smallest eigenvalue share of a flat patch
constexpr double kNormalCos = 0.9;     // inlier normal within ~25 deg of the plane's
constexpr std::size_t kScoreSample = 3000;
constexpr double kSample = 0.06;  // m, one normal per cell of this edge for the plane search

std::int64_t CellKey(double u, double z) {
  return geometry::PackCell2(geometry::CellOf(u, kCell), geometry::CellOf(z, kCell));
}

struct Plane {
  Eigen::Vector2d n;  // unit, horizontal
  double d = 0;
  double Distance(const Eigen::Vector3f& p) const { return n.x() * p.x() + n.y() * p.y() + d; }
  double U(const Eigen::Vector3f& p) const { return -n.y() * p.x() + n.x() * p.y(); }
};

}  // namespace

void WallPlaneConfig::Validate() const {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw InvalidArgument(std::string("wall planes: ") + what);
  };
  need(distance > 0 && distance <= 0.5, "distance must be in (0, 0.5] m");
  need(min_area > 0 && min_area <= 1000, "min_area must be in (0, 1000] m²");
  need(max_behind >= 0 && max_behind <= 1, "max_behind must be in [0, 1]");
  need(neighbours >= 4 && neighbours <= 100, "neighbours must be in [4, 100]");
  need(max_planes >= 1 && max_planes <= 1000, "max_planes must be in [1, 1000]");
  need(hypotheses >= 1 && hypotheses <= 100000, "hypotheses must be in [1, 100000]");
}

bool WallPlaneOverrides(int c) {
  using namespace labels;
  switch (c) {
    case kBed:
    case kChair:
    case kSofa:
    case kTable:
    case kDesk:
    case kCurtain:
    case kToilet:
    case kSink:
    case kBathtub:
    case kOtherFurniture:
    case kTrashBin:
    case kOtherTable:
      return true;
    default:
      return false;
  }
}

WallPlaneResult ApplyWallPlanes(const std::vector<Eigen::Vector3f>& points,
                                const WallPlaneConfig& config, std::vector<int>* semantic) {
  config.Validate();
  const std::size_t n = points.size();
  if (semantic == nullptr || semantic->size() != n)
    throw InvalidArgument("wall planes: " + std::to_string(n) + " points but " +
                          std::to_string(semantic ? semantic->size() : 0) + " labels");
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite())
      throw InvalidArgument("wall planes: point " + std::to_string(i) + " is not finite");
  }
  WallPlaneResult result;
  if (n < static_cast<std::size_t>(config.neighbours) + 1) return result;

  // 1. Normals of locally flat, vertical surface patches, at one representative point per
  // kSample cell (the first in input order; the neighbours come from the whole cloud).
  std::vector<geometry::Vec3> xyz(n);
  for (std::size_t i = 0; i < n; ++i) xyz[i] = points[i].cast<double>();
  const geometry::KdTree tree(xyz);
  // PCA normal of point i's neighbourhood and the smallest eigenvalue's share (-1: degenerate).
  auto pca = [&](std::size_t i, Eigen::Vector3f* nr) {
    const geometry::NeighbourhoodPca p =
        geometry::PcaOfNeighbours(xyz, tree.KNearest(xyz[i], config.neighbours));
    const double sum = p.eigenvalues.sum();
    if (!p.ok || !(sum > 0)) return -1.0;
    *nr = p.normal.cast<float>();
    return p.eigenvalues(0) / sum;
  };

  std::vector<int> reps;
  {
    std::unordered_set<std::uint64_t> seen;
    seen.reserve(n / 2 + 1);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t key = geometry::PackCell3(geometry::CellOf(points[i].x(), kSample),
                                                    geometry::CellOf(points[i].y(), kSample),
                                                    geometry::CellOf(points[i].z(), kSample));
      if (seen.insert(key).second) reps.push_back(static_cast<int>(i));
    }
  }
  std::vector<Eigen::Vector2f> normal(n, Eigen::Vector2f::Zero());  // candidates: unit
  std::vector<char> is_candidate(reps.size(), 0);
  ParallelRanges(reps.size(), 0, 512, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      Eigen::Vector3f nr;
      const double flat = pca(static_cast<std::size_t>(reps[r]), &nr);
      if (flat < 0 || flat > kMaxFlatness || std::abs(nr.z()) > kMaxNormalZ) continue;
      normal[reps[r]] = Eigen::Vector2f(nr.x(), nr.y()).normalized();
      is_candidate[r] = 1;
    }
  });
  std::vector<int> candidates;
  for (std::size_t r = 0; r < reps.size(); ++r)
    if (is_candidate[r]) candidates.push_back(reps[r]);

  // 2.-4. Sequential RANSAC for vertical planes.
  std::mt19937_64 rng(config.seed);
  std::vector<char> used(n, 0);
  for (int round = 0; round < config.max_planes; ++round) {
    std::vector<int> left;
    for (int i : candidates)
      if (!used[i]) left.push_back(i);
    if (left.size() < 50) break;
    std::vector<int> sample = left;
    if (sample.size() > kScoreSample) {
      std::shuffle(sample.begin(), sample.end(), rng);
      sample.resize(kScoreSample);
    }
    auto inliers_of = [&](const Plane& pl, const std::vector<int>& set) {
      std::vector<int> in;
      for (int i : set) {
        if (std::abs(pl.Distance(points[i])) > config.distance) continue;
        if (std::abs(normal[i].cast<double>().dot(pl.n)) < kNormalCos) continue;
        in.push_back(i);
      }
      return in;
    };
    Plane best;
    std::size_t best_count = 0;
    std::uniform_int_distribution<std::size_t> pick(0, left.size() - 1);
    for (int h = 0; h < config.hypotheses; ++h) {
      const int s = left[pick(rng)];
      Plane pl;
      pl.n = normal[s].cast<double>();
      pl.d = -(pl.n.x() * points[s].x() + pl.n.y() * points[s].y());
      const std::size_t c = inliers_of(pl, sample).size();
      if (c > best_count) best_count = c, best = pl;
    }
    if (best_count < 3) break;
    // Least-squares refit on the inliers' x-y (twice), then the inliers among all candidates.
    std::vector<int> in = inliers_of(best, left);
    for (int pass = 0; pass < 2 && in.size() >= 3; ++pass) {
      Eigen::Vector2d m = Eigen::Vector2d::Zero();
      for (int i : in) m += Eigen::Vector2d(points[i].x(), points[i].y());
      m /= static_cast<double>(in.size());
      Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
      for (int i : in) {
        const Eigen::Vector2d d = Eigen::Vector2d(points[i].x(), points[i].y()) - m;
        cov += d * d.transpose();
      }
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
      Eigen::Vector2d nn = eig.eigenvectors().col(0);
      if (nn.dot(best.n) < 0) nn = -nn;
      best.n = nn.normalized();
      best.d = -best.n.dot(m);
      in = inliers_of(best, left);
    }
    for (int i : in) used[i] = 1;
    std::unordered_set<std::int64_t> cells;
    std::vector<double> us;
    for (int i : in) {
      cells.insert(CellKey(best.U(points[i]), points[i].z()));
      us.push_back(best.U(points[i]));
    }
    const double area = static_cast<double>(cells.size()) * kCell * kCell;
    if (area < config.min_area) break;  // the largest plane left is too small
    // The room on one side: the share of the cloud more than kBehind on the thinner side,
    // within the plane's span along it.
    std::sort(us.begin(), us.end());
    const double u0 = us[us.size() / 50], u1 = us[us.size() - 1 - us.size() / 50];
    std::size_t front = 0, back = 0;
    for (const auto& p : points) {
      const double u = best.U(p);
      if (u < u0 || u > u1) continue;
      const double s = best.Distance(p);
      front += s > kBehind;
      back += s < -kBehind;
    }
    if (static_cast<double>(std::min(front, back)) > config.max_behind * static_cast<double>(n))
      continue;
    // A wall: relabel the overridable points on it, inside its cells grown by one.
    std::unordered_set<std::int64_t> grown;
    for (const std::int64_t key : cells) {
      const auto [iu, iz] = geometry::UnpackCell2(key);
      for (int du = -1; du <= 1; ++du)
        for (int dz = -1; dz <= 1; ++dz)
          grown.insert(geometry::PackCell2(std::int64_t{iu} + du, std::int64_t{iz} + dz));
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!WallPlaneOverrides((*semantic)[i])) continue;
      if (std::abs(best.Distance(points[i])) > config.distance) continue;
      if (!grown.count(CellKey(best.U(points[i]), points[i].z()))) continue;
      // Part of the plane's surface, not an object touching it (a bin's curved side).
      Eigen::Vector3f pn;
      if (pca(i, &pn) < 0) continue;
      if (std::abs(pn.x() * best.n.x() + pn.y() * best.n.y()) < kNormalCos) continue;
      (*semantic)[i] = labels::kWall;
      ++result.relabelled;
    }
    // Stored with the normal into the room (after the relabelling: its cells use this U).
    if (back > front) best.n = -best.n, best.d = -best.d;
    result.planes.emplace_back(static_cast<float>(best.n.x()), static_cast<float>(best.n.y()), 0.f,
                               static_cast<float>(best.d));
    result.areas.push_back(area);
    float u_lo = std::numeric_limits<float>::max(), u_hi = -u_lo, z_lo = u_lo, z_hi = -u_lo;
    for (int i : in) {
      const float u = static_cast<float>(best.U(points[i]));
      u_lo = std::min(u_lo, u), u_hi = std::max(u_hi, u);
      z_lo = std::min(z_lo, points[i].z()), z_hi = std::max(z_hi, points[i].z());
    }
    result.extents.emplace_back(u_lo, u_hi, z_lo, z_hi);
  }
  return result;
}

}  // namespace dimr::pipeline
