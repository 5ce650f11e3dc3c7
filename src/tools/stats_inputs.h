// Inputs of `dimr stats cloud` and `dimr real eval` (tools code on top of geometry and data):
// a PLY file, a ScanNet scene folder, a folder of scene folders or a SynthScan split.
#pragma once

#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::tools {

// A labelled cloud as the statistics and the real-scene evaluation read it.
struct StatsCloud {
  std::string name;
  std::vector<geometry::Vec3> points;
  std::vector<geometry::Color> colors;  // empty when the file has none
  std::vector<int> nyu40;               // per point NYU40 id (0 = unannotated); empty: no labels
  std::vector<int> semantic;            // per point RFS 25 label, 255 = unlabelled; empty: none
  std::vector<int> instance;            // per point instance id (0 = none); empty: none
};

// The clouds INPUT holds, as paths ReadStatsCloud accepts, in name order: a .ply file; a
// ScanNet scene folder (<dir>/<name>_vh_clean_2.ply); a folder of scene folders; a SynthScan
// split (<dir>/scans/). Throws dimr::ParseError naming INPUT when it is none of these.
std::vector<std::string> ListStatsInputs(const std::string& input);

// Reads one. A scene folder with segs.json + aggregation.json goes through
// data::ReadScanNetScene (RFS labels from the raw categories, instances); otherwise the mesh
// vertices and, when present, labels.ply's NYU40 ids (RFS by data::Nyu40ToRfs; no instances).
// A .ply file's optional `label` property is read as NYU40. Throws dimr::ParseError naming the
// file.
StatsCloud ReadStatsCloud(const std::string& path);

}  // namespace dimr::tools
