// Procedural CAD library of SynthScan: parametric families for the 8 CAD classes plus
// distractor / clutter objects, each a watertight mesh in a ShapeNet-like canonical frame.
//
// Canonical frame (DIMR's, dimr-method.md section 5.5): x = object forward (the side a person
// faces / uses), y = left, z = up; the model fills the box [-0.5, 0.5]^3 (unit bounding box,
// per-axis extents of exactly 1 after normalisation). ShapeNet's own axis convention (y up,
// -z forward) is produced only by the ShapeNet tree writer: (x_sn, y_sn, z_sn) = (-y, z, -x).
//
// Mesh structure: a model is the UNION of closed parts (like a BSP convex union). Each part
// is a closed, consistently outward-oriented triangle mesh (every edge shared by exactly two
// triangles of that part, traversed in opposite directions; positive signed volume). Parts
// may overlap or touch; the faces of part i are the contiguous range
// [part_face_begin[i], part_face_begin[i + 1]) (the last part ends at mesh.faces.size()).
// Hollow objects (trash bins, bathtubs) are closed thin-walled solids, so their cavity is
// real empty space. See docs/cad_library.md for the families and their parameters.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::data {

struct CadModel {
  int cad_class = -1;           // 0..7 (labels.h CadClass) or -1 for a non-CAD object
  int rfs_class = -1;           // semantic label (25-class) of the object's points; -1 = ignore
  std::string synset;           // ShapeNet synset ("" for non-CAD)
  std::string model_id;         // stable id derived from (class, family, seed): 32 hex chars
  std::string family;           // e.g. "four_leg_chair", "swivel_chair", "l_sofa"
  geometry::TriangleMesh mesh;  // canonical frame, unit box [-0.5,0.5]^3, watertight parts
  // Typical real-world size (metres, forward/left/up) this model was designed at.
  geometry::Vec3 nominal_size = geometry::Vec3::Ones();
  bool symmetric_about_z = false;  // rotationally symmetric (round bins, stools)

  // Part structure (see the file comment): first face of each part, and a short name per
  // part ("seat", "back", "leg", "screen", "stand", "door", "handle", ...). Same length.
  std::vector<int> part_face_begin;
  std::vector<std::string> part_names;
  std::uint64_t seed = 0;    // the seed this model was generated from
  int distractor_kind = -1;  // GenerateDistractor kind, -1 for CAD models

  int NumParts() const { return static_cast<int>(part_face_begin.size()); }
  // Face range [begin, end) of part i.
  int PartBegin(int i) const { return part_face_begin[i]; }
  int PartEnd(int i) const {
    return i + 1 < NumParts() ? part_face_begin[i + 1] : static_cast<int>(mesh.faces.size());
  }
};

// One model of CAD class `cad_class` (0..7), varied by `seed` (same seed -> same bytes on
// every platform). Pure function, no shared mutable state: safe to call from many threads.
// Throws dimr::InvalidArgument for a class out of range.
CadModel GenerateCadModel(int cad_class, std::uint64_t seed);

// Non-CAD furniture / clutter with its RFS label (bed, door, window, picture, counter-free
// clutter such as boxes, lamps, plants, books). `kind` < NumDistractorKinds().
// Clutter that belongs to no RFS class has rfs_class = -1: its points get the ignore label
// (kIgnoreLabel in training, 0 = "unannotated" in ScanNet files).
int NumDistractorKinds();
CadModel GenerateDistractor(int kind, std::uint64_t seed);

// Where a distractor goes in a room (for the composer).
enum class DistractorPlacement {
  kFloor,      // stands on the floor (free or against a wall)
  kWall,       // hangs on / is set into a wall, its back (-x) against the wall
  kOnSurface,  // stands on a table, shelf or cabinet top
};

struct DistractorInfo {
  const char* name;  // "bed", "door", "window", ..., also CadModel::family
  int rfs_class;     // 25-class label, -1 = ignore
  DistractorPlacement placement;
  double bottom_min;  // height of the object's bottom above the floor (metres) for kWall
  double bottom_max;  // (0 for floor / surface objects)
};

// Throws dimr::InvalidArgument for a kind out of range.
const DistractorInfo& GetDistractorInfo(int kind);

// Family names available for a CAD class (for summaries and tests).
std::vector<std::string> CadFamilies(int cad_class);

}  // namespace dimr::data
