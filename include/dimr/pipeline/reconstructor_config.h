// Configuration of the scene Reconstructor (pipeline/reconstructor.h): model paths, preset,
// shape mode, filters, ICP, input validation. Defaults are the reference's test-time values
// (dimr-method.md sections 3.6, 7, 9, 10.2); units are metres. Validate() names the bad key.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "dimr/geometry/types.h"
#include "dimr/pipeline/icp.h"

namespace dimr::pipeline {

// How an object's mesh is made from its predicted latent (section 9).
enum class ReconstructionMode {
  kGeneration,  // decode the predicted mu
  kProjection,  // decode the projection onto the affine hull of the k nearest pool codes
  kRetrieval,   // the nearest pool entry's CAD mesh, placed by the box
};
// "generation", "projection", "retrieval".
const char* ReconstructionModeName(ReconstructionMode mode);
// Parses a mode name (case-sensitive, the names above). Throws dimr::InvalidArgument listing
// the valid names.
ReconstructionMode ParseReconstructionMode(const std::string& name);

// Stage-1 inference preset: kAccurate = the stage-1 card's test-time augmentation, kFast = one
// pass.
enum class ReconstructionPreset { kFast, kAccurate };
const char* ReconstructionPresetName(ReconstructionPreset preset);  // "fast", "accurate"
ReconstructionPreset ParseReconstructionPreset(const std::string& name);

// The detection score that the filter, NMS and the output use. Section 3.6 uses stage 2's;
// the default here is the geometric mean with stage 1's, selected on 30 validation rooms
// (docs/results.md: IoU@0.25 +6.4, PCR@0.5 +7.9 with the first stage-2 model).
enum class ScoreRanking {
  kStage2,    // stage 2's confidence (sigmoid), the reference
  kCombined,  // sqrt(stage-1 proposal score x stage-2 confidence)
};
const char* ScoreRankingName(ScoreRanking r);  // "stage2", "combined"
ScoreRanking ParseScoreRanking(const std::string& name);

struct ReconstructorConfig {
  // Models (weights; each card model.yaml beside them). An empty pool = none (generation only).
  std::string stage1_model = "models/stage1/stage1.pt";
  std::string stage2_model = "models/stage2/stage2.pt";
  std::string bsp_model = "models/bsp/bsp.pt";
  std::string pool = "models/bsp/pool.bin";
  // ShapeNet-style tree of the pool's CAD meshes for retrieval (ShapePool::AttachMeshTree);
  // empty = the mesh paths stored in the pool file.
  std::string pool_meshes;

  ReconstructionPreset preset = ReconstructionPreset::kAccurate;
  ReconstructionMode mode = ReconstructionMode::kGeneration;
  int k = 1;               // projection neighbours (>= 1)
  int samples = 0;         // alternative shapes sampled from sigma per object (>= 0)
  std::uint64_t seed = 0;  // sampling seed (alternative shapes, ICP surface samples)

  // Proposal filter (section 3.6).
  double score_threshold = 0.05;  // keep sigmoid(score) > threshold, [0, 1)
  // keep proposals with > min_points points (>= 0). 30, not the reference's 100: that was
  // set for ScanNet's ~2 cm sampling; stage 1 here sees one point per 4.5 cm cell (~5x fewer
  // points per object), and 30 was chosen on the validation rooms (docs/results.md).
  int min_points = 30;
  double nms_iou = 0.3;  // point-IoU NMS drops IoU > nms_iou, [0, 1]
  ScoreRanking score = ScoreRanking::kCombined;

  // Decoded (generation / projection) meshes are placed by v -> Rz(heading)(v * size / 2 *
  // decoded_mesh_scale) + centre. 1 = the reference (section 6.4; the decoded mesh fills
  // [-s, s], s = 1 - 1/32, so it spans 96.9 % of the box); 1 / s fills the box. (0.5, 2].
  double decoded_mesh_scale = 1.0;

  IcpConfig icp;

  // Module switches (ablations): the stage-2 box residual (false: the proposal's own box,
  // centre c0 and extents s0) and stage 1's multi-scale clustering (false: one shifted pass at
  // 3 cm).
  bool box_residual = true;
  bool multi_scale = true;

  // Input validation (in the input frame, metres).
  std::size_t max_points = 3000000;  // more points: an error (downsample first)
  int min_input_points = 50;         // fewer points: an empty result with a warning
  bool crop = false;                 // keep only points inside [crop_min, crop_max]
  geometry::Vec3 crop_min = geometry::Vec3::Constant(-1e6);
  geometry::Vec3 crop_max = geometry::Vec3::Constant(1e6);
  // A cloud larger than this along any axis is refused (a millimetre cloud or a map far too
  // big for one pass); metres.
  double max_extent = 200.0;

  int threads = 0;  // intra-op threads for the networks; 0 = leave the process setting

  // Throws dimr::InvalidArgument naming the key ("k", "score_threshold", "icp.samples", ...).
  void Validate() const;
  // The configuration as YAML text (every key above), for SceneResult::config and logs.
  std::string ToYaml() const;
};

}  // namespace dimr::pipeline
