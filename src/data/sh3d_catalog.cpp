// Sweet Home 3D furniture catalogue importer (see include/dimr/data/sh3d_catalog.h).
#include "dimr/data/sh3d_catalog.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <unordered_map>

#ifdef DIMR_HAVE_PNG
#include <png.h>
#endif
#ifdef DIMR_HAVE_JPEG
#include <jpeglib.h>

#include <csetjmp>
#endif

#include "dimr/core/error.h"
#include "dimr/core/hash.h"
#include "dimr/core/labels.h"
#include "dimr/core/parallel.h"
#include "dimr/data/synth_random.h"

namespace dimr::data {
namespace {

using geometry::Color;
using geometry::TriangleMesh;
using geometry::Vec3;
using geometry::Vec3i;

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::uint32_t Le32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
std::uint16_t Le16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | p[1] << 8); }

void AppendUtf8(std::uint32_t cp, std::string* out) {
  if (cp < 0x80) {
    out->push_back(static_cast<char>(cp));
  } else if (cp < 0x800) {
    out->push_back(static_cast<char>(0xC0 | (cp >> 6)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else if (cp < 0x10000) {
    out->push_back(static_cast<char>(0xE0 | (cp >> 12)));
    out->push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else {
    out->push_back(static_cast<char>(0xF0 | (cp >> 18)));
    out->push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  }
}

}  // namespace

// =======================================================================================
// Zip.
// =======================================================================================
ZipArchive ZipArchive::Open(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ParseError(path, "cannot open zip archive");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) throw ParseError(path, "read error");
  return FromBytes(std::move(bytes), path);
}

ZipArchive ZipArchive::FromBytes(std::vector<std::uint8_t> bytes, const std::string& source) {
  ZipArchive z;
  z.source_ = source;
  const std::size_t n = bytes.size();
  if (n < 22) throw ParseError(source, "not a zip archive (" + std::to_string(n) + " bytes)");
  // End of central directory: the last signature within the final 64 KiB + 22 bytes.
  std::size_t eocd = std::string::npos;
  const std::size_t lowest = n > 65557 ? n - 65557 : 0;
  for (std::size_t i = n - 22 + 1; i-- > lowest;) {
    if (Le32(&bytes[i]) == 0x06054b50u) {
      eocd = i;
      break;
    }
  }
  if (eocd == std::string::npos)
    throw ParseError(source, "not a zip archive (no end-of-central-directory record)");
  const std::uint16_t count = Le16(&bytes[eocd + 10]);
  const std::uint32_t cd_size = Le32(&bytes[eocd + 12]);
  const std::uint32_t cd_offset = Le32(&bytes[eocd + 16]);
  if (cd_offset == 0xFFFFFFFFu || count == 0xFFFF)
    throw ParseError(source, "zip64 archives are not supported");
  if (static_cast<std::uint64_t>(cd_offset) + cd_size > eocd)
    throw ParseError(source, "central directory (offset " + std::to_string(cd_offset) + ", " +
                                 std::to_string(cd_size) + " bytes) lies outside the file");
  std::size_t p = cd_offset;
  for (int i = 0; i < count; ++i) {
    if (p + 46 > eocd || Le32(&bytes[p]) != 0x02014b50u)
      throw ParseError(source, "central directory entry " + std::to_string(i) + " is malformed");
    Entry e;
    e.method = Le16(&bytes[p + 10]);
    e.crc = Le32(&bytes[p + 16]);
    e.compressed = Le32(&bytes[p + 20]);
    e.uncompressed = Le32(&bytes[p + 24]);
    const std::size_t nlen = Le16(&bytes[p + 28]), xlen = Le16(&bytes[p + 30]),
                      clen = Le16(&bytes[p + 32]);
    e.local_offset = Le32(&bytes[p + 42]);
    if (p + 46 + nlen + xlen + clen > eocd)
      throw ParseError(source, "central directory entry " + std::to_string(i) + " is truncated");
    e.name.assign(reinterpret_cast<const char*>(&bytes[p + 46]), nlen);
    p += 46 + nlen + xlen + clen;
    if (e.name.empty() || e.name.back() == '/') continue;  // directories
    z.by_name_.emplace(e.name, z.entries_.size());
    z.entries_.push_back(std::move(e));
  }
  z.bytes_ = std::make_shared<const std::vector<std::uint8_t>>(std::move(bytes));
  return z;
}

std::vector<std::string> ZipArchive::Names() const {
  std::vector<std::string> out;
  out.reserve(entries_.size());
  for (const auto& e : entries_) out.push_back(e.name);
  return out;
}

const ZipArchive::Entry* ZipArchive::Find(const std::string& name_in) const {
  std::string name = name_in;
  while (!name.empty() && name.front() == '/') name.erase(name.begin());
  auto it = by_name_.find(name);
  if (it != by_name_.end()) return &entries_[it->second];
  const std::string lower = Lower(name);
  for (const auto& e : entries_) {
    if (Lower(e.name) == lower) return &e;
  }
  return nullptr;
}

bool ZipArchive::Contains(const std::string& name) const { return Find(name) != nullptr; }

std::vector<std::uint8_t> ZipArchive::Read(const std::string& name) const {
  const Entry* e = Find(name);
  const std::string where = source_ + ":" + name;
  if (!e) throw ParseError(where, "no such entry in the archive");
  const auto& b = *bytes_;
  const std::uint64_t lo = e->local_offset;
  if (lo + 30 > b.size() || Le32(&b[lo]) != 0x04034b50u)
    throw ParseError(where, "local header at offset " + std::to_string(lo) + " is malformed");
  const std::uint64_t data = lo + 30 + Le16(&b[lo + 26]) + Le16(&b[lo + 28]);
  if (data + e->compressed > b.size())
    throw ParseError(where, "entry data (" + std::to_string(e->compressed) +
                                " bytes) runs past the end of the file");
  if (e->uncompressed > (std::uint64_t{1} << 31))
    throw ParseError(where, "entry too large (" + std::to_string(e->uncompressed) + " bytes)");
  // Deflate cannot expand by more than ~1032:1: a larger claim is a corrupt directory (and would
  // make us allocate gigabytes for nothing).
  if (e->method == 8 && e->uncompressed > e->compressed * 1032 + 1024)
    throw ParseError(where, "uncompressed size " + std::to_string(e->uncompressed) +
                                " impossible for " + std::to_string(e->compressed) +
                                " deflated bytes");
  std::vector<std::uint8_t> out(static_cast<std::size_t>(e->uncompressed));
  if (e->method == 0) {
    if (e->compressed != e->uncompressed)
      throw ParseError(where, "stored entry with different sizes");
    std::copy(b.begin() + static_cast<std::ptrdiff_t>(data),
              b.begin() + static_cast<std::ptrdiff_t>(data + e->compressed), out.begin());
  } else if (e->method == 8) {
    z_stream zs{};
    if (inflateInit2(&zs, -MAX_WBITS) != Z_OK) throw ParseError(where, "inflateInit2 failed");
    zs.next_in = const_cast<Bytef*>(&b[static_cast<std::size_t>(data)]);
    zs.avail_in = static_cast<uInt>(e->compressed);
    zs.next_out = out.data();
    zs.avail_out = static_cast<uInt>(out.size());
    const int rc = inflate(&zs, Z_FINISH);
    const std::uint64_t produced = zs.total_out;
    inflateEnd(&zs);
    if (rc != Z_STREAM_END || produced != e->uncompressed)
      throw ParseError(where, "corrupt deflate stream (zlib " + std::to_string(rc) + ", " +
                                  std::to_string(produced) + " of " +
                                  std::to_string(e->uncompressed) + " bytes)");
  } else {
    throw ParseError(where, "unsupported compression method " + std::to_string(e->method));
  }
  const std::uint32_t crc =
      static_cast<std::uint32_t>(crc32(0L, out.data(), static_cast<uInt>(out.size())));
  if (crc != e->crc) throw ParseError(where, "CRC-32 mismatch (entry is corrupt)");
  return out;
}

// =======================================================================================
// Java .properties.
// =======================================================================================
std::map<std::string, std::string> ParseJavaProperties(const std::string& text,
                                                       const std::string& source) {
  // Natural lines.
  std::vector<std::string> lines;
  {
    std::string cur;
    for (std::size_t i = 0; i < text.size(); ++i) {
      const char c = text[i];
      if (c == '\n' || c == '\r') {
        lines.push_back(cur);
        cur.clear();
        if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      } else {
        cur.push_back(c);
      }
    }
    if (!cur.empty()) lines.push_back(cur);
  }
  auto is_blank = [](char c) { return c == ' ' || c == '\t' || c == '\f'; };
  std::map<std::string, std::string> out;
  for (std::size_t li = 0; li < lines.size(); ++li) {
    const std::size_t first_line = li + 1;
    std::string s = lines[li];
    std::size_t b = 0;
    while (b < s.size() && is_blank(s[b])) ++b;
    s.erase(0, b);
    if (s.empty() || s[0] == '#' || s[0] == '!') continue;
    // Logical line: join continuations (odd number of trailing backslashes).
    for (;;) {
      std::size_t bs = 0;
      while (bs < s.size() && s[s.size() - 1 - bs] == '\\') ++bs;
      if (bs % 2 == 0 || li + 1 >= lines.size()) {
        if (bs % 2 == 1) s.pop_back();  // a continuation at the end of the file
        break;
      }
      s.pop_back();
      std::string next = lines[++li];
      std::size_t k = 0;
      while (k < next.size() && is_blank(next[k])) ++k;
      s += next.substr(k);
    }
    // Split key / value on the first unescaped separator.
    std::size_t i = 0;
    std::string raw_key;
    while (i < s.size()) {
      const char c = s[i];
      if (c == '\\' && i + 1 < s.size()) {
        raw_key.push_back(c);
        raw_key.push_back(s[i + 1]);
        i += 2;
        continue;
      }
      if (c == '=' || c == ':' || is_blank(c)) break;
      raw_key.push_back(c);
      ++i;
    }
    while (i < s.size() && is_blank(s[i])) ++i;
    if (i < s.size() && (s[i] == '=' || s[i] == ':')) ++i;
    while (i < s.size() && is_blank(s[i])) ++i;
    const std::string raw_value = s.substr(i);
    auto unescape = [&](const std::string& r) {
      std::string u;
      std::uint32_t pending_high = 0;
      auto flush_high = [&]() {
        if (pending_high) AppendUtf8(0xFFFD, &u);
        pending_high = 0;
      };
      for (std::size_t k = 0; k < r.size(); ++k) {
        const unsigned char c = static_cast<unsigned char>(r[k]);
        if (c == '\\' && k + 1 < r.size()) {
          const char e = r[++k];
          if (e == 'u') {
            if (k + 4 >= r.size())
              throw ParseError(source + ":" + std::to_string(first_line),
                               "malformed \\uXXXX escape (fewer than 4 hex digits)");
            std::uint32_t cp = 0;
            for (int d = 1; d <= 4; ++d) {
              const char h = r[k + d];
              cp <<= 4;
              if (h >= '0' && h <= '9') {
                cp |= static_cast<std::uint32_t>(h - '0');
              } else if (h >= 'a' && h <= 'f') {
                cp |= static_cast<std::uint32_t>(h - 'a' + 10);
              } else if (h >= 'A' && h <= 'F') {
                cp |= static_cast<std::uint32_t>(h - 'A' + 10);
              } else {
                throw ParseError(source + ":" + std::to_string(first_line),
                                 "malformed \\uXXXX escape ('" + r.substr(k - 1, 6) + "')");
              }
            }
            k += 4;
            if (cp >= 0xD800 && cp < 0xDC00) {
              flush_high();
              pending_high = cp;
            } else if (cp >= 0xDC00 && cp < 0xE000) {
              if (pending_high) {
                AppendUtf8(0x10000 + ((pending_high - 0xD800) << 10) + (cp - 0xDC00), &u);
                pending_high = 0;
              } else {
                AppendUtf8(0xFFFD, &u);
              }
            } else {
              flush_high();
              AppendUtf8(cp, &u);
            }
            continue;
          }
          flush_high();
          switch (e) {
            case 't':
              u.push_back('\t');
              break;
            case 'n':
              u.push_back('\n');
              break;
            case 'r':
              u.push_back('\r');
              break;
            case 'f':
              u.push_back('\f');
              break;
            default:
              AppendUtf8(static_cast<unsigned char>(e), &u);
              break;
          }
          continue;
        }
        flush_high();
        AppendUtf8(c, &u);  // ISO 8859-1 byte -> code point
      }
      flush_high();
      return u;
    };
    out[unescape(raw_key)] = unescape(raw_value);
  }
  return out;
}

// =======================================================================================
// Catalogue entries.
// =======================================================================================
std::vector<Sh3dEntry> ParseSh3dCatalog(const std::map<std::string, std::string>& props,
                                        const std::string& catalog, const std::string& source) {
  std::map<int, std::map<std::string, std::string>> by_index;
  for (const auto& [k, v] : props) {
    const std::size_t hash = k.rfind('#');
    if (hash == std::string::npos || hash + 1 >= k.size()) continue;
    const std::string num = k.substr(hash + 1);
    if (!std::all_of(num.begin(), num.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    if (num.size() > 9) continue;
    by_index[std::stoi(num)][k.substr(0, hash)] = v;
  }
  auto get = [&](const std::map<std::string, std::string>& m, const char* key) {
    auto it = m.find(key);
    return it == m.end() ? std::string() : it->second;
  };
  const std::string cat_license = get(props, "license");
  const std::string cat_name = get(props, "name");
  const std::string cat_provider = get(props, "provider");
  std::vector<Sh3dEntry> out;
  for (const auto& [index, m] : by_index) {
    Sh3dEntry e;
    e.catalog = catalog;
    e.index = index;
    e.id = get(m, "id");
    e.name = get(m, "name");
    e.category = get(m, "category");
    e.tags = get(m, "tags");
    e.creator = get(m, "creator");
    e.model_path = get(m, "model");
    e.license = get(m, "license");
    if (e.license.empty()) e.license = cat_license;
    e.catalog_name = cat_name;
    e.catalog_provider = cat_provider;
    e.door_or_window = get(m, "doorOrWindow") == "true";
    if (e.model_path.empty() || get(m, "width").empty()) continue;
    if (e.id.empty()) e.id = catalog + "#" + std::to_string(index);
    auto size = [&](const char* key) {
      const std::string where = source + ": " + key + "#" + std::to_string(index);
      const std::string v = get(m, key);
      char* end = nullptr;
      const double d = std::strtod(v.c_str(), &end);
      if (v.empty() || end == v.c_str() || *end != '\0' || !std::isfinite(d) || d <= 0 || d > 1e5)
        throw ParseError(where, "size '" + v + "' is not a positive number of centimetres");
      return d;
    };
    e.width_cm = size("width");
    e.depth_cm = size("depth");
    e.height_cm = size("height");
    const std::string rot = get(m, "modelRotation");
    if (!rot.empty()) {
      std::istringstream is(rot);
      double a[9];
      for (double& x : a) {
        if (!(is >> x) || !std::isfinite(x))
          throw ParseError(source + ": modelRotation#" + std::to_string(index),
                           "expected 9 numbers, got '" + rot + "'");
      }
      e.model_rotation << a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8];
      if (std::abs(e.model_rotation.determinant()) < 1e-6)
        throw ParseError(source + ": modelRotation#" + std::to_string(index),
                         "singular matrix '" + rot + "'");
      e.has_rotation = true;
    }
    out.push_back(std::move(e));
  }
  return out;
}

// =======================================================================================
// Class map.
// =======================================================================================
namespace {

// Whole-word (letters) occurrence of `w` in lower-case text `s`; `w` may contain spaces.
bool HasWord(const std::string& s, const std::string& w) {
  for (std::size_t p = s.find(w); p != std::string::npos; p = s.find(w, p + 1)) {
    const bool left = p == 0 || !std::isalpha(static_cast<unsigned char>(s[p - 1]));
    const std::size_t e = p + w.size();
    const bool right = e >= s.size() || !std::isalpha(static_cast<unsigned char>(s[e]));
    if (left && right) return true;
  }
  return false;
}
bool Has(const std::string& s, const std::string& w) { return s.find(w) != std::string::npos; }
template <typename... W>
bool AnyWord(const std::string& s, W... w) {
  return (HasWord(s, w) || ...);
}

// Distractor kinds of the procedural library, found by name (cad_library.cpp's table).
int KindByName(const char* name) {
  for (int k = 0; k < NumDistractorKinds(); ++k) {
    if (std::strcmp(GetDistractorInfo(k).name, name) == 0) return k;
  }
  throw InvalidArgument(std::string("sh3d class map: no distractor kind '") + name + "'");
}

Sh3dClass Cad(int cad, const char* label, int rfs = -2) {
  Sh3dClass c;
  c.cad_class = cad;
  c.rfs_class = rfs == -2 ? labels::CadToRfs(cad) : rfs;
  c.label = label;
  return c;
}
Sh3dClass Distractor(const char* kind, const char* label, int rfs = -2) {
  Sh3dClass c;
  c.distractor_kind = KindByName(kind);
  c.rfs_class = rfs == -2 ? GetDistractorInfo(c.distractor_kind).rfs_class : rfs;
  c.label = label;
  return c;
}
Sh3dClass Other(int rfs, const char* label) {
  Sh3dClass c;
  c.rfs_class = rfs;
  c.label = label;
  return c;
}

}  // namespace

Sh3dClass ClassifySh3dEntry(const std::string& name_in, const std::string& category_in) {
  const std::string n = Lower(name_in), cat = Lower(category_in);
  using namespace labels;  // NOLINT(build/namespaces): the RFS / CAD class constants
  if (cat == "characters" || cat == "vehicles" || cat == "staircases") return {};
  // Garden furniture: only chairs, tables, sofas and bins (no trees, pools, huts).
  if (cat == "exterior") {
    const Sh3dClass c = ClassifySh3dEntry(name_in, "");
    const bool keep = c.cad_class == kCadChair || c.cad_class == kCadTable ||
                      c.cad_class == kCadSofa || c.cad_class == kCadTrashBin;
    return keep ? c : Sh3dClass{};
  }
  // Doors and windows (built into walls by our composer; the real ones stand in for them).
  if (cat == "doors and windows") {
    if (Has(n, "window")) return Distractor("window", "window");
    if (Has(n, "door") && !AnyWord(n, "garage", "elevator")) return Distractor("door", "door");
    return {};
  }
  // Lamps first ("desk lamp" is no desk); floor vs table lamp is decided by height on import.
  if (Has(n, "lamp")) {
    if (AnyWord(n, "ceiling", "wall", "pendant", "street", "lamppost", "hanging", "chandelier",
                "camping", "outdoor", "park"))
      return {};
    return Distractor("table_lamp", "table_lamp");
  }
  // Never furniture, whatever the other words say.
  if (AnyWord(n, "toy", "model", "doll", "game", "remote", "tennis", "football", "pool",
              "intercom") ||
      Has(n, "wheelchair"))
    return {};
  // ---- CAD classes.
  if (AnyWord(n, "bath", "bathtub", "tub", "corner bathtub", "island bath"))
    return Cad(kCadBathtub, "bathtub");
  if (Has(n, "trash") || AnyWord(n, "dustbin", "bin", "wastebasket", "garbage"))
    return Cad(kCadTrashBin, "trash_bin");
  // ("Screen" alone is a folding room divider, not a display.)
  if (AnyWord(n, "tv", "television", "monitor", "imac") &&
      !AnyWord(n, "stand", "cabinet", "door", "remote"))
    return HasWord(n, "wall") ? Cad(kCadDisplay, "wall_display") : Cad(kCadDisplay, "display");
  // An opened sofa bed is a bed.
  if (HasWord(n, "opened") && AnyWord(n, "sofa", "couch")) return Distractor("bed", "bed");
  if (AnyWord(n, "sofa", "couch", "settee", "loveseat", "chaise")) return Cad(kCadSofa, "sofa");
  if (AnyWord(n, "bedside", "nightstand", "night stand"))
    return Distractor("ottoman", "nightstand");
  if (AnyWord(n, "chair", "armchair", "stool", "seat") && !Has(n, "ottoman"))
    return Cad(kCadChair, "chair");
  if (Has(n, "desk")) return Cad(kCadTable, "desk", kDesk);
  if (AnyWord(n, "table", "workbench") &&
      !AnyWord(n, "dressing", "changing", "fan", "tennis", "football", "pool"))
    return Cad(kCadTable, "table");
  // Kitchen units before the general cabinets: ScanNet's "kitchen cabinet" is its own class.
  if (cat == "kitchen" && (AnyWord(n, "cabinet", "island", "drawers", "extension")))
    return Distractor("kitchen_cabinet", "kitchen_cabinet");
  if (AnyWord(n, "bookcase", "bookshelf", "shelves", "shelf", "etagere"))
    return Cad(kCadBookshelf, "bookshelf");
  if (AnyWord(n, "cabinet", "cupboard", "dresser", "wardrobe", "sideboard", "buffet", "vanity",
              "locker", "drawers", "tv stand") ||
      (HasWord(n, "chest") && !Has(n, "freezer")))
    return Cad(kCadCabinet, "cabinet");
  if (AnyWord(n, "fridge", "refrigerator")) return Cad(kCadCabinet, "fridge");
  // ---- Distractors of the composer.
  if (AnyWord(n, "bed", "crib", "mattress", "futon") && !Has(n, "bedside"))
    return Distractor("bed", "bed");
  if (AnyWord(n, "frame", "painting", "picture", "poster")) return Distractor("picture", "picture");
  if (HasWord(n, "shower curtain")) return Other(kShowerCurtain, "shower_curtain");
  if (HasWord(n, "curtain")) return Distractor("curtain", "curtain");
  if (AnyWord(n, "ottoman", "puff", "pouf")) return Distractor("ottoman", "ottoman");
  if (HasWord(n, "bench")) return Distractor("bench", "bench");
  if (HasWord(n, "radiator")) return Distractor("radiator", "radiator");
  if (AnyWord(n, "oven", "stove", "cooker", "dishwasher", "washing machine", "freezer",
              "water heater", "boiler", "box", "crate", "suitcase", "trunk", "trunck", "basket",
              "barrel"))
    return Distractor("box", "appliance_or_box", -1);
  if (AnyWord(n, "plant", "ficus", "yucca", "bamboo", "cactus", "bonsai", "orchids", "tulips",
              "flowers", "lily", "spathiphyllum", "palm", "christmas tree"))
    return Distractor("plant", "plant");
  if (AnyWord(n, "book", "books")) return Distractor("books", "books");
  // ---- Labelled objects the composer does not place.
  if (HasWord(n, "toilets") || HasWord(n, "toilet") || HasWord(n, "bidet"))
    return HasWord(n, "brush") || HasWord(n, "paper") ? Sh3dClass{} : Other(kToilet, "toilet");
  if (AnyWord(n, "sink", "washbasin", "basin", "lavatory")) return Other(kSink, "sink");
  return {};
}

std::string Sh3dModelId(const Sh3dEntry& e) {
  const std::string key = "dimr-sh3d" + e.catalog + "#" + e.id;
  const std::uint64_t h0 = Fnv1a(key);
  const std::uint64_t h1 = synth::Mix64(h0), h2 = synth::Mix64(h1 ^ 0x9e3779b97f4a7c15ULL);
  char buf[33];
  std::snprintf(buf, sizeof(buf), "%016llx%016llx", static_cast<unsigned long long>(h1),
                static_cast<unsigned long long>(h2));
  return buf;
}

bool IsHeldOutModel(const std::string& model_id) {
  return Fnv1a(std::string("dimr-sh3d-split:") + model_id) % 5 == 0;
}

// =======================================================================================
// OBJ + MTL + textures.
// =======================================================================================
namespace {

struct Image {
  int w = 0, h = 0;
  std::vector<std::uint8_t> rgb;
};

#ifdef DIMR_HAVE_PNG
bool DecodePng(const std::vector<std::uint8_t>& bytes, Image* img) {
  png_image im;
  std::memset(&im, 0, sizeof(im));
  im.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&im, bytes.data(), bytes.size())) return false;
  im.format = PNG_FORMAT_RGB;
  if (im.width == 0 || im.height == 0 || im.width > 16384 || im.height > 16384) {
    png_image_free(&im);
    return false;
  }
  img->w = static_cast<int>(im.width);
  img->h = static_cast<int>(im.height);
  img->rgb.resize(PNG_IMAGE_SIZE(im));
  if (!png_image_finish_read(&im, nullptr, img->rgb.data(), 0, nullptr)) {
    png_image_free(&im);
    return false;
  }
  return true;
}
#endif

#ifdef DIMR_HAVE_JPEG
struct JpegErr {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
};
void JpegErrorExit(j_common_ptr cinfo) {
  std::longjmp(reinterpret_cast<JpegErr*>(cinfo->err)->jump, 1);
}
void JpegSilent(j_common_ptr, int) {}
bool DecodeJpeg(const std::vector<std::uint8_t>& bytes, Image* img) {
  jpeg_decompress_struct cinfo;
  JpegErr err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = &JpegErrorExit;
  err.mgr.emit_message = &JpegSilent;
  // Only plain data lives across the setjmp (no destructors are skipped by the longjmp).
  std::uint8_t* dst = nullptr;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&cinfo, TRUE);
  cinfo.out_color_space = JCS_RGB;
  jpeg_start_decompress(&cinfo);
  if (cinfo.output_width == 0 || cinfo.output_width > 16384 || cinfo.output_height > 16384 ||
      cinfo.output_components != 3) {
    jpeg_destroy_decompress(&cinfo);
    return false;
  }
  img->w = static_cast<int>(cinfo.output_width);
  img->h = static_cast<int>(cinfo.output_height);
  img->rgb.resize(static_cast<std::size_t>(img->w) * img->h * 3);
  dst = img->rgb.data();
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = dst + static_cast<std::size_t>(cinfo.output_scanline) * img->w * 3;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return true;
}
#endif

bool DecodeImage(const std::string& name, const std::vector<std::uint8_t>& bytes, Image* img) {
  const std::string l = Lower(name);
  (void)bytes;
  (void)img;
#ifdef DIMR_HAVE_PNG
  if (l.size() > 4 && l.compare(l.size() - 4, 4, ".png") == 0) return DecodePng(bytes, img);
#endif
#ifdef DIMR_HAVE_JPEG
  if ((l.size() > 4 && l.compare(l.size() - 4, 4, ".jpg") == 0) ||
      (l.size() > 5 && l.compare(l.size() - 5, 5, ".jpeg") == 0))
    return DecodeJpeg(bytes, img);
#endif
  return false;
}

struct Material {
  Vec3 kd = Vec3::Constant(0.8);  // display (sRGB) values in [0, 1]
  std::shared_ptr<Image> texture;
};

std::string DirOf(const std::string& path) {
  const std::size_t s = path.rfind('/');
  return s == std::string::npos ? std::string() : path.substr(0, s + 1);
}

// Resolves a file name relative to the OBJ's folder ("a/b/../c" collapsed).
std::string Resolve(const std::string& dir, std::string name) {
  std::replace(name.begin(), name.end(), '\\', '/');
  std::string joined = name.size() && name[0] == '/' ? name.substr(1) : dir + name;
  std::vector<std::string> parts;
  std::stringstream ss(joined);
  std::string p;
  while (std::getline(ss, p, '/')) {
    if (p.empty() || p == ".") continue;
    if (p == ".." && !parts.empty()) {
      parts.pop_back();
      continue;
    }
    parts.push_back(p);
  }
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i ? "/" : "") + parts[i];
  return out;
}

