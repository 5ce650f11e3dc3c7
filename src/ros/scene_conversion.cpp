// Backend results -> ROS messages (see scene_conversion.h).
#include "dimr/ros/scene_conversion.h"

#include <sensor_msgs/point_cloud2_iterator.h>

#include <cstring>

#include "dimr/ros/marker_builder.h"

namespace dimr::ros1 {
namespace {

std::uint64_t Fnv(std::uint64_t h, const void* data, std::size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

std_msgs::ColorRGBA ColorOf(const BackendInstance& inst, std::uint32_t id,
                            const VisualizationConfig& v) {
  switch (v.color_mode()) {
    case ColorBy::kInstance:
      return InstanceColor(id, v.alpha);
    case ColorBy::kSource:
      return SourceColor(static_cast<int>(inst.source), v.alpha);
    case ColorBy::kClass:
    default:
      return ClassColor(inst.cad_class, v.alpha);
  }
}

std::uint32_t PackRgb(float r, float g, float b) {
  auto u8 = [](float v) {
    return static_cast<std::uint32_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
  };
  return (u8(r) << 16) | (u8(g) << 8) | u8(b);
}

}  // namespace

std::uint64_t MeshHash(const geometry::TriangleMesh& mesh) {
  std::uint64_t h = 1469598103934665603ull;
  if (!mesh.vertices.empty())
    h = Fnv(h, mesh.vertices.data(), mesh.vertices.size() * sizeof(geometry::Vec3));
  if (!mesh.faces.empty())
    h = Fnv(h, mesh.faces.data(), mesh.faces.size() * sizeof(geometry::Vec3i));
  return h;
}

TrackInput TrackOf(const BackendInstance& inst) {
  TrackInput t;
  t.cad_class = inst.cad_class;
  t.box = inst.box;
  t.content_hash = MeshHash(inst.mesh) ^ (static_cast<std::uint64_t>(inst.source) << 60);
  return t;
}

shape_msgs::Mesh ToShapeMesh(const geometry::TriangleMesh& mesh) {
  shape_msgs::Mesh m;
  m.vertices.reserve(mesh.vertices.size());
  for (const geometry::Vec3& v : mesh.vertices) {
    geometry_msgs::Point p;
    p.x = v.x();
    p.y = v.y();
    p.z = v.z();
    m.vertices.push_back(p);
  }
  for (const geometry::Vec3i& f : mesh.faces) {
    shape_msgs::MeshTriangle t;
    t.vertex_indices = {static_cast<std::uint32_t>(f[0]), static_cast<std::uint32_t>(f[1]),
                        static_cast<std::uint32_t>(f[2])};
    m.triangles.push_back(t);
  }
  return m;
}

InstanceMesh ToInstanceMesh(const BackendInstance& inst, std::uint32_t id, std::uint32_t revision,
                            const NodeConfig& config) {
  InstanceMesh m;
  m.id = id;
  m.revision = revision;
  m.class_id = inst.cad_class;
  m.class_name = inst.class_name;
  m.score = inst.score;
  m.num_points = static_cast<std::uint32_t>(inst.support.size());
  m.source = static_cast<std::uint8_t>(inst.source);
  m.pose.position.x = inst.box.center.x();
  m.pose.position.y = inst.box.center.y();
  m.pose.position.z = inst.box.center.z();
  m.pose.orientation.z = std::sin(inst.box.heading / 2);
  m.pose.orientation.w = std::cos(inst.box.heading / 2);
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.bbox_size.x = inst.box.size.x();
  m.bbox_size.y = inst.box.size.y();
  m.bbox_size.z = inst.box.size.z();
  // Vertices into the object frame: R^T (v - c).
  const Eigen::Matrix3d rt = inst.box.Rotation().transpose();
  geometry::TriangleMesh local = inst.mesh;
  for (geometry::Vec3& v : local.vertices) v = rt * (v - inst.box.center);
  m.mesh = ToShapeMesh(local);
  m.color = ColorOf(inst, id, config.visualization);
  if (config.publish_latent_codes)
    m.latent_code.assign(inst.latent.data(), inst.latent.data() + inst.latent.size());
  m.model_id = inst.pool_model_id;
  m.neighbor_ids = inst.neighbour_ids;
  m.neighbor_weights = inst.neighbour_weights;
  m.code_distance = inst.code_distance;
  return m;
}

sensor_msgs::PointCloud2 ToSegmentedCloud(const BackendResult& result,
                                          const std::vector<std::uint32_t>& ids,
                                          const BackendCloud& cloud, const NodeConfig& config,
                                          const std_msgs::Header& header) {
  const std::size_t n = cloud.points.size();
  std::vector<std::uint32_t> inst(n, 0);
  std::vector<std::int32_t> label(n, -1);
  std::vector<std::uint32_t> rgb(n, PackRgb(0.5f, 0.5f, 0.5f));
  if (!cloud.colors.empty())
    for (std::size_t i = 0; i < n; ++i)
      rgb[i] = PackRgb(cloud.colors[i].x(), cloud.colors[i].y(), cloud.colors[i].z());
  for (std::size_t k = 0; k < result.instances.size() && k < ids.size(); ++k) {
    const BackendInstance& b = result.instances[k];
    const std_msgs::ColorRGBA c = ColorOf(b, ids[k], config.visualization);
    const std::uint32_t packed = PackRgb(c.r, c.g, c.b);
    for (int s : b.support) {
      if (s < 0 || static_cast<std::size_t>(s) >= n) continue;
      inst[s] = ids[k];
      label[s] = b.cad_class;
      rgb[s] = packed;
    }
  }
  sensor_msgs::PointCloud2 msg;
  msg.header = header;
  sensor_msgs::PointCloud2Modifier mod(msg);
  mod.setPointCloud2Fields(
      6, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32, "z", 1,
      sensor_msgs::PointField::FLOAT32, "rgb", 1, sensor_msgs::PointField::FLOAT32, "instance", 1,
      sensor_msgs::PointField::UINT32, "label", 1, sensor_msgs::PointField::INT32);
  mod.resize(n);
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(n);
  msg.is_dense = true;
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  sensor_msgs::PointCloud2Iterator<std::uint32_t> c(msg, "rgb"), id(msg, "instance");
  sensor_msgs::PointCloud2Iterator<std::int32_t> l(msg, "label");
  for (std::size_t i = 0; i < n; ++i, ++x, ++y, ++z, ++c, ++id, ++l) {
    *x = cloud.points[i].x();
    *y = cloud.points[i].y();
    *z = cloud.points[i].z();
    *c = rgb[i];
    *id = inst[i];
    *l = label[i];
  }
  return msg;
}

sensor_msgs::PointCloud2 SupportCloud(const BackendInstance& inst, const BackendCloud& cloud,
                                      const std_msgs::Header& header) {
  std::vector<int> idx;
  for (int s : inst.support)
    if (s >= 0 && static_cast<std::size_t>(s) < cloud.points.size()) idx.push_back(s);
  sensor_msgs::PointCloud2 msg;
  msg.header = header;
  sensor_msgs::PointCloud2Modifier mod(msg);
  mod.setPointCloud2FieldsByString(2, "xyz", "rgb");
  mod.resize(idx.size());
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(idx.size());
  msg.is_dense = true;
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  sensor_msgs::PointCloud2Iterator<std::uint8_t> r(msg, "r"), g(msg, "g"), b(msg, "b");
  for (std::size_t k = 0; k < idx.size(); ++k, ++x, ++y, ++z, ++r, ++g, ++b) {
    const Eigen::Vector3f& p = cloud.points[idx[k]];
    *x = p.x();
    *y = p.y();
    *z = p.z();
    const Eigen::Vector3f c =
        cloud.colors.empty() ? Eigen::Vector3f(0.5f, 0.5f, 0.5f) : cloud.colors[idx[k]];
    *r = static_cast<std::uint8_t>(std::lround(std::clamp(c.x(), 0.0f, 1.0f) * 255));
    *g = static_cast<std::uint8_t>(std::lround(std::clamp(c.y(), 0.0f, 1.0f) * 255));
    *b = static_cast<std::uint8_t>(std::lround(std::clamp(c.z(), 0.0f, 1.0f) * 255));
  }
  return msg;
}

const char* ShapeModeName(ShapeMode mode) {
  switch (mode) {
    case ShapeMode::kGeneration:
      return "generation";
    case ShapeMode::kProjection:
      return "projection";
    case ShapeMode::kRetrieval:
      return "retrieval";
  }
  return "?";
}

}  // namespace dimr::ros1
