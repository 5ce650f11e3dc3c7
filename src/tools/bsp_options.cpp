#include "tools/bsp_options.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "dimr/geometry/error.h"
#include "tools/model_card.h"

namespace dimr::tools {

float ResolveBspDilation(const std::string& model_path, float requested) {
  if (requested >= 0.0f) return requested;
  const std::optional<std::string> value = ReadModelCardValue(model_path, "recommended_dilation");
  if (!value) return 0.0f;
  try {
    std::size_t used = 0;
    const float d = std::stof(*value, &used);
    if (!std::isfinite(d) || d < 0.0f) throw std::invalid_argument("negative");
    if (used != value->size()) throw std::invalid_argument("trailing text");
    return d;
  } catch (const std::exception&) {
    throw ParseError(ModelCardPath(model_path),
                     "recommended_dilation must be a number >= 0, got '" + *value + "'");
  }
}

void AddBspDilationOption(CLI::App& app, float* dilation) {
  app.add_option("--dilation", *dilation,
                 "move every BSP plane outwards by this much (plane units) for occupancy and "
                 "meshes; default: the model card's recommended_dilation, else 0 (reference)");
}

}  // namespace dimr::tools
