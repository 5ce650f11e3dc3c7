// Mesh cleaning and quadric-error decimation on flat arrays (see mesh_simplify.h).
#include "dimr/geometry/mesh_simplify.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::geometry {
namespace {

void CheckFaces(const std::vector<Vec3i>& faces, std::size_t num_vertices, const char* where) {
  for (std::size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = faces[f][k];
      if (v < 0 || static_cast<std::size_t>(v) >= num_vertices)
        throw InvalidArgument(std::string(where) + ": face " + std::to_string(f) +
                              " has vertex index " + std::to_string(v) + " outside [0, " +
                              std::to_string(num_vertices) + ")");
    }
  }
}

// Vertex -> incident faces, compressed rows.
struct VertexFaces {
  std::vector<std::size_t> offset;  // num_vertices + 1
  std::vector<int> face;
  VertexFaces(const std::vector<Vec3i>& faces, std::size_t num_vertices)
      : offset(num_vertices + 1, 0), face(3 * faces.size()) {
    for (const Vec3i& t : faces) {
      for (int k = 0; k < 3; ++k) ++offset[t[k] + 1];
    }
    std::partial_sum(offset.begin(), offset.end(), offset.begin());
    std::vector<std::size_t> next(offset.begin(), offset.end() - 1);
    for (std::size_t f = 0; f < faces.size(); ++f) {
      for (int k = 0; k < 3; ++k) face[next[faces[f][k]]++] = static_cast<int>(f);
    }
  }
};

inline bool HasVertex(const Vec3i& t, int v) { return t[0] == v || t[1] == v || t[2] == v; }

// New index (in vertex order) of every vertex one of `faces` references, -1 for the others;
// *count = how many are referenced.
std::vector<int> RenumberReferenced(const std::vector<Vec3i>& faces, std::size_t num_vertices,
                                    int* count) {
  std::vector<int> remap(num_vertices, -1);
  for (const Vec3i& t : faces) {
    for (int k = 0; k < 3; ++k) remap[t[k]] = 0;
  }
  int next = 0;
  for (int& r : remap) {
    if (r == 0) r = next++;
  }
  *count = next;
  return remap;
}

int FindRoot(std::vector<int>* parent, int x) {
  std::vector<int>& p = *parent;
  while (p[x] != x) {
    p[x] = p[p[x]];
    x = p[x];
  }
  return x;
}

// Symmetric 3x3 A, vector b, scalar c: E(v) = v'Av + 2 b'v + c.
struct Quadric {
  double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0;
  double b0 = 0, b1 = 0, b2 = 0, c = 0;

  void AddPlane(const Vec3& n, double d, double w) {
    a00 += w * n[0] * n[0];
    a01 += w * n[0] * n[1];
    a02 += w * n[0] * n[2];
    a11 += w * n[1] * n[1];
    a12 += w * n[1] * n[2];
    a22 += w * n[2] * n[2];
    b0 += w * d * n[0];
    b1 += w * d * n[1];
    b2 += w * d * n[2];
    c += w * d * d;
  }
  Quadric& operator+=(const Quadric& o) {
    a00 += o.a00;
    a01 += o.a01;
    a02 += o.a02;
    a11 += o.a11;
    a12 += o.a12;
    a22 += o.a22;
    b0 += o.b0;
    b1 += o.b1;
    b2 += o.b2;
    c += o.c;
    return *this;
  }
  double Eval(const Vec3& v) const {
    const double x = v[0], y = v[1], z = v[2];
    const double ax = a00 * x + a01 * y + a02 * z;
    const double ay = a01 * x + a11 * y + a12 * z;
    const double az = a02 * x + a12 * y + a22 * z;
    return x * ax + y * ay + z * az + 2.0 * (b0 * x + b1 * y + b2 * z) + c;
  }
  double Determinant() const {
    return a00 * (a11 * a22 - a12 * a12) - a01 * (a01 * a22 - a12 * a02) +
           a02 * (a01 * a12 - a11 * a02);
  }
  Vec3 Minimum() const {
    Eigen::Matrix3d a;
    a << a00, a01, a02, a01, a11, a12, a02, a12, a22;
    return -a.ldlt().solve(Vec3(b0, b1, b2));
  }
};

