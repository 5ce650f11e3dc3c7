#include "dimr/core/labels.h"

#include <string>

#include "dimr/core/error.h"

namespace dimr::labels {

const std::array<const char*, kNumRfsClasses>& RfsClassNames() {
  static const std::array<const char*, kNumRfsClasses> kNames = {"wall",
                                                                 "floor",
                                                                 "cabinet",
                                                                 "bed",
                                                                 "chair",
                                                                 "sofa",
                                                                 "table",
                                                                 "door",
                                                                 "window",
                                                                 "bookshelf",
                                                                 "picture",
                                                                 "counter",
                                                                 "desk",
                                                                 "curtain",
                                                                 "refridgerator",
                                                                 "shower curtain",
                                                                 "toilet",
                                                                 "sink",
                                                                 "bathtub",
                                                                 "otherfurniture",
                                                                 "kitchen_cabinet",
                                                                 "display",
                                                                 "trash_bin",
                                                                 "other_shelf",
                                                                 "other_table"};
  return kNames;
}

const std::array<const char*, kNumCadClasses>& CadClassNames() {
  static const std::array<const char*, kNumCadClasses> kNames = {
      "table", "chair", "bookshelf", "sofa", "trash_bin", "cabinet", "display", "bathtub"};
  return kNames;
}

const std::array<const char*, kNumCadClasses>& CadSynsets() {
  static const std::array<const char*, kNumCadClasses> kSynsets = {
      "04379243", "03001627", "02871439", "04256520",
      "02747177", "02933112", "03211117", "02808440"};
  return kSynsets;
}

int RfsToCad(int rfs) {
  static const std::array<int, kNumRfsClasses> kMap = {
      kNonCad,        // wall
      kNonCad,        // floor
      kCadCabinet,    // cabinet
      kNonCad,        // bed
      kCadChair,      // chair
      kCadSofa,       // sofa
      kCadTable,      // table
      kNonCad,        // door
      kNonCad,        // window
      kCadBookshelf,  // bookshelf
      kNonCad,        // picture
      kCadCabinet,    // counter
      kCadTable,      // desk
      kNonCad,        // curtain
      kNonCad,        // refridgerator (dead class)
      kNonCad,        // shower curtain
      kCadChair,      // toilet
      kCadBathtub,    // sink
      kCadBathtub,    // bathtub
      kNonCad,        // otherfurniture
      kNonCad,        // kitchen_cabinet
      kCadDisplay,    // display
      kCadTrashBin,   // trash_bin
      kCadBookshelf,  // other_shelf
      kCadTable,      // other_table
  };
  if (rfs < 0 || rfs >= kNumRfsClasses) {
    throw InvalidArgument("RFS class id " + std::to_string(rfs) + " out of range [0, 25)");
  }
  return kMap[rfs];
}

int CadToRfs(int cad) {
  static const std::array<int, kNumCadClasses> kMap = {kTable,    kChair,   kBookshelf, kSofa,
                                                       kTrashBin, kCabinet, kDisplay,   kBathtub};
  if (cad < 0 || cad >= kNumCadClasses) {
    throw InvalidArgument("CAD class id " + std::to_string(cad) + " out of range [0, 8)");
  }
  return kMap[cad];
}

int RfsClassFromName(const std::string& name) {
  const auto& names = RfsClassNames();
  for (int i = 0; i < kNumRfsClasses; ++i) {
    if (name == names[i]) return i;
  }
  return -1;
}

int CadClassFromName(const std::string& name) {
  if (name == "trash") return kCadTrashBin;
  const auto& names = CadClassNames();
  for (int i = 0; i < kNumCadClasses; ++i) {
    if (name == names[i]) return i;
  }
  return -1;
}

int CadClassFromSynset(const std::string& synset) {
  const auto& s = CadSynsets();
  for (int i = 0; i < kNumCadClasses; ++i) {
    if (synset == s[i]) return i;
  }
  return -1;
}

}  // namespace dimr::labels
