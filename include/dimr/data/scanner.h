// SynthScan virtual RGB-D scanner: a hand-held-scan-like camera trajectory through a composed
// room, depth images by ray casting (Embree 3), a depth-noise / dropout model, optional
// registration drift, accumulation in the world frame and down-sampling to a ScanNet-like
// density. Occlusion (self and by other objects) comes from the ray casting itself, so backs
// against walls, undersides and hidden legs are missing from the output like in real scans.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "dimr/data/room.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

enum class ScanDensity {
  kMesh,  // one point per occupied `mesh_voxel_size` voxel (ScanNet mesh-vertex-like)
  kRaw    // every valid depth return of every frame (what a robot accumulates)
};
const char* ScanDensityName(ScanDensity d);
ScanDensity ScanDensityFromName(const std::string& name);  // throws InvalidArgument

struct ScannerConfig {
  // Pinhole depth camera (Structure-sensor-like).
  int width = 320;
  int height = 240;
  double fov_x_deg = 58.0;  // horizontal field of view; fy = fx (square pixels)
  double min_range = 0.35;  // metres; closer returns are dropped
  double max_range = 4.0;   // metres; farther returns are dropped
  // Trajectory: a loop walked inside the room, looking inward.
  int frames = 60;
  double min_camera_height = 1.2;
  double max_camera_height = 1.7;
  double path_inset = 0.9;     // distance of the walked loop from the walls (metres)
  double min_tilt_deg = 10.0;  // downward pitch range
  double max_tilt_deg = 40.0;
  double yaw_sweep_deg = 35.0;  // amplitude of the left/right sweep around the look-at
  // Depth noise: sigma_z(z) = axial_noise_base + axial_noise_quad * (z - 0.4)^2 (Kinect-like,
  // Nguyen et al. 2012), truncated at noise_clip sigmas; lateral noise in pixels.
  double axial_noise_base = 0.0012;
  double axial_noise_quad = 0.0019;
  double noise_clip = 2.5;
  double lateral_noise_px = 0.4;
  // Dropout: random, and growing from grazing_start_deg to grazing_end_deg incidence.
  double dropout = 0.02;
  double grazing_start_deg = 70.0;
  double grazing_end_deg = 85.0;
  // Registration drift: slowly varying pose error (random walk, metres / degrees per frame).
  double drift_translation = 0.0;
  double drift_rotation_deg = 0.0;
  // Output density.
  ScanDensity density = ScanDensity::kMesh;
  double mesh_voxel_size = 0.045;  // 4.5 cm cells: ~1 point per occupied 2 cm voxel (ScanNet)
  int min_observations = 2;        // mesh mode: voxels seen fewer times are dropped
  // Mesh mode: each output point is the 1/sigma^2-weighted mean of the voxel's returns (like
  // TSDF fusion); voxels whose fused standard error sqrt(1 / sum w) exceeds this are dropped
  // (surfaces seen only from far away stay holes, as in real reconstructions).
  double max_fused_sigma = 0.008;
  int raw_pixel_stride = 2;  // raw mode: every k-th pixel in u and v
  // Frames kept (camera-frame points) for rosbags; 0 = none.
  bool keep_frames = false;
  int frame_pixel_stride = 2;
  int threads = 0;  // ray-casting threads (0 = hardware concurrency)
  // Throws dimr::InvalidArgument naming the bad field.
  void Validate() const;
};

// One depth frame as a sensor would publish it.
struct ScanFrame {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // map <- camera (estimated, drifted)
  Eigen::Isometry3d true_pose = Eigen::Isometry3d::Identity();
  // Camera optical frame (x right, y down, z forward), metres.
  std::vector<Eigen::Vector3f> points;
  std::vector<geometry::Color> colors;
};

struct ScanResult {
  std::vector<geometry::Vec3> points;  // world frame (float-representable)
  std::vector<geometry::Color> colors;
  std::vector<int> object;               // index into Room::objects
  std::vector<Eigen::Isometry3d> poses;  // map <- camera (estimated) per frame
  std::vector<ScanFrame> frames;         // only with keep_frames
  std::size_t rays = 0;                  // rays cast
  std::size_t returns = 0;               // valid depth returns
  // Sorted CellKey()s of the true surface points every valid return hit (1 cm cells), for
  // visibility (partiality) statistics.
  std::vector<std::uint64_t> observed_cells;
};

constexpr double kObservedCell = 0.01;
// Key of the 1 cm cell of `p` for object `object` (16 bits per axis, 15 bits of object).
std::uint64_t CellKey(const geometry::Vec3& p, int object);
// True if a return of `object` hit within one cell (<= ~1-2 cm) of p.
bool ObservedNear(const ScanResult& scan, int object, const geometry::Vec3& p);

// Camera trajectory (map <- camera optical frame) for a room; deterministic in the seed.
std::vector<Eigen::Isometry3d> MakeTrajectory(const Room& room, const ScannerConfig& config,
                                              std::uint64_t seed);

// Scans the room. Objects with role kCeiling occlude but never appear in the output.
// Throws dimr::Error if Embree is unavailable in this build.
ScanResult ScanRoom(const Room& room, const ScannerConfig& config, std::uint64_t seed);

}  // namespace dimr::data
