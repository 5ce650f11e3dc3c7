// Google Benchmark cases for the geometry query layer (`dimr bench geometry`): kd-tree build
// and nearest-neighbour queries, exact point-to-mesh distance (BVH vs brute force), and the
// convex polytope from half-spaces (the BSP decoder's hot path).
#ifdef DIMR_HAVE_BENCHMARK
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/mesh_distance.h"
#include "dimr/geometry/polytope.h"
#include "tools/bench_meshes.h"

namespace dimr::geometry {
namespace {

std::vector<Vec3> UniformPoints(int n, unsigned seed, double lo = -1.0, double hi = 1.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<Vec3> pts(n);
  for (Vec3& p : pts) p = Vec3(u(rng), u(rng), u(rng));
  return pts;
}

// A closed, bumpy latitude/longitude sphere with 2 * lon * (lat - 1) triangles.
TriangleMesh BumpySphere(int lat, int lon) {
  return dimr::tools::LatLonMesh(lat, lon, [](double th, double ph) {
    const double r = 1.0 + 0.1 * std::sin(5 * th) * std::cos(7 * ph);
    return Vec3(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th));
  });
}

// Random convexes around the origin: planes tangent to spheres of radius 0.2..0.9.
std::vector<std::vector<HalfSpace>> RandomConvexes(int count, int planes, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.2, 0.9);
  std::vector<std::vector<HalfSpace>> out(count);
  for (auto& set : out) {
    for (int i = 0; i < planes; ++i) {
      const Vec3 n = Vec3(g(rng), g(rng), g(rng)).normalized();
      set.push_back({n, -u(rng)});
    }
  }
  return out;
}

