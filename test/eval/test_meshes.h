// Small procedural meshes for the eval tests.
#pragma once

#include <cmath>

#include "dimr/geometry/types.h"

namespace dimr::eval::testing {

inline void AddBox(geometry::TriangleMesh* m, const geometry::Vec3& lo, const geometry::Vec3& hi) {
  const int b = static_cast<int>(m->vertices.size());
  for (int i = 0; i < 8; ++i) {
    m->vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(),
                             i & 4 ? hi.z() : lo.z());
  }
  static const int kF[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& f : kF) m->faces.emplace_back(b + f[0], b + f[1], b + f[2]);
}

inline geometry::TriangleMesh Box(const geometry::Vec3& lo, const geometry::Vec3& hi) {
  geometry::TriangleMesh m;
  AddBox(&m, lo, hi);
  return m;
}

// A 4-leg table with dyadic dimensions (exact under power-of-two scaling).
inline geometry::TriangleMesh Table() {
  geometry::TriangleMesh m;
  AddBox(&m, {0, 0, 0.6875}, {1.25, 0.75, 0.75});
  for (double x : {0.0, 1.125}) {
    for (double y : {0.0, 0.625}) AddBox(&m, {x, y, 0}, {x + 0.125, y + 0.125, 0.6875});
  }
  return m;
}

inline geometry::TriangleMesh Sphere(int nu = 48, int nv = 24) {
  geometry::TriangleMesh m;
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
      m.vertices.emplace_back(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph),
                              std::cos(th));
    }
  }
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const int a = j * nu + i, b = j * nu + (i + 1) % nu, c = a + nu, d = b + nu;
      m.faces.emplace_back(a, c, b);
      m.faces.emplace_back(b, c, d);
    }
  }
  return m;
}

// Unit square in the z = z0 plane, [0,1]^2, two triangles.
inline geometry::TriangleMesh Square(double z0 = 0.0) {
  geometry::TriangleMesh m;
  m.vertices = {{0, 0, z0}, {1, 0, z0}, {1, 1, z0}, {0, 1, z0}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

}  // namespace dimr::eval::testing
