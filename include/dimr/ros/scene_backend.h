// What the reconstruction node needs from a scene reconstructor, in the node's own terms: a
// cloud in the fixed frame in, instances (class, score, box, mesh in the fixed frame, shape
// source, support points) out, plus the shape mode and the CAD pool. The production backend
// wraps pipeline::Reconstructor (pipeline_backend.h); keeping the node on this interface lets
// the ROS plumbing (threading, services, markers, TF, hostile input) be tested in rostests
// independently of model files. A backend is used by one thread at a time (the node's worker),
// except the const query methods, which must be thread-safe. ROS-free.
#pragma once

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/types.h"

namespace dimr::ros1 {

enum class ShapeMode { kGeneration = 0, kProjection = 1, kRetrieval = 2 };  // SceneMeshes::MODE_*
const char* ShapeModeName(ShapeMode mode);

struct BackendCloud {
  std::string name;                      // for messages
  std::vector<Eigen::Vector3f> points;   // fixed frame, metres, z up
  std::vector<Eigen::Vector3f> colors;   // empty or one per point, [0, 1]
  std::vector<Eigen::Vector3f> normals;  // empty or one per point
};

struct BackendInstance {
  int cad_class = -1;  // 0 table .. 7 bathtub
  std::string class_name;
  float score = 0;
  geometry::OrientedBox box;    // fixed frame
  geometry::TriangleMesh mesh;  // fixed frame (may be empty)
  ShapeMode source = ShapeMode::kGeneration;
  std::string pool_model_id;  // projection / retrieval
  std::vector<std::string> neighbour_ids;
  std::vector<float> neighbour_weights;
  float code_distance = 0;
  Eigen::VectorXf latent;    // [mu, logvar] or empty
  std::vector<int> support;  // indices into the input cloud
};

struct BackendResult {
  std::vector<BackendInstance> instances;
  std::map<std::string, double> timings_ms;
  // Non-fatal problems of this scene (pipeline::SceneResult::warnings: e.g. no floor at the
  // bottom of the cloud, an instance whose mesh failed); the node reports each as an issue.
  std::vector<std::string> warnings;
};

class SceneBackend {
 public:
  virtual ~SceneBackend() = default;
  // Throws dimr::Error on a cloud the pipeline refuses (named); never crashes on valid input.
  virtual BackendResult Reconstruct(const BackendCloud& cloud) = 0;
  // Throws dimr::InvalidArgument when projection / retrieval is asked without a pool.
  virtual void SetMode(ShapeMode mode, int k) = 0;
  virtual bool has_pool() const = 0;
  // Whether SetMode(mode) would succeed; otherwise `why` says what is missing (e.g. no pool,
  // or retrieval without pool meshes). Thread-safe.
  virtual bool SupportsMode(ShapeMode mode, std::string* why) const = 0;
  virtual std::string model_version() const = 0;  // weights id (SceneMeshes.model_version)
  virtual std::string pool_id() const = 0;        // "" without a pool
  // Compute path for diagnostics and benchmarks (e.g. the sparse-kernel path); may be "".
  virtual std::string compute_info() const { return ""; }
  // A pool model's mesh in its canonical frame (get_pool_model); false when unknown.
  virtual bool PoolModel(const std::string& model_id, geometry::TriangleMesh* mesh,
                         std::string* mesh_resource) const = 0;
};

}  // namespace dimr::ros1
