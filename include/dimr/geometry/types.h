// Core geometric containers: point clouds and triangle meshes (Eigen, double precision).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace dimr::geometry {

using Vec3 = Eigen::Vector3d;
using Vec3f = Eigen::Vector3f;
using Vec3i = Eigen::Vector3i;
using Color = Eigen::Matrix<std::uint8_t, 3, 1>;

// Scalar type of a per-vertex attribute (mirrors the PLY scalar types so that files
// round-trip with their original property types).
enum class ScalarType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

// Size in bytes of one value of `type`.
int ScalarSize(ScalarType type);
// PLY name of the type ("uchar", "float", ...).
const char* ScalarName(ScalarType type);

// An extra named per-vertex scalar property (e.g. ScanNet's `label`). Values are stored
// as double, which represents every PLY scalar type exactly.
struct VertexAttribute {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  std::vector<double> values;
};

// Axis-aligned bounding box. Empty when min > max on any axis.
struct AABB {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 max = Vec3::Constant(-std::numeric_limits<double>::infinity());

  bool Empty() const { return (min.array() > max.array()).any(); }
  void Extend(const Vec3& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void Extend(const AABB& b) {
    min = min.cwiseMin(b.min);
    max = max.cwiseMax(b.max);
  }
  Vec3 Center() const { return 0.5 * (min + max); }
  Vec3 Extent() const { return Empty() ? Vec3::Zero() : Vec3(max - min); }
  double Volume() const {
    const Vec3 e = Extent();
    return e.x() * e.y() * e.z();
  }
  bool Contains(const Vec3& p) const {
    return (p.array() >= min.array()).all() && (p.array() <= max.array()).all();
  }
};

// A point cloud with optional per-point normals, colours and extra attributes. Optional
// arrays are either empty or exactly as long as `points`.
struct PointCloud {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;
  std::vector<Color> colors;
  std::vector<VertexAttribute> attributes;

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool HasNormals() const { return !normals.empty(); }
  bool HasColors() const { return !colors.empty(); }

  // Attribute by name, or nullptr.
  const VertexAttribute* FindAttribute(const std::string& name) const;
  VertexAttribute* FindAttribute(const std::string& name);
  // Adds (or replaces) an attribute; `values` must have size() entries.
  void SetAttribute(const std::string& name, ScalarType type, std::vector<double> values);

  AABB Bounds() const;
  // Applies p -> R p + t to the points (and R to the normals), as TriangleMesh::Transform.
  void Transform(const Eigen::Matrix3d& R, const Vec3& t = Vec3::Zero());
  // Throws dimr::InvalidArgument naming `what` if an optional array has the wrong length
  // or any coordinate is not finite.
  void Validate(const std::string& what) const;
};

// An indexed triangle mesh. Optional per-vertex arrays are empty or match `vertices`.
struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<Vec3i> faces;
  std::vector<Vec3> vertex_normals;
  std::vector<Color> vertex_colors;
  std::vector<VertexAttribute> attributes;

  bool empty() const { return faces.empty(); }
  const VertexAttribute* FindAttribute(const std::string& name) const;
  VertexAttribute* FindAttribute(const std::string& name);
  void SetAttribute(const std::string& name, ScalarType type, std::vector<double> values);

  // Bounds over all vertices (referenced or not).
  AABB Bounds() const;
  // Sum of triangle areas.
  double SurfaceArea() const;
  // Signed volume by the divergence theorem (positive for outward-oriented closed meshes).
  double SignedVolume() const;
  // Area of face f.
  double FaceArea(std::size_t f) const;
  // Appends another mesh (indices offset). Attributes are dropped unless both have them.
  void Append(const TriangleMesh& other);
  // Applies p -> R p + t to vertices (and R to normals).
  void Transform(const Eigen::Matrix3d& R, const Vec3& t);
  // Throws dimr::InvalidArgument naming `what` on out-of-range indices, non-finite
  // vertices, or optional arrays of the wrong length.
  void Validate(const std::string& what) const;
};

}  // namespace dimr::geometry
