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

#include "dimr/core/config_fields.h"
#include "dimr/data/room.h"
#include "dimr/data/tsdf_fusion.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

enum class ScanDensity {
  kMesh,  // one point per occupied `mesh_voxel_size` voxel (ScanNet mesh-vertex-like)
  kRaw,   // every valid depth return of every frame (what a robot accumulates)
  // ScanNet's own chain: RGB-D frames fused into a TSDF, marching cubes, small-component
  // cleaning, quadric decimation to ScanNet's vertex density; the output points are the mesh
  // vertices with fused colours (tsdf_fusion.h), labelled by the nearest surface return.
  kScanNet
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
  // With axial_noise_z0 = 0 this is the structured-light form a + b z^2.
  double axial_noise_base = 0.0012;
  double axial_noise_quad = 0.0019;
  double axial_noise_z0 = 0.4;
  double noise_clip = 2.5;
  // Disparity quantisation: the inverse depth is rounded to multiples of this (1/m); the depth
  // step is then disparity_quantum * z^2 (Kinect v1: 1/8 px at f = 580 px, baseline 7.5 cm ->
  // 0.0029 / m). 0 = off.
  double disparity_quantum = 0.0;
  // Temporal averaging: each rendered frame stands for this many sensor frames taken from
  // (almost) the same pose, which the TSDF averages - a 30 Hz hand-held scan of a room has
  // thousands of frames, SynthScan renders 60. A pixel's depth is the mean of this many
  // independent noisy, quantised measurements (MeasuredDepth), so the axial noise shrinks by
  // sqrt(sensor_frames) and the disparity steps are dithered away. 1 = one measurement.
  int sensor_frames = 1;
  // Flying pixels: a return whose 4-neighbour depth differs by more than flying_pixel_edge
  // (metres) gets, with this probability, a depth between the two surfaces. 0 = off.
  double flying_pixel_probability = 0.0;
  double flying_pixel_edge = 0.08;
  // Dropout on dark surfaces: extra probability rising linearly to dark_dropout as the shaded
  // linear luminance falls from dark_luminance to 0 (structured light does not return from
  // black). Glossy surfaces (displays, lacquered furniture): extra glossy_dropout * cos^16 of
  // the incidence angle (specular saturation when looked at head-on). 0 = off.
  double dark_dropout = 0.0;
  double dark_luminance = 0.08;
  double glossy_dropout = 0.0;
  double lateral_noise_px = 0.4;
  // Dropout: random, and growing from grazing_start_deg to grazing_end_deg incidence.
  double dropout = 0.02;
  double grazing_start_deg = 70.0;
  double grazing_end_deg = 85.0;
  // Registration drift: slowly varying pose error (random walk, metres / degrees per frame).
  double drift_translation = 0.0;
  double drift_rotation_deg = 0.0;
  // Loop closure: the accumulated drift is removed linearly along the trajectory so that the
  // end meets the start again; the middle keeps a misregistration (ghosted double surfaces
  // where the loop's parts overlap), like a SLAM-registered hand-held scan.
  bool loop_closure = false;
  // Hand-held coverage: the walked part of the loop is drawn in [min_coverage, 1] per scene
  // (1 = the whole loop), so parts of the room are seen from one side only or not at all.
  double min_coverage = 1.0;
  // Scans that stop at a height (ScanNet scene0470_00: nothing above 1.37 m): with this
  // probability per scene, returns above a height drawn in [height_cap_min, height_cap_max]
  // are dropped.
  double height_cap_probability = 0.0;
  double height_cap_min = 1.3;
  double height_cap_max = 1.9;
  // Ceilings (real scans often hold part of the ceiling; SynthScan v1 never does): with this
  // probability per scene the ceiling's returns are kept (label: ignore, like clutter) and a
  // share ceiling_look_up_fraction of the frames gets a twin looking up by an angle drawn in
  // [10, ceiling_max_up_deg] degrees. 0 = the ceiling is an occluder only.
  double ceiling_probability = 0.0;
  double ceiling_look_up_fraction = 0.2;
  double ceiling_max_up_deg = 45.0;
  // Colour realism (0 / false = today's colours). Per scene: white balance = per-channel gain
  // exp(N(0, white_balance_jitter)), exposure gain exp(N(0, exposure_jitter)); per frame an
  // auto-exposure gain exp(N(0, frame_exposure_jitter)).
  double white_balance_jitter = 0.0;
  double exposure_jitter = 0.0;
  double frame_exposure_jitter = 0.0;
  // Lambert shading from one point light under the ceiling (random per scene) + ambient,
  // instead of today's fixed directional light and view term.
  bool lambert_shading = false;
  double ambient = 0.35;
  // Cast shadows of the point light (lambert_shading): a return whose shadow ray to the light
  // hits another surface keeps (1 - shadow_strength) of its direct light. 0 = off.
  double shadow_strength = 0.0;
  // Auto exposure that wanders along the scan: a smooth log-gain process (AR(1) with a
  // correlation length of 25 % of the trajectory) of this standard deviation, on top of the
  // i.i.d. frame_exposure_jitter. Surfaces seen from different parts of the loop are fused with
  // different gains (the patchy brightness of real fused scans). 0 = off.
  double exposure_drift = 0.0;
  // Multiplies every material's texture amplitude (colour realism only; 1 = as composed).
  double texture_gain = 1.0;
  // Floor patterns (colour realism): per scene wood planks (55 %: boards 9-22 cm wide along x
  // or y, each with a log-normal brightness of this sigma), tiles (25 %: 30-60 cm, sigma / 3
  // per tile, dark 6 mm grout) or a plain carpet (20 %). 0 = off.
  double floor_pattern = 0.0;
  // Material colour variety in [0, 1]: walls / floors / doors take a per-scene colour from
  // palettes of real paints, woods, tiles and carpets, furniture a per-object brightness and
  // tint jitter; blended with the room's own material by this weight.
  double material_variety = 0.0;
  // ScanNet mode: TSDF fusion and decimation settings.
  TsdfConfig tsdf;
  // Output density.
  ScanDensity density = ScanDensity::kMesh;
  double mesh_voxel_size = 0.045;  // 4.5 cm cells: ~1 point per occupied 2 cm voxel (ScanNet)
  int min_observations = 2;        // mesh mode: voxels seen fewer times are dropped
  // Mesh mode: the voxel grid is shifted by this fraction of a voxel. With 0 (today's default,
  // what the shipped models were trained on) the floor (z = 0) lies on a voxel boundary and
  // comes out as two layers of points a few millimetres apart; 0.5 puts it inside one layer
  // (docs/synthscan.md, "One floor layer").
  double mesh_grid_offset = 0.0;
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
  // SynthScan v2 realism (sensor, trajectory, colour) on top of this config; density unchanged.
  void EnableRealism();
  bool ColourRealism() const {
    return white_balance_jitter > 0 || exposure_jitter > 0 || frame_exposure_jitter > 0 ||
           exposure_drift > 0 || lambert_shading || material_variety > 0;
  }
};