void BM_GeometryKdTreeBuild(benchmark::State& state) {
  const auto pts = UniformPoints(static_cast<int>(state.range(0)), 1);
  for (auto _ : state) {
    KdTree tree(pts);
    benchmark::DoNotOptimize(tree.size());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_GeometryKdTreeBuild)->Arg(100000)->Unit(benchmark::kMillisecond);

// Build + 100k single-threaded nearest queries (items = queries).
void BM_GeometryKdTreeBuildAndNearest(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const auto pts = UniformPoints(n, 2);
  const auto queries = UniformPoints(100000, 3, -1.1, 1.1);
  for (auto _ : state) {
    KdTree tree(pts);
    double sum = 0;
    for (const Vec3& q : queries) sum += tree.Nearest(q).second;
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryKdTreeBuildAndNearest)->Arg(100000)->Unit(benchmark::kMillisecond);

void BM_GeometryKdTreeNearestDistancesParallel(benchmark::State& state) {
  const KdTree tree(UniformPoints(static_cast<int>(state.range(0)), 2));
  const auto queries = UniformPoints(100000, 3, -1.1, 1.1);
  for (auto _ : state) benchmark::DoNotOptimize(NearestDistances(queries, tree).data());
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryKdTreeNearestDistancesParallel)
    ->Arg(100000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_GeometryKdTreeKNearest16(benchmark::State& state) {
  const KdTree tree(UniformPoints(100000, 2));
  const auto queries = UniformPoints(10000, 4);
  for (auto _ : state) {
    std::size_t total = 0;
    for (const Vec3& q : queries) total += tree.KNearest(q, 16).size();
    benchmark::DoNotOptimize(total);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryKdTreeKNearest16)->Unit(benchmark::kMillisecond);

void BM_GeometryKdTreeRadius(benchmark::State& state) {
  const KdTree tree(UniformPoints(100000, 2));
  const auto queries = UniformPoints(10000, 5);
  for (auto _ : state) {
    std::size_t total = 0;
    for (const Vec3& q : queries) total += tree.RadiusSearch(q, 0.05).size();
    benchmark::DoNotOptimize(total);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryKdTreeRadius)->Unit(benchmark::kMillisecond);

// 100k point queries on a ~20k-triangle mesh, single thread (items = queries).
void BM_GeometryMeshDistanceQuery(benchmark::State& state) {
  const TriangleMesh mesh = BumpySphere(100, 100);  // 19800 triangles
  const MeshDistance md(mesh);
  const auto queries = UniformPoints(100000, 6, -1.3, 1.3);
  for (auto _ : state) {
    double sum = 0;
    for (const Vec3& q : queries) sum += md.Query(q).distance;
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
  state.counters["triangles"] = static_cast<double>(mesh.faces.size());
}
BENCHMARK(BM_GeometryMeshDistanceQuery)->Unit(benchmark::kMillisecond);

// The typical evaluation workload: 100k points near the surface (surface samples + noise).
void BM_GeometryMeshDistanceNearSurface(benchmark::State& state) {
  const TriangleMesh mesh = BumpySphere(100, 100);
  const MeshDistance md(mesh);
  std::mt19937 rng(9);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> queries(100000);
  for (Vec3& q : queries) {
    const Vec3i& f = mesh.faces[rng() % mesh.faces.size()];
    double a = u(rng), b = u(rng);
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    q = mesh.vertices[f[0]] + a * (mesh.vertices[f[1]] - mesh.vertices[f[0]]) +
        b * (mesh.vertices[f[2]] - mesh.vertices[f[0]]) + Vec3(noise(rng), noise(rng), noise(rng));
  }
  for (auto _ : state) {
    double sum = 0;
    for (const Vec3& q : queries) sum += md.Query(q).distance;
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryMeshDistanceNearSurface)->Unit(benchmark::kMillisecond);

void BM_GeometryMeshDistanceParallel(benchmark::State& state) {
  const MeshDistance md(BumpySphere(100, 100));
  const auto queries = UniformPoints(100000, 6, -1.3, 1.3);
  for (auto _ : state) benchmark::DoNotOptimize(md.Distances(queries).data());
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryMeshDistanceParallel)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_GeometryMeshDistanceBuild(benchmark::State& state) {
  const TriangleMesh mesh = BumpySphere(100, 100);
  for (auto _ : state) {
    MeshDistance md(mesh);
    benchmark::DoNotOptimize(md.empty());
  }
  state.SetItemsProcessed(state.iterations() * mesh.faces.size());
}
BENCHMARK(BM_GeometryMeshDistanceBuild)->Unit(benchmark::kMillisecond);

// Speed-up on a small case: 2k queries on a ~2k-triangle mesh, BVH vs brute force.
void BM_GeometryMeshDistanceSmallBVH(benchmark::State& state) {
  const MeshDistance md(BumpySphere(32, 32));  // 1984 triangles
  const auto queries = UniformPoints(2000, 7, -1.3, 1.3);
  for (auto _ : state) {
    double sum = 0;
    for (const Vec3& q : queries) sum += md.Query(q).distance;
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryMeshDistanceSmallBVH)->Unit(benchmark::kMillisecond);

void BM_GeometryMeshDistanceSmallBruteForce(benchmark::State& state) {
  const TriangleMesh mesh = BumpySphere(32, 32);
  const auto queries = UniformPoints(2000, 7, -1.3, 1.3);
  for (auto _ : state) {
    double sum = 0;
    for (const Vec3& q : queries) {
      double best = std::numeric_limits<double>::infinity();
      for (const Vec3i& f : mesh.faces) {
        const Vec3 c = ClosestPointOnTriangle(q, mesh.vertices[f[0]], mesh.vertices[f[1]],
                                              mesh.vertices[f[2]]);
        best = std::min(best, (c - q).squaredNorm());
      }
      sum += std::sqrt(best);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * queries.size());
}
BENCHMARK(BM_GeometryMeshDistanceSmallBruteForce)->Unit(benchmark::kMillisecond);

// Convexes per second for random sets of 8 / 16 / 32 planes (items = convexes).
void BM_GeometryPolytope(benchmark::State& state) {
  const auto sets = RandomConvexes(256, static_cast<int>(state.range(0)), 8);
  std::size_t i = 0, faces = 0, calls = 0;
  for (auto _ : state) {
    const Polytope p = IntersectHalfSpaces(sets[i++ % sets.size()]);
    faces += p.faces.size();
    ++calls;
    benchmark::DoNotOptimize(p.vertices.data());
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["faces"] = calls ? static_cast<double>(faces) / calls : 0.0;
}
BENCHMARK(BM_GeometryPolytope)->Arg(8)->Arg(16)->Arg(32)->Arg(64);

}  // namespace
}  // namespace dimr::geometry

#endif  // DIMR_HAVE_BENCHMARK
