#include "dimr/pipeline/cloud_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::pipeline {
namespace {

std::string LowerExtension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}

// A bounded reader of PCD files (PCL's format, versions 0.6 / 0.7): header lines VERSION,
// FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS, DATA; bodies ascii, binary
// (interleaved records) and binary_compressed (LZF of the field-major block). Written here
// rather than taken from pcl::PCDReader because that reader crashes on malformed headers.
struct PcdField {
  std::string name;
  int size = 4;
  char type = 'F';
  int count = 1;
  std::size_t offset = 0;  // in a record (bytes)
};

double DecodeScalar(const std::uint8_t* p, const PcdField& f) {
  switch (f.type) {
    case 'F':
      if (f.size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      } else {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    case 'U':
      if (f.size == 1) return *p;
      if (f.size == 2) {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
      }
      if (f.size == 4) {
        std::uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
      {
        std::uint64_t v;
        std::memcpy(&v, p, 8);
        return static_cast<double>(v);
      }
    default:  // 'I'
      if (f.size == 1) return static_cast<std::int8_t>(*p);
      if (f.size == 2) {
        std::int16_t v;
        std::memcpy(&v, p, 2);
        return v;
      }
      if (f.size == 4) {
        std::int32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
      {
        std::int64_t v;
        std::memcpy(&v, p, 8);
        return static_cast<double>(v);
      }
  }
}

// LZF decompression (liblzf's format, as PCL writes it). Throws on corrupt input.
void LzfDecompress(const std::uint8_t* in, std::size_t n_in, std::uint8_t* out, std::size_t n_out,
                   const std::string& path) {
  std::size_t ip = 0, op = 0;
  while (ip < n_in) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {  // literal run of ctrl + 1 bytes
      const std::size_t len = ctrl + 1;
      if (ip + len > n_in || op + len > n_out) throw ParseError(path, "corrupt LZF data");
      std::memcpy(out + op, in + ip, len);
      ip += len;
      op += len;
    } else {  // back reference
      std::size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= n_in) throw ParseError(path, "corrupt LZF data");
        len += in[ip++];
      }
      len += 2;
      if (ip >= n_in) throw ParseError(path, "corrupt LZF data");
      const std::size_t back = ((ctrl & 0x1f) << 8) + in[ip++] + 1;
      if (back > op || op + len > n_out) throw ParseError(path, "corrupt LZF data");
      for (std::size_t k = 0; k < len; ++k, ++op) out[op] = out[op - back];
    }
  }
  if (op != n_out) throw ParseError(path, "LZF data decompresses to the wrong size");
}