std::vector<std::string> Tokens(const std::string& line) {
  std::vector<std::string> t;
  std::istringstream is(line);
  std::string w;
  while (is >> w) t.push_back(w);
  return t;
}

std::map<std::string, Material> ParseMtl(const ZipArchive& zip, const std::string& path,
                                         Sh3dLoadStats* st) {
  std::map<std::string, Material> out;
  if (!zip.Contains(path)) return out;
  const auto bytes = zip.Read(path);
  const std::string text(bytes.begin(), bytes.end());
  std::istringstream is(text);
  std::string line;
  Material* cur = nullptr;
  const std::string dir = DirOf(path);
  while (std::getline(is, line)) {
    const auto t = Tokens(line);
    if (t.empty()) continue;
    if (t[0] == "newmtl" && t.size() >= 2) {
      cur = &out[t[1]];
      ++st->materials;
    } else if (cur && t[0] == "Kd" && t.size() >= 4) {
      for (int k = 0; k < 3; ++k) {
        const double v = std::strtod(t[1 + k].c_str(), nullptr);
        cur->kd[k] = std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.8;
      }
    } else if (cur && t[0] == "map_Kd" && t.size() >= 2) {
      const std::string tex = Resolve(dir, t.back());
      auto img = std::make_shared<Image>();
      bool ok = false;
      if (zip.Contains(tex)) ok = DecodeImage(tex, zip.Read(tex), img.get());
      if (ok) {
        cur->texture = img;
        ++st->textures_sampled;
      } else {
        ++st->textures_missing;
      }
    }
  }
  return out;
}

