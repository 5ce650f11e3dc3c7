// TSDF fusion -> marching cubes -> cleaning -> quadric decimation (see tsdf_fusion.h).
// The only translation unit that includes Open3D (its headers cost ~10 s to compile).
#include "dimr/data/tsdf_fusion.h"

#ifdef DIMR_HAVE_OPEN3D
#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/pipelines/integration/ScalableTSDFVolume.h>
#include <open3d/utility/Logging.h>
#endif
#ifdef _OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>
#include <tuple>

#include "dimr/geometry/error.h"
#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/mesh_simplify.h"

namespace dimr::data {

#ifdef DIMR_HAVE_OPEN3D
namespace o3d = open3d;
#endif

void TsdfConfig::Validate() const {
  auto fail = [](const std::string& m) { throw InvalidArgument("TsdfConfig: " + m); };
  if (!(voxel_size >= 0.002 && voxel_size <= 0.2)) fail("voxel_size must be in [0.002, 0.2] m");
  if (!(truncation >= 2 * voxel_size && truncation <= 1.0))
    fail("truncation must be in [2 * voxel_size, 1] m");
  if (block_resolution < 4 || block_resolution > 64 ||
      (block_resolution & (block_resolution - 1)) != 0)
    fail("block_resolution must be a power of two in [4, 64]");
  if (!(max_depth > 0.1 && max_depth <= 20)) fail("max_depth must be in (0.1, 20] m");
  if (min_component_triangles < 0) fail("min_component_triangles must be >= 0");
  if (open3d_simplify != 0 && open3d_simplify != 1) fail("open3d_simplify must be 0 or 1");
  if (!(target_spacing >= voxel_size && target_spacing <= 0.5))
    fail("target_spacing must be in [voxel_size, 0.5] m");
}

#ifdef DIMR_HAVE_OPEN3D
struct TsdfFusion::Impl {
  explicit Impl(const TsdfConfig& c)
      : volume(c.voxel_size, c.truncation, o3d::pipelines::integration::TSDFVolumeColorType::RGB8,
               c.block_resolution, 4) {}
  o3d::pipelines::integration::ScalableTSDFVolume volume;
  bool extracted = false;
};

TsdfFusion::TsdfFusion(const TsdfConfig& config) : config_(config) {
  config_.Validate();
  static std::once_flag quiet;
  std::call_once(quiet,
                 []() { o3d::utility::SetVerbosityLevel(o3d::utility::VerbosityLevel::Error); });
  impl_ = std::make_unique<Impl>(config_);
}

TsdfFusion::~TsdfFusion() = default;

void TsdfFusion::Integrate(const RgbdFrame& f) {
  if (impl_->extracted) throw Error("TsdfFusion::Integrate: called after Extract()");
  const std::size_t n = static_cast<std::size_t>(std::max(0, f.width)) * std::max(0, f.height);
  if (f.width < 1 || f.height < 1 || f.depth.size() != n || f.color.size() != n)
    throw InvalidArgument("TsdfFusion::Integrate: frame " + std::to_string(frames_) + " is " +
                          std::to_string(f.width) + "x" + std::to_string(f.height) + " with " +
                          std::to_string(f.depth.size()) + " depths and " +
                          std::to_string(f.color.size()) + " colours");
  if (!(f.fx > 0 && f.fy > 0 && std::isfinite(f.cx) && std::isfinite(f.cy)))
    throw InvalidArgument("TsdfFusion::Integrate: frame " + std::to_string(frames_) +
                          " has invalid intrinsics");
  if (!f.pose.matrix().allFinite())
    throw InvalidArgument("TsdfFusion::Integrate: frame " + std::to_string(frames_) +
                          " has a non-finite pose");
  o3d::geometry::Image depth, color;
  depth.Prepare(f.width, f.height, 1, 4);
  color.Prepare(f.width, f.height, 3, 1);
  float* d = depth.PointerAs<float>();
  std::uint8_t* c = color.data_.data();
  const float max_depth = static_cast<float>(config_.max_depth);
  for (std::size_t i = 0; i < n; ++i) {
    const float z = f.depth[i];
    d[i] = (std::isfinite(z) && z > 0 && z <= max_depth) ? z : 0.0f;
    for (int k = 0; k < 3; ++k) c[3 * i + k] = f.color[i][k];
  }
  ScopedTimer timer(&timings_, "integrate");
#ifdef _OPENMP
  // Open3D opens one OpenMP region per 8^3-voxel block: on a loaded machine their barriers
  // cost ~1 ms each (0.7 s per frame measured). One thread per scan; scenes run in parallel.
  omp_set_num_threads(1);
#endif
  const o3d::geometry::RGBDImage rgbd(color, depth);
  const o3d::camera::PinholeCameraIntrinsic intrinsic(f.width, f.height, f.fx, f.fy, f.cx, f.cy);
  impl_->volume.Integrate(rgbd, intrinsic, f.pose.inverse().matrix());
  ++frames_;
}

namespace {

// Triangle budget of a regular lattice with `spacing` over `area`.
int DecimationTarget(double area, double spacing) {
  const double tri_area = std::sqrt(3.0) / 4.0 * spacing * spacing;
  return static_cast<int>(std::clamp(area / tri_area, 4.0, 2.0e9));
}

// Vertices, faces and (when it has them) 8-bit vertex colours of an Open3D mesh; vertices
// without a colour are grey downstream (Extract).
geometry::TriangleMesh ToMesh(const o3d::geometry::TriangleMesh& m) {
  geometry::TriangleMesh out;
  out.vertices.assign(m.vertices_.begin(), m.vertices_.end());
  out.faces.assign(m.triangles_.begin(), m.triangles_.end());
  if (m.HasVertexColors()) {
    out.vertex_colors.resize(out.vertices.size());
    for (std::size_t i = 0; i < out.vertices.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        out.vertex_colors[i][k] = static_cast<std::uint8_t>(
            std::clamp(std::lround(m.vertex_colors_[i][k] * 255.0), 0L, 255L));
      }
    }
  }
  return out;
}

// Open3D 0.16's cleaning and decimation (open3d_simplify = 1): `fine` gets the cleaned mesh
// with its colours, the return value the decimated one.
geometry::TriangleMesh Open3dSimplify(o3d::geometry::TriangleMesh* mc, const TsdfConfig& config,
                                      geometry::TriangleMesh* fine, FusedMesh* out) {
  Stopwatch watch;
  if (config.min_component_triangles > 0) {
    std::vector<int> cluster;
    std::vector<std::size_t> cluster_size;
    std::vector<double> cluster_area;
    std::tie(cluster, cluster_size, cluster_area) = mc->ClusterConnectedTriangles();
    std::vector<bool> remove(mc->triangles_.size(), false);
    for (std::size_t t = 0; t < cluster.size(); ++t) {
      remove[t] = cluster[t] < 0 || cluster_size[cluster[t]] <
                                        static_cast<std::size_t>(config.min_component_triangles);
    }
    for (std::size_t s : cluster_size) {
      if (s < static_cast<std::size_t>(config.min_component_triangles)) ++out->removed_components;
    }
    mc->RemoveTrianglesByMask(remove);
    mc->RemoveUnreferencedVertices();
  }
  mc->RemoveDegenerateTriangles();
  *fine = ToMesh(*mc);
  out->timings.Add("clean", watch.ElapsedMs());
  geometry::TriangleMesh dec;
  if (mc->triangles_.empty()) return dec;
  watch.Restart();
  out->surface_area = mc->GetSurfaceArea();
  const int target = DecimationTarget(out->surface_area, config.target_spacing);
  std::shared_ptr<o3d::geometry::TriangleMesh> d;
  if (static_cast<std::size_t>(target) < mc->triangles_.size()) {
    d = mc->SimplifyQuadricDecimation(target, std::numeric_limits<double>::infinity(), 1.0);
    d->RemoveUnreferencedVertices();
    dec.vertices.assign(d->vertices_.begin(), d->vertices_.end());
    dec.faces.assign(d->triangles_.begin(), d->triangles_.end());
  } else {
    dec.vertices = fine->vertices;
    dec.faces = fine->faces;
  }
  out->timings.Add("decimate", watch.ElapsedMs());
  return dec;
}

}  // namespace