// The `key=value` form of the sensor-model, trajectory, colour and TSDF knobs of ScannerConfig
// (`dimr synth --scanner 'disparity_quantum=0 tsdf_voxel_size=0.008'`): applied on top of the
// mode's defaults (after EnableRealism()); the keys are the field names (tsdf_* = tsdf.*).
const config::Fields<ScannerConfig>& ScannerFields();

// Axial depth noise sigma(z) = base + quad * (z - z0)^2 (metres).
double AxialSigma(const ScannerConfig& config, double z);
// The depth the sensor reports for true depth z: axial noise (standard_normal truncated at
// noise_clip) then disparity quantisation. The scanner uses exactly this.
double MeasuredDepth(const ScannerConfig& config, double z, double standard_normal);

// The mean of MeasuredDepth over `count` >= 1 standard normals (sensor_frames temporal
// averaging).
double AveragedDepth(const ScannerConfig& config, double z, const double* standard_normals,
                     int count);

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
  std::vector<int> object;  // index into Room::objects
  // ScanNet mode: the triangles of the decimated mesh whose vertices are `points`.
  std::vector<geometry::Vec3i> faces;
  std::vector<Eigen::Isometry3d> poses;  // map <- camera (estimated) per frame
  std::vector<ScanFrame> frames;         // only with keep_frames
  // ScanNet mode: ray_cast (all frames), then the fusion's integrate, marching_cubes, clean,
  // decimate, colour, then labels.
  Timings timings;
  std::size_t rays = 0;     // rays cast
  std::size_t returns = 0;  // valid depth returns
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
