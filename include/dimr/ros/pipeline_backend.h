// The production SceneBackend: pipeline::Reconstructor (stage 1 + stage 2 + BSP decoder + pool)
// behind the node's interface. ROS-free.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "dimr/pipeline/reconstructor.h"
#include "dimr/ros/scene_backend.h"

namespace dimr::ros1 {

class PipelineBackend : public SceneBackend {
 public:
  // Loads every model of `config` (throws dimr::Error naming the file) and, for the services,
  // its own copy of the pool (get_pool_model must not touch the worker's Reconstructor).
  explicit PipelineBackend(const pipeline::ReconstructorConfig& config);
  ~PipelineBackend() override;

  BackendResult Reconstruct(const BackendCloud& cloud) override;
  void SetMode(ShapeMode mode, int k) override;
  bool has_pool() const override { return has_pool_; }
  bool SupportsMode(ShapeMode mode, std::string* why) const override;
  std::string model_version() const override { return model_version_; }
  std::string pool_id() const override { return pool_id_; }
  std::string compute_info() const override;  // "sparse kernels <path>"
  bool PoolModel(const std::string& model_id, geometry::TriangleMesh* mesh,
                 std::string* mesh_resource) const override;

  static pipeline::ReconstructionMode ToPipeline(ShapeMode mode);
  static ShapeMode FromPipeline(pipeline::ReconstructionMode mode);

 private:
  pipeline::Reconstructor reconstructor_;
  bool has_pool_ = false;
  int pool_meshes_ = 0;
  std::string model_version_, pool_id_;
  struct PoolCopy;
  std::unique_ptr<PoolCopy> pool_;
  mutable std::mutex pool_mutex_;
};

}  // namespace dimr::ros1
