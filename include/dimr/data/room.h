// SynthScan room composer: room shells (rectangular and L-shaped floor plans with walls of
// finite thickness, a floor slab, an optional ceiling, doors and windows cut into walls) and
// plausible furniture arrangements (objects with their backs to walls, chairs around tables,
// sofas facing a display or coffee table, displays and clutter on top of furniture), without
// interpenetration.
//
// Every object is a canonical mesh filling the unit box [-0.5, 0.5]^3 (x forward, y left,
// z up; cad_library.h) placed by a 9-DoF transform (Scan2CAD style):
//   p_world = translation + Rz(yaw) * diag(scale) * p_canonical,
// so `translation` is the centre of the object's oriented box, `scale` its size in metres
// (forward, left, up) and `yaw` its heading (canonical +x rotated towards +y).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

// What an object is in the room; walls, floor, doors and windows are built by the composer,
// furniture and clutter come from the CAD library.
enum class ObjectRole { kWall, kFloor, kCeiling, kDoor, kWindow, kFurniture, kClutter };

// Families of the window panes RoomConfig::window_pane adds (the scanner gives glass its gloss).
inline constexpr const char* kWindowGlassFamily = "window_glass";
inline constexpr const char* kWindowBlindsFamily = "window_blinds";
const char* ObjectRoleName(ObjectRole role);

// A simple diffuse material: base colour plus a procedural value-noise texture.
struct Material {
  geometry::Vec3 albedo = geometry::Vec3::Constant(0.6);  // linear RGB in [0, 1]
  double texture_amplitude = 0.05;  // relative brightness variation of the texture
  double texture_scale = 0.1;       // texture feature size (metres)
};

struct PlacedObject {
  ObjectRole role = ObjectRole::kFurniture;
  std::string category;  // raw ScanNet-style category ("wall", "chair", "trash can", "box")
  int rfs_class = -1;    // 25-class label of its points, -1 = ignore (clutter)
  int cad_class = -1;    // 0..7 or -1
  std::string synset, model_id, family;
  geometry::TriangleMesh mesh;  // canonical frame, unit box
  geometry::Vec3 translation = geometry::Vec3::Zero();
  double yaw = 0.0;
  geometry::Vec3 scale = geometry::Vec3::Ones();
  Material material;
  int support = -1;  // index of the object it stands on (-1: the floor or a wall)
  bool symmetric = false;
  bool wall_mounted = false;  // hangs on a wall (pictures, wall TVs, radiators, curtains)
  std::shared_ptr<const CadModel> model;  // the library model (CAD and distractor objects)

  Eigen::Matrix3d Rotation() const;
  geometry::OrientedBox Box() const;
  geometry::TriangleMesh WorldMesh() const;
};

// A window pane added by RoomConfig::window_pane (glass or blinds), not a window frame.
inline bool IsWindowPane(const PlacedObject& o) {
  return o.family == kWindowGlassFamily || o.family == kWindowBlindsFamily;
}

struct Room {
  std::string shape;                     // "rect" or "L"
  std::vector<Eigen::Vector2d> outline;  // interior floor polygon, counter-clockwise
  double height = 2.7;                   // floor to ceiling (metres)
  double wall_thickness = 0.12;
  std::string room_type;  // "living", "office", "dining", "bedroom", "bathroom", "studio"
  std::vector<PlacedObject> objects;  // walls, floor, ceiling, doors, windows, furniture

  // True if the 2-D point lies inside the interior polygon.
  bool Inside(const Eigen::Vector2d& p) const;
  double FloorArea() const;
};

struct RoomConfig {
  int min_objects = 5;  // furniture + clutter + pictures per room (walls etc. not counted)
  int max_objects = 25;
  double l_shape_probability = 0.35;
  double min_side = 3.2;  // room side lengths (metres); grown with the object count
  double max_side = 8.0;
  double min_height = 2.5;
  double max_height = 3.1;
  double wall_thickness = 0.12;
  int max_doors = 2;
  int max_windows = 3;
  // Probability that a window has a pane the scanner sees (glass or closed blinds, set back 1-7 cm
  // from the wall's inner face, its own object labelled window, family kWindowGlassFamily /
  // kWindowBlindsFamily). 0 (the default) leaves windows as open frames and draws nothing, so the
  // rooms of earlier versions are unchanged.
  double window_pane = 0.0;
  // Probability that a door's leaf is closed (flush in its frame); otherwise it stands open by
  // 0.4-1.6 rad (one more draw). The default keeps the rooms of earlier versions.
  double door_closed = 0.35;
  // Probability that a room is a studio apartment (room type "studio"): the zones of a flat in
  // one open room - a sofa group, floor units against the walls (beds, kitchen units,
  // appliances when real furniture is on), a run of cabinets, a desk or a dining table, a
  // bookshelf, sometimes a bathtub - with at least 18 objects (capped by max_objects), like
  // ScanNet's apartment scans. 0 (the default) draws nothing: earlier rooms are unchanged.
  double studio = 0.0;
  bool ceiling = true;        // part of the ray-cast scene (occluder), never in the output
  double clearance = 0.03;    // minimum gap between the boxes of two objects (metres)
  double size_jitter = 0.12;  // anisotropic per-axis scale jitter around the model's nominal size
  // Throws dimr::InvalidArgument naming the bad field.
  void Validate() const;
};

// Where furniture meshes come from (the procedural CAD library by default; tests may plug in
// simpler models).
struct ModelSource {
  std::function<CadModel(int cad_class, std::uint64_t seed)> cad;
  std::function<CadModel(int kind, std::uint64_t seed)> distractor;
  std::function<const DistractorInfo&(int kind)> distractor_info;
  int num_distractor_kinds = 0;
};
ModelSource DefaultModelSource();

// Composes one room; deterministic in (config, seed, source).
Room ComposeRoom(const RoomConfig& config, std::uint64_t seed,
                 const ModelSource& source = DefaultModelSource());

// Bird's-eye overlap test of two z-rotated boxes (separating axes) combined with their
// height intervals; boxes closer than `gap` count as overlapping.
bool BoxesOverlap(const geometry::OrientedBox& a, const geometry::OrientedBox& b, double gap = 0.0);

// Per-class plausible size range (metres; forward, left, up) used to clamp the anisotropic
// scaling of CAD objects.
void CadSizeRange(int cad_class, geometry::Vec3* min_size, geometry::Vec3* max_size);

}  // namespace dimr::data
