// Software rendering of meshes to PNG for docs and tools (no image library needed): a z-buffer
// rasteriser with orthographic front-left-above views, 3x supersampling, a 3x5 pixel font and
// an own PNG encoder (zlib stream with fixed-Huffman deflate blocks, CRC-32 and Adler-32).
#include "tools/render.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "dimr/geometry/crc32.h"
#include "dimr/geometry/error.h"

namespace dimr::tools {

using geometry::Vec3;

namespace {

// ---------------------------------------------------------------------------------------
// PNG encoding.
// ---------------------------------------------------------------------------------------
class BitWriter {
 public:
  // Writes `n` bits of `value`, least significant first (deflate's bit order).
  void Bits(std::uint32_t value, int n) {
    for (int i = 0; i < n; ++i) {
      if (bit_ == 0) out_.push_back(0);
      if ((value >> i) & 1) out_.back() |= static_cast<std::uint8_t>(1u << bit_);
      bit_ = (bit_ + 1) & 7;
    }
  }
  // Writes a Huffman code of `n` bits, most significant bit first.
  void Code(std::uint32_t code, int n) {
    for (int i = n - 1; i >= 0; --i) Bits((code >> i) & 1, 1);
  }
  std::vector<std::uint8_t>& bytes() { return out_; }

 private:
  std::vector<std::uint8_t> out_;
  int bit_ = 0;
};

// Fixed-Huffman literal/length symbol.
void PutSymbol(BitWriter& w, int sym) {
  if (sym < 144) {
    w.Code(0x30 + sym, 8);
  } else if (sym < 256) {
    w.Code(0x190 + sym - 144, 9);
  } else if (sym < 280) {
    w.Code(sym - 256, 7);
  } else {
    w.Code(0xc0 + sym - 280, 8);
  }
}

// zlib stream (RFC 1950) of one fixed-Huffman deflate block (RFC 1951) with greedy LZ77
// matching through a hash of 3-byte prefixes.
std::vector<std::uint8_t> ZlibCompress(const std::vector<std::uint8_t>& in) {
  static const int kLenBase[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                   31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
  static const int kLenExtra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                    2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
  static const int kDistBase[30] = {1,    2,    3,    4,    5,    7,    9,    13,    17,    25,
                                    33,   49,   65,   97,   129,  193,  257,  385,   513,   769,
                                    1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
  static const int kDistExtra[30] = {0, 0, 0, 0, 1, 1, 2, 2,  3,  3,  4,  4,  5,  5,  6,
                                     6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};
  BitWriter w;
  w.Bits(0x78, 8);
  w.Bits(0x01, 8);  // deflate, 32K window, no dictionary; (0x78 * 256 + 0x01) % 31 == 0
  w.Bits(1, 1);     // final block
  w.Bits(1, 2);     // fixed Huffman codes
  const std::size_t n = in.size();
  constexpr int kHashBits = 16;
  std::vector<std::int64_t> head(1 << kHashBits, -1);
  auto hash = [&](std::size_t i) {
    const std::uint32_t v = in[i] | (in[i + 1] << 8) | (in[i + 2] << 16);
    return (v * 2654435761u) >> (32 - kHashBits);
  };
  std::size_t i = 0;
  while (i < n) {
    int best_len = 0;
    std::size_t best_dist = 0;
    if (i + 3 <= n) {
      const std::uint32_t h = hash(i);
      const std::int64_t cand = head[h];
      head[h] = static_cast<std::int64_t>(i);
      if (cand >= 0 && i - cand <= 32768) {
        const std::size_t c = static_cast<std::size_t>(cand);
        int len = 0;
        while (len < 258 && i + len < n && in[c + len] == in[i + len]) ++len;
        if (len >= 3) {
          best_len = len;
          best_dist = i - c;
        }
      }
    }
    if (best_len == 0) {
      PutSymbol(w, in[i]);
      ++i;
      continue;
    }
    int lc = 28;
    while (kLenBase[lc] > best_len) --lc;
    PutSymbol(w, 257 + lc);
    w.Bits(best_len - kLenBase[lc], kLenExtra[lc]);
    int dc = 29;
    while (kDistBase[dc] > static_cast<int>(best_dist)) --dc;
    w.Code(dc, 5);
    w.Bits(static_cast<std::uint32_t>(best_dist) - kDistBase[dc], kDistExtra[dc]);
    for (int k = 1; k < best_len && i + k + 3 <= n; ++k) head[hash(i + k)] = i + k;
    i += best_len;
  }
  PutSymbol(w, 256);  // end of block
  std::vector<std::uint8_t> out = std::move(w.bytes());
  std::uint32_t a = 1, b = 0;
  for (std::uint8_t c : in) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  const std::uint32_t adler = (b << 16) | a;
  for (int k = 3; k >= 0; --k) out.push_back(static_cast<std::uint8_t>(adler >> (8 * k)));
  return out;
}

}  // namespace

void WritePng(const std::string& path, int width, int height,
              const std::vector<std::uint8_t>& rgb) {
  std::vector<std::uint8_t> raw;
  raw.reserve(static_cast<std::size_t>(height) * (3 * width + 1));
  for (int y = 0; y < height; ++y) {
    raw.push_back(0);  // filter: none
    raw.insert(raw.end(), rgb.begin() + static_cast<std::size_t>(y) * 3 * width,
               rgb.begin() + static_cast<std::size_t>(y + 1) * 3 * width);
  }
  std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  auto chunk = [&](const char* type, const std::vector<std::uint8_t>& data) {
    const std::uint32_t len = static_cast<std::uint32_t>(data.size());
    for (int k = 3; k >= 0; --k) png.push_back(static_cast<std::uint8_t>(len >> (8 * k)));
    std::vector<std::uint8_t> body(type, type + 4);
    body.insert(body.end(), data.begin(), data.end());
    png.insert(png.end(), body.begin(), body.end());
    const std::uint32_t crc = geometry::Crc32(body.data(), body.size());
    for (int k = 3; k >= 0; --k) png.push_back(static_cast<std::uint8_t>(crc >> (8 * k)));
  };
  std::vector<std::uint8_t> ihdr;
  for (std::uint32_t v : {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height)}) {
    for (int k = 3; k >= 0; --k) ihdr.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
  }
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit RGB, deflate, no filter, no interlace
  chunk("IHDR", ihdr);
  chunk("IDAT", ZlibCompress(raw));
  chunk("IEND", {});
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  if (!out) throw dimr::InvalidArgument("cannot write PNG '" + path + "'");
}

namespace {

// ---------------------------------------------------------------------------------------
// Software rasteriser.
// ---------------------------------------------------------------------------------------
struct Image {
  int w, h;
  std::vector<float> rgb;  // linear-ish colour, row-major
  Image(int width, int height, float bg) : w(width), h(height), rgb(3 * width * height, bg) {}
  void Set(int x, int y, const Vec3& c) {
    float* p = &rgb[3 * (static_cast<std::size_t>(y) * w + x)];
    p[0] = static_cast<float>(c.x());
    p[1] = static_cast<float>(c.y());
    p[2] = static_cast<float>(c.z());
  }
};

}  // namespace

Vec3 NameColour(const std::string& name) {
  std::uint32_t h = 2166136261u;
  for (unsigned char c : name) h = (h ^ c) * 16777619u;
  static const std::array<Vec3, 8> kPalette = {Vec3(0.80, 0.55, 0.35), Vec3(0.45, 0.60, 0.80),
                                               Vec3(0.60, 0.75, 0.45), Vec3(0.85, 0.75, 0.45),
                                               Vec3(0.70, 0.50, 0.70), Vec3(0.55, 0.55, 0.55),
                                               Vec3(0.85, 0.50, 0.50), Vec3(0.45, 0.75, 0.75)};
  return kPalette[h % kPalette.size()];
}

namespace {

// Renders the model (real proportions) into the square tile at (x0, y0) of size `tile`
// (image pixels = tile * ss), orthographic view from front-left-above.
void RenderMesh(const RenderTile& m, Image& img, int x0, int y0, int tile) {
  const Vec3 eye = Vec3(1.0, 0.75, 0.6).normalized();  // from the object towards the viewer
  const Vec3 fwd = -eye;
  const Vec3 right = fwd.cross(Vec3::UnitZ()).normalized();
  const Vec3 up = right.cross(fwd);
  const Vec3 light = Vec3(0.6, 0.3, 1.0).normalized();
  const double scale_max = m.scale.maxCoeff();
  std::vector<Vec3> p(m.mesh.vertices.size());
  double umin = 1e9, umax = -1e9, vmin = 1e9, vmax = -1e9;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3 w = m.mesh.vertices[i].cwiseProduct(m.scale) / scale_max;
    p[i] = Vec3(w.dot(right), w.dot(up), w.dot(eye));
    umin = std::min(umin, p[i].x());
    umax = std::max(umax, p[i].x());
    vmin = std::min(vmin, p[i].y());
    vmax = std::max(vmax, p[i].y());
  }
  const double margin = 0.1 * tile;
  const double s = (tile - 2 * margin) / std::max(umax - umin, vmax - vmin);
  const double cu = 0.5 * (umin + umax), cv = 0.5 * (vmin + vmax);
  for (auto& q : p) {
    q.x() = x0 + 0.5 * tile + (q.x() - cu) * s;
    q.y() = y0 + 0.5 * tile - (q.y() - cv) * s - 0.04 * tile;
  }
  std::vector<double> zbuf(static_cast<std::size_t>(tile) * tile, -1e30);
  {
    for (std::size_t f = 0; f < m.mesh.faces.size(); ++f) {
      const Vec3 base = f < m.face_colors.size() ? m.face_colors[f] : m.color;
      const auto& t = m.mesh.faces[f];
      const Vec3 wa = m.mesh.vertices[t[0]].cwiseProduct(m.scale);
      const Vec3 n = (m.mesh.vertices[t[1]].cwiseProduct(m.scale) - wa)
                         .cross(m.mesh.vertices[t[2]].cwiseProduct(m.scale) - wa);
      if (n.dot(eye) <= 0 || n.norm() == 0) continue;  // back face of a closed part
      const Vec3 nn = n.normalized();
      const double shade = 0.35 + 0.5 * std::max(0.0, nn.dot(light)) + 0.15 * nn.dot(eye);
      const Vec3 colour = base * shade;
      const Vec3 &a = p[t[0]], &b = p[t[1]], &c = p[t[2]];
      const int xa = std::max(x0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
      const int xb =
          std::min(x0 + tile - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
      const int ya = std::max(y0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
      const int yb =
          std::min(y0 + tile - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
      const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
      if (std::abs(area) < 1e-12) continue;
      for (int y = ya; y <= yb; ++y) {
        for (int x = xa; x <= xb; ++x) {
          const double px = x + 0.5, py = y + 0.5;
          const double w0 = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) / area;
          const double w1 = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) / area;
          const double w2 = 1.0 - w0 - w1;
          if (w0 < 0 || w1 < 0 || w2 < 0) continue;
          const double z = w0 * a.z() + w1 * b.z() + w2 * c.z();
          double& zb = zbuf[static_cast<std::size_t>(y - y0) * tile + (x - x0)];
          if (z <= zb) continue;
          zb = z;
          img.Set(x, y, colour);
        }
      }
    }
  }
}

// 3x5 pixel font: rows top to bottom, bit 2 = left column.
const std::map<char, std::array<int, 5>>& Font() {
  static const std::map<char, std::array<int, 5>> kFont = {
      {'a', {2, 5, 7, 5, 5}}, {'b', {6, 5, 6, 5, 6}}, {'c', {3, 4, 4, 4, 3}},
      {'d', {6, 5, 5, 5, 6}}, {'e', {7, 4, 6, 4, 7}}, {'f', {7, 4, 6, 4, 4}},
      {'g', {3, 4, 5, 5, 3}}, {'h', {5, 5, 7, 5, 5}}, {'i', {7, 2, 2, 2, 7}},
      {'j', {1, 1, 1, 5, 2}}, {'k', {5, 5, 6, 5, 5}}, {'l', {4, 4, 4, 4, 7}},
      {'m', {5, 7, 7, 5, 5}}, {'n', {6, 5, 5, 5, 5}}, {'o', {2, 5, 5, 5, 2}},
      {'p', {6, 5, 6, 4, 4}}, {'q', {2, 5, 5, 6, 3}}, {'r', {6, 5, 6, 5, 5}},
      {'s', {3, 4, 2, 1, 6}}, {'t', {7, 2, 2, 2, 2}}, {'u', {5, 5, 5, 5, 7}},
      {'v', {5, 5, 5, 5, 2}}, {'w', {5, 5, 7, 7, 5}}, {'x', {5, 5, 2, 5, 5}},
      {'y', {5, 5, 2, 2, 2}}, {'z', {7, 1, 2, 4, 7}}, {'0', {7, 5, 5, 5, 7}},
      {'1', {2, 6, 2, 2, 7}}, {'2', {6, 1, 2, 4, 7}}, {'3', {6, 1, 2, 1, 6}},
      {'4', {5, 5, 7, 1, 1}}, {'5', {7, 4, 6, 1, 6}}, {'6', {3, 4, 6, 5, 2}},
      {'7', {7, 1, 2, 2, 2}}, {'8', {2, 5, 2, 5, 2}}, {'9', {2, 5, 3, 1, 6}},
      {'_', {0, 0, 0, 0, 7}}, {'-', {0, 0, 7, 0, 0}}, {' ', {0, 0, 0, 0, 0}}};
  return kFont;
}

void DrawText(Image& img, int x, int y, const std::string& text, int px, const Vec3& colour) {
  for (char ch : text) {
    const auto it = Font().find(static_cast<char>(std::tolower(static_cast<unsigned char>(ch))));
    if (it != Font().end()) {
      for (int r = 0; r < 5; ++r) {
        for (int c = 0; c < 3; ++c) {
          if (!((it->second[r] >> (2 - c)) & 1)) continue;
          for (int dy = 0; dy < px; ++dy) {
            for (int dx = 0; dx < px; ++dx) {
              const int xx = x + c * px + dx, yy = y + r * px + dy;
              if (xx >= 0 && yy >= 0 && xx < img.w && yy < img.h) img.Set(xx, yy, colour);
            }
          }
        }
      }
    }
    x += 4 * px;
  }
}

}  // namespace

// Renders the models as a grid (`cols` per row, label under each) and writes the PNG.
void RenderSheet(const std::vector<RenderTile>& models, int cols, int tile,
                 const std::string& out) {
  constexpr int kSs = 3;  // supersampling factor
  const int rows = (static_cast<int>(models.size()) + cols - 1) / cols;
  const int label = 24;
  Image big(cols * tile * kSs, rows * (tile + label) * kSs, 1.0f);
  for (std::size_t i = 0; i < models.size(); ++i) {
    const int r = static_cast<int>(i) / cols, c = static_cast<int>(i) % cols;
    const int x0 = c * tile * kSs, y0 = r * (tile + label) * kSs;
    RenderMesh(models[i], big, x0, y0, tile * kSs);
    // Family name under the tile, wrapped once at an underscore when too long.
    std::string line1 = models[i].label, line2;
    const std::size_t max_chars = static_cast<std::size_t>((tile - 8) / 8);
    if (line1.size() > max_chars) {
      std::size_t cut = line1.rfind('_', max_chars);
      if (cut == std::string::npos || cut == 0) cut = max_chars;
      line2 = line1.substr(cut);
      line1.resize(cut);
      if (line2.size() > max_chars) line2.resize(max_chars);
    }
    const Vec3 ink(0.1, 0.1, 0.1);
    DrawText(big, x0 + 4 * kSs, y0 + tile * kSs, line1, 2 * kSs, ink);
    DrawText(big, x0 + 4 * kSs, y0 + (tile + 12) * kSs, line2, 2 * kSs, ink);
  }
  const int w = cols * tile, h = rows * (tile + label);
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(3) * w * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int k = 0; k < 3; ++k) {
        double acc = 0;
        for (int dy = 0; dy < kSs; ++dy) {
          for (int dx = 0; dx < kSs; ++dx) {
            acc += big.rgb[3 * (static_cast<std::size_t>(y * kSs + dy) * big.w + x * kSs + dx) + k];
          }
        }
        const double v = std::clamp(acc / (kSs * kSs), 0.0, 1.0);
        rgb[3 * (static_cast<std::size_t>(y) * w + x) + k] =
            static_cast<std::uint8_t>(std::lround(255.0 * v));
      }
    }
  }
  WritePng(out, w, h, rgb);
}

