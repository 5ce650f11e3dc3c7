#include "dimr/pipeline/placement.h"

#include <cmath>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"

namespace dimr::pipeline {
namespace {

void CheckBox(const geometry::OrientedBox& box, const char* what) {
  if (!box.center.allFinite() || !box.size.allFinite() || !std::isfinite(box.heading) ||
      (box.size.array() < 0).any()) {
    throw InvalidArgument(std::string(what) + ": box is not finite or has a negative size");
  }
}

geometry::TriangleMesh Place(const geometry::TriangleMesh& in, const geometry::Vec3& offset,
                             const geometry::Vec3& scale, const geometry::OrientedBox& box) {
  geometry::TriangleMesh out;
  out.faces = in.faces;
  out.vertex_colors = in.vertex_colors;
  const Eigen::Matrix3d r = box.Rotation();
  out.vertices.reserve(in.vertices.size());
  for (const auto& v : in.vertices) {
    out.vertices.push_back(r * ((v - offset).cwiseProduct(scale)) + box.center);
  }
  return out;
}

}  // namespace

geometry::TriangleMesh PlaceCanonicalMesh(const geometry::TriangleMesh& canonical,
                                          const geometry::OrientedBox& box) {
  CheckBox(box, "PlaceCanonicalMesh");
  return Place(canonical, geometry::Vec3::Zero(), 0.5 * box.size, box);
}

geometry::TriangleMesh PlaceRetrievedMesh(const geometry::TriangleMesh& cad,
                                          const geometry::OrientedBox& box) {
  CheckBox(box, "PlaceRetrievedMesh");
  if (cad.vertices.empty()) throw InvalidArgument("PlaceRetrievedMesh: the CAD mesh is empty");
  const geometry::AABB b = cad.Bounds();
  if (!b.min.allFinite() || !b.max.allFinite()) {
    throw InvalidArgument("PlaceRetrievedMesh: the CAD mesh has non-finite vertices");
  }
  const geometry::Vec3 extent = b.Extent();
  geometry::Vec3 scale;
  for (int a = 0; a < 3; ++a) scale[a] = extent[a] > 0 ? box.size[a] / extent[a] : 0.0;
  return Place(cad, b.Center(), scale, box);
}

geometry::TriangleMesh ReadShapeNetMeshCanonical(const std::string& obj_path) {
  geometry::TriangleMesh m = geometry::ReadMesh(obj_path);
  for (auto& v : m.vertices) v = geometry::Vec3(-v.z(), -v.x(), v.y());
  m.vertex_normals.clear();
  return m;
}

}  // namespace dimr::pipeline
