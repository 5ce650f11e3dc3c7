// The scene Reconstructor: one call from a point cloud to labelled, complete instance meshes
// (dimr-method.md section 0). `dimr reconstruct`, `dimr bench reconstruct` and the ROS node
// all run this.
//
//   pipeline::ReconstructorConfig cfg;             // models/..., preset accurate, generation
//   pipeline::Reconstructor rec(cfg);              // loads the models (throws naming the file)
//   pipeline::SceneResult r = rec.Reconstruct(cloud);
//   rec.SetMode(pipeline::ReconstructionMode::kRetrieval, 1);
//
// Steps: validate (finite points: non-finite ones are dropped with a warning; count <=
// max_points; optional crop; extent <= max_extent) -> stage 1 (Stage1Segmenter: floor and
// network frame, U-Net, heads, semantic vote, multi-scale clustering; its own NMS off, every
// proposal goes to stage 2 as in the reference) -> stage 2 (Stage2Predictor: score, box, latent)
// -> filter (score > score_threshold, > min_points points, point-IoU NMS) -> per object the
// shape by mode (generation: decode mu; projection: decode the projection onto the k nearest
// pool codes; retrieval: the nearest pool CAD mesh) -> placement by the box -> ICP against the
// proposal's points (accepted iff |roll|, |pitch| <= icp.max_tilt_deg) -> input frame.
// Optional alternative shapes: `samples` codes drawn from the predicted sigma per object.
// The shapes: all objects' codes decoded to planes in one batched network call, then mesh
// extraction, placement and ICP per object on `threads` threads (0: the hardware's), merged in
// object order, so the result does not depend on the thread count. The "mesh" and "icp"
// timings are summed over objects (over threads when several run).
//
// Thread safety: Reconstruct() is const but the networks are not safe to run from two threads
// at once: use one Reconstructor per thread (e.g. the ROS node's worker thread owns one).
// SetMode() must not run concurrently with Reconstruct() on the same instance.
#pragma once

#include <memory>
#include <string>

#include "dimr/pipeline/point_cloud_input.h"
#include "dimr/pipeline/reconstructor_config.h"
#include "dimr/pipeline/scene_result.h"

namespace dimr::pipeline {

class ShapePool;

class Reconstructor {
 public:
  // Validates the config and loads every model it names (stage 1, stage 2, BSP decoder; the
  // pool when the file exists or the mode needs it). Throws dimr::InvalidArgument for a bad
  // config, dimr::ParseError naming the file for a missing or corrupt model.
  explicit Reconstructor(const ReconstructorConfig& config);
  ~Reconstructor();
  Reconstructor(Reconstructor&&) noexcept;
  Reconstructor& operator=(Reconstructor&&) noexcept;

  // The whole pipeline on one cloud (metres, z up, any origin). An empty instance list with a
  // warning is a valid answer (too few points, no objects). Throws dimr::InvalidArgument naming
  // the cloud for more than max_points points or an extent beyond max_extent (e.g. a cloud in
  // millimetres).
  SceneResult Reconstruct(const PointCloudInput& input) const;

  // The shapes of an earlier result again under another mode (the networks are not re-run):
  // boxes, latents, scores and support points are kept, meshes, sources, pool models and ICP
  // are redone. `input` must be the cloud `scene` came from. Throws dimr::InvalidArgument as
  // SetMode, or for a support index outside `input`.
  SceneResult Remesh(const SceneResult& scene, const PointCloudInput& input,
                     ReconstructionMode mode, int k = 1) const;

  // Switches the shape mode (k: projection neighbours, >= 1). Throws dimr::InvalidArgument
  // when projection or retrieval is asked without a pool, or retrieval without pool meshes.
  void SetMode(ReconstructionMode mode, int k = 1);
  // Alternative shapes per object (>= 0).
  void SetSamples(int samples);
  bool has_pool() const;
  // Number of pool entries with a CAD mesh (retrieval candidates); 0 without a pool.
  int pool_meshes() const;
  const ShapePool* pool() const;  // nullptr without one
  const ReconstructorConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dimr::pipeline
