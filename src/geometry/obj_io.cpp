// Wavefront OBJ reader/writer and the extension-dispatching ReadMesh/WriteMesh.
#include "dimr/geometry/obj_io.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::geometry {
namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// Statements of the OBJ specification that this reader does not need (everything except
// v, vt, vn, f). Other purely alphabetic keywords are ignored too; anything else (binary
// bytes, punctuation) is an error.
bool IsIdentifier(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  }
  return std::isalpha(static_cast<unsigned char>(s[0])) != 0;
}

class ObjParser {
 public:
  ObjParser(const std::uint8_t* data, std::size_t size, const std::string& source)
      : text_(reinterpret_cast<const char*>(data), size), source_(source) {}

  TriangleMesh Parse() {
    if (text_.empty()) throw ParseError(source_, "empty file");
    std::size_t pos = 0;
    while (pos < text_.size()) {
      std::size_t nl = text_.find('\n', pos);
      if (nl == std::string_view::npos) nl = text_.size();
      std::string_view line = text_.substr(pos, nl - pos);
      pos = nl + 1;
      ++line_no_;
      const std::size_t hash = line.find('#');
      if (hash != std::string_view::npos) line = line.substr(0, hash);
      ParseLine(line);
    }
    return std::move(mesh_);
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    throw ParseError(source_ + ":" + std::to_string(line_no_), what);
  }

  void Split(std::string_view line) {
    words_.clear();
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && IsBlank(line[i])) ++i;
      const std::size_t start = i;
      while (i < line.size() && !IsBlank(line[i])) ++i;
      if (i > start) words_.push_back(line.substr(start, i - start));
    }
  }

  double Number(std::string_view tok) const {
    if (tok.size() > 1 && tok[0] == '+') tok.remove_prefix(1);
    double v = 0;
    const char* b = tok.data();
    const char* e = b + tok.size();
    const auto r = std::from_chars(b, e, v);
    if (r.ptr != e || (r.ec != std::errc() && r.ec != std::errc::result_out_of_range)) {
      Fail("'" + detail::Printable(tok) + "' is not a number");
    }
    if (r.ec == std::errc::result_out_of_range)
      Fail("number '" + detail::Printable(tok) + "' out of range");
    return v;
  }

  void ParseLine(std::string_view line) {
    if (line.find('\0') != std::string_view::npos) Fail("binary data (NUL byte) in OBJ text");
    Split(line);
    if (words_.empty()) return;
    const std::string_view key = words_[0];
    if (key == "v") {
      if (words_.size() < 4)
        Fail("vertex needs 3 coordinates, got " + std::to_string(words_.size() - 1));
      Vec3 p;
      for (int k = 0; k < 3; ++k) p[k] = Number(words_[1 + k]);
      // Trailing values (w, or r g b colours) are checked and ignored.
      for (std::size_t k = 4; k < words_.size(); ++k) Number(words_[k]);
      if (!p.allFinite()) {
        char buf[128];
        std::snprintf(buf, sizeof(buf), "vertex %zu: non-finite coordinate (%g, %g, %g)",
                      mesh_.vertices.size() + 1, p.x(), p.y(), p.z());
        Fail(buf);
      }
      mesh_.vertices.push_back(p);
    } else if (key == "vn" || key == "vt") {
      const std::size_t need = key == "vn" ? 3 : 1;
      if (words_.size() < need + 1) {
        Fail(std::string(key) + " needs " + std::to_string(need) + " values, got " +
             std::to_string(words_.size() - 1));
      }
      for (std::size_t k = 1; k < words_.size(); ++k) Number(words_[k]);
      (key == "vn" ? num_normals_ : num_texcoords_)++;
    } else if (key == "f") {
      ParseFace();
    } else if (!IsIdentifier(key)) {
      Fail("unknown statement '" + detail::Printable(key) + "'");
    }
    // o, g, s, usemtl, mtllib, l, p, ... : ignored.
  }

  // Resolves a 1-based or negative (relative) index against `count` defined items.
  long Index(std::string_view tok, std::size_t count, const char* what) const {
    long long v = 0;
    const char* b = tok.data();
    const char* e = b + tok.size();
    const auto r = std::from_chars(b, e, v);
    if (r.ec != std::errc() || r.ptr != e)
      Fail(std::string("invalid ") + what + " index '" + detail::Printable(tok) + "'");
    const long long n = static_cast<long long>(count);
    long long idx = -1;
    if (v > 0 && v <= n) idx = v - 1;
    if (v < 0 && v >= -n) idx = n + v;
    if (idx < 0) {
      Fail(std::string(what) + " index " + std::to_string(v) + " out of range (" +
           std::to_string(n) + " " +
           (std::string(what) == "face" ? "vertices" : std::string(what) + "s") + ")");
    }
    return static_cast<long>(idx);
  }

  void ParseFace() {
    const std::size_t n = words_.size() - 1;
    if (n < 3) Fail("face with " + std::to_string(n) + " vertices (a face needs at least 3)");
    corners_.clear();
    for (std::size_t k = 1; k < words_.size(); ++k) {
      std::string_view tok = words_[k];
      const std::size_t s1 = tok.find('/');
      const std::string_view vpart = tok.substr(0, s1);
      corners_.push_back(static_cast<int>(Index(vpart, mesh_.vertices.size(), "face")));
      if (s1 == std::string_view::npos) continue;
      std::string_view rest = tok.substr(s1 + 1);
      const std::size_t s2 = rest.find('/');
      const std::string_view tpart = rest.substr(0, s2);
      if (!tpart.empty()) Index(tpart, num_texcoords_, "texture coordinate");
      if (s2 == std::string_view::npos) continue;
      const std::string_view npart = rest.substr(s2 + 1);
      if (npart.empty() && tpart.empty())
        Fail("invalid face vertex '" + detail::Printable(tok) + "'");
      if (!npart.empty()) Index(npart, num_normals_, "normal");
    }
    for (std::size_t k = 1; k + 1 < corners_.size(); ++k) {
      mesh_.faces.emplace_back(corners_[0], corners_[k], corners_[k + 1]);
    }
  }

  std::string_view text_;
  const std::string& source_;
  TriangleMesh mesh_;
  std::vector<std::string_view> words_;
  std::vector<int> corners_;
  std::size_t num_normals_ = 0;
  std::size_t num_texcoords_ = 0;
  std::size_t line_no_ = 0;
};

}  // namespace

