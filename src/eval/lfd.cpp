// Light Field Distance, re-implemented from ../shared/reference/dimr-metrics.md section 6.
#include "dimr/eval/lfd.h"

#include <immintrin.h>

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

namespace {
// First / last foreground pixel of a row that has one (whole 8-byte words of background skipped).
inline int FirstForeground(const std::uint8_t* row) {
  int a = 0;
  for (; a + 8 <= W; a += 8) {
    std::uint64_t v;
    std::memcpy(&v, row + a, 8);
    if (v != ~std::uint64_t{0}) break;
  }
  while (row[a] == 255) ++a;
  return a;
}
inline int LastForeground(const std::uint8_t* row) {
  int b = W;
  for (; b - 8 >= 0; b -= 8) {
    std::uint64_t v;
    std::memcpy(&v, row + b - 8, 8);
    if (v != ~std::uint64_t{0}) break;
  }
  --b;
  while (row[b] == 255) --b;
  return b;
}
}  // namespace

ViewCentre ComputeCentre(const Image& img) {
  int minx = W, maxx = -1, miny = W, maxy = -1, n = 0;
  for (int y = 0; y < W; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    int rn = 0;
    for (int x = 0; x < W; ++x) rn += row[x] < 255;  // branch-free, vectorised
    if (rn == 0) continue;
    n += rn;
    const int a = FirstForeground(row), b = LastForeground(row);
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
// Squared maximum radius and the second moments of the foreground about the centre, one pass
// over the bounding box (the same sums in the same order as separate loops).
struct ViewMoments {
  double max_r2 = 0, m20 = 0, m02 = 0, m11 = 0;
};
ViewMoments Moments(const Image& img, const ViewCentre& c) {
  ViewMoments m;
  if (c.count == 0) return m;
  for (int y = c.miny; y <= c.maxy; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    const double dy = y - c.cy;
    for (int x = c.minx; x <= c.maxx; ++x) {
      if (row[x] < 255) {
        const double dx = x - c.cx;
        m.max_r2 = std::max(m.max_r2, dx * dx + dy * dy);
        m.m20 += dx * dx;
        m.m02 += dy * dy;
        m.m11 += dx * dy;
      }
    }
  }
  return m;
}

// Centre (as ComputeCentre) and moments (as Moments) of a view in one pass, from per-row counts,
// coordinate sums and extreme pixels. Exact: the centre is a multiple of 1/2, so every term
// (x - cx)^2, (x - cx)(y - cy) is a multiple of 1/4 below 2^15 and every partial sum below 2^31,
// all exactly representable, so the sums do not depend on their order and equal the per-pixel
// loops' bit for bit; the largest (x - cx)^2 of a row is at its first or last pixel.
void AnalyseView(const Image& img, ViewCentre* centre, ViewMoments* moments) {
  std::int64_t rn[W], rsx[W], rsxx[W];
  int rfirst[W], rlast[W];
  int minx = W, maxx = -1, miny = W, maxy = -1, n = 0;
  for (int y = 0; y < W; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    int cnt = 0;
    for (int x = 0; x < W; ++x) cnt += row[x] < 255;  // branch-free, vectorised
    rn[y] = cnt;
    if (cnt == 0) continue;
    n += cnt;
    const int a = FirstForeground(row), b = LastForeground(row);
    std::int64_t sx = 0, sxx = 0;
    for (int x = a; x <= b; ++x) {
      const std::int64_t f = row[x] < 255;
      sx += f * x;
      sxx += f * x * x;
    }
    rsx[y] = sx;
    rsxx[y] = sxx;
    rfirst[y] = a;
    rlast[y] = b;
    minx = std::min(minx, a);
    maxx = std::max(maxx, b);
    miny = std::min(miny, y);
    maxy = std::max(maxy, y);
  }
  ViewCentre c;
  c.count = n;
  *moments = ViewMoments();
  if (n > 0) {
    c.minx = minx;
    c.maxx = maxx;
    c.miny = miny;
    c.maxy = maxy;
    if (maxx > 0) {
      c.cx = (minx + maxx) / 2.0;
      c.cy = (miny + maxy) / 2.0;
    }
    ViewMoments& m = *moments;
    for (int y = miny; y <= maxy; ++y) {
      if (rn[y] == 0) continue;
      const double dy = y - c.cy;
      const double cnt = static_cast<double>(rn[y]), sx = static_cast<double>(rsx[y]);
      const double da = rfirst[y] - c.cx, db = rlast[y] - c.cx;
      m.max_r2 = std::max(m.max_r2, std::max(da * da, db * db) + dy * dy);
      m.m20 += static_cast<double>(rsxx[y]) - 2.0 * c.cx * sx + cnt * c.cx * c.cx;
      m.m02 += cnt * dy * dy;
      m.m11 += dy * (sx - cnt * c.cx);
    }
  }
  *centre = c;
}

std::uint8_t EccentricityFromMoments(const ViewCentre& c, const ViewMoments& m) {
  if (c.count <= 1) return 0;
  const double den = (m.m20 + m.m02) * (m.m20 + m.m02);
  if (!(den > 0)) return 0;
  double ecc = ((m.m20 - m.m02) * (m.m20 - m.m02) + 4.0 * m.m11 * m.m11) / den;
  ecc = std::min(1.0, ecc);
  return Quantize(ecc, 256.0);
}
}  // namespace

std::uint8_t EccentricityByte(const Image& img, const ViewCentre& c) {
  if (c.count <= 1) return 0;
  return EccentricityFromMoments(c, Moments(img, c));
}

namespace {
// Circularity with the foreground bounding box `bb` of img already known.
std::uint8_t CircularityInBox(const Image& img, const ViewCentre& bb);
}  // namespace

std::uint8_t CircularityByte(const Image& img) { return CircularityInBox(img, ComputeCentre(img)); }

namespace {
std::uint8_t CircularityInBox(const Image& img, const ViewCentre& bb) {
  if (bb.count == 0) return 0;
  long area = 0, perim = 0;
  // A foreground pixel is on the perimeter when one of its 8 neighbours (inside the image) is
  // background. Interior pixels run 16 at a time (SSE2 byte compares; integer counts, exact).
  auto scalar = [&](int x, int y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    if (row[x] == 255) return;
    ++area;
    bool edge = false;
    if (y > 0 && y < W - 1 && x > 0 && x < W - 1) {
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
  };
  const __m128i bg = _mm_set1_epi8(static_cast<char>(255));
  auto is_bg = [&bg](const std::uint8_t* p) {
    return _mm_cmpeq_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)), bg);
  };
  for (int y = bb.miny; y <= bb.maxy; ++y) {
    const std::uint8_t* row = &img[static_cast<std::size_t>(y) * W];
    int x = bb.minx;
    if (y > 0 && y < W - 1) {
      for (; x < 1; ++x) scalar(x, y);
      const std::uint8_t* up = row + W;
      const std::uint8_t* dn = row - W;
      // Vector blocks need x + 16 <= W - 1 (the right neighbour load) and x + 15 <= maxx.
      for (; x + 15 <= bb.maxx && x + 16 <= W - 1; x += 16) {
        const __m128i centre = is_bg(row + x);
        __m128i any = _mm_or_si128(is_bg(row + x - 1), is_bg(row + x + 1));
        any = _mm_or_si128(any, _mm_or_si128(is_bg(up + x - 1), is_bg(up + x)));
        any = _mm_or_si128(any, _mm_or_si128(is_bg(up + x + 1), is_bg(dn + x - 1)));
        any = _mm_or_si128(any, _mm_or_si128(is_bg(dn + x), is_bg(dn + x + 1)));
        const unsigned fg = ~static_cast<unsigned>(_mm_movemask_epi8(centre)) & 0xFFFFu;
        const unsigned edge =
            static_cast<unsigned>(_mm_movemask_epi8(_mm_andnot_si128(centre, any)));
        area += __builtin_popcount(fg);
        perim += __builtin_popcount(edge);
      }
    }
    for (; x <= bb.maxx; ++x) scalar(x, y);
  }
  if (perim == 0) return 0;
  double cir = 12.5663704 * static_cast<double>(area) / (static_cast<double>(perim) * perim);
  cir = std::min(1.0, cir);
  return Quantize(cir, 256.0);
}
}  // namespace

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

