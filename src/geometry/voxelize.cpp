// Voxelisation: exact surface cells (separating-axis test), solid fill by border flood fill,
// and the reference mesh-IoU voxel set (spec dimr-metrics.md section 3).
#include "dimr/geometry/voxelize.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

// Largest per-axis cell count accepted by the reference voxeliser (binvox's own limit).
constexpr int kMaxReferenceDim = 1024;
// Cells of a dense grid we are willing to allocate.
constexpr double kMaxGridCells = 4.0e9;
// Slack, in cell units, when turning a triangle's bounding box into candidate cells/lines.
constexpr double kEps = 1e-7;

// Projection interval of the triangle (vertices relative to the box centre) on `axis`
// compared with the box radius on that axis. True if `axis` separates them. Touching
// counts as overlapping. A zero axis never separates.
inline bool Separated(const Vec3& axis, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                      const Vec3& half) {
  const double p0 = axis.dot(v0), p1 = axis.dot(v1), p2 = axis.dot(v2);
  const double r =
      half.x() * std::abs(axis.x()) + half.y() * std::abs(axis.y()) + half.z() * std::abs(axis.z());
  const double lo = std::min({p0, p1, p2});
  const double hi = std::max({p0, p1, p2});
  return lo > r || hi < -r;
}

// Separating-axis triangle / axis-aligned box overlap test (13 candidate axes: the 3 box
// normals, the triangle normal and the 9 edge x box-axis cross products).
bool TriangleBoxOverlap(const Vec3& centre, const Vec3& half, const Vec3& a, const Vec3& b,
                        const Vec3& c) {
  const Vec3 v0 = a - centre, v1 = b - centre, v2 = c - centre;
  // Box face normals: the triangle's bounding box against the box.
  for (int k = 0; k < 3; ++k) {
    const double lo = std::min({v0[k], v1[k], v2[k]});
    const double hi = std::max({v0[k], v1[k], v2[k]});
    if (lo > half[k] || hi < -half[k]) return false;
  }
  const Vec3 e0 = v1 - v0, e1 = v2 - v1, e2 = v0 - v2;
  // Triangle plane.
  if (Separated(e0.cross(e1), v0, v1, v2, half)) return false;
  // Edge x box axis.
  const std::array<const Vec3*, 3> edges = {&e0, &e1, &e2};
  for (const Vec3* e : edges) {
    if (Separated(Vec3(0.0, -e->z(), e->y()), v0, v1, v2, half)) return false;  // x × e
    if (Separated(Vec3(e->z(), 0.0, -e->x()), v0, v1, v2, half)) return false;  // y × e
    if (Separated(Vec3(-e->y(), e->x(), 0.0), v0, v1, v2, half)) return false;  // z × e
  }
  return true;
}

void CheckMesh(const TriangleMesh& mesh, const std::string& what) { mesh.Validate(what); }

int ClampIndex(double v, int n) {
  if (!(v > 0.0)) return 0;  // also NaN
  if (v >= n - 1) return n - 1;
  return static_cast<int>(v);
}

// Signed doubled area of (a, b, p), evaluated so that swapping a and b negates the result
// exactly: points on an edge shared by two triangles are classified consistently.
inline double EdgeFunction(double ax, double ay, double bx, double by, double px, double py) {
  const bool swap = (bx < ax) || (bx == ax && by < ay);
  if (swap) {
    std::swap(ax, bx);
    std::swap(ay, by);
  }
  const double v = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
  return swap ? -v : v;
}

// Membership of the (already rounded/floored) cell indices `idx` in v.united.
bool LookupUnited(const ReferenceVoxels& v, const double idx[3]) {
  for (int a = 0; a < 3; ++a) {
    if (!(idx[a] >= 0.0) || !(idx[a] < v.d)) return false;  // also rejects NaN
  }
  return v.united[v.Index(static_cast<int>(idx[0]), static_cast<int>(idx[1]),
                          static_cast<int>(idx[2]))] != 0;
}

}  // namespace