TriangleMesh ParseObj(const std::uint8_t* data, std::size_t size, const std::string& source) {
  return ObjParser(data, size, source).Parse();
}

TriangleMesh ReadObj(const std::string& path) {
  const auto bytes = detail::ReadFileBytes(path);
  return ParseObj(bytes.data(), bytes.size(), path);
}

void WriteObj(const std::string& path, const TriangleMesh& mesh, int precision) {
  if (precision < 0 || precision > 17) {
    throw InvalidArgument("WriteObj " + path + ": precision " + std::to_string(precision) +
                          " outside 0..17");
  }
  mesh.Validate(path);
  std::string out = "# written by dimr\n";
  out.reserve(out.size() + mesh.vertices.size() * (3 * (precision + 6) + 4) +
              mesh.faces.size() * 24);
  char buf[400];
  for (const Vec3& v : mesh.vertices) {
    out += 'v';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      const auto r =
          std::to_chars(buf, buf + sizeof(buf), v[k], std::chars_format::fixed, precision);
      out.append(buf, r.ptr);
    }
    out += '\n';
  }
  for (const Vec3i& f : mesh.faces) {
    out += 'f';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      const auto r = std::to_chars(buf, buf + sizeof(buf), f[k] + 1);
      out.append(buf, r.ptr);
    }
    out += '\n';
  }
  detail::WriteFileBytes(path, out);
}

std::string LowerExtension(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

TriangleMesh ReadMesh(const std::string& path) {
  const std::string ext = LowerExtension(path);
  if (ext == ".ply") return ReadPlyMesh(path);
  if (ext == ".obj") return ReadObj(path);
  throw ParseError(path, "unsupported mesh format '" + ext + "' (expected .ply or .obj)");
}

void WriteMesh(const std::string& path, const TriangleMesh& mesh) {
  const std::string ext = LowerExtension(path);
  if (ext == ".ply") {
    WritePly(path, mesh);
  } else if (ext == ".obj") {
    WriteObj(path, mesh);
  } else {
    throw InvalidArgument("cannot write '" + path + "': unsupported mesh format '" + ext +
                          "' (expected .ply or .obj)");
  }
}

}  // namespace dimr::geometry
