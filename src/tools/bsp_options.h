// Inference settings of a BSP-CVAE model that its model card recommends.
#pragma once

#include <string>

namespace CLI {
class App;
}

namespace dimr::tools {

// The dilation to decode with: `requested` when >= 0; with a negative value the model card's
// `recommended_dilation:` (model.yaml beside the weights), else 0 (the reference). Throws
// dimr::ParseError naming the card for a malformed or negative value.
float ResolveBspDilation(const std::string& model_path, float requested);

// Adds `--dilation` (default -1 = from the model card) to a BSP command.
void AddBspDilationOption(CLI::App& app, float* dilation);

}  // namespace dimr::tools