std::size_t VoxelGrid::Count() const {
  return static_cast<std::size_t>(
      std::count_if(occupied.begin(), occupied.end(), [](std::uint8_t v) { return v != 0; }));
}

VoxelGrid MakeGrid(const AABB& bounds, double voxel_size, int padding) {
  if (!(voxel_size > 0.0) || !std::isfinite(voxel_size)) {
    throw InvalidArgument("MakeGrid: voxel_size must be positive and finite, got " +
                          std::to_string(voxel_size));
  }
  if (padding < 0) {
    throw InvalidArgument("MakeGrid: padding must be >= 0, got " + std::to_string(padding));
  }
  if (bounds.Empty() || !bounds.min.allFinite() || !bounds.max.allFinite()) {
    throw InvalidArgument("MakeGrid: bounds are empty or not finite");
  }
  VoxelGrid grid;
  grid.voxel_size = voxel_size;
  grid.origin = bounds.min - Vec3::Constant(padding * voxel_size);
  double cells = 1.0;
  for (int k = 0; k < 3; ++k) {
    const double n = std::max(1.0, std::ceil((bounds.max[k] - bounds.min[k]) / voxel_size));
    const double total = n + 2.0 * padding;
    if (total > std::numeric_limits<int>::max() / 2) {
      throw InvalidArgument("MakeGrid: grid axis " + std::to_string(k) + " would have " +
                            std::to_string(total) + " cells");
    }
    grid.dims[k] = static_cast<int>(total);
    cells *= total;
  }
  if (cells > kMaxGridCells) {
    throw InvalidArgument("MakeGrid: grid would have " + std::to_string(cells) +
                          " cells (voxel_size " + std::to_string(voxel_size) + " too small)");
  }
  grid.occupied.assign(static_cast<std::size_t>(cells), 0);
  return grid;
}

void VoxelizeSurface(const TriangleMesh& mesh, VoxelGrid* grid) {
  if (grid == nullptr) throw InvalidArgument("VoxelizeSurface: grid is null");
  CheckMesh(mesh, "VoxelizeSurface mesh");
  const Vec3i& n = grid->dims;
  if ((n.array() <= 0).any() ||
      grid->occupied.size() != static_cast<std::size_t>(n.x()) * n.y() * n.z()) {
    throw InvalidArgument("VoxelizeSurface: grid dims do not match its occupancy array");
  }
  const double s = grid->voxel_size;
  const Vec3 half = Vec3::Constant(0.5 * s);
  for (const Vec3i& f : mesh.faces) {
    const Vec3& a = mesh.vertices[f[0]];
    const Vec3& b = mesh.vertices[f[1]];
    const Vec3& c = mesh.vertices[f[2]];
    const Vec3 lo = (a.cwiseMin(b).cwiseMin(c) - grid->origin) / s;
    const Vec3 hi = (a.cwiseMax(b).cwiseMax(c) - grid->origin) / s;
    // Skip triangles entirely outside the grid.
    bool outside = false;
    for (int k = 0; k < 3; ++k) outside |= hi[k] < 0.0 || lo[k] >= n[k];
    if (outside) continue;
    const Vec3i i0(ClampIndex(std::floor(lo.x()), n.x()), ClampIndex(std::floor(lo.y()), n.y()),
                   ClampIndex(std::floor(lo.z()), n.z()));
    const Vec3i i1(ClampIndex(std::floor(hi.x()), n.x()), ClampIndex(std::floor(hi.y()), n.y()),
                   ClampIndex(std::floor(hi.z()), n.z()));
    for (int k = i0.z(); k <= i1.z(); ++k) {
      for (int j = i0.y(); j <= i1.y(); ++j) {
        for (int i = i0.x(); i <= i1.x(); ++i) {
          const std::size_t idx = grid->Index(i, j, k);
          if (grid->occupied[idx]) continue;
          if (TriangleBoxOverlap(grid->CellCenter(i, j, k), half, a, b, c)) {
            grid->occupied[idx] = 1;
          }
        }
      }
    }
  }
}

