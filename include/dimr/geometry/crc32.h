// CRC-32 (IEEE 802.3, reflected polynomial 0xedb88320) as zip and PNG use it. `crc` continues a
// previous value (0 to start).
#pragma once

#include <cstddef>
#include <cstdint>

namespace dimr::geometry {

std::uint32_t Crc32(const void* data, std::size_t n, std::uint32_t crc = 0);

}  // namespace dimr::geometry
