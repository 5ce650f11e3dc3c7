// PLY reader/writer. The file is read with one bulk read; the header is parsed into
// elements/properties, every property gets a role (x, nx, red, attribute, face list,
// skip), and the body is decoded by one generic loop templated on the source (ascii
// tokens or binary with/without byte swapping). Claimed counts are checked against the
// remaining bytes before anything is reserved.
#include "dimr/geometry/ply_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "dimr/geometry/error.h"

namespace dimr::geometry {

// ---------------------------------------------------------------------------
// File helpers.
// ---------------------------------------------------------------------------
namespace detail {

std::string Printable(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 32 && u < 127) {
      out += c;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", u);
      out += buf;
    }
  }
  if (s.size() > 40) out += "...";
  return out;
}

std::vector<std::uint8_t> ReadFileBytes(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw ParseError(path, std::string("cannot open file: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw ParseError(path, "not a regular file");
  }
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(st.st_size));
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      throw ParseError(path, n == 0 ? std::string("file shrank while reading")
                                    : std::string("read failed: ") + std::strerror(err));
    }
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  return bytes;
}

void WriteFileBytes(const std::string& path, std::string_view bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw Error("cannot open '" + path + "' for writing: " + std::strerror(errno));
  const std::size_t n = bytes.empty() ? 0 : std::fwrite(bytes.data(), 1, bytes.size(), f);
  const bool ok = n == bytes.size() && std::fflush(f) == 0;
  const int err = errno;
  if (std::fclose(f) != 0 || !ok) {
    throw Error("cannot write '" + path + "': " + std::strerror(ok ? errno : err));
  }
}

}  // namespace detail

const char* PlyFormatName(PlyFormat format) {
  switch (format) {
    case PlyFormat::kAscii:
      return "ascii";
    case PlyFormat::kBinaryLittleEndian:
      return "binary_little_endian";
    case PlyFormat::kBinaryBigEndian:
      return "binary_big_endian";
  }
  return "?";
}

