// Stage-1 samples from ScanNet-format scene folders (torch-free; shared by the `dimr stage1 …`
// and `dimr train stage1` commands).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "dimr/core/config_fields.h"
#include "dimr/data/scan2cad_io.h"
#include "dimr/data/scan2cad_relabel.h"
#include "dimr/data/synthscan.h"
#include "dimr/nn/stage1_data.h"

namespace dimr::tools {

// One scene as a stage-1 sample: float points, colours in [0, 1], semantic 255 / -1 / out of
// range -> nn::kStage1Ignore, 1-based instance ids -> indices into `instances` (the scene's
// instance order; 0 -> -1). Per instance: semantic = rfs_class (-1 -> ignore), cad_class,
// has_heading = cad_class >= 0, heading = box.heading. Throws dimr::InvalidArgument naming the
// scene for a point whose instance id is not listed.
nn::Stage1Sample Stage1SampleFromScene(const data::SynthScene& scene);

// Scan2CAD annotations (full_annotations.json entries) by id_scan.
using Scan2CadByScene = std::map<std::string, data::Scan2CadScene>;
// Reads full_annotations.json into a map; throws dimr::ParseError naming the file for a
// malformed file or a scan listed twice.
Scan2CadByScene ReadScan2CadByScene(const std::string& path);

// What LoadStage1Scenes did with the scenes.
struct Stage1LoadReport {
  int relabelled = 0;          // real (or forced) scenes re-labelled from their Scan2CAD entry
  int kept_synthscan = 0;      // SynthScan scenes with a Scan2CAD entry that kept their own boxes
  int without_scan2cad = 0;    // real scenes without a Scan2CAD entry (point boxes, see below)
  data::RelabelStats relabel;  // summed over the re-labelled scenes
};

// Reads `scans_dir/<name>` for every name (empty: every sub-folder, sorted) with
// data::ReadScanNetScene on `threads` threads (<= 0: all cores), in the order of the names.
// Real ScanNet scenes (no <scene>.synthscan.json) are brought into their axis-aligned frame
// (data::AxisAlignScene; instance boxes recomputed from the points). With `scan2cad`, a real
// scene that has an entry is re-labelled with data::RelabelWithScan2Cad before it becomes a
// sample; SynthScan scenes keep their own CAD boxes unless `force_scan2cad`. `report` (may be
// null) receives the counts. Throws dimr::ParseError naming the scene folder (the first
// failing one in name order).
std::vector<nn::Stage1Sample> LoadStage1Scenes(const std::string& scans_dir,
                                               const std::vector<std::string>& scene_names,
                                               int threads,
                                               const Scan2CadByScene* scan2cad = nullptr,
                                               bool force_scan2cad = false,
                                               Stage1LoadReport* report = nullptr);

// Split of a scene by its name (SynthScan's ranges, data::SceneName): "scene0000".."scene4999"
// train, "scene5000".."scene7999" val, "scene8000".. test; anything else other.
enum class SceneSplit { kTrain, kVal, kTest, kOther };
const config::EnumNames<SceneSplit>& SceneSplitNames();  // train, val, test, other
SceneSplit Stage1SplitOf(const std::string& name);
// The name of Stage1SplitOf(name).
std::string Stage1SplitOfScene(const std::string& name);

}  // namespace dimr::tools