// Plane (unit normal, offset) and area of a face; zero normal and area when degenerate.
void FacePlane(const Vec3& p0, const Vec3& p1, const Vec3& p2, Vec3* n, double* d, double* area) {
  const Vec3 cr = (p1 - p0).cross(p2 - p0);
  const double len = cr.norm();
  *area = 0.5 * len;
  if (!(len > 0)) {
    n->setZero();
    *d = 0;
    *area = 0;
    return;
  }
  *n = cr / len;
  *d = -n->dot(p0);
}

// A heap entry: 16 bytes, so that the four children of a node of the 4-ary heap share one
// cache line. The cost is rounded to float (ties are broken by the indices); an entry is
// current when both endpoints are alive, their 16-bit stamps match, and the recomputed cost
// rounds to the stored one (the stamp check alone could wrap after 65536 collapses into one
// vertex; the cost check is Open3D's own criterion).
struct Candidate {
  float cost;
  int a, b;  // a < b
  std::uint16_t stamp_a, stamp_b;
};
static_assert(sizeof(Candidate) == 16, "Candidate must stay 16 bytes");

// Cheaper first, then lower indices: a total order, so the collapse sequence does not depend
// on the heap's internals.
inline bool Before(const Candidate& x, const Candidate& y) {
  if (x.cost != y.cost) return x.cost < y.cost;
  if (x.a != y.a) return x.a < y.a;
  return x.b < y.b;
}

// 4-ary min-heap. The binary heap of std::push_heap / pop_heap (24-byte entries) spent ~1 us
// per operation in cache misses on a room's ~10^7 entries; four children per node halve the
// depth and read one line per level.
class CandidateHeap {
 public:
  void Reserve(std::size_t n) { h_.reserve(n); }
  void PushUnordered(const Candidate& c) { h_.push_back(c); }
  void Build() {
    if (h_.size() < 2) return;
    for (std::size_t i = (h_.size() - 2) / 4 + 1; i-- > 0;) SiftDown(i, h_[i]);
  }
  bool empty() const { return h_.empty(); }
  void Push(const Candidate& c) {
    std::size_t i = h_.size();
    h_.push_back(c);
    while (i > 0) {
      const std::size_t p = (i - 1) / 4;
      if (!Before(c, h_[p])) break;
      h_[i] = h_[p];
      i = p;
    }
    h_[i] = c;
  }
  std::size_t size() const { return h_.size(); }
  // Drops every entry `dead` says is outdated and re-heapifies (linear).
  template <typename Dead>
  std::size_t Purge(Dead dead) {
    const std::size_t n = h_.size();
    h_.erase(std::remove_if(h_.begin(), h_.end(), dead), h_.end());
    Build();
    return n - h_.size();
  }
  Candidate Pop() {
    const Candidate top = h_[0];
    const Candidate last = h_.back();
    h_.pop_back();
    if (!h_.empty()) SiftDown(0, last);
    return top;
  }

 private:
  void SiftDown(std::size_t i, const Candidate c) {
    const std::size_t n = h_.size();
    for (;;) {
      const std::size_t first = 4 * i + 1;
      if (first >= n) break;
      std::size_t best = first;
      const std::size_t end = std::min(first + 4, n);
      // The grandchildren's lines, one level ahead: four misses in flight instead of one.
      for (std::size_t k = first; k < end && 4 * k + 1 < n; ++k) __builtin_prefetch(&h_[4 * k + 1]);
      for (std::size_t k = first + 1; k < end; ++k) {
        if (Before(h_[k], h_[best])) best = k;
      }
      if (!Before(h_[best], c)) break;
      h_[i] = h_[best];
      i = best;
    }
    h_[i] = c;
  }
  std::vector<Candidate> h_;
};

}  // namespace

