// Light Field Distance, re-implemented from ../shared/reference/dimr-metrics.md section 6.
#include "dimr/eval/lfd.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

#include "dimr/geometry/error.h"

namespace dimr::eval::lfd {

namespace {

#include "lfd_tables.inc"

using geometry::Vec3;
using geometry::Vec3i;

constexpr int W = kSize;
constexpr int kNumPix = kSize * kSize;

inline bool Fg(const Image& img, long idx) {
  return idx >= 0 && idx < kNumPix && img[static_cast<std::size_t>(idx)] < 255;
}

// ---------------------------------------------------------------------------------------------
// ART basis LUT: 102 x 102 grid (x fastest) of 36 complex values (p = 0..11, r = 0..2),
// stored as 72 doubles (re, im) per node; row/column 101 is zero padding.
constexpr int kLut = 102;
constexpr int kCoef = 36;
struct ArtLut {
  std::vector<double> v;  // ((y * kLut + x) * kCoef + p*3 + r) * 2 + {0 re, 1 im}
  ArtLut() : v(static_cast<std::size_t>(kLut) * kLut * kCoef * 2, 0.0) {
    const double kPi = 3.141592653;  // the reference's constant
    for (int y = 0; y <= 100; ++y) {
      for (int x = 0; x <= 100; ++x) {
        const double dx = x - 50, dy = y - 50;
        const double rho = std::hypot(dx, dy);
        if (!(rho < 50.0)) continue;
        const double theta = std::atan2(dy, dx);
        double* node = &v[(static_cast<std::size_t>(y) * kLut + x) * kCoef * 2];
        for (int p = 0; p < 12; ++p) {
          for (int r = 0; r < 3; ++r) {
            const double radial = std::cos(kPi * r * rho / 50.0);
            node[(p * 3 + r) * 2] = radial * std::cos(p * theta);
            node[(p * 3 + r) * 2 + 1] = radial * std::sin(p * theta);
          }
        }
      }
    }
  }
};
const ArtLut& Lut() {
  static const ArtLut lut;
  return lut;
}

// The same basis factorised per node: 3 radial values and 12 (cos p.theta, sin p.theta) pairs
// (216 instead of 576 bytes per node); the projection multiplies (w * radial) * angular, a
// regrouping of the reference's w * (radial * angular) that differs by rounding only.
struct ArtFactors {
  std::vector<double> rad;  // (y * kLut + x) * 3 + r
  std::vector<double> ang;  // ((y * kLut + x) * 12 + p) * 2 + {0 cos, 1 sin}
  ArtFactors()
      : rad(static_cast<std::size_t>(kLut) * kLut * 3, 0.0),
        ang(static_cast<std::size_t>(kLut) * kLut * 24, 0.0) {
    const double kPi = 3.141592653;
    for (int y = 0; y <= 100; ++y) {
      for (int x = 0; x <= 100; ++x) {
        const double dx = x - 50, dy = y - 50;
        const double rho = std::hypot(dx, dy);
        if (!(rho < 50.0)) continue;
        const double theta = std::atan2(dy, dx);
        const std::size_t node = static_cast<std::size_t>(y) * kLut + x;
        for (int r = 0; r < 3; ++r) rad[node * 3 + r] = std::cos(kPi * r * rho / 50.0);
        for (int p = 0; p < 12; ++p) {
          ang[(node * 12 + p) * 2] = std::cos(p * theta);
          ang[(node * 12 + p) * 2 + 1] = std::sin(p * theta);
        }
      }
    }
  }
};
const ArtFactors& Factors() {
  static const ArtFactors f;
  return f;
}

// Floor / ceiling of a / b for b > 0.
inline std::int64_t FloorDiv(std::int64_t a, std::int64_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}
inline std::int64_t CeilDiv(std::int64_t a, std::int64_t b) { return -FloorDiv(-a, b); }

std::uint8_t Quantize(double v, double scale) {
  const double q = v * scale;
  if (!(q >= 0.0)) return 0;
  if (q >= 255.0) return 255;
  return static_cast<std::uint8_t>(static_cast<int>(q));
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Tables.

const std::array<std::array<Vec3, kViews>, kSets>& CameraSets() {
  static const auto kSetsTable = [] {
    std::array<std::array<Vec3, kViews>, kSets> s;
    for (int k = 0; k < kSets; ++k) {
      for (int v = 0; v < kViews; ++v) {
        s[k][v] = Vec3(kCameraTable[k][v][0], kCameraTable[k][v][1], kCameraTable[k][v][2]);
      }
    }
    return s;
  }();
  return kSetsTable;
}

const std::array<std::array<std::uint8_t, kViews>, 60>& Align10() {
  static const auto kTable = [] {
    std::array<std::array<std::uint8_t, kViews>, 60> t{};
    for (int r = 0; r < 60; ++r) {
      for (int m = 0; m < kViews; ++m) t[r][m] = static_cast<std::uint8_t>(kAlignTable[r][m] - '0');
    }
    return t;
  }();
  return kTable;
}

bool DelTab(int code) {
  if (code < 0 || code > 255) return false;
  return kDelTable[code / 32][code % 32] == '1';
}

// ---------------------------------------------------------------------------------------------
// Normalisation and rasterisation.

std::vector<Vec3> NormalizeForLfd(const geometry::TriangleMesh& mesh) {
  geometry::AABB box;
  const int nv = static_cast<int>(mesh.vertices.size());
  for (const Vec3i& f : mesh.faces) {
    for (int c = 0; c < 3; ++c) {
      if (f[c] < 0 || f[c] >= nv) {
        throw InvalidArgument("LFD: face index " + std::to_string(f[c]) + " out of range (" +
                              std::to_string(nv) + " vertices)");
      }
      box.Extend(mesh.vertices[f[c]]);
    }
  }
  std::vector<Vec3> out(mesh.vertices.size(), Vec3::Zero());
  if (box.Empty()) return out;
  const Vec3 centre = 0.5 * (box.min + box.max);
  const double extent = (box.max - box.min).maxCoeff();
  const double scale = extent > 0 ? 1.0 / extent : 1.0;
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = (mesh.vertices[i] - centre) * scale;
  return out;
}

Image RenderSilhouette(const std::vector<Vec3>& vertices, const std::vector<Vec3i>& faces,
                       const Vec3& eye) {
  Image img(kNumPix, 255);
  const Vec3 up(0, 1, 0);
  const Vec3 f = -eye / eye.norm();
  const Vec3 s = f.cross(up).normalized();
  const Vec3 u = s.cross(f);
  // Window coordinates snapped to 1/256 pixel, as integers in 1/256-pixel units.
  std::vector<std::int64_t> px(vertices.size()), py(vertices.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const Vec3 d = vertices[i] - eye;
    const double xw = (s.dot(d) + 1.0) * 128.0;
    const double yw = (u.dot(d) + 1.0) * 128.0;
    px[i] = static_cast<std::int64_t>(std::nearbyint(xw * 256.0));
    py[i] = static_cast<std::int64_t>(std::nearbyint(yw * 256.0));
  }
  for (const Vec3i& tri : faces) {
    int a = tri[0], b = tri[1], c = tri[2];
    std::int64_t ax = px[a], ay = py[a], bx = px[b], by = py[b], cx = px[c], cy = py[c];
    const std::int64_t area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if (area == 0) continue;
    if (area < 0) {
      std::swap(bx, cx);
      std::swap(by, cy);
    }
    // Pixel range whose centres (x*256+128) may be inside.
    const std::int64_t minx = std::min({ax, bx, cx}), maxx = std::max({ax, bx, cx});
    const std::int64_t miny = std::min({ay, by, cy}), maxy = std::max({ay, by, cy});
    int x0 = static_cast<int>(std::max<std::int64_t>(0, (minx - 128 + 255) >> 8));
    int x1 = static_cast<int>(std::min<std::int64_t>(W - 1, (maxx - 128) >> 8));
    int y0 = static_cast<int>(std::max<std::int64_t>(0, (miny - 128 + 255) >> 8));
    int y1 = static_cast<int>(std::min<std::int64_t>(W - 1, (maxy - 128) >> 8));
    if (x0 > x1 || y0 > y1) continue;
    // Edge functions E(p) = dx * (p.y - v0.y) - dy * (p.x - v0.x), > 0 inside (CCW); an edge
    // counts its zero set iff it is left/top: dy < 0, or dy == 0 and dx < 0.
    const std::int64_t ex[3] = {bx - ax, cx - bx, ax - cx};
    const std::int64_t ey[3] = {by - ay, cy - by, ay - cy};
    const std::int64_t ox[3] = {ax, bx, cx};
    const std::int64_t oy[3] = {ay, by, cy};
    std::int64_t bias[3];
    for (int e = 0; e < 3; ++e) {
      const bool top_left = ey[e] < 0 || (ey[e] == 0 && ex[e] < 0);
      bias[e] = top_left ? 0 : -1;  // E + bias >= 0  <=>  E > 0 (or E >= 0 for top-left)
    }
    // Per row, each edge bounds x from one side: E_k(x) = A_k + B_k * x >= 0 with
    // B_k = -256 * ey_k; the covered pixels form one span, filled at once.
    for (int y = y0; y <= y1; ++y) {
      const std::int64_t pyc = static_cast<std::int64_t>(y) * 256 + 128;
      std::int64_t lo = x0, hi = x1;
      for (int k = 0; k < 3 && lo <= hi; ++k) {
        const std::int64_t a = ex[k] * (pyc - oy[k]) - ey[k] * (128 - ox[k]) + bias[k];
        const std::int64_t b = -256 * ey[k];
        if (b == 0) {
          if (a < 0) hi = lo - 1;
        } else if (b > 0) {
          lo = std::max(lo, CeilDiv(-a, b));
        } else {
          hi = std::min(hi, FloorDiv(a, -b));
        }
      }
      if (lo <= hi) {
        std::memset(&img[static_cast<std::size_t>(y) * W + lo], 0,
                    static_cast<std::size_t>(hi - lo + 1));
      }
    }
  }
  return img;
}

// ---------------------------------------------------------------------------------------------
// Per-view features.

ViewCentre ComputeCentre(const Image& img) {
  int minx = W, maxx = -1, miny = W, maxy = -1, n = 0;
  for (int y = 0; y < W; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    int rn = 0;
    for (int x = 0; x < W; ++x) rn += row[x] < 255;  // branch-free, vectorised
    if (rn == 0) continue;
    n += rn;
    int a = 0;
    while (row[a] == 255) ++a;
    int b = W - 1;
    while (row[b] == 255) --b;
    minx = std::min(minx, a);
    maxx = std::max(maxx, b);
    miny = std::min(miny, y);
    maxy = std::max(maxy, y);
  }
  ViewCentre c;
  c.count = n;
  if (n == 0) return c;
  c.minx = minx;
  c.maxx = maxx;
  c.miny = miny;
  c.maxy = maxy;
  if (maxx <= 0) return c;
  c.cx = (minx + maxx) / 2.0;
  c.cy = (miny + maxy) / 2.0;
  return c;
}

namespace {
double MaxRadius(const Image& img, const ViewCentre& c) {
  double best = 0.0;
  if (c.count == 0) return 0.0;
  for (int y = c.miny; y <= c.maxy; ++y) {
    for (int x = c.minx; x <= c.maxx; ++x) {
      if (img[static_cast<std::size_t>(y) * W + x] < 255) {
        const double dx = x - c.cx, dy = y - c.cy;
        best = std::max(best, dx * dx + dy * dy);
      }
    }
  }
  return std::sqrt(best);
}
}  // namespace

std::uint8_t EccentricityByte(const Image& img, const ViewCentre& c) {
  if (c.count <= 1) return 0;
  double m20 = 0, m02 = 0, m11 = 0;
  for (int y = c.miny; y <= c.maxy; ++y) {
    for (int x = c.minx; x <= c.maxx; ++x) {
      if (img[static_cast<std::size_t>(y) * W + x] < 255) {
        const double dx = x - c.cx, dy = y - c.cy;
        m20 += dx * dx;
        m02 += dy * dy;
        m11 += dx * dy;
      }
    }
  }
  const double den = (m20 + m02) * (m20 + m02);
  if (!(den > 0)) return 0;
  double ecc = ((m20 - m02) * (m20 - m02) + 4.0 * m11 * m11) / den;
  ecc = std::min(1.0, ecc);
  return Quantize(ecc, 256.0);
}

std::uint8_t CircularityByte(const Image& img) {
  const ViewCentre bb = ComputeCentre(img);
  if (bb.count == 0) return 0;
  long area = 0, perim = 0;
  for (int y = bb.miny; y <= bb.maxy; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    const bool interior_row = y > 0 && y < W - 1;
    for (int x = bb.minx; x <= bb.maxx; ++x) {
      if (row[x] == 255) continue;
      ++area;
      bool edge = false;
      if (interior_row && x > 0 && x < W - 1) {
        const std::uint8_t* up = row + W;
        const std::uint8_t* dn = row - W;
        edge = row[x - 1] == 255 || row[x + 1] == 255 || up[x - 1] == 255 || up[x] == 255 ||
               up[x + 1] == 255 || dn[x - 1] == 255 || dn[x] == 255 || dn[x + 1] == 255;
      } else {
        for (int dy = -1; dy <= 1 && !edge; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = x + dx, ny = y + dy;
            if ((!dx && !dy) || nx < 0 || ny < 0 || nx >= W || ny >= W) continue;
            if (img[static_cast<std::size_t>(ny) * W + nx] == 255) {
              edge = true;
              break;
            }
          }
        }
      }
      if (edge) ++perim;
    }
  }
  if (perim == 0) return 0;
  double cir = 12.5663704 * static_cast<double>(area) / (static_cast<double>(perim) * perim);
  cir = std::min(1.0, cir);
  return Quantize(cir, 256.0);
}

void ArtBytesDirect(const Image& img, const ViewCentre& c, double r, std::uint8_t* out35) {
  std::fill(out35, out35 + kArt, 0);
  if (c.count == 0) return;
  const double* lut = Lut().v.data();
  double re[kCoef] = {0}, im[kCoef] = {0};
  for (int y = 0; y < W; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    const double ty = (y - c.cy) * r + 50.0;
    const int iy = static_cast<int>(ty);
    const double fy = ty - iy;
    if (iy < 0 || iy > 100) continue;  // unreachable for r = 50 / R_k; guards the LUT
    for (int x = 0; x < W; ++x) {
      if (row[x] == 255) continue;
      const double tx = (x - c.cx) * r + 50.0;
      const int ix = static_cast<int>(tx);
      if (ix < 0 || ix > 100) continue;
      const double fx = tx - ix;
      const double* v00 = lut + (static_cast<std::size_t>(iy) * kLut + ix) * kCoef * 2;
      const double* v10 = v00 + kCoef * 2;
      const double* v01 = v00 + static_cast<std::size_t>(kLut) * kCoef * 2;
      const double* v11 = v01 + kCoef * 2;
      const double gx = 1.0 - fx, gy = 1.0 - fy;
      for (int k = 0; k < kCoef; ++k) {
        const double x1r = v00[2 * k] * gx + v10[2 * k] * fx;
        const double x1i = v00[2 * k + 1] * gx + v10[2 * k + 1] * fx;
        const double x2r = v01[2 * k] * gx + v11[2 * k] * fx;
        const double x2i = v01[2 * k + 1] * gx + v11[2 * k + 1] * fx;
        re[k] += x1r * gy + x2r * fy;
        im[k] -= x1i * gy + x2i * fy;
      }
    }
  }
  const double n = c.count;
  // (0,0) dropped; raw magnitudes (the reference's in-place normalisation divides by 1).
  for (int k = 1; k < kCoef; ++k) {
    const double mag = std::hypot(re[k] / n, im[k] / n);
    out35[k - 1] = Quantize(mag, 256.0);
  }
}

void ArtBytes(const Image& img, const ViewCentre& c, double r, std::uint8_t* out35) {
  std::fill(out35, out35 + kArt, 0);
  if (c.count == 0) return;
  // Bilinear splat: sum_p V(t_p) = sum_nodes w_node V(node), with w the bilinear weights.
  thread_local std::vector<double> w;
  w.assign(static_cast<std::size_t>(kLut) * kLut, 0.0);
  int nminx = kLut, nmaxx = -1, nminy = kLut, nmaxy = -1;
  for (int y = c.miny; y <= c.maxy; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    const double ty = (y - c.cy) * r + 50.0;
    const int iy = static_cast<int>(ty);
    const double fy = ty - iy;
    if (iy < 0 || iy > 100) continue;
    const double gy = 1.0 - fy;
    double* w0 = &w[static_cast<std::size_t>(iy) * kLut];
    double* w1 = w0 + kLut;
    for (int x = c.minx; x <= c.maxx; ++x) {
      if (row[x] == 255) continue;
      const double tx = (x - c.cx) * r + 50.0;
      const int ix = static_cast<int>(tx);
      if (ix < 0 || ix > 100) continue;
      const double fx = tx - ix;
      const double gx = 1.0 - fx;
      w0[ix] += gx * gy;
      w0[ix + 1] += fx * gy;
      w1[ix] += gx * fy;
      w1[ix + 1] += fx * fy;
      nminx = std::min(nminx, ix);
      nmaxx = std::max(nmaxx, ix + 1);
      nminy = std::min(nminy, iy);
      nmaxy = std::max(nmaxy, iy + 1);
    }
  }
  const ArtFactors& fac = Factors();
  double acc[kCoef * 2] = {0};
  for (int y = nminy; y <= nmaxy; ++y) {
    for (int x = nminx; x <= nmaxx; ++x) {
      const std::size_t node = static_cast<std::size_t>(y) * kLut + x;
      const double wt = w[node];
      if (wt == 0.0) continue;
      const double* rad = &fac.rad[node * 3];
      const double* ang = &fac.ang[node * 24];
      const double wr[3] = {wt * rad[0], wt * rad[1], wt * rad[2]};
      for (int p = 0; p < 12; ++p) {
        const double cp = ang[2 * p], sp = ang[2 * p + 1];
        for (int r = 0; r < 3; ++r) {
          acc[(p * 3 + r) * 2] += wr[r] * cp;
          acc[(p * 3 + r) * 2 + 1] += wr[r] * sp;
        }
      }
    }
  }
  const double n = c.count;
  for (int k = 1; k < kCoef; ++k) {
    const double mag = std::hypot(acc[2 * k] / n, -acc[2 * k + 1] / n);
    out35[k - 1] = Quantize(mag, 256.0);
  }
}

std::vector<int> TraceContour(const Image& img) {
  int start = -1;
  for (int i = 0; i < kNumPix; ++i) {
    if (img[i] < 255) {
      start = i;
      break;
    }
  }
  if (start < 0) return {};
  const bool may_loss = Fg(img, start + W - 1) && !Fg(img, start + W) &&
                        (Fg(img, start + W + 1) || Fg(img, start + 1));
  // Candidate offsets (dx, drow) and the new direction, per direction.
  static const int kOff[4][3][3] = {
      {{-1, +1, 3}, {0, +1, 0}, {+1, +1, 0}},
      {{+1, +1, 0}, {+1, 0, 1}, {+1, -1, 1}},
      {{+1, -1, 1}, {0, -1, 2}, {-1, -1, 2}},
      {{-1, -1, 2}, {-1, 0, 3}, {-1, +1, 3}},
  };
  std::vector<int> contour = {start};
  int dir = 0;
  int cur = start;
  const std::size_t kMaxLen = 4 * static_cast<std::size_t>(kNumPix);
  while (true) {
    bool moved = false;
    for (int rot = 0; rot < 4 && !moved; ++rot) {
      for (int k = 0; k < 3; ++k) {
        const long nxt = static_cast<long>(cur) + kOff[dir][k][0] + kOff[dir][k][1] * W;
        if (Fg(img, nxt)) {
          cur = static_cast<int>(nxt);
          dir = kOff[dir][k][2];
          contour.push_back(cur);
          moved = true;
          break;
        }
      }
      if (!moved) dir = (dir + 1) % 4;
    }
    if (!moved) return {};
    if (cur == start && (!may_loss || dir != 1)) break;
    if (contour.size() > kMaxLen) return {};
  }
  return contour;
}

namespace {

// Multipart test: flood "outside" from the image border through unmarked pixels.
bool IsMultiPart(const std::vector<int>& contour, const Image& img) {
  // Pixels outside the foreground bbox grown by one are background and connected to the image
  // border, so the flood runs inside that window, seeded from its boundary ring.
  const ViewCentre bb = ComputeCentre(img);
  if (bb.count == 0) return false;
  const int x0 = std::max(0, bb.minx - 1), x1 = std::min(W - 1, bb.maxx + 1);
  const int y0 = std::max(0, bb.miny - 1), y1 = std::min(W - 1, bb.maxy + 1);
  thread_local std::vector<std::uint8_t> mark;  // 1 = contour, 2 = outside
  mark.assign(kNumPix, 0);
  for (int p : contour) mark[p] = 1;
  std::vector<int> stack;
  auto seed = [&](int x, int y) {
    const int i = y * W + x;
    if (mark[i] == 0) {
      mark[i] = 2;
      stack.push_back(i);
    }
  };
  for (int x = x0; x <= x1; ++x) {
    seed(x, y0);
    seed(x, y1);
  }
  for (int y = y0; y <= y1; ++y) {
    seed(x0, y);
    seed(x1, y);
  }
  while (!stack.empty()) {
    const int p = stack.back();
    stack.pop_back();
    const int x = p % W, y = p / W;
    const int nb[4][2] = {{x + 1, y}, {x - 1, y}, {x, y + 1}, {x, y - 1}};
    for (const auto& q : nb) {
      if (q[0] < x0 || q[1] < y0 || q[0] > x1 || q[1] > y1) continue;
      const int qi = q[1] * W + q[0];
      if (mark[qi] == 0) {
        mark[qi] = 2;
        stack.push_back(qi);
      }
    }
  }
  long inside = 0, outside = 0;
  for (int y = bb.miny; y <= bb.maxy; ++y) {
    for (int x = bb.minx; x <= bb.maxx; ++x) {
      const int i = y * W + x;
      if (img[i] == 255) continue;
      if (mark[i] == 2) {
        ++outside;
      } else {
        ++inside;
      }
    }
  }
  if (inside + outside == 0) return false;
  return static_cast<double>(inside) / static_cast<double>(inside + outside) <= 0.95;
}

// Foreground dilation over `offsets` restricted to rows/cols [2, 253].
Image Dilate(const Image& src, const std::vector<std::pair<int, int>>& offsets) {
  Image out = src;
  for (int y = 2; y <= 253; ++y) {
    for (int x = 2; x <= 253; ++x) {
      for (const auto& o : offsets) {
        if (src[(y + o.second) * W + x + o.first] < 255) {
          out[y * W + x] = 0;
          break;
        }
      }
    }
  }
  return out;
}

// Thins B against the original silhouette (section 6.3 FD step 3).
void Thin(Image* b, const Image& img) {
  static const int kNb[8][2] = {{+1, 0},  {0, -1},  {-1, 0},  {0, +1},
                                {+1, +1}, {+1, -1}, {-1, -1}, {-1, +1}};
  std::vector<std::uint8_t> flag(kNumPix);
  for (int i = 0; i < kNumPix; ++i) flag[i] = (*b)[i] < 255;
  static const int kSides[4] = {1, 3, 2, 0};  // sides 2, 4, 3, 1 (0-based indices into kNb)
  std::vector<int> deleted;
  bool any = true;
  while (any) {
    any = false;
    for (int side : kSides) {
      deleted.clear();
      const int soff = kNb[side][0] + kNb[side][1] * W;
      for (int y = 1; y <= 254; ++y) {
        for (int x = 1; x <= 254; ++x) {
          const int p = y * W + x;
          if (!flag[p] || flag[p + soff]) continue;
          int code = 0;
          for (int k = 0; k < 8; ++k) {
            code |= flag[p + kNb[k][0] + kNb[k][1] * W] << k;
          }
          if (DelTab(code) && img[p] == 255) {
            (*b)[p] = 255;
            deleted.push_back(p);
          }
        }
      }
      for (int p : deleted) flag[p] = 0;
      if (!deleted.empty()) any = true;
    }
  }
}

}  // namespace

void FourierBytes(const Image& img, const ViewCentre& c, std::uint8_t* out10) {
  std::fill(out10, out10 + kFd, 0);
  std::vector<int> contour = TraceContour(img);
  if (!contour.empty() && IsMultiPart(contour, img)) {
    static const std::vector<std::pair<int, int>> k3 = [] {
      std::vector<std::pair<int, int>> o;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) o.emplace_back(dx, dy);
      return o;
    }();
    static const std::vector<std::pair<int, int>> k5 = [] {
      std::vector<std::pair<int, int>> o;
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx)
          if (!(std::abs(dx) == 2 && std::abs(dy) == 2)) o.emplace_back(dx, dy);
      return o;
    }();
    Image b = Dilate(img, k3);
    contour = TraceContour(b);
    if (!contour.empty() && IsMultiPart(contour, b)) {
      b = Dilate(b, k5);
      contour = TraceContour(b);
      if (!contour.empty() && IsMultiPart(contour, b)) {
        b = img;
        int minx = W, maxx = -1, miny = W, maxy = -1;
        for (int i = 0; i < kNumPix; ++i) {
          if (img[i] < 255) {
            minx = std::min(minx, i % W);
            maxx = std::max(maxx, i % W);
            miny = std::min(miny, i / W);
            maxy = std::max(maxy, i / W);
          }
        }
        for (int y = miny; y <= maxy; ++y)
          for (int x = minx; x <= maxx; ++x) b[y * W + x] = 0;
      }
    }
    Thin(&b, img);
    contour = TraceContour(b);
  }
  const int n = static_cast<int>(contour.size());
  if (n < 8) return;
  std::vector<double> d(n);
  for (int i = 0; i < n; ++i) {
    d[i] = std::hypot(contour[i] % W - c.cx, contour[i] / W - c.cy);
  }
  double mag[kFd + 1];
  const double kTwoPi = 2.0 * M_PI;
  thread_local std::vector<double> cs, sn;
  cs.resize(n);
  sn.resize(n);
  for (int m = 0; m < n; ++m) {
    const double ang = kTwoPi * static_cast<double>(m) / n;
    cs[m] = std::cos(ang);
    sn[m] = std::sin(ang);
  }
  for (int k = 0; k <= kFd; ++k) {
    double re = 0, im = 0;
    long m = 0;
    for (int i = 0; i < n; ++i) {
      re += d[i] * cs[m];
      im -= d[i] * sn[m];
      m = (m + k) % n;
    }
    mag[k] = std::hypot(re, im);
  }
  if (!(mag[0] > 0)) return;
  for (int k = 1; k <= kFd; ++k) {
    if (k < n / 2 + 1) out10[k - 1] = Quantize(mag[k] / mag[0], 512.0);
  }
}

