// Google Benchmark cases for surface sampling, oriented-box IoU and voxelisation
// (`dimr bench geometry`): 1M samples on a 10k-triangle sphere, surface/solid voxelisation
// of a procedural chair at 1 and 2 cm, and the reference mesh-IoU voxel set at 0.047 m.
#ifdef DIMR_HAVE_BENCHMARK
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/sampling.h"
#include "dimr/geometry/voxelize.h"
#include "tools/bench_meshes.h"

namespace dimr::geometry {
namespace {

// Latitude/longitude ellipsoid with semi-axes `r`, centred at `c`: 2 * lon * (lat - 1) triangles.
TriangleMesh Ellipsoid(const Vec3& c, const Vec3& r, int lat, int lon) {
  return dimr::tools::LatLonMesh(lat, lon, [&](double th, double ph) {
    return Vec3(c + Vec3(r.x() * std::sin(th) * std::cos(ph), r.y() * std::sin(th) * std::sin(ph),
                         r.z() * std::cos(th)));
  });
}

// Closed box of size `s` centred at the origin, each face an n x n grid of quads, then
// rotated by R and moved to c.
TriangleMesh GridBox(const Vec3& s, int n, const Eigen::Matrix3d& R, const Vec3& c) {
  TriangleMesh m;
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = -1; side <= 1; side += 2) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const int base = static_cast<int>(m.vertices.size());
      for (int j = 0; j <= n; ++j) {
        for (int i = 0; i <= n; ++i) {
          Vec3 p;
          p[axis] = 0.5 * side * s[axis];
          p[u] = s[u] * (static_cast<double>(i) / n - 0.5);
          p[v] = s[v] * (static_cast<double>(j) / n - 0.5);
          m.vertices.push_back(p);
        }
      }
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          const int a = base + j * (n + 1) + i, b = a + 1, d = a + (n + 1), e = d + 1;
          if (side > 0) {  // u x v = +axis
            m.faces.emplace_back(a, b, e);
            m.faces.emplace_back(a, e, d);
          } else {
            m.faces.emplace_back(a, e, b);
            m.faces.emplace_back(a, d, e);
          }
        }
      }
    }
  }
  m.Transform(R, c);
  return m;
}

// Closed cylinder along z (radius r, from z0 to z1) at (x, y) with `seg` segments.
TriangleMesh Cylinder(double x, double y, double r, double z0, double z1, int seg) {
  TriangleMesh m;
  m.vertices.emplace_back(x, y, z0);
  m.vertices.emplace_back(x, y, z1);
  for (int j = 0; j < seg; ++j) {
    const double ph = 2 * M_PI * j / seg;
    m.vertices.emplace_back(x + r * std::cos(ph), y + r * std::sin(ph), z0);
    m.vertices.emplace_back(x + r * std::cos(ph), y + r * std::sin(ph), z1);
  }
  for (int j = 0; j < seg; ++j) {
    const int b0 = 2 + 2 * j, t0 = b0 + 1, b1 = 2 + 2 * ((j + 1) % seg), t1 = b1 + 1;
    m.faces.emplace_back(0, b1, b0);
    m.faces.emplace_back(1, t0, t1);
    m.faces.emplace_back(b0, b1, t1);
    m.faces.emplace_back(b0, t1, t0);
  }
  return m;
}

// A chair of overlapping closed parts (seat, tilted back, 4 legs, cushion), about
// 0.5 x 0.55 x 0.95 m at scale 1, ~8.8k triangles.
TriangleMesh Chair(double scale = 1.0) {
  TriangleMesh m = GridBox(Vec3(0.5, 0.5, 0.06), 16, Eigen::Matrix3d::Identity(), Vec3(0, 0, 0.45));
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(-0.17, Vec3::UnitX()).toRotationMatrix();
  m.Append(GridBox(Vec3(0.5, 0.04, 0.5), 16, tilt, Vec3(0, -0.27, 0.71)));
  for (int k = 0; k < 4; ++k) {
    const double x = (k & 1) ? 0.21 : -0.21, y = (k & 2) ? 0.21 : -0.21;
    m.Append(Cylinder(x, y, 0.025, 0.0, 0.44, 24));
  }
  m.Append(Ellipsoid(Vec3(0, 0.01, 0.5), Vec3(0.22, 0.22, 0.05), 24, 48));
  m.Transform(Eigen::Matrix3d::Identity() * scale, Vec3::Zero());
  return m;
}