Vec3 SampleTexture(const Image& img, double u, double v) {
  u -= std::floor(u);
  v -= std::floor(v);
  const int x = std::clamp(static_cast<int>(u * img.w), 0, img.w - 1);
  const int y = std::clamp(static_cast<int>((1.0 - v) * img.h), 0, img.h - 1);
  const std::uint8_t* p = &img.rgb[(static_cast<std::size_t>(y) * img.w + x) * 3];
  return Vec3(p[0], p[1], p[2]) / 255.0;
}

int ObjIndex(const std::string& tok, std::size_t count, const std::string& where) {
  char* end = nullptr;
  const long v = std::strtol(tok.c_str(), &end, 10);
  if (end == tok.c_str()) throw ParseError(where, "bad index '" + tok + "'");
  const long idx = v < 0 ? static_cast<long>(count) + v : v - 1;
  if (idx < 0 || idx >= static_cast<long>(count))
    throw ParseError(where, "index " + std::to_string(v) + " out of range (" +
                                std::to_string(count) + " defined)");
  return static_cast<int>(idx);
}

double SrgbToLinear(double c) { return std::pow(std::clamp(c, 0.0, 1.0), 2.2); }

}  // namespace

CadModel LoadSh3dModel(const ZipArchive& zip, const Sh3dEntry& e, const Sh3dClass& cls,
                       Sh3dLoadStats* stats_out) {
  Sh3dLoadStats st;
  const std::string path = Resolve("", e.model_path);
  const std::string where = zip.source() + ":" + path;
  const auto bytes = zip.Read(path);
  const std::string dir = DirOf(path);
  std::map<std::string, Material> mats;
  std::vector<Vec3> v;
  std::vector<std::array<double, 2>> vt;
  // Faces as corners (position index, uv index or -1) plus material name and group run.
  struct Face {
    int p[3];
    int t[3];
    int run;
  };
  std::vector<Face> faces;
  std::vector<std::string> run_names;
  std::vector<const Material*> run_mat;
  std::string group = "mesh";
  const Material* mat = nullptr;
  std::string mat_name;
  bool new_run = true;
  const Material default_mat;
  std::size_t pos = 0, line_no = 0;
  const std::string text(bytes.begin(), bytes.end());
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::string lw = where + ":" + std::to_string(line_no);
    const auto t = Tokens(line);
    if (t.empty()) continue;
    if (t[0] == "v") {
      if (t.size() < 4) throw ParseError(lw, "vertex needs 3 coordinates");
      Vec3 p;
      for (int k = 0; k < 3; ++k) {
        char* q = nullptr;
        p[k] = std::strtod(t[1 + k].c_str(), &q);
        if (q == t[1 + k].c_str() || !std::isfinite(p[k]))
          throw ParseError(lw, "bad vertex coordinate '" + t[1 + k] + "'");
      }
      v.push_back(p);
    } else if (t[0] == "vt") {
      std::array<double, 2> uv{0, 0};
      for (std::size_t k = 0; k < 2 && k + 1 < t.size(); ++k) {
        uv[k] = std::strtod(t[1 + k].c_str(), nullptr);
        if (!std::isfinite(uv[k])) uv[k] = 0;
      }
      vt.push_back(uv);
    } else if (t[0] == "f") {
      if (t.size() < 4) continue;  // degenerate face lines occur in the catalogues: skipped
      std::vector<int> cp, ct;
      for (std::size_t k = 1; k < t.size(); ++k) {
        const std::string& c = t[k];
        const std::size_t s1 = c.find('/');
        cp.push_back(ObjIndex(c.substr(0, s1), v.size(), lw));
        int ti = -1;
        if (s1 != std::string::npos) {
          const std::size_t s2 = c.find('/', s1 + 1);
          const std::string ts =
              c.substr(s1 + 1, s2 == std::string::npos ? std::string::npos : s2 - s1 - 1);
          if (!ts.empty()) ti = ObjIndex(ts, vt.size(), lw);
        }
        ct.push_back(ti);
      }
      if (new_run) {
        run_names.push_back(mat_name.empty() ? group : mat_name);
        run_mat.push_back(mat ? mat : &default_mat);
        new_run = false;
      }
      const int run = static_cast<int>(run_names.size()) - 1;
      for (std::size_t k = 1; k + 1 < cp.size(); ++k) {
        faces.push_back({{cp[0], cp[k], cp[k + 1]}, {ct[0], ct[k], ct[k + 1]}, run});
      }
    } else if (t[0] == "mtllib" && t.size() >= 2) {
      for (std::size_t k = 1; k < t.size(); ++k) {
        auto m = ParseMtl(zip, Resolve(dir, t[k]), &st);
        for (auto& [name, mm] : m) mats[name] = mm;
      }
    } else if (t[0] == "usemtl") {
      mat_name = t.size() >= 2 ? t[1] : std::string();
      auto it = mats.find(mat_name);
      mat = it == mats.end() ? nullptr : &it->second;
      new_run = true;
    } else if (t[0] == "g" || t[0] == "o") {
      group = t.size() >= 2 ? t[1] : "mesh";
      new_run = true;
    }
  }
  st.input_faces = faces.size();
  if (faces.empty() || v.empty()) throw ParseError(where, "OBJ has no faces");

  // Frame: modelRotation, then (x, y, z)_canonical = (z, x, y)_sh3d.
  const Eigen::Matrix3d perm = (Eigen::Matrix3d() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished();
  const Eigen::Matrix3d M = perm * e.model_rotation;
  const bool flip = M.determinant() < 0;
  // Only vertices used by faces count for the bounds.
  std::vector<char> used(v.size(), 0);
  for (const Face& f : faces)
    for (int k = 0; k < 3; ++k) used[f.p[k]] = 1;
  geometry::AABB box;
  std::vector<Vec3> cv(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    cv[i] = M * v[i];
    if (used[i]) box.Extend(cv[i]);
  }
  const Vec3 ext = box.Extent();
  if (!(ext.minCoeff() > 0))
    throw ParseError(where, "model is flat (extent " + std::to_string(ext.x()) + " x " +
                                std::to_string(ext.y()) + " x " + std::to_string(ext.z()) + ")");

  // Corner colours (display values), accumulated per welded vertex.
  std::unordered_map<std::uint64_t, int> weld;
  CadModel m;
  TriangleMesh& mesh = m.mesh;
  std::vector<int> remap(v.size(), -1);
  std::vector<Vec3> col_sum;
  std::vector<double> col_w;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!used[i]) continue;
    Vec3 p = (cv[i] - box.min).cwiseQuotient(ext) - Vec3::Constant(0.5);
    const std::uint64_t key = Fnv1a(p.data(), sizeof(double) * 3);
    auto it = weld.find(key);
    if (it != weld.end() && mesh.vertices[it->second] == p) {
      remap[i] = it->second;
    } else {
      remap[i] = static_cast<int>(mesh.vertices.size());
      weld.emplace(key, remap[i]);
      mesh.vertices.push_back(p);
      col_sum.emplace_back(Vec3::Zero());
      col_w.push_back(0.0);
    }
  }
  // Bounds exactly +-0.5 (the same formula as the procedural generator).
  m.part_names.clear();
  m.part_face_begin.clear();
  int last_run = -1;
  const Eigen::Vector3d scale(e.depth_cm, e.width_cm, e.height_cm);
  for (const Face& f : faces) {
    Vec3i tri(remap[f.p[0]], remap[f.p[1]], remap[f.p[2]]);
    if (flip) std::swap(tri[1], tri[2]);
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) continue;
    const Vec3& a = mesh.vertices[tri[0]];
    const Vec3& b = mesh.vertices[tri[1]];
    const Vec3& c = mesh.vertices[tri[2]];
    const double area = 0.5 * (b - a).cwiseProduct(scale).cross((c - a).cwiseProduct(scale)).norm();
    if (!(area > 1e-12)) continue;
    if (f.run != last_run) {
      m.part_face_begin.push_back(static_cast<int>(mesh.faces.size()));
      m.part_names.push_back(run_names[f.run]);
      last_run = f.run;
    }
    mesh.faces.push_back(tri);
    const Material& mt = *run_mat[f.run];
    for (int k = 0; k < 3; ++k) {
      Vec3 cc = mt.kd;
      if (mt.texture && f.t[k] >= 0) cc = SampleTexture(*mt.texture, vt[f.t[k]][0], vt[f.t[k]][1]);
      col_sum[tri[k]] += area * cc;
      col_w[tri[k]] += area;
    }
  }
  if (mesh.faces.empty()) throw ParseError(where, "OBJ has only degenerate faces");
  // Drop vertices no face uses (welded duplicates of degenerate faces).
  {
    std::vector<int> keep(mesh.vertices.size(), -1);
    std::vector<Vec3> nv;
    std::vector<Vec3> ncs;
    std::vector<double> ncw;
    for (auto& f : mesh.faces) {
      for (int k = 0; k < 3; ++k) {
        if (keep[f[k]] < 0) {
          keep[f[k]] = static_cast<int>(nv.size());
          nv.push_back(mesh.vertices[f[k]]);
          ncs.push_back(col_sum[f[k]]);
          ncw.push_back(col_w[f[k]]);
        }
        f[k] = keep[f[k]];
      }
    }
    mesh.vertices = std::move(nv);
    col_sum = std::move(ncs);
    col_w = std::move(ncw);
  }
  // Re-normalise (dropped faces may have held the extremes).
  geometry::AABB b2 = mesh.Bounds();
  const Vec3 e2 = b2.Extent();
  if (!(e2.minCoeff() > 0))
    throw ParseError(where, "model is flat after removing degenerate faces");
  for (Vec3& p : mesh.vertices) p = (p - b2.min).cwiseQuotient(e2) - Vec3::Constant(0.5);
  mesh.vertex_colors.resize(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3 c = col_w[i] > 0 ? Vec3(col_sum[i] / col_w[i]) : Vec3::Constant(0.8);
    for (int k = 0; k < 3; ++k)
      mesh.vertex_colors[i][k] =
          static_cast<std::uint8_t>(std::clamp(std::lround(c[k] * 255.0), 0L, 255L));
  }
  // Boundary edges (a watertightness indicator).
  {
    std::unordered_map<std::uint64_t, int> edges;
    for (const auto& f : mesh.faces) {
      for (int k = 0; k < 3; ++k) {
        std::uint64_t a = static_cast<std::uint32_t>(f[k]),
                      bb = static_cast<std::uint32_t>(f[(k + 1) % 3]);
        if (a > bb) std::swap(a, bb);
        ++edges[a << 32 | bb];
      }
    }
    for (const auto& [k, n] : edges) st.boundary_edges += n == 1;
  }
  m.cad_class = cls.cad_class;
  m.rfs_class = cls.rfs_class;
  m.distractor_kind = cls.distractor_kind;
  m.synset = cls.cad_class >= 0 ? labels::CadSynsets()[cls.cad_class] : "";
  m.model_id = Sh3dModelId(e);
  m.family = "sh3d_" + cls.label;
  m.nominal_size = Vec3(e.depth_cm, e.width_cm, e.height_cm) / 100.0;
  m.symmetric_about_z = false;
  m.seed = Fnv1a(m.model_id);
  if (stats_out) *stats_out = st;
  return m;
}

