// The 8 CAD classes the DIMR evaluation reports on, and the 25-class RFS -> CAD map used to
// label PCR ground truth, under the eval layer's names (the tables: dimr/core/labels.h).
// Spec: ../shared/reference/dimr-metrics.md section 1.1 and dimr-method.md section 8.1.
#pragma once

#include <array>
#include <string>

namespace dimr::eval {

constexpr int kNumClasses = 8;

// "table", "chair", "bookshelf", "sofa", "trash_bin", "cabinet", "display", "bathtub".
const std::array<const char*, kNumClasses>& ClassNames();
// Name -> CAD id, or -1. Accepts the reference's file-name token "trash" for trash_bin.
int ClassFromName(const std::string& name);
// RFS id (0..24) -> CAD id (0..7) or -1 (non-CAD). Ids outside [0, 25) (e.g. 255) -> -1.
int RfsToCad(int rfs);

}  // namespace dimr::eval
