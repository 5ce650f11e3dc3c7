// Integer cell coordinates packed into one 64-bit hash key, for the unordered sets and maps
// of cells that several layers keep (voxel occupancy, 2-D floor or wall cells, Poisson-disk
// grids). One definition, so that two places that must agree on a cell do.
//
//   PackCell2(ix, iy)      : ix in the high 32 bits, iy in the low 32 (two's complement), exact
//                            for any int32 coordinates; UnpackCell2 inverts it.
//   PackCell3(ix, iy, iz)  : 21 bits per axis (x lowest), each coordinate taken modulo 2^21, so
//                            it is exact for coordinates spanning < 2^21 cells (a 20 km room at
//                            1 cm); callers that can see wider clouds must check the span.
//   CellOf(v, cell)        : floor(v / cell) as an integer.
#pragma once

#include <cmath>
#include <cstdint>
#include <utility>

namespace dimr::geometry {

inline std::int64_t CellOf(double v, double cell) {
  return static_cast<std::int64_t>(std::floor(v / cell));
}

inline std::int64_t PackCell2(std::int64_t ix, std::int64_t iy) {
  return static_cast<std::int64_t>((static_cast<std::uint64_t>(ix) << 32) ^
                                   static_cast<std::uint32_t>(iy));
}

inline std::pair<std::int32_t, std::int32_t> UnpackCell2(std::int64_t key) {
  return {static_cast<std::int32_t>(static_cast<std::uint64_t>(key) >> 32),
          static_cast<std::int32_t>(static_cast<std::uint32_t>(key))};
}

inline std::uint64_t PackCell3(std::int64_t ix, std::int64_t iy, std::int64_t iz) {
  constexpr std::uint64_t kMask = (std::uint64_t{1} << 21) - 1;
  return (static_cast<std::uint64_t>(ix) & kMask) |
         ((static_cast<std::uint64_t>(iy) & kMask) << 21) |
         ((static_cast<std::uint64_t>(iz) & kMask) << 42);
}

}  // namespace dimr::geometry