namespace {

constexpr bool kHostLittleEndian = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;

bool IsIntegerType(ScalarType t) { return t != ScalarType::kFloat32 && t != ScalarType::kFloat64; }

// Range of the values a scalar type can hold (floats: finite range).
void TypeRange(ScalarType t, double* lo, double* hi) {
  switch (t) {
    case ScalarType::kInt8:
      *lo = -128, *hi = 127;
      return;
    case ScalarType::kUInt8:
      *lo = 0, *hi = 255;
      return;
    case ScalarType::kInt16:
      *lo = -32768, *hi = 32767;
      return;
    case ScalarType::kUInt16:
      *lo = 0, *hi = 65535;
      return;
    case ScalarType::kInt32:
      *lo = -2147483648.0, *hi = 2147483647.0;
      return;
    case ScalarType::kUInt32:
      *lo = 0, *hi = 4294967295.0;
      return;
    case ScalarType::kFloat32:
      *lo = -std::numeric_limits<float>::max(), *hi = std::numeric_limits<float>::max();
      return;
    case ScalarType::kFloat64:
      *lo = -std::numeric_limits<double>::max(), *hi = std::numeric_limits<double>::max();
      return;
  }
}

bool ParseTypeName(std::string_view s, ScalarType* t) {
  static const std::pair<const char*, ScalarType> kNames[] = {
      {"char", ScalarType::kInt8},      {"int8", ScalarType::kInt8},
      {"uchar", ScalarType::kUInt8},    {"uint8", ScalarType::kUInt8},
      {"short", ScalarType::kInt16},    {"int16", ScalarType::kInt16},
      {"ushort", ScalarType::kUInt16},  {"uint16", ScalarType::kUInt16},
      {"int", ScalarType::kInt32},      {"int32", ScalarType::kInt32},
      {"uint", ScalarType::kUInt32},    {"uint32", ScalarType::kUInt32},
      {"float", ScalarType::kFloat32},  {"float32", ScalarType::kFloat32},
      {"double", ScalarType::kFloat64}, {"float64", ScalarType::kFloat64}};
  for (const auto& [name, type] : kNames) {
    if (s == name) {
      *t = type;
      return true;
    }
  }
  return false;
}

// ---------------------------------------------------------------------------
// Header.
// ---------------------------------------------------------------------------
enum class Role : std::uint8_t {
  kSkip,
  kX,
  kY,
  kZ,
  kNx,
  kNy,
  kNz,
  kRed,
  kGreen,
  kBlue,
  kAttribute,
  kFaceList,
};

struct Property {
  std::string name;
  ScalarType type = ScalarType::kFloat32;  // value type; item type of a list
  bool is_list = false;
  ScalarType count_type = ScalarType::kUInt8;
  Role role = Role::kSkip;
  int attribute = -1;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> props;
};

struct Header {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<Element> elements;
  std::vector<std::string> comments;
  std::size_t body_offset = 0;
};

std::vector<std::string_view> SplitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

Header ParseHeader(const std::uint8_t* data, std::size_t size, const std::string& source) {
  if (size == 0) throw ParseError(source, "empty file");
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  Header h;
  bool have_format = false;
  std::size_t pos = 0;
  int line_no = 0;
  std::set<std::string, std::less<>> element_names;
  std::set<std::string, std::less<>> property_names;  // of the current element
  auto fail = [&](const std::string& what) {
    throw ParseError(source + ":" + std::to_string(line_no), what);
  };
  while (true) {
    if (pos >= text.size()) {
      if (line_no == 0) throw ParseError(source, "empty file");
      throw ParseError(source, "truncated header: no 'end_header' line");
    }
    const std::size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) {
      throw ParseError(source, "truncated header: no 'end_header' line");
    }
    std::string_view line = text.substr(pos, nl - pos);
    pos = nl + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line_no == 1) {
      if (line != "ply") throw ParseError(source, "not a PLY file (first line is not 'ply')");
      continue;
    }
    const auto words = SplitWords(line);
    if (words.empty()) continue;
    const std::string_view key = words[0];
    if (key == "comment" || key == "obj_info") {
      const std::size_t at = line.find(key) + key.size();
      std::string_view rest = line.substr(at);
      while (!rest.empty() && (rest.front() == ' ' || rest.front() == '\t')) rest.remove_prefix(1);
      h.comments.emplace_back(rest);
    } else if (key == "format") {
      if (have_format) fail("duplicate 'format' line");
      if (words.size() != 3) fail("malformed 'format' line");
      if (words[1] == "ascii") {
        h.format = PlyFormat::kAscii;
      } else if (words[1] == "binary_little_endian") {
        h.format = PlyFormat::kBinaryLittleEndian;
      } else if (words[1] == "binary_big_endian") {
        h.format = PlyFormat::kBinaryBigEndian;
      } else {
        fail("unknown format '" + detail::Printable(words[1]) + "'");
      }
      if (words[2] != "1.0" && words[2] != "1") {
        fail("unsupported PLY version '" + detail::Printable(words[2]) + "'");
      }
      have_format = true;
    } else if (key == "element") {
      if (words.size() != 3) fail("malformed 'element' line");
      std::uint64_t count = 0;
      const char* b = words[2].data();
      const char* e = b + words[2].size();
      const auto r = std::from_chars(b, e, count);
      if (r.ec != std::errc() || r.ptr != e) {
        fail("element '" + detail::Printable(words[1]) + "': invalid count '" +
             detail::Printable(words[2]) + "'");
      }
      if (!element_names.emplace(words[1]).second) {
        fail("duplicate element '" + detail::Printable(words[1]) + "'");
      }
      property_names.clear();
      h.elements.push_back(Element{std::string(words[1]), count, {}});
    } else if (key == "property") {
      if (h.elements.empty()) fail("property before any element");
      Element& el = h.elements.back();
      Property p;
      if (words.size() >= 2 && words[1] == "list") {
        if (words.size() != 5) fail("malformed list property line");
        if (!ParseTypeName(words[2], &p.count_type)) {
          fail("unknown property type '" + detail::Printable(words[2]) + "'");
        }
        if (!ParseTypeName(words[3], &p.type)) {
          fail("unknown property type '" + detail::Printable(words[3]) + "'");
        }
        if (!IsIntegerType(p.count_type)) {
          fail("list '" + detail::Printable(words[4]) + "': count type " +
               ScalarName(p.count_type) + " is not an integer type");
        }
        p.is_list = true;
        p.name = std::string(words[4]);
      } else {
        if (words.size() != 3) fail("malformed property line");
        if (!ParseTypeName(words[1], &p.type)) {
          fail("unknown property type '" + detail::Printable(words[1]) + "'");
        }
        p.name = std::string(words[2]);
      }
      if (!property_names.insert(p.name).second) {
        fail("element '" + detail::Printable(el.name) + "': duplicate property '" +
             detail::Printable(p.name) + "'");
      }
      el.props.push_back(std::move(p));
    } else if (key == "end_header") {
      if (words.size() != 1) fail("malformed 'end_header' line");
      break;
    } else {
      fail("unknown header keyword '" + detail::Printable(key) + "'");
    }
  }
  if (!have_format) throw ParseError(source, "header has no 'format' line");
  h.body_offset = pos;
  return h;
}

// ---------------------------------------------------------------------------
// Body sources.
// ---------------------------------------------------------------------------
enum class Status { kOk, kEof, kBadNumber, kOutOfRange };