void VoxelizeFilled(const TriangleMesh& mesh, VoxelGrid* grid) {
  VoxelizeSurface(mesh, grid);
  const Vec3i n = grid->dims;
  // 0 = empty (not yet reached), 1 = surface, 2 = reached from the border.
  std::vector<std::uint8_t>& occ = grid->occupied;
  std::vector<std::size_t> stack;
  auto push = [&](int i, int j, int k) {
    const std::size_t idx = grid->Index(i, j, k);
    if (occ[idx] == 0) {
      occ[idx] = 2;
      stack.push_back(idx);
    }
  };
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        if (i == 0 || j == 0 || k == 0 || i == n.x() - 1 || j == n.y() - 1 || k == n.z() - 1) {
          push(i, j, k);
        }
      }
    }
  }
  const std::size_t sx = 1, sy = static_cast<std::size_t>(n.x()),
                    sz = static_cast<std::size_t>(n.x()) * n.y();
  while (!stack.empty()) {
    const std::size_t idx = stack.back();
    stack.pop_back();
    const int i = static_cast<int>(idx % sy);
    const int j = static_cast<int>((idx / sy) % n.y());
    const int k = static_cast<int>(idx / sz);
    const auto visit = [&](std::size_t nb) {
      if (occ[nb] == 0) {
        occ[nb] = 2;
        stack.push_back(nb);
      }
    };
    if (i > 0) visit(idx - sx);
    if (i + 1 < n.x()) visit(idx + sx);
    if (j > 0) visit(idx - sy);
    if (j + 1 < n.y()) visit(idx + sy);
    if (k > 0) visit(idx - sz);
    if (k + 1 < n.z()) visit(idx + sz);
  }
  // Everything not reached from outside is solid.
  for (std::uint8_t& v : occ) v = (v == 2) ? 0 : 1;
}

// ---------------------------------------------------------------------------------------
// Reference voxel set.
// ---------------------------------------------------------------------------------------

Vec3 ReferenceVoxels::CellPoint(int i, int j, int k) const {
  const double step = extent / (d - 1);
  return t + Vec3(i, j, k) * step;
}

Vec3 ReferenceVoxels::CellCentre(int i, int j, int k) const {
  const double step = extent / d;
  return t + (Vec3(i, j, k).array() + 0.5).matrix() * step;
}

bool ReferenceVoxels::IsFilled(const Vec3& p) const {
  if (d < 2 || united.empty()) return false;
  double idx[3];
  for (int a = 0; a < 3; ++a) {
    // Default rounding mode: ties to even, like numpy.round.
    idx[a] = std::nearbyint((p[a] - t[a]) * (d - 1) / extent);
  }
  return LookupUnited(*this, idx);
}

bool ReferenceVoxels::IsFilledExact(const Vec3& p) const {
  if (d < 2 || united.empty()) return false;
  double idx[3];
  for (int a = 0; a < 3; ++a) idx[a] = std::floor((p[a] - t[a]) * d / extent);
  return LookupUnited(*this, idx);
}

std::size_t ReferenceVoxels::SurfaceCount() const {
  return static_cast<std::size_t>(std::count(surface.begin(), surface.end(), 1));
}

std::size_t ReferenceVoxels::UnitedCount() const {
  return static_cast<std::size_t>(std::count(united.begin(), united.end(), 1));
}

