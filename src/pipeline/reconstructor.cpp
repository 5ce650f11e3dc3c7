#include "dimr/pipeline/reconstructor.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "dimr/core/parallel.h"
#include "dimr/core/timing.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/hash.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/gravity.h"
#include "dimr/pipeline/icp.h"
#include "dimr/pipeline/placement.h"
#include "dimr/pipeline/shape_pool.h"
#include "dimr/pipeline/stage1_segmenter.h"
#include "dimr/pipeline/stage2_predictor.h"

namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

Stage1Preset ToStage1Preset(ReconstructionPreset p) {
  return p == ReconstructionPreset::kFast ? Stage1Preset::kFast : Stage1Preset::kAccurate;
}

std::string CloudName(const PointCloudInput& in) {
  return in.name.empty() ? std::string("point cloud") : in.name;
}

}  // namespace

struct Reconstructor::Impl {
  ReconstructorConfig config;
  Stage1Segmenter stage1;
  Stage2Predictor stage2;
  BspDecoder decoder;
  std::unique_ptr<ShapePool> pool;
  // Retrieved CAD meshes (canonical axes) by pool index; filled on first use.
  mutable std::mutex cache_mutex;
  mutable std::map<int, std::shared_ptr<const geometry::TriangleMesh>> cad_cache;

  Impl(const ReconstructorConfig& c, Stage1Segmenter s1, Stage2Predictor s2, BspDecoder d)
      : config(c), stage1(std::move(s1)), stage2(std::move(s2)), decoder(std::move(d)) {}

  std::shared_ptr<const geometry::TriangleMesh> CadMesh(int index) const {
    {
      std::lock_guard<std::mutex> lock(cache_mutex);
      auto it = cad_cache.find(index);
      if (it != cad_cache.end()) return it->second;
    }
    const PoolEntry& e = pool->entries()[static_cast<std::size_t>(index)];
    auto m = std::make_shared<const geometry::TriangleMesh>(ReadShapeNetMeshCanonical(e.mesh_path));
    std::lock_guard<std::mutex> lock(cache_mutex);
    cad_cache[index] = m;
    return m;
  }

  // The nearest pool entry of the class that has a CAD mesh, or -1.
  int NearestWithMesh(const Eigen::VectorXf& code, int cad_class) const {
    for (const PoolMatch& m : pool->Nearest(code, cad_class, static_cast<int>(pool->size()))) {
      if (!pool->entries()[static_cast<std::size_t>(m.index)].mesh_path.empty()) return m.index;
    }
    return -1;
  }

  // The shapes of `insts` (targets[i]: the points instance i's ICP aligns to): codes chosen per
  // mode (pool look-ups), every code's planes in one batched network call ("decode"), then per
  // instance, on `threads` threads (plain C++, no network call), mesh extraction and placement
  // ("mesh") and ICP ("icp"). Per-instance timings and warnings are merged in instance order,
  // so the result does not depend on the thread count.
  void MakeShapes(std::vector<InstanceResult>* insts,
                  const std::vector<std::vector<geometry::Vec3>>& targets, ReconstructionMode mode,
                  int k, int samples, SceneResult* result) const;

  // Threads of the per-instance shape work: the config's network thread count, else the
  // hardware's.
  int ShapeThreads() const { return ResolveThreads(config.threads); }

  // The canonical mesh of decoded planes, placed by `box` (scaled by decoded_mesh_scale).
  geometry::TriangleMesh PlacedFromPlanes(const Eigen::MatrixXf& planes,
                                          const geometry::OrientedBox& box) const {
    geometry::OrientedBox scaled = box;
    scaled.size *= config.decoded_mesh_scale;
    return PlaceCanonicalMesh(decoder.MeshFromPlanes(planes).mesh, scaled);
  }
};

