// Placing object meshes in the world by a 7-DoF box (dimr-method.md sections 6.4 and 9).
// LibTorch-free.
#pragma once

#include <string>

#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/types.h"

namespace dimr::pipeline {

// A decoded BSP mesh (canonical object frame, inside [-1, 1]^3) in the world (section 6.4):
// v_world = Rz(heading) (v * size / 2) + centre. Throws dimr::InvalidArgument for a
// non-finite or negative box.
geometry::TriangleMesh PlaceCanonicalMesh(const geometry::TriangleMesh& canonical,
                                          const geometry::OrientedBox& box);

// A retrieved CAD mesh (canonical axes: x forward, y left, z up; any scale) in the world
// (section 9): per-axis normalised to its bounding box, v <- (v - (min + max) / 2) /
// (max - min) * size (no 1/64 shrink), rotated by Rz(heading), translated to the centre. A
// flat axis (max == min) is left at the box centre. Throws dimr::InvalidArgument for an
// empty mesh or a bad box.
geometry::TriangleMesh PlaceRetrievedMesh(const geometry::TriangleMesh& cad,
                                          const geometry::OrientedBox& box);

// Reads a ShapeNet model_normalized.obj (y up, -z forward) and remaps its axes to the
// canonical frame: (x, y, z) -> (-z, -x, y) (section 9). Throws dimr::ParseError naming the
// file.
geometry::TriangleMesh ReadShapeNetMeshCanonical(const std::string& obj_path);

}  // namespace dimr::pipeline