template <typename T>
T Load(const std::uint8_t* p, bool swap) {
  T v;
  if (!swap) {
    std::memcpy(&v, p, sizeof(T));
  } else {
    std::uint8_t b[sizeof(T)];
    for (std::size_t i = 0; i < sizeof(T); ++i) b[i] = p[sizeof(T) - 1 - i];
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

class BinarySource {
 public:
  BinarySource(const std::uint8_t* begin, const std::uint8_t* end, bool swap)
      : p_(begin), end_(end), swap_(swap) {}

  Status Read(ScalarType t, double* v) {
    const std::size_t n = static_cast<std::size_t>(ScalarSize(t));
    if (static_cast<std::size_t>(end_ - p_) < n) return Status::kEof;
    switch (t) {
      case ScalarType::kInt8:
        *v = static_cast<std::int8_t>(*p_);
        break;
      case ScalarType::kUInt8:
        *v = *p_;
        break;
      case ScalarType::kInt16:
        *v = Load<std::int16_t>(p_, swap_);
        break;
      case ScalarType::kUInt16:
        *v = Load<std::uint16_t>(p_, swap_);
        break;
      case ScalarType::kInt32:
        *v = Load<std::int32_t>(p_, swap_);
        break;
      case ScalarType::kUInt32:
        *v = Load<std::uint32_t>(p_, swap_);
        break;
      case ScalarType::kFloat32:
        *v = Load<float>(p_, swap_);
        break;
      case ScalarType::kFloat64:
        *v = Load<double>(p_, swap_);
        break;
    }
    p_ += n;
    return Status::kOk;
  }
  // Skips `n` items of `item_size` bytes; false (nothing consumed) if they are not there.
  bool Skip(std::uint64_t n, std::size_t item_size) {
    if (n > Remaining() / item_size) return false;
    p_ += n * item_size;
    return true;
  }
  std::size_t Remaining() const { return static_cast<std::size_t>(end_ - p_); }
  std::string Location(const std::string& source) const { return source; }
  std::string_view LastToken() const { return {}; }

 private:
  const std::uint8_t* p_;
  const std::uint8_t* end_;
  bool swap_;
};

bool IsSpace(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

class AsciiSource {
 public:
  AsciiSource(const char* file_begin, const char* begin, const char* end)
      : file_begin_(file_begin), p_(begin), end_(end) {}

  Status Read(ScalarType t, double* v) {
    if (!NextToken()) return Status::kEof;
    std::string_view tok = token_;
    if (tok.size() > 1 && tok[0] == '+') tok.remove_prefix(1);
    const char* b = tok.data();
    const char* e = b + tok.size();
    if (IsIntegerType(t)) {
      std::int64_t i = 0;
      const auto r = std::from_chars(b, e, i);
      if (r.ec == std::errc() && r.ptr == e) {
        *v = static_cast<double>(i);
      } else if (r.ec == std::errc::result_out_of_range) {
        return Status::kOutOfRange;
      } else {
        // Some writers print integers as "3.0": accept integral values.
        double d = 0;
        const auto rd = std::from_chars(b, e, d);
        if (rd.ec != std::errc() || rd.ptr != e || !std::isfinite(d) || d != std::floor(d)) {
          return Status::kBadNumber;
        }
        *v = d;
      }
      double lo = 0, hi = 0;
      TypeRange(t, &lo, &hi);
      if (*v < lo || *v > hi) return Status::kOutOfRange;
      return Status::kOk;
    }
    double d = 0;
    const auto r = std::from_chars(b, e, d);
    if (r.ec == std::errc::result_out_of_range && r.ptr == e) return Status::kOutOfRange;
    if (r.ec != std::errc() || r.ptr != e) return Status::kBadNumber;
    if (t == ScalarType::kFloat32) {
      if (std::isfinite(d) && std::fabs(d) > std::numeric_limits<float>::max()) {
        return Status::kOutOfRange;
      }
      d = static_cast<double>(static_cast<float>(d));
    }
    *v = d;
    return Status::kOk;
  }

  std::size_t Remaining() const { return static_cast<std::size_t>(end_ - p_); }
  std::string_view LastToken() const { return token_; }
  std::string Location(const std::string& source) const {
    const char* at = token_.empty() ? p_ : token_.data();
    const long line = 1 + std::count(file_begin_, at, '\n');
    return source + ":" + std::to_string(line);
  }

 private:
  bool NextToken() {
    while (p_ < end_ && IsSpace(*p_)) ++p_;
    if (p_ == end_) {
      token_ = {};
      return false;
    }
    const char* start = p_;
    while (p_ < end_ && !IsSpace(*p_)) ++p_;
    token_ = std::string_view(start, static_cast<std::size_t>(p_ - start));
    return true;
  }

  const char* file_begin_;
  const char* p_;
  const char* end_;
  std::string_view token_;
};

// ---------------------------------------------------------------------------
// Body decoding.
// ---------------------------------------------------------------------------
struct PlyData {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;
  std::vector<Color> colors;
  std::vector<VertexAttribute> attributes;
  std::vector<Vec3i> faces;
};

std::uint8_t ColorByte(ScalarType t, double v) {
  if (std::isnan(v)) return 0;
  if (!IsIntegerType(t)) v = std::round(v * 255.0);
  return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
}

class BodyReader {
 public:
  BodyReader(const std::string& source, bool want_faces)
      : source_(source), want_faces_(want_faces) {}

  // Assigns roles to the properties of the vertex and face elements.
  void Prepare(Header* h, PlyData* out) {
    std::uint64_t vertex_count = 0;
    for (Element& el : h->elements) {
      if (el.name == "vertex") {
        vertex_count = el.count;
        PrepareVertex(&el, out);
      }
    }
    vertex_count_ = vertex_count;
    for (Element& el : h->elements) {
      if (el.name != "face" || !want_faces_) continue;
      bool found = false;
      for (Property& p : el.props) {
        if (p.name != "vertex_indices" && p.name != "vertex_index") continue;
        if (!p.is_list) {
          throw ParseError(source_, "face property '" + p.name + "' is not a list");
        }
        if (!IsIntegerType(p.type)) {
          throw ParseError(source_, "face list '" + p.name + "' has non-integer index type " +
                                        ScalarName(p.type));
        }
        if (found) throw ParseError(source_, "face element has two vertex index lists");
        p.role = Role::kFaceList;
        found = true;
      }
      if (!found && el.count > 0) {
        throw ParseError(source_, "face element has no 'vertex_indices' list");
      }
    }
  }

  template <typename Source>
  void ReadElements(const Header& h, Source& src, bool binary, PlyData* out) {
    for (const Element& el : h.elements) {
      if (el.props.empty() || el.count == 0) continue;
      // Minimal bytes per record: binary = fixed sizes (+ list counts with no items);
      // ascii = one character and one separator per value.
      std::size_t min_record = 0;
      for (const Property& p : el.props) {
        // A face list needs at least 3 indices (anything shorter is an error).
        const std::size_t items = p.role == Role::kFaceList && want_faces_ ? 3 : 0;
        min_record +=
            binary ? static_cast<std::size_t>(ScalarSize(p.is_list ? p.count_type : p.type)) +
                         items * static_cast<std::size_t>(ScalarSize(p.type))
                   : 2 * (1 + items);
      }
      const std::size_t budget = binary ? src.Remaining() : src.Remaining() + 1;
      if (el.count > budget / min_record) {
        throw ParseError(source_, "element '" + detail::Printable(el.name) + "' claims " +
                                      std::to_string(el.count) + " records (at least " +
                                      std::to_string(min_record) + " bytes each) but only " +
                                      std::to_string(src.Remaining()) + " bytes remain");
      }
      const bool is_vertex = el.name == "vertex";
      const bool is_face = el.name == "face" && want_faces_;
      if (binary && is_vertex) {
        const std::size_t n = static_cast<std::size_t>(el.count);
        out->points.reserve(n);
        if (has_normals_) out->normals.reserve(n);
        if (has_colors_) out->colors.reserve(n);
        for (auto& a : out->attributes) a.values.reserve(n);
      }
      if (binary && is_face) out->faces.reserve(static_cast<std::size_t>(el.count));
      if (is_vertex) {
        ReadVertices(el, src, out);
      } else {
        ReadGeneric(el, src, is_face, out);
      }
    }
  }

 private:
  void PrepareVertex(Element* el, PlyData* out) {
    auto find = [&](const char* name) -> Property* {
      for (Property& p : el->props) {
        if (p.name == name && !p.is_list) return &p;
      }
      return nullptr;
    };
    const char* xyz[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      Property* p = find(xyz[k]);
      if (!p)
        throw ParseError(source_, std::string("vertex element has no property '") + xyz[k] + "'");
      p->role = static_cast<Role>(static_cast<int>(Role::kX) + k);
    }
    Property* n[3] = {find("nx"), find("ny"), find("nz")};
    if (n[0] && n[1] && n[2]) {
      has_normals_ = true;
      for (int k = 0; k < 3; ++k) n[k]->role = static_cast<Role>(static_cast<int>(Role::kNx) + k);
    }
    Property* c[3] = {find("red"), find("green"), find("blue")};
    if (!(c[0] && c[1] && c[2])) {
      c[0] = find("diffuse_red"), c[1] = find("diffuse_green"), c[2] = find("diffuse_blue");
    }
    if (c[0] && c[1] && c[2]) {
      has_colors_ = true;
      for (int k = 0; k < 3; ++k) c[k]->role = static_cast<Role>(static_cast<int>(Role::kRed) + k);
    }
    for (Property& p : el->props) {
      if (p.role != Role::kSkip || p.is_list) continue;
      p.role = Role::kAttribute;
      p.attribute = static_cast<int>(out->attributes.size());
      out->attributes.push_back(VertexAttribute{p.name, p.type, {}});
    }
  }

  [[noreturn]] void Fail(const std::string& location, const std::string& what) const {
    throw ParseError(location, what);
  }

  template <typename Source>
  [[noreturn]] void FailRead(const Source& src, const Element& el, std::uint64_t i,
                             const Property& p, Status st, bool count) const {
    std::string what = detail::Printable(el.name) + " " + std::to_string(i) + ": property '" +
                       detail::Printable(p.name) + "': ";
    const std::string tok = detail::Printable(src.LastToken());
    const char* type = ScalarName(count ? p.count_type : p.type);
    switch (st) {
      case Status::kEof:
        what += "unexpected end of file";
        break;
      case Status::kBadNumber:
        what += "'" + tok + "' is not a valid " + type + " value";
        break;
      case Status::kOutOfRange:
        what += "value '" + tok + "' out of range for " + type;
        break;
      case Status::kOk:
        break;
    }
    Fail(src.Location(source_), what);
  }

  // Skips (ascii: reads) the items of a list property after its count was read.
  template <typename Source>
  void SkipListItems(Source& src, const Element& el, std::uint64_t i, const Property& p,
                     std::uint64_t n) {
    if constexpr (std::is_same_v<Source, BinarySource>) {
      if (!src.Skip(n, static_cast<std::size_t>(ScalarSize(p.type)))) {
        Fail(source_, detail::Printable(el.name) + " " + std::to_string(i) + ": property '" +
                          detail::Printable(p.name) + "': list of " + std::to_string(n) +
                          " items runs past the end of the file");
      }
    } else {
      for (std::uint64_t k = 0; k < n; ++k) {
        double v;
        const Status st = src.Read(p.type, &v);
        if (st != Status::kOk) FailRead(src, el, i, p, st, false);
      }
    }
  }

  template <typename Source>
  std::uint64_t ReadCount(Source& src, const Element& el, std::uint64_t i, const Property& p) {
    double c;
    const Status st = src.Read(p.count_type, &c);
    if (st != Status::kOk) FailRead(src, el, i, p, st, true);
    if (c < 0) {
      Fail(src.Location(source_), detail::Printable(el.name) + " " + std::to_string(i) +
                                      ": property '" + detail::Printable(p.name) +
                                      "': negative list count " +
                                      std::to_string(static_cast<long long>(c)));
    }
    return static_cast<std::uint64_t>(c);
  }

  template <typename Source>
  void ReadVertices(const Element& el, Source& src, PlyData* out) {
    for (std::uint64_t i = 0; i < el.count; ++i) {
      Vec3 x = Vec3::Zero(), n = Vec3::Zero();
      Color c = Color::Zero();
      for (const Property& p : el.props) {
        if (p.is_list) {
          SkipListItems(src, el, i, p, ReadCount(src, el, i, p));
          continue;
        }
        double v;
        const Status st = src.Read(p.type, &v);
        if (st != Status::kOk) FailRead(src, el, i, p, st, false);
        switch (p.role) {
          case Role::kX:
          case Role::kY:
          case Role::kZ:
            x[static_cast<int>(p.role) - static_cast<int>(Role::kX)] = v;
            break;
          case Role::kNx:
          case Role::kNy:
          case Role::kNz:
            n[static_cast<int>(p.role) - static_cast<int>(Role::kNx)] = v;
            break;
          case Role::kRed:
          case Role::kGreen:
          case Role::kBlue:
            c[static_cast<int>(p.role) - static_cast<int>(Role::kRed)] = ColorByte(p.type, v);
            break;
          case Role::kAttribute:
            out->attributes[static_cast<std::size_t>(p.attribute)].values.push_back(v);
            break;
          case Role::kSkip:
          case Role::kFaceList:
            break;
        }
      }
      if (!x.allFinite()) {
        char buf[128];
        std::snprintf(buf, sizeof(buf), "vertex %llu: non-finite coordinate (%g, %g, %g)",
                      static_cast<unsigned long long>(i), x.x(), x.y(), x.z());
        Fail(src.Location(source_), buf);
      }
      out->points.push_back(x);
      if (has_normals_) out->normals.push_back(n);
      if (has_colors_) out->colors.push_back(c);
    }
  }

  template <typename Source>
  void ReadGeneric(const Element& el, Source& src, bool is_face, PlyData* out) {
    if constexpr (std::is_same_v<Source, BinarySource>) {
      // Elements of fixed-size scalars that nobody reads are skipped in one step.
      bool fixed = !is_face;
      std::size_t record = 0;
      for (const Property& p : el.props) {
        fixed = fixed && !p.is_list;
        record += static_cast<std::size_t>(ScalarSize(p.type));
      }
      if (fixed) {
        if (!src.Skip(el.count, record)) {
          Fail(source_, "element '" + detail::Printable(el.name) + "': unexpected end of file");
        }
        return;
      }
    }
    for (std::uint64_t i = 0; i < el.count; ++i) {
      for (const Property& p : el.props) {
        if (!p.is_list) {
          double v;
          const Status st = src.Read(p.type, &v);
          if (st != Status::kOk) FailRead(src, el, i, p, st, false);
          continue;
        }
        const std::uint64_t n = ReadCount(src, el, i, p);
        if (!is_face || p.role != Role::kFaceList) {
          SkipListItems(src, el, i, p, n);
          continue;
        }
        if (n < 3) {
          Fail(src.Location(source_), "face " + std::to_string(i) + ": " + std::to_string(n) +
                                          " vertex indices (a face needs at least 3)");
        }
        if constexpr (std::is_same_v<Source, BinarySource>) {
          if (n > src.Remaining() / static_cast<std::size_t>(ScalarSize(p.type))) {
            Fail(source_, "face " + std::to_string(i) + ": list of " + std::to_string(n) +
                              " indices runs past the end of the file");
          }
        }
        int first = 0, prev = 0;
        for (std::uint64_t k = 0; k < n; ++k) {
          double v;
          const Status st = src.Read(p.type, &v);
          if (st != Status::kOk) FailRead(src, el, i, p, st, false);
          if (v < 0 || v >= static_cast<double>(vertex_count_) ||
              v > static_cast<double>(std::numeric_limits<int>::max())) {
            Fail(src.Location(source_), "face " + std::to_string(i) + ": vertex index " +
                                            std::to_string(static_cast<long long>(v)) +
                                            " out of range (" + std::to_string(vertex_count_) +
                                            " vertices)");
          }
          const int idx = static_cast<int>(v);
          if (k == 0) {
            first = idx;
          } else if (k >= 2) {
            out->faces.emplace_back(first, prev, idx);
          }
          prev = idx;
        }
      }
    }
  }

  const std::string& source_;
  bool want_faces_;
  bool has_normals_ = false;
  bool has_colors_ = false;
  std::uint64_t vertex_count_ = 0;
};

PlyData Parse(const std::uint8_t* data, std::size_t size, const std::string& source,
              bool want_faces) {
  Header h = ParseHeader(data, size, source);
  PlyData out;
  BodyReader reader(source, want_faces);
  reader.Prepare(&h, &out);
  const std::uint8_t* body = data + h.body_offset;
  const std::uint8_t* end = data + size;
  if (h.format == PlyFormat::kAscii) {
    AsciiSource src(reinterpret_cast<const char*>(data), reinterpret_cast<const char*>(body),
                    reinterpret_cast<const char*>(end));
    reader.ReadElements(h, src, false, &out);
  } else {
    const bool little = h.format == PlyFormat::kBinaryLittleEndian;
    BinarySource src(body, end, little != kHostLittleEndian);
    reader.ReadElements(h, src, true, &out);
  }
  return out;
}

// ---------------------------------------------------------------------------
// Writing.
// ---------------------------------------------------------------------------
class Encoder {
 public:
  explicit Encoder(PlyFormat format) : format_(format) {}

  std::string& buffer() { return buf_; }

  // Appends one value; integer types must hold an integral in-range value.
  void Put(ScalarType t, double v) {
    if (format_ == PlyFormat::kAscii) {
      if (!first_in_record_) buf_ += ' ';
      first_in_record_ = false;
      char tmp[64];
      std::to_chars_result r{};
      if (IsIntegerType(t)) {
        r = std::to_chars(tmp, tmp + sizeof(tmp), static_cast<std::int64_t>(v));
      } else if (t == ScalarType::kFloat32) {
        r = std::to_chars(tmp, tmp + sizeof(tmp), static_cast<float>(v));
      } else {
        r = std::to_chars(tmp, tmp + sizeof(tmp), v);
      }
      buf_.append(tmp, r.ptr);
      return;
    }
    const bool swap = (format_ == PlyFormat::kBinaryLittleEndian) != kHostLittleEndian;
    switch (t) {
      case ScalarType::kInt8:
        Store(static_cast<std::int8_t>(v), swap);
        break;
      case ScalarType::kUInt8:
        Store(static_cast<std::uint8_t>(v), swap);
        break;
      case ScalarType::kInt16:
        Store(static_cast<std::int16_t>(v), swap);
        break;
      case ScalarType::kUInt16:
        Store(static_cast<std::uint16_t>(v), swap);
        break;
      case ScalarType::kInt32:
        Store(static_cast<std::int32_t>(v), swap);
        break;
      case ScalarType::kUInt32:
        Store(static_cast<std::uint32_t>(v), swap);
        break;
      case ScalarType::kFloat32:
        Store(static_cast<float>(v), swap);
        break;
      case ScalarType::kFloat64:
        Store(v, swap);
        break;
    }
  }

  void EndRecord() {
    if (format_ == PlyFormat::kAscii) buf_ += '\n';
    first_in_record_ = true;
  }

 private:
  template <typename T>
  void Store(T v, bool swap) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (swap) std::reverse(b, b + sizeof(T));
    buf_.append(b, sizeof(T));
  }

  PlyFormat format_;
  std::string buf_;
  bool first_in_record_ = true;
};

// Checks that `v` can be stored in a property of type `t` (the writer casts).
void CheckStorable(const std::string& path, const VertexAttribute& a, std::size_t i) {
  const double v = a.values[i];
  double lo = 0, hi = 0;
  TypeRange(a.type, &lo, &hi);
  if (IsIntegerType(a.type)) {
    if (!(v >= lo && v <= hi) || v != std::floor(v)) {
      throw InvalidArgument(path + ": attribute '" + a.name + "' value " + std::to_string(v) +
                            " at vertex " + std::to_string(i) + " is not a valid " +
                            ScalarName(a.type));
    }
  } else if (a.type == ScalarType::kFloat32 && std::isfinite(v) && (v < lo || v > hi)) {
    throw InvalidArgument(path + ": attribute '" + a.name + "' value " + std::to_string(v) +
                          " at vertex " + std::to_string(i) + " does not fit a float");
  }
}

bool ValidAttributeName(const std::string& name) {
  if (name.empty()) return false;
  for (char c : name) {
    if (IsSpace(c) || static_cast<unsigned char>(c) < 32) return false;
  }
  return true;
}

void WriteVertexPly(const std::string& path, const std::vector<Vec3>& points,
                    const std::vector<Vec3>& normals, const std::vector<Color>& colors,
                    const std::vector<VertexAttribute>& attributes, const std::vector<Vec3i>* faces,
                    const PlyWriteOptions& opt) {
  const std::size_t n = points.size();
  const bool with_normals = opt.write_normals && !normals.empty();
  const bool with_colors = opt.write_colors && !colors.empty();
  const bool with_attrs = opt.write_attributes && !attributes.empty();
  if (with_normals && normals.size() != n) {
    throw InvalidArgument(path + ": " + std::to_string(normals.size()) + " normals for " +
                          std::to_string(n) + " vertices");
  }
  if (with_colors && colors.size() != n) {
    throw InvalidArgument(path + ": " + std::to_string(colors.size()) + " colours for " +
                          std::to_string(n) + " vertices");
  }
  const char* reserved[] = {"x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"};
  if (with_attrs) {
    for (const auto& a : attributes) {
      if (a.values.size() != n) {
        throw InvalidArgument(path + ": attribute '" + a.name + "' has " +
                              std::to_string(a.values.size()) + " values for " + std::to_string(n) +
                              " vertices");
      }
      if (!ValidAttributeName(a.name)) {
        throw InvalidArgument(path + ": attribute name '" + a.name + "' is not a valid PLY name");
      }
      for (const char* r : reserved) {
        if (a.name == r) {
          throw InvalidArgument(path + ": attribute name '" + a.name + "' is reserved");
        }
      }
      for (std::size_t i = 0; i < n; ++i) CheckStorable(path, a, i);
    }
  }
  if (faces) {
    for (std::size_t f = 0; f < faces->size(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int idx = (*faces)[f][k];
        if (idx < 0 || static_cast<std::size_t>(idx) >= n) {
          throw InvalidArgument(path + ": face " + std::to_string(f) + " index " +
                                std::to_string(idx) + " out of range (" + std::to_string(n) +
                                " vertices)");
        }
      }
    }
  }
  const ScalarType coord = opt.double_precision ? ScalarType::kFloat64 : ScalarType::kFloat32;
  if (coord == ScalarType::kFloat32) {
    const double fmax = std::numeric_limits<float>::max();
    auto check = [&](const std::vector<Vec3>& v, const char* what) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        if ((v[i].array().abs() > fmax && v[i].array().isFinite()).any()) {
          throw InvalidArgument(path + ": " + what + " " + std::to_string(i) +
                                " does not fit a float (use double_precision)");
        }
      }
    };
    check(points, "vertex");
    if (with_normals) check(normals, "normal");
  }
  const char* coord_name = ScalarName(coord);
  std::string header = std::string("ply\nformat ") + PlyFormatName(opt.format) +
                       " 1.0\ncomment written by dimr\nelement vertex " + std::to_string(n) + "\n";
  for (const char* c : {"x", "y", "z"})
    header += std::string("property ") + coord_name + " " + c + "\n";
  if (with_normals) {
    for (const char* c : {"nx", "ny", "nz"})
      header += std::string("property ") + coord_name + " " + c + "\n";
  }
  if (with_colors) {
    for (const char* c : {"red", "green", "blue"})
      header += std::string("property uchar ") + c + "\n";
  }
  if (with_attrs) {
    for (const auto& a : attributes)
      header += std::string("property ") + ScalarName(a.type) + " " + a.name + "\n";
  }
  if (faces) {
    header += "element face " + std::to_string(faces->size()) +
              "\nproperty list uchar int vertex_indices\n";
  }
  header += "end_header\n";

  Encoder enc(opt.format);
  std::string& buf = enc.buffer();
  buf = std::move(header);
  buf.reserve(buf.size() + n * 64 + (faces ? faces->size() * 40 : 0));
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) enc.Put(coord, points[i][k]);
    if (with_normals) {
      for (int k = 0; k < 3; ++k) enc.Put(coord, normals[i][k]);
    }
    if (with_colors) {
      for (int k = 0; k < 3; ++k) enc.Put(ScalarType::kUInt8, colors[i][k]);
    }
    if (with_attrs) {
      for (const auto& a : attributes) enc.Put(a.type, a.values[i]);
    }
    enc.EndRecord();
  }
  if (faces) {
    for (const Vec3i& f : *faces) {
      enc.Put(ScalarType::kUInt8, 3);
      for (int k = 0; k < 3; ++k) enc.Put(ScalarType::kInt32, f[k]);
      enc.EndRecord();
    }
  }
  detail::WriteFileBytes(path, buf);
}

}  // namespace