Reconstructor::Reconstructor(const ReconstructorConfig& config) {
  config.Validate();
  if (config.threads > 0) nn::SetIntraOpThreads(config.threads);
  Stage1Segmenter seg = Stage1Segmenter::Load(config.stage1_model, ToStage1Preset(config.preset));
  // Stage 2 scores every proposal and the filter below runs on its scores (section 3.6), so
  // stage 1's own size filter and NMS are off.
  Stage1InferenceConfig s1 = seg.config();
  s1.nms_iou = 1.0;
  s1.min_points = 0;
  // Ablation without multi-scale clustering: one pass on the shifted points at 3 cm.
  if (!config.multi_scale) s1.passes = {ClusterPass{true, 0.03}};
  seg.set_config(s1);
  impl_ = std::make_unique<Impl>(config, std::move(seg), Stage2Predictor::Load(config.stage2_model),
                                 BspDecoder::Load(config.bsp_model));
  std::error_code ec;
  const bool need_pool = config.mode != ReconstructionMode::kGeneration;
  if (!config.pool.empty() && (need_pool || fs::exists(config.pool, ec))) {
    impl_->pool = std::make_unique<ShapePool>(ShapePool::Load(config.pool));
    if (impl_->pool->latent_dim() != impl_->decoder.latent_dim()) {
      throw InvalidArgument("reconstructor config: pool '" + config.pool + "' has latent size " +
                            std::to_string(impl_->pool->latent_dim()) + ", the BSP decoder " +
                            std::to_string(impl_->decoder.latent_dim()));
    }
    if (!config.pool_meshes.empty()) impl_->pool->AttachMeshTree(config.pool_meshes);
  }
  SetMode(config.mode, config.k);
}

Reconstructor::~Reconstructor() = default;
Reconstructor::Reconstructor(Reconstructor&&) noexcept = default;
Reconstructor& Reconstructor::operator=(Reconstructor&&) noexcept = default;

void Reconstructor::SetMode(ReconstructionMode mode, int k) {
  if (k < 1 || k > 64)
    throw InvalidArgument("SetMode: k must be in [1, 64], got " + std::to_string(k));
  if (mode != ReconstructionMode::kGeneration && !impl_->pool) {
    throw InvalidArgument(std::string("SetMode: mode ") + ReconstructionModeName(mode) +
                          " needs a shape pool (config key pool)");
  }
  if (mode == ReconstructionMode::kRetrieval && impl_->pool->NumWithMeshes() == 0) {
    throw InvalidArgument(
        "SetMode: retrieval needs the pool's CAD meshes (config key pool_meshes: a ShapeNet-style "
        "tree of the pool models, e.g. from `dimr export pool-meshes`)");
  }
  impl_->config.mode = mode;
  impl_->config.k = k;
}

void Reconstructor::SetSamples(int samples) {
  if (samples < 0 || samples > 64) {
    throw InvalidArgument("SetSamples: samples must be in [0, 64], got " + std::to_string(samples));
  }
  impl_->config.samples = samples;
}

bool Reconstructor::has_pool() const { return impl_->pool != nullptr; }
int Reconstructor::pool_meshes() const { return impl_->pool ? impl_->pool->NumWithMeshes() : 0; }
const ShapePool* Reconstructor::pool() const { return impl_->pool.get(); }
const ReconstructorConfig& Reconstructor::config() const { return impl_->config; }