// =======================================================================================
// Watertightness.
// =======================================================================================
geometry::VoxelGrid ClosedOccupancy(const TriangleMesh& unit_mesh, int res, int close_cells) {
  if (res < 4 || res > 512) throw InvalidArgument("ClosedOccupancy: res must be in [4, 512]");
  if (close_cells < 0 || close_cells > res / 4)
    throw InvalidArgument("ClosedOccupancy: close_cells must be in [0, res / 4]");
  const int pad = close_cells + 1;
  geometry::VoxelGrid g;
  g.voxel_size = 1.0 / res;
  g.origin = Vec3::Constant(-0.5 - pad * g.voxel_size);
  g.dims = Vec3i::Constant(res + 2 * pad);
  const std::size_t total = static_cast<std::size_t>(g.dims.x()) * g.dims.y() * g.dims.z();
  g.occupied.assign(total, 0);
  geometry::VoxelizeSurface(unit_mesh, &g);
  const std::vector<std::uint8_t> surface = g.occupied;
  const int n = g.dims.x();
  auto dilate = [&](std::vector<std::uint8_t> src, int r) {
    // Separable box dilation (a cube of side 2r+1).
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<std::uint8_t> dst(total, 0);
      for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            if (!src[g.Index(i, j, k)]) continue;
            for (int d = -r; d <= r; ++d) {
              int c[3] = {i, j, k};
              c[axis] += d;
              if (c[axis] < 0 || c[axis] >= n) continue;
              dst[g.Index(c[0], c[1], c[2])] = 1;
            }
          }
      src.swap(dst);
    }
    return src;
  };
  const std::vector<std::uint8_t> wall = close_cells > 0 ? dilate(surface, close_cells) : surface;
  // Outside: flood fill from the border through non-wall cells (6-connected).
  std::vector<std::uint8_t> outside(total, 0);
  std::vector<std::size_t> stack;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        if (i == 0 || j == 0 || k == 0 || i == n - 1 || j == n - 1 || k == n - 1) {
          const std::size_t id = g.Index(i, j, k);
          if (!wall[id] && !outside[id]) {
            outside[id] = 1;
            stack.push_back(id);
          }
        }
      }
  while (!stack.empty()) {
    const std::size_t id = stack.back();
    stack.pop_back();
    const int i = static_cast<int>(id % n), j = static_cast<int>((id / n) % n),
              k = static_cast<int>(id / (static_cast<std::size_t>(n) * n));
    const int nb[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k},
                          {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
    for (const auto& c : nb) {
      if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] >= n || c[1] >= n || c[2] >= n) continue;
      const std::size_t q = g.Index(c[0], c[1], c[2]);
      if (!wall[q] && !outside[q]) {
        outside[q] = 1;
        stack.push_back(q);
      }
    }
  }
  const std::vector<std::uint8_t> out_grown =
      close_cells > 0 ? dilate(outside, close_cells) : outside;
  for (std::size_t id = 0; id < total; ++id) g.occupied[id] = surface[id] || !out_grown[id];
  return g;
}

