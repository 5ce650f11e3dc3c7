// save_scene: meshes written in the scene frame (pose applied) and scene.json, read back.
#include "dimr/ros/scene_files.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::ros1 {
namespace {

namespace fs = std::filesystem;

InstanceMesh BoxInstance(std::uint32_t id, double x, double yaw) {
  InstanceMesh inst;
  inst.id = id;
  inst.class_id = 0;
  inst.class_name = "table";
  inst.score = 0.75f;
  inst.pose.position.x = x;
  inst.pose.position.z = 0.4;
  inst.pose.orientation.z = std::sin(yaw / 2);
  inst.pose.orientation.w = std::cos(yaw / 2);
  inst.bbox_size.x = 2.0;
  inst.bbox_size.y = 1.0;
  inst.bbox_size.z = 0.8;
  geometry::OrientedBox b;
  b.size = geometry::Vec3(2.0, 1.0, 0.8);
  const geometry::TriangleMesh m = b.ToMesh();  // object frame
  for (const auto& v : m.vertices) {
    geometry_msgs::Point p;
    p.x = v.x();
    p.y = v.y();
    p.z = v.z();
    inst.mesh.vertices.push_back(p);
  }
  for (const auto& f : m.faces) {
    shape_msgs::MeshTriangle t;
    t.vertex_indices = {static_cast<std::uint32_t>(f[0]), static_cast<std::uint32_t>(f[1]),
                        static_cast<std::uint32_t>(f[2])};
    inst.mesh.triangles.push_back(t);
  }
  return inst;
}

TEST(SceneFiles, MeshesInSceneFrameAndJson) {
  SceneMeshes scene;
  scene.header.frame_id = "map";
  scene.header.stamp.sec = 12;
  scene.instances = {BoxInstance(3, 1.0, M_PI / 2), BoxInstance(8, -2.0, 0.0)};
  scene.input_points = 4321;
  scene.processing_time = 1.5f;
  scene.latency = 2.25f;
  scene.instances[1].mesh.triangles.clear();  // an instance without a mesh: JSON only
  const fs::path dir = fs::temp_directory_path() / ("dimr_save_" + std::to_string(getpid()));
  const auto files = SaveSceneFiles(scene, dir.string(), "ply");
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(fs::path(files[0]).filename(), "instance_3_table.ply");
  const geometry::TriangleMesh m = geometry::ReadPlyMesh(files[0]);
  ASSERT_EQ(m.faces.size(), 12u);
  // Rotated by 90 deg: the 2 m side now runs along y, centred at (1, 0, 0.4).
  const geometry::AABB bb = m.Bounds();
  EXPECT_NEAR(bb.Extent().x(), 1.0, 1e-5);
  EXPECT_NEAR(bb.Extent().y(), 2.0, 1e-5);
  EXPECT_NEAR(bb.Center().x(), 1.0, 1e-5);
  EXPECT_NEAR(bb.Center().z(), 0.4, 1e-5);

  std::ifstream f(files[1]);
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j["frame_id"], "map");
  EXPECT_EQ(j["input_points"], 4321);
  EXPECT_NEAR(j["processing_s"].get<double>(), 1.5, 1e-6);
  EXPECT_NEAR(j["latency_s"].get<double>(), 2.25, 1e-6);
  ASSERT_EQ(j["instances"].size(), 2u);
  EXPECT_EQ(j["instances"][0]["id"], 3);
  EXPECT_EQ(j["instances"][0]["mesh_file"], "instance_3_table.ply");
  EXPECT_TRUE(j["instances"][1]["mesh_file"].is_null());
  EXPECT_NEAR(j["instances"][0]["score"].get<double>(), 0.75, 1e-6);

  const auto obj = SaveSceneFiles(scene, dir.string(), "obj");
  EXPECT_EQ(geometry::ReadObj(obj[0]).faces.size(), 12u);
  fs::remove_all(dir);
}

TEST(SceneFiles, BadRequests) {
  SceneMeshes scene;
  EXPECT_THROW(SaveSceneFiles(scene, "", "ply"), InvalidArgument);
  EXPECT_THROW(SaveSceneFiles(scene, "/tmp/x", "stl"), InvalidArgument);
  try {
    SaveSceneFiles(scene, "/proc/dimr/nope", "ply");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/dimr/nope"), std::string::npos);
  }
}

}  // namespace
}  // namespace dimr::ros1
