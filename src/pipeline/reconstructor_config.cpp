#include "dimr/pipeline/reconstructor_config.h"

#include <cmath>
#include <sstream>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"

namespace dimr::pipeline {

namespace {

// Name tables of the config's enums (config::EnumNames: Parse errors list the valid names).
const config::EnumNames<ReconstructionMode>& ModeNames() {
  static const config::EnumNames<ReconstructionMode> names(
      "mode", {{ReconstructionMode::kGeneration, "generation"},
               {ReconstructionMode::kProjection, "projection"},
               {ReconstructionMode::kRetrieval, "retrieval"}});
  return names;
}

const config::EnumNames<ReconstructionPreset>& PresetNames() {
  static const config::EnumNames<ReconstructionPreset> names(
      "preset",
      {{ReconstructionPreset::kFast, "fast"}, {ReconstructionPreset::kAccurate, "accurate"}});
  return names;
}

const config::EnumNames<ScoreRanking>& ScoreNames() {
  static const config::EnumNames<ScoreRanking> names(
      "score", {{ScoreRanking::kStage2, "stage2"}, {ScoreRanking::kCombined, "combined"}});
  return names;
}

}  // namespace

const char* ReconstructionModeName(ReconstructionMode mode) {
  return ModeNames().Name(mode).c_str();
}
ReconstructionMode ParseReconstructionMode(const std::string& name) {
  return ModeNames().Parse(name);
}
const char* ReconstructionPresetName(ReconstructionPreset preset) {
  return PresetNames().Name(preset).c_str();
}
ReconstructionPreset ParseReconstructionPreset(const std::string& name) {
  return PresetNames().Parse(name);
}
const char* ScoreRankingName(ScoreRanking r) { return ScoreNames().Name(r).c_str(); }
ScoreRanking ParseScoreRanking(const std::string& name) { return ScoreNames().Parse(name); }

void ReconstructorConfig::Validate() const {
  auto bad = [](const std::string& key, const std::string& why) {
    throw InvalidArgument("reconstructor config: " + key + " " + why);
  };
  if (stage1_model.empty()) bad("stage1_model", "is empty");
  if (stage2_model.empty()) bad("stage2_model", "is empty");
  if (bsp_model.empty()) bad("bsp_model", "is empty");
  if (k < 1) bad("k", "must be >= 1 (got " + std::to_string(k) + ")");
  if (k > 64) bad("k", "must be <= 64 (got " + std::to_string(k) + ")");
  if (samples < 0 || samples > 64) {
    bad("samples", "must be in [0, 64] (got " + std::to_string(samples) + ")");
  }
  if (!std::isfinite(score_threshold) || score_threshold < 0 || score_threshold >= 1) {
    bad("score_threshold", "must be in [0, 1) (got " + std::to_string(score_threshold) + ")");
  }
  if (min_points < 0) bad("min_points", "must be >= 0 (got " + std::to_string(min_points) + ")");
  if (!std::isfinite(nms_iou) || nms_iou < 0 || nms_iou > 1) {
    bad("nms_iou", "must be in [0, 1] (got " + std::to_string(nms_iou) + ")");
  }
  if (!std::isfinite(decoded_mesh_scale) || decoded_mesh_scale <= 0.5 || decoded_mesh_scale > 2) {
    bad("decoded_mesh_scale",
        "must be in (0.5, 2] (got " + std::to_string(decoded_mesh_scale) + ")");
  }
  if (max_points < 1) bad("max_points", "must be >= 1");
  if (min_input_points < 1) bad("min_input_points", "must be >= 1");
  if (!crop_min.allFinite() || !crop_max.allFinite()) bad("crop_min/crop_max", "must be finite");
  if (crop && (crop_min.array() >= crop_max.array()).any()) {
    bad("crop_min", "must be below crop_max on every axis");
  }
  if (!std::isfinite(max_extent) || max_extent <= 0) bad("max_extent", "must be > 0");
  if (threads < 0) bad("threads", "must be >= 0");
  if (mode != ReconstructionMode::kGeneration && pool.empty()) {
    bad("pool",
        std::string("is empty but mode ") + ReconstructionModeName(mode) + " needs a shape pool");
  }
  icp.Validate();
}

std::string ReconstructorConfig::ToYaml() const {
  std::ostringstream o;
  o.precision(9);
  auto vec = [&o](const geometry::Vec3& v) {
    o << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  };
  o << "stage1_model: \"" << stage1_model << "\"\n"
    << "stage2_model: \"" << stage2_model << "\"\n"
    << "bsp_model: \"" << bsp_model << "\"\n"
    << "pool: \"" << pool << "\"\n"
    << "pool_meshes: \"" << pool_meshes << "\"\n"
    << "preset: " << ReconstructionPresetName(preset) << "\n"
    << "mode: " << ReconstructionModeName(mode) << "\n"
    << "k: " << k << "\n"
    << "samples: " << samples << "\n"
    << "seed: " << seed << "\n"
    << "score_threshold: " << score_threshold << "\n"
    << "min_points: " << min_points << "\n"
    << "nms_iou: " << nms_iou << "\n"
    << "score: " << ScoreRankingName(score) << "\n"
    << "decoded_mesh_scale: " << decoded_mesh_scale << "\n"
    << "box_residual: " << (box_residual ? "true" : "false") << "\n"
    << "multi_scale: " << (multi_scale ? "true" : "false") << "\n"
    << "icp:\n"
    << "  enabled: " << (icp.enabled ? "true" : "false") << "\n"
    << "  backend: " << IcpBackendName(icp.backend) << "\n"
    << "  metric: " << IcpMetricName(icp.metric) << "\n"
    << "  max_correspondence: " << icp.max_correspondence << "\n"
    << "  max_iterations: " << icp.max_iterations << "\n"
    << "  samples: " << icp.samples << "\n"
    << "  max_tilt_deg: " << icp.max_tilt_deg << "\n"
    << "  relative_rms_change: " << icp.relative_rms_change << "\n"
    << "max_points: " << max_points << "\n"
    << "min_input_points: " << min_input_points << "\n"
    << "crop: " << (crop ? "true" : "false") << "\n"
    << "crop_min: ";
  vec(crop_min);
  o << "\ncrop_max: ";
  vec(crop_max);
  o << "\nmax_extent: " << max_extent << "\n"
    << "threads: " << threads << "\n";
  return o.str();
}

}  // namespace dimr::pipeline
