// ScanNet scene folders: writer and reader (SynthScene <-> files, exact round trip).
//
// A scene folder `<dir>/<scene>/` holds
//   <scene>_vh_clean_2.ply                 vertices: float x y z, uchar red green blue alpha
//   <scene>_vh_clean_2.labels.ply          the same + ushort `label` = NYU40 id (ScanNet's
//                                          convention; 0 = unannotated)
//   <scene>_vh_clean_2.0.010000.segs.json  {"sceneId", "params", "segIndices": [per vertex]}
//   <scene>.aggregation.json               {"sceneId", "appId", "segGroups": [{"id",
//                                          "objectId", "segments", "label"}], "segmentsFile"}
//   <scene>.txt                            "axisAlignment = m00 m01 ... m33" (row-major 4x4),
//                                          "sceneType = ..."
//   <scene>.synthscan.json                 SynthScan only: per-instance CAD ids, 9-DoF
//                                          alignment, 7-DoF box, point count, visible fraction
// Semantic labels (25-class RFS) are recovered like the DIMR reference does: from the raw
// category of each segGroup (RfsFromCategory); the NYU40 ids of labels.ply are used only
// where a scene has no aggregation. Instance id = objectId + 1.
#pragma once

#include <string>

#include "dimr/data/synthscan.h"

namespace dimr::data {

// Raw ScanNet category -> RFS id (0..24) or -1 (ignored: clutter, unknown names).
int RfsFromCategory(const std::string& raw_category);
// RFS id -> NYU40 id written to labels.ply (0 for -1 / ignore).
int RfsToNyu40(int rfs);
// NYU40 id -> RFS id, -1 where NYU40 has no RFS counterpart (best effort, lossy).
int Nyu40ToRfs(int nyu40);

// Writes `<scans_dir>/<scene.name>/...`; creates the folder. Throws dimr::Error naming the path
// when a file cannot be written, dimr::InvalidArgument for an inconsistent scene.
void WriteScanNetScene(const std::string& scans_dir, const SynthScene& scene);

// Reads the scene folder `scene_dir` (its last path component is the scene name). Throws
// dimr::ParseError naming the file for missing / malformed files or inconsistent counts.
SynthScene ReadScanNetScene(const std::string& scene_dir);

}  // namespace dimr::data
