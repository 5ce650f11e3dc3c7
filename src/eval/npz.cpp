#include "dimr/eval/npz.h"

#include <array>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

#include "dimr/geometry/crc32.h"
#include "dimr/geometry/error.h"

#ifdef DIMR_HAVE_ZLIB
#include <zlib.h>
#endif

namespace dimr::eval {
namespace {

std::uint32_t U32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) |
         (std::uint32_t(p[3]) << 24);
}
std::uint16_t U16(const std::uint8_t* p) { return std::uint16_t(p[0] | (p[1] << 8)); }

// Value of key `key` in the npy header dict text, e.g. 'descr': '<f8' -> "<f8".
std::string DictValue(const std::string& header, const std::string& key,
                      const std::string& source) {
  const std::size_t k = header.find("'" + key + "'");
  if (k == std::string::npos) throw ParseError(source, "npy header has no '" + key + "'");
  std::size_t p = header.find(':', k);
  if (p == std::string::npos) throw ParseError(source, "npy header: bad '" + key + "'");
  ++p;
  while (p < header.size() && header[p] == ' ') ++p;
  if (p >= header.size()) throw ParseError(source, "npy header: bad '" + key + "'");
  if (header[p] == '\'') {
    const std::size_t e = header.find('\'', p + 1);
    if (e == std::string::npos) throw ParseError(source, "npy header: unterminated string");
    return header.substr(p + 1, e - p - 1);
  }
  if (header[p] == '(') {
    const std::size_t e = header.find(')', p);
    if (e == std::string::npos) throw ParseError(source, "npy header: unterminated shape");
    return header.substr(p, e - p + 1);
  }
  std::size_t e = p;
  while (e < header.size() && header[e] != ',' && header[e] != '}') ++e;
  return header.substr(p, e - p);
}

template <typename T>
void Convert(const std::uint8_t* src, std::size_t n, std::vector<double>* out) {
  out->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    T v;
    std::memcpy(&v, src + i * sizeof(T), sizeof(T));
    (*out)[i] = static_cast<double>(v);
  }
}

std::string Inflate(const std::uint8_t* data, std::size_t size, std::size_t expected,
                    const std::string& source) {
#ifdef DIMR_HAVE_ZLIB
  std::string out(expected, '\0');
  z_stream z{};
  if (inflateInit2(&z, -MAX_WBITS) != Z_OK) throw ParseError(source, "zlib init failed");
  z.next_in = const_cast<Bytef*>(data);
  z.avail_in = static_cast<uInt>(size);
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(expected);
  const int rc = inflate(&z, Z_FINISH);
  const std::size_t produced = expected - z.avail_out;
  inflateEnd(&z);
  if (rc != Z_STREAM_END || produced != expected) {
    throw ParseError(source, "corrupt deflate stream");
  }
  return out;
#else
  (void)data;
  (void)size;
  (void)expected;
  throw ParseError(source, "compressed npz entries need zlib (this build has none)");
#endif
}

}  // namespace

std::int64_t NpyArray::size() const {
  std::int64_t n = 1;
  for (auto d : shape) n *= d;
  return n;
}