// ---------------------------------------------------------------------------------------------

Descriptor ComputeDescriptor(const geometry::TriangleMesh& mesh) {
  Descriptor desc;
  const std::vector<Vec3> verts = NormalizeForLfd(mesh);
  const auto& sets = CameraSets();
  std::vector<Image> imgs(kViews);
  std::vector<ViewCentre> centres(kViews);
  for (int k = 0; k < kSets; ++k) {
    double radius = 0.0;
    for (int v = 0; v < kViews; ++v) {
      imgs[v] = RenderSilhouette(verts, mesh.faces, sets[k][v]);
      centres[v] = ComputeCentre(imgs[v]);
      radius = std::max(radius, MaxRadius(imgs[v], centres[v]));
    }
    const double r = radius > 0 ? 50.0 / radius : 0.0;
    for (int v = 0; v < kViews; ++v) {
      const int kv = k * kViews + v;
      ArtBytes(imgs[v], centres[v], r, &desc.art[kv * kArt]);
      FourierBytes(imgs[v], centres[v], &desc.fd[kv * kFd]);
      desc.cir[kv] = CircularityByte(imgs[v]);
      desc.ecc[kv] = EccentricityByte(imgs[v], centres[v]);
    }
  }
  return desc;
}

long long Distance(const Descriptor& pred, const Descriptor& gt, bool gt_ecc) {
  const auto& align = Align10();
  long long best = std::numeric_limits<long long>::max();
  int cost[kViews][kViews];
  for (int s = 0; s < kSets; ++s) {
    for (int d = 0; d < kSets; ++d) {
      for (int i = 0; i < kViews; ++i) {
        const int pi = d * kViews + i;
        const std::uint8_t* ap = &pred.art[pi * kArt];
        const std::uint8_t* fp = &pred.fd[pi * kFd];
        for (int j = 0; j < kViews; ++j) {
          const int gj = s * kViews + j;
          const std::uint8_t* ag = &gt.art[gj * kArt];
          const std::uint8_t* fg = &gt.fd[gj * kFd];
          int c = 0;
          for (int m = 0; m < kArt; ++m) c += std::abs(int(ap[m]) - int(ag[m]));
          int cf = 0;
          for (int m = 0; m < kFd; ++m) cf += std::abs(int(fp[m]) - int(fg[m]));
          c += 2 * cf + 2 * std::abs(int(pred.cir[pi]) - int(gt.cir[gj]));
          c += std::abs(int(pred.ecc[pi]) - (gt_ecc ? int(gt.ecc[gj]) : 0));
          cost[i][j] = c;
        }
      }
      for (int r = 0; r < 60; ++r) {
        long long sum = 0;
        for (int m = 0; m < kViews; ++m) sum += cost[align[r][m]][m];
        best = std::min(best, sum);
      }
    }
  }
  return best;
}

