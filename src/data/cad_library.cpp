// Procedural CAD library: parametric furniture families built as unions of closed primitive
// parts (lofted rings with caps), normalised to the unit box. See docs/cad_library.md.
#include "dimr/data/cad_library.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"

namespace dimr::data {
namespace {

using geometry::TriangleMesh;
using geometry::Vec3;
using geometry::Vec3i;
using Ring = std::vector<Vec3>;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------
// Deterministic randomness (no std distributions: their output is implementation-defined).
// ---------------------------------------------------------------------------------------
std::uint64_t Mix64(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

std::uint64_t HashString(const std::string& s, std::uint64_t h = 0xcbf29ce484222325ULL) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(Mix64(seed ^ 0x5851f42d4c957f2dULL)) {}
  std::uint64_t Next() {
    state_ += 0x9e3779b97f4a7c15ULL;
    std::uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1).
  double Unit() { return static_cast<double>(Next() >> 11) * (1.0 / 9007199254740992.0); }
  double Uniform(double a, double b) { return a + (b - a) * Unit(); }
  // Uniform integer in [lo, hi].
  int Int(int lo, int hi) {
    return lo + static_cast<int>(Next() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  bool Chance(double p) { return Unit() < p; }

 private:
  std::uint64_t state_;
};

std::string ModelId(const std::string& domain, int kind, std::uint64_t seed) {
  const std::uint64_t base = HashString(domain) ^ Mix64(static_cast<std::uint64_t>(kind) + 1);
  const std::uint64_t h1 = Mix64(base ^ Mix64(seed));
  const std::uint64_t h2 = Mix64(h1 ^ HashString(domain, 0x84222325cbf29ce4ULL) ^ seed);
  static const char* kHex = "0123456789abcdef";
  std::string id(32, '0');
  for (int i = 0; i < 16; ++i) {
    id[i] = kHex[(h1 >> (60 - 4 * i)) & 0xF];
    id[16 + i] = kHex[(h2 >> (60 - 4 * i)) & 0xF];
  }
  return id;
}

// ---------------------------------------------------------------------------------------
// Geometry helpers.
// ---------------------------------------------------------------------------------------
Eigen::Matrix3d RotZ(double a) { return Eigen::AngleAxisd(a, Vec3::UnitZ()).toRotationMatrix(); }
Eigen::Matrix3d RotY(double a) { return Eigen::AngleAxisd(a, Vec3::UnitY()).toRotationMatrix(); }
Eigen::Matrix3d RotX(double a) { return Eigen::AngleAxisd(a, Vec3::UnitX()).toRotationMatrix(); }

// Superellipse ring around (cx, cy) at height z: exponent 2 = ellipse, large = rounded
// rectangle. Counter-clockwise seen from +z; n points starting at angle `phase`.
Ring SuperRing(double cx, double cy, double a, double b, double exponent, int n, double z,
               double phase = 0.0) {
  Ring r;
  r.reserve(n);
  for (int i = 0; i < n; ++i) {
    const double t = phase + 2.0 * kPi * i / n;
    const double c = std::cos(t), s = std::sin(t);
    const double px = std::copysign(std::pow(std::abs(c), 2.0 / exponent), c);
    const double py = std::copysign(std::pow(std::abs(s), 2.0 / exponent), s);
    r.emplace_back(cx + a * px, cy + b * py, z);
  }
  return r;
}

// Rectangle ring with 4 * k points (k per side), corners included, counter-clockwise.
Ring RectRing(double cx, double cy, double hx, double hy, double z, int per_side = 1) {
  Ring r;
  const std::array<Vec3, 4> c = {Vec3(cx + hx, cy - hy, z), Vec3(cx + hx, cy + hy, z),
                                 Vec3(cx - hx, cy + hy, z), Vec3(cx - hx, cy - hy, z)};
  for (int s = 0; s < 4; ++s) {
    for (int k = 0; k < per_side; ++k) {
      const double t = static_cast<double>(k) / per_side;
      r.push_back((1.0 - t) * c[s] + t * c[(s + 1) % 4]);
    }
  }
  return r;
}

Ring Transformed(const Ring& ring, const Eigen::Matrix3d& R, const Vec3& t) {
  Ring out;
  out.reserve(ring.size());
  for (const auto& p : ring) out.push_back(R * p + t);
  return out;
}

// Accumulates closed parts into one mesh and records the part boundaries.
class Builder {
 public:
  // Lofts a sequence of rings (all of the same size) into a closed part: consecutive rings
  // are joined by quads; `closed_sequence` joins the last ring back to the first (a torus-like
  // tube, e.g. an annulus); otherwise the first and last rings are capped by fans around
  // their centroid (rings must then be star-shaped about it). Orientation is made outward.
  void Loft(const std::vector<Ring>& rings, bool closed_sequence, const std::string& name) {
    const int nr = static_cast<int>(rings.size());
    const int n = static_cast<int>(rings.front().size());
    TriangleMesh part;
    for (const auto& r : rings) part.vertices.insert(part.vertices.end(), r.begin(), r.end());
    const int segs = closed_sequence ? nr : nr - 1;
    for (int k = 0; k < segs; ++k) {
      const int k1 = (k + 1) % nr;
      for (int i = 0; i < n; ++i) {
        const int i1 = (i + 1) % n;
        const int a = k * n + i, b = k * n + i1, c = k1 * n + i1, d = k1 * n + i;
        part.faces.emplace_back(a, b, c);
        part.faces.emplace_back(a, c, d);
      }
    }
    if (!closed_sequence) {
      for (int end = 0; end < 2; ++end) {
        const int k = end == 0 ? 0 : nr - 1;
        Vec3 centre = Vec3::Zero();
        for (const auto& p : rings[k]) centre += p;
        centre /= n;
        const int ci = static_cast<int>(part.vertices.size());
        part.vertices.push_back(centre);
        for (int i = 0; i < n; ++i) {
          const int i1 = (i + 1) % n;
          if (end == 0) {
            part.faces.emplace_back(ci, k * n + i1, k * n + i);
          } else {
            part.faces.emplace_back(ci, k * n + i, k * n + i1);
          }
        }
      }
    }
    // Signed volume about the part centroid (translation-invariant for a closed surface,
    // computed locally for accuracy); flip to outward orientation if negative.
    Vec3 mean = Vec3::Zero();
    for (const auto& v : part.vertices) mean += v;
    mean /= static_cast<double>(part.vertices.size());
    double vol = 0.0;
    for (const auto& f : part.faces) {
      vol += (part.vertices[f[0]] - mean)
                 .dot((part.vertices[f[1]] - mean).cross(part.vertices[f[2]] - mean));
    }
    if (vol < 0.0) {
      for (auto& f : part.faces) std::swap(f[1], f[2]);
    }
    part_face_begin_.push_back(static_cast<int>(mesh_.faces.size()));
    part_names_.push_back(name);
    mesh_.Append(part);
  }

  // Oriented box: centre, full size, rotation.
  void Box(const Vec3& centre, const Vec3& size, const std::string& name,
           const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
    const Vec3 h = 0.5 * size;
    Loft({Transformed(RectRing(0, 0, h.x(), h.y(), -h.z()), R, centre),
          Transformed(RectRing(0, 0, h.x(), h.y(), h.z()), R, centre)},
         false, name);
  }
  // Axis-aligned box from min / max corners.
  void BoxMinMax(const Vec3& lo, const Vec3& hi, const std::string& name) {
    Box(0.5 * (lo + hi), hi - lo, name);
  }
  // Vertical frustum / (elliptic) cylinder on base centre `base`: radii at bottom and top
  // (x and y radius ratio `aspect_y`), n segments.
  void Cylinder(const Vec3& base, double r_bottom, double r_top, double height, int n,
                const std::string& name, double aspect_y = 1.0) {
    Loft({SuperRing(base.x(), base.y(), r_bottom, r_bottom * aspect_y, 2.0, n, base.z()),
          SuperRing(base.x(), base.y(), r_top, r_top * aspect_y, 2.0, n, base.z() + height)},
         false, name);
  }
  // Cylinder from point a to point b.
  void Rod(const Vec3& a, const Vec3& b, double r, int n, const std::string& name) {
    const Vec3 axis = (b - a).normalized();
    const Vec3 helper = std::abs(axis.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX();
    const Vec3 u = axis.cross(helper).normalized();
    const Vec3 v = axis.cross(u);
    Ring ra, rb;
    for (int i = 0; i < n; ++i) {
      const double t = 2.0 * kPi * i / n;
      const Vec3 off = r * (std::cos(t) * u + std::sin(t) * v);
      ra.push_back(a + off);
      rb.push_back(b + off);
    }
    Loft({ra, rb}, false, name);
  }
  // Box between two points (a beam) with cross-section w x h; `up` orients the h side.
  void Beam(const Vec3& a, const Vec3& b, double w, double h, const std::string& name,
            const Vec3& up_hint = Vec3::UnitZ()) {
    const Vec3 axis = (b - a).normalized();
    Vec3 up = up_hint - up_hint.dot(axis) * axis;
    if (up.norm() < 1e-6) up = Vec3::UnitX() - Vec3::UnitX().dot(axis) * axis;
    up.normalize();
    const Vec3 side = up.cross(axis);
    Eigen::Matrix3d R;
    R.col(0) = axis;
    R.col(1) = side;
    R.col(2) = up;
    Box(0.5 * (a + b), Vec3((b - a).norm(), w, h), name, R);
  }
  // Thin-walled open-top container (cup): outer bottom ring -> outer top ring -> inner top
  // ring -> inner bottom ring, capped at the outer bottom and the inner floor. One closed
  // part with a real cavity.
  void Cup(const Ring& outer_bottom, const Ring& outer_top, const Ring& inner_top,
           const Ring& inner_bottom, const std::string& name) {
    Loft({outer_bottom, outer_top, inner_top, inner_bottom}, false, name);
  }
  // Closed annulus (ring-shaped solid): outer bottom -> outer top -> inner top -> inner bottom.
  void Annulus(const Ring& outer_bottom, const Ring& outer_top, const Ring& inner_top,
               const Ring& inner_bottom, const std::string& name) {
    Loft({outer_bottom, outer_top, inner_top, inner_bottom}, true, name);
  }

  // Normalises to the unit box and fills the model.
  void Finish(CadModel* m) {
    const geometry::AABB box = mesh_.Bounds();
    const Vec3 lo = box.min, ext = box.Extent();
    m->nominal_size = ext;
    for (auto& v : mesh_.vertices) {
      for (int a = 0; a < 3; ++a) v[a] = (v[a] - lo[a]) / ext[a] - 0.5;
    }
    m->mesh = std::move(mesh_);
    m->part_face_begin = std::move(part_face_begin_);
    m->part_names = std::move(part_names_);
  }

 private:
  TriangleMesh mesh_;
  std::vector<int> part_face_begin_;
  std::vector<std::string> part_names_;
};

// Small drawer / door handle on the +x face at (x, y, z): a bar (vertical or horizontal)
// or a round knob.
void Handle(Builder& b, double x, double y, double z, int style, double length) {
  if (style == 0) {  // vertical bar
    b.Box(Vec3(x + 0.012, y, z), Vec3(0.024, 0.014, length), "handle");
  } else if (style == 1) {  // horizontal bar
    b.Box(Vec3(x + 0.012, y, z), Vec3(0.024, length, 0.014), "handle");
  } else {  // knob
    b.Rod(Vec3(x - 0.002, y, z), Vec3(x + 0.025, y, z), 0.012, 10, "handle");
  }
}

// Four legs at the corners of a rectangle (half extents hx, hy), from z0 to z1.
void FourLegs(Builder& b, double hx, double hy, double z0, double z1, double t, bool round,
              double splay = 0.0) {
  for (int sx = -1; sx <= 1; sx += 2) {
    for (int sy = -1; sy <= 1; sy += 2) {
      const Vec3 top(sx * (hx - t / 2), sy * (hy - t / 2), z1);
      const Vec3 bottom = top + Vec3(sx * splay, sy * splay, z0 - z1);
      if (round) {
        b.Rod(bottom, top, t / 2, 12, "leg");
      } else {
        b.Beam(bottom, top, t, t, "leg", Vec3::UnitX());
      }
    }
  }
}

// ---------------------------------------------------------------------------------------
// Tables (x = the side a person sits at; for rectangular tables the long side is along y).
// ---------------------------------------------------------------------------------------
void RectTableTop(Builder& b, double hx, double hy, double z, double t, bool round_corners) {
  if (round_corners) {
    const double ex = 6.0;
    b.Loft({SuperRing(0, 0, hx, hy, ex, 32, z - t), SuperRing(0, 0, hx, hy, ex, 32, z)}, false,
           "top");
  } else {
    b.BoxMinMax(Vec3(-hx, -hy, z - t), Vec3(hx, hy, z), "top");
  }
}

void FourLegTable(Builder& b, Rng& r, bool coffee) {
  const double L = coffee ? r.Uniform(0.8, 1.4) : r.Uniform(0.9, 2.2);
  const double D = std::min(L, coffee ? r.Uniform(0.45, 0.8) : r.Uniform(0.6, 1.05));
  const double H = coffee ? r.Uniform(0.35, 0.5) : r.Uniform(0.7, 0.78);
  const double t = r.Uniform(0.02, 0.05);
  const double lt = r.Uniform(0.03, 0.08);
  double inset = r.Uniform(0.0, 0.08);
  const bool round_legs = r.Chance(0.4);
  const bool round_corners = r.Chance(0.3);
  // Rounded corners cut into the corner: keep the legs under the top.
  if (round_corners) inset = std::max(inset, 0.22 * std::min(D, L) / 2);
  RectTableTop(b, D / 2, L / 2, H, t, round_corners);
  const double hx = D / 2 - inset, hy = L / 2 - inset;
  FourLegs(b, hx, hy, 0.0, H - t, lt, round_legs, r.Chance(0.2) ? r.Uniform(0.0, 0.04) : 0.0);
  if (r.Chance(coffee ? 0.3 : 0.6)) {  // apron
    const double ah = r.Uniform(0.05, 0.12), at = 0.02;
    const double z = H - t - ah / 2;
    for (int s = -1; s <= 1; s += 2) {
      b.Box(Vec3(s * (hx - lt / 2), 0, z), Vec3(at, 2 * hy - lt, ah), "apron");
      b.Box(Vec3(0, s * (hy - lt / 2), z), Vec3(2 * hx - lt, at, ah), "apron");
    }
  }
  if (r.Chance(coffee ? 0.6 : 0.15)) {  // lower shelf
    const double z = r.Uniform(0.08, 0.2) * H / 0.5;
    b.BoxMinMax(Vec3(-hx + lt * 0.5, -hy + lt * 0.5, std::min(z, H * 0.45)),
                Vec3(hx - lt * 0.5, hy - lt * 0.5, std::min(z, H * 0.45) + 0.02), "shelf");
  }
}

void RoundLegTable(Builder& b, Rng& r) {
  const double R = r.Uniform(0.3, 0.65);
  const double H = r.Chance(0.25) ? r.Uniform(0.9, 1.1) : r.Uniform(0.7, 0.76);  // bar / dining
  const double t = r.Uniform(0.02, 0.05);
  const double aspect = r.Chance(0.3) ? r.Uniform(1.2, 1.8) : 1.0;  // oval tops
  b.Cylinder(Vec3(0, 0, H - t), R, R, t, 32, "top", aspect);
  const int legs = r.Int(3, 4);
  const double lt = r.Uniform(0.03, 0.06);
  const double splay = r.Uniform(0.0, 0.08);
  const double rr = R * r.Uniform(0.55, 0.8);
  for (int i = 0; i < legs; ++i) {
    const double a = 2.0 * kPi * i / legs + kPi / 4;
    const Vec3 top(rr * std::cos(a), rr * aspect * std::sin(a), H - t);
    const Vec3 bottom(top.x() + splay * std::cos(a), top.y() + splay * std::sin(a), 0.0);
    b.Rod(bottom, top, lt / 2, 12, "leg");
  }
}

void PedestalTable(Builder& b, Rng& r) {
  const bool square = r.Chance(0.3);
  const double R = r.Uniform(0.3, 0.6);
  const double H = r.Uniform(0.7, 0.76);
  const double t = r.Uniform(0.02, 0.05);
  if (square) {
    b.BoxMinMax(Vec3(-R, -R, H - t), Vec3(R, R, H), "top");
  } else {
    b.Cylinder(Vec3(0, 0, H - t), R, R, t, 32, "top");
  }
  const double cr = r.Uniform(0.03, 0.08);
  b.Cylinder(Vec3(0, 0, 0.02), cr, cr * r.Uniform(0.7, 1.0), H - t - 0.02, 16, "column");
  if (r.Chance(0.5)) {
    const double br = R * r.Uniform(0.5, 0.8);
    b.Cylinder(Vec3(0, 0, 0), br, br * r.Uniform(0.6, 1.0), r.Uniform(0.02, 0.05), 24, "base");
  } else {
    const int feet = r.Int(3, 4);
    const double fl = R * r.Uniform(0.6, 0.85);
    for (int i = 0; i < feet; ++i) {
      const double a = 2.0 * kPi * i / feet;
      b.Beam(Vec3(0, 0, 0.025), Vec3(fl * std::cos(a), fl * std::sin(a), 0.025), 0.05, 0.05,
             "foot");
    }
  }
}

void TrestleTable(Builder& b, Rng& r) {
  const double L = r.Uniform(1.4, 2.4), D = r.Uniform(0.7, 1.0), H = r.Uniform(0.72, 0.78);
  const double t = r.Uniform(0.03, 0.06);
  RectTableTop(b, D / 2, L / 2, H, t, false);
  const double yend = L / 2 - r.Uniform(0.1, 0.3);
  const double pw = r.Uniform(0.05, 0.09);  // plank thickness (y)
  const double pd = D * r.Uniform(0.15, 0.5);
  const double fh = r.Uniform(0.05, 0.09);
  for (int s = -1; s <= 1; s += 2) {
    const double y = s * yend;
    b.Box(Vec3(0, y, fh / 2), Vec3(D * r.Uniform(0.75, 0.9), pw * 1.2, fh), "foot");
    b.Box(Vec3(0, y, (H - t) / 2), Vec3(pd, pw, H - t), "trestle");
    b.Box(Vec3(0, y, H - t - 0.03), Vec3(D * 0.8, pw, 0.06), "cleat");
  }
  const double sz = r.Uniform(0.15, 0.45);
  b.Box(Vec3(0, 0, sz), Vec3(0.05, 2 * yend, 0.08), "stretcher");
}

void DrawerStack(Builder& b, Rng& r, double x0, double x1, double y0, double y1, double z0,
                 double z1, int drawers, int handle_style) {
  b.BoxMinMax(Vec3(x0, y0, z0), Vec3(x1, y1, z1), "body");
  const double gap = 0.004, ft = 0.018;
  const double h = (z1 - z0) / drawers;
  for (int i = 0; i < drawers; ++i) {
    const double za = z0 + i * h + gap, zb = z0 + (i + 1) * h - gap;
    b.BoxMinMax(Vec3(x1 - 0.002, y0 + gap, za), Vec3(x1 + ft, y1 - gap, zb), "drawer");
    Handle(b, x1 + ft, 0.5 * (y0 + y1), std::max(za + 0.03, zb - std::min(0.06, h * 0.3)),
           handle_style, std::min(0.12, 0.5 * (y1 - y0)));
  }
}

void Desk(Builder& b, Rng& r) {
  const double L = r.Uniform(1.0, 1.8), D = r.Uniform(0.55, 0.8), H = r.Uniform(0.72, 0.76);
  const double t = r.Uniform(0.025, 0.04);
  RectTableTop(b, D / 2, L / 2, H, t, false);
  const double pw = r.Uniform(0.35, 0.45);
  const bool two = L > 1.3 && r.Chance(0.5);
  const int drawers = r.Int(2, 4);
  const int hs = r.Int(0, 2);
  const double x0 = -D / 2 + 0.02, x1 = D / 2 - 0.04;
  DrawerStack(b, r, x0, x1, L / 2 - pw, L / 2 - 0.01, 0.0, H - t, drawers, hs);
  if (two) {
    DrawerStack(b, r, x0, x1, -L / 2 + 0.01, -L / 2 + pw, 0.0, H - t, drawers, hs);
  } else if (r.Chance(0.5)) {
    b.BoxMinMax(Vec3(x0, -L / 2 + 0.01, 0), Vec3(x1, -L / 2 + 0.04, H - t), "side_panel");
  } else {
    FourLegs(b, D / 2 - 0.02, L / 2 - 0.01, 0.0, H - t, 0.04, false);
  }
  if (r.Chance(0.7)) {  // modesty panel at the back
    b.BoxMinMax(Vec3(-D / 2 + 0.03, -L / 2 + 0.02, H * r.Uniform(0.3, 0.6)),
                Vec3(-D / 2 + 0.05, L / 2 - 0.02, H - t), "modesty_panel");
  }
}

// ---------------------------------------------------------------------------------------
// Chairs (seat front at +x, backrest at -x).
// ---------------------------------------------------------------------------------------
void Backrest(Builder& b, Rng& r, double x_back, double hy, double z0, double height, double tilt,
              double thick, bool slats) {
  const Eigen::Matrix3d R = RotY(-tilt);  // top of the back leans towards -x
  const Vec3 pivot(x_back + thick / 2, 0, z0);
  auto place = [&](const Vec3& c) { return Vec3(pivot + R * (c - pivot)); };
  if (!slats) {
    b.Box(place(Vec3(x_back + thick / 2, 0, z0 + height / 2)), Vec3(thick, 2 * hy, height), "back",
          R);
    return;
  }
  const double post = r.Uniform(0.025, 0.04);
  for (int s = -1; s <= 1; s += 2) {
    b.Box(place(Vec3(x_back + thick / 2, s * (hy - post / 2), z0 + height / 2)),
          Vec3(thick, post, height), "back", R);
  }
  const double rail = r.Uniform(0.05, 0.12);
  b.Box(place(Vec3(x_back + thick / 2, 0, z0 + height - rail / 2)), Vec3(thick, 2 * hy, rail),
        "back", R);
  const int n = r.Int(0, 4);
  const bool vertical = r.Chance(0.5);
  for (int i = 0; i < n; ++i) {
    if (vertical) {
      const double y = -hy + post + (2 * hy - 2 * post) * (i + 1) / (n + 1);
      b.Box(place(Vec3(x_back + thick / 2, y, z0 + (height - rail) / 2)),
            Vec3(thick * 0.7, 0.02, height - rail), "back", R);
    } else {
      const double z = z0 + (height - rail) * (i + 1) / (n + 1);
      b.Box(place(Vec3(x_back + thick / 2, 0, z)), Vec3(thick * 0.7, 2 * hy - post, 0.025), "back",
            R);
    }
  }
}

void FourLegChair(Builder& b, Rng& r) {
  const double W = r.Uniform(0.40, 0.52), D = r.Uniform(0.40, 0.50);
  const double sh = r.Uniform(0.42, 0.48), st = r.Uniform(0.03, 0.06);
  const double lt = r.Uniform(0.025, 0.045);
  const bool round = r.Chance(0.3);
  b.BoxMinMax(Vec3(-D / 2, -W / 2, sh - st), Vec3(D / 2, W / 2, sh), "seat");
  FourLegs(b, D / 2, W / 2, 0.0, sh - st, lt, round, r.Chance(0.3) ? r.Uniform(0.0, 0.03) : 0.0);
  if (r.Chance(0.4)) {  // stretchers
    const double z = r.Uniform(0.12, 0.2);
    for (int s = -1; s <= 1; s += 2) {
      b.Box(Vec3(0, s * (W / 2 - lt / 2), z), Vec3(D - lt, 0.02, 0.02), "stretcher");
    }
  }
  const double bh = r.Uniform(0.35, 0.5);
  Backrest(b, r, -D / 2, W / 2, sh, bh, r.Uniform(0.0, 0.26), r.Uniform(0.02, 0.04), r.Chance(0.5));
  if (r.Chance(0.25)) {  // dining armchair: arm rests on posts
    const double ah = r.Uniform(0.18, 0.25);
    for (int s = -1; s <= 1; s += 2) {
      b.Box(Vec3(0, s * (W / 2 - 0.02), sh + ah), Vec3(D * 0.9, 0.05, 0.025), "arm");
      b.Box(Vec3(D / 2 - 0.05, s * (W / 2 - 0.02), sh + ah / 2), Vec3(0.025, 0.025, ah), "arm");
    }
  }
}

// Slab with a rounded (superellipse) outline in its y-z plane, thickness along its local x.
void RoundedSlab(Builder& b, const Vec3& c, const Vec3& size, double ex, const std::string& name,
                 const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Matrix3d P;
  P << 0, 0, 1, 1, 0, 0, 0, 1, 0;  // local (u, v, w) -> (w, u, v)
  const Eigen::Matrix3d M = R * P;
  b.Loft({Transformed(SuperRing(0, 0, size.y() / 2, size.z() / 2, ex, 24, -size.x() / 2), M, c),
          Transformed(SuperRing(0, 0, size.y() / 2, size.z() / 2, ex, 24, size.x() / 2), M, c)},
         false, name);
}

void SwivelChair(Builder& b, Rng& r) {
  const double W = r.Uniform(0.45, 0.55), D = r.Uniform(0.42, 0.52);
  const double sh = r.Uniform(0.42, 0.52), st = r.Uniform(0.05, 0.09);
  const double base_r = r.Uniform(0.26, 0.34);
  const int arms = r.Chance(0.8) ? 5 : 4;
  const bool casters = r.Chance(0.75);
  const double foot_z = casters ? 0.06 : 0.015;
  const double phase = r.Uniform(0.0, 2.0 * kPi / arms);
  b.Cylinder(Vec3(0, 0, foot_z), 0.05, 0.045, 0.06, 16, "base");
  for (int i = 0; i < arms; ++i) {
    const double a = phase + 2.0 * kPi * i / arms;
    const Vec3 dir(std::cos(a), std::sin(a), 0);
    b.Beam(Vec3(0, 0, foot_z + 0.04), base_r * dir + Vec3(0, 0, foot_z + 0.01), 0.045, 0.035,
           "base");
    if (casters) {
      const Vec3 side(-dir.y(), dir.x(), 0);
      const Vec3 c = (base_r - 0.02) * dir + Vec3(0, 0, 0.03);
      b.Rod(c - 0.02 * side, c + 0.02 * side, 0.03, 10, "caster");
    }
  }
  const double col_r = r.Uniform(0.02, 0.035);
  b.Cylinder(Vec3(0, 0, foot_z + 0.05), col_r, col_r, sh - st - 0.04 - foot_z - 0.05, 12, "column");
  b.BoxMinMax(Vec3(-0.12, -0.1, sh - st - 0.05), Vec3(0.1, 0.1, sh - st), "mechanism");
  const double ex = r.Uniform(3.0, 8.0);
  b.Loft(
      {SuperRing(0, 0, D / 2, W / 2, ex, 24, sh - st), SuperRing(0, 0, D / 2, W / 2, ex, 24, sh)},
      false, "seat");
  // Backrest on a support bar behind the seat, leaning back by `tilt`.
  const double tilt = r.Uniform(0.05, 0.3);
  const double bh = r.Uniform(0.4, 0.75), bt = r.Uniform(0.04, 0.08);
  const double bz0 = sh + r.Uniform(0.04, 0.1);
  const double bx = -D / 2 - 0.02;
  const Eigen::Matrix3d R = RotY(-tilt);
  const Vec3 pivot(bx, 0, bz0);
  b.Beam(Vec3(-0.1, 0, sh - st - 0.03), Vec3(bx - bt, 0, sh - st - 0.03), 0.06, 0.02,
         "back_support");
  b.Beam(Vec3(bx - bt, 0, sh - st - 0.04), pivot + R * Vec3(-bt, 0, 0.15), 0.06, 0.02,
         "back_support", Vec3::UnitX());
  RoundedSlab(b, pivot + R * Vec3(-bt / 2, 0, bh / 2), Vec3(bt, W * r.Uniform(0.85, 1.05), bh),
              2.0 + ex, "back", R);
  if (r.Chance(0.6)) {
    const double ah = r.Uniform(0.18, 0.26);
    for (int s = -1; s <= 1; s += 2) {
      const double y = s * (W / 2 + 0.03);
      const double z0 = sh - st - 0.03;  // the post stands on the bar under the seat
      b.Box(Vec3(-0.02, y, 0.5 * (z0 + sh + ah)), Vec3(0.04, 0.03, sh + ah - z0), "arm");
      b.Box(Vec3(0.0, y, sh + ah), Vec3(0.25, 0.07, 0.03), "arm");
      b.Box(Vec3(-0.02, 0.5 * (y + s * 0.08), sh - st - 0.02), Vec3(0.04, std::abs(y) - 0.07, 0.02),
            "arm");
    }
  }
}

void Armchair(Builder& b, Rng& r) {
  const double W = r.Uniform(0.7, 0.95), D = r.Uniform(0.7, 0.9);
  const double feet = r.Uniform(0.04, 0.15);
  const double sh = r.Uniform(0.40, 0.46);
  const double aw = r.Uniform(0.1, 0.2), ah = r.Uniform(0.55, 0.68);
  const double bt = r.Uniform(0.15, 0.25), bh = r.Uniform(0.75, 1.0);
  const double z0 = feet;
  const double cushion = r.Uniform(0.08, 0.14);
  b.BoxMinMax(Vec3(-D / 2, -W / 2 + aw, z0), Vec3(D / 2, W / 2 - aw, sh - cushion), "base");
  b.BoxMinMax(Vec3(-D / 2 + bt, -W / 2 + aw, sh - cushion), Vec3(D / 2, W / 2 - aw, sh), "seat");
  for (int s = -1; s <= 1; s += 2) {
    const double y0 = s < 0 ? -W / 2 : W / 2 - aw;
    if (r.Chance(0.5)) {
      b.BoxMinMax(Vec3(-D / 2, y0, z0), Vec3(D / 2, y0 + aw, ah), "arm");
    } else {  // rolled arm: rounded profile in the y-z plane
      RoundedSlab(b, Vec3(0, y0 + aw / 2, 0.5 * (z0 + ah)), Vec3(D, aw, ah - z0), 5.0, "arm");
    }
  }
  const double tilt = r.Uniform(0.0, 0.2);
  const Eigen::Matrix3d R = RotY(-tilt);
  const Vec3 pivot(-D / 2 + bt, 0, z0);
  b.Box(pivot + R * Vec3(-bt / 2, 0, (bh - z0) / 2),
        Vec3(bt, W - (r.Chance(0.5) ? 0.0 : 2 * aw), bh - z0), "back", R);
  if (feet > 0.06) {
    FourLegs(b, D / 2 - 0.03, W / 2 - 0.03, 0.0, z0 + 0.01, 0.04, r.Chance(0.5));
  } else {
    b.BoxMinMax(Vec3(-D / 2 + 0.03, -W / 2 + 0.03, 0), Vec3(D / 2 - 0.03, W / 2 - 0.03, z0 + 0.01),
                "plinth");
  }
}

void Stool(Builder& b, Rng& r, bool* symmetric) {
  const bool round = r.Chance(0.75);
  *symmetric = round;
  const double R = r.Uniform(0.15, 0.22);
  const double H = r.Chance(0.5) ? r.Uniform(0.42, 0.5) : r.Uniform(0.62, 0.8);
  const double st = r.Uniform(0.03, 0.07);
  if (round) {
    b.Cylinder(Vec3(0, 0, H - st), R, R * r.Uniform(0.95, 1.05), st, 24, "seat");
  } else {
    b.BoxMinMax(Vec3(-R, -R, H - st), Vec3(R, R, H), "seat");
  }
  if (r.Chance(0.35)) {  // pedestal base
    const double cr = r.Uniform(0.02, 0.04);
    b.Cylinder(Vec3(0, 0, 0.02), cr, cr, H - st - 0.02, 16, "column");
    const double br = R * r.Uniform(0.9, 1.3);
    b.Cylinder(Vec3(0, 0, 0), br, br * 0.9, 0.025, 24, "base");
    if (H > 0.6) {  // foot ring
      const double fr = R * 0.9, ft = 0.02, fz = H * 0.35;
      b.Annulus(SuperRing(0, 0, fr, fr, 2, 24, fz), SuperRing(0, 0, fr, fr, 2, 24, fz + ft),
                SuperRing(0, 0, fr - ft, fr - ft, 2, 24, fz + ft),
                SuperRing(0, 0, fr - ft, fr - ft, 2, 24, fz), "footrest");
      b.Beam(Vec3(-fr + 0.01, 0, fz + ft / 2), Vec3(fr - 0.01, 0, fz + ft / 2), 0.015, 0.015,
             "footrest");
    }
    return;
  }
  const int legs = round ? r.Int(3, 4) : 4;
  const double splay = r.Uniform(0.0, 0.1) * H;
  const double lr = r.Uniform(0.012, 0.025);
  const double inset = R * (round ? 0.75 : 0.85);
  for (int i = 0; i < legs; ++i) {
    const double a = 2.0 * kPi * i / legs + kPi / 4;
    const Vec3 dir(std::cos(a), std::sin(a), 0);
    b.Rod(inset * dir + splay * dir, inset * dir + Vec3(0, 0, H - st), lr, 10, "leg");
  }
  if (H > 0.6) {  // rungs as foot rest
    const double z = H * 0.35;
    const double rr = inset + splay * (1.0 - z / (H - st));
    for (int i = 0; i < legs; ++i) {
      const double a0 = 2.0 * kPi * i / legs + kPi / 4, a1 = 2.0 * kPi * (i + 1) / legs + kPi / 4;
      b.Rod(Vec3(rr * std::cos(a0), rr * std::sin(a0), z),
            Vec3(rr * std::cos(a1), rr * std::sin(a1), z), lr * 0.8, 8, "rung");
    }
  }
}

// ---------------------------------------------------------------------------------------
// Bookshelves (open side +x).
// ---------------------------------------------------------------------------------------
void Bookshelf(Builder& b, Rng& r, int style) {
  // style 0: sides + back panel, 1: sides, open back, 2: etagere (corner posts, open sides),
  // 3: cube grid.
  const double W = r.Uniform(0.4, 1.6), D = r.Uniform(0.25, 0.45), H = r.Uniform(0.7, 2.2);
  const double t = r.Uniform(0.015, 0.03);
  const double plinth = (style <= 1 && r.Chance(0.5)) ? r.Uniform(0.04, 0.1) : 0.0;
  int levels = std::clamp(static_cast<int>(std::lround(H / r.Uniform(0.28, 0.42))), 2, 8);
  if (style == 2) {
    const double post = r.Uniform(0.02, 0.04);
    for (int sx = -1; sx <= 1; sx += 2) {
      for (int sy = -1; sy <= 1; sy += 2) {
        b.BoxMinMax(Vec3(sx > 0 ? D / 2 - post : -D / 2, sy > 0 ? W / 2 - post : -W / 2, 0),
                    Vec3(sx > 0 ? D / 2 : -D / 2 + post, sy > 0 ? W / 2 : -W / 2 + post, H),
                    "post");
      }
    }
    const double foot = r.Uniform(0.03, 0.12);
    for (int i = 0; i <= levels; ++i) {
      const double z = foot + (H - foot - t) * i / levels;
      b.BoxMinMax(Vec3(-D / 2, -W / 2, z), Vec3(D / 2, W / 2, z + t), "shelf");
    }
    if (r.Chance(0.5)) {  // X brace at the back
      b.Beam(Vec3(-D / 2 + 0.01, -W / 2 + post, foot), Vec3(-D / 2 + 0.01, W / 2 - post, H - t),
             0.015, 0.01, "brace", Vec3::UnitX());
      b.Beam(Vec3(-D / 2 + 0.01, W / 2 - post, foot), Vec3(-D / 2 + 0.01, -W / 2 + post, H - t),
             0.015, 0.01, "brace", Vec3::UnitX());
    }
    return;
  }
  for (int s = -1; s <= 1; s += 2) {
    b.BoxMinMax(Vec3(-D / 2, s > 0 ? W / 2 - t : -W / 2, 0),
                Vec3(D / 2, s > 0 ? W / 2 : -W / 2 + t, H), "side");
  }
  const double top_over = r.Chance(0.3) ? r.Uniform(0.01, 0.03) : 0.0;
  b.BoxMinMax(Vec3(-D / 2, -W / 2 - top_over, H - t), Vec3(D / 2 + top_over, W / 2 + top_over, H),
              "top");
  b.BoxMinMax(Vec3(-D / 2, -W / 2 + t, plinth), Vec3(D / 2, W / 2 - t, plinth + t), "bottom");
  if (plinth > 0) {
    b.BoxMinMax(Vec3(D / 2 - 0.03, -W / 2 + t, 0), Vec3(D / 2 - 0.01, W / 2 - t, plinth), "plinth");
  }
  if (style == 0) {
    b.BoxMinMax(Vec3(-D / 2, -W / 2 + t, plinth), Vec3(-D / 2 + 0.008, W / 2 - t, H - t), "back");
  }
  const double inner0 = plinth + t, inner1 = H - t;
  if (style == 3) {
    levels = std::clamp(static_cast<int>(std::lround(H / r.Uniform(0.3, 0.4))), 2, 6);
    const int cols = std::clamp(static_cast<int>(std::lround(W / r.Uniform(0.3, 0.4))), 1, 5);
    for (int c = 1; c < cols; ++c) {
      const double y = -W / 2 + t + (W - 2 * t) * c / cols;
      b.BoxMinMax(Vec3(-D / 2, y - t / 2, inner0), Vec3(D / 2, y + t / 2, inner1), "divider");
    }
  }
  for (int i = 1; i < levels; ++i) {
    const double z = inner0 + (inner1 - inner0) * i / levels - t / 2;
    b.BoxMinMax(Vec3(-D / 2 + (style == 0 ? 0.008 : 0.0), -W / 2 + t, z),
                Vec3(D / 2 - 0.005, W / 2 - t, z + t), "shelf");
  }
}

// ---------------------------------------------------------------------------------------
// Sofas (seat front +x).
// ---------------------------------------------------------------------------------------
void Sofa(Builder& b, Rng& r, int style) {
  // style 0: with arms, 1: armless, 2: L-shape (chaise on one side, arms optional).
  // Two or three seats in every style: a one-seat sofa with arms is an armchair, which ScanNet
  // labels chair (NYU40 5; "armchair" and "sofa chair" are chair categories) and the chair
  // family `armchair` makes. One-seat sofas taught "armchair = sofa" (a quarter of the sofas
  // of 400 v1 rooms were under 1.25 m wide; docs/real.md).
  const int seats = r.Int(2, 3);
  const double sw = r.Uniform(0.5, 0.7);
  const double D = r.Uniform(0.8, 1.0);
  const double feet = r.Uniform(0.03, 0.12);
  const double sh = r.Uniform(0.38, 0.46), cushion = r.Uniform(0.1, 0.16);
  const bool arms = style == 0 || (style == 2 && r.Chance(0.6));
  const double aw = arms ? r.Uniform(0.1, 0.25) : 0.0;
  const double ah = r.Uniform(0.55, 0.7);
  const double bt = r.Uniform(0.15, 0.25), bh = r.Uniform(0.75, 0.95);
  const double W = seats * sw + 2 * aw;
  const double z0 = feet;
  const int chaise_side = r.Chance(0.5) ? 1 : -1;
  const double chaise = style == 2 ? r.Uniform(0.55, 0.85) : 0.0;
  // Base under the seats.
  b.BoxMinMax(Vec3(-D / 2, -W / 2 + aw, z0), Vec3(D / 2, W / 2 - aw, sh - cushion), "base");
  for (int i = 0; i < seats; ++i) {
    const double y0 = -W / 2 + aw + i * sw, y1 = y0 + sw;
    const bool on_chaise =
        style == 2 && ((chaise_side > 0 && i == seats - 1) || (chaise_side < 0 && i == 0));
    b.BoxMinMax(Vec3(-D / 2 + bt, y0 + 0.005, sh - cushion),
                Vec3(D / 2 + (on_chaise ? chaise : 0.0), y1 - 0.005, sh), "seat");
  }
  if (style == 2) {
    const double y0 = chaise_side > 0 ? W / 2 - aw - sw : -W / 2 + aw;
    b.BoxMinMax(Vec3(D / 2 - 0.01, y0, z0), Vec3(D / 2 + chaise, y0 + sw, sh - cushion), "base");
  }
  for (int s = -1; s <= 1 && arms; s += 2) {
    const double y0 = s < 0 ? -W / 2 : W / 2 - aw;
    const double front = (style == 2 && s == chaise_side) ? D / 2 + chaise : D / 2;
    if (r.Chance(0.5)) {
      b.BoxMinMax(Vec3(-D / 2, y0, z0), Vec3(front, y0 + aw, ah), "arm");
    } else {
      RoundedSlab(b, Vec3(0.5 * (front - D / 2), y0 + aw / 2, 0.5 * (z0 + ah)),
                  Vec3(front + D / 2, aw, ah - z0), 5.0, "arm");
    }
  }
  const double tilt = r.Uniform(0.0, 0.2);
  const Eigen::Matrix3d R = RotY(-tilt);
  const Vec3 pivot(-D / 2 + bt, 0, z0);
  b.Box(pivot + R * Vec3(-bt / 2, 0, (bh - z0) / 2), Vec3(bt, W, bh - z0), "back", R);
  if (r.Chance(0.6)) {  // back cushions
    const double ct = r.Uniform(0.1, 0.16);
    for (int i = 0; i < seats; ++i) {
      const double yc = -W / 2 + aw + (i + 0.5) * sw;
      const Vec3 c = pivot + R * Vec3(ct / 2, 0, (sh - z0) + (bh - sh) * 0.45);
      RoundedSlab(b, Vec3(c.x(), yc, c.z()), Vec3(ct, sw - 0.02, (bh - sh) * 0.8), 6.0, "cushion",
                  R);
    }
  }
  const double ft = 0.05;
  const double fx = D / 2 - 0.05, fy = W / 2 - 0.05;
  for (int sx = -1; sx <= 1; sx += 2) {
    for (int sy = -1; sy <= 1; sy += 2) {
      b.Cylinder(Vec3(sx * fx, sy * fy, 0), ft / 2, ft / 2 * 1.2, z0 + 0.01, 10, "foot");
    }
  }
  if (style == 2) {
    const double yc = chaise_side * (W / 2 - 0.05);
    b.Cylinder(Vec3(D / 2 + chaise - 0.05, yc, 0), ft / 2, ft / 2 * 1.2, z0 + 0.01, 10, "foot");
  }
}

// ---------------------------------------------------------------------------------------
// Trash bins: open-top thin-walled containers.
// ---------------------------------------------------------------------------------------
// Ring of a bin cross-section: round (exponent 2) or square-ish (rounded corners).
Ring BinRing(bool round, double ex, double a, double b, double z) {
  return round ? SuperRing(0, 0, a, b, 2.0, 32, z) : SuperRing(0, 0, a, b, ex, 32, z);
}

void TrashBin(Builder& b, Rng& r, int style, bool* symmetric) {
  // style 0: round, 1: square, 2: tapered, 3: pedal bin with an open hinged lid.
  bool round = style == 0 || ((style == 2 || style == 3) && r.Chance(0.5));
  const double ex = r.Uniform(5.0, 12.0);
  const double H = r.Uniform(0.3, 0.75);
  const double rt = r.Uniform(0.12, 0.25);
  const double aspect = round ? 1.0 : r.Uniform(0.6, 1.0);
  double rb = rt;
  if (style == 2) rb = rt / r.Uniform(1.15, 1.5);
  if (style == 0 || style == 1) rb = rt * r.Uniform(0.92, 1.0);
  const double wall = r.Uniform(0.004, 0.015), floor_t = r.Uniform(0.01, 0.03);
  const double at = rt * aspect, ab = rb * aspect;
  // Inner rings offset by the wall thickness (along the radial direction).
  b.Cup(BinRing(round, ex, rb, ab, 0.0), BinRing(round, ex, rt, at, H),
        BinRing(round, ex, rt - wall, at - wall, H),
        BinRing(round, ex, rb - wall, ab - wall, floor_t), "body");
  const bool lip = r.Chance(0.4) || style == 3;
  if (lip) {  // rolled rim: an annulus around the opening
    const double lh = r.Uniform(0.015, 0.03), lw = r.Uniform(0.006, 0.015);
    b.Annulus(BinRing(round, ex, rt + lw, at + lw, H - lh), BinRing(round, ex, rt + lw, at + lw, H),
              BinRing(round, ex, rt - wall, at - wall, H),
              BinRing(round, ex, rt - wall, at - wall, H - lh), "rim");
  }
  bool handles = false;
  if (style != 3 && r.Chance(0.3)) {  // carrying handles on the left and right walls
    handles = true;
    const double zh = H * r.Uniform(0.78, 0.88);
    const double ah = ab + (at - ab) * zh / H;
    for (int s = -1; s <= 1; s += 2) {
      b.Box(Vec3(0, s * (ah + 0.008), zh), Vec3(std::min(0.1, rt), 0.026, 0.025), "handle");
    }
  }
  *symmetric = round && style != 3 && !handles;
  if (style == 3) {
    // Lid hinged at the back (-x), opened by `angle` (0 = closed) so the opening stays free.
    const double angle = r.Uniform(1.2, 1.9);
    const double lt = 0.012;
    const Vec3 hinge(-rt - 0.01, 0, H + 0.01);
    const Eigen::Matrix3d R = RotY(-angle);
    Ring lid0 = BinRing(round, ex, rt + 0.01, at + 0.01, 0.0);
    Ring lid1 = BinRing(round, ex, rt + 0.01, at + 0.01, lt);
    for (auto* ring : {&lid0, &lid1}) {
      for (auto& p : *ring) p = hinge + R * (p + Vec3(rt + 0.01, 0, 0));
    }
    b.Loft({lid0, lid1}, false, "lid");
    b.BoxMinMax(Vec3(-rt - 0.03, -0.04, H - 0.04), Vec3(-rt + 0.005, 0.04, H + 0.02), "hinge");
    b.BoxMinMax(Vec3(rb - 0.01, -0.05, 0.01), Vec3(rb + 0.06, 0.05, 0.03), "pedal");
  }
}

// ---------------------------------------------------------------------------------------
// Cabinets (doors / drawers on the +x face).
// ---------------------------------------------------------------------------------------
void CabinetCarcass(Builder& b, Rng& r, double D, double W, double z0, double H) {
  b.BoxMinMax(Vec3(-D / 2, -W / 2, z0), Vec3(D / 2, W / 2, H), "body");
  if (z0 > 0.0) {
    if (r.Chance(0.5)) {
      b.BoxMinMax(Vec3(-D / 2 + 0.02, -W / 2 + 0.02, 0),
                  Vec3(D / 2 - 0.05, W / 2 - 0.02, z0 + 0.005), "plinth");
    } else {
      FourLegs(b, D / 2 - 0.02, W / 2 - 0.02, 0.0, z0 + 0.005, 0.04, r.Chance(0.5));
    }
  }
}

void Doors(Builder& b, double x, double y0, double y1, double z0, double z1, int n, int hs) {
  const double gap = 0.004, dt = 0.018;
  const double w = (y1 - y0) / n;
  for (int i = 0; i < n; ++i) {
    const double ya = y0 + i * w + gap, yb = y0 + (i + 1) * w - gap;
    b.BoxMinMax(Vec3(x - 0.002, ya, z0 + gap), Vec3(x + dt, yb, z1 - gap), "door");
    // Handle next to the door's opening edge (pairs open in the middle).
    const bool left_edge = (n % 2 == 0) ? (i >= n / 2) : (i % 2 == 1);
    const double hy = left_edge ? ya + 0.04 : yb - 0.04;
    const double hz = z1 - gap - std::min(0.12, 0.25 * (z1 - z0));
    Handle(b, x + dt, hy, hz, hs == 1 ? 0 : hs, std::min(0.15, 0.3 * (z1 - z0)));
  }
}

void Cabinet(Builder& b, Rng& r, int style) {
  // style 0: doors, 1: drawers, 2: sideboard (drawers over doors), 3: fridge.
  const int hs = r.Int(0, 2);
  if (style == 3) {
    const double W = r.Uniform(0.55, 0.9), D = r.Uniform(0.6, 0.75), H = r.Uniform(1.45, 1.95);
    const double z0 = r.Uniform(0.0, 0.03);
    if (z0 > 0.01) {
      b.BoxMinMax(Vec3(-D / 2 + 0.03, -W / 2 + 0.03, 0),
                  Vec3(D / 2 - 0.08, W / 2 - 0.03, z0 + 0.005), "plinth");
    }
    b.BoxMinMax(Vec3(-D / 2, -W / 2, z0), Vec3(D / 2 - 0.05, W / 2, H), "body");
    const int layout = r.Int(0, 2);  // single door, freezer split, side-by-side
    const double x = D / 2 - 0.05, dt = 0.05;
    auto door = [&](double ya, double yb, double za, double zb, double hy) {
      b.BoxMinMax(Vec3(x - 0.002, ya + 0.003, za + 0.003),
                  Vec3(x + dt - 0.01, yb - 0.003, zb - 0.003), "door");
      const double hl = std::min(0.5, 0.6 * (zb - za));
      b.Box(Vec3(x + dt - 0.01 + 0.015, hy, 0.5 * (za + zb)), Vec3(0.03, 0.025, hl), "handle");
    };
    if (layout == 0) {
      door(-W / 2, W / 2, z0, H, W / 2 - 0.05);
    } else if (layout == 1) {
      const double split = z0 + (H - z0) * r.Uniform(0.55, 0.72);
      door(-W / 2, W / 2, z0, split, W / 2 - 0.05);
      door(-W / 2, W / 2, split, H, W / 2 - 0.05);
    } else {
      door(-W / 2, 0.0, z0, H, -0.04);
      door(0.0, W / 2, z0, H, 0.04);
    }
    return;
  }
  const double W = r.Uniform(0.4, style == 2 ? 2.0 : 1.2);
  const double D = r.Uniform(0.35, 0.6);
  const double H = style == 0 ? (r.Chance(0.3) ? r.Uniform(1.5, 2.1) : r.Uniform(0.5, 1.1))
                              : r.Uniform(0.6, 1.2);
  const double z0 = r.Chance(0.6) ? r.Uniform(0.05, 0.15) : 0.0;
  CabinetCarcass(b, r, D, W, z0, H);
  const double x = D / 2;
  const double top_t = r.Uniform(0.02, 0.04);
  const bool top = r.Chance(0.5);
  const double zt = top ? H - 0.002 : H;
  if (top) {
    const double over = r.Uniform(0.0, 0.04);
    b.BoxMinMax(Vec3(-D / 2, -W / 2 - over, H - 0.002),
                Vec3(D / 2 + 0.02 + over, W / 2 + over, H + top_t), "top");
  }
  if (style == 0) {
    const int n = W > 0.8 ? 2 * r.Int(1, 2) : r.Int(1, 2);
    Doors(b, x, -W / 2, W / 2, z0, zt, n, hs);
  } else if (style == 1) {
    const int cols = W > 0.9 && r.Chance(0.5) ? 2 : 1;
    const int drawers = r.Int(2, 6);
    const double gap = 0.004, ft = 0.018;
    for (int c = 0; c < cols; ++c) {
      const double y0 = -W / 2 + W * c / cols, y1 = -W / 2 + W * (c + 1) / cols;
      const double h = (zt - z0) / drawers;
      for (int i = 0; i < drawers; ++i) {
        const double za = z0 + i * h + gap, zb = z0 + (i + 1) * h - gap;
        b.BoxMinMax(Vec3(x - 0.002, y0 + gap, za), Vec3(x + ft, y1 - gap, zb), "drawer");
        Handle(b, x + ft, 0.5 * (y0 + y1), 0.5 * (za + zb) + 0.2 * (zb - za), hs == 0 ? 1 : hs,
               std::min(0.15, 0.4 * (y1 - y0)));
      }
    }
  } else {
    const int cols = std::clamp(static_cast<int>(std::lround(W / 0.45)), 1, 4);
    const double dh = r.Uniform(0.12, 0.2);
    const double zs = zt - dh;
    const double gap = 0.004, ft = 0.018;
    for (int c = 0; c < cols; ++c) {
      const double y0 = -W / 2 + W * c / cols, y1 = -W / 2 + W * (c + 1) / cols;
      b.BoxMinMax(Vec3(x - 0.002, y0 + gap, zs + gap), Vec3(x + ft, y1 - gap, zt - gap), "drawer");
      Handle(b, x + ft, 0.5 * (y0 + y1), zs + dh / 2, hs == 0 ? 1 : hs, 0.1);
    }
    Doors(b, x, -W / 2, W / 2, z0, zs, cols, hs);
  }
}

// ---------------------------------------------------------------------------------------
// Displays (screen faces +x; stands / brackets behind it).
// ---------------------------------------------------------------------------------------
void Display(Builder& b, Rng& r, int style) {
  // style 0: monitor on a stand, 1: TV on feet / pedestal, 2: wall TV, 3: CRT-like monitor.
  if (style == 3) {
    const double W = r.Uniform(0.35, 0.5), Hs = W * r.Uniform(0.72, 0.8);
    const double depth = W * r.Uniform(0.8, 1.05);
    const double z0 = r.Uniform(0.03, 0.06);
    b.BoxMinMax(Vec3(-0.04, -W / 2, z0), Vec3(0.0, W / 2, z0 + Hs), "screen");
    const double bw = W * r.Uniform(0.45, 0.65), bh = Hs * r.Uniform(0.5, 0.7);
    // Tapered tube housing behind the screen: local z of the rings becomes -x.
    const Eigen::Matrix3d back = RotY(-kPi / 2);
    const Vec3 c(-0.035, 0, z0 + Hs / 2);
    b.Loft({Transformed(RectRing(0, 0, 0.5 * Hs - 0.01, 0.5 * W - 0.01, 0.0), back, c),
            Transformed(RectRing(0, 0, 0.5 * bh, 0.5 * bw, depth), back, c)},
           false, "housing");
    b.BoxMinMax(Vec3(-depth * 0.5, -W * 0.3, 0), Vec3(-0.02, W * 0.3, z0 + 0.015), "stand");
    return;
  }
  const double W = style == 0 ? r.Uniform(0.45, 0.8) : r.Uniform(0.8, 1.8);
  const double aspect = style == 0 ? r.Uniform(0.42, 0.65) : r.Uniform(0.52, 0.6);
  const double Hs = W * aspect;
  const double t = style == 2 ? r.Uniform(0.02, 0.05) : r.Uniform(0.015, 0.04);
  const double lift = style == 2 ? 0.0 : r.Uniform(0.06, 0.16);
  b.BoxMinMax(Vec3(-t, -W / 2, lift), Vec3(0.0, W / 2, lift + Hs), "screen");
  if (style != 2 && r.Chance(0.6)) {  // electronics housing on the back
    b.BoxMinMax(Vec3(-t - r.Uniform(0.01, 0.04), -W * 0.35, lift + Hs * 0.15),
                Vec3(-t + 0.002, W * 0.35, lift + Hs * 0.8), "housing");
  }
  if (style == 0) {
    const double nx = -t - 0.03;
    const double nw = r.Uniform(0.04, 0.08);
    b.BoxMinMax(Vec3(nx - 0.02, -nw / 2, 0.01), Vec3(nx, nw / 2, lift + Hs * 0.6), "stand");
    b.BoxMinMax(Vec3(nx - 0.005, -nw / 2, lift + Hs * 0.45),
                Vec3(-t + 0.002, nw / 2, lift + Hs * 0.6), "stand");
    const double bd = r.Uniform(0.15, 0.25), bw = r.Uniform(0.18, 0.3);
    if (r.Chance(0.5)) {
      b.BoxMinMax(Vec3(nx - bd * 0.6, -bw / 2, 0), Vec3(nx + bd * 0.4, bw / 2, 0.015), "base");
    } else {
      b.Cylinder(Vec3(nx - bd * 0.1, 0, 0), bd / 2, bd / 2 * 0.95, 0.015, 24, "base", bw / bd);
    }
  } else if (style == 1) {
    if (r.Chance(0.5)) {  // two feet near the edges
      for (int s = -1; s <= 1; s += 2) {
        const double y = s * W * r.Uniform(0.3, 0.42);
        b.BoxMinMax(Vec3(-t - 0.12, y - 0.03, 0), Vec3(-t + 0.1, y + 0.03, 0.015), "stand");
        b.BoxMinMax(Vec3(-t - 0.02, y - 0.015, 0.01), Vec3(-t + 0.001, y + 0.015, lift + 0.05),
                    "stand");
      }
    } else {  // central pedestal
      b.BoxMinMax(Vec3(-t - 0.06, -0.04, 0.01), Vec3(-t + 0.001, 0.04, lift + Hs * 0.3), "stand");
      b.BoxMinMax(Vec3(-t - 0.15, -W * 0.2, 0), Vec3(-t + 0.08, W * 0.2, 0.015), "base");
    }
  } else {  // wall bracket behind the slab
    const double bd = r.Uniform(0.03, 0.08);
    b.BoxMinMax(Vec3(-t - bd, -W * 0.2, Hs * 0.3), Vec3(-t + 0.001, W * 0.2, Hs * 0.7), "bracket");
  }
}

// ---------------------------------------------------------------------------------------
// Bathtubs: a closed thin-walled tub body (cup) with a rim; length along y.
// ---------------------------------------------------------------------------------------
void Bathtub(Builder& b, Rng& r, int style) {
  // style 0: free-standing oval on feet, 1: free-standing on a plinth, 2: built-in (box).
  const double L = r.Uniform(1.4, 1.85), Wd = r.Uniform(0.7, 0.9), H = r.Uniform(0.45, 0.62);
  const double wall = r.Uniform(0.03, 0.08), floor_t = r.Uniform(0.04, 0.08);
  if (style == 2) {
    const double ex_in = r.Uniform(3.0, 8.0);
    const double rim = r.Uniform(0.05, 0.14);
    const int n = 48;
    // Outer: rectangle sampled with the same parametrisation (very high exponent).
    b.Cup(SuperRing(0, 0, Wd / 2, L / 2, 60.0, n, 0.0), SuperRing(0, 0, Wd / 2, L / 2, 60.0, n, H),
          SuperRing(0, 0, Wd / 2 - rim, L / 2 - rim, ex_in, n, H),
          SuperRing(0, 0, (Wd / 2 - rim) * 0.85, (L / 2 - rim) * 0.9, ex_in, n, floor_t), "tub");
    if (r.Chance(0.5)) {  // faucet on the rim at one end
      const double y = L / 2 - rim / 2;
      b.Rod(Vec3(0, y, H - 0.01), Vec3(0, y, H + 0.12), 0.015, 10, "faucet");
      b.Rod(Vec3(0, y + 0.015, H + 0.11), Vec3(0, y - 0.1, H + 0.11), 0.012, 10, "faucet");
    }
    if (r.Chance(0.4)) {  // tiled deck at the foot end
      const double deck = r.Uniform(0.1, 0.35);
      b.BoxMinMax(Vec3(-Wd / 2, -L / 2 - deck, 0), Vec3(Wd / 2, -L / 2 + 0.01, H), "deck");
    }
    return;
  }
  const double ex = r.Uniform(2.0, 3.5);
  const double taper = r.Uniform(0.75, 0.92);
  const double base = style == 0 ? r.Uniform(0.08, 0.15) : r.Uniform(0.05, 0.12);
  const int n = 48;
  const double lip = r.Uniform(0.01, 0.03);
  // Body: outer bottom (tapered), outer top, rolled rim, inner top, inner bottom.
  b.Loft({SuperRing(0, 0, Wd / 2 * taper, L / 2 * taper, ex, n, base),
          SuperRing(0, 0, Wd / 2, L / 2, ex, n, H - lip),
          SuperRing(0, 0, Wd / 2 + lip, L / 2 + lip, ex, n, H - lip),
          SuperRing(0, 0, Wd / 2 + lip, L / 2 + lip, ex, n, H),
          SuperRing(0, 0, Wd / 2 - wall, L / 2 - wall, ex, n, H),
          SuperRing(0, 0, (Wd / 2 - wall) * taper, (L / 2 - wall) * taper, ex, n, base + floor_t)},
         false, "tub");
  if (style == 0) {
    for (int sx = -1; sx <= 1; sx += 2) {
      for (int sy = -1; sy <= 1; sy += 2) {
        const Vec3 p(sx * Wd / 2 * taper * 0.6, sy * L / 2 * taper * 0.75, 0.0);
        b.Cylinder(p, 0.035, 0.025, base + 0.02, 10, "foot");
      }
    }
  }
  if (r.Chance(0.35)) {  // deck-mounted tap standing in the rim at the head end
    const double y = L / 2 - 0.5 * (wall - lip), top = H + r.Uniform(0.12, 0.25);
    b.Rod(Vec3(0, y, H - 0.02), Vec3(0, y, top), 0.015, 10, "faucet");
    b.Rod(Vec3(0, y + 0.015, top - 0.015), Vec3(0, y - r.Uniform(0.1, 0.2), top - 0.015), 0.012, 10,
          "faucet");
  }
  if (style == 1) {
    b.Loft({SuperRing(0, 0, Wd / 2 * taper * 0.85, L / 2 * taper * 0.85, ex, n, 0.0),
            SuperRing(0, 0, Wd / 2 * taper * 0.85, L / 2 * taper * 0.85, ex, n, base + 0.02)},
           false, "plinth");
  }
}

// ---------------------------------------------------------------------------------------
// Family tables.
// ---------------------------------------------------------------------------------------
const std::vector<std::vector<std::string>>& FamilyTable() {
  static const std::vector<std::vector<std::string>> kFamilies = {
      {"rect_four_leg_table", "coffee_table", "round_leg_table", "pedestal_table", "trestle_table",
       "desk"},
      {"four_leg_chair", "swivel_chair", "armchair", "stool"},
      {"closed_bookshelf", "open_back_bookshelf", "etagere", "cube_shelf"},
      {"sofa", "armless_sofa", "l_sofa"},
      {"round_bin", "square_bin", "tapered_bin", "pedal_bin"},
      {"door_cabinet", "drawer_cabinet", "sideboard", "fridge"},
      {"monitor", "tv_on_stand", "wall_tv", "crt_monitor"},
      {"freestanding_tub", "pedestal_tub", "built_in_tub"},
  };
  return kFamilies;
}

void BuildCad(int cad_class, int family, Builder& b, Rng& r, bool* symmetric) {
  switch (cad_class) {
    case kCadTable:
      if (family <= 1) FourLegTable(b, r, family == 1);
      if (family == 2) RoundLegTable(b, r);
      if (family == 3) PedestalTable(b, r);
      if (family == 4) TrestleTable(b, r);
      if (family == 5) Desk(b, r);
      break;
    case kCadChair:
      if (family == 0) FourLegChair(b, r);
      if (family == 1) SwivelChair(b, r);
      if (family == 2) Armchair(b, r);
      if (family == 3) Stool(b, r, symmetric);
      break;
    case kCadBookshelf:
      Bookshelf(b, r, family);
      break;
    case kCadSofa:
      Sofa(b, r, family);
      break;
    case kCadTrashBin:
      TrashBin(b, r, family, symmetric);
      break;
    case kCadCabinet:
      Cabinet(b, r, family);
      break;
    case kCadDisplay:
      Display(b, r, family);
      break;
    case kCadBathtub:
      Bathtub(b, r, family);
      break;
    default:
      break;
  }
}

// ---------------------------------------------------------------------------------------
// Distractors.
// ---------------------------------------------------------------------------------------
const std::vector<DistractorInfo>& DistractorTable() {
  static const std::vector<DistractorInfo> kInfo = {
      {"bed", kBed, DistractorPlacement::kFloor, 0.0, 0.0},
      {"door", kDoor, DistractorPlacement::kWall, 0.0, 0.0},
      {"window", kWindow, DistractorPlacement::kWall, 0.7, 1.1},
      {"picture", kPicture, DistractorPlacement::kWall, 1.1, 1.6},
      {"curtain", kCurtain, DistractorPlacement::kWall, 0.0, 0.05},
      {"ottoman", kOtherFurniture, DistractorPlacement::kFloor, 0.0, 0.0},
      {"bench", kOtherFurniture, DistractorPlacement::kFloor, 0.0, 0.0},
      {"radiator", kOtherFurniture, DistractorPlacement::kWall, 0.05, 0.2},
      {"kitchen_cabinet", kKitchenCabinet, DistractorPlacement::kFloor, 0.0, 0.0},
      {"box", -1, DistractorPlacement::kFloor, 0.0, 0.0},
      {"floor_lamp", -1, DistractorPlacement::kFloor, 0.0, 0.0},
      {"table_lamp", -1, DistractorPlacement::kOnSurface, 0.0, 0.0},
      {"plant", -1, DistractorPlacement::kFloor, 0.0, 0.0},
      {"books", -1, DistractorPlacement::kOnSurface, 0.0, 0.0},
  };
  return kInfo;
}

void Bed(Builder& b, Rng& r) {
  const double W = r.Chance(0.5) ? r.Uniform(0.9, 1.1) : r.Uniform(1.4, 1.9);
  const double L = r.Uniform(1.95, 2.15);  // along x (foot end at +x)
  const double fz = r.Uniform(0.15, 0.3), mt = r.Uniform(0.15, 0.28);
  b.BoxMinMax(Vec3(-L / 2, -W / 2, fz), Vec3(L / 2, W / 2, fz + 0.12), "frame");
  b.BoxMinMax(Vec3(-L / 2 + 0.02, -W / 2 + 0.02, fz + 0.1),
              Vec3(L / 2 - 0.02, W / 2 - 0.02, fz + 0.1 + mt), "mattress");
  FourLegs(b, L / 2, W / 2, 0.0, fz + 0.01, 0.06, false);
  const double hh = r.Uniform(0.8, 1.3);
  b.BoxMinMax(Vec3(-L / 2 - 0.06, -W / 2 - 0.02, 0), Vec3(-L / 2, W / 2 + 0.02, hh), "headboard");
  if (r.Chance(0.5)) {
    b.BoxMinMax(Vec3(L / 2, -W / 2 - 0.02, 0), Vec3(L / 2 + 0.04, W / 2 + 0.02, fz + 0.3),
                "footboard");
  }
  const int pillows = W > 1.3 ? 2 : 1;
  for (int i = 0; i < pillows; ++i) {
    const double yc = -W / 2 + W * (i + 0.5) / pillows;
    const double pz = fz + 0.1 + mt;
    b.Loft({SuperRing(-L / 2 + 0.25, yc, 0.17, (W / pillows - 0.1) / 2, 4.0, 24, pz - 0.01),
            SuperRing(-L / 2 + 0.25, yc, 0.15, (W / pillows - 0.14) / 2, 4.0, 24, pz + 0.11)},
           false, "pillow");
  }
}

void Door(Builder& b, Rng& r) {
  const double W = r.Uniform(0.75, 1.0), H = r.Uniform(1.95, 2.15), ft = r.Uniform(0.05, 0.1);
  const double depth = r.Uniform(0.1, 0.2);
  b.BoxMinMax(Vec3(-depth, -W / 2 - ft, 0), Vec3(0.01, -W / 2, H + ft), "frame");
  b.BoxMinMax(Vec3(-depth, W / 2, 0), Vec3(0.01, W / 2 + ft, H + ft), "frame");
  b.BoxMinMax(Vec3(-depth, -W / 2, H), Vec3(0.01, W / 2, H + ft), "frame");
  b.BoxMinMax(Vec3(-depth * 0.7, -W / 2, 0.005), Vec3(-depth * 0.7 + 0.04, W / 2, H), "leaf");
  const double hy = r.Chance(0.5) ? W / 2 - 0.07 : -W / 2 + 0.07;
  b.Box(Vec3(-depth * 0.7 + 0.06, hy, 1.0), Vec3(0.04, 0.12, 0.02), "handle");
}

void Window(Builder& b, Rng& r) {
  const double W = r.Uniform(0.6, 1.8), H = r.Uniform(0.8, 1.6), ft = r.Uniform(0.04, 0.08);
  const double depth = r.Uniform(0.06, 0.15);
  b.BoxMinMax(Vec3(-depth, -W / 2, 0), Vec3(0, -W / 2 + ft, H), "frame");
  b.BoxMinMax(Vec3(-depth, W / 2 - ft, 0), Vec3(0, W / 2, H), "frame");
  b.BoxMinMax(Vec3(-depth, -W / 2 + ft, 0), Vec3(0, W / 2 - ft, ft), "frame");
  b.BoxMinMax(Vec3(-depth, -W / 2 + ft, H - ft), Vec3(0, W / 2 - ft, H), "frame");
  b.BoxMinMax(Vec3(-depth * 0.6, -W / 2 + ft, ft), Vec3(-depth * 0.6 + 0.01, W / 2 - ft, H - ft),
              "glass");
  if (W > 1.0 && r.Chance(0.7)) {
    b.BoxMinMax(Vec3(-depth, -ft / 3, ft), Vec3(0, ft / 3, H - ft), "mullion");
  }
  if (r.Chance(0.6)) {
    b.BoxMinMax(Vec3(-depth, -W / 2 - 0.04, -0.03), Vec3(0.05, W / 2 + 0.04, 0.0), "sill");
  }
}

void Picture(Builder& b, Rng& r) {
  const double W = r.Uniform(0.25, 1.2), H = W * r.Uniform(0.6, 1.4), t = r.Uniform(0.01, 0.04);
  const double fw = r.Uniform(0.015, 0.05);
  b.BoxMinMax(Vec3(-t, -W / 2, 0), Vec3(-t + 0.006, W / 2, H), "canvas");
  b.BoxMinMax(Vec3(-t, -W / 2, 0), Vec3(0, -W / 2 + fw, H), "frame");
  b.BoxMinMax(Vec3(-t, W / 2 - fw, 0), Vec3(0, W / 2, H), "frame");
  b.BoxMinMax(Vec3(-t, -W / 2 + fw, 0), Vec3(0, W / 2 - fw, fw), "frame");
  b.BoxMinMax(Vec3(-t, -W / 2 + fw, H - fw), Vec3(0, W / 2 - fw, H), "frame");
}

void Curtain(Builder& b, Rng& r) {
  const double W = r.Uniform(0.8, 2.4), H = r.Uniform(1.5, 2.5), depth = r.Uniform(0.06, 0.12);
  const int folds = std::max(4, static_cast<int>(W / r.Uniform(0.08, 0.14)));
  const double fw = W / folds;
  // Pleats: a zig-zag of thin full-height panels.
  for (int i = 0; i < folds; ++i) {
    const double y0 = -W / 2 + i * fw, y1 = y0 + fw;
    const double xa = (i % 2 == 0) ? -depth : -0.01, xb = (i % 2 == 0) ? -0.01 : -depth;
    const Vec3 a(xa, y0, 0.5 * H + 0.01), c(xb, y1, 0.5 * H + 0.01);  // hem 1 cm above the floor
    b.Beam(a, c, 0.008, H - 0.02, "cloth");
  }
  b.Rod(Vec3(-depth * 0.5, -W / 2 - 0.1, H + 0.01), Vec3(-depth * 0.5, W / 2 + 0.1, H + 0.01),
        0.015, 10, "rod");
}

void Ottoman(Builder& b, Rng& r) {
  if (r.Chance(0.4)) {
    const double R = r.Uniform(0.2, 0.35), H = r.Uniform(0.35, 0.45);
    b.Cylinder(Vec3(0, 0, 0), R, R, H, 32, "body");
    return;
  }
  const double W = r.Uniform(0.4, 0.9), D = r.Uniform(0.4, 0.7), H = r.Uniform(0.35, 0.45);
  const double f = r.Uniform(0.0, 0.08);
  b.Loft({SuperRing(0, 0, D / 2, W / 2, 8.0, 32, f), SuperRing(0, 0, D / 2, W / 2, 8.0, 32, H)},
         false, "body");
  if (f > 0.02) FourLegs(b, D / 2 - 0.03, W / 2 - 0.03, 0.0, f + 0.01, 0.035, true);
}

void Bench(Builder& b, Rng& r) {
  const double L = r.Uniform(0.9, 1.8), D = r.Uniform(0.3, 0.45), H = r.Uniform(0.4, 0.48);
  const double t = r.Uniform(0.03, 0.06);
  b.BoxMinMax(Vec3(-D / 2, -L / 2, H - t), Vec3(D / 2, L / 2, H), "seat");
  if (r.Chance(0.5)) {
    FourLegs(b, D / 2, L / 2 - 0.05, 0.0, H - t, r.Uniform(0.03, 0.06), r.Chance(0.5));
  } else {
    for (int s = -1; s <= 1; s += 2) {
      b.BoxMinMax(Vec3(-D / 2, s * (L / 2 - 0.1) - 0.02, 0),
                  Vec3(D / 2, s * (L / 2 - 0.1) + 0.02, H - t), "side");
    }
  }
}

void Radiator(Builder& b, Rng& r) {
  const double W = r.Uniform(0.5, 1.4), H = r.Uniform(0.4, 0.8), D = r.Uniform(0.06, 0.12);
  const int fins = std::max(4, static_cast<int>(W / r.Uniform(0.05, 0.09)));
  for (int i = 0; i < fins; ++i) {
    const double y = -W / 2 + (i + 0.5) * W / fins;
    b.BoxMinMax(Vec3(-D, y - 0.015, 0.0), Vec3(0.0, y + 0.015, H), "fin");
  }
  b.BoxMinMax(Vec3(-D * 0.7, -W / 2, H * 0.85), Vec3(-D * 0.3, W / 2, H * 0.92), "pipe");
  b.BoxMinMax(Vec3(-D * 0.7, -W / 2, H * 0.08), Vec3(-D * 0.3, W / 2, H * 0.15), "pipe");
}

void KitchenCabinet(Builder& b, Rng& r) {
  const double W = r.Uniform(0.6, 2.4), D = r.Uniform(0.55, 0.65), H = r.Uniform(0.85, 0.92);
  const double plinth = r.Uniform(0.08, 0.15);
  b.BoxMinMax(Vec3(-D / 2, -W / 2, plinth), Vec3(D / 2 - 0.02, W / 2, H - 0.03), "body");
  b.BoxMinMax(Vec3(-D / 2, -W / 2, 0), Vec3(D / 2 - 0.08, W / 2, plinth + 0.005), "plinth");
  b.BoxMinMax(Vec3(-D / 2, -W / 2, H - 0.03), Vec3(D / 2 + 0.03, W / 2, H + 0.01), "countertop");
  const int n = std::max(1, static_cast<int>(std::lround(W / 0.5)));
  Doors(b, D / 2 - 0.02, -W / 2, W / 2, plinth, H - 0.03 - 0.18, n, r.Int(0, 2));
  const double gap = 0.004;
  for (int i = 0; i < n; ++i) {
    const double y0 = -W / 2 + W * i / n, y1 = -W / 2 + W * (i + 1) / n;
    b.BoxMinMax(Vec3(D / 2 - 0.022, y0 + gap, H - 0.21 + gap),
                Vec3(D / 2 - 0.004, y1 - gap, H - 0.03 - gap), "drawer");
  }
}

void ClutterBox(Builder& b, Rng& r) {
  const Vec3 s(r.Uniform(0.2, 0.7), r.Uniform(0.2, 0.7), r.Uniform(0.15, 0.6));
  b.BoxMinMax(Vec3(-s.x() / 2, -s.y() / 2, 0), Vec3(s.x() / 2, s.y() / 2, s.z()), "box");
  if (r.Chance(0.4)) {  // a second box stacked on top
    const Vec3 t(s.x() * r.Uniform(0.5, 0.95), s.y() * r.Uniform(0.5, 0.95), r.Uniform(0.1, 0.4));
    b.BoxMinMax(Vec3(-t.x() / 2, -t.y() / 2, s.z()), Vec3(t.x() / 2, t.y() / 2, s.z() + t.z()),
                "box");
  }
}

void Lamp(Builder& b, Rng& r, bool floor) {
  const double H = floor ? r.Uniform(1.4, 1.8) : r.Uniform(0.35, 0.6);
  const double br = floor ? r.Uniform(0.12, 0.18) : r.Uniform(0.06, 0.1);
  b.Cylinder(Vec3(0, 0, 0), br, br * 0.9, 0.025, 20, "base");
  const double sr_b = floor ? r.Uniform(0.18, 0.25) : r.Uniform(0.1, 0.18);
  const double sh = floor ? r.Uniform(0.2, 0.3) : r.Uniform(0.12, 0.2);
  b.Cylinder(Vec3(0, 0, 0.02), 0.012, 0.012, H - sh * 0.5, 10, "pole");
  b.Cylinder(Vec3(0, 0, H - sh), sr_b, sr_b * r.Uniform(0.6, 0.9), sh, 24, "shade");
}

void Plant(Builder& b, Rng& r) {
  const double pr = r.Uniform(0.1, 0.22), ph = r.Uniform(0.15, 0.35);
  b.Cylinder(Vec3(0, 0, 0), pr * 0.75, pr, ph, 20, "pot");
  const double stem = r.Uniform(0.2, 0.9);
  b.Cylinder(Vec3(0, 0, ph - 0.01), 0.015, 0.01, stem, 8, "stem");
  // Foliage: a blob of randomly rotated boxes around the stem top.
  const int leaves = r.Int(6, 14);
  const double spread = r.Uniform(0.15, 0.35);
  for (int i = 0; i < leaves; ++i) {
    const double a = r.Uniform(0, 2 * kPi), rad = spread * std::sqrt(r.Unit());
    const Vec3 c(rad * std::cos(a), rad * std::sin(a),
                 ph + stem * r.Uniform(0.5, 1.0) + r.Uniform(-0.1, 0.1));
    const Eigen::Matrix3d R =
        RotZ(r.Uniform(0, kPi)) * RotX(r.Uniform(-0.6, 0.6)) * RotY(r.Uniform(-0.6, 0.6));
    const double s = r.Uniform(0.08, 0.2);
    b.Box(c, Vec3(s, s * r.Uniform(0.5, 1.0), s * r.Uniform(0.4, 0.9)), "foliage", R);
    const Vec3 top(0, 0, ph + stem - 0.02);
    if ((c - top).norm() > 0.03) b.Rod(top, c, 0.006, 6, "twig");  // leaves hang on twigs
  }
}

void Books(Builder& b, Rng& r) {
  const int n = r.Int(3, 10);
  const bool lying = r.Chance(0.3);
  double y = 0.0, z = 0.0;
  for (int i = 0; i < n; ++i) {
    const double d = r.Uniform(0.14, 0.22), h = r.Uniform(0.18, 0.3), t = r.Uniform(0.015, 0.05);
    if (lying) {
      b.BoxMinMax(Vec3(-d / 2, -h / 2, z), Vec3(d / 2, h / 2, z + t), "book");
      z += t;
    } else {
      b.BoxMinMax(Vec3(-d / 2, y, 0), Vec3(d / 2, y + t, h), "book");
      y += t;
    }
  }
}

void BuildDistractor(int kind, Builder& b, Rng& r) {
  switch (kind) {
    case 0:
      Bed(b, r);
      break;
    case 1:
      Door(b, r);
      break;
    case 2:
      Window(b, r);
      break;
    case 3:
      Picture(b, r);
      break;
    case 4:
      Curtain(b, r);
      break;
    case 5:
      Ottoman(b, r);
      break;
    case 6:
      Bench(b, r);
      break;
    case 7:
      Radiator(b, r);
      break;
    case 8:
      KitchenCabinet(b, r);
      break;
    case 9:
      ClutterBox(b, r);
      break;
    case 10:
      Lamp(b, r, true);
      break;
    case 11:
      Lamp(b, r, false);
      break;
    case 12:
      Plant(b, r);
      break;
    default:
      Books(b, r);
      break;
  }
}

}  // namespace

CadModel GenerateCadModel(int cad_class, std::uint64_t seed) {
  if (cad_class < 0 || cad_class >= kNumCadClasses) {
    throw InvalidArgument("GenerateCadModel: CAD class " + std::to_string(cad_class) +
                          " out of range [0, " + std::to_string(kNumCadClasses) + ")");
  }
  const auto& families = FamilyTable()[cad_class];
  Rng r(seed ^ Mix64(0xcad0000ULL + static_cast<std::uint64_t>(cad_class)));
  const int family = static_cast<int>(r.Next() % families.size());
  CadModel m;
  m.cad_class = cad_class;
  // Desks carry ScanNet's own "desk" label (RFS 12, which maps back to the CAD table class).
  m.rfs_class = families[family] == "desk" ? kDesk : CadToRfs(cad_class);
  m.synset = CadSynsets()[cad_class];
  m.family = families[family];
  m.model_id = ModelId("dimr-cad", cad_class, seed);
  m.seed = seed;
  Builder b;
  bool symmetric = false;
  BuildCad(cad_class, family, b, r, &symmetric);
  b.Finish(&m);
  m.symmetric_about_z = symmetric;
  return m;
}

int NumDistractorKinds() { return static_cast<int>(DistractorTable().size()); }

const DistractorInfo& GetDistractorInfo(int kind) {
  if (kind < 0 || kind >= NumDistractorKinds()) {
    throw InvalidArgument("distractor kind " + std::to_string(kind) + " out of range [0, " +
                          std::to_string(NumDistractorKinds()) + ")");
  }
  return DistractorTable()[kind];
}

CadModel GenerateDistractor(int kind, std::uint64_t seed) {
  const DistractorInfo& info = GetDistractorInfo(kind);
  Rng r(seed ^ Mix64(0xd157000ULL + static_cast<std::uint64_t>(kind)));
  CadModel m;
  m.cad_class = kNonCad;
  m.rfs_class = info.rfs_class;
  m.family = info.name;
  m.model_id = ModelId("dimr-distractor", kind, seed);
  m.seed = seed;
  m.distractor_kind = kind;
  Builder b;
  BuildDistractor(kind, b, r);
  b.Finish(&m);
  return m;
}

std::vector<std::string> CadFamilies(int cad_class) {
  if (cad_class < 0 || cad_class >= kNumCadClasses) {
    throw InvalidArgument("CadFamilies: CAD class " + std::to_string(cad_class) +
                          " out of range [0, " + std::to_string(kNumCadClasses) + ")");
  }
  return FamilyTable()[cad_class];
}

}  // namespace dimr::data