geometry::PointCloud ReadPcd(const std::string& path) {
  const std::vector<std::uint8_t> bytes = geometry::detail::ReadFileBytes(path);
  std::size_t pos = 0;
  std::vector<PcdField> fields;
  std::vector<int> sizes, counts;
  std::vector<char> types;
  std::uint64_t width = 0, height = 1, points = 0;
  bool have_points = false;
  std::string data;
  int line_no = 0;
  while (data.empty()) {
    if (pos >= bytes.size()) throw ParseError(path, "header ends before DATA");
    std::size_t end = pos;
    while (end < bytes.size() && bytes[end] != '\n') ++end;
    std::string line(reinterpret_cast<const char*>(bytes.data()) + pos, end - pos);
    pos = std::min(bytes.size(), end + 1);
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (line.size() > 4096 || line_no > 64) throw ParseError(path, "not a PCD header");
    std::istringstream in(line);
    std::string key;
    in >> key;
    const std::string where = "header line " + std::to_string(line_no) + " (" + key + ")";
    auto numbers = [&](auto* v) {
      std::vector<std::int64_t> out;
      std::int64_t x;
      while (in >> x) out.push_back(x);
      if (!in.eof()) throw ParseError(path, where + ": not a number");
      *v = out;
    };
    if (key == "VERSION" || key == "VIEWPOINT") {
      continue;
    } else if (key == "FIELDS" || key == "COLUMNS") {
      std::string name;
      while (in >> name) fields.push_back({name});
    } else if (key == "SIZE" || key == "COUNT") {
      std::vector<std::int64_t> v;
      numbers(&v);
      for (auto x : v) {
        if (x < 1 || x > (key == "SIZE" ? 8 : 1 << 20))
          throw ParseError(path, where + ": out of range");
        (key == "SIZE" ? sizes : counts).push_back(static_cast<int>(x));
      }
    } else if (key == "TYPE") {
      std::string t;
      while (in >> t) {
        if (t.size() != 1 || (t[0] != 'F' && t[0] != 'U' && t[0] != 'I')) {
          throw ParseError(path, where + ": unknown type '" + t + "'");
        }
        types.push_back(t[0]);
      }
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      std::vector<std::int64_t> v;
      numbers(&v);
      if (v.size() != 1 || v[0] < 0) throw ParseError(path, where + ": expected one count");
      (key == "WIDTH"    ? width
       : key == "HEIGHT" ? height
                         : points) = static_cast<std::uint64_t>(v[0]);
      if (key == "POINTS") have_points = true;
    } else if (key == "DATA") {
      in >> data;
      if (data != "ascii" && data != "binary" && data != "binary_compressed") {
        throw ParseError(path, where + ": unknown DATA '" + data + "'");
      }
    } else {
      throw ParseError(path, where + ": unknown header key");
    }
  }
  if (fields.empty()) throw ParseError(path, "no FIELDS");
  if (sizes.size() != fields.size() || types.size() != fields.size()) {
    throw ParseError(path, "FIELDS, SIZE and TYPE disagree in length");
  }
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (counts.size() != fields.size()) throw ParseError(path, "FIELDS and COUNT disagree in length");
  std::size_t record = 0;
  for (std::size_t f = 0; f < fields.size(); ++f) {
    fields[f].size = sizes[f];
    fields[f].type = types[f];
    fields[f].count = counts[f];
    if (types[f] == 'F' && sizes[f] != 4 && sizes[f] != 8) {
      throw ParseError(path,
                       "field '" + fields[f].name + "': float of size " + std::to_string(sizes[f]));
    }
    if (sizes[f] != 1 && sizes[f] != 2 && sizes[f] != 4 && sizes[f] != 8) {
      throw ParseError(path, "field '" + fields[f].name + "': size " + std::to_string(sizes[f]));
    }
    fields[f].offset = record;
    record += static_cast<std::size_t>(sizes[f]) * static_cast<std::size_t>(counts[f]);
  }
  if (!have_points) points = width * height;
  if (width * height != points) throw ParseError(path, "POINTS is not WIDTH x HEIGHT");
  const std::size_t remaining = bytes.size() - pos;
  // Every point needs at least 2 bytes in ascii ("0\n") and `record` bytes in binary.
  if (points > remaining / 2 + 1 && data == "ascii") {
    throw ParseError(path,
                     "claims " + std::to_string(points) + " points, more than the file holds");
  }
  auto index = [&](const char* name) -> int {
    for (std::size_t f = 0; f < fields.size(); ++f) {
      if (fields[f].name == name) return static_cast<int>(f);
    }
    return -1;
  };
  const int ix = index("x"), iy = index("y"), iz = index("z");
  if (ix < 0 || iy < 0 || iz < 0) throw ParseError(path, "no x, y, z fields");
  int irgb = index("rgb");
  if (irgb < 0) irgb = index("rgba");
  if (irgb >= 0 && fields[irgb].size != 4) irgb = -1;
  const int inx = index("normal_x"), iny = index("normal_y"), inz = index("normal_z");
  const bool normals = inx >= 0 && iny >= 0 && inz >= 0;
  const std::size_t n = static_cast<std::size_t>(points);
  geometry::PointCloud out;
  // Records in one interleaved block (ascii: parsed values as doubles; binary: raw bytes).
  std::vector<std::uint8_t> block;
  if (data == "binary") {
    if (record == 0 || n > remaining / record) {
      throw ParseError(path, "binary body shorter than POINTS x record size");
    }
    block.assign(bytes.begin() + static_cast<std::ptrdiff_t>(pos),
                 bytes.begin() + static_cast<std::ptrdiff_t>(pos + n * record));
  } else if (data == "binary_compressed") {
    if (remaining < 8) throw ParseError(path, "binary_compressed body without sizes");
    std::uint32_t csize, usize;
    std::memcpy(&csize, bytes.data() + pos, 4);
    std::memcpy(&usize, bytes.data() + pos + 4, 4);
    if (csize > remaining - 8) throw ParseError(path, "compressed size beyond the file");
    if (record == 0 || usize != n * record) {
      throw ParseError(path, "uncompressed size is not POINTS x record size");
    }
    std::vector<std::uint8_t> fieldmajor(usize);
    LzfDecompress(bytes.data() + pos + 8, csize, fieldmajor.data(), usize, path);
    // Field-major (all x, then all y, ...) to interleaved records.
    block.resize(usize);
    std::size_t src = 0;
    for (const auto& f : fields) {
      const std::size_t fb = static_cast<std::size_t>(f.size) * f.count;
      for (std::size_t i = 0; i < n; ++i, src += fb) {
        std::memcpy(block.data() + i * record + f.offset, fieldmajor.data() + src, fb);
      }
    }
  }
  out.points.resize(n);
  if (irgb >= 0) out.colors.resize(n);
  if (normals) out.normals.resize(n);
  if (data == "ascii") {
    const char* p = reinterpret_cast<const char*>(bytes.data()) + pos;
    const char* e = reinterpret_cast<const char*>(bytes.data()) + bytes.size();
    std::vector<double> vals(record);  // upper bound on values per record
    std::size_t per = 0;
    for (const auto& f : fields) per += static_cast<std::size_t>(f.count);
    vals.resize(per);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t v = 0; v < per; ++v) {
        while (p < e && std::isspace(static_cast<unsigned char>(*p))) ++p;
        if (p >= e) throw ParseError(path, "ascii body ends at point " + std::to_string(i));
        char* q = nullptr;
        vals[v] = std::strtod(p, &q);
        if (q == p) throw ParseError(path, "ascii point " + std::to_string(i) + ": not a number");
        p = q;
      }
      std::size_t col = 0;
      std::vector<double> first(fields.size());
      for (std::size_t f = 0; f < fields.size(); ++f) {
        first[f] = vals[col];
        col += static_cast<std::size_t>(fields[f].count);
      }
      out.points[i] = geometry::Vec3(first[ix], first[iy], first[iz]);
      if (irgb >= 0) {
        std::uint32_t c;
        if (fields[irgb].type == 'F') {
          const float fv = static_cast<float>(first[irgb]);
          std::memcpy(&c, &fv, 4);
        } else {
          c = static_cast<std::uint32_t>(first[irgb]);
        }
        out.colors[i] = geometry::Color((c >> 16) & 255, (c >> 8) & 255, c & 255);
      }
      if (normals) out.normals[i] = geometry::Vec3(first[inx], first[iny], first[inz]);
    }
    return out;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* r = block.data() + i * record;
    out.points[i] = geometry::Vec3(DecodeScalar(r + fields[ix].offset, fields[ix]),
                                   DecodeScalar(r + fields[iy].offset, fields[iy]),
                                   DecodeScalar(r + fields[iz].offset, fields[iz]));
    if (irgb >= 0) {
      std::uint32_t c;
      std::memcpy(&c, r + fields[irgb].offset, 4);
      out.colors[i] = geometry::Color((c >> 16) & 255, (c >> 8) & 255, c & 255);
    }
    if (normals) {
      out.normals[i] = geometry::Vec3(DecodeScalar(r + fields[inx].offset, fields[inx]),
                                      DecodeScalar(r + fields[iny].offset, fields[iny]),
                                      DecodeScalar(r + fields[inz].offset, fields[inz]));
    }
  }
  return out;
}

}  // namespace

