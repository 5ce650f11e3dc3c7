// save_scene files (see scene_files.h).
#include "dimr/ros/scene_files.h"

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::ros1 {
namespace {

namespace fs = std::filesystem;

const char* SourceName(int source) {
  switch (source) {
    case InstanceMesh::SOURCE_GENERATED:
      return "generated";
    case InstanceMesh::SOURCE_PROJECTED:
      return "projected";
    case InstanceMesh::SOURCE_RETRIEVED:
      return "retrieved";
    default:
      return "unknown";
  }
}

Eigen::Isometry3d PoseOf(const geometry_msgs::Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  if (q.norm() < 1e-9) q = Eigen::Quaterniond::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

}  // namespace

geometry::TriangleMesh InstanceMeshInSceneFrame(const InstanceMesh& inst) {
  const Eigen::Isometry3d T = PoseOf(inst.pose);
  geometry::TriangleMesh m;
  m.vertices.reserve(inst.mesh.vertices.size());
  for (const geometry_msgs::Point& v : inst.mesh.vertices)
    m.vertices.push_back(T * Eigen::Vector3d(v.x, v.y, v.z));
  for (const shape_msgs::MeshTriangle& t : inst.mesh.triangles) {
    const auto& i = t.vertex_indices;
    if (i[0] < m.vertices.size() && i[1] < m.vertices.size() && i[2] < m.vertices.size())
      m.faces.emplace_back(static_cast<int>(i[0]), static_cast<int>(i[1]), static_cast<int>(i[2]));
  }
  return m;
}

std::vector<std::string> SaveSceneFiles(const SceneMeshes& scene, const std::string& directory,
                                        const std::string& format) {
  if (directory.empty()) throw InvalidArgument("save_scene: directory is empty");
  if (format != "ply" && format != "obj")
    throw InvalidArgument("save_scene: format '" + format + "' is not ply or obj");
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) throw Error("save_scene: cannot create '" + directory + "': " + ec.message());

  std::vector<std::string> files;
  nlohmann::json j;
  j["frame_id"] = scene.header.frame_id;
  j["stamp"] = scene.header.stamp.toSec();
  j["mode"] = scene.mode == SceneMeshes::MODE_GENERATION
                  ? "generation"
                  : (scene.mode == SceneMeshes::MODE_PROJECTION ? "projection" : "retrieval");
  j["scene_revision"] = scene.scene_revision;
  j["model_version"] = scene.model_version;
  j["pool_id"] = scene.pool_id;
  j["input_points"] = scene.input_points;
  j["processing_s"] = scene.processing_time;
  j["latency_s"] = scene.latency;
  j["instances"] = nlohmann::json::array();
  for (const InstanceMesh& inst : scene.instances) {
    nlohmann::json e;
    e["id"] = inst.id;
    e["class_id"] = inst.class_id;
    e["class_name"] = inst.class_name;
    e["score"] = inst.score;
    e["source"] = SourceName(inst.source);
    e["num_points"] = inst.num_points;
    e["position"] = {inst.pose.position.x, inst.pose.position.y, inst.pose.position.z};
    e["orientation_xyzw"] = {inst.pose.orientation.x, inst.pose.orientation.y,
                             inst.pose.orientation.z, inst.pose.orientation.w};
    e["bbox_size"] = {inst.bbox_size.x, inst.bbox_size.y, inst.bbox_size.z};
    e["model_id"] = inst.model_id;
    e["triangles"] = inst.mesh.triangles.size();
    if (!inst.mesh.triangles.empty()) {
      const std::string name = "instance_" + std::to_string(inst.id) + "_" +
                               (inst.class_name.empty() ? "object" : inst.class_name) + "." +
                               format;
      const std::string path = (fs::path(directory) / name).string();
      const geometry::TriangleMesh mesh = InstanceMeshInSceneFrame(inst);
      if (format == "ply")
        geometry::WritePly(path, mesh);
      else
        geometry::WriteObj(path, mesh);
      files.push_back(path);
      e["mesh_file"] = name;
    } else {
      e["mesh_file"] = nullptr;
    }
    j["instances"].push_back(e);
  }
  const std::string json_path = (fs::path(directory) / "scene.json").string();
  std::ofstream out(json_path);
  if (!out) throw Error("save_scene: cannot write '" + json_path + "'");
  out << j.dump(2) << "\n";
  if (!out) throw Error("save_scene: writing '" + json_path + "' failed");
  files.push_back(json_path);
  return files;
}

}  // namespace dimr::ros1