void BM_GeometrySampleSurface(benchmark::State& state) {
  const TriangleMesh sphere = Ellipsoid(Vec3::Zero(), Vec3::Ones(), 51, 100);  // 10000 tris
  const std::size_t n = static_cast<std::size_t>(state.range(0));
  std::uint64_t seed = 1;
  for (auto _ : state) {
    SurfaceSamples s = SampleSurface(sphere, n, seed++);
    benchmark::DoNotOptimize(s.points.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(n));
  state.counters["triangles"] = static_cast<double>(sphere.faces.size());
}
BENCHMARK(BM_GeometrySampleSurface)->Arg(1000000)->Unit(benchmark::kMillisecond);

void BM_GeometrySampleSurfaceEven(benchmark::State& state) {
  const TriangleMesh chair = Chair();
  const std::size_t n = static_cast<std::size_t>(state.range(0));
  std::size_t kept = 0;
  for (auto _ : state) {
    SurfaceSamples s = SampleSurfaceEven(chair, n, 3);
    kept = s.points.size();
    benchmark::DoNotOptimize(s.points.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(n));
  state.counters["kept"] = static_cast<double>(kept);
}
BENCHMARK(BM_GeometrySampleSurfaceEven)->Arg(10000)->Unit(benchmark::kMillisecond);

// Arg: voxel size in mm.
void BM_GeometryVoxelizeSurface(benchmark::State& state) {
  const TriangleMesh chair = Chair();
  const double v = state.range(0) / 1000.0;
  std::size_t count = 0, cells = 0;
  for (auto _ : state) {
    VoxelGrid g = MakeGrid(chair.Bounds(), v, 1);
    VoxelizeSurface(chair, &g);
    count = g.Count();
    cells = g.occupied.size();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(chair.faces.size()));
  state.counters["triangles"] = static_cast<double>(chair.faces.size());
  state.counters["cells"] = static_cast<double>(cells);
  state.counters["occupied"] = static_cast<double>(count);
}
BENCHMARK(BM_GeometryVoxelizeSurface)->Arg(20)->Arg(10)->Unit(benchmark::kMillisecond);

void BM_GeometryVoxelizeFilled(benchmark::State& state) {
  const TriangleMesh chair = Chair();
  const double v = state.range(0) / 1000.0;
  std::size_t count = 0, cells = 0;
  for (auto _ : state) {
    VoxelGrid g = MakeGrid(chair.Bounds(), v, 1);
    VoxelizeFilled(chair, &g);
    count = g.Count();
    cells = g.occupied.size();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(cells));
  state.counters["cells"] = static_cast<double>(cells);
  state.counters["occupied"] = static_cast<double>(count);
}
BENCHMARK(BM_GeometryVoxelizeFilled)->Arg(20)->Arg(10)->Unit(benchmark::kMillisecond);

// Arg: object size in cm (the chair scaled to that height), pitch 0.047 m.
void BM_GeometryVoxelizeReference(benchmark::State& state) {
  const double scale = state.range(0) / 100.0 / 0.95;
  const TriangleMesh chair = Chair(scale);
  int d = 0;
  std::size_t united = 0;
  for (auto _ : state) {
    ReferenceVoxels rv = VoxelizeReference(chair, 0.047);
    d = rv.d;
    united = rv.UnitedCount();
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["d"] = d;
  state.counters["united"] = static_cast<double>(united);
}
BENCHMARK(BM_GeometryVoxelizeReference)->Arg(100)->Arg(200)->Unit(benchmark::kMicrosecond);

void BM_GeometryReferenceMeshIoU(benchmark::State& state) {
  const TriangleMesh a = Chair(1.0 / 0.95);
  TriangleMesh b = a;
  b.Transform(Eigen::AngleAxisd(0.2, Vec3::UnitZ()).toRotationMatrix(), Vec3(0.05, 0.02, 0));
  const ReferenceVoxels va = VoxelizeReference(a, 0.047), vb = VoxelizeReference(b, 0.047);
  double iou = 0;
  for (auto _ : state) {
    iou = ReferenceMeshIoU(va, vb);
    benchmark::DoNotOptimize(iou);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["iou"] = iou;
}
BENCHMARK(BM_GeometryReferenceMeshIoU)->Unit(benchmark::kMicrosecond);

void BM_GeometryBoxIoU(benchmark::State& state) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<OrientedBox> boxes(1024);
  for (OrientedBox& b : boxes) {
    b = OrientedBox{Vec3(u(rng), u(rng), u(rng)), Vec3(0.3 + u(rng), 0.3 + u(rng), 0.3 + u(rng)),
                    2 * M_PI * u(rng)};
  }
  double sum = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i + 1 < boxes.size(); ++i) sum += BoxIoU(boxes[i], boxes[i + 1]);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(boxes.size() - 1));
}
BENCHMARK(BM_GeometryBoxIoU)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace dimr::geometry
#endif  // DIMR_HAVE_BENCHMARK
