#include "dimr/pipeline/bsp_mesher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {
namespace {

void CheckInputs(const Eigen::MatrixXf& planes, const std::vector<std::vector<int>>& convexes) {
  if (planes.cols() != 4) {
    throw InvalidArgument("BSP planes must be P x 4, got " + std::to_string(planes.rows()) + " x " +
                          std::to_string(planes.cols()));
  }
  const bool all_finite = planes.allFinite();
  for (std::size_t k = 0; k < convexes.size(); ++k) {
    for (int p : convexes[k]) {
      if (p < 0 || p >= planes.rows()) {
        throw InvalidArgument("convex " + std::to_string(k) + " references plane " +
                              std::to_string(p) + " of " + std::to_string(planes.rows()));
      }
      if (!all_finite && !planes.row(p).allFinite()) {
        throw InvalidArgument("plane " + std::to_string(p) + " of convex " + std::to_string(k) +
                              " is not finite");
      }
    }
  }
}

// Summed positive excess of point x over the planes of a convex, with early exit once the
// threshold is reached.
inline bool InsideConvex(const Eigen::MatrixXf& planes, const std::vector<int>& ids, float x,
                         float y, float z, float threshold, float dilation) {
  float sum = 0.f;
  for (int p : ids) {
    const float v =
        planes(p, 0) * x + planes(p, 1) * y + planes(p, 2) * z + planes(p, 3) - dilation;
    if (v > 0.f) {
      sum += v;
      if (sum >= threshold) return false;
    }
  }
  return true;
}

void CheckDilation(float dilation) {
  if (!(dilation >= 0.0f) || !std::isfinite(dilation)) {
    throw InvalidArgument("BSP dilation must be finite and >= 0, got " + std::to_string(dilation));
  }
}

// An axis-aligned block of grid cells, [lo, hi] per axis (inclusive).
struct CellRange {
  int lo[3], hi[3];
  int Cells() const { return (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1); }
};

// The cells of a grid inside one convex, by recursive subdivision of the grid: for a block of
// cells, the range of every plane's value over the block's cell centres (a linear function:
// its extremes lie at the corners) says whether the plane is positive nowhere in it (it then
// adds nothing to any cell's sum and is dropped for the block's sub-blocks) or whether the
// summed minimum excess already reaches the threshold (no cell of the block is inside). The
// cells of small blocks are tested one by one with the planes left, in the convex's plane
// order and with the arithmetic of InsideConvex, so the result is that of testing every cell
// with every plane, bit for bit. The bounds are computed in double with margins far above the
// rounding error of the float test, so they only ever keep a cell for the exact test.
class GridTester {
 public:
  GridTester(int grid, float threshold, float dilation)
      : grid_(grid), threshold_(threshold), dilation_(dilation) {
    coord_.resize(static_cast<std::size_t>(grid));
    for (int i = 0; i < grid; ++i) coord_[i] = -1.0f + (2.0f * i + 1.0f) / static_cast<float>(grid);
    // Each split halves one side: at most 3 * ceil(log2(grid)) + 1 levels (grid <= 256).
    levels_.resize(3 * 9 + 2);
  }

  void Run(const Eigen::MatrixXf& planes, const std::vector<int>& ids, const CellRange& range,
           std::vector<std::uint32_t>* inside) {
    const std::size_t n = ids.size();
    a_.resize(n);
    b_.resize(n);
    c_.resize(n);
    d_.resize(n);
    margin_.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      const int p = ids[j];
      a_[j] = planes(p, 0);
      b_[j] = planes(p, 1);
      c_[j] = planes(p, 2);
      d_[j] = planes(p, 3);
      // |float result - exact value| <= ~4 ulp of the summed magnitudes (|x|, |y|, |z| <= 1).
      const double magnitude = std::abs(static_cast<double>(a_[j])) + std::abs(b_[j]) +
                               std::abs(c_[j]) + std::abs(d_[j]) + std::abs(dilation_);
      // A plane whose float value may overflow (inf, or NaN from inf - inf) is never dropped
      // nor counted in a block's minimum: only the cell test decides, as it did.
      margin_[j] =
          magnitude > 1e37 ? std::numeric_limits<double>::infinity() : 1e-5 * magnitude + 1e-30;
    }
    levels_[0].resize(n);
    for (std::size_t j = 0; j < n; ++j) levels_[0][j] = static_cast<int>(j);
    out_ = inside;
    Visit(range, 0);
  }

 private:
  static constexpr int kLeafCells = 16;