ReferenceVoxels VoxelizeReference(const TriangleMesh& mesh, double pitch, bool exact_pitch) {
  if (!(pitch > 0.0) || !std::isfinite(pitch)) {
    throw InvalidArgument("VoxelizeReference: pitch must be positive and finite, got " +
                          std::to_string(pitch));
  }
  CheckMesh(mesh, "VoxelizeReference mesh");
  ReferenceVoxels rv;
  rv.exact_pitch = exact_pitch;
  if (mesh.vertices.empty()) return rv;
  const AABB bounds = mesh.Bounds();  // over ALL vertices, referenced or not
  rv.t = bounds.min;
  rv.extent = (bounds.max - bounds.min).maxCoeff();
  if (mesh.faces.empty() || !(rv.extent > 0.0)) return rv;  // degenerate: empty voxel set
  const double q = rv.extent / pitch;
  if (q >= kMaxReferenceDim + 1) {
    throw InvalidArgument("VoxelizeReference: extent " + std::to_string(rv.extent) + " / pitch " +
                          std::to_string(pitch) + " exceeds " + std::to_string(kMaxReferenceDim) +
                          " cells per axis");
  }
  const int d = std::max(2, static_cast<int>(q));  // int() truncation, as in the reference
  rv.d = d;
  const double s = rv.extent / d;
  const std::size_t nc = static_cast<std::size_t>(d) * d * d;
  rv.surface.assign(nc, 0);
  rv.united.assign(nc, 0);

  // S: SAT with the cell half-size enlarged by 2%.
  const Vec3 half = Vec3::Constant(1.02 * rv.extent / (2.0 * d));
  const double grow = 0.01;  // the enlarged cell i spans [(i - 0.01) s, (i + 1.01) s]
  for (const Vec3i& f : mesh.faces) {
    const Vec3& a = mesh.vertices[f[0]];
    const Vec3& b = mesh.vertices[f[1]];
    const Vec3& c = mesh.vertices[f[2]];
    const Vec3 lo = (a.cwiseMin(b).cwiseMin(c) - rv.t) / s;
    const Vec3 hi = (a.cwiseMax(b).cwiseMax(c) - rv.t) / s;
    Vec3i i0, i1;
    for (int k = 0; k < 3; ++k) {
      // Candidates: enlarged cells overlapping the triangle's bbox (kEps absorbs rounding
      // of the division; the exact SAT test decides).
      i0[k] = ClampIndex(std::ceil(lo[k] - 1.0 - grow - kEps), d);
      i1[k] = ClampIndex(std::floor(hi[k] + grow + kEps), d);
    }
    for (int k = i0.z(); k <= i1.z(); ++k) {
      for (int j = i0.y(); j <= i1.y(); ++j) {
        for (int i = i0.x(); i <= i1.x(); ++i) {
          const std::size_t idx = rv.Index(i, j, k);
          if (rv.surface[idx]) continue;
          if (TriangleBoxOverlap(rv.CellCentre(i, j, k), half, a, b, c)) rv.surface[idx] = 1;
        }
      }
    }
  }

  // C: for each axis a, each line through a row of cell centres parallel to a gets the
  // min/max coordinate of its intersections with all triangles. Lines are indexed by the
  // cell indices (u, v) along the other two axes (u = axis a+1, v = axis a+2, cyclic).
  const double inf = std::numeric_limits<double>::infinity();
  std::array<std::vector<double>, 3> line_min, line_max;
  for (int axis = 0; axis < 3; ++axis) {
    const int ua = (axis + 1) % 3, va = (axis + 2) % 3;
    std::vector<double>& mn = line_min[axis];
    std::vector<double>& mx = line_max[axis];
    mn.assign(static_cast<std::size_t>(d) * d, inf);
    mx.assign(static_cast<std::size_t>(d) * d, -inf);
    for (const Vec3i& f : mesh.faces) {
      const Vec3& p0 = mesh.vertices[f[0]];
      const Vec3& p1 = mesh.vertices[f[1]];
      const Vec3& p2 = mesh.vertices[f[2]];
      const double x0 = p0[ua], y0 = p0[va], x1 = p1[ua], y1 = p1[va], x2 = p2[ua], y2 = p2[va];
      // Lines whose centre coordinate t + (idx + 0.5) s lies in the projected bbox.
      const double ulo = (std::min({x0, x1, x2}) - rv.t[ua]) / s - 0.5;
      const double uhi = (std::max({x0, x1, x2}) - rv.t[ua]) / s - 0.5;
      const double vlo = (std::min({y0, y1, y2}) - rv.t[va]) / s - 0.5;
      const double vhi = (std::max({y0, y1, y2}) - rv.t[va]) / s - 0.5;
      // Lines whose centre lies in the bbox (kEps absorbs rounding of the division; the
      // exact inclusive test below decides).
      const int iu0 = ClampIndex(std::ceil(ulo - kEps), d);
      const int iu1 = ClampIndex(std::floor(uhi + kEps), d);
      const int iv0 = ClampIndex(std::ceil(vlo - kEps), d);
      const int iv1 = ClampIndex(std::floor(vhi + kEps), d);
      const double area2 = EdgeFunction(x0, y0, x1, y1, x2, y2);
      if (area2 == 0.0) continue;  // projects to a segment: neighbours carry its hits
      for (int iv = iv0; iv <= iv1; ++iv) {
        const double py = rv.t[va] + (iv + 0.5) * s;
        for (int iu = iu0; iu <= iu1; ++iu) {
          const double px = rv.t[ua] + (iu + 0.5) * s;
          // Barycentric weights (w0 opposite p0, ...), inclusive of edges.
          const double w0 = EdgeFunction(x1, y1, x2, y2, px, py);
          const double w1 = EdgeFunction(x2, y2, x0, y0, px, py);
          const double w2 = EdgeFunction(x0, y0, x1, y1, px, py);
          const bool inside = (w0 >= 0 && w1 >= 0 && w2 >= 0) || (w0 <= 0 && w1 <= 0 && w2 <= 0);
          if (!inside) continue;
          const double sum = w0 + w1 + w2;
          if (sum == 0.0) continue;
          const double hit = (w0 * p0[axis] + w1 * p1[axis] + w2 * p2[axis]) / sum;
          const std::size_t li = static_cast<std::size_t>(iu) + static_cast<std::size_t>(d) * iv;
          mn[li] = std::min(mn[li], hit);
          mx[li] = std::max(mx[li], hit);
        }
      }
    }
  }
  for (int k = 0; k < d; ++k) {
    for (int j = 0; j < d; ++j) {
      for (int i = 0; i < d; ++i) {
        const std::size_t idx = rv.Index(i, j, k);
        if (rv.surface[idx]) {
          rv.united[idx] = 1;
          continue;
        }
        const int ijk[3] = {i, j, k};
        bool in = true;
        for (int axis = 0; axis < 3 && in; ++axis) {
          const int ua = (axis + 1) % 3, va = (axis + 2) % 3;
          const std::size_t li =
              static_cast<std::size_t>(ijk[ua]) + static_cast<std::size_t>(d) * ijk[va];
          const double c = rv.t[axis] + (ijk[axis] + 0.5) * s;
          in = line_min[axis][li] <= c && c <= line_max[axis][li];  // false when no hit
        }
        if (in) rv.united[idx] = 1;
      }
    }
  }
  return rv;
}