FusedMesh TsdfFusion::Extract() {
  if (impl_->extracted) throw Error("TsdfFusion::Extract: called twice");
  impl_->extracted = true;
  FusedMesh out;
  out.timings = timings_;
  Stopwatch watch;
  std::shared_ptr<o3d::geometry::TriangleMesh> mc = impl_->volume.ExtractTriangleMesh();
  impl_->volume.Reset();
  out.timings.Add("marching_cubes", watch.ElapsedMs());
  if (!mc || mc->triangles_.empty()) return out;
  out.marching_cubes_vertices = mc->vertices_.size();
  out.marching_cubes_triangles = mc->triangles_.size();
  geometry::TriangleMesh fine, dec;
  if (config_.open3d_simplify) {
    dec = Open3dSimplify(mc.get(), config_, &fine, &out);
    mc.reset();
  } else {
    // The marching-cubes mesh in our arrays, then small-component cleaning (floating fragments
    // of noise and flying pixels) and degenerate faces.
    watch.Restart();
    fine = ToMesh(*mc);
    mc.reset();
    out.removed_components =
        geometry::RemoveSmallComponents(&fine, config_.min_component_triangles).removed_components;
    out.timings.Add("clean", watch.ElapsedMs());
    if (!fine.faces.empty()) {
      // Quadric decimation to the triangle budget of a regular lattice with `target_spacing`.
      watch.Restart();
      out.surface_area = fine.SurfaceArea();
      geometry::QuadricDecimationConfig dc;
      dc.target_faces =
          static_cast<std::size_t>(DecimationTarget(out.surface_area, config_.target_spacing));
      if (dc.target_faces < fine.faces.size()) {
        dec = geometry::DecimateQuadric(fine.vertices, fine.faces, dc);
      } else {
        dec.vertices = fine.vertices;
        dec.faces = fine.faces;
      }
      out.timings.Add("decimate", watch.ElapsedMs());
    }
  }
  if (dec.faces.empty()) return out;
  // Vertex colours of the decimated vertices: those of the nearest fine vertex.
  watch.Restart();
  std::vector<geometry::Color> fine_color = std::move(fine.vertex_colors);
  fine_color.resize(fine.vertices.size(), geometry::Color(128, 128, 128));
  out.mesh.vertices = std::move(dec.vertices);
  out.mesh.faces = std::move(dec.faces);
  const geometry::KdTree tree(std::move(fine.vertices));
  out.colors.reserve(out.mesh.vertices.size());
  for (const auto& v : out.mesh.vertices) {
    const auto nn = tree.Nearest(v);
    out.colors.push_back(nn.first >= 0 ? fine_color[nn.first] : geometry::Color(128, 128, 128));
  }
  out.timings.Add("colour", watch.ElapsedMs());
  return out;
}
#else
struct TsdfFusion::Impl {};
TsdfFusion::TsdfFusion(const TsdfConfig& config) : config_(config) {
  config_.Validate();
  throw Error("TsdfFusion: this build of dimr has no Open3D (libopen3d-dev) - cannot fuse a TSDF");
}
TsdfFusion::~TsdfFusion() = default;
void TsdfFusion::Integrate(const RgbdFrame&) {}
FusedMesh TsdfFusion::Extract() { return {}; }
#endif

}  // namespace dimr::data