void Reconstructor::Impl::MakeShapes(std::vector<InstanceResult>* insts,
                                     const std::vector<std::vector<geometry::Vec3>>& targets,
                                     ReconstructionMode mode, int k, int samples,
                                     SceneResult* result) const {
  const std::size_t n = insts->size();
  // Per instance: which planes (index into the batch) or pool CAD mesh it gets, and its own
  // timings and warnings (merged in order at the end).
  struct Job {
    int planes = -1;                 // main shape's planes, -1: none
    int cad = -1;                    // retrieval: pool entry of the CAD mesh, -1: none
    std::vector<int> sample_planes;  // planes of each alternative
    Timings timings;
    std::vector<std::string> warnings;
  };
  std::vector<Job> jobs(n);
  std::vector<Eigen::VectorXf> codes;
  std::vector<int> classes;
  auto add_code = [&](const Eigen::VectorXf& code, int cad_class) {
    codes.push_back(code);
    classes.push_back(cad_class);
    return static_cast<int>(codes.size()) - 1;
  };
  const int d_lat = decoder.latent_dim();
  for (std::size_t i = 0; i < n; ++i) {
    InstanceResult* inst = &(*insts)[i];
    Job& job = jobs[i];
    const int d = inst->id;
    inst->mesh = geometry::TriangleMesh();
    inst->neighbours.clear();
    inst->pool_model_id.clear();
    inst->shape_code.resize(0);
    inst->alternatives.clear();
    inst->icp_accepted = false;
    inst->icp_transform.setIdentity();
    switch (mode) {
      case ReconstructionMode::kGeneration:
        inst->source = MeshSource::kGenerated;
        inst->shape_code = inst->latent;
        job.planes = add_code(inst->latent, inst->cad_class);
        break;
      case ReconstructionMode::kProjection: {
        inst->source = MeshSource::kProjected;
        Projection proj;
        {
          ScopedTimer s(&job.timings, "pool");
          proj = pool->Project(inst->latent, inst->cad_class, k);
        }
        inst->shape_code = proj.code;
        for (int nb : proj.neighbors) {
          inst->neighbours.push_back(pool->entries()[static_cast<std::size_t>(nb)].model_id);
        }
        if (!inst->neighbours.empty()) inst->pool_model_id = inst->neighbours.front();
        job.planes = add_code(proj.code, inst->cad_class);
        break;
      }
      case ReconstructionMode::kRetrieval: {
        inst->source = MeshSource::kRetrieved;
        {
          ScopedTimer s(&job.timings, "pool");
          job.cad = NearestWithMesh(inst->latent, inst->cad_class);
        }
        if (job.cad < 0) {
          job.warnings.push_back("instance " + std::to_string(d) +
                                 ": no pool entry of its class has a CAD mesh; no mesh");
          break;
        }
        const PoolEntry& e = pool->entries()[static_cast<std::size_t>(job.cad)];
        inst->pool_model_id = e.model_id;
        inst->neighbours = {e.model_id};
        break;
      }
    }
    // Alternative shapes sampled from sigma (decoded, as generation).
    for (int j = 0; j < samples && inst->latent.size() == 2 * d_lat; ++j) {
      ShapeHypothesis h;
      h.source = MeshSource::kGenerated;
      const std::uint64_t seed = config.seed * 0x9e3779b97f4a7c15ull +
                                 static_cast<std::uint64_t>(d) * 1000003ull +
                                 static_cast<std::uint64_t>(j) + 1;
      h.latent = SampleCode(inst->latent, seed);
      const Eigen::ArrayXf sigma = (0.5f * inst->latent.tail(d_lat).array()).exp();
      const Eigen::ArrayXf eps = (h.latent.head(d_lat) - inst->latent.head(d_lat)).array() / sigma;
      h.score = inst->score * std::exp(-0.5 * static_cast<double>(eps.square().sum()) / d_lat);
      job.sample_planes.push_back(add_code(h.latent, inst->cad_class));
      inst->alternatives.push_back(std::move(h));
    }
  }
  std::vector<Eigen::MatrixXf> planes;
  if (!codes.empty()) {
    ScopedTimer s(&result->timings, "decode");
    planes = decoder.PlanesBatch(codes, classes);
  }
  ParallelFor(n, ShapeThreads(), [&](std::size_t i) {
    InstanceResult* inst = &(*insts)[i];
    Job& job = jobs[i];
    const int d = inst->id;
    if (job.planes >= 0) {
      ScopedTimer s(&job.timings, "mesh");
      inst->mesh = PlacedFromPlanes(planes[static_cast<std::size_t>(job.planes)], inst->box);
    } else if (job.cad >= 0) {
      ScopedTimer s(&job.timings, "mesh");
      inst->mesh = PlaceRetrievedMesh(*CadMesh(job.cad), inst->box);
    }
    if (inst->mesh.empty()) {
      job.warnings.push_back("instance " + std::to_string(d) + " (class " +
                             std::to_string(inst->cad_class) + "): the shape has no mesh");
    }
    if (config.icp.enabled && !inst->mesh.empty()) {
      ScopedTimer s(&job.timings, "icp");
      IcpConfig icp = config.icp;
      icp.seed = config.seed ^ static_cast<std::uint64_t>(d);
      const IcpResult r = RefineMeshByIcp(&inst->mesh, targets[i], icp);
      inst->icp_accepted = r.ran && r.accepted;
      if (inst->icp_accepted) inst->icp_transform = r.transform;
    }
    for (std::size_t j = 0; j < job.sample_planes.size(); ++j) {
      ShapeHypothesis& h = inst->alternatives[j];
      {
        ScopedTimer s(&job.timings, "mesh");
        h.mesh =
            PlacedFromPlanes(planes[static_cast<std::size_t>(job.sample_planes[j])], inst->box);
      }
      if (config.icp.enabled && !h.mesh.empty()) {
        ScopedTimer s(&job.timings, "icp");
        RefineMeshByIcp(&h.mesh, targets[i], config.icp);
      }
    }
  });
  for (Job& job : jobs) {
    result->timings.Merge(job.timings);
    for (std::string& w : job.warnings) result->warnings.push_back(std::move(w));
  }
}

