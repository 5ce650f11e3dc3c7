#include "dimr/pipeline/bsp_mesher.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {
namespace {

void CheckInputs(const Eigen::MatrixXf& planes, const std::vector<std::vector<int>>& convexes) {
  if (planes.cols() != 4) {
    throw InvalidArgument("BSP planes must be P x 4, got " + std::to_string(planes.rows()) + " x " +
                          std::to_string(planes.cols()));
  }
  for (std::size_t k = 0; k < convexes.size(); ++k) {
    for (int p : convexes[k]) {
      if (p < 0 || p >= planes.rows()) {
        throw InvalidArgument("convex " + std::to_string(k) + " references plane " +
                              std::to_string(p) + " of " + std::to_string(planes.rows()));
      }
      if (!planes.row(p).allFinite()) {
        throw InvalidArgument("plane " + std::to_string(p) + " of convex " + std::to_string(k) +
                              " is not finite");
      }
    }
  }
}

// Summed positive excess of point x over the planes of a convex, with early exit once the
// threshold is reached.
inline bool InsideConvex(const Eigen::MatrixXf& planes, const std::vector<int>& ids, float x,
                         float y, float z, float threshold, float dilation) {
  float sum = 0.f;
  for (int p : ids) {
    const float v =
        planes(p, 0) * x + planes(p, 1) * y + planes(p, 2) * z + planes(p, 3) - dilation;
    if (v > 0.f) {
      sum += v;
      if (sum >= threshold) return false;
    }
  }
  return true;
}

void CheckDilation(float dilation) {
  if (!(dilation >= 0.0f) || !std::isfinite(dilation)) {
    throw InvalidArgument("BSP dilation must be finite and >= 0, got " + std::to_string(dilation));
  }
}

}  // namespace

Eigen::MatrixXf DistanceDilatedPlanes(const Eigen::MatrixXf& planes, float distance) {
  if (planes.cols() != 4) {
    throw InvalidArgument("BSP planes must be P x 4, got " + std::to_string(planes.rows()) + " x " +
                          std::to_string(planes.cols()));
  }
  CheckDilation(distance);
  Eigen::MatrixXf out = planes;
  if (distance > 0.0f) out.col(3) -= distance * planes.leftCols(3).rowwise().norm();
  return out;
}

std::vector<std::uint8_t> BspOccupancy(const Eigen::MatrixXf& planes,
                                       const std::vector<std::vector<int>>& convex_planes,
                                       const Eigen::MatrixX3f& points,
                                       const BspMeshOptions& options) {
  return BspOccupancy(DistanceDilatedPlanes(planes, options.distance_dilation), convex_planes,
                      points, options.inside_threshold, options.dilation);
}

std::vector<std::uint8_t> BspOccupancy(const Eigen::MatrixXf& planes,
                                       const std::vector<std::vector<int>>& convex_planes,
                                       const Eigen::MatrixX3f& points, float inside_threshold,
                                       float dilation) {
  CheckInputs(planes, convex_planes);
  CheckDilation(dilation);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(points.rows()), 0);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    for (const auto& ids : convex_planes) {
      if (ids.empty()) continue;
      if (InsideConvex(planes, ids, points(i, 0), points(i, 1), points(i, 2), inside_threshold,
                       dilation)) {
        out[static_cast<std::size_t>(i)] = 1;
        break;
      }
    }
  }
  return out;
}

