// SynthScan: synthetic scanned rooms with ScanNet / Scan2CAD / ShapeNet ground truth.
// GenerateScene() composes a room (room.h), scans it (scanner.h) and turns the result into a
// SynthScene: the point cloud DIMR consumes plus per-point semantic / instance / segment
// labels and per-instance CAD alignments and boxes. scannet_io.h / scan2cad_io.h write and
// read the scene in the real dataset formats.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/room.h"
#include "dimr/data/scanner.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

constexpr int kSemanticIgnore = 255;  // per-point semantic label of unlabelled / clutter points

struct SynthInstance {
  int id = 0;            // 1-based instance id (the ScanNet objectId + 1)
  std::string category;  // raw ScanNet-style category (aggregation label)
  int rfs_class = -1;    // 25-class label, -1 = ignore
  int cad_class = -1;    // 0..7, -1 = non-CAD
  std::string synset, model_id, family;
  bool symmetric = false;  // rotationally symmetric about up (Scan2CAD __SYM_ROTATE_UP_INF)
  // 9-DoF alignment in Scan2CAD's convention: p_scan = translation + R(rotation) *
  // diag(scale) * q, where q is a vertex of the ShapeNet model_normalized.obj (CAD objects,
  // shapenet_io.h) or of the canonical unit-box mesh (x forward, y left, z up; non-CAD objects).
  geometry::Vec3 translation = geometry::Vec3::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  geometry::Vec3 scale = geometry::Vec3::Ones();
  geometry::OrientedBox box;  // 7-DoF: centre, size (forward, left, up), heading
  int num_points = 0;
  double visible_fraction = 0.0;  // observed fraction of the placed mesh's surface
};

struct SynthScene {
  std::string name;  // "scene0000_00"
  Eigen::Matrix4d axis_alignment = Eigen::Matrix4d::Identity();
  std::vector<geometry::Vec3> points;  // float-representable coordinates
  std::vector<geometry::Color> colors;
  std::vector<int> semantic;  // 0..24 or kSemanticIgnore
  std::vector<int> instance;  // 1-based, 0 = none
  std::vector<int> segment;   // over-segmentation id (ScanNet segIndices)
  std::vector<SynthInstance> instances;
  // Room metadata (SynthScan only; empty for real ScanNet scenes).
  std::string room_shape, room_type;
  double floor_area = 0.0, room_height = 0.0;

  const SynthInstance* FindInstance(int id) const;
  // Throws dimr::InvalidArgument naming the scene when arrays disagree in length or a point
  // refers to an unknown instance / a label inconsistent with its instance.
  void Validate() const;
};

bool operator==(const SynthInstance& a, const SynthInstance& b);
bool operator==(const SynthScene& a, const SynthScene& b);
inline bool operator!=(const SynthScene& a, const SynthScene& b) { return !(a == b); }

struct SynthConfig {
  RoomConfig room;
  ScannerConfig scanner;
  double segment_size = 0.5;    // edge of the cells that split instances into segments (m)
  int min_instance_points = 5;  // objects with fewer points get no instance (like ScanNet)
  // Surface samples per object for the visible fraction: a sample counts as observed when a
  // depth return of that object hit within one 1 cm cell of it (scanner.h ObservedNear).
  int visibility_samples = 2000;
  void Validate() const;
};

// The scene seed: hash(seed, split, index), so that any shard reproduces scene `index`.
std::uint64_t SceneSeed(std::uint64_t seed, const std::string& split, int index);
// "scene%04d_00" with a per-split offset (train 0, val 5000, test 8000).
std::string SceneName(const std::string& split, int index);
// Largest scene count a split supports with its name range.
int MaxScenes(const std::string& split);

struct GeneratedScene {
  SynthScene scene;
  Room room;
  ScanResult scan;
  std::vector<std::shared_ptr<const CadModel>> cad_models;  // unique CAD models of the room
  std::map<int, int> object_of_instance;                    // instance id -> Room::objects index
};

GeneratedScene GenerateScene(const SynthConfig& config, std::uint64_t seed, const std::string& name,
                             const ModelSource& source = DefaultModelSource());

// ---------------------------------------------------------------- statistics and index
struct SceneSummary {
  std::string name;
  std::uint64_t seed = 0;
  std::string shape, room_type;
  double floor_area = 0;
  int frames = 0;
  std::size_t rays = 0, returns = 0, num_points = 0;
  std::size_t occupied_2cm = 0, occupied_5cm = 0;
  double seconds = 0;
  struct Object {
    int id = 0;
    std::string category;
    int rfs_class = -1, cad_class = -1;
    int num_points = 0;
    double visible_fraction = 0;
  };
  std::vector<Object> objects;
};

SceneSummary Summarize(const GeneratedScene& g);
// Number of occupied cells of edge `voxel` (grid anchored at the origin).
std::size_t OccupiedVoxels(const std::vector<geometry::Vec3>& points, double voxel);

// Writes the `synthscan.yaml` index (config, scenes, per-class statistics). Throws dimr::Error
// naming the path when it cannot be written.
void WriteSynthIndex(const std::string& path, const SynthConfig& config, std::uint64_t seed,
                     const std::string& split, int shard, int num_shards,
                     const std::vector<SceneSummary>& scenes);

// An 8-bit RGB image, row-major, top row first.
struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;
};

// Top-down (bird's-eye) render of a scene's cloud, `metres_per_pixel` per pixel, coloured by
// point colour or (by_instance) by instance id; highest point wins. Write it with any image
// writer (the `dimr` tools write PNG).
RgbImage RenderTopDown(const SynthScene& scene, double metres_per_pixel, bool by_instance);

// Realism statistics next to the ScanNet figures of the issue, as a Markdown table.
std::string RealismReport(const std::vector<SceneSummary>& scenes);

}  // namespace dimr::data