  void Visit(const CellRange& r, std::size_t depth) {
    const std::vector<int>& active = levels_[depth];
    std::vector<int>& kept = levels_[depth + 1];
    kept.clear();
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = coord_[r.lo[a]];
      hi[a] = coord_[r.hi[a]];
    }
    const double base_dil = static_cast<double>(dilation_);
    double min_sum = 0.0;
    for (int j : active) {
      const double a = a_[j], b = b_[j], c = c_[j];
      const double base = static_cast<double>(d_[j]) - base_dil;
      const double mn = base + std::min(a * lo[0], a * hi[0]) + std::min(b * lo[1], b * hi[1]) +
                        std::min(c * lo[2], c * hi[2]);
      const double mx = base + std::max(a * lo[0], a * hi[0]) + std::max(b * lo[1], b * hi[1]) +
                        std::max(c * lo[2], c * hi[2]);
      if (mx <= -margin_[j]) continue;  // float value <= 0 in every cell: adds nothing
      if (mn > margin_[j]) min_sum += mn - margin_[j];
      kept.push_back(j);
    }
    // Every cell's float sum >= (1 - 1e-4) * min_sum (at most ~1000 roundings of 6e-8 each), so
    // a block whose summed minimum excess clears the threshold with room to spare has no cell in.
    if (min_sum > 0.0 && min_sum * (1.0 - 1e-3) >= static_cast<double>(threshold_)) return;
    if (kept.empty()) {  // no plane positive anywhere: every cell is inside
      for (int z = r.lo[2]; z <= r.hi[2]; ++z) {
        for (int y = r.lo[1]; y <= r.hi[1]; ++y) {
          for (int x = r.lo[0]; x <= r.hi[0]; ++x) out_->push_back(Cell(x, y, z));
        }
      }
      return;
    }
    if (r.Cells() <= kLeafCells) {
      for (int z = r.lo[2]; z <= r.hi[2]; ++z) {
        for (int y = r.lo[1]; y <= r.hi[1]; ++y) {
          for (int x = r.lo[0]; x <= r.hi[0]; ++x) {
            if (Inside(kept, coord_[x], coord_[y], coord_[z])) out_->push_back(Cell(x, y, z));
          }
        }
      }
      return;
    }
    // Split the longest side in two.
    int axis = 0;
    for (int a = 1; a < 3; ++a) {
      if (r.hi[a] - r.lo[a] > r.hi[axis] - r.lo[axis]) axis = a;
    }
    const int mid = (r.lo[axis] + r.hi[axis]) / 2;
    CellRange first = r, second = r;
    first.hi[axis] = mid;
    second.lo[axis] = mid + 1;
    Visit(first, depth + 1);
    Visit(second, depth + 1);
  }

  // InsideConvex over the planes `ids` (indices into the convex's arrays).
  bool Inside(const std::vector<int>& ids, float x, float y, float z) const {
    float sum = 0.f;
    for (int j : ids) {
      const float v = a_[j] * x + b_[j] * y + c_[j] * z + d_[j] - dilation_;
      if (v > 0.f) {
        sum += v;
        if (sum >= threshold_) return false;
      }
    }
    return true;
  }

  std::uint32_t Cell(int x, int y, int z) const {
    return static_cast<std::uint32_t>(x + grid_ * (y + grid_ * z));
  }

  int grid_;
  float threshold_, dilation_;
  std::vector<float> coord_;
  std::vector<float> a_, b_, c_, d_;
  std::vector<double> margin_;
  std::vector<std::vector<int>> levels_;  // active planes per recursion depth
  std::vector<std::uint32_t>* out_ = nullptr;
};

}  // namespace

Eigen::MatrixXf DistanceDilatedPlanes(const Eigen::MatrixXf& planes, float distance) {
  if (planes.cols() != 4) {
    throw InvalidArgument("BSP planes must be P x 4, got " + std::to_string(planes.rows()) + " x " +
                          std::to_string(planes.cols()));
  }
  CheckDilation(distance);
  Eigen::MatrixXf out = planes;
  if (distance > 0.0f) out.col(3) -= distance * planes.leftCols(3).rowwise().norm();
  return out;
}

std::vector<std::uint8_t> BspOccupancy(const Eigen::MatrixXf& planes,
                                       const std::vector<std::vector<int>>& convex_planes,
                                       const Eigen::MatrixX3f& points,
                                       const BspMeshOptions& options) {
  return BspOccupancy(DistanceDilatedPlanes(planes, options.distance_dilation), convex_planes,
                      points, options.inside_threshold, options.dilation);
}

std::vector<std::uint8_t> BspOccupancy(const Eigen::MatrixXf& planes,
                                       const std::vector<std::vector<int>>& convex_planes,
                                       const Eigen::MatrixX3f& points, float inside_threshold,
                                       float dilation) {
  CheckInputs(planes, convex_planes);
  CheckDilation(dilation);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(points.rows()), 0);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    for (const auto& ids : convex_planes) {
      if (ids.empty()) continue;
      if (InsideConvex(planes, ids, points(i, 0), points(i, 1), points(i, 2), inside_threshold,
                       dilation)) {
        out[static_cast<std::size_t>(i)] = 1;
        break;
      }
    }
  }
  return out;
}