NpyArray ParseNpy(const std::uint8_t* data, std::size_t size, const std::string& source) {
  static const std::uint8_t kMagic[6] = {0x93, 'N', 'U', 'M', 'P', 'Y'};
  if (size < 10 || std::memcmp(data, kMagic, 6) != 0) throw ParseError(source, "not an .npy array");
  const int major = data[6];
  std::size_t header_len = 0, offset = 0;
  if (major == 1) {
    header_len = U16(data + 8);
    offset = 10;
  } else if (major == 2 || major == 3) {
    if (size < 12) throw ParseError(source, "truncated npy header");
    header_len = U32(data + 8);
    offset = 12;
  } else {
    throw ParseError(source, "unsupported npy version " + std::to_string(major));
  }
  if (header_len > size - offset) throw ParseError(source, "truncated npy header");
  const std::string header(reinterpret_cast<const char*>(data + offset), header_len);
  offset += header_len;
  NpyArray a;
  const std::string descr = DictValue(header, "descr", source);
  if (DictValue(header, "fortran_order", source).find("True") != std::string::npos) {
    throw ParseError(source, "Fortran-order arrays are not supported");
  }
  if (descr.size() < 2 || descr[0] == '>') {
    throw ParseError(source, "unsupported dtype '" + descr + "' (little-endian numeric only)");
  }
  a.dtype = (descr[0] == '<' || descr[0] == '|' || descr[0] == '=') ? descr.substr(1) : descr;
  const std::string shape = DictValue(header, "shape", source);
  {
    std::string digits;
    for (char c : shape) {
      if (c >= '0' && c <= '9') {
        digits += c;
      } else if (!digits.empty()) {
        if (digits.size() > 12) throw ParseError(source, "absurd array dimension");
        a.shape.push_back(std::stoll(digits));
        digits.clear();
      }
    }
  }
  std::size_t elem = 0;
  const std::string& t = a.dtype;
  if (t == "f8" || t == "i8" || t == "u8") {
    elem = 8;
  } else if (t == "f4" || t == "i4" || t == "u4") {
    elem = 4;
  } else if (t == "i2" || t == "u2") {
    elem = 2;
  } else if (t == "i1" || t == "u1" || t == "b1") {
    elem = 1;
  } else {
    throw ParseError(source, "unsupported dtype '" + descr + "'");
  }
  const std::int64_t n = a.size();
  if (n < 0 || static_cast<std::uint64_t>(n) > (size - offset) / elem) {
    throw ParseError(source, "array data shorter than its shape claims");
  }
  const std::uint8_t* p = data + offset;
  const std::size_t count = static_cast<std::size_t>(n);
  if (t == "f8") Convert<double>(p, count, &a.values);
  if (t == "f4") Convert<float>(p, count, &a.values);
  if (t == "i8") Convert<std::int64_t>(p, count, &a.values);
  if (t == "u8") Convert<std::uint64_t>(p, count, &a.values);
  if (t == "i4") Convert<std::int32_t>(p, count, &a.values);
  if (t == "u4") Convert<std::uint32_t>(p, count, &a.values);
  if (t == "i2") Convert<std::int16_t>(p, count, &a.values);
  if (t == "u2") Convert<std::uint16_t>(p, count, &a.values);
  if (t == "i1") Convert<std::int8_t>(p, count, &a.values);
  if (t == "u1" || t == "b1") Convert<std::uint8_t>(p, count, &a.values);
  return a;
}

