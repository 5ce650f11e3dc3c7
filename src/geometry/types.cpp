#include "dimr/geometry/types.h"

#include <string>
#include <utility>

#include "dimr/geometry/error.h"

namespace dimr::geometry {

int ScalarSize(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUInt8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUInt16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUInt32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

const char* ScalarName(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
      return "char";
    case ScalarType::kUInt8:
      return "uchar";
    case ScalarType::kInt16:
      return "short";
    case ScalarType::kUInt16:
      return "ushort";
    case ScalarType::kInt32:
      return "int";
    case ScalarType::kUInt32:
      return "uint";
    case ScalarType::kFloat32:
      return "float";
    case ScalarType::kFloat64:
      return "double";
  }
  return "?";
}

namespace {

template <typename Attrs>
auto FindIn(Attrs& attrs, const std::string& name) -> decltype(&attrs.front()) {
  for (auto& a : attrs) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

void SetIn(std::vector<VertexAttribute>& attrs, std::size_t n, const std::string& name,
           ScalarType type, std::vector<double> values) {
  if (values.size() != n) {
    throw InvalidArgument("attribute '" + name + "' has " + std::to_string(values.size()) +
                          " values, expected " + std::to_string(n));
  }
  for (auto& a : attrs) {
    if (a.name == name) {
      a.type = type;
      a.values = std::move(values);
      return;
    }
  }
  attrs.push_back(VertexAttribute{name, type, std::move(values)});
}

void CheckAttributes(const std::vector<VertexAttribute>& attrs, std::size_t n,
                     const std::string& what) {
  for (const auto& a : attrs) {
    if (a.values.size() != n) {
      throw InvalidArgument(what + ": attribute '" + a.name + "' has " +
                            std::to_string(a.values.size()) + " values for " + std::to_string(n) +
                            " vertices");
    }
  }
}

void CheckOptional(std::size_t have, std::size_t n, const std::string& what, const char* field) {
  if (have != 0 && have != n) {
    throw InvalidArgument(what + ": " + field + " has " + std::to_string(have) + " entries for " +
                          std::to_string(n) + " vertices");
  }
}

}  // namespace

const VertexAttribute* PointCloud::FindAttribute(const std::string& name) const {
  return FindIn(attributes, name);
}
VertexAttribute* PointCloud::FindAttribute(const std::string& name) {
  return FindIn(attributes, name);
}
void PointCloud::SetAttribute(const std::string& name, ScalarType type,
                              std::vector<double> values) {
  SetIn(attributes, points.size(), name, type, std::move(values));
}

AABB PointCloud::Bounds() const {
  AABB box;
  for (const auto& p : points) box.Extend(p);
  return box;
}

void PointCloud::Validate(const std::string& what) const {
  const std::size_t n = points.size();
  CheckOptional(normals.size(), n, what, "normals");
  CheckOptional(colors.size(), n, what, "colors");
  CheckAttributes(attributes, n, what);
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument(what + ": point " + std::to_string(i) + " is not finite");
    }
  }
}

const VertexAttribute* TriangleMesh::FindAttribute(const std::string& name) const {
  return FindIn(attributes, name);
}
VertexAttribute* TriangleMesh::FindAttribute(const std::string& name) {
  return FindIn(attributes, name);
}
void TriangleMesh::SetAttribute(const std::string& name, ScalarType type,
                                std::vector<double> values) {
  SetIn(attributes, vertices.size(), name, type, std::move(values));
}

AABB TriangleMesh::Bounds() const {
  AABB box;
  for (const auto& v : vertices) box.Extend(v);
  return box;
}

double TriangleMesh::FaceArea(std::size_t f) const {
  const Vec3i& t = faces[f];
  return 0.5 * (vertices[t[1]] - vertices[t[0]]).cross(vertices[t[2]] - vertices[t[0]]).norm();
}

double TriangleMesh::SurfaceArea() const {
  double area = 0.0;
  for (std::size_t f = 0; f < faces.size(); ++f) area += FaceArea(f);
  return area;
}

double TriangleMesh::SignedVolume() const {
  double vol = 0.0;
  for (const auto& t : faces) {
    vol += vertices[t[0]].dot(vertices[t[1]].cross(vertices[t[2]]));
  }
  return vol / 6.0;
}

void TriangleMesh::Append(const TriangleMesh& other) {
  const int offset = static_cast<int>(vertices.size());
  const bool normals = vertex_normals.size() == vertices.size() && !vertices.empty() &&
                       other.vertex_normals.size() == other.vertices.size();
  const bool colors = vertex_colors.size() == vertices.size() && !vertices.empty() &&
                      other.vertex_colors.size() == other.vertices.size();
  const bool was_empty = vertices.empty();
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  for (const auto& f : other.faces) faces.push_back(f.array() + offset);
  if (was_empty) {
    vertex_normals = other.vertex_normals;
    vertex_colors = other.vertex_colors;
    attributes = other.attributes;
    return;
  }
  if (normals) {
    vertex_normals.insert(vertex_normals.end(), other.vertex_normals.begin(),
                          other.vertex_normals.end());
  } else {
    vertex_normals.clear();
  }
  if (colors) {
    vertex_colors.insert(vertex_colors.end(), other.vertex_colors.begin(),
                         other.vertex_colors.end());
  } else {
    vertex_colors.clear();
  }
  std::vector<VertexAttribute> merged;
  for (const auto& a : attributes) {
    for (const auto& b : other.attributes) {
      if (a.name == b.name) {
        VertexAttribute m = a;
        m.values.insert(m.values.end(), b.values.begin(), b.values.end());
        merged.push_back(std::move(m));
      }
    }
  }
  attributes = std::move(merged);
}

void PointCloud::Transform(const Eigen::Matrix3d& R, const Vec3& t) {
  for (auto& p : points) p = R * p + t;
  for (auto& n : normals) n = R * n;
}

void TriangleMesh::Transform(const Eigen::Matrix3d& R, const Vec3& t) {
  for (auto& v : vertices) v = R * v + t;
  for (auto& n : vertex_normals) n = R * n;
}

void TriangleMesh::Validate(const std::string& what) const {
  const std::size_t n = vertices.size();
  CheckOptional(vertex_normals.size(), n, what, "vertex normals");
  CheckOptional(vertex_colors.size(), n, what, "vertex colors");
  CheckAttributes(attributes, n, what);
  for (std::size_t i = 0; i < n; ++i) {
    if (!vertices[i].allFinite()) {
      throw InvalidArgument(what + ": vertex " + std::to_string(i) + " is not finite");
    }
  }
  for (std::size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (faces[f][k] < 0 || static_cast<std::size_t>(faces[f][k]) >= n) {
        throw InvalidArgument(what + ": face " + std::to_string(f) + " references vertex " +
                              std::to_string(faces[f][k]) + " of " + std::to_string(n));
      }
    }
  }
}

}  // namespace dimr::geometry