std::uint64_t MeshHash(const geometry::TriangleMesh& mesh) {
  std::uint64_t h = 1469598103934665603ULL;
  auto mix = [&h](const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= p[i];
      h *= 1099511628211ULL;
    }
  };
  const std::uint64_t nv = mesh.vertices.size(), nf = mesh.faces.size();
  mix(&nv, sizeof nv);
  mix(&nf, sizeof nf);
  for (const Vec3& v : mesh.vertices) {
    const double xyz[3] = {v.x(), v.y(), v.z()};
    mix(xyz, sizeof xyz);
  }
  for (const Vec3i& f : mesh.faces) {
    const std::int32_t ijk[3] = {f[0], f[1], f[2]};
    mix(ijk, sizeof ijk);
  }
  return h;
}

// ---------------------------------------------------------------------------------------------

namespace {
constexpr char kMagic[8] = {'D', 'I', 'M', 'R', 'L', 'F', 'D', '1'};

std::string CachePath(const std::string& dir, std::uint64_t h) {
  char name[32];
  std::snprintf(name, sizeof name, "%016llx.lfd", static_cast<unsigned long long>(h));
  return dir + "/" + name;
}

bool LoadDescriptor(const std::string& path, Descriptor* d) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  char magic[8];
  if (!in.read(magic, 8) || std::memcmp(magic, kMagic, 8) != 0) return false;
  auto rd = [&in](auto& arr) {
    return static_cast<bool>(in.read(reinterpret_cast<char*>(arr.data()), arr.size()));
  };
  return rd(d->art) && rd(d->fd) && rd(d->cir) && rd(d->ecc);
}

