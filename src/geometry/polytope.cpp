#include "dimr/geometry/polytope.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

enum : signed char { kIn = -1, kOn = 0, kOut = 1 };

// A polyhedron under construction: vertex positions and faces as vertex cycles stored flat
// (face f is idx[start[f]] .. idx[start[f + 1] - 1], counter-clockwise seen from outside).
struct Poly {
  std::vector<Vec3> verts;
  std::vector<int> idx;
  std::vector<int> start{0};
  std::vector<int> plane;

  int num_faces() const { return static_cast<int>(plane.size()); }
  void Clear() {
    idx.clear();
    start.assign(1, 0);
    plane.clear();
  }
  void AddFace(std::initializer_list<int> cycle, int p) {
    idx.insert(idx.end(), cycle);
    start.push_back(static_cast<int>(idx.size()));
    plane.push_back(p);
  }
};

struct EdgeVertex {
  int a, b;  // edge endpoints, a < b
  int v;     // index of the intersection vertex
};

// Clips `cur` by the plane n.x + d <= 0 (n unit length) into `next`. Returns
//   0: nothing is cut off (redundant plane; box faces lying on the plane are relabelled),
//   1: clipped, `next` holds the result (vertices compacted),
//  -1: nothing remains strictly inside: the result is empty or flat,
//   2: the cap could not be closed consistently (the plane is then skipped; never observed,
//      kept as a safety net so that the output stays watertight).
class Clipper {
 public:
  int Clip(Poly& cur, Poly& next, const Vec3& n, double d, double tol, int plane_id) {
    const int nv = static_cast<int>(cur.verts.size());
    s_.resize(nv);
    cls_.resize(nv);
    bool any_out = false, any_in = false;
    for (int v = 0; v < nv; ++v) {
      const double sv = n.dot(cur.verts[v]) + d;
      s_[v] = sv;
      const signed char c = sv > tol ? kOut : (sv < -tol ? kIn : kOn);
      cls_[v] = c;
      any_out |= c == kOut;
      any_in |= c == kIn;
    }
    if (!any_out) {
      for (int f = 0; f < cur.num_faces(); ++f) {
        if (cur.plane[f] != -1) continue;
        bool all_on = true;
        for (int k = cur.start[f]; k < cur.start[f + 1] && all_on; ++k) {
          all_on = cls_[cur.idx[k]] == kOn;
        }
        if (all_on) cur.plane[f] = plane_id;
      }
      return 0;
    }
    if (!any_in) return -1;

    next.Clear();
    next.verts.assign(cur.verts.begin(), cur.verts.end());
    on_plane_.resize(nv);
    for (int v = 0; v < nv; ++v) on_plane_[v] = cls_[v] == kOn;
    cache_.clear();
    cand_.clear();
    for (int f = 0; f < cur.num_faces(); ++f) {
      const int b = cur.start[f], e = cur.start[f + 1];
      bool has_in = false;
      for (int k = b; k < e && !has_in; ++k) has_in = cls_[cur.idx[k]] == kIn;
      if (!has_in) continue;  // entirely outside or on the plane: replaced by the cap
      const int fb = static_cast<int>(next.idx.size());
      for (int k = b; k < e; ++k) {
        const int u = cur.idx[k];
        const int w = cur.idx[k + 1 < e ? k + 1 : b];
        if (cls_[u] != kOut) next.idx.push_back(u);
        if (cls_[u] * cls_[w] == -1) next.idx.push_back(EdgePoint(u, w, next.verts));
      }
      const int fe = static_cast<int>(next.idx.size());
      next.start.push_back(fe);
      next.plane.push_back(cur.plane[f]);
      // Edges of the clipped face lying in the plane: the cap's boundary is among them.
      for (int k = fb; k < fe; ++k) {
        const int x = next.idx[k];
        const int y = next.idx[k + 1 < fe ? k + 1 : fb];
        if (on_plane_[x] && on_plane_[y]) cand_.emplace_back(x, y);
      }
    }
    // The cap consists of the in-plane edges whose twin edge no longer exists (their
    // neighbouring face was removed or cut), reversed.
    cap_.clear();
    for (const auto& c : cand_) {
      bool twin = false;
      for (const auto& o : cand_) {
        if (o.first == c.second && o.second == c.first) {
          twin = true;
          break;
        }
      }
      if (!twin) cap_.emplace_back(c.second, c.first);
    }
    // (No cap edge at all: only vertices lying on straight edges were cut off; the faces
    // around them already close up.)
    // Chain the cap edges into loops. A walk that comes back to one of its own vertices
    // (a pinch, possible only through tolerance decisions) is split there, so that every cap
    // face is a simple polygon.
    used_.assign(cap_.size(), 0);
    std::size_t remaining = cap_.size();
    while (remaining > 0) {
      std::size_t first = 0;
      while (used_[first]) ++first;
      used_[first] = 1;
      --remaining;
      walk_.assign(1, cap_[first].first);
      int cur_v = cap_[first].second;
      while (true) {
        if (cur_v == walk_[0]) {
          if (!EmitLoop(next, 0, plane_id)) return 2;
          break;
        }
        const auto it = std::find(walk_.begin() + 1, walk_.end(), cur_v);
        if (it != walk_.end()) {
          const std::size_t j = static_cast<std::size_t>(it - walk_.begin());
          if (!EmitLoop(next, j, plane_id)) return 2;
          walk_.resize(j + 1);  // cur_v stays as the last vertex of the walk
        } else {
          walk_.push_back(cur_v);
        }
        std::size_t j = 0;
        while (j < cap_.size() && (used_[j] || cap_[j].first != cur_v)) ++j;
        if (j == cap_.size()) return 2;  // open chain: inconsistent topology
        used_[j] = 1;
        --remaining;
        cur_v = cap_[j].second;
      }
    }
    Compact(next);
    return 1;
  }

