// Area-weighted uniform surface sampling and greedy "even" (Poisson-disk-like) sampling.
#include "dimr/geometry/sampling.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <unordered_map>

#include "dimr/geometry/error.h"
#include "dimr/geometry/grid_key.h"

namespace dimr::geometry {
namespace {

// Uniform double in [0, 1) from the top 53 bits (identical on every standard library,
// unlike std::uniform_real_distribution).
inline double Uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0);
}

}  // namespace

SurfaceSamples SampleSurface(const TriangleMesh& mesh, std::size_t n, std::uint64_t seed) {
  mesh.Validate("SampleSurface mesh");
  SurfaceSamples out;
  const std::size_t nf = mesh.faces.size();
  if (n == 0 || nf == 0) return out;
  // Cumulative areas and unit normals.
  std::vector<double> cum(nf);
  std::vector<Vec3> normals(nf);
  double total = 0.0;
  std::size_t last_positive = nf;
  for (std::size_t f = 0; f < nf; ++f) {
    const Vec3i& t = mesh.faces[f];
    const Vec3 cr = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                        .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
    const double len = cr.norm();
    const double area = 0.5 * len;
    if (area > 0.0) {
      normals[f] = cr / len;
      last_positive = f;
    } else {
      normals[f] = Vec3::Zero();
    }
    total += area;
    cum[f] = total;
  }
  if (!std::isfinite(total)) {
    throw InvalidArgument("SampleSurface: mesh surface area is not finite");
  }
  if (!(total > 0.0) || last_positive == nf) return out;

  std::mt19937_64 rng(seed);
  out.points.resize(n);
  out.normals.resize(n);
  out.face_index.resize(n);
  for (std::size_t s = 0; s < n; ++s) {
    // Face with probability area / total: first cumulative area exceeding r. Zero-area
    // faces never exceed their predecessor, so they are never chosen.
    const double r = Uniform01(rng) * total;
    std::size_t f =
        static_cast<std::size_t>(std::upper_bound(cum.begin(), cum.end(), r) - cum.begin());
    if (f > last_positive) f = last_positive;  // r rounded up to total
    double u = Uniform01(rng), v = Uniform01(rng);
    if (u + v > 1.0) {  // reflect into the triangle
      u = 1.0 - u;
      v = 1.0 - v;
    }
    const Vec3i& t = mesh.faces[f];
    const Vec3& a = mesh.vertices[t[0]];
    out.points[s] = a + u * (mesh.vertices[t[1]] - a) + v * (mesh.vertices[t[2]] - a);
    out.normals[s] = normals[f];
    out.face_index[s] = static_cast<int>(f);
  }
  return out;
}

SurfaceSamples SampleSurfaceEven(const TriangleMesh& mesh, std::size_t n, std::uint64_t seed,
                                 double radius) {
  if (std::isnan(radius)) throw InvalidArgument("SampleSurfaceEven: radius is NaN");
  mesh.Validate("SampleSurfaceEven mesh");
  SurfaceSamples out;
  if (n == 0) return out;
  if (radius <= 0.0) {
    const double area = mesh.SurfaceArea();
    if (!(area > 0.0)) return out;
    radius = std::sqrt(area / (3.0 * static_cast<double>(n)));
  }
  if (!std::isfinite(radius)) throw InvalidArgument("SampleSurfaceEven: radius is not finite");
  // Oversample 3x, then keep points greedily in sample order if no kept point is closer
  // than `radius` (spatial hash of cell size radius: only the 27 neighbouring cells).
  const SurfaceSamples cand = SampleSurface(mesh, 3 * n, seed);
  if (cand.points.empty()) return out;
  const double r2 = radius * radius;
  const double inv = 1.0 / radius;
  const Vec3 origin = mesh.Bounds().min;
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> cells;
  cells.reserve(cand.points.size());
  for (std::size_t i = 0; i < cand.points.size() && out.points.size() < n; ++i) {
    const Vec3& p = cand.points[i];
    const Vec3 q = (p - origin) * inv;
    const std::int64_t cx = static_cast<std::int64_t>(std::floor(q.x()));
    const std::int64_t cy = static_cast<std::int64_t>(std::floor(q.y()));
    const std::int64_t cz = static_cast<std::int64_t>(std::floor(q.z()));
    bool close = false;
    for (std::int64_t dz = -1; dz <= 1 && !close; ++dz) {
      for (std::int64_t dy = -1; dy <= 1 && !close; ++dy) {
        for (std::int64_t dx = -1; dx <= 1 && !close; ++dx) {
          // Keys wrap modulo 2^21 per axis: colliding cells only add candidates.
          const auto it = cells.find(PackCell3(cx + dx, cy + dy, cz + dz));
          if (it == cells.end()) continue;
          for (std::size_t k : it->second) {
            if ((out.points[k] - p).squaredNorm() < r2) {
              close = true;
              break;
            }
          }
        }
      }
    }
    if (close) continue;
    cells[PackCell3(cx, cy, cz)].push_back(out.points.size());
    out.points.push_back(p);
    out.normals.push_back(cand.normals[i]);
    out.face_index.push_back(cand.face_index[i]);
  }
  return out;
}

}  // namespace dimr::geometry
