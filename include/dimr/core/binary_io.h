// Bounded binary reading and writing for the project's file formats (checkpoints, BSP
// datasets, shape pools, caches): values in host byte order (little-endian on every supported
// target: x86-64, aarch64), raw copies of trivially copyable types, no padding, no alignment.
//
// BinaryReader never reads past its end and never trusts a count it read: Count() checks a
// claimed element count against the bytes that remain before anything is allocated, so a
// truncated or corrupt file is a dimr::ParseError naming the source, the field and the offset,
// never a huge allocation or a crash.
//
//   dimr::BinaryReader r(path, dimr::ReadFileBytes(path));
//   r.ExpectMagic("DIMRPOOL", "a dimr shape pool");
//   const std::uint32_t version = r.Get<std::uint32_t>("version");
//   const std::size_t n = r.Count(r.Get<std::uint64_t>("count"), 12, "entries");
//
// The writer appends to a byte string that WriteFile() stores.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace dimr {

// The whole file (binary). Throws dimr::ParseError naming `path` when it cannot be opened or
// read, or is larger than `max_bytes`.
std::string ReadFileBytes(const std::string& path,
                          std::uint64_t max_bytes = std::uint64_t{1} << 40);

class BinaryReader {
 public:
  // Reads `bytes` (not copied: the viewed memory must outlive the reader); `source` names the
  // file or stream in errors.
  BinaryReader(std::string source, std::string_view bytes);

  template <typename T>
  T Get(const char* what) {
    static_assert(std::is_trivially_copyable<T>::value, "Get needs a trivially copyable type");
    T v;
    std::memcpy(&v, Take(sizeof(T), what), sizeof(T));
    return v;
  }
  // n values into `out` (resized).
  template <typename T>
  void GetArray(std::size_t n, std::vector<T>* out, const char* what) {
    static_assert(std::is_trivially_copyable<T>::value, "GetArray needs trivially copyable T");
    Need(n, sizeof(T), what);
    out->resize(n);
    if (n > 0) std::memcpy(out->data(), Take(n * sizeof(T), what), n * sizeof(T));
  }
  // n values into raw memory of at least n * sizeof(T) bytes.
  template <typename T>
  void GetInto(T* out, std::size_t n, const char* what) {
    static_assert(std::is_trivially_copyable<T>::value, "GetInto needs trivially copyable T");
    Need(n, sizeof(T), what);
    if (n > 0) std::memcpy(out, Take(n * sizeof(T), what), n * sizeof(T));
  }
  // n bytes as a string.
  std::string GetString(std::size_t n, const char* what);
  // A pointer to the next n bytes (valid as long as the viewed memory), then skips them.
  const char* Bytes(std::size_t n, const char* what) { return Take(n, what); }
  void Skip(std::size_t n, const char* what) { Take(n, what); }

  // `count` as a size, after checking that count elements of at least `min_bytes_each` bytes
  // fit in what remains (min_bytes_each 0 counts as 1). Throws otherwise.
  std::size_t Count(std::uint64_t count, std::size_t min_bytes_each, const char* what) const;
  // Throws "not <what> (bad magic)" unless the next bytes are `magic` (its characters, no
  // terminator), then skips them.
  void ExpectMagic(std::string_view magic, const char* what);
  // Throws "<n> trailing bytes after <what>" unless every byte was read.
  void ExpectEnd(const char* what) const;

  std::size_t pos() const { return pos_; }
  std::size_t size() const { return bytes_.size(); }
  std::size_t remaining() const { return bytes_.size() - pos_; }
  bool at_end() const { return pos_ == bytes_.size(); }
  const std::string& source() const { return source_; }

  // Throws dimr::ParseError(source, problem + " (at byte offset <pos>)").
  [[noreturn]] void Fail(const std::string& problem) const;

 private:
  const char* Take(std::size_t n, const char* what);
  void Need(std::size_t n, std::size_t each, const char* what) const;

  std::string source_;
  std::string_view bytes_;
  std::size_t pos_ = 0;
};

class BinaryWriter {
 public:
  template <typename T>
  void Put(const T& v) {
    static_assert(std::is_trivially_copyable<T>::value, "Put needs a trivially copyable type");
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <typename T>
  void PutArray(const T* values, std::size_t n) {
    static_assert(std::is_trivially_copyable<T>::value, "PutArray needs trivially copyable T");
    if (n > 0) bytes_.append(reinterpret_cast<const char*>(values), n * sizeof(T));
  }
  void PutBytes(const void* data, std::size_t n) {
    if (n > 0) bytes_.append(static_cast<const char*>(data), n);
  }
  void PutString(std::string_view s) { bytes_.append(s.data(), s.size()); }

  const std::string& bytes() const { return bytes_; }
  std::size_t size() const { return bytes_.size(); }
  // The bytes written so far (moved out; the writer is empty afterwards).
  std::string Release() { return std::move(bytes_); }
  // Writes every byte to `path` (truncating). Throws dimr::ParseError naming the path when it
  // cannot be opened or written.
  void WriteFile(const std::string& path) const;

 private:
  std::string bytes_;
};

}  // namespace dimr
