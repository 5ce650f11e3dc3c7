// Area-weighted uniform surface sampling (seeded; same seed -> same points).
#pragma once

#include <cstdint>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

struct SurfaceSamples {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;    // unit face normals of the sampled faces
  std::vector<int> face_index;  // face each sample lies on
};

// `n` points uniformly distributed over the surface (face chosen with probability proportional
// to area, reflected barycentrics inside the face). Empty/zero-area mesh -> empty result.
SurfaceSamples SampleSurface(const TriangleMesh& mesh, std::size_t n, std::uint64_t seed);

// Poisson-disk-like "even" sampling: oversamples, then rejects points closer than `radius`
// (if radius <= 0 it is derived from the area so that about n points remain). May return fewer.
SurfaceSamples SampleSurfaceEven(const TriangleMesh& mesh, std::size_t n, std::uint64_t seed,
                                 double radius = 0.0);

}  // namespace dimr::geometry