 private:
  // The intersection of edge (u, w) with the plane (u and w strictly on opposite sides),
  // created once per edge and shared by both faces of the edge.
  int EdgePoint(int u, int w, std::vector<Vec3>& verts) {
    const int a = std::min(u, w), b = std::max(u, w);
    for (const EdgeVertex& ev : cache_) {
      if (ev.a == a && ev.b == b) return ev.v;
    }
    const double t = s_[a] / (s_[a] - s_[b]);  // in (0, 1): |s| > tol on both sides
    const Vec3 p = verts[a] + t * (verts[b] - verts[a]);
    const int v = static_cast<int>(verts.size());
    verts.push_back(p);
    on_plane_.push_back(1);
    cache_.push_back({a, b, v});
    return v;
  }

  // Appends walk_[from..] as a cap face; false if it has fewer than 3 vertices.
  bool EmitLoop(Poly& next, std::size_t from, int plane_id) {
    if (walk_.size() - from < 3) return false;
    next.idx.insert(next.idx.end(), walk_.begin() + from, walk_.end());
    next.start.push_back(static_cast<int>(next.idx.size()));
    next.plane.push_back(plane_id);
    return true;
  }

  // Drops unreferenced vertices and renumbers the faces.
  void Compact(Poly& p) {
    remap_.assign(p.verts.size(), -1);
    int n = 0;
    for (int v : p.idx) {
      if (remap_[v] < 0) remap_[v] = n++;
    }
    tmp_.resize(n);
    for (std::size_t v = 0; v < p.verts.size(); ++v) {
      if (remap_[v] >= 0) tmp_[remap_[v]] = p.verts[v];
    }
    p.verts.swap(tmp_);
    for (int& v : p.idx) v = remap_[v];
  }

  std::vector<double> s_;
  std::vector<signed char> cls_;
  std::vector<char> on_plane_;
  std::vector<EdgeVertex> cache_;
  std::vector<std::pair<int, int>> cand_, cap_;
  std::vector<char> used_;
  std::vector<int> walk_;
  std::vector<int> remap_;
  std::vector<Vec3> tmp_;
};

// Per-thread scratch buffers: the decoder calls IntersectHalfSpaces hundreds of times per
// object, and reusing their capacity removes nearly all allocations from the clipping loop.
struct Scratch {
  Poly a, b;
  Clipper clipper;
};

// Out of line on purpose: inside a shared library every use of a thread_local address is a
// __tls_get_addr call, and GCC re-materialises the address at each use after inlining.
__attribute__((noinline)) Scratch& ThreadScratch() {
  thread_local Scratch scratch;
  return scratch;
}

}  // namespace

double Polytope::Volume() const {
  if (faces.empty() || vertices.empty()) return 0.0;
  Vec3 ref = Vec3::Zero();
  for (const Vec3& v : vertices) ref += v;
  ref /= static_cast<double>(vertices.size());
  double six_vol = 0.0;
  for (const auto& f : faces) {
    if (f.size() < 3) continue;
    const Vec3 a = vertices[f[0]] - ref;
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      six_vol += a.dot((vertices[f[k]] - ref).cross(vertices[f[k + 1]] - ref));
    }
  }
  return six_vol / 6.0;
}

TriangleMesh Polytope::ToMesh() const {
  TriangleMesh m;
  m.vertices = vertices;
  for (const auto& f : faces) {
    for (std::size_t k = 1; k + 1 < f.size(); ++k) m.faces.emplace_back(f[0], f[k], f[k + 1]);
  }
  return m;
}

