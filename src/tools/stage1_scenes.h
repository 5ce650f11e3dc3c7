// Stage-1 samples from ScanNet-format scene folders (torch-free; shared by the `dimr stage1 …`
// and `dimr train stage1` commands).
#pragma once

#include <string>
#include <vector>

#include "dimr/data/synthscan.h"
#include "dimr/nn/stage1_data.h"

namespace dimr::tools {

// One scene as a stage-1 sample: float points, colours in [0, 1], semantic 255 / -1 / out of
// range -> nn::kStage1Ignore, 1-based instance ids -> indices into `instances` (the scene's
// instance order; 0 -> -1). Per instance: semantic = rfs_class (-1 -> ignore), cad_class,
// has_heading = cad_class >= 0, heading = box.heading. Throws dimr::InvalidArgument naming the
// scene for a point whose instance id is not listed.
nn::Stage1Sample Stage1SampleFromScene(const data::SynthScene& scene);

// Reads `scans_dir/<name>` for every name (empty: every sub-folder, sorted) with
// data::ReadScanNetScene on `threads` threads (<= 0: all cores), in the order of the names.
// Throws dimr::ParseError naming the scene folder (the first failing one in name order).
std::vector<nn::Stage1Sample> LoadStage1Scenes(const std::string& scans_dir,
                                               const std::vector<std::string>& scene_names,
                                               int threads);

// Split of a scene by its name (SynthScan's ranges, data::SceneName): "scene0000".."scene4999"
// train, "scene5000".."scene7999" val, "scene8000".. test; anything else "other".
std::string Stage1SplitOfScene(const std::string& name);

}  // namespace dimr::tools