// ---------------------------------------------------------------------------------------
// Perspective scene panels.
// ---------------------------------------------------------------------------------------
Vec3 PaletteColour(int index) {
  static const std::array<Vec3, 12> kPalette = {
      Vec3(0.90, 0.35, 0.30), Vec3(0.30, 0.55, 0.90), Vec3(0.35, 0.75, 0.35),
      Vec3(0.95, 0.70, 0.20), Vec3(0.65, 0.40, 0.80), Vec3(0.25, 0.75, 0.75),
      Vec3(0.90, 0.50, 0.70), Vec3(0.60, 0.45, 0.30), Vec3(0.55, 0.80, 0.20),
      Vec3(0.20, 0.40, 0.60), Vec3(0.85, 0.55, 0.40), Vec3(0.50, 0.50, 0.85)};
  const int n = static_cast<int>(kPalette.size());
  return kPalette[((index % n) + n) % n];
}

namespace {

struct Camera {
  Vec3 eye, right, up, fwd;
  double focal = 1;  // pixels
  double cx = 0, cy = 0;
  // Pixel position (x, y) and depth along fwd; depth <= 0 = behind the camera.
  Vec3 Project(const Vec3& p) const {
    const Vec3 d = p - eye;
    const double z = d.dot(fwd);
    if (z <= 1e-6) return Vec3(0, 0, -1);
    return Vec3(cx + focal * d.dot(right) / z, cy - focal * d.dot(up) / z, z);
  }
};

// `bias`: a surface wins against what is already drawn up to this much behind it (meshes over
// the observed points that lie on them).
void RasterTriangle(Image& img, std::vector<double>& zbuf, int x0, int w, int h, const Vec3& a,
                    const Vec3& b, const Vec3& c, const Vec3& colour, double bias) {
  if (a.z() <= 0 || b.z() <= 0 || c.z() <= 0) return;
  const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
  if (std::abs(area) < 1e-12) return;
  const int xa = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
  const int xb = std::min(w - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
  const int ya = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
  const int yb = std::min(h - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
  for (int y = ya; y <= yb; ++y) {
    for (int x = xa; x <= xb; ++x) {
      const double px = x + 0.5, py = y + 0.5;
      const double w0 = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) / area;
      const double w1 = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) / area;
      const double w2 = 1.0 - w0 - w1;
      if (w0 < 0 || w1 < 0 || w2 < 0) continue;
      // Perspective-correct depth: interpolate 1/z.
      const double iz = w0 / a.z() + w1 / b.z() + w2 / c.z();
      const double z = 1.0 / iz;
      double& zb = zbuf[static_cast<std::size_t>(y) * w + x];
      if (z >= zb + bias) continue;
      zb = z;
      img.Set(x0 + x, y, colour);
    }
  }
}

void RasterLine(Image& img, std::vector<double>& zbuf, int x0, int w, int h, const Vec3& a,
                const Vec3& b, const Vec3& colour, int thickness) {
  if (a.z() <= 0 || b.z() <= 0) return;
  const double len = std::max(std::abs(b.x() - a.x()), std::abs(b.y() - a.y()));
  const int steps = std::max(1, static_cast<int>(std::ceil(len)));
  for (int s = 0; s <= steps; ++s) {
    const double t = static_cast<double>(s) / steps;
    const double x = a.x() + t * (b.x() - a.x()), y = a.y() + t * (b.y() - a.y());
    const double z = 1.0 / ((1 - t) / a.z() + t / b.z());
    for (int dy = -thickness / 2; dy <= thickness / 2; ++dy) {
      for (int dx = -thickness / 2; dx <= thickness / 2; ++dx) {
        const int xi = static_cast<int>(x) + dx, yi = static_cast<int>(y) + dy;
        if (xi < 0 || yi < 0 || xi >= w || yi >= h) continue;
        double& zb = zbuf[static_cast<std::size_t>(yi) * w + xi];
        if (z >= zb * 1.02 + 0.02) continue;  // lines win near-ties with surfaces
        zb = std::min(zb, z);
        img.Set(x0 + xi, yi, colour);
      }
    }
  }
}

}  // namespace