namespace {

// The whole file; throws ParseError naming it when it cannot be opened.
std::string ReadFileBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ParseError(path, "cannot open file");
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace

NpyArray ReadNpy(const std::string& path) {
  const std::string bytes = ReadFileBytes(path);
  return ParseNpy(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size(), path);
}

std::map<std::string, NpyArray> ReadNpz(const std::string& path) {
  const std::string bytes = ReadFileBytes(path);
  const auto* b = reinterpret_cast<const std::uint8_t*>(bytes.data());
  const std::size_t n = bytes.size();
  // End of central directory: the last "PK\5\6" within the final 64 KiB + 22 bytes.
  std::size_t eocd = std::string::npos;
  for (std::size_t i = n >= 22 ? n - 22 : 0; n >= 22; --i) {
    if (U32(b + i) == 0x06054b50) {
      eocd = i;
      break;
    }
    if (i == 0 || n - i > 65557) break;
  }
  if (eocd == std::string::npos) throw ParseError(path, "not a zip/npz archive (no end record)");
  const std::size_t entries = U16(b + eocd + 10);
  const std::size_t cd_offset = U32(b + eocd + 16);
  if (cd_offset == 0xffffffffu) throw ParseError(path, "ZIP64 archives are not supported");
  std::map<std::string, NpyArray> out;
  std::size_t p = cd_offset;
  for (std::size_t e = 0; e < entries; ++e) {
    if (p + 46 > n || U32(b + p) != 0x02014b50) throw ParseError(path, "corrupt central directory");
    const int method = U16(b + p + 10);
    const std::size_t csize = U32(b + p + 20), usize = U32(b + p + 24);
    const std::size_t name_len = U16(b + p + 28), extra_len = U16(b + p + 30),
                      comment_len = U16(b + p + 32);
    const std::size_t local = U32(b + p + 42);
    if (p + 46 + name_len > n) throw ParseError(path, "corrupt central directory");
    std::string name(bytes.data() + p + 46, name_len);
    p += 46 + name_len + extra_len + comment_len;
    const std::string where = path + ":" + name;
    if (csize == 0xffffffffu || usize == 0xffffffffu || local == 0xffffffffu) {
      throw ParseError(where, "ZIP64 entries are not supported");
    }
    if (local + 30 > n || U32(b + local) != 0x04034b50) throw ParseError(where, "bad local header");
    const std::size_t data = local + 30 + U16(b + local + 26) + U16(b + local + 28);
    if (data > n || csize > n - data) throw ParseError(where, "entry data truncated");
    std::string content;
    if (method == 0) {
      if (csize != usize) throw ParseError(where, "stored entry with different sizes");
      content.assign(bytes.data() + data, csize);
    } else if (method == 8) {
      if (usize > (std::size_t{1} << 33)) throw ParseError(where, "absurd uncompressed size");
      content = Inflate(b + data, csize, usize, where);
    } else {
      throw ParseError(where, "unsupported zip compression method " + std::to_string(method));
    }
    if (name.size() > 4 && name.compare(name.size() - 4, 4, ".npy") == 0)
      name.resize(name.size() - 4);
    out[name] =
        ParseNpy(reinterpret_cast<const std::uint8_t*>(content.data()), content.size(), where);
  }
  return out;
}

void WriteNpz(const std::string& path, const std::map<std::string, NpyArray>& arrays) {
  std::string zip, central;
  auto put16 = [](std::string* s, std::uint16_t v) {
    s->push_back(static_cast<char>(v & 0xff));
    s->push_back(static_cast<char>(v >> 8));
  };
  auto put32 = [&](std::string* s, std::uint32_t v) {
    put16(s, static_cast<std::uint16_t>(v & 0xffff));
    put16(s, static_cast<std::uint16_t>(v >> 16));
  };
  for (const auto& [key, a] : arrays) {
    std::string descr;
    std::size_t elem = 0;
    if (a.dtype == "f8") {
      descr = "<f8";
      elem = 8;
    } else if (a.dtype == "i8") {
      descr = "<i8";
      elem = 8;
    } else if (a.dtype == "u1") {
      descr = "|u1";
      elem = 1;
    } else {
      throw InvalidArgument("WriteNpz: unsupported dtype '" + a.dtype + "' for '" + key + "'");
    }
    if (static_cast<std::int64_t>(a.values.size()) != a.size()) {
      throw InvalidArgument("WriteNpz: '" + key + "' has a shape inconsistent with its values");
    }
    std::ostringstream h;
    h << "{'descr': '" << descr << "', 'fortran_order': False, 'shape': (";
    for (std::size_t i = 0; i < a.shape.size(); ++i)
      h << a.shape[i] << (a.shape.size() == 1 ? "," : (i + 1 < a.shape.size() ? ", " : ""));
    h << "), }";
    std::string header = h.str();
    while ((10 + header.size() + 1) % 64 != 0) header += ' ';
    header += '\n';
    std::string npy("\x93NUMPY\x01\x00", 8);
    put16(&npy, static_cast<std::uint16_t>(header.size()));
    npy += header;
    for (double v : a.values) {
      if (elem == 8 && a.dtype == "f8") {
        npy.append(reinterpret_cast<const char*>(&v), 8);
      } else if (elem == 8) {
        const auto iv = static_cast<std::int64_t>(v);
        npy.append(reinterpret_cast<const char*>(&iv), 8);
      } else {
        npy.push_back(static_cast<char>(static_cast<std::uint8_t>(v)));
      }
    }
    const std::string name = key + ".npy";
    const std::uint32_t crc = geometry::Crc32(npy.data(), npy.size());
    const std::uint32_t offset = static_cast<std::uint32_t>(zip.size());
    put32(&zip, 0x04034b50);
    put16(&zip, 20);
    put16(&zip, 0);
    put16(&zip, 0);  // stored
    put16(&zip, 0);
    put16(&zip, 0);
    put32(&zip, crc);
    put32(&zip, static_cast<std::uint32_t>(npy.size()));
    put32(&zip, static_cast<std::uint32_t>(npy.size()));
    put16(&zip, static_cast<std::uint16_t>(name.size()));
    put16(&zip, 0);
    zip += name;
    zip += npy;
    put32(&central, 0x02014b50);
    put16(&central, 20);
    put16(&central, 20);
    put16(&central, 0);
    put16(&central, 0);
    put16(&central, 0);
    put16(&central, 0);
    put32(&central, crc);
    put32(&central, static_cast<std::uint32_t>(npy.size()));
    put32(&central, static_cast<std::uint32_t>(npy.size()));
    put16(&central, static_cast<std::uint16_t>(name.size()));
    put16(&central, 0);
    put16(&central, 0);
    put16(&central, 0);
    put16(&central, 0);
    put32(&central, 0);
    put32(&central, offset);
    central += name;
  }
  const std::uint32_t cd_offset = static_cast<std::uint32_t>(zip.size());
  zip += central;
  put32(&zip, 0x06054b50);
  put16(&zip, 0);
  put16(&zip, 0);
  put16(&zip, static_cast<std::uint16_t>(arrays.size()));
  put16(&zip, static_cast<std::uint16_t>(arrays.size()));
  put32(&zip, static_cast<std::uint32_t>(central.size()));
  put32(&zip, cd_offset);
  put16(&zip, 0);
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw Error("cannot open '" + path + "' for writing");
  f.write(zip.data(), static_cast<std::streamsize>(zip.size()));
  if (!f) throw Error("failed writing '" + path + "'");
}

}  // namespace dimr::eval