TriangleMesh OccupancyToMesh(const geometry::VoxelGrid& g) {
  TriangleMesh out;
  std::unordered_map<std::uint64_t, int> corner;
  const int nx = g.dims.x(), ny = g.dims.y(), nz = g.dims.z();
  auto vid = [&](int i, int j, int k) {
    const std::uint64_t key = (static_cast<std::uint64_t>(i) * (ny + 1) + j) * (nz + 1) + k;
    auto it = corner.find(key);
    if (it != corner.end()) return it->second;
    const int id = static_cast<int>(out.vertices.size());
    out.vertices.push_back(g.origin + Vec3(i, j, k) * g.voxel_size);
    corner.emplace(key, id);
    return id;
  };
  auto occ = [&](int i, int j, int k) {
    if (i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz) return false;
    return g.At(i, j, k);
  };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        if (!g.At(i, j, k)) continue;
        for (int axis = 0; axis < 3; ++axis) {
          for (int side = 0; side < 2; ++side) {
            int c[3] = {i, j, k};
            c[axis] += side ? 1 : -1;
            if (occ(c[0], c[1], c[2])) continue;
            // Quad on the face of the cell at axis = side, wound so its normal points along
            // (side ? +axis : -axis).
            const int u = (axis + 1) % 3, w = (axis + 2) % 3;
            int q[4][3];
            for (int r = 0; r < 4; ++r) {
              q[r][0] = i;
              q[r][1] = j;
              q[r][2] = k;
              q[r][axis] += side;
            }
            // (0,0) (1,0) (1,1) (0,1) in the (u, w) plane: normal u x w = +axis.
            q[1][u] += 1;
            q[2][u] += 1;
            q[2][w] += 1;
            q[3][w] += 1;
            int id[4];
            for (int r = 0; r < 4; ++r) id[r] = vid(q[r][0], q[r][1], q[r][2]);
            if (side) {
              out.faces.emplace_back(id[0], id[1], id[2]);
              out.faces.emplace_back(id[0], id[2], id[3]);
            } else {
              out.faces.emplace_back(id[0], id[2], id[1]);
              out.faces.emplace_back(id[0], id[3], id[2]);
            }
          }
        }
      }
  return out;
}

