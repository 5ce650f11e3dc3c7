// Real ScanNet scenes from per-vertex arrays (issue 22). Public ScanNet exports often ship a
// scene not as its ScanNet files but as numpy arrays of the mesh vertices and their labels -
// e.g. mmdetection3d's `scannet_train_instance_data/<scene>_vert_all.npy` (N x 6: x y z r g b,
// axis-aligned), `_sem_label_all.npy` (N NYU40 ids, 0 = unannotated) and `_ins_label_all.npy`
// (N object ids, 0 = none). SceneFromLabelledVertices turns such arrays into a SynthScene that
// data::WriteScanNetScene writes as an ordinary ScanNet scene folder, so `dimr real eval` and
// `dimr stage1 eval` read it like any other: semantic labels and, from the object ids, the
// ground-truth instances for the CAD-class instance AP.
#pragma once

#include <string>

#include "dimr/data/synthscan.h"
#include "dimr/eval/npz.h"

namespace dimr::eval {

// The NYU40 class name of an id 1..40 ("wall", "floor", ..., "otherfurniture", "otherprop"),
// "" for anything else. data::RfsFromCategory(Nyu40ClassName(k)) == data::Nyu40ToRfs(k) for
// every k.
const char* Nyu40ClassName(int nyu40);

struct LabelledVertexSources {
  std::string vertices = "vertices", nyu40 = "nyu40", instance = "instance";  // for errors
};

// vertices: N x 3 (x y z) or N x >= 6 (x y z r g b, colours 0..255; more columns ignored);
// nyu40, instance: N integers (any integer dtype, or floats holding integers). Each object
// (instance id > 0) takes the NYU40 class most of its vertices carry (ties: the smaller id);
// its category is that class's NYU40 name, its RFS / CAD class follow from the category as
// for any ScanNet aggregation. A vertex of an object gets the object's RFS class (ignore when
// it has none), a vertex of no object its own NYU40 id's (data::Nyu40ToRfs). One segment per
// object (segment id = object id, 0 for the rest). No colours: mid grey.
// Throws dimr::ParseError naming the array for a wrong shape, a length mismatch, a non-finite
// coordinate, a colour outside [0, 255], a label outside [0, 40] or an object id outside
// [0, 65535] or not an integer.
data::SynthScene SceneFromLabelledVertices(const std::string& name, const NpyArray& vertices,
                                           const NpyArray& nyu40, const NpyArray& instance,
                                           const LabelledVertexSources& sources = {});

}  // namespace dimr::eval