FaceComponents EdgeConnectedComponents(const std::vector<Vec3i>& faces, std::size_t num_vertices) {
  CheckFaces(faces, num_vertices, "EdgeConnectedComponents");
  const VertexFaces vf(faces, num_vertices);
  std::vector<int> parent(faces.size());
  std::iota(parent.begin(), parent.end(), 0);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const Vec3i& t = faces[f];
    for (int k = 0; k < 3; ++k) {
      const int u = t[k], v = t[(k + 1) % 3];
      if (u == v) continue;
      for (std::size_t i = vf.offset[u]; i < vf.offset[u + 1]; ++i) {
        const int g = vf.face[i];
        if (g <= static_cast<int>(f) || !HasVertex(faces[g], v)) continue;
        const int ra = FindRoot(&parent, static_cast<int>(f)), rb = FindRoot(&parent, g);
        if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
      }
    }
  }
  FaceComponents out;
  out.component.assign(faces.size(), -1);
  std::vector<int> id_of_root(faces.size(), -1);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const int r = FindRoot(&parent, static_cast<int>(f));
    if (id_of_root[r] < 0) {
      id_of_root[r] = static_cast<int>(out.size.size());
      out.size.push_back(0);
    }
    out.component[f] = id_of_root[r];
    ++out.size[id_of_root[r]];
  }
  return out;
}

CleanStats RemoveSmallComponents(TriangleMesh* mesh, int min_component_faces) {
  if (mesh == nullptr) throw InvalidArgument("RemoveSmallComponents: null mesh");
  if (min_component_faces < 0)
    throw InvalidArgument("RemoveSmallComponents: min_component_faces must be >= 0, got " +
                          std::to_string(min_component_faces));
  const std::size_t nv = mesh->vertices.size();
  CheckFaces(mesh->faces, nv, "RemoveSmallComponents");
  CleanStats stats;
  std::vector<char> keep_face(mesh->faces.size(), 1);
  if (min_component_faces > 0) {
    const FaceComponents comps = EdgeConnectedComponents(mesh->faces, nv);
    const auto min = static_cast<std::size_t>(min_component_faces);
    for (std::size_t s : comps.size) stats.removed_components += s < min ? 1 : 0;
    for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
      if (comps.size[comps.component[f]] < min) keep_face[f] = 0;
    }
  }
  std::vector<Vec3i> faces;
  faces.reserve(mesh->faces.size());
  for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
    const Vec3i& t = mesh->faces[f];
    if (!keep_face[f] || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    faces.push_back(t);
  }
  stats.removed_faces = mesh->faces.size() - faces.size();
  int next = 0;
  const std::vector<int> remap = RenumberReferenced(faces, nv, &next);
  stats.removed_vertices = nv - static_cast<std::size_t>(next);
  for (Vec3i& t : faces) {
    for (int k = 0; k < 3; ++k) t[k] = remap[t[k]];
  }
  auto compact = [&](auto* values) {
    if (values->size() != nv) return;
    for (std::size_t v = 0; v < nv; ++v) {
      if (remap[v] >= 0) (*values)[remap[v]] = (*values)[v];
    }
    values->resize(next);
  };
  compact(&mesh->vertices);
  compact(&mesh->vertex_colors);
  compact(&mesh->vertex_normals);
  for (auto& attr : mesh->attributes) compact(&attr.values);
  mesh->faces = std::move(faces);
  return stats;
}

void QuadricDecimationConfig::Validate() const {
  auto fail = [](const std::string& m) { throw InvalidArgument("QuadricDecimationConfig: " + m); };
  if (!(max_error >= 0)) fail("max_error must be >= 0 (inf = no limit)");
  if (!(boundary_weight >= 0 && std::isfinite(boundary_weight)))
    fail("boundary_weight must be finite and >= 0");
  if (!(invertible_determinant >= 0 && std::isfinite(invertible_determinant)))
    fail("invertible_determinant must be finite and >= 0");
}

