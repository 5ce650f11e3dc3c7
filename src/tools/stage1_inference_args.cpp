#include "tools/stage1_inference_args.h"

#include "dimr/core/error.h"
#include "dimr/pipeline/model_card.h"

namespace dimr::tools {

void AddInferenceFlags(CLI::App& app, InferenceArgs* a) {
  app.add_option("--model", a->model, "stage-1 weights (dimr train stage1)");
  app.add_option("--preset", a->preset,
                 "fast (one network pass) | accurate (the model card's recommended_inference)");
  a->options = std::make_shared<ConfigOptions<pipeline::Stage1InferenceConfig>>(
      app, pipeline::Stage1InferenceConfig::Fields(),
      "; default: the model card's recommended_inference, else the reference's");
}

pipeline::Stage1InferenceConfig ResolveInference(const InferenceArgs& a, std::string* source) {
  const pipeline::Stage1Preset preset = pipeline::Stage1PresetNames().Parse(a.preset);
  pipeline::Stage1InferenceConfig c = pipeline::Stage1InferenceConfig().WithPreset(preset);
  *source = "defaults (reference passes, no test-time augmentation)";
  if (const auto card = pipeline::ModelCard::LoadIfExists(a.model);
      card && card->has("recommended_inference")) {
    c = pipeline::Stage1InferenceConfig::FromModelCard(*card, preset);
    *source = card->path();
  }
  a.options->Apply(&c);
  c.Validate();
  return c;
}

void AddCeilingFlag(CLI::App& app, std::string* value) {
  app.add_option("--ceiling", *value,
                 "auto: drop a detected ceiling (the topmost large horizontal layer) before stage "
                 "1, its points get no label | off")
      ->capture_default_str();
}

pipeline::CeilingConfig CeilingFromFlag(const std::string& value) {
  pipeline::CeilingConfig c;
  if (value == "auto") return c;
  if (value == "off") {
    c.enabled = false;
    return c;
  }
  throw InvalidArgument("--ceiling: expected auto or off, got '" + value + "'");
}

}  // namespace dimr::tools