void StoreDescriptor(const std::string& path, const Descriptor& d) {
  const std::string tmp =
      path + ".tmp" +
      std::to_string(std::hash<std::string>()(path) ^ reinterpret_cast<std::uintptr_t>(&d));
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) return;  // cache is optional: an unwritable dir only costs recomputation
    out.write(kMagic, 8);
    auto wr = [&out](const auto& arr) {
      out.write(reinterpret_cast<const char*>(arr.data()), arr.size());
    };
    wr(d.art);
    wr(d.fd);
    wr(d.cir);
    wr(d.ecc);
    if (!out) return;
  }
  std::rename(tmp.c_str(), path.c_str());
}
}  // namespace

DescriptorCache::DescriptorCache(std::string dir) : dir_(std::move(dir)) {}

std::shared_ptr<const Descriptor> DescriptorCache::Get(const geometry::TriangleMesh& mesh) {
  const std::uint64_t h = MeshHash(mesh);
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = map_.find(h);
    if (it != map_.end()) {
      ++hits_;
      return it->second;
    }
  }
  auto desc = std::make_shared<Descriptor>();
  bool loaded = false;
  if (!dir_.empty()) loaded = LoadDescriptor(CachePath(dir_, h), desc.get());
  if (!loaded) {
    *desc = ComputeDescriptor(mesh);
    if (!dir_.empty()) StoreDescriptor(CachePath(dir_, h), *desc);
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (loaded) {
    ++hits_;
  } else {
    ++computed_;
  }
  auto [it, inserted] = map_.emplace(h, std::move(desc));
  return it->second;
}

}  // namespace dimr::eval::lfd
