#include "tools/bsp_options.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/bsp_mesher.h"
#include "tools/repeated_set.h"

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
    const RepeatedSet set = ParseRepeatedSet(spec, "--train");
    const std::string& path = set.path;
    const nn::BspDataset one = nn::BspDataset::Load(path);
    if (first) all.resolution = one.resolution;
    first = false;
    if (one.resolution != all.resolution) {
      throw InvalidArgument("--train '" + path + "' has resolution " +
                            std::to_string(one.resolution) + ", the first dataset " +
                            std::to_string(all.resolution));
    }
    for (int r = 0; r < set.repeat; ++r) all.Append(one);
  }
  return all;
}

}  // namespace dimr::tools
