#include "tools/bsp_options.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/bsp_mesher.h"
#include "tools/model_card.h"

namespace dimr::tools {
namespace {

float ResolveCardValue(const std::string& model_path, const char* key, float requested) {
  if (requested >= 0.0f) return requested;
  const std::optional<std::string> value = ReadModelCardValue(model_path, key);
  if (!value) return 0.0f;
  try {
    std::size_t used = 0;
    const float d = std::stof(*value, &used);
    if (!std::isfinite(d) || d < 0.0f) throw std::invalid_argument("negative");
    if (used != value->size()) throw std::invalid_argument("trailing text");
    return d;
  } catch (const std::exception&) {
    throw ParseError(ModelCardPath(model_path),
                     std::string(key) + " must be a number >= 0, got '" + *value + "'");
  }
}

}  // namespace

BspDilation ApplyBspDilation(const std::string& model_path, const BspDilation& requested,
                             pipeline::BspMeshOptions* options) {
  BspDilation d;
  d.plane = ResolveCardValue(model_path, "recommended_dilation", requested.plane);
  d.distance = ResolveCardValue(model_path, "recommended_distance_dilation", requested.distance);
  options->dilation = d.plane;
  options->distance_dilation = d.distance;
  return d;
}

void AddBspDilationOption(CLI::App& app, BspDilation* dilation) {
  app.add_option("--dilation", dilation->plane,
                 "move every BSP plane outwards by this much (plane units) for occupancy and "
                 "meshes; default: the model card's recommended_dilation, else 0 (reference)");
  app.add_option("--distance-dilation", dilation->distance,
                 "move every BSP face outwards by this distance (normalised cube [-1, 1]^3); "
                 "default: the model card's recommended_distance_dilation, else 0");
}

}  // namespace dimr::tools
