// The imported real-furniture library on disk (written by `dimr cad import`) and its use in
// SynthScan rooms (a ModelSource that draws a fraction of the CAD objects and distractors from
// it).
//
// Layout of an import folder (gitignored, e.g. data/sh3d):
//   train/            ShapeNet-style tree (shapenet_io.h) of the CAD-class models, train split
//   test/             the same for the held-out split (IsHeldOutModel): testing only
//   train_solid/, test_solid/   (with --solid) the same models as closed voxel meshes
//   distractors/<model_id>.obj  non-CAD models, canonical frame (unit box)
//   colors/<model_id>.ply       per-vertex colours of every model (canonical mesh, same vertex
//                               order as its OBJ; texture / MTL colours, sRGB)
//   catalog.json      one entry per model: id, split, class, rfs_class, distractor kind, rule,
//                     name, category, catalogue, creator, licence, source, nominal size, mean
//                     colour, triangles, boundary edges, solid fractions, path
//   ATTRIBUTION.md    per catalogue and model: name, creator, licence, source
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/room.h"
#include "dimr/data/sh3d_catalog.h"

namespace dimr::data {

struct RealFurnitureWriteOptions {
  bool solid = false;  // also write train_solid/ and test_solid/ (ClosedOccupancy meshes)
  int solid_res = 64;
  int close_cells = 1;
  int precision = 6;  // OBJ digits after the point
};

// Writes the layout above (merging into existing trees like WriteShapeNetTree; catalog.json
// and ATTRIBUTION.md are rewritten). Throws dimr::InvalidArgument for an unwritable folder.
void WriteRealFurniture(const std::string& dir, const std::vector<ImportedModel>& models,
                        const RealFurnitureWriteOptions& opt = {});

struct RealFurnitureLibrary {
  std::array<std::vector<CadModel>, 8> cad;        // by CAD class
  std::vector<std::vector<CadModel>> distractors;  // by GenerateDistractor kind
  std::size_t size() const;
};

// Reads one split ("train" or "test") of an import folder: the CAD tree and the distractors of
// that split. Every model gets its per-vertex colours from colors/ (else uniform vertex colours =
// its catalogue mean colour); the room composer takes their mean as the material albedo and
// keeps them on the placed mesh. Throws dimr::ParseError naming the file for a
// missing / malformed catalog.json or model.
RealFurnitureLibrary LoadRealFurniture(const std::string& dir, const std::string& split);

// The default procedural source, except that a CAD object of class c (or a distractor of
// kind k) is drawn from `lib` with probability `fraction` (decided by a hash of the model
// seed, so rooms stay deterministic) when `lib` has models of that class / kind.
// fraction must be in [0, 1]; 0 gives exactly DefaultModelSource()'s models.
ModelSource MixedModelSource(std::shared_ptr<const RealFurnitureLibrary> lib, double fraction);

}  // namespace dimr::data
