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
// to area by binary search in the cumulative areas, reflected barycentrics inside the face).
// std::mt19937_64(seed) drives it, 3 draws per point (face, u, v), so the first m points of
// an n-point run equal an m-point run. Empty/zero-area mesh -> empty result. Throws
// InvalidArgument for an invalid mesh (TriangleMesh::Validate).
SurfaceSamples SampleSurface(const TriangleMesh& mesh, std::size_t n, std::uint64_t seed);

// Poisson-disk-like "even" sampling (as trimesh's sample_surface_even): draws 3n points with
// SampleSurface(mesh, 3n, seed), then keeps them greedily in order unless a kept point is
// closer than `radius` (spatial hash), stopping at n. If radius <= 0 it is
// sqrt(area / (3n)). Returns at most n points, possibly fewer. Throws InvalidArgument for
// an invalid mesh or a NaN/infinite radius.
SurfaceSamples SampleSurfaceEven(const TriangleMesh& mesh, std::size_t n, std::uint64_t seed,
                                 double radius = 0.0);

}  // namespace dimr::geometry