// ---------------------------------------------------------------------------
// Public API.
// ---------------------------------------------------------------------------
PlyHeader ParsePlyHeader(const std::uint8_t* data, std::size_t size, const std::string& source) {
  const Header h = ParseHeader(data, size, source);
  PlyHeader out;
  out.format = h.format;
  out.comments = h.comments;
  out.body_offset = h.body_offset;
  for (const Element& el : h.elements) {
    PlyHeader::Element e;
    e.name = el.name;
    e.count = el.count;
    for (const Property& p : el.props) {
      if (p.is_list) {
        e.properties.push_back(std::string("list ") + ScalarName(p.count_type) + " " +
                               ScalarName(p.type) + " " + p.name);
      } else {
        e.properties.push_back(std::string(ScalarName(p.type)) + " " + p.name);
      }
    }
    out.elements.push_back(std::move(e));
  }
  return out;
}

PlyHeader ReadPlyHeader(const std::string& path) {
  const auto bytes = detail::ReadFileBytes(path);
  return ParsePlyHeader(bytes.data(), bytes.size(), path);
}

TriangleMesh ParsePlyMesh(const std::uint8_t* data, std::size_t size, const std::string& source) {
  PlyData d = Parse(data, size, source, true);
  TriangleMesh m;
  m.vertices = std::move(d.points);
  m.faces = std::move(d.faces);
  m.vertex_normals = std::move(d.normals);
  m.vertex_colors = std::move(d.colors);
  m.attributes = std::move(d.attributes);
  return m;
}