TriangleMesh DecimateQuadric(const std::vector<Vec3>& vertices, const std::vector<Vec3i>& faces,
                             const QuadricDecimationConfig& config, DecimationStats* stats_out) {
  config.Validate();
  const std::size_t nv = vertices.size();
  CheckFaces(faces, nv, "DecimateQuadric");
  for (std::size_t v = 0; v < nv; ++v) {
    if (!vertices[v].allFinite())
      throw InvalidArgument("DecimateQuadric: vertex " + std::to_string(v) + " is not finite");
  }
  if (faces.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
      nv > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw InvalidArgument("DecimateQuadric: more than 2^31 faces or vertices");
  DecimationStats stats;
  std::vector<Vec3> pos = vertices;
  std::vector<Vec3i> tri = faces;
  std::vector<char> face_dead(tri.size(), 0), vertex_dead(nv, 0);
  std::vector<std::uint16_t> stamp(nv, 0);
  std::vector<std::vector<int>> around(nv);
  {
    const VertexFaces vf(tri, nv);
    for (std::size_t v = 0; v < nv; ++v)
      around[v].assign(vf.face.begin() + vf.offset[v], vf.face.begin() + vf.offset[v + 1]);
  }
  // Vertex quadrics: face planes weighted by area, then boundary planes.
  std::vector<Quadric> quad(nv);
  std::vector<Vec3> normal(tri.size());
  std::vector<double> area(tri.size());
  for (std::size_t f = 0; f < tri.size(); ++f) {
    const Vec3i& t = tri[f];
    double d;
    FacePlane(pos[t[0]], pos[t[1]], pos[t[2]], &normal[f], &d, &area[f]);
    if (area[f] == 0) continue;
    for (int k = 0; k < 3; ++k) quad[t[k]].AddPlane(normal[f], d, area[f]);
  }
  if (config.boundary_weight > 0) {
    for (std::size_t f = 0; f < tri.size(); ++f) {
      if (area[f] == 0) continue;
      const Vec3i& t = tri[f];
      for (int k = 0; k < 3; ++k) {
        const int u = t[k], v = t[(k + 1) % 3];
        int shared = 0;
        for (int g : around[u]) shared += HasVertex(tri[g], v) ? 1 : 0;
        if (shared != 1) continue;
        const Vec3 side = (pos[v] - pos[u]).cross(normal[f]);
        const double len = side.norm();
        if (!(len > 0)) continue;
        const Vec3 n = side / len;
        const double d = -n.dot(pos[u]), w = area[f] * config.boundary_weight;
        quad[u].AddPlane(n, d, w);
        quad[v].AddPlane(n, d, w);
      }
    }
  }

  // Cost and position of collapsing edge (a, b).
  auto evaluate = [&](int a, int b, Vec3* best) {
    Quadric q = quad[a];
    q += quad[b];
    const double det = q.Determinant();
    if (det != 0 && std::abs(det) > config.invertible_determinant) {
      *best = q.Minimum();
      if (best->allFinite()) return q.Eval(*best);
    }
    const Vec3 mid = 0.5 * (pos[a] + pos[b]);
    const double c0 = q.Eval(pos[a]), c1 = q.Eval(pos[b]), cm = q.Eval(mid);
    const double cost = std::min(cm, std::min(c0, c1));
    *best = cost == cm ? mid : cost == c0 ? pos[a] : pos[b];
    return cost;
  };

  CandidateHeap heap;
  heap.Reserve(3 * tri.size() / 2 + 16);
  std::vector<int> neighbours;
  auto collect_neighbours = [&](int v, bool only_higher) {
    neighbours.clear();
    for (int f : around[v]) {
      if (face_dead[f]) continue;
      for (int k = 0; k < 3; ++k) {
        const int w = tri[f][k];
        if (w == v || (only_higher && w < v)) continue;
        if (std::find(neighbours.begin(), neighbours.end(), w) == neighbours.end())
          neighbours.push_back(w);
      }
    }
  };
  auto candidate = [&](int u, int w) {
    const int a = std::min(u, w), b = std::max(u, w);
    Vec3 best;
    const double cost = evaluate(a, b, &best);
    return Candidate{static_cast<float>(cost), a, b, stamp[a], stamp[b]};
  };
  for (std::size_t v = 0; v < nv; ++v) {
    collect_neighbours(static_cast<int>(v), true);
    for (int w : neighbours) heap.PushUnordered(candidate(static_cast<int>(v), w));
  }
  heap.Build();

  // Would moving `moved` (of face f) to p flip f or collapse it to zero area?
  auto flips = [&](int f, int moved, const Vec3& p) {
    Vec3 c[3] = {pos[tri[f][0]], pos[tri[f][1]], pos[tri[f][2]]};
    const Vec3 before = (c[1] - c[0]).cross(c[2] - c[0]);
    for (int k = 0; k < 3; ++k) {
      if (tri[f][k] == moved) c[k] = p;
    }
    const Vec3 after = (c[1] - c[0]).cross(c[2] - c[0]);
    if (before.squaredNorm() == 0) return false;  // already degenerate: nothing to protect
    return after.squaredNorm() == 0 || before.dot(after) < 0;
  };

  std::size_t live = tri.size();
  // Outdated entries (of a dead vertex or older stamps) would each cost a full pop, a cache miss
  // per level; once they could be half the heap they are swept out in one linear pass instead.
  std::size_t outdated_bound = 0;
  auto outdated = [&](const Candidate& c) {
    return vertex_dead[c.a] || vertex_dead[c.b] || stamp[c.a] != c.stamp_a ||
           stamp[c.b] != c.stamp_b;
  };
  while (live > config.target_faces && !heap.empty()) {
    const Candidate e = heap.Pop();
    const int a = e.a, b = e.b;
    if (outdated(e)) {
      ++stats.stale_entries;
      continue;
    }
    Vec3 target;
    const double cost = evaluate(a, b, &target);
    if (static_cast<float>(cost) != e.cost) {
      ++stats.stale_entries;
      continue;
    }
    if (cost > config.max_error) break;
    bool reject = false;
    for (const int v : {a, b}) {
      for (int f : around[v]) {
        if (face_dead[f] || (HasVertex(tri[f], a) && HasVertex(tri[f], b))) continue;
        if (flips(f, v, target)) {
          reject = true;
          break;
        }
      }
      if (reject) break;
    }
    if (reject) {
      ++stats.rejected_flips;
      continue;
    }
    // Collapse b into a.
    for (int f : around[b]) {
      if (face_dead[f]) continue;
      Vec3i& t = tri[f];
      if (HasVertex(t, a)) {
        face_dead[f] = 1;
        --live;
        continue;
      }
      for (int k = 0; k < 3; ++k) {
        if (t[k] == b) t[k] = a;
      }
      around[a].push_back(f);
    }
    std::vector<int>().swap(around[b]);
    vertex_dead[b] = 1;
    pos[a] = target;
    quad[a] += quad[b];
    ++stamp[a];
    around[a].erase(std::remove_if(around[a].begin(), around[a].end(),
                                   [&](int f) { return face_dead[f] != 0; }),
                    around[a].end());
    ++stats.collapses;
    stats.max_collapse_error = std::max(stats.max_collapse_error, cost);
    collect_neighbours(a, false);
    // Every edge of a is pushed again and b's old edges die: at most this many entries outdated.
    outdated_bound += 2 * neighbours.size() + 2;
    for (int w : neighbours) heap.Push(candidate(a, w));
    if (2 * outdated_bound > heap.size()) {
      stats.purged_entries += heap.Purge(outdated);
      outdated_bound = 0;
    }
  }

  TriangleMesh out;
  out.faces.reserve(live);
  for (std::size_t f = 0; f < tri.size(); ++f) {
    if (!face_dead[f]) out.faces.push_back(tri[f]);
  }
  int next = 0;
  const std::vector<int> remap = RenumberReferenced(out.faces, nv, &next);
  out.vertices.resize(next);
  for (std::size_t v = 0; v < nv; ++v) {
    if (remap[v] >= 0) out.vertices[remap[v]] = pos[v];
  }
  for (Vec3i& t : out.faces) {
    for (int k = 0; k < 3; ++k) t[k] = remap[t[k]];
  }
  if (stats_out != nullptr) *stats_out = stats;
  return out;
}

}  // namespace dimr::geometry