SceneResult Reconstructor::Remesh(const SceneResult& scene, const PointCloudInput& input,
                                  ReconstructionMode mode, int k) const {
  if (mode != ReconstructionMode::kGeneration && !impl_->pool) {
    throw InvalidArgument(std::string("Remesh: mode ") + ReconstructionModeName(mode) +
                          " needs a shape pool");
  }
  if (mode == ReconstructionMode::kRetrieval && impl_->pool->NumWithMeshes() == 0) {
    throw InvalidArgument("Remesh: retrieval needs the pool's CAD meshes (pool_meshes)");
  }
  if (k < 1 || k > 64) throw InvalidArgument("Remesh: k must be in [1, 64]");
  ReconstructorConfig cfg = impl_->config;
  cfg.mode = mode;
  cfg.k = k;
  SceneResult out;
  out.config = cfg.ToYaml();
  out.input_points = scene.input_points;
  out.used_points = scene.used_points;
  out.warnings = scene.warnings;
  std::vector<std::vector<geometry::Vec3>> targets;
  for (const InstanceResult& in : scene.instances) {
    std::vector<geometry::Vec3>& target = targets.emplace_back();
    for (int p : in.support) {
      if (p < 0 || static_cast<std::size_t>(p) >= input.size()) {
        throw InvalidArgument("Remesh: support index " + std::to_string(p) +
                              " outside the input cloud (" + std::to_string(input.size()) +
                              " points): not the cloud of this result");
      }
      target.push_back(input.points[static_cast<std::size_t>(p)].cast<double>());
    }
  }
  out.instances = scene.instances;
  impl_->MakeShapes(&out.instances, targets, mode, k, cfg.samples, &out);
  return out;
}