Polytope IntersectHalfSpaces(const std::vector<HalfSpace>& planes, const PolytopeOptions& options) {
  const AABB& box = options.bounds;
  if (!box.min.allFinite() || !box.max.allFinite()) {
    throw InvalidArgument("IntersectHalfSpaces: options.bounds is not finite");
  }
  if (box.Empty()) {
    throw InvalidArgument("IntersectHalfSpaces: options.bounds is empty (min > max)");
  }
  if (!(options.eps >= 0.0) || !std::isfinite(options.eps)) {
    throw InvalidArgument("IntersectHalfSpaces: options.eps must be finite and >= 0, got " +
                          std::to_string(options.eps));
  }
  for (std::size_t i = 0; i < planes.size(); ++i) {
    if (!planes[i].normal.allFinite() || !std::isfinite(planes[i].offset)) {
      throw InvalidArgument("IntersectHalfSpaces: half-space " + std::to_string(i) +
                            " is not finite");
    }
  }
  Polytope out;
  if (!((box.max - box.min).minCoeff() > 0.0)) return out;  // flat bounds: zero volume
  // Rounding errors of n.x + d grow with the magnitude of the coordinates.
  const double scale = std::max(box.min.cwiseAbs().maxCoeff(), box.max.cwiseAbs().maxCoeff());
  const double tol = options.eps * scale;

  Scratch& scratch = ThreadScratch();
  Clipper& clipper = scratch.clipper;
  Poly* cur_p = &scratch.a;
  Poly* next_p = &scratch.b;
  Poly& box_poly = *cur_p;
  box_poly.Clear();
  box_poly.verts.clear();
  for (int i = 0; i < 8; ++i) {
    box_poly.verts.emplace_back(i & 1 ? box.max.x() : box.min.x(),
                                i & 2 ? box.max.y() : box.min.y(),
                                i & 4 ? box.max.z() : box.min.z());
  }
  box_poly.AddFace({0, 2, 3, 1}, -1);  // z = min
  box_poly.AddFace({4, 5, 7, 6}, -1);  // z = max
  box_poly.AddFace({0, 1, 5, 4}, -1);  // y = min
  box_poly.AddFace({2, 6, 7, 3}, -1);  // y = max
  box_poly.AddFace({0, 4, 6, 2}, -1);  // x = min
  box_poly.AddFace({1, 3, 7, 5}, -1);  // x = max

  Vec3 lo = box.min, hi = box.max;  // bounding box of the current polytope's vertices
  for (std::size_t i = 0; i < planes.size(); ++i) {
    Vec3 n = planes[i].normal;
    double d = planes[i].offset;
    // Normalise (pre-scaling by the largest component keeps tiny or huge normals exact
    // enough and avoids under/overflow in the norm).
    const double m = n.cwiseAbs().maxCoeff();
    if (m == 0.0) {
      if (d > 0.0) return out;  // 0 . x + d <= 0 holds nowhere
      continue;                 // ... or everywhere
    }
    n /= m;
    d /= m;
    const double len = n.norm();
    n /= len;
    d /= len;
    // A plane that keeps the whole bounding box of the current polytope strictly inside
    // (beyond the tolerance and the rounding of n.x + d) classifies every vertex as inside:
    // Clip would cut nothing and relabel nothing. Most planes of a BSP convex are such.
    double reach = d;
    for (int a = 0; a < 3; ++a) reach += std::max(n[a] * lo[a], n[a] * hi[a]);
    if (reach < -tol - 1e-12 * (scale + std::abs(d))) continue;
    const int r = clipper.Clip(*cur_p, *next_p, n, d, tol, static_cast<int>(i));
    if (r == -1) return out;
    if (r == 1) {
      std::swap(cur_p, next_p);
      lo = hi = cur_p->verts[0];
      for (const Vec3& v : cur_p->verts) {
        lo = lo.cwiseMin(v);
        hi = hi.cwiseMax(v);
      }
    }
  }

  const Poly& cur = *cur_p;
  out.vertices.assign(cur.verts.begin(), cur.verts.end());
  out.faces.reserve(cur.num_faces());
  for (int f = 0; f < cur.num_faces(); ++f) {
    out.faces.emplace_back(cur.idx.begin() + cur.start[f], cur.idx.begin() + cur.start[f + 1]);
  }
  out.face_plane.assign(cur.plane.begin(), cur.plane.end());
  if (out.faces.size() < 4 || !(out.Volume() > 0.0)) return Polytope();
  return out;
}

}  // namespace dimr::geometry
