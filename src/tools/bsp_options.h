// Helpers shared by the BSP commands: the decoding settings a model card recommends, and
// BSP training samples from a ShapeNet-format tree.
#pragma once

#include <string>
#include <vector>

#include "dimr/nn/bsp_dataset.h"

namespace CLI {
class App;
}

namespace dimr::pipeline {
struct BspMeshOptions;
}

namespace dimr::tools {

// Decoding dilations of a BSP command: the plane-unit dilation and the Euclidean face
// offset (BspMeshOptions::dilation, ::distance_dilation). A negative value means "from the
// model card".
struct BspDilation {
  float plane = -1.0f;
  float distance = -1.0f;
};

// The dilations to decode with, written into `options` and returned: each requested value
// when >= 0; for a negative one the model card's `recommended_dilation:` /
// `recommended_distance_dilation:` (model.yaml beside the weights), else 0 (the reference).
// Throws dimr::ParseError naming the card for a malformed or negative value.
BspDilation ApplyBspDilation(const std::string& model_path, const BspDilation& requested,
                             pipeline::BspMeshOptions* options);

// Adds `--dilation` and `--distance-dilation` (default -1 = from the model card) to a BSP
// command.
void AddBspDilationOption(CLI::App& app, BspDilation* dilation);

// Which models of a ShapeNet-format tree to turn into BSP samples.
struct ShapeNetSelection {
  // "all", or "train" / "val" / "test": a stable function of the model id (64-bit FNV-1a of the
  // id, mod 100: < 80 train, < 90 val, else test), so a model never changes split when the
  // tree grows and the three never share a model.
  std::string split = "all";
  std::vector<int> classes = {0, 1, 2, 3, 4, 5, 6, 7};  // CAD class ids to keep
  int per_class = 0;    // > 0: at most this many per class (in path order), for balancing
  int resolution = 32;  // encoder grid
  int jobs = 1;         // worker threads (0 = all cores); the result does not depend on it
  // Also a left-right mirrored copy of every model (pipeline::MirrorLeftRight), id
  // "<model_id>~mirror", right after the original (training augmentation).
  bool mirror = false;
};

// Training data of `dimr train bsp`: the concatenation of one or more caches, each given as
// `FILE` or `FILE@N` (its samples N times, N in 1..100: oversampling a small set, e.g. real models
// among thousands of procedural ones). Throws dimr::InvalidArgument for an empty list, a bad
// repeat count (`FILE@0`, `FILE@x2`) or caches of different resolutions, dimr::ParseError
// naming the file for a missing or corrupt cache.
nn::BspDataset LoadBspTrainingSets(const std::vector<std::string>& specs);

// Split of a model id under ShapeNetSelection::split's rule ("train", "val" or "test").
std::string ShapeNetSplitOf(const std::string& model_id);

// BSP samples (pipeline::MakeBspSample, seeded by the model id) of every
// `<dir>/<synset>/<model_id>/models/model_normalized.obj` of a CAD synset that the selection
// keeps: a tree written by `dimr cad generate` or a real ShapeNetCore v2 (other synsets are
// skipped). Models are read one at a time in parallel, never the whole tree at once. Throws
// dimr::ParseError naming the file for a missing tree or a malformed model and
// dimr::InvalidArgument for a bad split name or a tree without any selected model.
nn::BspDataset ShapeNetBspDataset(const std::string& dir, const ShapeNetSelection& selection);

}  // namespace dimr::tools
