#include "tools/bsp_options.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/bsp_mesher.h"

namespace dimr::tools {

BspDilation ApplyBspDilation(const std::string& model_path, const BspDilation& requested,
                             pipeline::BspMeshOptions* options) {
  const pipeline::BspMeshOptions card =
      pipeline::BspDecodingOptions(model_path, {requested.plane, requested.distance});
  options->dilation = card.dilation;
  options->distance_dilation = card.distance_dilation;
  return {card.dilation, card.distance_dilation};
}

void AddBspDilationOption(CLI::App& app, BspDilation* dilation) {
  app.add_option("--dilation", dilation->plane,
                 "move every BSP plane outwards by this much (plane units) for occupancy and "
                 "meshes; default: the model card's recommended_dilation, else 0 (reference)");
  app.add_option("--distance-dilation", dilation->distance,
                 "move every BSP face outwards by this distance (normalised cube [-1, 1]^3); "
                 "default: the model card's recommended_distance_dilation, else 0");
}

nn::BspDataset LoadBspTrainingSets(const std::vector<std::string>& specs) {
  if (specs.empty()) throw InvalidArgument("--train: no training dataset given");
  nn::BspDataset all;
  bool first = true;
  for (const std::string& spec : specs) {
    std::string path = spec;
    int repeat = 1;
    const std::size_t at = spec.rfind('@');
    if (at != std::string::npos) {
      const std::string count = spec.substr(at + 1);
      const bool digits =
          !count.empty() && count.size() <= 3 &&
          std::all_of(count.begin(), count.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
      if (!digits || std::stoi(count) < 1 || std::stoi(count) > 100) {
        throw InvalidArgument("--train '" + spec +
                              "': the repeat count after '@' must be an integer in 1..100");
      }
      repeat = std::stoi(count);
      path = spec.substr(0, at);
    }
    const nn::BspDataset one = nn::BspDataset::Load(path);
    if (first) all.resolution = one.resolution;
    first = false;
    if (one.resolution != all.resolution) {
      throw InvalidArgument("--train '" + path + "' has resolution " +
                            std::to_string(one.resolution) + ", the first dataset " +
                            std::to_string(all.resolution));
    }
    for (int r = 0; r < repeat; ++r) all.Append(one);
  }
  return all;
}

}  // namespace dimr::tools
