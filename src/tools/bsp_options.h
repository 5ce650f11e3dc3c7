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

// The dilation to decode with: `requested` when >= 0; with a negative value the model card's
// `recommended_dilation:` (model.yaml beside the weights), else 0 (the reference). Throws
// dimr::ParseError naming the card for a malformed or negative value.
float ResolveBspDilation(const std::string& model_path, float requested);
// Both dilations (card keys recommended_dilation and recommended_distance_dilation), written
// into `options`; returns the resolved pair.
BspDilation ApplyBspDilation(const std::string& model_path, const BspDilation& requested,
                             pipeline::BspMeshOptions* options);

// Adds `--dilation` and `--distance-dilation` (default -1 = from the model card) to a BSP
// command.
void AddBspDilationOption(CLI::App& app, BspDilation* dilation);

}  // namespace dimr::tools
