#include "dimr/eval/mesh_metrics.h"

#include <cmath>
#include <limits>

#include "dimr/geometry/error.h"
#include "dimr/geometry/sampling.h"

namespace dimr::eval {

const char* ProtocolName(Protocol p) {
  return p == Protocol::kReference ? "reference" : "corrected";
}

Protocol ParseProtocol(const std::string& name) {
  if (name == "reference") return Protocol::kReference;
  if (name == "corrected") return Protocol::kCorrected;
  throw InvalidArgument("unknown protocol '" + name + "' (expected reference or corrected)");
}

double ChamferDistance(const geometry::KdTree& a, const geometry::KdTree& b) {
  if (a.size() == 0 || b.size() == 0) return std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> d_ba = geometry::NearestDistances(b.points(), a);
  const std::vector<double> d_ab = geometry::NearestDistances(a.points(), b);
  double s1 = 0.0, s2 = 0.0;
  for (double d : d_ba) s1 += d;
  for (double d : d_ab) s2 += d;
  return 0.5 * (s1 / static_cast<double>(d_ba.size()) + s2 / static_cast<double>(d_ab.size()));
}

double ChamferDistance(const std::vector<geometry::Vec3>& a, const std::vector<geometry::Vec3>& b) {
  return ChamferDistance(geometry::KdTree(a), geometry::KdTree(b));
}

std::vector<geometry::Vec3> ChamferSamples(const geometry::TriangleMesh& mesh, std::uint64_t seed,
                                           std::size_t n) {
  return geometry::SampleSurface(mesh, n, seed).points;
}

double PointCoverageRatio(const geometry::MeshDistance& mesh,
                          const std::vector<geometry::Vec3>& points, double omega) {
  if (points.empty() || mesh.empty()) return 0.0;
  const std::vector<double> d = mesh.Distances(points);
  std::size_t covered = 0;
  for (double v : d) covered += v < omega ? 1 : 0;
  return static_cast<double>(covered) / static_cast<double>(points.size());
}

std::uint64_t MixSeed(std::uint64_t a, std::uint64_t b) {
  std::uint64_t z = a ^ (b + 0x9e3779b97f4a7c15ULL + (a << 6) + (a >> 2));
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace dimr::eval
