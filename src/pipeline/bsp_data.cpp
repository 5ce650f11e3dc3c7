#include "dimr/pipeline/bsp_data.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <string>

#include "dimr/geometry/error.h"
#include "dimr/geometry/sampling.h"
#include "dimr/geometry/voxelize.h"

namespace dimr::pipeline {
namespace {

// [-1, 1]^3 at F = R * factor cells per axis.
geometry::VoxelGrid FineGrid(int R, int factor) {
  const int F = R * factor;
  geometry::VoxelGrid fine;
  fine.origin = geometry::Vec3::Constant(-1.0);
  fine.voxel_size = 2.0 / F;
  fine.dims = geometry::Vec3i::Constant(F);
  fine.occupied.assign(static_cast<std::size_t>(F) * F * F, 0);
  return fine;
}

// R^3 cell set iff any of its factor^3 fine cells is (x fastest).
std::vector<std::uint8_t> MaxPool(const geometry::VoxelGrid& fine, int R, int factor) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(R) * R * R, 0);
  const int F = R * factor;
  for (int k = 0; k < F; ++k) {
    for (int j = 0; j < F; ++j) {
      for (int i = 0; i < F; ++i) {
        if (fine.At(i, j, k)) {
          out[static_cast<std::size_t>(i / factor + R * (j / factor + R * (k / factor)))] = 1;
        }
      }
    }
  }
  return out;
}

}  // namespace

std::vector<std::uint8_t> BspCellOccupancy(const geometry::TriangleMesh& normalized_mesh,
                                           int resolution, int fine_factor) {
  if (resolution < 1 || fine_factor < 1 || resolution * fine_factor > 1024) {
    throw InvalidArgument("BspCellOccupancy: resolution " + std::to_string(resolution) +
                          " x fine factor " + std::to_string(fine_factor) +
                          " must be in [1, 1024]");
  }
  if (normalized_mesh.faces.empty()) {
    return std::vector<std::uint8_t>(static_cast<std::size_t>(resolution) * resolution * resolution,
                                     0);
  }
  normalized_mesh.Validate("BspCellOccupancy mesh");
  geometry::VoxelGrid fine = FineGrid(resolution, fine_factor);
  geometry::VoxelizeFilled(normalized_mesh, &fine);
  return MaxPool(fine, resolution, fine_factor);
}

geometry::TriangleMesh NormalizeForBsp(const geometry::TriangleMesh& mesh, int resolution) {
  if (mesh.faces.empty()) throw InvalidArgument("NormalizeForBsp: mesh has no faces");
  mesh.Validate("BSP training mesh");
  const geometry::AABB box = mesh.Bounds();
  const geometry::Vec3 ext = box.Extent();
  if ((ext.array() <= 1e-12).any()) {
    throw InvalidArgument("NormalizeForBsp: mesh has zero extent on an axis");
  }
  const double s = 1.0 - 1.0 / resolution;
  geometry::TriangleMesh out = mesh;
  for (auto& v : out.vertices) {
    v = ((2.0 * (v - box.min).array() / ext.array() - 1.0) * s).matrix();
  }
  out.vertex_normals.clear();
  return out;
}

std::vector<std::uint8_t> BspCellOccupancy(const BspMeshResult& decoded, int resolution,
                                           int fine_factor) {
  // Validates the sizes and handles the empty shape.
  std::vector<std::uint8_t> empty =
      BspCellOccupancy(geometry::TriangleMesh(), resolution, fine_factor);
  const geometry::TriangleMesh& mesh = decoded.mesh;
  if (mesh.faces.empty()) return empty;
  if (decoded.face_convex.size() != mesh.faces.size()) {
    throw InvalidArgument("BspCellOccupancy: " + std::to_string(decoded.face_convex.size()) +
                          " convex ids for " + std::to_string(mesh.faces.size()) + " triangles");
  }
  mesh.Validate("BspCellOccupancy decoded mesh");
  geometry::VoxelGrid fine = FineGrid(resolution, fine_factor);
  const int F = resolution * fine_factor;
  std::map<int, std::vector<std::size_t>> faces_of;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) faces_of[decoded.face_convex[f]].push_back(f);
  for (const auto& [convex, faces] : faces_of) {
    geometry::TriangleMesh part;
    std::map<int, int> vid;
    for (std::size_t f : faces) {
      geometry::Vec3i tri;
      for (int c = 0; c < 3; ++c) {
        const int v = mesh.faces[f][c];
        const auto it = vid.emplace(v, static_cast<int>(part.vertices.size())).first;
        if (it->second == static_cast<int>(part.vertices.size())) {
          part.vertices.push_back(mesh.vertices[static_cast<std::size_t>(v)]);
        }
        tri[c] = it->second;
      }
      part.faces.push_back(tri);
    }
    // A sub-grid aligned with the fine grid over the convex's bounds plus one cell.
    const geometry::AABB box = part.Bounds();
    geometry::Vec3i lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo[a] = static_cast<int>(std::floor((box.min[a] + 1.0) / fine.voxel_size)) - 1;
      hi[a] = static_cast<int>(std::floor((box.max[a] + 1.0) / fine.voxel_size)) + 1;
    }
    geometry::VoxelGrid sub;
    sub.voxel_size = fine.voxel_size;
    sub.origin = (lo.cast<double>() * fine.voxel_size).array() - 1.0;
    sub.dims = hi - lo + geometry::Vec3i::Ones();
    sub.occupied.assign(static_cast<std::size_t>(sub.dims.x()) * sub.dims.y() * sub.dims.z(), 0);
    geometry::VoxelizeFilled(part, &sub);
    for (int k = 0; k < sub.dims.z(); ++k) {
      for (int j = 0; j < sub.dims.y(); ++j) {
        for (int i = 0; i < sub.dims.x(); ++i) {
          if (!sub.At(i, j, k)) continue;
          const int gi = lo.x() + i, gj = lo.y() + j, gk = lo.z() + k;
          if (gi < 0 || gj < 0 || gk < 0 || gi >= F || gj >= F || gk >= F) continue;
          fine.occupied[fine.Index(gi, gj, gk)] = 1;
        }
      }
    }
  }
  return MaxPool(fine, resolution, fine_factor);
}