BspMeshResult ExtractBspMesh(const Eigen::MatrixXf& input_planes,
                             const std::vector<std::vector<int>>& convex_planes,
                             const BspMeshOptions& options) {
  CheckInputs(input_planes, convex_planes);
  const Eigen::MatrixXf planes = DistanceDilatedPlanes(input_planes, options.distance_dilation);
  if (options.grid < 2 || options.grid > 256) {
    throw InvalidArgument("BspMeshOptions.grid must be in [2, 256]");
  }
  if (!(options.bound > 0.0) || !std::isfinite(options.bound)) {
    throw InvalidArgument("BspMeshOptions.bound must be finite and > 0, got " +
                          std::to_string(options.bound));
  }
  CheckDilation(options.dilation);
  const double dil = options.dilation;
  const int G = options.grid;
  const std::size_t cells = static_cast<std::size_t>(G) * G * G;

  // The cells whose centres can lie in the clipping box (all of them for bound >= 1).
  CellRange all;
  for (int a = 0; a < 3; ++a) {
    all.lo[a] =
        std::max(0, static_cast<int>(std::ceil((-options.bound + 1.0) * G / 2.0 - 0.5)) - 1);
    all.hi[a] =
        std::min(G - 1, static_cast<int>(std::floor((options.bound + 1.0) * G / 2.0 - 0.5)) + 1);
  }
  geometry::PolytopeOptions popt;
  popt.bounds.min = geometry::Vec3::Constant(-options.bound);
  popt.bounds.max = geometry::Vec3::Constant(options.bound);
  const std::size_t C = convex_planes.size();
  std::vector<std::vector<std::uint32_t>> inside(C);  // grid cells inside each convex
  std::vector<int> count(cells, 0);
  BspMeshResult result;
  GridTester tester(G, options.inside_threshold, options.dilation);
  for (std::size_t k = 0; k < C; ++k) {
    if (convex_planes[k].empty()) continue;
    tester.Run(planes, convex_planes[k], all, &inside[k]);
    for (std::uint32_t cell : inside[k]) ++count[cell];
    if (!inside[k].empty()) ++result.nonempty_convexes;
  }
  // Greedy redundancy removal in convex index order.
  std::vector<geometry::HalfSpace> hs;
  for (std::size_t k = 0; k < C; ++k) {
    if (inside[k].empty()) continue;
    bool redundant = true;
    for (std::uint32_t cell : inside[k]) {
      if (count[cell] < 2) {
        redundant = false;
        break;
      }
    }
    if (redundant) {
      for (std::uint32_t cell : inside[k]) --count[cell];
      continue;
    }
    // The mesh is the exact polytope of the (dilated) planes, as bspt's without dilation; a
    // convex that holds grid points only within the tolerance has none.
    hs.clear();
    for (int p : convex_planes[k]) {
      hs.push_back({geometry::Vec3(planes(p, 0), planes(p, 1), planes(p, 2)),
                    static_cast<double>(planes(p, 3)) - dil});
    }
    const geometry::Polytope poly = geometry::IntersectHalfSpaces(hs, popt);
    if (poly.empty()) continue;
    result.kept_convexes.push_back(static_cast<int>(k));
    const geometry::TriangleMesh part = poly.ToMesh();
    result.mesh.Append(part);
    result.face_convex.insert(result.face_convex.end(), part.faces.size(), static_cast<int>(k));
  }
  return result;
}

Eigen::MatrixX3f BspGridCenters(int resolution) {
  const int R = resolution;
  if (R < 1) throw InvalidArgument("BspGridCenters: resolution must be >= 1");
  Eigen::MatrixX3f centers(R * R * R, 3);
  for (int z = 0; z < R; ++z) {
    for (int y = 0; y < R; ++y) {
      for (int x = 0; x < R; ++x) {
        centers.row(x + R * (y + R * z)) << -1.0f + (2.0f * x + 1) / R, -1.0f + (2.0f * y + 1) / R,
            -1.0f + (2.0f * z + 1) / R;
      }
    }
  }
  return centers;
}

double OccupancyIoU(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  if (a.size() != b.size()) {
    throw InvalidArgument("OccupancyIoU: sizes differ (" + std::to_string(a.size()) + " vs " +
                          std::to_string(b.size()) + ")");
  }
  std::size_t inter = 0, uni = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    inter += a[i] && b[i];
    uni += a[i] || b[i];
  }
  return uni ? static_cast<double>(inter) / static_cast<double>(uni) : 1.0;
}

}  // namespace dimr::pipeline
