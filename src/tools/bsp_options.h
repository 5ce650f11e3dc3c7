// Inference settings of a BSP-CVAE model that its model card recommends.
#pragma once

#include <string>

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

}  // namespace dimr::tools