geometry::TriangleMesh MirrorLeftRight(const geometry::TriangleMesh& mesh) {
  geometry::TriangleMesh out = mesh;
  for (auto& v : out.vertices) v.y() = -v.y();
  for (auto& n : out.vertex_normals) n.y() = -n.y();
  for (auto& f : out.faces) std::swap(f.y(), f.z());
  return out;
}

nn::BspSample MakeBspSample(const geometry::TriangleMesh& mesh, int cad_class,
                            const std::string& model_id, const BspSampleOptions& opt,
                            std::uint64_t seed) {
  const int R = opt.resolution;
  if (R < 4 || opt.fine_factor < 1) throw InvalidArgument("BspSampleOptions: bad resolution");
  const geometry::TriangleMesh m = NormalizeForBsp(mesh, R);
  const int F = R * opt.fine_factor;
  geometry::VoxelGrid fine = FineGrid(R, opt.fine_factor);
  geometry::VoxelizeFilled(m, &fine);

  auto fine_inside = [&](float x, float y, float z) {
    const int i = static_cast<int>(std::floor((x + 1.0) / fine.voxel_size));
    const int j = static_cast<int>(std::floor((y + 1.0) / fine.voxel_size));
    const int k = static_cast<int>(std::floor((z + 1.0) / fine.voxel_size));
    if (i < 0 || j < 0 || k < 0 || i >= F || j >= F || k >= F) return false;
    return fine.At(i, j, k);
  };

  nn::BspSample s;
  s.cad_class = cad_class;
  s.model_id = model_id;
  const std::size_t cells = static_cast<std::size_t>(R) * R * R;
  s.iou_grid.assign(cells, 0);
  s.grid = MaxPool(fine, R, opt.fine_factor);
  for (int k = 0; k < R; ++k) {
    for (int j = 0; j < R; ++j) {
      for (int i = 0; i < R; ++i) {
        const float c[3] = {-1.0f + (2.0f * i + 1.0f) / R, -1.0f + (2.0f * j + 1.0f) / R,
                            -1.0f + (2.0f * k + 1.0f) / R};
        s.iou_grid[static_cast<std::size_t>(i + R * (j + R * k))] = fine_inside(c[0], c[1], c[2]);
      }
    }
  }

  std::mt19937_64 rng(seed);
  const auto surf = geometry::SampleSurface(m, static_cast<std::size_t>(opt.surface_points), rng());
  std::normal_distribution<double> noise(0.0, opt.surface_sigma);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  auto add = [&](const geometry::Vec3& p) {
    if ((p.array().abs() > 1.0).any()) return;
    const float x = static_cast<float>(p.x()), y = static_cast<float>(p.y()),
                z = static_cast<float>(p.z());
    auto& dst = fine_inside(x, y, z) ? s.inside_points : s.outside_points;
    if (dst.size() / 3 >= static_cast<std::size_t>(opt.max_points_per_side)) return;
    dst.push_back(x);
    dst.push_back(y);
    dst.push_back(z);
  };
  for (const auto& p : surf.points) {
    add(p + geometry::Vec3(noise(rng), noise(rng), noise(rng)));
  }
  for (int i = 0; i < opt.uniform_points; ++i) add(geometry::Vec3(uni(rng), uni(rng), uni(rng)));
  // Thin shapes may get few inside points from the random draws: add fine-cell centres.
  if (s.inside_points.size() / 3 < 64) {
    for (int k = 0; k < F; ++k) {
      for (int j = 0; j < F; ++j) {
        for (int i = 0; i < F; ++i) {
          if (!fine.At(i, j, k)) continue;
          const geometry::Vec3 c = fine.CellCenter(i, j, k);
          if (s.inside_points.size() / 3 >= static_cast<std::size_t>(opt.max_points_per_side))
            break;
          s.inside_points.push_back(static_cast<float>(c.x()));
          s.inside_points.push_back(static_cast<float>(c.y()));
          s.inside_points.push_back(static_cast<float>(c.z()));
        }
      }
    }
  }
  if (s.inside_points.empty()) {
    throw InvalidArgument("MakeBspSample: '" + model_id + "' has no interior at resolution " +
                          std::to_string(F));
  }
  return s;
}

}  // namespace dimr::pipeline
