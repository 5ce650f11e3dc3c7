// The bytes numpy.save writes for a little-endian C-order array (format version 1, the data
// starting at byte 128), for tests that feed .npy files to the readers and the CLI.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace dimr::testing {

// `descr` e.g. "<f4", "<u4"; `data` holds the elements' bytes in C order.
inline std::string NpyBytes(const std::string& descr, const std::vector<long long>& shape,
                            const void* data, std::size_t bytes) {
  std::string dims;
  for (long long d : shape) dims += std::to_string(d) + ", ";
  std::string header =
      "{'descr': '" + descr + "', 'fortran_order': False, 'shape': (" + dims + "), }";
  header.append(128 - 10 - header.size() - 1, ' ');
  header += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  out.push_back(static_cast<char>(header.size()));
  out.push_back('\0');
  out += header;
  out.append(static_cast<const char*>(data), bytes);
  return out;
}

}  // namespace dimr::testing
