// Forwarding header: FNV-1a lives in the core layer (dimr/core/hash.h); these names stay valid.
#pragma once

#include "dimr/core/hash.h"

namespace dimr::geometry {

using dimr::Fnv1a;
using dimr::kFnv1aOffset;
using dimr::kFnv1aStandardOffset;

}  // namespace dimr::geometry