geometry::PointCloud ReadPointCloudFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw ParseError(path, "no such file");
  const std::string ext = LowerExtension(path);
  if (ext == ".ply") return geometry::ReadPlyCloud(path);
  if (ext == ".pcd") return ReadPcd(path);
  throw ParseError(path, "unsupported point cloud format '" + ext + "' (.ply or .pcd)");
}

std::size_t DropNonFinitePoints(geometry::PointCloud* cloud) {
  const std::size_t n = cloud->points.size();
  auto check = [n](std::size_t got, const std::string& what) {
    if (got != 0 && got != n) {
      throw InvalidArgument("DropNonFinitePoints: " + std::to_string(got) + " " + what + " for " +
                            std::to_string(n) + " points");
    }
  };
  check(cloud->colors.size(), "colours");
  check(cloud->normals.size(), "normals");
  for (const auto& a : cloud->attributes) check(a.values.size(), "values of '" + a.name + "'");
  std::size_t w = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!cloud->points[i].allFinite()) continue;
    if (w != i) {
      cloud->points[w] = cloud->points[i];
      if (!cloud->colors.empty()) cloud->colors[w] = cloud->colors[i];
      if (!cloud->normals.empty()) cloud->normals[w] = cloud->normals[i];
      for (auto& a : cloud->attributes) {
        if (!a.values.empty()) a.values[w] = a.values[i];
      }
    }
    ++w;
  }
  cloud->points.resize(w);
  if (!cloud->colors.empty()) cloud->colors.resize(w);
  if (!cloud->normals.empty()) cloud->normals.resize(w);
  for (auto& a : cloud->attributes) {
    if (!a.values.empty()) a.values.resize(w);
  }
  return n - w;
}

}  // namespace dimr::pipeline
