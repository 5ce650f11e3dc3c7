#include "dimr/eval/classes.h"

namespace dimr::eval {

const std::array<const char*, kNumClasses>& ClassNames() {
  static const std::array<const char*, kNumClasses> kNames = {
      "table", "chair", "bookshelf", "sofa", "trash_bin", "cabinet", "display", "bathtub"};
  return kNames;
}

int ClassFromName(const std::string& name) {
  if (name == "trash") return 4;
  const auto& names = ClassNames();
  for (int i = 0; i < kNumClasses; ++i) {
    if (name == names[i]) return i;
  }
  return -1;
}

int RfsToCad(int rfs) {
  // dimr-method.md section 8.1 (the generated rfs_label_map.csv, last row wins): cabinet and
  // counter -> cabinet; chair and toilet -> chair; sofa; table, desk, other_table -> table;
  // bookshelf, other_shelf -> bookshelf; sink, bathtub -> bathtub; display; trash_bin.
  static const std::array<int, 25> kMap = {-1, -1, 5,  -1, 1, 3, 0,  -1, -1, 2, -1, 5, 0,
                                           -1, -1, -1, 1,  7, 7, -1, -1, 6,  4, 2,  0};
  if (rfs < 0 || rfs >= 25) return -1;
  return kMap[rfs];
}

}  // namespace dimr::eval