SceneResult Reconstructor::Reconstruct(const PointCloudInput& input) const {
  const ReconstructorConfig& cfg = impl_->config;
  SceneResult result;
  result.config = cfg.ToYaml();
  result.input_points = input.size();
  const std::string name = CloudName(input);
  Timings& t = result.timings;

  // ---- validate: finite points, count, crop, extent.
  PointCloudInput cloud;
  cloud.name = input.name;
  std::vector<int> to_input;  // cloud index -> input index
  {
    ScopedTimer s(&t, "validate");
    if (input.size() > cfg.max_points) {
      throw InvalidArgument(name + ": " + std::to_string(input.size()) +
                            " points, more than max_points = " + std::to_string(cfg.max_points) +
                            " (downsample the cloud or raise max_points)");
    }
    const bool colors = input.has_colors() && input.colors.size() == input.size();
    const bool normals = input.has_normals() && input.normals.size() == input.size();
    std::size_t non_finite = 0;
    cloud.points.reserve(input.size());
    to_input.reserve(input.size());
    for (std::size_t i = 0; i < input.size(); ++i) {
      const Eigen::Vector3f& p = input.points[i];
      if (!p.allFinite()) {
        ++non_finite;
        continue;
      }
      if (cfg.crop) {
        const Eigen::Vector3d q = p.cast<double>();
        if ((q.array() < cfg.crop_min.array()).any() || (q.array() > cfg.crop_max.array()).any()) {
          continue;
        }
      }
      cloud.points.push_back(p);
      if (colors) cloud.colors.push_back(input.colors[i]);
      if (normals) cloud.normals.push_back(input.normals[i]);
      to_input.push_back(static_cast<int>(i));
    }
    if (non_finite > 0) {
      result.warnings.push_back(name + ": " + std::to_string(non_finite) +
                                " points with NaN/Inf coordinates were dropped");
    }
    result.used_points = cloud.size();
    if (cloud.size() < static_cast<std::size_t>(cfg.min_input_points)) {
      result.warnings.push_back(name + ": " + std::to_string(cloud.size()) +
                                " usable points, fewer than min_input_points = " +
                                std::to_string(cfg.min_input_points) + ": nothing to reconstruct");
      return result;
    }
    Eigen::Vector3f lo = cloud.points[0], hi = cloud.points[0];
    for (const auto& p : cloud.points) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double extent = (hi - lo).maxCoeff();
    if (extent > cfg.max_extent) {
      throw InvalidArgument(name + ": the cloud spans " + std::to_string(extent) +
                            " units, more than max_extent = " + std::to_string(cfg.max_extent) +
                            " m: not a room in metres (millimetres? scale it by 0.001)");
    }
    if (impl_->stage1.uses_color() && !cloud.has_colors()) {
      cloud.colors.assign(cloud.size(), Eigen::Vector3f::Constant(0.5f));
      result.warnings.push_back(
          name + ": no colours; the stage-1 model uses colour, neutral grey assumed");
    }
    cloud.Validate();
    // The frame: a cloud without a flat floor at its bottom is most likely not z up (a depth
    // camera's optical frame) - a warning, since a map may lack its floor (gravity.h).
    const FloorCheck floor = CheckFloor(cloud);
    if (!floor.found) {
      result.warnings.push_back(
          name + ": no floor at the bottom of the cloud (flat in its lowest 10 cm: " +
          std::to_string(static_cast<int>(std::lround(100.0 * floor.area_fraction))) +
          " % of the footprint): dimr expects metres, gravity aligned, z up (a depth camera's "
          "optical frame is up = -y: dimr reconstruct --up=-y; a tilted one needs levelling)");
    }
  }

  // ---- stage 1.
  Stage1Result s1;
  {
    ScopedTimer s(&t, "stage1");
    s1 = impl_->stage1.Segment(cloud, /*with_features=*/true);
  }
  for (const auto& [stage, ms] : s1.timings) {
    if (stage != "total") t.Add("stage1." + stage, ms);
  }
  if (s1.instances.empty()) return result;

  // ---- stage 2 + filter.
  Stage2FilterConfig filter;
  filter.score_threshold = cfg.score_threshold;
  filter.min_points = cfg.min_points;
  filter.nms_iou = cfg.nms_iou;
  std::vector<Stage2Detection> dets;
  {
    ScopedTimer s(&t, "stage2");
    Stage2SceneInput scene;
    scene.points = &cloud.points;
    scene.features = &s1.features;
    scene.feature_dim = s1.feature_dim;
    scene.floor_z = s1.network_origin.z();
    dets = impl_->stage2.Predict(scene, s1.instances);
    if (cfg.score == ScoreRanking::kCombined) {
      for (Stage2Detection& d : dets) d.score = std::sqrt(std::max(0.0, d.stage1_score * d.score));
    }
    dets = FilterDetections(std::move(dets), filter);
  }

  // ---- shapes, placement, ICP.
  std::vector<std::vector<geometry::Vec3>> targets(dets.size());
  result.instances.resize(dets.size());
  for (std::size_t d = 0; d < dets.size(); ++d) {
    const Stage2Detection& det = dets[d];
    InstanceResult& inst = result.instances[d];
    inst.id = static_cast<int>(d);
    inst.cad_class = det.cad_class;
    inst.score = det.score;
    inst.box = cfg.box_residual ? det.box : ProposalBox(det.frame);
    inst.latent = det.code;
    inst.support.reserve(det.points.size());
    targets[d].reserve(det.points.size());
    for (int p : det.points) {
      inst.support.push_back(to_input[static_cast<std::size_t>(p)]);
      targets[d].push_back(cloud.points[static_cast<std::size_t>(p)].cast<double>());
    }
  }
  impl_->MakeShapes(&result.instances, targets, cfg.mode, cfg.k, cfg.samples, &result);
  return result;
}

}  // namespace dimr::pipeline
