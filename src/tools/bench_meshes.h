// Procedural test meshes shared by the Google Benchmark case files.
#pragma once

#include <cmath>
#include <functional>

#include "dimr/geometry/types.h"

namespace dimr::tools {

// Closed latitude/longitude sphere-like surface with 2 * lon * (lat - 1) triangles (outward
// for a star-shaped `point`): vertex (theta, phi) = point(theta, phi), poles at theta = 0, pi.
inline geometry::TriangleMesh LatLonMesh(
    int lat, int lon, const std::function<geometry::Vec3(double, double)>& point) {
  geometry::TriangleMesh m;
  m.vertices.push_back(point(0.0, 0.0));
  for (int i = 1; i < lat; ++i) {
    const double th = M_PI * i / lat;
    for (int j = 0; j < lon; ++j) m.vertices.push_back(point(th, 2 * M_PI * j / lon));
  }
  m.vertices.push_back(point(M_PI, 0.0));
  const int south = static_cast<int>(m.vertices.size()) - 1;
  auto ring = [lon](int i, int j) { return 1 + (i - 1) * lon + (j % lon); };
  for (int j = 0; j < lon; ++j) m.faces.emplace_back(0, ring(1, j), ring(1, j + 1));
  for (int i = 1; i + 1 < lat; ++i) {
    for (int j = 0; j < lon; ++j) {
      m.faces.emplace_back(ring(i, j), ring(i + 1, j), ring(i + 1, j + 1));
      m.faces.emplace_back(ring(i, j), ring(i + 1, j + 1), ring(i, j + 1));
    }
  }
  for (int j = 0; j < lon; ++j) m.faces.emplace_back(south, ring(lat - 1, j + 1), ring(lat - 1, j));
  return m;
}

}  // namespace dimr::tools