BspMeshResult ExtractBspMesh(const Eigen::MatrixXf& input_planes,
                             const std::vector<std::vector<int>>& convex_planes,
                             const BspMeshOptions& options) {
  CheckInputs(input_planes, convex_planes);
  const Eigen::MatrixXf planes = DistanceDilatedPlanes(input_planes, options.distance_dilation);
  if (options.grid < 2 || options.grid > 256) {
    throw InvalidArgument("BspMeshOptions.grid must be in [2, 256]");
  }
  CheckDilation(options.dilation);
  const double dil = options.dilation;
  const int G = options.grid;
  const std::size_t cells = static_cast<std::size_t>(G) * G * G;
  auto coord = [G](int i) { return -1.0f + (2.0f * i + 1.0f) / static_cast<float>(G); };

  // A grid point can only be inside convex k (summed excess < threshold) if every single
  // plane's excess is below the threshold, i.e. if it lies in the polytope of the planes
  // shifted outwards by the threshold. That polytope's box bounds the cells to test exactly;
  // an empty one means the convex holds no grid point.
  geometry::PolytopeOptions popt;
  popt.bounds.min = geometry::Vec3::Constant(-options.bound);
  popt.bounds.max = geometry::Vec3::Constant(options.bound);
  const std::size_t C = convex_planes.size();
  std::vector<std::vector<std::uint32_t>> inside(C);  // grid cells inside each convex
  std::vector<int> count(cells, 0);
  BspMeshResult result;
  auto half_spaces = [&](const std::vector<int>& ids, double shift) {
    std::vector<geometry::HalfSpace> hs;
    hs.reserve(ids.size());
    for (int p : ids) {
      hs.push_back({geometry::Vec3(planes(p, 0), planes(p, 1), planes(p, 2)),
                    static_cast<double>(planes(p, 3)) - shift});
    }
    return hs;
  };
  for (std::size_t k = 0; k < C; ++k) {
    const auto& ids = convex_planes[k];
    if (ids.empty()) continue;
    const geometry::Polytope grown =
        geometry::IntersectHalfSpaces(half_spaces(ids, options.inside_threshold + dil), popt);
    if (grown.empty()) continue;
    geometry::AABB box;
    for (const auto& v : grown.vertices) box.Extend(v);
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      // Cell centres c_i = -1 + (2i + 1) / G inside [box.min, box.max].
      lo[a] = std::max(0, static_cast<int>(std::ceil((box.min[a] + 1.0) * G / 2.0 - 0.5)) - 1);
      hi[a] = std::min(G - 1, static_cast<int>(std::floor((box.max[a] + 1.0) * G / 2.0 - 0.5)) + 1);
    }
    for (int z = lo[2]; z <= hi[2]; ++z) {
      for (int y = lo[1]; y <= hi[1]; ++y) {
        for (int x = lo[0]; x <= hi[0]; ++x) {
          if (InsideConvex(planes, ids, coord(x), coord(y), coord(z), options.inside_threshold,
                           options.dilation)) {
            const std::uint32_t cell = static_cast<std::uint32_t>(x + G * (y + G * z));
            inside[k].push_back(cell);
            ++count[cell];
          }
        }
      }
    }
    if (!inside[k].empty()) ++result.nonempty_convexes;
  }
  // Greedy redundancy removal in convex index order.
  for (std::size_t k = 0; k < C; ++k) {
    if (inside[k].empty()) continue;
    bool redundant = true;
    for (std::uint32_t cell : inside[k]) {
      if (count[cell] < 2) {
        redundant = false;
        break;
      }
    }
    if (redundant) {
      for (std::uint32_t cell : inside[k]) --count[cell];
      continue;
    }
    // The mesh is the exact polytope of the (dilated) planes, as bspt's without dilation; a
    // convex that holds grid points only within the tolerance has none.
    const geometry::Polytope poly =
        geometry::IntersectHalfSpaces(half_spaces(convex_planes[k], dil), popt);
    if (poly.empty()) continue;
    result.kept_convexes.push_back(static_cast<int>(k));
    const geometry::TriangleMesh part = poly.ToMesh();
    result.mesh.Append(part);
    result.face_convex.insert(result.face_convex.end(), part.faces.size(), static_cast<int>(k));
  }
  return result;
}

Eigen::MatrixX3f BspGridCenters(int resolution) {
  const int R = resolution;
  if (R < 1) throw InvalidArgument("BspGridCenters: resolution must be >= 1");
  Eigen::MatrixX3f centers(R * R * R, 3);
  for (int z = 0; z < R; ++z) {
    for (int y = 0; y < R; ++y) {
      for (int x = 0; x < R; ++x) {
        centers.row(x + R * (y + R * z)) << -1.0f + (2.0f * x + 1) / R, -1.0f + (2.0f * y + 1) / R,
            -1.0f + (2.0f * z + 1) / R;
      }
    }
  }
  return centers;
}

double OccupancyIoU(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  if (a.size() != b.size()) {
    throw InvalidArgument("OccupancyIoU: sizes differ (" + std::to_string(a.size()) + " vs " +
                          std::to_string(b.size()) + ")");
  }
  std::size_t inter = 0, uni = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    inter += a[i] && b[i];
    uni += a[i] || b[i];
  }
  return uni ? static_cast<double>(inter) / static_cast<double>(uni) : 1.0;
}

}  // namespace dimr::pipeline
