// Node + pipeline parameters (see node_params.h).
#include "dimr/ros/node_params.h"

#include <filesystem>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

std::string Resolve(const std::string& path, const std::string& base) {
  if (path.empty() || base.empty() || std::filesystem::path(path).is_absolute()) return path;
  return (std::filesystem::path(base) / path).string();
}

}  // namespace

void DeclarePipelineParams(pipeline::ReconstructorConfig* c, PipelineParamText* text,
                           ParamTable* t) {
  t->AddString("pipeline/stage1_model", &c->stage1_model, {},
               "stage-1 weights (model.yaml beside them); relative to the package", false);
  t->AddString("pipeline/stage2_model", &c->stage2_model, {},
               "stage-2 weights; relative to the package", false);
  t->AddString("pipeline/bsp_model", &c->bsp_model, {},
               "BSP-CVAE decoder weights; relative to the package", false);
  t->AddString("pipeline/pool", &c->pool, {},
               "latent CAD pool (dimr encode-pool); empty = none (generation only)");
  t->AddString("pipeline/pool_meshes", &c->pool_meshes, {},
               "ShapeNet-style tree of the pool's CAD meshes for retrieval; empty = the paths "
               "stored in the pool");
  t->AddString("pipeline/preset", &text->preset, {"fast", "accurate"},
               "stage-1 inference: fast = one pass, accurate = the card's test-time augmentation");
  t->AddString("pipeline/mode", &text->mode, {"generation", "projection", "retrieval"},
               "initial shape mode (set_mode changes it at run time)");
  t->AddInt("pipeline/k", &c->k, 1, 64, "", "projection neighbours");
  t->AddInt("pipeline/samples", &c->samples, 0, 32, "", "alternative shapes sampled per object");
  t->AddInt("pipeline/seed", &text->seed, 0, 2147483647, "", "sampling seed");
  t->AddDouble("pipeline/score_threshold", &c->score_threshold, 0, 0.999, "",
               "keep proposals with sigmoid(score) above this");
  t->AddInt("pipeline/min_points", &c->min_points, 0, 1000000, "",
            "keep proposals with more points than this");
  t->AddDouble("pipeline/nms_iou", &c->nms_iou, 0, 1, "", "point-IoU non-maximum suppression");
  t->AddString("pipeline/score", &text->score, {"combined", "stage2"},
               "detection score: combined = sqrt(stage-1 x stage-2), stage2 = the reference's");
  t->AddBool("pipeline/icp/enabled", &c->icp.enabled, "refine each mesh's pose by ICP");
  t->AddDouble("pipeline/icp/max_correspondence", &c->icp.max_correspondence, 1e-4, 1, "m",
               "ICP correspondence distance");
  t->AddString("pipeline/icp/backend", &text->icp_backend, {"own", "pcl"},
               "ICP implementation: own (kd-tree, early stop) or PCL's");
  t->AddString("pipeline/icp/metric", &text->icp_metric, {"point_to_point", "point_to_plane"},
               "ICP error metric (own backend)");
  t->AddInt("pipeline/icp/max_iterations", &c->icp.max_iterations, 1, 10000, "", "ICP iterations");
  t->AddInt("pipeline/icp/samples", &c->icp.samples, 3, 1000000, "", "mesh surface samples");
  t->AddDouble("pipeline/icp/max_tilt_deg", &c->icp.max_tilt_deg, 0, 90, "deg",
               "largest accepted roll / pitch of the ICP correction");
  t->AddInt("pipeline/min_input_points", &c->min_input_points, 0, 100000000, "",
            "fewer points: an empty scene with a warning");
  t->AddDouble("pipeline/max_extent", &c->max_extent, 0.1, 100000, "m",
               "a cloud larger than this along an axis is refused");
  t->AddInt("pipeline/threads", &c->threads, 0, 256, "",
            "intra-op threads of the networks; 0 = the process setting");
}

ReadResult ReadNodeParams(const ParamSource& source, const std::string& package_dir) {
  ReadResult r;
  PipelineParamText text;
  ParamTable t;
  DeclareNodeParams(&r.params.node, &t);
  DeclarePipelineParams(&r.params.pipeline, &text, &t);
  r.unknown_keys = t.Read(source, {"bond/", "diagnostic_period"});
  pipeline::ReconstructorConfig& p = r.params.pipeline;
  p.preset = pipeline::ParseReconstructionPreset(text.preset);
  p.mode = pipeline::ParseReconstructionMode(text.mode);
  p.seed = static_cast<std::uint64_t>(text.seed);
  p.score = pipeline::ParseScoreRanking(text.score);
  p.icp.backend = pipeline::ParseIcpBackend(text.icp_backend);
  p.icp.metric = pipeline::ParseIcpMetric(text.icp_metric);
  p.icp.seed = p.seed;
  for (std::string* path :
       {&p.stage1_model, &p.stage2_model, &p.bsp_model, &p.pool, &p.pool_meshes})
    *path = Resolve(*path, package_dir);
  // The node crops and subsamples itself (crop_box, max_input_points); the pipeline's own
  // limit must not refuse what the node hands over.
  p.crop = false;
  p.max_points = std::max<std::size_t>(p.max_points, r.params.node.max_input_points);
  try {
    r.params.node.Validate();
    p.Validate();
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(std::string(e.what()) + " (" + source.Describe() + ")");
  }
  r.resolved = t.Dump();
  return r;
}

std::vector<std::string> DeclaredParamNames() {
  NodeParams p;
  PipelineParamText text;
  ParamTable t;
  DeclareNodeParams(&p.node, &t);
  DeclarePipelineParams(&p.pipeline, &text, &t);
  std::vector<std::string> names;
  for (const ParamEntry& e : t.entries()) names.push_back(e.name);
  return names;
}

}  // namespace dimr::ros1
