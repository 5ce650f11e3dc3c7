// Procedural CAD library of SynthScan: parametric families for the 8 CAD classes plus
// distractor / clutter objects, each a watertight mesh in a ShapeNet-like canonical frame.
//
// Canonical frame (DIMR's, dimr-method.md section 5.5): x = object forward (the side a person
// faces / uses), y = left, z = up; the model fills the box [-0.5, 0.5]^3 (unit bounding box,
// per-axis extents of exactly 1 after normalisation). ShapeNet's own axis convention (y up,
// -z forward) is produced only by the ShapeNet tree writer: (x_sn, y_sn, z_sn) = (-y, z, -x).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::data {

struct CadModel {
  int cad_class = -1;         // 0..7 (labels.h CadClass) or -1 for a non-CAD object
  int rfs_class = -1;         // semantic label (25-class) of the object's points
  std::string synset;         // ShapeNet synset ("" for non-CAD)
  std::string model_id;       // stable id derived from (class, family, seed): 32 hex chars
  std::string family;         // e.g. "four_leg_chair", "swivel_chair", "l_sofa"
  geometry::TriangleMesh mesh;  // canonical frame, unit box [-0.5,0.5]^3, watertight parts
  // Typical real-world size (metres, forward/left/up) this model was designed at.
  geometry::Vec3 nominal_size = geometry::Vec3::Ones();
  bool symmetric_about_z = false;  // rotationally symmetric (round bins, stools)
};

// One model of CAD class `cad_class` (0..7), varied by `seed` (same seed -> same bytes).
CadModel GenerateCadModel(int cad_class, std::uint64_t seed);

// Non-CAD furniture / clutter with its RFS label (bed, door, window, picture, counter-free
// clutter such as boxes, lamps, plants, books). `kind` < NumDistractorKinds().
int NumDistractorKinds();
CadModel GenerateDistractor(int kind, std::uint64_t seed);

// Family names available for a CAD class (for summaries and tests).
std::vector<std::string> CadFamilies(int cad_class);

}  // namespace dimr::data