// =======================================================================================
// Import.
// =======================================================================================
std::string DefaultSh3dFurnitureDir() { return "/usr/share/sweethome3d/furniture"; }

std::vector<std::string> ListSh3dCatalogs(const std::string& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& de : std::filesystem::directory_iterator(dir, ec)) {
    const std::string p = de.path().string();
    if (Lower(de.path().extension().string()) == ".sh3f") out.push_back(p);
  }
  std::sort(out.begin(), out.end());
  if (out.empty())
    throw InvalidArgument(dir +
                          ": no .sh3f furniture catalogues (install the Debian package "
                          "sweethome3d-furniture)");
  return out;
}

std::vector<ImportedModel> ImportSh3dCatalogs(const std::vector<std::string>& paths,
                                              const ImportOptions& opt,
                                              std::vector<std::string>* errors) {
  struct Job {
    const ZipArchive* zip;
    Sh3dEntry entry;
    Sh3dClass cls;
  };
  std::vector<std::unique_ptr<ZipArchive>> zips;
  std::vector<Job> jobs;
  for (const std::string& path : paths) {
    zips.push_back(std::make_unique<ZipArchive>(ZipArchive::Open(path)));
    const ZipArchive& z = *zips.back();
    const std::string prop_name = "PluginFurnitureCatalog.properties";
    const auto bytes = z.Read(prop_name);
    const auto props =
        ParseJavaProperties(std::string(bytes.begin(), bytes.end()), path + ":" + prop_name);
    const std::string stem = std::filesystem::path(path).stem().string();
    for (Sh3dEntry& e : ParseSh3dCatalog(props, stem, path + ":" + prop_name)) {
      Sh3dClass c = ClassifySh3dEntry(e.name, e.category);
      if (c.Skip()) continue;
      if (c.cad_class < 0 && !opt.include_distractors) continue;
      // Small boxes and jars are no floor clutter.
      if (c.label == "appliance_or_box" && e.height_cm < 25) continue;
      // Tall "table lamps" are floor lamps.
      if (c.label == "table_lamp" && e.height_cm > 120) {
        c = Sh3dClass{};
        c.distractor_kind = KindByName("floor_lamp");
        c.rfs_class = GetDistractorInfo(c.distractor_kind).rfs_class;
        c.label = "floor_lamp";
      }
      jobs.push_back({&z, std::move(e), c});
    }
  }
  std::vector<ImportedModel> out(jobs.size());
  std::vector<std::string> errs(jobs.size());
  std::vector<char> ok(jobs.size(), 0);
  ParallelFor(jobs.size(), 0, [&](std::size_t i) {
    const Job& j = jobs[i];
    ImportedModel& im = out[i];
    try {
      im.model = LoadSh3dModel(*j.zip, j.entry, j.cls, &im.stats);
    } catch (const Error& ex) {
      errs[i] = ex.what();
      return;
    }
    im.entry = j.entry;
    im.cls = j.cls;
    im.held_out = IsHeldOutModel(im.model.model_id);
    // Area-weighted linear mean colour.
    Vec3 sum = Vec3::Zero();
    double w = 0;
    const TriangleMesh& mesh = im.model.mesh;
    const Vec3 s = im.model.nominal_size;
    for (const auto& f : mesh.faces) {
      const Vec3 a = mesh.vertices[f[0]].cwiseProduct(s), b = mesh.vertices[f[1]].cwiseProduct(s),
                 c = mesh.vertices[f[2]].cwiseProduct(s);
      const double area = 0.5 * (b - a).cross(c - a).norm();
      for (int k = 0; k < 3; ++k)
        for (int ch = 0; ch < 3; ++ch)
          sum[ch] += area / 3 * SrgbToLinear(mesh.vertex_colors[f[k]][ch] / 255.0);
      w += area;
    }
    if (w > 0) im.mean_color = sum / w;
    if (opt.watertight_res > 0) {
      const int r = opt.watertight_res;
      geometry::VoxelGrid open;
      open.voxel_size = 1.0 / r;
      open.origin = Vec3::Constant(-0.5 - open.voxel_size);
      open.dims = Vec3i::Constant(r + 2);
      open.occupied.assign(static_cast<std::size_t>(r + 2) * (r + 2) * (r + 2), 0);
      geometry::VoxelizeFilled(mesh, &open);
      im.solid_fraction_open = static_cast<double>(open.Count()) / (1.0 * r * r * r);
      im.solid_fraction_closed =
          static_cast<double>(ClosedOccupancy(mesh, r, opt.close_cells).Count()) /
          (1.0 * r * r * r);
    }
    ok[i] = 1;
  });
  std::vector<ImportedModel> kept;
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (ok[i]) {
      kept.push_back(std::move(out[i]));
    } else if (errors) {
      errors->push_back(errs[i]);
    }
  }
  return kept;
}

}  // namespace dimr::data
