#include "dimr/core/binary_io.h"

#include <fstream>
#include <utility>

#include "dimr/core/error.h"

namespace dimr {

std::string ReadFileBytes(const std::string& path, std::uint64_t max_bytes) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw ParseError(path, "cannot open");
  const std::streamoff size = in.tellg();
  if (size < 0) throw ParseError(path, "cannot determine the file size");
  if (static_cast<std::uint64_t>(size) > max_bytes) {
    throw ParseError(path, "file of " + std::to_string(size) + " bytes is larger than the " +
                               std::to_string(max_bytes) + " accepted");
  }
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.seekg(0);
  if (size > 0 && !in.read(&bytes[0], static_cast<std::streamsize>(size))) {
    throw ParseError(path, "read error");
  }
  return bytes;
}

BinaryReader::BinaryReader(std::string source, std::string_view bytes)
    : source_(std::move(source)), bytes_(bytes) {}

void BinaryReader::Fail(const std::string& problem) const {
  throw ParseError(source_, problem + " (at byte offset " + std::to_string(pos_) + ")");
}

const char* BinaryReader::Take(std::size_t n, const char* what) {
  if (n > remaining()) {
    Fail(std::string("truncated: ") + what + " needs " + std::to_string(n) + " bytes, only " +
         std::to_string(remaining()) + " left");
  }
  const char* p = bytes_.data() + pos_;
  pos_ += n;
  return p;
}

void BinaryReader::Need(std::size_t n, std::size_t each, const char* what) const {
  if (each == 0) each = 1;
  if (n > remaining() / each) {
    Fail(std::string("truncated or corrupt: ") + what + " claims " + std::to_string(n) + " x " +
         std::to_string(each) + " bytes, only " + std::to_string(remaining()) + " left");
  }
}

std::size_t BinaryReader::Count(std::uint64_t count, std::size_t min_bytes_each,
                                const char* what) const {
  if (min_bytes_each == 0) min_bytes_each = 1;
  if (count > remaining() / min_bytes_each) {
    Fail(std::string("corrupt count: ") + std::to_string(count) + " " + what + " of at least " +
         std::to_string(min_bytes_each) + " bytes each cannot fit in the " +
         std::to_string(remaining()) + " bytes left");
  }
  return static_cast<std::size_t>(count);
}

std::string BinaryReader::GetString(std::size_t n, const char* what) {
  return std::string(Take(n, what), n);
}

void BinaryReader::ExpectMagic(std::string_view magic, const char* what) {
  if (remaining() < magic.size() || bytes_.substr(pos_, magic.size()) != magic) {
    Fail(std::string("not ") + what + " (bad magic)");
  }
  pos_ += magic.size();
}

void BinaryReader::ExpectEnd(const char* what) const {
  if (!at_end()) Fail(std::to_string(remaining()) + " trailing bytes after " + what);
}

void BinaryWriter::WriteFile(const std::string& path) const {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw ParseError(path, "cannot open for writing");
  out.write(bytes_.data(), static_cast<std::streamsize>(bytes_.size()));
  out.flush();
  if (!out) throw ParseError(path, "write failed");
}

}  // namespace dimr
