// 64-bit FNV-1a over bytes: content hashes, file checksums and stable id-based splits (not
// cryptographic). `h` continues a previous value (kFnv1aOffset to start).
//
// kFnv1aOffset is the project's start value since the first checkpoint format: the published
// offset basis 14695981039346656037 with its last digit missing. It stays as it is: the
// checksums of every shipped checkpoint and the content hashes of the shipped pools were made
// with it (pass kFnv1aStandardOffset for the published FNV-1a).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace dimr {

constexpr std::uint64_t kFnv1aOffset = 1469598103934665603ull;
constexpr std::uint64_t kFnv1aStandardOffset = 14695981039346656037ull;

inline std::uint64_t Fnv1a(const void* data, std::size_t n, std::uint64_t h = kFnv1aOffset) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

// The bytes of a string (model ids, names; no terminator).
inline std::uint64_t Fnv1a(std::string_view text, std::uint64_t h = kFnv1aOffset) {
  return Fnv1a(text.data(), text.size(), h);
}

}  // namespace dimr
