// The save_scene service's files: one mesh per instance (in the fixed frame, PLY or OBJ) plus
// scene.json with ids, classes, scores, sources, poses, boxes, pool model ids and file names.
#pragma once

#include <string>
#include <vector>

#include "dimr/SceneMeshes.h"
#include "dimr/geometry/types.h"

namespace dimr::ros1 {

// An InstanceMesh's mesh (object frame) mapped into the scene frame by its pose.
geometry::TriangleMesh InstanceMeshInSceneFrame(const InstanceMesh& instance);

// Writes the files into `directory` (created when missing) and returns their paths, scene.json
// last. `format` is "ply" or "obj". Throws dimr::InvalidArgument for another format or an
// empty directory, dimr::Error naming the path when a file cannot be written.
std::vector<std::string> SaveSceneFiles(const SceneMeshes& scene, const std::string& directory,
                                        const std::string& format);

}  // namespace dimr::ros1
