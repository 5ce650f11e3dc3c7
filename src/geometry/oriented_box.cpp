// 7-DoF oriented boxes and exact box IoU (bird's-eye convex polygon clipping x height overlap).
#include "dimr/geometry/oriented_box.h"

#include <algorithm>
#include <cmath>

namespace dimr::geometry {
namespace {

using Vec2 = Eigen::Vector2d;

double Cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// Signed shoelace area (positive for counter-clockwise polygons).
double SignedArea(const std::vector<Vec2>& p) {
  double a = 0.0;
  for (std::size_t i = 0, n = p.size(); i < n; ++i) a += Cross2(p[i], p[(i + 1) % n]);
  return 0.5 * a;
}

// Bottom-face corner signs, counter-clockwise from (-x, -y).
constexpr double kSignX[4] = {-1, 1, 1, -1};
constexpr double kSignY[4] = {-1, -1, 1, 1};

std::vector<Vec2> Footprint(const OrientedBox& b) {
  const double c = std::cos(b.heading), s = std::sin(b.heading);
  std::vector<Vec2> out(4);
  for (int i = 0; i < 4; ++i) {
    const double lx = 0.5 * b.size.x() * kSignX[i], ly = 0.5 * b.size.y() * kSignY[i];
    out[i] = Vec2(b.center.x() + c * lx - s * ly, b.center.y() + s * lx + c * ly);
  }
  return out;
}

}  // namespace

Eigen::Matrix3d OrientedBox::Rotation() const {
  return Eigen::AngleAxisd(heading, Vec3::UnitZ()).toRotationMatrix();
}

std::array<Vec3, 8> OrientedBox::Corners() const {
  const Eigen::Matrix3d R = Rotation();
  const Vec3 h = 0.5 * size;
  std::array<Vec3, 8> out;
  for (int i = 0; i < 8; ++i) {
    const double sz = i < 4 ? -1.0 : 1.0;
    const Vec3 local(kSignX[i % 4] * h.x(), kSignY[i % 4] * h.y(), sz * h.z());
    out[i] = center + R * local;
  }
  return out;
}

bool OrientedBox::Contains(const Vec3& p, double margin) const {
  const Vec3 local = Rotation().transpose() * (p - center);
  return (local.cwiseAbs().array() <= (0.5 * size.array() + margin)).all();
}

AABB OrientedBox::Bounds() const {
  AABB b;
  for (const Vec3& c : Corners()) b.Extend(c);
  return b;
}

TriangleMesh OrientedBox::ToMesh() const {
  TriangleMesh m;
  const std::array<Vec3, 8> c = Corners();
  m.vertices.assign(c.begin(), c.end());
  // Corners 0-3 bottom (ccw seen from above), 4-7 top. Outward orientation.
  const int f[12][3] = {
      {0, 2, 1}, {0, 3, 2},  // bottom (-z)
      {4, 5, 6}, {4, 6, 7},  // top (+z)
      {0, 1, 5}, {0, 5, 4},  // -y side
      {1, 2, 6}, {1, 6, 5},  // +x side
      {2, 3, 7}, {2, 7, 6},  // +y side
      {3, 0, 4}, {3, 4, 7},  // -x side
  };
  for (const auto& t : f) m.faces.emplace_back(t[0], t[1], t[2]);
  return m;
}

double ConvexPolygonIntersectionArea(const std::vector<Eigen::Vector2d>& a,
                                     const std::vector<Eigen::Vector2d>& b) {
  if (a.size() < 3 || b.size() < 3) return 0.0;
  std::vector<Vec2> subject = a, clip = b;
  // Accept either orientation: normalise both to counter-clockwise.
  if (SignedArea(subject) < 0) std::reverse(subject.begin(), subject.end());
  if (SignedArea(clip) < 0) std::reverse(clip.begin(), clip.end());
  // Sutherland-Hodgman: clip `subject` by each half-plane left of a clip edge.
  std::vector<Vec2> input;
  for (std::size_t e = 0, m = clip.size(); e < m && !subject.empty(); ++e) {
    const Vec2& p = clip[e];
    const Vec2 dir = clip[(e + 1) % m] - p;
    input.swap(subject);
    subject.clear();
    const std::size_t n = input.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2& cur = input[i];
      const Vec2& nxt = input[(i + 1) % n];
      const double dc = Cross2(dir, cur - p), dn = Cross2(dir, nxt - p);
      if (dc >= 0) subject.push_back(cur);
      if ((dc >= 0) != (dn >= 0)) {
        const double t = dc / (dc - dn);
        subject.push_back(cur + t * (nxt - cur));
      }
    }
  }
  if (subject.size() < 3) return 0.0;
  return std::max(0.0, SignedArea(subject));
}

double BoxIoU(const OrientedBox& a, const OrientedBox& b) {
  const double va = a.Volume(), vb = b.Volume();
  if (!(va > 0.0) || !(vb > 0.0)) return 0.0;
  const double zlo = std::max(a.center.z() - 0.5 * a.size.z(), b.center.z() - 0.5 * b.size.z());
  const double zhi = std::min(a.center.z() + 0.5 * a.size.z(), b.center.z() + 0.5 * b.size.z());
  const double h = zhi - zlo;
  if (!(h > 0.0)) return 0.0;
  const double area = ConvexPolygonIntersectionArea(Footprint(a), Footprint(b));
  const double inter = area * h;
  const double uni = va + vb - inter;
  if (!(uni > 0.0)) return 0.0;
  return std::clamp(inter / uni, 0.0, 1.0);
}

double AabbIoU(const AABB& a, const AABB& b) {
  if (a.Empty() || b.Empty()) return 0.0;
  const Vec3 lo = a.min.cwiseMax(b.min), hi = a.max.cwiseMin(b.max);
  if ((hi.array() <= lo.array()).any()) return 0.0;
  const Vec3 e = hi - lo;
  const double inter = e.x() * e.y() * e.z();
  const double uni = a.Volume() + b.Volume() - inter;
  if (!(uni > 0.0)) return 0.0;
  return inter / uni;
}

}  // namespace dimr::geometry
