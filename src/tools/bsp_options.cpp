#include "tools/bsp_options.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "dimr/geometry/error.h"

namespace dimr::tools {

float ResolveBspDilation(const std::string& model_path, float requested) {
  if (requested >= 0.0f) return requested;
  const std::filesystem::path card = std::filesystem::path(model_path).parent_path() / "model.yaml";
  std::ifstream in(card);
  if (!in) return 0.0f;
  const std::string key = "recommended_dilation:";
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0) continue;
    std::string value = line.substr(key.size());
    value = value.substr(0, value.find('#'));
    try {
      std::size_t used = 0;
      const float d = std::stof(value, &used);
      if (!std::isfinite(d) || d < 0.0f) throw std::invalid_argument("negative");
      if (value.find_first_not_of(" \t\r", used) != std::string::npos) {
        throw std::invalid_argument("trailing text");
      }
      return d;
    } catch (const std::exception&) {
      throw ParseError(card.string(),
                       "recommended_dilation must be a number >= 0, got '" + value + "'");
    }
  }
  return 0.0f;
}

void AddBspDilationOption(CLI::App& app, float* dilation) {
  app.add_option("--dilation", *dilation,
                 "move every BSP plane outwards by this much (plane units) for occupancy and "
                 "meshes; default: the model card's recommended_dilation, else 0 (reference)");
}

}  // namespace dimr::tools