namespace {
// acc[radial][j] += (w[node] * rad[node * 3 + radial]) * ang[node * 24 + j] (j < 24: 12 angular
// orders x cos / sin) over `nodes` in order: the projection of the splatted weights on the basis.
// Each accumulator sums the same products in the same order as the scalar loop of the reference
// regrouping; vectors only run the 72 independent sums side by side, with multiplies and adds
// kept separate (no FMA), so both versions give the scalar loop's bits. One pass over the nodes
// (the factor tables are ~2 MB: a pass per radial order was bound by reading them).
__attribute__((target("avx"))) void ProjectAvx(const std::vector<int>& nodes, const double* w,
                                               const ArtFactors& fac, double (*acc)[24]) {
  __m256d a0[6], a1[6], a2[6];
  for (int j = 0; j < 6; ++j) a0[j] = a1[j] = a2[j] = _mm256_setzero_pd();
  for (int node : nodes) {
    const double* rad = &fac.rad[static_cast<std::size_t>(node) * 3];
    const double wt = w[node];
    const __m256d w0 = _mm256_set1_pd(wt * rad[0]);
    const __m256d w1 = _mm256_set1_pd(wt * rad[1]);
    const __m256d w2 = _mm256_set1_pd(wt * rad[2]);
    const double* ang = &fac.ang[static_cast<std::size_t>(node) * 24];
    for (int j = 0; j < 6; ++j) {
      const __m256d g = _mm256_loadu_pd(ang + 4 * j);
      a0[j] = _mm256_add_pd(a0[j], _mm256_mul_pd(w0, g));
      a1[j] = _mm256_add_pd(a1[j], _mm256_mul_pd(w1, g));
      a2[j] = _mm256_add_pd(a2[j], _mm256_mul_pd(w2, g));
    }
  }
  for (int j = 0; j < 6; ++j) {
    _mm256_storeu_pd(acc[0] + 4 * j, a0[j]);
    _mm256_storeu_pd(acc[1] + 4 * j, a1[j]);
    _mm256_storeu_pd(acc[2] + 4 * j, a2[j]);
  }
}

void ProjectSse2(const std::vector<int>& nodes, const double* w, const ArtFactors& fac,
                 double (*acc)[24]) {
  for (int radial = 0; radial < 3; ++radial) {
    __m128d a[12];
    for (int j = 0; j < 12; ++j) a[j] = _mm_setzero_pd();
    for (int node : nodes) {
      const __m128d wr =
          _mm_set1_pd(w[node] * fac.rad[static_cast<std::size_t>(node) * 3 + radial]);
      const double* ang = &fac.ang[static_cast<std::size_t>(node) * 24];
      for (int j = 0; j < 12; ++j) {
        a[j] = _mm_add_pd(a[j], _mm_mul_pd(wr, _mm_loadu_pd(ang + 2 * j)));
      }
    }
    for (int j = 0; j < 12; ++j) _mm_storeu_pd(acc[radial] + 2 * j, a[j]);
  }
}
}  // namespace

