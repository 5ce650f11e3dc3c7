// Evaluation inputs: the reference's folder layout and file naming (spec
// ../shared/reference/dimr-metrics.md sections 1.2-1.5) and dimr's own SceneResult JSON.
//
// Reference layout: every `*.ply` in the prediction folder is one detection named
// `{scene}_{k}_{class}_{score}.ply` (scene = first 12 characters, class = token [3] split on
// '_' with `trash` -> `trash_bin`, score = last token); GT meshes are `{scene}_{k}_{class}_1.ply`.
//
// SceneResult JSON (one file per scene, `*.json` in the prediction folder):
//   {"scene": "scene0011_00",
//    "instances": [{"id": 3, "class": "chair", "score": 0.9123, "mesh": "meshes/a.ply",
//                   "points": [17, 18, 42]}]}
// `mesh` is relative to the JSON file's folder (.ply or .obj); `id` and `points` (indices of
// the instance's input points) are optional. Instances keep their array order.
//
// PCR ground truth (`--gt-points DIR`): one vertex PLY per scene, `{scene}.ply`, with x, y, z
// and two integer vertex properties: the RFS semantic label (`semantic_label`,
// `semantic_labels` or `label`; 255 = ignore) and the 1-based instance label
// (`instance_label`, `instance_labels` or `instance`; 0 = none) - the contents of the
// reference's data.npz.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::eval {

struct MeshRecord {
  std::string scene;
  int cls = -1;  // CAD class id
  double score = 1.0;
  std::string path;                                    // mesh file (empty when `mesh` is given)
  std::string name;                                    // sort key within the scene (file basename)
  std::shared_ptr<const geometry::TriangleMesh> mesh;  // in-memory mesh (bench, tests)
};

struct PointsGt {
  std::string scene;
  int cls = -1;
  std::vector<geometry::Vec3> points;
};

// Parses a reference file name (path or basename). Throws dimr::ParseError naming the file on
// a malformed name, a missing/unknown class token or a non-numeric score.
MeshRecord ParseReferenceName(const std::string& path);

// All detections in `dir`: `*.ply` files by reference name and `*.json` SceneResult files,
// sorted by (scene, name) - the reference's base order. Throws dimr::ParseError for a missing
// folder or bad file.
std::vector<MeshRecord> ListMeshFolder(const std::string& dir);
std::vector<MeshRecord> ReadSceneResultJson(const std::string& path);
// Parses SceneResult JSON text; mesh paths are resolved against `folder`; `source` names the
// data in errors (dimr::ParseError for malformed JSON, missing fields, unknown classes).
std::vector<MeshRecord> ParseSceneResultJson(const std::string& text, const std::string& source,
                                             const std::string& folder);
void WriteSceneResultJson(const std::string& path, const std::string& scene,
                          const std::vector<MeshRecord>& instances,
                          const std::vector<std::vector<int>>& points = {});

// PCR GT instances of one scene from its point PLY (spec section 5): instance id = label - 1,
// class = RFS label of the instance's lowest-index vertex mapped to CAD (skipped if 255 or
// non-CAD), points = all its vertices.
std::vector<PointsGt> ReadPcrGtScene(const std::string& path, const std::string& scene);
// The same from arrays.
std::vector<PointsGt> PcrGtFromArrays(const std::string& scene,
                                      const std::vector<geometry::Vec3>& points,
                                      const std::vector<int>& semantic_rfs,
                                      const std::vector<int>& instance_1based);
// PCR GT instances of one scene from the reference's processed data
// (`processed_data/<scene>/data.npz`: mesh_vertices N x 6 (or N x 3), semantic_labels,
// instance_labels).
std::vector<PointsGt> ReadPcrGtNpz(const std::string& path, const std::string& scene);
// All `{scene}.ply` files of a folder, or (the reference layout) every `{scene}/data.npz`
// below it; `scenes` receives the scene list (sorted). With `scene_list` (e.g. the
// reference's val.txt, one scene per line) exactly those scenes are read, a missing one is
// an error naming it.
std::vector<PointsGt> LoadPcrGtFolder(const std::string& dir, std::vector<std::string>* scenes,
                                      const std::string& scene_list = "");

}  // namespace dimr::eval
