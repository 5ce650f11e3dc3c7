#include "dimr/pipeline/bsp_data.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "dimr/geometry/error.h"
#include "dimr/geometry/sampling.h"
#include "dimr/geometry/voxelize.h"

namespace dimr::pipeline {

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

nn::BspSample MakeBspSample(const geometry::TriangleMesh& mesh, int cad_class,
                            const std::string& model_id, const BspSampleOptions& opt,
                            std::uint64_t seed) {
  const int R = opt.resolution;
  if (R < 4 || opt.fine_factor < 1) throw InvalidArgument("BspSampleOptions: bad resolution");
  const geometry::TriangleMesh m = NormalizeForBsp(mesh, R);
  const int F = R * opt.fine_factor;
  geometry::VoxelGrid fine;
  fine.origin = geometry::Vec3::Constant(-1.0);
  fine.voxel_size = 2.0 / F;
  fine.dims = geometry::Vec3i::Constant(F);
  fine.occupied.assign(static_cast<std::size_t>(F) * F * F, 0);
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
  s.grid.assign(cells, 0);
  s.iou_grid.assign(cells, 0);
  for (int k = 0; k < F; ++k) {
    for (int j = 0; j < F; ++j) {
      for (int i = 0; i < F; ++i) {
        if (fine.At(i, j, k)) {
          const int ci = i / opt.fine_factor, cj = j / opt.fine_factor, ck = k / opt.fine_factor;
          s.grid[static_cast<std::size_t>(ci + R * (cj + R * ck))] = 1;
        }
      }
    }
  }
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
