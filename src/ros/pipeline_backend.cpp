// pipeline::Reconstructor as the node's SceneBackend (see pipeline_backend.h).
#include "dimr/ros/pipeline_backend.h"

#include <filesystem>
#include <fstream>

#include "dimr/core/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/placement.h"
#include "dimr/pipeline/shape_pool.h"

namespace dimr::ros1 {
namespace {

// FNV-1a of the first 4 MiB and the size of a file: a cheap identity of a weights file.
std::string FileId(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return "missing";
  std::uint64_t h = 1469598103934665603ull;
  std::vector<char> buf(1 << 16);
  std::size_t total = 0;
  while (f && total < (4u << 20)) {
    f.read(buf.data(), buf.size());
    const std::streamsize n = f.gcount();
    for (std::streamsize i = 0; i < n; ++i) {
      h ^= static_cast<unsigned char>(buf[i]);
      h *= 1099511628211ull;
    }
    total += static_cast<std::size_t>(n);
  }
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  char out[64];
  std::snprintf(out, sizeof(out), "%016llx-%llu", static_cast<unsigned long long>(h),
                static_cast<unsigned long long>(ec ? 0 : size));
  return out;
}

}  // namespace

struct PipelineBackend::PoolCopy {
  pipeline::ShapePool pool;
};

pipeline::ReconstructionMode PipelineBackend::ToPipeline(ShapeMode mode) {
  switch (mode) {
    case ShapeMode::kProjection:
      return pipeline::ReconstructionMode::kProjection;
    case ShapeMode::kRetrieval:
      return pipeline::ReconstructionMode::kRetrieval;
    default:
      return pipeline::ReconstructionMode::kGeneration;
  }
}

ShapeMode PipelineBackend::FromPipeline(pipeline::ReconstructionMode mode) {
  switch (mode) {
    case pipeline::ReconstructionMode::kProjection:
      return ShapeMode::kProjection;
    case pipeline::ReconstructionMode::kRetrieval:
      return ShapeMode::kRetrieval;
    default:
      return ShapeMode::kGeneration;
  }
}

PipelineBackend::PipelineBackend(const pipeline::ReconstructorConfig& config)
    : reconstructor_(config) {
  has_pool_ = reconstructor_.has_pool();
  pool_meshes_ = reconstructor_.pool_meshes();
  const std::string s1 = FileId(config.stage1_model), s2 = FileId(config.stage2_model),
                    bsp = FileId(config.bsp_model);
  model_version_ = "stage1 " + s1 + ", stage2 " + s2 + ", bsp " + bsp;
  if (has_pool_ && reconstructor_.pool()) {
    pool_ = std::make_unique<PoolCopy>();
    pool_->pool = *reconstructor_.pool();
    pool_id_ = pool_->pool.ContentHash();
  }
}

PipelineBackend::~PipelineBackend() = default;

BackendResult PipelineBackend::Reconstruct(const BackendCloud& cloud) {
  pipeline::PointCloudInput in;
  in.name = cloud.name;
  in.points = cloud.points;
  in.colors = cloud.colors;
  in.normals = cloud.normals;
  pipeline::SceneResult r = reconstructor_.Reconstruct(in);
  BackendResult out;
  const auto& names = labels::CadClassNames();
  for (pipeline::InstanceResult& i : r.instances) {
    BackendInstance b;
    b.cad_class = i.cad_class;
    b.class_name = (i.cad_class >= 0 && i.cad_class < static_cast<int>(names.size()))
                       ? names[i.cad_class]
                       : "unknown";
    b.score = static_cast<float>(i.score);
    b.box = i.box;
    b.mesh = std::move(i.mesh);
    b.source = i.source == pipeline::MeshSource::kProjected
                   ? ShapeMode::kProjection
                   : (i.source == pipeline::MeshSource::kRetrieved ? ShapeMode::kRetrieval
                                                                   : ShapeMode::kGeneration);
    b.pool_model_id = i.pool_model_id;
    b.neighbour_ids = i.neighbours;
    b.latent = i.latent;
    b.support = std::move(i.support);
    out.instances.push_back(std::move(b));
  }
  for (const auto& [name, ms] : r.timings) out.timings_ms[name] = ms;
  out.warnings = std::move(r.warnings);
  return out;
}

std::string PipelineBackend::compute_info() const {
  return "sparse kernels " + nn::SparseKernelsInUse();
}

bool PipelineBackend::SupportsMode(ShapeMode mode, std::string* why) const {
  if (mode == ShapeMode::kGeneration) return true;
  if (!has_pool_) {
    *why = "no CAD pool is loaded (parameter pipeline/pool)";
    return false;
  }
  if (mode == ShapeMode::kRetrieval && pool_meshes_ == 0) {
    *why =
        "the pool has no CAD meshes (parameter pipeline/pool_meshes: a tree from "
        "`dimr export pool-meshes`)";
    return false;
  }
  return true;
}

void PipelineBackend::SetMode(ShapeMode mode, int k) {
  reconstructor_.SetMode(ToPipeline(mode), k);
}

bool PipelineBackend::PoolModel(const std::string& model_id, geometry::TriangleMesh* mesh,
                                std::string* mesh_resource) const {
  std::lock_guard<std::mutex> lock(pool_mutex_);
  if (!pool_) return false;
  for (const pipeline::PoolEntry& e : pool_->pool.entries()) {
    if (e.model_id != model_id) continue;
    if (e.mesh_path.empty()) return false;
    *mesh = pipeline::ReadShapeNetMeshCanonical(e.mesh_path);
    *mesh_resource = "file://" + std::filesystem::absolute(e.mesh_path).string();
    return true;
  }
  return false;
}

}  // namespace dimr::ros1
