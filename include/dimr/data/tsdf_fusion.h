// ScanNet-faithful reconstruction: RGB-D frames fused into a truncated signed distance field,
// marching cubes, small-component cleaning and quadric decimation to ScanNet's vertex density
// (the chain that made ScanNet's `vh_clean_2` meshes, whose vertices DIMR consumes).
//
// The implementation (src/data/tsdf_fusion.cpp) uses Open3D 0.16's ScalableTSDFVolume and
// marching cubes, then geometry::RemoveSmallComponents and geometry::DecimateQuadric (or, with
// open3d_simplify, Open3D's own cleaning and decimation); this header is Open3D-free (pimpl),
// so only one translation unit pays for Open3D's headers.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

#include "dimr/core/timing.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

struct TsdfConfig {
  double voxel_size = 0.01;  // TSDF voxel edge (metres); ScanNet's BundleFusion used 1 cm
  double truncation = 0.04;  // signed-distance truncation (metres), 4 voxels
  int block_resolution = 8;  // voxels per side of one allocated block (ScalableTSDFVolume unit)
  double max_depth = 4.0;    // depth beyond this is not integrated (metres)
  // Cleaning: connected components with fewer triangles are removed (floating fragments).
  int min_component_triangles = 300;
  // Decimation: target nearest-neighbour vertex spacing on a flat surface (metres); the
  // triangle budget is 2 * area / (sqrt(3)/2 * spacing^2) of the marching-cubes mesh.
  // ScanNet's vh_clean_2 rooms: NN spacing p50 1.3-2.9 cm.
  double target_spacing = 0.02;
  // 0: cleaning and decimation by geometry/mesh_simplify.h (~10x faster); 1: Open3D 0.16's
  // ClusterConnectedTriangles + SimplifyQuadricDecimation (what SynthScan v2 used before
  // 2026-12-03; kept for A/B measurements, docs/synthscan.md "Decimation").
  int open3d_simplify = 0;
  // Throws dimr::InvalidArgument naming the bad field.
  void Validate() const;
};

// One RGB-D frame: pinhole intrinsics, depth in metres along the optical axis (0 = no return),
// colour per pixel (row-major, width * height), and the (estimated) pose map <- camera optical.
struct RgbdFrame {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::vector<float> depth;
  std::vector<geometry::Color> color;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

struct FusedMesh {
  geometry::TriangleMesh mesh;          // decimated, cleaned mesh (world frame)
  std::vector<geometry::Color> colors;  // per vertex of `mesh`, fused from the frames
  std::size_t marching_cubes_vertices = 0;
  std::size_t marching_cubes_triangles = 0;
  std::size_t removed_components = 0;
  double surface_area = 0;  // of the cleaned marching-cubes mesh (m^2)
  // integrate (all frames), marching_cubes, clean, decimate, colour.
  Timings timings;
};

class TsdfFusion {
 public:
  explicit TsdfFusion(const TsdfConfig& config);  // validates
  ~TsdfFusion();
  TsdfFusion(const TsdfFusion&) = delete;
  TsdfFusion& operator=(const TsdfFusion&) = delete;

  // Integrates one frame. Throws dimr::InvalidArgument on inconsistent sizes or intrinsics.
  void Integrate(const RgbdFrame& frame);
  int frames() const { return frames_; }
  // Marching cubes, cleaning, decimation and vertex colours. An empty volume gives an empty
  // mesh. Can be called once; the volume is released afterwards.
  FusedMesh Extract();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  TsdfConfig config_;
  int frames_ = 0;
  Timings timings_;
};

}  // namespace dimr::data