PointCloud ParsePlyCloud(const std::uint8_t* data, std::size_t size, const std::string& source) {
  PlyData d = Parse(data, size, source, false);
  PointCloud c;
  c.points = std::move(d.points);
  c.normals = std::move(d.normals);
  c.colors = std::move(d.colors);
  c.attributes = std::move(d.attributes);
  return c;
}

TriangleMesh ReadPlyMesh(const std::string& path) {
  const auto bytes = detail::ReadFileBytes(path);
  return ParsePlyMesh(bytes.data(), bytes.size(), path);
}

PointCloud ReadPlyCloud(const std::string& path) {
  const auto bytes = detail::ReadFileBytes(path);
  return ParsePlyCloud(bytes.data(), bytes.size(), path);
}

void WritePly(const std::string& path, const TriangleMesh& mesh, const PlyWriteOptions& opt) {
  WriteVertexPly(path, mesh.vertices, mesh.vertex_normals, mesh.vertex_colors, mesh.attributes,
                 &mesh.faces, opt);
}

void WritePly(const std::string& path, const PointCloud& cloud, const PlyWriteOptions& opt) {
  WriteVertexPly(path, cloud.points, cloud.normals, cloud.colors, cloud.attributes, nullptr, opt);
}

void WritePlyPolygons(const std::string& path, const std::vector<Vec3>& vertices,
                      const std::vector<std::vector<int>>& polygons, PlyFormat format) {
  const std::size_t n = vertices.size();
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const auto& poly = polygons[f];
    if (poly.size() < 3 || poly.size() > 255) {
      throw InvalidArgument(path + ": polygon " + std::to_string(f) + " has " +
                            std::to_string(poly.size()) + " vertices (must be 3..255)");
    }
    for (int idx : poly) {
      if (idx < 0 || static_cast<std::size_t>(idx) >= n) {
        throw InvalidArgument(path + ": polygon " + std::to_string(f) + " index " +
                              std::to_string(idx) + " out of range (" + std::to_string(n) +
                              " vertices)");
      }
    }
  }
  Encoder enc(format);
  std::string& buf = enc.buffer();
  buf = std::string("ply\nformat ") + PlyFormatName(format) +
        " 1.0\ncomment written by dimr\nelement vertex " + std::to_string(n) +
        "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
        std::to_string(polygons.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3& v : vertices) {
    for (int k = 0; k < 3; ++k) enc.Put(ScalarType::kFloat64, v[k]);
    enc.EndRecord();
  }
  for (const auto& poly : polygons) {
    enc.Put(ScalarType::kUInt8, static_cast<double>(poly.size()));
    for (int idx : poly) enc.Put(ScalarType::kInt32, idx);
    enc.EndRecord();
  }
  detail::WriteFileBytes(path, buf);
}

}  // namespace dimr::geometry
