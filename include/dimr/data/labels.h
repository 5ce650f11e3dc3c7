// The label sets (RFS 25, CAD 8, the RFS -> CAD map) under the data layer's names
// (dimr::data::kNumCadClasses, data::CadClassNames(), data::RfsToCad(), ...). The tables
// themselves are the core layer's, dimr/core/labels.h.
#pragma once

#include "dimr/core/labels.h"

namespace dimr::data {

using namespace ::dimr::labels;  // NOLINT(build/namespaces): the same tables, the data layer's
                                 // names

}  // namespace dimr::data
