// ShapeNet-style model trees: `<dir>/<synset>/<model_id>/models/model_normalized.obj` plus
// `<dir>/index.json` (model id, synset, class, family, nominal size, seed, part structure).
//
// Coordinates in the OBJ files follow ShapeNetCore v2's model_normalized convention: y up,
// -z forward, centred at the bounding-box centre, bounding-box diagonal = 1, the model's real
// proportions kept. From a CadModel's canonical unit-box vertex p (x forward, y left, z up)
// with nominal size s (metres) the written vertex is
//     q = A * diag(s) * p / |s|,    A = [[0,-1,0],[0,0,1],[-1,0,0]]
// i.e. (x_sn, y_sn, z_sn) = (-y, z, -x) * (scaled). The reader applies the inverse
//     p = (diag(e)^-1 * A^T * q) - centre,   e = per-axis extent of A^T q
// (per-axis re-normalisation to [-0.5, 0.5]^3), which is exact up to the OBJ precision for
// files written here and maps a real ShapeNet model to the same canonical unit box.
// See docs/cad_library.md.
#pragma once

#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

// Linear map from canonical unit-box coordinates to ShapeNet model_normalized coordinates
// for a model of nominal size `nominal_size` (q = M p; the offset is zero).
Eigen::Matrix3d CanonicalToShapeNet(const geometry::Vec3& nominal_size);

// Axis permutation A of the file comment: ShapeNet axes from canonical axes (no scaling).
Eigen::Matrix3d CanonicalToShapeNetAxes();

// Relative path of a model's OBJ inside a tree: "<synset>/<model_id>/models/model_normalized.obj".
std::string ShapeNetRelativePath(const std::string& synset, const std::string& model_id);

// Writes the models (CAD models only: every model needs a synset and a 32-hex model id) and
// merges them into `<dir>/index.json` (an existing index is kept; entries with the same model
// id are replaced). `precision` = digits after the decimal point of the OBJ coordinates.
// Throws dimr::InvalidArgument naming the path when the output cannot be written or a model
// has no synset, dimr::ParseError when an existing index is malformed.
void WriteShapeNetTree(const std::string& dir, const std::vector<CadModel>& models,
                       int precision = 8);

// Reads a tree back into canonical-frame models (unit box). With an index.json the entries
// (family, nominal size, seed, parts) come from it, in index order; without one, every
// `<synset>/<id>/models/model_normalized.obj` of a known CAD synset is read (a real ShapeNet
// tree), sorted by synset then id. Throws dimr::ParseError naming the path for a missing
// directory, a malformed index or a malformed OBJ.
std::vector<CadModel> ReadShapeNetTree(const std::string& dir);

// One model_normalized.obj back in the canonical frame. cad_class from the synset (-1 if it
// is not one of the 8 CAD synsets), model_id from the path's `<id>/models/` folder when
// present, nominal_size = the proportions of the file's bounding box (diagonal 1; the
// metric size is only known from an index), one part named "mesh".
CadModel ReadShapeNetModel(const std::string& path, const std::string& synset);

}  // namespace dimr::data
