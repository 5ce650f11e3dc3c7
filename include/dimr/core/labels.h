// Label sets of DIMR, the one copy every layer uses: the 25-class "RFS" semantic set the
// networks predict, the 8 CAD classes with meshes (and their ShapeNet synsets), and the
// RFS -> CAD map with the reference's quirks (toilet -> chair, sink -> bathtub, counter ->
// cabinet, desk / other_table -> table, kitchen_cabinet -> non-CAD, class 14 dead). Spec:
// ../shared/reference/dimr-method.md section 8.1. The numbering is fixed: it is in every
// shipped model, pool and dataset file.
//
// data/labels.h (dimr::data::...) and eval/classes.h (dimr::eval::...) give the same tables
// under their layers' names.
#pragma once

#include <array>
#include <string>

namespace dimr::labels {

constexpr int kNumRfsClasses = 25;
constexpr int kNumCadClasses = 8;
constexpr int kIgnoreLabel = -100;  // semantic ignore index of the losses
constexpr int kNonCad = -1;

enum RfsClass : int {
  kWall = 0,
  kFloor = 1,
  kCabinet = 2,
  kBed = 3,
  kChair = 4,
  kSofa = 5,
  kTable = 6,
  kDoor = 7,
  kWindow = 8,
  kBookshelf = 9,
  kPicture = 10,
  kCounter = 11,
  kDesk = 12,
  kCurtain = 13,
  kRefridgerator = 14,
  kShowerCurtain = 15,
  kToilet = 16,
  kSink = 17,
  kBathtub = 18,
  kOtherFurniture = 19,
  kKitchenCabinet = 20,
  kDisplay = 21,
  kTrashBin = 22,
  kOtherShelf = 23,
  kOtherTable = 24
};

enum CadClass : int {
  kCadTable = 0,
  kCadChair = 1,
  kCadBookshelf = 2,
  kCadSofa = 3,
  kCadTrashBin = 4,
  kCadCabinet = 5,
  kCadDisplay = 6,
  kCadBathtub = 7
};

// Network-order names ("wall", "floor", ..., "other_table").
const std::array<const char*, kNumRfsClasses>& RfsClassNames();
// "table", "chair", "bookshelf", "sofa", "trash_bin", "cabinet", "display", "bathtub".
const std::array<const char*, kNumCadClasses>& CadClassNames();
// ShapeNet synsets of the CAD classes ("04379243", ...), same order.
const std::array<const char*, kNumCadClasses>& CadSynsets();

// RFS id -> CAD id (0..7) or kNonCad. Throws dimr::InvalidArgument out of range.
int RfsToCad(int rfs);
// A representative RFS class of a CAD class (table -> table, bathtub -> bathtub, ...).
int CadToRfs(int cad);
// Name -> id; -1 if unknown. CadClassFromName also accepts "trash" (reference file names).
int RfsClassFromName(const std::string& name);
int CadClassFromName(const std::string& name);
// Synset -> CAD id, -1 if none.
int CadClassFromSynset(const std::string& synset);

}  // namespace dimr::labels
