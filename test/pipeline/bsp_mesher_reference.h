// The straightforward BSP mesh extraction that pipeline::ExtractBspMesh replaced, kept as the
// reference its fast path must reproduce bit for bit: per convex a half-space intersection of
// the planes grown by the threshold (its box bounds the cells to test), every cell of that box
// tested plane by plane, greedy redundancy removal on per-cell counts, then the exact polytope
// of each kept convex. Test-only (header-only, one TU per test binary includes it).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "dimr/geometry/polytope.h"
#include "dimr/pipeline/bsp_mesher.h"

namespace dimr::pipeline::testing {

inline bool ReferenceInsideConvex(const Eigen::MatrixXf& planes, const std::vector<int>& ids,
                                  float x, float y, float z, float threshold, float dilation) {
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

// Same inputs and result as ExtractBspMesh (valid inputs only: no checks).
inline BspMeshResult ReferenceExtractBspMesh(const Eigen::MatrixXf& input_planes,
                                             const std::vector<std::vector<int>>& convex_planes,
                                             const BspMeshOptions& options) {
  const Eigen::MatrixXf planes = DistanceDilatedPlanes(input_planes, options.distance_dilation);
  const double dil = options.dilation;
  const int G = options.grid;
  const std::size_t cells = static_cast<std::size_t>(G) * G * G;
  auto coord = [G](int i) { return -1.0f + (2.0f * i + 1.0f) / static_cast<float>(G); };
  geometry::PolytopeOptions popt;
  popt.bounds.min = geometry::Vec3::Constant(-options.bound);
  popt.bounds.max = geometry::Vec3::Constant(options.bound);
  const std::size_t C = convex_planes.size();
  std::vector<std::vector<std::uint32_t>> inside(C);
  std::vector<int> count(cells, 0);
  BspMeshResult result;
  auto half_spaces = [&](const std::vector<int>& ids, double shift) {
    std::vector<geometry::HalfSpace> hs;
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
      lo[a] = std::max(0, static_cast<int>(std::ceil((box.min[a] + 1.0) * G / 2.0 - 0.5)) - 1);
      hi[a] = std::min(G - 1, static_cast<int>(std::floor((box.max[a] + 1.0) * G / 2.0 - 0.5)) + 1);
    }
    for (int z = lo[2]; z <= hi[2]; ++z) {
      for (int y = lo[1]; y <= hi[1]; ++y) {
        for (int x = lo[0]; x <= hi[0]; ++x) {
          if (ReferenceInsideConvex(planes, ids, coord(x), coord(y), coord(z),
                                    options.inside_threshold, options.dilation)) {
            const std::uint32_t cell = static_cast<std::uint32_t>(x + G * (y + G * z));
            inside[k].push_back(cell);
            ++count[cell];
          }
        }
      }
    }
    if (!inside[k].empty()) ++result.nonempty_convexes;
  }
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

}  // namespace dimr::pipeline::testing
