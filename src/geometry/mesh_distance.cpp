#include "dimr/geometry/mesh_distance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "dimr/core/parallel.h"
#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kLeafSize = 4;
constexpr int kBins = 16;

// Closest point on segment [a, b] (a point if a == b).
inline Vec3 ClosestOnSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (!(len2 > 0.0)) return a;
  const double t = (p - a).dot(ab) / len2;
  if (t <= 0.0) return a;
  if (t >= 1.0) return b;
  return a + t * ab;
}

// Squared distance from p to the box (0 inside).
inline double BoxDistance2(const AABB& box, const Vec3& p) {
  double d2 = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double lo = box.min[k] - p[k];
    const double hi = p[k] - box.max[k];
    const double d = std::max(0.0, std::max(lo, hi));
    d2 += d * d;
  }
  return d2;
}

// A triangle is treated as degenerate (collapsed to a segment or a point, or so flat that its
// normal is meaningless: sin(angle at a) < 1e-12) when this holds.
inline bool IsDegenerate(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  return !(ab.cross(ac).squaredNorm() > 1e-24 * ab.squaredNorm() * ac.squaredNorm());
}

// Degenerate triangle: the closest point of the union of its edges.
inline Vec3 ClosestOnDegenerate(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 q0 = ClosestOnSegment(p, a, b);
  const Vec3 q1 = ClosestOnSegment(p, b, c);
  const Vec3 q2 = ClosestOnSegment(p, c, a);
  const double d0 = (q0 - p).squaredNorm();
  const double d1 = (q1 - p).squaredNorm();
  const double d2 = (q2 - p).squaredNorm();
  if (d0 <= d1 && d0 <= d2) return q0;
  return d1 <= d2 ? q1 : q2;
}

// Proper triangle: Voronoi regions of the vertices, the edges and the face.
inline Vec3 ClosestOnProper(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;  // vertex a
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;  // vertex b
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {  // edge ab
    const double den = d1 - d3;
    return den > 0.0 ? Vec3(a + (d1 / den) * ab) : a;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;  // vertex c
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {  // edge ac
    const double den = d2 - d6;
    return den > 0.0 ? Vec3(a + (d2 / den) * ac) : a;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {  // edge bc
    const double den = (d4 - d3) + (d5 - d6);
    return den > 0.0 ? Vec3(b + ((d4 - d3) / den) * (c - b)) : b;
  }
  // Face interior: va, vb, vc > 0 here.
  const double inv = 1.0 / (va + vb + vc);
  return a + ab * (vb * inv) + ac * (vc * inv);
}

}  // namespace

Vec3 ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return IsDegenerate(a, b, c) ? ClosestOnDegenerate(p, a, b, c) : ClosestOnProper(p, a, b, c);
}

MeshDistance::MeshDistance(const TriangleMesh& mesh) {
  const std::size_t nv = mesh.vertices.size();
  tris_.reserve(mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Vec3i& face = mesh.faces[f];
    for (int k = 0; k < 3; ++k) {
      if (face[k] < 0 || static_cast<std::size_t>(face[k]) >= nv) {
        throw InvalidArgument("MeshDistance: face " + std::to_string(f) + " has vertex index " +
                              std::to_string(face[k]) + " out of range [0, " + std::to_string(nv) +
                              ")");
      }
      if (!mesh.vertices[face[k]].allFinite()) {
        throw InvalidArgument("MeshDistance: vertex " + std::to_string(face[k]) + " (face " +
                              std::to_string(f) + ") is not finite");
      }
    }
    const Vec3& a = mesh.vertices[face[0]];
    const Vec3& b = mesh.vertices[face[1]];
    const Vec3& c = mesh.vertices[face[2]];
    tris_.push_back(Tri{a, b, c, static_cast<int>(f), IsDegenerate(a, b, c)});
  }
  if (tris_.empty()) return;
  nodes_.reserve(2 * tris_.size() / kLeafSize + 2);
  Build(0, static_cast<int>(tris_.size()));
}

