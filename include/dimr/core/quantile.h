// Nearest-rank quantile: the value of rank floor(q · n) (clamped to the last) of `values`, found
// with std::nth_element (O(n); `values` is reordered). The convention of the ceiling and floor
// rules (pipeline/ceiling.h, pipeline/gravity.h): q = 0 is the minimum, q = 1 the maximum.
// Throws dimr::InvalidArgument for an empty vector or q outside [0, 1].
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include "dimr/core/error.h"

namespace dimr {

template <typename T>
T NearestRankQuantile(std::vector<T>* values, double q) {
  if (values->empty()) throw InvalidArgument("NearestRankQuantile: no values");
  if (!(q >= 0.0 && q <= 1.0)) throw InvalidArgument("NearestRankQuantile: q must be in [0, 1]");
  const std::size_t k = std::min(values->size() - 1,
                                 static_cast<std::size_t>(q * static_cast<double>(values->size())));
  std::nth_element(values->begin(), values->begin() + static_cast<std::ptrdiff_t>(k),
                   values->end());
  return (*values)[k];
}

}  // namespace dimr