void RenderScenePanels(const std::vector<ScenePanel>& panels, int width, int height,
                       const std::string& out) {
  if (panels.empty()) throw InvalidArgument("RenderScenePanels: no panels");
  if (width < 16 || height < 16) throw InvalidArgument("RenderScenePanels: size below 16 px");
  geometry::AABB bounds;
  for (const auto& p : panels) {
    for (const auto& q : p.points) {
      if (q.allFinite()) bounds.Extend(q);
    }
    for (const auto& m : p.meshes) {
      for (const auto& v : m.mesh.vertices) {
        if (v.allFinite()) bounds.Extend(v);
      }
    }
  }
  if (bounds.Empty()) throw InvalidArgument("RenderScenePanels: nothing to frame");
  constexpr int kSs = 2;
  const int pw = width * kSs, ph = height * kSs;
  const int title_h = 14 * kSs;
  // Camera from above the (-x, -y) corner, looking at the centre, about 40 degrees down; the
  // focal length is then chosen so that the projected bounding box fills the panel.
  const Vec3 centre = bounds.Center();
  const double radius = std::max(0.5 * bounds.Extent().norm(), 0.25);
  Camera cam;
  const Vec3 dir = Vec3(-0.62, -0.95, 0.9).normalized();  // from the centre to the eye
  cam.eye = centre + dir * radius * 2.2;
  cam.fwd = (centre - cam.eye).normalized();
  cam.right = cam.fwd.cross(Vec3::UnitZ()).normalized();
  cam.up = cam.right.cross(cam.fwd);
  cam.focal = 1.0;
  cam.cx = 0;
  cam.cy = 0;
  double umin = 1e30, umax = -1e30, vmin = 1e30, vmax = -1e30;
  for (int c = 0; c < 8; ++c) {
    const Vec3 corner((c & 1) ? bounds.max.x() : bounds.min.x(),
                      (c & 2) ? bounds.max.y() : bounds.min.y(),
                      (c & 4) ? bounds.max.z() : bounds.min.z());
    const Vec3 q = cam.Project(corner);
    umin = std::min(umin, q.x());
    umax = std::max(umax, q.x());
    vmin = std::min(vmin, q.y());
    vmax = std::max(vmax, q.y());
  }
  const double avail_w = 0.94 * pw, avail_h = 0.94 * (ph - title_h);
  cam.focal =
      std::min(avail_w / std::max(umax - umin, 1e-9), avail_h / std::max(vmax - vmin, 1e-9));
  cam.cx = 0.5 * pw - cam.focal * 0.5 * (umin + umax);
  cam.cy = title_h + 0.5 * (ph - title_h) - cam.focal * 0.5 * (vmin + vmax);
  const Vec3 light = Vec3(0.4, -0.3, 1.0).normalized();
  const int n = static_cast<int>(panels.size());
  Image big(n * pw, ph, 1.0f);
  const int point_px = std::max(2, static_cast<int>(std::lround(1.5 * kSs * width / 800.0)));
  for (int k = 0; k < n; ++k) {
    const ScenePanel& panel = panels[k];
    const int x0 = k * pw;
    std::vector<double> zbuf(static_cast<std::size_t>(pw) * ph, 1e30);
    for (std::size_t i = 0; i < panel.points.size(); ++i) {
      if (!panel.points[i].allFinite()) continue;
      const Vec3 q = cam.Project(panel.points[i]);
      if (q.z() <= 0) continue;
      const Vec3 colour =
          i < panel.point_colors.size() ? panel.point_colors[i] : Vec3(0.55, 0.55, 0.55);
      const int rad = point_px;
      for (int dy = 0; dy < rad; ++dy) {
        for (int dx = 0; dx < rad; ++dx) {
          const int xi = static_cast<int>(q.x()) + dx, yi = static_cast<int>(q.y()) + dy;
          if (xi < 0 || yi < 0 || xi >= pw || yi >= ph) continue;
          double& zb = zbuf[static_cast<std::size_t>(yi) * pw + xi];
          if (q.z() >= zb) continue;
          zb = q.z();
          big.Set(x0 + xi, yi, colour);
        }
      }
    }
    for (const auto& m : panel.meshes) {
      std::vector<Vec3> proj(m.mesh.vertices.size());
      for (std::size_t i = 0; i < proj.size(); ++i) proj[i] = cam.Project(m.mesh.vertices[i]);
      for (const auto& f : m.mesh.faces) {
        const Vec3& a = m.mesh.vertices[f[0]];
        const Vec3 nrm = (m.mesh.vertices[f[1]] - a).cross(m.mesh.vertices[f[2]] - a);
        if (nrm.norm() == 0) continue;
        Vec3 nn = nrm.normalized();
        if (nn.dot(cam.eye - a) < 0) nn = -nn;  // two-sided
        const double shade =
            0.35 + 0.5 * std::max(0.0, nn.dot(light)) + 0.15 * std::abs(nn.dot(cam.fwd));
        RasterTriangle(big, zbuf, x0, pw, ph, proj[f[0]], proj[f[1]], proj[f[2]], m.color * shade,
                       0.03);
      }
    }
    for (const auto& b : panel.boxes) {
      const auto c = b.box.Corners();
      static const int kEdges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                        {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
      for (const auto& e : kEdges) {
        RasterLine(big, zbuf, x0, pw, ph, cam.Project(c[e[0]]), cam.Project(c[e[1]]), b.color, kSs);
      }
    }
    DrawText(big, x0 + 4 * kSs, 3 * kSs, panel.title, 2 * kSs, Vec3(0.1, 0.1, 0.1));
    // Panel separator.
    if (k > 0) {
      for (int y = 0; y < ph; ++y) big.Set(x0, y, Vec3(0.7, 0.7, 0.7));
    }
  }
  const int w = n * width, h = height;
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(3) * w * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        double acc = 0;
        for (int dy = 0; dy < kSs; ++dy) {
          for (int dx = 0; dx < kSs; ++dx) {
            acc += big.rgb[3 * (static_cast<std::size_t>(y * kSs + dy) * big.w + x * kSs + dx) + c];
          }
        }
        rgb[3 * (static_cast<std::size_t>(y) * w + x) + c] =
            static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(acc / (kSs * kSs), 0.0, 1.0)));
      }
    }
  }
  WritePng(out, w, h, rgb);
}

}  // namespace dimr::tools
