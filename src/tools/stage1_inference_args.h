// The stage-1 inference flags `dimr stage1 eval`, `dimr stage1 calibrate`, `dimr bench stage1`
// and `dimr real eval` share: the weights, a preset, and one option per Stage1InferenceConfig
// field overriding the model card.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "dimr/pipeline/ceiling.h"
#include "dimr/pipeline/stage1_segmenter.h"
#include "tools/config_options.h"

namespace dimr::tools {

struct InferenceArgs {
  std::string model = "models/stage1/stage1.pt";
  std::string preset = "accurate";
  std::shared_ptr<ConfigOptions<pipeline::Stage1InferenceConfig>> options;
};

void AddInferenceFlags(CLI::App& app, InferenceArgs* a);

// The model card's recommended_inference under the preset, overridden by the flags given;
// `source` names where the settings came from.
pipeline::Stage1InferenceConfig ResolveInference(const InferenceArgs& a, std::string* source);

// `--ceiling auto|off` (pipeline/ceiling.h): remove a detected ceiling before stage 1.
void AddCeilingFlag(CLI::App& app, std::string* value);
// "auto" -> the default CeilingConfig, "off" -> disabled; anything else throws
// dimr::InvalidArgument naming the flag.
pipeline::CeilingConfig CeilingFromFlag(const std::string& value);

}  // namespace dimr::tools