double ReferenceMeshIoU(const ReferenceVoxels& a, const ReferenceVoxels& b, bool exact_pitch) {
  if (a.SurfaceCount() == 0 || b.SurfaceCount() == 0) return 0.0;
  // Number of cells of `x` whose point is filled in `y`.
  const auto hits = [exact_pitch](const ReferenceVoxels& x, const ReferenceVoxels& y,
                                  std::size_t* n) {
    std::size_t h = 0, count = 0;
    for (int k = 0; k < x.d; ++k) {
      for (int j = 0; j < x.d; ++j) {
        for (int i = 0; i < x.d; ++i) {
          if (!x.united[x.Index(i, j, k)]) continue;
          ++count;
          const bool filled = exact_pitch ? y.IsFilledExact(x.CellCentre(i, j, k))
                                          : y.IsFilled(x.CellPoint(i, j, k));
          if (filled) ++h;
        }
      }
    }
    *n = count;
    return h;
  };
  std::size_t na = 0, nb = 0;
  const std::size_t ha = hits(a, b, &na);
  const std::size_t hb = hits(b, a, &nb);
  if (ha == 0 || hb == 0) return 0.0;
  const double a1 = static_cast<double>(ha) / static_cast<double>(na);
  const double a2 = static_cast<double>(hb) / static_cast<double>(nb);
  return a1 * a2 / (a1 + a2 - a1 * a2);
}

}  // namespace dimr::geometry
