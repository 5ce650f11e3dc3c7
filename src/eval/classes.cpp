#include "dimr/eval/classes.h"

#include "dimr/core/labels.h"

namespace dimr::eval {

static_assert(kNumClasses == labels::kNumCadClasses, "eval reports on the 8 CAD classes");

const std::array<const char*, kNumClasses>& ClassNames() { return labels::CadClassNames(); }

int ClassFromName(const std::string& name) { return labels::CadClassFromName(name); }

int RfsToCad(int rfs) {
  // dimr-method.md section 8.1 (core/labels.h); ids outside [0, 25), e.g. 255, are non-CAD here.
  if (rfs < 0 || rfs >= labels::kNumRfsClasses) return -1;
  return labels::RfsToCad(rfs);
}

}  // namespace dimr::eval
