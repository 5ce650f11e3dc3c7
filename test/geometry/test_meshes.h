// Small meshes shared by the geometry tests.
#pragma once

#include "dimr/geometry/types.h"

namespace dimr::geometry::testing {

// The unit cube [0, 1]^3: 8 vertices (vertex i = (i & 1, i >> 1 & 1, i >> 2 & 1)) and 12
// outward-oriented triangles.
inline TriangleMesh UnitCube() {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) m.vertices.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) m.faces.emplace_back(t[0], t[1], t[2]);
  return m;
}

}  // namespace dimr::geometry::testing