int MeshDistance::Build(int begin, int end) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  AABB box, cbox;
  for (int i = begin; i < end; ++i) {
    const Tri& t = tris_[i];
    box.Extend(t.a);
    box.Extend(t.b);
    box.Extend(t.c);
    cbox.Extend(Vec3((t.a + t.b + t.c) / 3.0));
  }
  nodes_[id].box = box;
  const int count = end - begin;
  if (count <= kLeafSize) {
    nodes_[id].begin = begin;
    nodes_[id].end = end;
    return id;
  }
  const Vec3 ext = cbox.max - cbox.min;
  int axis = 0;
  if (ext.y() > ext[axis]) axis = 1;
  if (ext.z() > ext[axis]) axis = 2;
  auto centroid = [axis](const Tri& t) { return (t.a[axis] + t.b[axis] + t.c[axis]) / 3.0; };
  int mid = begin + count / 2;
  if (ext[axis] > 0.0) {
    // Binned surface-area heuristic along the longest centroid axis.
    const double scale = kBins / ext[axis];
    const double lo = cbox.min[axis];
    auto bin_of = [&](const Tri& t) {
      return std::min(kBins - 1, static_cast<int>((centroid(t) - lo) * scale));
    };
    std::array<AABB, kBins> bin_box;
    std::array<int, kBins> bin_count{};
    for (int i = begin; i < end; ++i) {
      const Tri& t = tris_[i];
      const int b = bin_of(t);
      ++bin_count[b];
      bin_box[b].Extend(t.a);
      bin_box[b].Extend(t.b);
      bin_box[b].Extend(t.c);
    }
    auto area = [](const AABB& bb) {
      if (bb.Empty()) return 0.0;
      const Vec3 e = bb.max - bb.min;
      return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
    };
    std::array<double, kBins> right_cost{};
    AABB acc;
    int n = 0;
    for (int b = kBins - 1; b > 0; --b) {
      acc.Extend(bin_box[b]);
      n += bin_count[b];
      right_cost[b] = area(acc) * n;
    }
    acc = AABB();
    n = 0;
    double best = kInf;
    int best_split = -1;
    for (int b = 0; b < kBins - 1; ++b) {
      acc.Extend(bin_box[b]);
      n += bin_count[b];
      if (n == 0 || n == count) continue;
      const double cost = area(acc) * n + right_cost[b + 1];
      if (cost < best) {
        best = cost;
        best_split = b;
      }
    }
    if (best_split >= 0) {
      Tri* m = std::partition(tris_.data() + begin, tris_.data() + end,
                              [&](const Tri& t) { return bin_of(t) <= best_split; });
      mid = static_cast<int>(m - tris_.data());
    } else {
      std::nth_element(tris_.begin() + begin, tris_.begin() + mid, tris_.begin() + end,
                       [&](const Tri& x, const Tri& y) { return centroid(x) < centroid(y); });
    }
  }
  // (Identical centroids: any half split is as good as another.)
  const int left = Build(begin, mid);
  const int right = Build(mid, end);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

ClosestPoint MeshDistance::Query(const Vec3& p) const {
  ClosestPoint out;
  if (tris_.empty()) {
    out.point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    out.distance = kInf;
    out.face = -1;
    return out;
  }
  if (!p.allFinite()) {
    out.point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    out.distance = std::numeric_limits<double>::quiet_NaN();
    out.face = -1;
    return out;
  }
  struct Entry {
    int node;
    double d2;
  };
  // Depth-first branch and bound, nearer child first; the depth of the SAH tree is bounded by
  // the triangle count, so the stack grows on the heap only for pathological inputs.
  Entry local[128];
  std::vector<Entry> overflow;
  int top = 0;
  auto push = [&](Entry e) {
    if (top < 128) {
      local[top++] = e;
    } else {
      overflow.push_back(e);
    }
  };
  auto pop = [&]() {
    if (!overflow.empty()) {
      const Entry e = overflow.back();
      overflow.pop_back();
      return e;
    }
    return local[--top];
  };
  double best = kInf;
  int best_tri = -1;
  Vec3 best_point = p;
  push({0, BoxDistance2(nodes_[0].box, p)});
  while (top > 0 || !overflow.empty()) {
    const Entry e = pop();
    if (e.d2 >= best) continue;
    const Node& node = nodes_[e.node];
    if (node.left < 0) {
      for (int i = node.begin; i < node.end; ++i) {
        const Tri& t = tris_[i];
        const Vec3 q = t.degenerate ? ClosestOnDegenerate(p, t.a, t.b, t.c)
                                    : ClosestOnProper(p, t.a, t.b, t.c);
        const double d2 = (q - p).squaredNorm();
        if (d2 < best) {
          best = d2;
          best_tri = i;
          best_point = q;
        }
      }
      continue;
    }
    const double dl = BoxDistance2(nodes_[node.left].box, p);
    const double dr = BoxDistance2(nodes_[node.right].box, p);
    if (dl <= dr) {
      if (dr < best) push({node.right, dr});
      if (dl < best) push({node.left, dl});
    } else {
      if (dl < best) push({node.left, dl});
      if (dr < best) push({node.right, dr});
    }
  }
  out.point = best_point;
  out.distance = std::sqrt(best);
  out.face = tris_[best_tri].face;
  return out;
}

std::vector<double> MeshDistance::Distances(const std::vector<Vec3>& points) const {
  std::vector<double> out(points.size(), kInf);
  if (tris_.empty() || points.empty()) return out;
  ParallelRanges(points.size(), 0, 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) out[i] = Query(points[i]).distance;
  });
  return out;
}

}  // namespace dimr::geometry
