// `dimr cad generate | stats | render`: the procedural CAD library from the command line.
//   dimr cad generate --class chair --count 100 --seed 0 --out data/cad
//   dimr cad stats --dir data/cad
//   dimr cad render --out docs/img/cad_contact_sheet.png --per-class 6
// `render` draws a labelled contact sheet with a small z-buffer software rasteriser and writes a
// PNG (own encoder: zlib stream with fixed-Huffman deflate blocks, CRC-32 and Adler-32).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/labels.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/error.h"
#include "tools/command_registry.h"

namespace {

using dimr::data::CadModel;
using dimr::geometry::Vec3;

// ---------------------------------------------------------------------------------------
// PNG encoding.
// ---------------------------------------------------------------------------------------
std::uint32_t Crc32(const std::uint8_t* data, std::size_t n, std::uint32_t crc = 0) {
  static const std::array<std::uint32_t, 256> kTable = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = kTable[(crc ^ data[i]) & 0xff] ^ (crc >> 8);
  return ~crc;
}

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
    const std::uint32_t crc = Crc32(body.data(), body.size());
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

Vec3 PartColour(const std::string& name) {
  std::uint32_t h = 2166136261u;
  for (unsigned char c : name) h = (h ^ c) * 16777619u;
  static const std::array<Vec3, 8> kPalette = {Vec3(0.80, 0.55, 0.35), Vec3(0.45, 0.60, 0.80),
                                               Vec3(0.60, 0.75, 0.45), Vec3(0.85, 0.75, 0.45),
                                               Vec3(0.70, 0.50, 0.70), Vec3(0.55, 0.55, 0.55),
                                               Vec3(0.85, 0.50, 0.50), Vec3(0.45, 0.75, 0.75)};
  return kPalette[h % kPalette.size()];
}

// Renders the model (real proportions) into the square tile at (x0, y0) of size `tile`
// (image pixels = tile * ss), orthographic view from front-left-above.
void RenderModel(const CadModel& m, Image& img, int x0, int y0, int tile) {
  const Vec3 eye = Vec3(1.0, 0.75, 0.6).normalized();  // from the object towards the viewer
  const Vec3 fwd = -eye;
  const Vec3 right = fwd.cross(Vec3::UnitZ()).normalized();
  const Vec3 up = right.cross(fwd);
  const Vec3 light = Vec3(0.6, 0.3, 1.0).normalized();
  const double scale_max = m.nominal_size.maxCoeff();
  std::vector<Vec3> p(m.mesh.vertices.size());
  double umin = 1e9, umax = -1e9, vmin = 1e9, vmax = -1e9;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3 w = m.mesh.vertices[i].cwiseProduct(m.nominal_size) / scale_max;
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
  for (int part = 0; part < m.NumParts(); ++part) {
    const Vec3 base = PartColour(m.part_names[part]);
    for (int f = m.PartBegin(part); f < m.PartEnd(part); ++f) {
      const auto& t = m.mesh.faces[f];
      const Vec3 wa = m.mesh.vertices[t[0]].cwiseProduct(m.nominal_size);
      const Vec3 n = (m.mesh.vertices[t[1]].cwiseProduct(m.nominal_size) - wa)
                         .cross(m.mesh.vertices[t[2]].cwiseProduct(m.nominal_size) - wa);
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

// Renders the models as a grid (`cols` per row, label under each) and writes the PNG.
void RenderSheet(const std::vector<CadModel>& models, int cols, int tile, const std::string& out) {
  constexpr int kSs = 3;  // supersampling factor
  const int rows = (static_cast<int>(models.size()) + cols - 1) / cols;
  const int label = 24;
  Image big(cols * tile * kSs, rows * (tile + label) * kSs, 1.0f);
  for (std::size_t i = 0; i < models.size(); ++i) {
    const int r = static_cast<int>(i) / cols, c = static_cast<int>(i) % cols;
    const int x0 = c * tile * kSs, y0 = r * (tile + label) * kSs;
    RenderModel(models[i], big, x0, y0, tile * kSs);
    // Family name under the tile, wrapped once at an underscore when too long.
    std::string line1 = models[i].family, line2;
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
// Commands.
// ---------------------------------------------------------------------------------------
std::vector<int> ParseClasses(const std::string& name) {
  if (name == "all") {
    std::vector<int> all(dimr::data::kNumCadClasses);
    for (int c = 0; c < dimr::data::kNumCadClasses; ++c) all[c] = c;
    return all;
  }
  const int c = dimr::data::CadClassFromName(name);
  if (c < 0) {
    throw dimr::InvalidArgument("--class: unknown CAD class '" + name +
                                "' (table, chair, bookshelf, sofa, trash_bin, cabinet, display, "
                                "bathtub or all)");
  }
  return {c};
}

struct GenerateArgs {
  std::string cls = "all";
  int count = 10;
  std::uint64_t seed = 0;
  std::string out;
  int precision = 8;
};

void SetupGenerate(CLI::App& app) {
  auto a = std::make_shared<GenerateArgs>();
  app.add_option("--class", a->cls, "CAD class name or 'all'")->capture_default_str();
  app.add_option("--count", a->count, "models per class")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  app.add_option("--seed", a->seed, "first seed (models use seed, seed+1, ...)")
      ->capture_default_str();
  app.add_option("--out", a->out, "output ShapeNet-style tree")->required();
  app.add_option("--precision", a->precision, "OBJ digits after the decimal point")
      ->capture_default_str()
      ->check(CLI::Range(1, 17));
  app.callback([a]() {
    const std::vector<int> classes = ParseClasses(a->cls);
    std::size_t faces = 0, total = 0;
    for (int c : classes) {
      std::vector<CadModel> models;
      models.reserve(a->count);
      for (int i = 0; i < a->count; ++i) {
        models.push_back(dimr::data::GenerateCadModel(c, a->seed + static_cast<std::uint64_t>(i)));
        faces += models.back().mesh.faces.size();
      }
      dimr::data::WriteShapeNetTree(a->out, models, a->precision);
      total += models.size();
      std::printf("%-10s %d models -> %s/%s\n", dimr::data::CadClassNames()[c], a->count,
                  a->out.c_str(), dimr::data::CadSynsets()[c]);
    }
    std::printf("wrote %zu models (mean %.0f triangles), index %s/index.json\n", total,
                total ? static_cast<double>(faces) / total : 0.0, a->out.c_str());
  });
}

void SetupStats(CLI::App& app) {
  auto dir = std::make_shared<std::string>();
  app.add_option("--dir,--out", *dir, "ShapeNet-style tree written by `dimr cad generate`")
      ->required();
  app.callback([dir]() {
    const auto models = dimr::data::ReadShapeNetTree(*dir);
    struct Row {
      int n = 0;
      std::map<std::string, int> families;
      double faces = 0, parts = 0;
      Vec3 size_min = Vec3::Constant(1e9), size_max = Vec3::Zero();
    };
    std::map<std::string, Row> rows;
    for (const auto& m : models) {
      const std::string name =
          m.cad_class >= 0 ? dimr::data::CadClassNames()[m.cad_class] : std::string("other");
      Row& r = rows[name];
      ++r.n;
      ++r.families[m.family];
      r.faces += static_cast<double>(m.mesh.faces.size());
      r.parts += m.NumParts();
      r.size_min = r.size_min.cwiseMin(m.nominal_size);
      r.size_max = r.size_max.cwiseMax(m.nominal_size);
    }
    std::printf("%-10s %7s %9s %9s %7s  %-31s %s\n", "class", "models", "families", "mean_tris",
                "parts", "size min..max (x y z, m)", "family counts");
    for (const auto& [name, r] : rows) {
      std::string fams;
      for (const auto& [f, n] : r.families) fams += f + ":" + std::to_string(n) + " ";
      std::printf("%-10s %7d %9zu %9.0f %7.1f  %4.2f..%4.2f %4.2f..%4.2f %4.2f..%4.2f  %s\n",
                  name.c_str(), r.n, r.families.size(), r.faces / r.n, r.parts / r.n,
                  r.size_min.x(), r.size_max.x(), r.size_min.y(), r.size_max.y(), r.size_min.z(),
                  r.size_max.z(), fams.c_str());
    }
    std::printf("total: %zu models\n", models.size());
  });
}

struct RenderArgs {
  std::string out;
  std::string cls = "all";
  int per_class = 6;
  std::uint64_t seed = 0;
  int tile = 160;
  bool distractors = false;
  bool families = false;
  int cols = 0;
};

void SetupRender(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  app.add_option("--out", a->out, "PNG file")->required();
  app.add_option("--class", a->cls, "CAD class name or 'all'")->capture_default_str();
  app.add_option("--per-class", a->per_class, "models per row")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--seed", a->seed, "first seed")->capture_default_str();
  app.add_option("--tile", a->tile, "tile size in pixels")
      ->capture_default_str()
      ->check(CLI::Range(32, 1024));
  app.add_option("--cols", a->cols, "tiles per row (default: --per-class, 6 with --families)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--distractors", a->distractors, "render the distractor kinds instead");
  app.add_flag("--families", a->families,
               "one model of each family per class (first seed with that family)");
  app.callback([a]() {
    std::vector<CadModel> models;
    int cols = a->per_class;
    if (a->distractors) {
      for (int k = 0; k < dimr::data::NumDistractorKinds(); ++k) {
        for (int i = 0; i < a->per_class; ++i) {
          models.push_back(dimr::data::GenerateDistractor(k, a->seed + i));
        }
      }
    } else {
      for (int c : ParseClasses(a->cls)) {
        if (a->families) {
          const auto fams = dimr::data::CadFamilies(c);
          cols = 6;
          std::set<std::string> seen;
          std::vector<CadModel> row;
          for (std::uint64_t s = a->seed; seen.size() < fams.size() && s < a->seed + 10000; ++s) {
            CadModel m = dimr::data::GenerateCadModel(c, s);
            if (seen.insert(m.family).second) row.push_back(std::move(m));
          }
          std::sort(row.begin(), row.end(), [&](const CadModel& x, const CadModel& y) {
            return std::find(fams.begin(), fams.end(), x.family) <
                   std::find(fams.begin(), fams.end(), y.family);
          });
          for (auto& m : row) models.push_back(std::move(m));
          // Pad the row so that each class starts a new row.
          while (models.size() % cols != 0) {
            models.push_back(models.back());
            models.back().mesh.faces.clear();
            models.back().part_face_begin.clear();
            models.back().part_names.clear();
            models.back().family.clear();
          }
          continue;
        }
        for (int i = 0; i < a->per_class; ++i) {
          models.push_back(dimr::data::GenerateCadModel(c, a->seed + i));
        }
      }
    }
    if (a->cols > 0 && !a->families) cols = a->cols;
    RenderSheet(models, cols, a->tile, a->out);
    std::printf("rendered %zu models -> %s\n", models.size(), a->out.c_str());
  });
}

const dimr::tools::Registrar kRegGenerate("cad", "generate",
                                          "Generate procedural CAD models as a ShapeNet tree",
                                          &SetupGenerate);
const dimr::tools::Registrar kRegStats("cad", "stats", "Summarise a ShapeNet-style CAD tree",
                                       &SetupStats);
const dimr::tools::Registrar kRegRender("cad", "render",
                                        "Render a contact sheet of CAD models to PNG",
                                        &SetupRender);

}  // namespace
