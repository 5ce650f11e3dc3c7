// Inputs and outputs of `dimr reconstruct` (torch-free tools code on top of geometry, data,
// eval and pipeline).
//
// Inputs: a bare PLY / PCD cloud (a user's scan: no labels, any extent), a ScanNet scene folder
// (`<scene>/<scene>_vh_clean_2.ply`; segs / aggregation files are not needed; the
// `<scene>.txt` axisAlignment is applied when present, as the evaluation GT lives in the
// axis-aligned frame), a folder of scene folders (ScanNet `scans/`), or a SynthScan split
// (a folder with `scans/`).
//
// Outputs in DIR: `meshes/{scene}_{k}_{class}_{score:.4f}.ply` (the evaluation layout, input
// frame), `{scene}.json` (SceneResult JSON: what `dimr eval --pred DIR` reads, plus boxes,
// sources, pool models, support points, timings), `vis/{scene}.ply` (every instance mesh in
// one PLY, coloured by instance) and `vis/{scene}.png` (a perspective 3-D picture: input
// points, meshes, box edges).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"
#include "dimr/pipeline/scene_result.h"

namespace dimr::tools {

struct InputScene {
  std::string name;  // scene name (ScanNet folder name or the file stem)
  std::string path;  // cloud file read
  std::string kind;  // "cloud", "scannet"
  Eigen::Matrix4d alignment = Eigen::Matrix4d::Identity();  // applied to the file's points
  geometry::PointCloud cloud;                               // what the Reconstructor gets
};

// The scenes an INPUT path holds (in name order), without reading their clouds. Throws
// dimr::ParseError naming the path when it is none of the accepted kinds.
std::vector<InputScene> ListInputScenes(const std::string& input);
// Reads the cloud of a listed scene (and applies its alignment).
void LoadInputScene(InputScene* scene);

// Reference name of an instance mesh: "{scene}_{k}_{class}_{score:.4f}.ply".
std::string InstanceMeshName(const std::string& scene, int k, int cad_class, double score);

struct WrittenScene {
  std::vector<std::string> meshes;  // paths
  std::string json, combined_ply, picture;
};
// Writes the outputs listed above for one scene into `out_dir` (created). `picture` false
// skips the PNG; `gt_meshes` (may be null) adds a third "ground truth" panel to it. Throws
// dimr::Error naming the path that cannot be written.
WrittenScene WriteSceneOutputs(const std::string& out_dir, const InputScene& scene,
                               const pipeline::SceneResult& result, bool picture = true,
                               const std::vector<geometry::TriangleMesh>* gt_meshes = nullptr);
// The GT meshes of `scene` in an evaluation GT folder (`{scene}_{k}_{class}_1.ply`), in name
// order; empty when there are none.
std::vector<geometry::TriangleMesh> ReadSceneGtMeshes(const std::string& gt_dir,
                                                      const std::string& scene);

}  // namespace dimr::tools
