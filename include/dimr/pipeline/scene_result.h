// What the Reconstructor returns for one cloud (pipeline/reconstructor.h): every detected
// object with its class, score, 7-DoF box, latent code, mesh (in the input frame), where the
// mesh came from, the pool models involved and the input points that support it; per-stage
// timings; the configuration used. A plain value type (copyable, no references into the
// Reconstructor), so a worker thread can hand it to another thread.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "dimr/core/timing.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/types.h"

namespace dimr::pipeline {

// Where an instance's mesh came from (dimr-method.md section 9).
enum class MeshSource {
  kGenerated,  // BSP decode of the predicted mu (or of a sample from sigma)
  kProjected,  // BSP decode of the projection onto the k nearest pool codes
  kRetrieved,  // the nearest pool entry's CAD mesh
};
const char* MeshSourceName(MeshSource source);  // "generated", "projected", "retrieved"

// One shape hypothesis of an instance beyond the main one (`--samples K`: codes sampled from
// the predicted sigma, z = mu + eps exp(0.5 logvar)).
struct ShapeHypothesis {
  Eigen::VectorXf latent;       // the code decoded (mu part used)
  geometry::TriangleMesh mesh;  // input frame, placed by the instance box (+ ICP)
  // The instance score times exp(-|eps|^2 / (2 d)) (d = latent size): the sample's
  // per-dimension likelihood relative to mu, so hypotheses far out in sigma rank lower.
  double score = 0.0;
  MeshSource source = MeshSource::kGenerated;
};

struct InstanceResult {
  int id = 0;                   // 0-based, in descending score order
  int cad_class = -1;           // 0..7 (table, chair, bookshelf, sofa, trash_bin, cabinet, display,
                                // bathtub)
  double score = 0.0;           // sigmoid of the stage-2 score logit
  geometry::OrientedBox box;    // input frame: centre, size (forward, left, up), heading
  Eigen::VectorXf latent;       // predicted [mu, logvar] (2 x latent_dim)
  Eigen::VectorXf shape_code;   // the code the mesh was decoded from (empty for retrieval)
  geometry::TriangleMesh mesh;  // input frame
  MeshSource source = MeshSource::kGenerated;
  std::string pool_model_id;            // retrieval: the CAD model; projection: the nearest
  std::vector<std::string> neighbours;  // projection: the k pool models used, nearest first
  std::vector<int> support;             // indices of the input points of the proposal
  bool icp_accepted = false;            // the ICP refinement was applied
  Eigen::Matrix4d icp_transform = Eigen::Matrix4d::Identity();  // applied (identity if not)
  std::vector<ShapeHypothesis> alternatives;
};

struct SceneResult {
  std::vector<InstanceResult> instances;  // descending score
  // Milliseconds per stage in pipeline order: validate, voxelise, unet, heads, vote,
  // clustering, stage2, decode, mesh, icp (names of the stages that ran).
  Timings timings;
  std::string config;                 // ReconstructorConfig::ToYaml() of the run
  std::vector<std::string> warnings;  // e.g. "cloud has 1 point: nothing to reconstruct"
  std::size_t input_points = 0;       // points given
  std::size_t used_points = 0;        // after validation and crop
};

}  // namespace dimr::pipeline