void ArtBytes(const Image& img, const ViewCentre& c, double r, std::uint8_t* out35) {
  std::fill(out35, out35 + kArt, 0);
  if (c.count == 0) return;
  // Bilinear splat: sum_p V(t_p) = sum_nodes w_node V(node), with w the bilinear weights.
  thread_local std::vector<double> tls_w;
  thread_local std::vector<int> tls_nodes;
  std::vector<double>& w = tls_w;
  std::vector<int>& nodes = tls_nodes;
  w.assign(static_cast<std::size_t>(kLut) * kLut, 0.0);
  // The LUT column and weights of each image column (they depend on x only).
  int col_ix[W];
  double col_fx[W], col_gx[W];
  for (int x = c.minx; x <= c.maxx; ++x) {
    const double tx = (x - c.cx) * r + 50.0;
    const int ix = static_cast<int>(tx);
    col_ix[x] = ix;
    col_fx[x] = tx - ix;
    col_gx[x] = 1.0 - col_fx[x];
  }
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
      const int ix = col_ix[x];
      if (ix < 0 || ix > 100) continue;
      const double fx = col_fx[x];
      const double gx = col_gx[x];
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
  nodes.clear();
  for (int y = nminy; y <= nmaxy; ++y) {
    for (int x = nminx; x <= nmaxx; ++x) {
      const int node = y * kLut + x;
      if (w[node] != 0.0) nodes.push_back(node);
    }
  }
  // acc[radial][2 p + {0 cos, 1 sin}] = sum over nodes of (w * rad_radial) * ang_p.
  const ArtFactors& fac = Factors();
  static const bool avx = __builtin_cpu_supports("avx");
  double acc[3][24];
  if (avx) {
    ProjectAvx(nodes, w.data(), fac, acc);
  } else {
    ProjectSse2(nodes, w.data(), fac, acc);
  }
  const double n = c.count;
  for (int k = 1; k < kCoef; ++k) {
    const int p = k / 3, radial = k % 3;
    const double mag = std::hypot(acc[radial][2 * p] / n, -acc[radial][2 * p + 1] / n);
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

// Multipart test: flood "outside" from the image border through unmarked pixels. `bb` is the
// foreground bounding box of img (ComputeCentre(img)).
bool IsMultiPart(const std::vector<int>& contour, const Image& img, const ViewCentre& bb) {
  // Pixels outside the foreground bbox grown by one are background and connected to the image
  // border, so the flood runs inside that window, seeded from its boundary ring. Span filling:
  // a seed fills its whole run of unmarked pixels in its row and seeds every unmarked run it
  // touches in the rows above and below (the same 4-connected set as a per-pixel flood).
  if (bb.count == 0) return false;
  const int x0 = std::max(0, bb.minx - 1), x1 = std::min(W - 1, bb.maxx + 1);
  const int y0 = std::max(0, bb.miny - 1), y1 = std::min(W - 1, bb.maxy + 1);
  thread_local std::vector<std::uint8_t> tls_mark;  // 1 = contour, 2 = outside
  thread_local std::vector<int> tls_stack;
  std::vector<std::uint8_t>& mark = tls_mark;
  std::vector<int>& stack = tls_stack;
  mark.resize(kNumPix);
  // Only the window is read below (the contour lies inside the bounding box).
  for (int y = y0; y <= y1; ++y) std::memset(&mark[y * W + x0], 0, x1 - x0 + 1);
  for (int p : contour) mark[p] = 1;
  stack.clear();
  for (int x = x0; x <= x1; ++x) {
    stack.push_back(y0 * W + x);
    stack.push_back(y1 * W + x);
  }
  for (int y = y0; y <= y1; ++y) {
    stack.push_back(y * W + x0);
    stack.push_back(y * W + x1);
  }
  std::uint8_t* m = mark.data();
  while (!stack.empty()) {
    const int p = stack.back();
    stack.pop_back();
    if (m[p] != 0) continue;
    const int y = p / W, row = y * W;
    int xl = p - row, xr = xl;
    while (xl > x0 && m[row + xl - 1] == 0) --xl;
    while (xr < x1 && m[row + xr + 1] == 0) ++xr;
    for (int x = xl; x <= xr; ++x) m[row + x] = 2;
    for (int ny : {y - 1, y + 1}) {
      if (ny < y0 || ny > y1) continue;
      const int nrow = ny * W;
      bool in_run = false;
      for (int x = xl; x <= xr; ++x) {
        const bool free = m[nrow + x] == 0;
        if (free && !in_run) stack.push_back(nrow + x);
        in_run = free;
      }
    }
  }
  long inside = 0, outside = 0;
  for (int y = bb.miny; y <= bb.maxy; ++y) {
    for (int x = bb.minx; x <= bb.maxx; ++x) {
      const int i = y * W + x;
      if (img[i] == 255) continue;
      if (m[i] == 2) {
        ++outside;
      } else {
        ++inside;
      }
    }
  }
  if (inside + outside == 0) return false;
  return static_cast<double>(inside) / static_cast<double>(inside + outside) <= 0.95;
}

// Foreground dilation restricted to rows/cols [2, 253] (pixels outside keep their value), with
// the structuring element 3 x 3 (`radius` 1) or 5 x 5 without its corners (`radius` 2). Computed
// separably: per row the horizontal OR over x - r .. x + r, then the OR of those rows over the
// element's rows (5 x 5 minus corners = 5 x 3 rows of width 5 plus the rows y +- 2 of width 3),
// and only inside the foreground bounding box grown by the radius; the same set as testing every
// offset at every pixel.
Image Dilate(const Image& src, int radius) {
  Image out = src;
  int minx = W, maxx = -1, miny = W, maxy = -1;
  for (int y = 0; y < W; ++y) {
    const std::uint8_t* row = &src[static_cast<std::size_t>(y) * W];
    for (int x = 0; x < W; ++x) {
      if (row[x] < 255) {
        minx = std::min(minx, x);
        maxx = std::max(maxx, x);
        miny = std::min(miny, y);
        maxy = std::max(maxy, y);
      }
    }
  }
  if (maxx < 0) return out;
  // h1[y * W + x]: foreground in src row y within x +- 1; h2: within x +- 2 (rows 0..255).
  thread_local std::vector<std::uint8_t> h1, h2;
  h1.assign(kNumPix, 0);
  h2.assign(kNumPix, 0);
  const int y_lo = std::max(0, miny - radius), y_hi = std::min(W - 1, maxy + radius);
  const int x_lo = std::max(2, minx - radius), x_hi = std::min(253, maxx + radius);
  for (int y = y_lo; y <= y_hi; ++y) {
    const std::uint8_t* row = &src[static_cast<std::size_t>(y) * W];
    std::uint8_t* a = &h1[static_cast<std::size_t>(y) * W];
    std::uint8_t* b = &h2[static_cast<std::size_t>(y) * W];
    for (int x = x_lo; x <= x_hi; ++x) {
      const bool c1 = row[x - 1] < 255 || row[x] < 255 || row[x + 1] < 255;
      a[x] = c1;
      b[x] = c1 || row[x - 2] < 255 || row[x + 2] < 255;
    }
  }
  const int oy_lo = std::max(2, miny - radius), oy_hi = std::min(253, maxy + radius);
  for (int y = oy_lo; y <= oy_hi; ++y) {
    std::uint8_t* o = &out[static_cast<std::size_t>(y) * W];
    const std::uint8_t* wide = radius == 1 ? h1.data() : h2.data();
    const std::uint8_t* r0 = wide + static_cast<std::size_t>(y - 1) * W;
    const std::uint8_t* r1 = r0 + W;
    const std::uint8_t* r2 = r1 + W;
    for (int x = x_lo; x <= x_hi; ++x) {
      bool on = r0[x] || r1[x] || r2[x];
      if (radius == 2) on = on || h1[(y - 2) * W + x] || h1[(y + 2) * W + x];
      if (on) o[x] = 0;
    }
  }
  return out;
}

// Thins B against the original silhouette (section 6.3 FD step 3): per pass the four sides in
// turn; in a side's sweep a pixel p of B with a background neighbour on that side, background in
// the original silhouette and deletable by its 8-neighbour code is removed, all decisions of the
// sweep taken on B as it was before the sweep (so their order does not matter); passes repeat
// until one deletes nothing. Only pixels of B outside the silhouette that have a background
// 4-neighbour can ever be deleted, so each sweep visits a list of those (the border), updated
// with the 4-neighbours of what was deleted, instead of the whole image: the same deletions.
void Thin(Image* b, const Image& img) {
  static const int kNb[8][2] = {{+1, 0},  {0, -1},  {-1, 0},  {0, +1},
                                {+1, +1}, {+1, -1}, {-1, -1}, {-1, +1}};
  int nboff[8];
  for (int k = 0; k < 8; ++k) nboff[k] = kNb[k][0] + kNb[k][1] * W;
  thread_local std::vector<std::uint8_t> tls_flag, tls_listed;
  std::vector<std::uint8_t>& flag = tls_flag;
  std::vector<std::uint8_t>& listed = tls_listed;
  flag.resize(kNumPix);
  listed.assign(kNumPix, 0);
  for (int i = 0; i < kNumPix; ++i) flag[i] = (*b)[i] < 255;
  // A pixel that may be deleted: inside the sweep window, in B, not in the silhouette, with a
  // background 4-neighbour (the side test below needs one).
  auto candidate = [&](int p) {
    const int x = p % W, y = p / W;
    if (x < 1 || x > 254 || y < 1 || y > 254) return false;
    if (!flag[p] || img[p] != 255) return false;
    return !flag[p + 1] || !flag[p - 1] || !flag[p + W] || !flag[p - W];
  };
  std::vector<int> border, deleted, next;
  for (int y = 1; y <= 254; ++y) {
    for (int x = 1; x <= 254; ++x) {
      const int p = y * W + x;
      if (candidate(p)) {
        border.push_back(p);
        listed[p] = 1;
      }
    }
  }
  static const int kSides[4] = {1, 3, 2, 0};  // sides 2, 4, 3, 1 (0-based indices into kNb)
  bool any = true;
  while (any) {
    any = false;
    for (int side : kSides) {
      deleted.clear();
      const int soff = nboff[side];
      for (int p : border) {
        if (flag[p + soff]) continue;
        int code = 0;
        for (int k = 0; k < 8; ++k) code |= flag[p + nboff[k]] << k;
        if (DelTab(code)) deleted.push_back(p);
      }
      if (deleted.empty()) continue;
      any = true;
      for (int p : deleted) {
        flag[p] = 0;
        (*b)[p] = 255;
        listed[p] = 0;
      }
      next.clear();
      for (int p : border) {
        if (flag[p]) next.push_back(p);
      }
      for (int p : deleted) {
        for (int q : {p + 1, p - 1, p + W, p - W}) {
          if (!listed[q] && candidate(q)) {
            listed[q] = 1;
            next.push_back(q);
          }
        }
      }
      border.swap(next);
    }
  }
}

}  // namespace

namespace {
// FourierBytes with the foreground bounding box `box` of img (ComputeCentre(img)) known.
void FourierBytesWithBox(const Image& img, const ViewCentre& c, const ViewCentre& box,
                         std::uint8_t* out10) {
  std::fill(out10, out10 + kFd, 0);
  std::vector<int> contour = TraceContour(img);
  if (!contour.empty() && IsMultiPart(contour, img, box)) {
    Image b = Dilate(img, 1);
    contour = TraceContour(b);
    if (!contour.empty() && IsMultiPart(contour, b, ComputeCentre(b))) {
      b = Dilate(b, 2);
      contour = TraceContour(b);
      if (!contour.empty() && IsMultiPart(contour, b, ComputeCentre(b))) {
        b = img;
        for (int y = box.miny; y <= box.maxy; ++y)
          for (int x = box.minx; x <= box.maxx; ++x) b[y * W + x] = 0;
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
      m += k;  // (m + k) % n without a division: m < n and k <= 10
      while (m >= n) m -= n;
    }
    mag[k] = std::hypot(re, im);
  }
  if (!(mag[0] > 0)) return;
  for (int k = 1; k <= kFd; ++k) {
    if (k < n / 2 + 1) out10[k - 1] = Quantize(mag[k] / mag[0], 512.0);
  }
}
}  // namespace

void FourierBytes(const Image& img, const ViewCentre& c, std::uint8_t* out10) {
  FourierBytesWithBox(img, c, ComputeCentre(img), out10);
}

// ---------------------------------------------------------------------------------------------

Descriptor ComputeDescriptor(const geometry::TriangleMesh& mesh) {
  Descriptor desc;
  const std::vector<Vec3> verts = NormalizeForLfd(mesh);
  const auto& sets = CameraSets();
  std::vector<Image> imgs(kViews);
  std::vector<ViewCentre> centres(kViews);
  std::vector<ViewMoments> moments(kViews);
  for (int k = 0; k < kSets; ++k) {
    double radius = 0.0;
    for (int v = 0; v < kViews; ++v) {
      imgs[v] = RenderSilhouette(verts, mesh.faces, sets[k][v]);
      AnalyseView(imgs[v], &centres[v], &moments[v]);
      radius = std::max(radius, std::sqrt(moments[v].max_r2));
    }
    const double r = radius > 0 ? 50.0 / radius : 0.0;
    for (int v = 0; v < kViews; ++v) {
      const int kv = k * kViews + v;
      ArtBytes(imgs[v], centres[v], r, &desc.art[kv * kArt]);
      // centres[v] is also the foreground bounding box of imgs[v].
      FourierBytesWithBox(imgs[v], centres[v], centres[v], &desc.fd[kv * kFd]);
      desc.cir[kv] = CircularityInBox(imgs[v], centres[v]);
      desc.ecc[kv] = EccentricityFromMoments(centres[v], moments[v]);
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
