// SynthScan room composer (see room.h).
#include "dimr/data/room.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "dimr/data/labels.h"
#include "dimr/data/synth_random.h"
#include "dimr/geometry/error.h"

namespace dimr::data {
namespace {

using synth::HashCombine;
using synth::Mix64;
using synth::Rng;

using geometry::OrientedBox;
using geometry::TriangleMesh;
using geometry::Vec3;
using Vec2 = Eigen::Vector2d;
constexpr double kPi = 3.14159265358979323846;

// Closed axis-aligned cuboid [lo, hi] with outward-facing triangles, appended to `mesh`.
void AppendBox(const Vec3& lo, const Vec3& hi, TriangleMesh* mesh) {
  const int base = static_cast<int>(mesh->vertices.size());
  for (int k = 0; k < 8; ++k) {
    mesh->vertices.emplace_back((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(),
                                (k & 4) ? hi.z() : lo.z());
  }
  static const int kFaces[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6},
                                    {0, 1, 5}, {0, 5, 4}, {2, 6, 7}, {2, 7, 3},
                                    {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  for (const auto& f : kFaces) mesh->faces.emplace_back(base + f[0], base + f[1], base + f[2]);
}

// A box given by centre and size in a frame rotated by `yaw` about z.
void AppendRotatedBox(const Vec3& center, const Vec3& size, double yaw, TriangleMesh* mesh) {
  TriangleMesh box;
  AppendBox(-0.5 * size, 0.5 * size, &box);
  box.Transform(Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix(), center);
  mesh->Append(box);
}

Eigen::Matrix3d Rz(double yaw) { return Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix(); }

// Turns a mesh given in a local metric frame (origin `origin`, rotated by `yaw`) into a placed
// object: canonical unit-box mesh + 9-DoF placement.
void SetFromLocalMesh(const TriangleMesh& local, const Vec3& origin, double yaw,
                      PlacedObject* obj) {
  const geometry::AABB b = local.Bounds();
  const Vec3 c = b.Center();
  const Vec3 e = b.Extent().cwiseMax(Vec3::Constant(1e-4));
  obj->mesh = local;
  for (auto& v : obj->mesh.vertices) v = (v - c).cwiseQuotient(e);
  obj->mesh.vertex_normals.clear();
  obj->scale = e;
  obj->yaw = yaw;
  obj->translation = origin + Rz(yaw) * c;
}

double WrapAngle(double a) {
  while (a > kPi) a -= 2 * kPi;
  while (a <= -kPi) a += 2 * kPi;
  return a;
}

Vec3 Jitter(Rng* rng, const Vec3& base, double amount) {
  return Vec3(base.x() * (1 + rng->Uniform(-amount, amount)),
              base.y() * (1 + rng->Uniform(-amount, amount)),
              base.z() * (1 + rng->Uniform(-amount, amount)));
}

Vec3 Hsv(double h, double s, double v) {
  h = std::fmod(h, 1.0) * 6.0;
  const int i = static_cast<int>(std::floor(h)) % 6;
  const double f = h - std::floor(h);
  const double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  switch (i) {
    case 0:
      return {v, t, p};
    case 1:
      return {q, v, p};
    case 2:
      return {p, v, t};
    case 3:
      return {p, q, v};
    case 4:
      return {t, p, v};
    default:
      return {v, p, q};
  }
}

// Per-category material palette (hue, saturation, value ranges) with random variation.
Material MakeMaterial(Rng* rng, ObjectRole role, int rfs) {
  Material m;
  double h = rng->Uniform(), s = rng->Uniform(0.1, 0.6), v = rng->Uniform(0.3, 0.8);
  m.texture_amplitude = rng->Uniform(0.02, 0.08);
  m.texture_scale = rng->Uniform(0.05, 0.3);
  if (role == ObjectRole::kWall || role == ObjectRole::kCeiling) {
    h = rng->Uniform(0.05, 0.6);
    s = rng->Uniform(0.0, 0.12);
    v = rng->Uniform(0.75, 0.95);
    m.texture_amplitude = rng->Uniform(0.01, 0.03);
  } else if (role == ObjectRole::kFloor) {
    if (rng->Bernoulli(0.6)) {  // wood
      h = rng->Uniform(0.05, 0.1);
      s = rng->Uniform(0.35, 0.6);
      v = rng->Uniform(0.35, 0.7);
    } else {  // tiles / carpet
      h = rng->Uniform();
      s = rng->Uniform(0.0, 0.2);
      v = rng->Uniform(0.4, 0.8);
    }
    m.texture_amplitude = rng->Uniform(0.05, 0.12);
    m.texture_scale = rng->Uniform(0.08, 0.25);
  } else if (role == ObjectRole::kDoor || rfs == kTable || rfs == kDesk || rfs == kBookshelf ||
             rfs == kCabinet) {
    if (rng->Bernoulli(0.6)) {
      h = rng->Uniform(0.05, 0.11);
      s = rng->Uniform(0.3, 0.65);
      v = rng->Uniform(0.3, 0.75);
    } else {
      s = rng->Uniform(0.0, 0.1);
      v = rng->Uniform(0.2, 0.95);
    }
  } else if (role == ObjectRole::kWindow) {
    s = 0.02;
    v = rng->Uniform(0.8, 0.95);
  } else if (rfs == kDisplay) {
    s = 0.05;
    v = rng->Uniform(0.05, 0.2);
  } else if (rfs == kBathtub) {
    s = 0.03;
    v = rng->Uniform(0.85, 0.97);
  }
  m.albedo = Hsv(h, s, v);
  return m;
}

const char* CategoryForRfs(int rfs, int cad) {
  switch (rfs) {
    case kWall:
      return "wall";
    case kFloor:
      return "floor";
    case kCabinet:
      return "cabinet";
    case kBed:
      return "bed";
    case kChair:
      return "chair";
    case kSofa:
      return "couch";
    case kTable:
      return "table";
    case kDoor:
      return "door";
    case kWindow:
      return "window";
    case kBookshelf:
      return "bookshelf";
    case kPicture:
      return "picture";
    case kCounter:
      return "counter";
    case kDesk:
      return "desk";
    case kCurtain:
      return "curtain";
    case kRefridgerator:
      return "refrigerator";
    case kShowerCurtain:
      return "shower curtain";
    case kToilet:
      return "toilet";
    case kSink:
      return "sink";
    case kBathtub:
      return "bathtub";
    case kOtherFurniture:
      return "otherfurniture";
    case kKitchenCabinet:
      return "kitchen cabinet";
    case kDisplay:
      return "monitor";
    case kTrashBin:
      return "trash can";
    case kOtherShelf:
      return "shelf";
    case kOtherTable:
      return "end table";
    default:
      break;
  }
  return cad >= 0 ? CadClassNames()[cad] : "object";
}

// What a distractor kind is good for (from the library's placement table).
enum class DistractorUse { kWallMounted, kFloorAgainstWall, kTableTop, kFloorClutter, kSkip };

struct DistractorUseInfo {
  int kind = 0;
  DistractorUse use = DistractorUse::kSkip;
  double bottom_min = 0, bottom_max = 0;
};

DistractorUseInfo ClassifyDistractor(int kind, const DistractorInfo& info) {
  DistractorUseInfo u;
  u.kind = kind;
  u.bottom_min = info.bottom_min;
  u.bottom_max = info.bottom_max;
  if (info.rfs_class == kDoor || info.rfs_class == kWindow || info.rfs_class == kWall ||
      info.rfs_class == kFloor) {
    u.use = DistractorUse::kSkip;  // the composer builds these itself
  } else if (info.placement == DistractorPlacement::kWall) {
    u.use = DistractorUse::kWallMounted;
  } else if (info.placement == DistractorPlacement::kOnSurface) {
    u.use = DistractorUse::kTableTop;
  } else {
    u.use = info.rfs_class >= 0 ? DistractorUse::kFloorAgainstWall : DistractorUse::kFloorClutter;
  }
  return u;
}

class Composer {
 public:
  Composer(const RoomConfig& cfg, std::uint64_t seed, const ModelSource& src)
      : cfg_(cfg), rng_(seed), src_(src) {}

  Room Run() {
    ProbeDistractors();
    target_ = rng_.UniformInt(cfg_.min_objects, cfg_.max_objects);
    static const char* kTypes[] = {"living", "office", "dining", "bedroom", "bathroom"};
    const double r = rng_.Uniform();
    room_.room_type = r < 0.28   ? kTypes[0]
                      : r < 0.56 ? kTypes[1]
                      : r < 0.78 ? kTypes[2]
                      : r < 0.92 ? kTypes[3]
                                 : kTypes[4];
    // No draw when off, so the rooms of earlier versions are unchanged.
    if (cfg_.studio > 0 && rng_.Bernoulli(cfg_.studio)) {
      room_.room_type = "studio";
      target_ = std::max(target_, std::min(cfg_.max_objects, 18));
    }
    BuildShell();
    FillFurniture();
    return std::move(room_);
  }

 private:
  struct Opening {
    int wall = 0;
    bool door = false;
    double s0 = 0, s1 = 0, z0 = 0, z1 = 0;
  };

  struct Wall {
    Vec2 a, b, dir, normal;  // normal points into the room
    double length = 0;
    int object = -1;
    std::vector<std::pair<double, double>> openings;  // [s0, s1] along the edge
  };

  // ------------------------------------------------------------------ shell
  void BuildShell() {
    const double scale_up = std::sqrt(std::max(1.0, (6.0 + 1.0 * target_) / 16.0));
    double lo = cfg_.min_side, hi = cfg_.max_side;
    if (room_.room_type == std::string("bathroom")) hi = std::max(lo, std::min(hi, 4.5));
    double w = std::min(hi, rng_.Uniform(lo, 0.5 * (lo + hi)) * scale_up);
    double d = std::min(hi, rng_.Uniform(lo, 0.5 * (lo + hi)) * scale_up);
    w = std::max(lo, w);
    d = std::max(lo, d);
    room_.height = rng_.Uniform(cfg_.min_height, cfg_.max_height);
    room_.wall_thickness = cfg_.wall_thickness;
    const bool l_shape =
        room_.room_type != std::string("bathroom") && rng_.Bernoulli(cfg_.l_shape_probability);
    if (l_shape) {
      w *= 1.2;
      d *= 1.2;
      const double a = w * rng_.Uniform(0.3, 0.5), b = d * rng_.Uniform(0.3, 0.5);
      room_.shape = "L";
      room_.outline = {Vec2(0, 0),         Vec2(w, 0),     Vec2(w, d - b),
                       Vec2(w - a, d - b), Vec2(w - a, d), Vec2(0, d)};
      rects_ = {{Vec2(0, 0), Vec2(w, d - b)}, {Vec2(0, d - b), Vec2(w - a, d)}};
    } else {
      room_.shape = "rect";
      room_.outline = {Vec2(0, 0), Vec2(w, 0), Vec2(w, d), Vec2(0, d)};
      rects_ = {{Vec2(0, 0), Vec2(w, d)}};
    }
    const int n = static_cast<int>(room_.outline.size());
    for (int i = 0; i < n; ++i) {
      Wall wall;
      wall.a = room_.outline[i];
      wall.b = room_.outline[(i + 1) % n];
      wall.length = (wall.b - wall.a).norm();
      wall.dir = (wall.b - wall.a) / wall.length;
      wall.normal = Vec2(-wall.dir.y(), wall.dir.x());
      walls_.push_back(wall);
    }
    PlanOpenings();
    // Floor (and ceiling) slabs: union of the room's rectangles.
    const double slab = 0.05;
    TriangleMesh floor_mesh, ceiling_mesh;
    for (const auto& r : rects_) {
      AppendBox(Vec3(r.first.x(), r.first.y(), -slab), Vec3(r.second.x(), r.second.y(), 0.0),
                &floor_mesh);
      AppendBox(Vec3(r.first.x(), r.first.y(), room_.height),
                Vec3(r.second.x(), r.second.y(), room_.height + slab), &ceiling_mesh);
    }
    PlacedObject floor;
    floor.role = ObjectRole::kFloor;
    floor.rfs_class = kFloor;
    floor.category = "floor";
    floor.family = "floor";
    floor.material = MakeMaterial(&rng_, floor.role, kFloor);
    SetFromLocalMesh(floor_mesh, Vec3::Zero(), 0.0, &floor);
    room_.objects.push_back(std::move(floor));
    const Material wall_material = MakeMaterial(&rng_, ObjectRole::kWall, kWall);
    for (auto& wall : walls_) BuildWall(&wall, wall_material);
    if (cfg_.ceiling) {
      PlacedObject ceiling;
      ceiling.role = ObjectRole::kCeiling;
      ceiling.rfs_class = -1;
      ceiling.category = "ceiling";
      ceiling.family = "ceiling";
      ceiling.material = MakeMaterial(&rng_, ceiling.role, -1);
      SetFromLocalMesh(ceiling_mesh, Vec3::Zero(), 0.0, &ceiling);
      room_.objects.push_back(std::move(ceiling));
    }
  }

  void PlanOpenings() {
    const int doors = rng_.UniformInt(1, std::max(1, cfg_.max_doors));
    const int windows = rng_.UniformInt(0, std::max(0, cfg_.max_windows));
    for (int k = 0; k < doors + windows; ++k) {
      const bool door = k < doors;
      for (int attempt = 0; attempt < 20; ++attempt) {
        const int wi = rng_.UniformInt(0, static_cast<int>(walls_.size()) - 1);
        Wall& wall = walls_[wi];
        const double width = door ? rng_.Uniform(0.8, 0.95) : rng_.Uniform(0.7, 1.6);
        const double margin = 0.25;
        if (wall.length < width + 2 * margin) continue;
        const double s0 = rng_.Uniform(margin, wall.length - margin - width);
        bool clash = false;
        for (const auto& o : wall.openings) {
          if (s0 < o.second + 0.3 && o.first < s0 + width + 0.3) clash = true;
        }
        if (clash) continue;
        Opening op;
        op.wall = wi;
        op.door = door;
        op.s0 = s0;
        op.s1 = s0 + width;
        if (door) {
          op.z0 = 0.0;
          op.z1 = std::min(room_.height - 0.2, rng_.Uniform(2.0, 2.15));
        } else {
          op.z0 = rng_.Uniform(0.75, 1.0);
          op.z1 = std::min(room_.height - 0.2, op.z0 + rng_.Uniform(0.9, 1.4));
        }
        wall.openings.emplace_back(op.s0, op.s1);
        openings_.push_back(op);
        break;
      }
    }
  }

  // Wall-local metric frame: origin at the wall box centre, x = into the room, y = along the
  // wall (from b to a), z up. Edge parameter s maps to y = L/2 - s.
  void BuildWall(Wall* wall, const Material& material) {
    const double t = cfg_.wall_thickness, h = room_.height, len = wall->length;
    const Vec3 origin(0.5 * (wall->a.x() + wall->b.x()) - wall->normal.x() * t / 2,
                      0.5 * (wall->a.y() + wall->b.y()) - wall->normal.y() * t / 2, h / 2);
    const double yaw = std::atan2(wall->normal.y(), wall->normal.x());
    std::vector<const Opening*> ops;
    for (const auto& o : openings_) {
      if (&walls_[o.wall] == wall) ops.push_back(&o);
    }
    std::sort(ops.begin(), ops.end(),
              [](const Opening* x, const Opening* y) { return x->s0 < y->s0; });
    TriangleMesh mesh;
    auto solid = [&](double s0, double s1, double z0, double z1) {
      if (s1 - s0 < 1e-6 || z1 - z0 < 1e-6) return;
      AppendBox(Vec3(-t / 2, len / 2 - s1, z0 - h / 2), Vec3(t / 2, len / 2 - s0, z1 - h / 2),
                &mesh);
    };
    double s = 0.0;
    for (const Opening* o : ops) {
      solid(s, o->s0, 0.0, h);
      solid(o->s0, o->s1, 0.0, o->z0);
      solid(o->s0, o->s1, o->z1, h);
      s = o->s1;
    }
    solid(s, len, 0.0, h);
    PlacedObject obj;
    obj.role = ObjectRole::kWall;
    obj.rfs_class = kWall;
    obj.category = "wall";
    obj.family = "wall";
    obj.material = material;
    SetFromLocalMesh(mesh, origin, yaw, &obj);
    wall->object = static_cast<int>(room_.objects.size());
    room_.objects.push_back(std::move(obj));
    for (const Opening* o : ops) BuildOpening(*wall, *o, origin, yaw);
  }

  void BuildOpening(const Wall& wall, const Opening& o, const Vec3& origin, double yaw) {
    const double t = cfg_.wall_thickness, h = room_.height, len = wall.length;
    const double y0 = len / 2 - o.s1, y1 = len / 2 - o.s0;  // y0 < y1
    const double zb = o.z0 - h / 2, zt = o.z1 - h / 2;
    const double fw = 0.06, fp = 0.015;  // frame width, protrusion into the room
    const double x0 = -t / 2 - 0.005, x1 = t / 2 + fp;
    TriangleMesh mesh;
    // Jambs and head (and a sill for windows).
    AppendBox(Vec3(x0, y0, zb), Vec3(x1, y0 + fw, zt), &mesh);
    AppendBox(Vec3(x0, y1 - fw, zb), Vec3(x1, y1, zt), &mesh);
    AppendBox(Vec3(x0, y0, zt - fw), Vec3(x1, y1, zt), &mesh);
    PlacedObject obj;
    const Vec2 in = wall.normal;
    if (o.door) {
      obj.role = ObjectRole::kDoor;
      obj.rfs_class = kDoor;
      obj.category = "door";
      obj.family = "door";
      // Leaf hinged at the y0 jamb, swung into the room by `angle`.
      const double leaf_w = (y1 - y0) - 2 * fw, leaf_t = 0.04, leaf_h = (zt - zb) - fw - 0.01;
      const double angle = rng_.Bernoulli(cfg_.door_closed) ? 0.0 : rng_.Uniform(0.4, 1.6);
      const Vec3 hinge(t / 2 - leaf_t, y0 + fw, zb);
      const Vec3 c_local(leaf_t / 2, leaf_w / 2, leaf_h / 2);
      const double a = -angle;  // about z at the hinge: the leaf (along +y) turns towards +x
      const Vec3 c = hinge + Rz(a) * c_local;
      AppendRotatedBox(c, Vec3(leaf_t, leaf_w, leaf_h), a, &mesh);
      // Keep the swing area free of furniture.
      OrientedBox zone;
      const double depth = leaf_w + 0.25;
      const Vec3 zc_local(t / 2 + depth / 2, 0.5 * (y0 + y1), 0.0);
      zone.center = origin + Rz(yaw) * zc_local;
      zone.center.z() = 1.05;
      zone.size = Vec3(depth, (y1 - y0) + 0.3, 2.1);
      zone.heading = yaw;
      reserved_.push_back(zone);
    } else {
      obj.role = ObjectRole::kWindow;
      obj.rfs_class = kWindow;
      obj.category = "window";
      obj.family = "window";
      AppendBox(Vec3(x0, y0, zb), Vec3(x1 + 0.04, y1, zb + fw), &mesh);  // sill
      AppendBox(Vec3(-0.02, 0.5 * (y0 + y1) - 0.025, zb), Vec3(0.02, 0.5 * (y0 + y1) + 0.025, zt),
                &mesh);  // mullion
      OrientedBox zone;
      const double depth = 0.45;
      zone.center = origin + Rz(yaw) * Vec3(t / 2 + depth / 2, 0.5 * (y0 + y1), 0.0);
      zone.center.z() = 0.5 * (o.z0 + o.z1);
      zone.size = Vec3(depth, (y1 - y0), o.z1 - o.z0);
      zone.heading = yaw;
      reserved_.push_back(zone);
    }
    (void)in;
    obj.material = MakeMaterial(&rng_, obj.role, obj.rfs_class);
    SetFromLocalMesh(mesh, origin, yaw, &obj);
    room_.objects.push_back(std::move(obj));
    // A scanned pane in the opening (RoomConfig::window_pane): no draw at all when off, so rooms
    // without panes are the rooms of earlier versions.
    if (!o.door && cfg_.window_pane > 0 && rng_.Bernoulli(cfg_.window_pane))
      BuildWindowPane(y0 + fw, y1 - fw, zb + fw, zt - fw, origin, yaw);
  }

  // What a depth camera sees of a real window: the glass (partly, glossy) or closed blinds, a
  // flat surface set back a few centimetres from the wall's inner face (x = t/2 in the wall frame),
  // filling the frame. Its own object (own colour), labelled window like the frame around it.
  void BuildWindowPane(double y0, double y1, double z0, double z1, const Vec3& origin, double yaw) {
    const double t = cfg_.wall_thickness, pane_t = 0.01;
    const double inset = rng_.Uniform(0.01, std::max(0.011, std::min(0.07, t - 2 * pane_t)));
    const bool blinds = rng_.Bernoulli(0.4);
    // Linear RGB: glass shows daylight, an overcast sky or a dark outside; blinds are painted.
    static const std::vector<Vec3> kGlass = {
        {0.85, 0.88, 0.92}, {0.55, 0.62, 0.72}, {0.40, 0.42, 0.44}, {0.12, 0.13, 0.15}};
    static const std::vector<Vec3> kBlinds = {
        {0.86, 0.85, 0.80}, {0.72, 0.64, 0.50}, {0.55, 0.55, 0.57}, {0.30, 0.24, 0.18}};
    const auto& palette = blinds ? kBlinds : kGlass;
    TriangleMesh mesh;
    AppendBox(Vec3(t / 2 - inset - pane_t, y0, z0), Vec3(t / 2 - inset, y1, z1), &mesh);
    PlacedObject pane;
    pane.role = ObjectRole::kWindow;
    pane.rfs_class = kWindow;
    pane.category = "window";
    pane.family = blinds ? kWindowBlindsFamily : kWindowGlassFamily;
    pane.wall_mounted = true;
    pane.material.albedo = rng_.Pick(palette);
    pane.material.texture_amplitude = blinds ? rng_.Uniform(0.03, 0.08) : rng_.Uniform(0.01, 0.03);
    pane.material.texture_scale = blinds ? rng_.Uniform(0.03, 0.06) : rng_.Uniform(0.2, 0.5);
    SetFromLocalMesh(mesh, origin, yaw, &pane);
    room_.objects.push_back(std::move(pane));
  }

  // ------------------------------------------------------------------ models
  void ProbeDistractors() {
    for (int k = 0; k < src_.num_distractor_kinds; ++k) {
      const DistractorUseInfo info = ClassifyDistractor(k, src_.distractor_info(k));
      if (info.use != DistractorUse::kSkip) distractors_.push_back(info);
    }
  }

  // A CAD model of `cad` (preferring one satisfying `want`, up to a few tries).
  CadModel PickCad(int cad, const std::function<bool(const CadModel&)>& want = nullptr) {
    CadModel m;
    for (int attempt = 0; attempt < 10; ++attempt) {
      m = src_.cad(cad, rng_.Next());
      if (!want || want(m)) break;
    }
    return m;
  }

  bool PickDistractor(DistractorUse use, CadModel* out, DistractorUseInfo* info = nullptr) {
    std::vector<const DistractorUseInfo*> kinds;
    for (const auto& d : distractors_) {
      if (d.use == use) kinds.push_back(&d);
    }
    if (kinds.empty()) return false;
    const DistractorUseInfo* d = rng_.Pick(kinds);
    *out = src_.distractor(d->kind, rng_.Next());
    if (info) *info = *d;
    return true;
  }

  Vec3 SizeFor(const CadModel& m) {
    Vec3 size = Jitter(&rng_, m.nominal_size, cfg_.size_jitter);
    if (m.cad_class >= 0) {
      Vec3 lo, hi;
      CadSizeRange(m.cad_class, &lo, &hi);
      size = size.cwiseMax(lo).cwiseMin(hi);
    } else {
      size = size.cwiseMax(Vec3::Constant(0.02)).cwiseMin(Vec3(2.5, 3.0, 2.4));
    }
    if (m.symmetric_about_z) size.y() = size.x();
    return size;
  }

  PlacedObject FromModel(const CadModel& m, const Vec3& size) {
    PlacedObject o;
    o.role = m.rfs_class < 0 ? ObjectRole::kClutter : ObjectRole::kFurniture;
    o.rfs_class = m.rfs_class;
    o.cad_class = m.cad_class;
    o.synset = m.synset;
    o.model_id = m.model_id;
    o.family = m.family;
    o.category = m.rfs_class < 0 ? (m.family.empty() ? "object" : m.family)
                                 : CategoryForRfs(m.rfs_class, m.cad_class);
    o.mesh = m.mesh;
    o.symmetric = m.symmetric_about_z;
    o.model = std::make_shared<const CadModel>(m);
    o.mesh.vertex_normals.clear();
    // Vertex colours stay: real furniture has its own (procedural models have none).
    o.mesh.attributes.clear();
    o.scale = size;
    o.material = MakeMaterial(&rng_, o.role, o.rfs_class);
    if (!m.mesh.vertex_colors.empty()) {  // real furniture: its own (mean) colour
      Vec3 mean = Vec3::Zero();
      for (const auto& c : m.mesh.vertex_colors)
        for (int k = 0; k < 3; ++k) mean[k] += std::pow(c[k] / 255.0, 2.2);
      o.material.albedo = mean / static_cast<double>(m.mesh.vertex_colors.size());
    }
    return o;
  }

  // ------------------------------------------------------------------ free space
  bool InsideRoom(const OrientedBox& box) const {
    const Eigen::Matrix3d r = Rz(box.heading);
    const Vec3 hx = r.col(0) * box.size.x() / 2, hy = r.col(1) * box.size.y() / 2;
    for (double u = -1; u <= 1.0001; u += 0.25) {
      for (double v = -1; v <= 1.0001; v += 0.25) {
        if (std::abs(u) < 0.99 && std::abs(v) < 0.99) continue;  // the rim suffices
        const Vec3 p = box.center + u * hx + v * hy;
        if (!room_.Inside(Vec2(p.x(), p.y()))) return false;
      }
    }
    for (const auto& q : room_.outline) {  // no reflex corner inside the box
      const Vec3 d = Vec3(q.x(), q.y(), box.center.z()) - box.center;
      if (std::abs(d.dot(r.col(0))) < box.size.x() / 2 - 1e-6 &&
          std::abs(d.dot(r.col(1))) < box.size.y() / 2 - 1e-6)
        return false;
    }
    return true;
  }

  bool Free(const OrientedBox& box, double gap) const {
    if (box.center.z() - box.size.z() / 2 < -1e-6) return false;
    if (box.center.z() + box.size.z() / 2 > room_.height - 0.05) return false;
    if (!InsideRoom(box)) return false;
    for (const auto& o : room_.objects) {
      if (o.role == ObjectRole::kFurniture || o.role == ObjectRole::kClutter) {
        if (BoxesOverlap(box, o.Box(), gap)) return false;
      }
    }
    for (const auto& z : reserved_) {
      if (BoxesOverlap(box, z, 0.0)) return false;
    }
    return true;
  }

  int Add(PlacedObject o, int support = -1) {
    o.support = support;
    room_.objects.push_back(std::move(o));
    ++placed_;
    return static_cast<int>(room_.objects.size()) - 1;
  }

  // Places `o` (size set) with its back to a wall; returns its index or -1.
  int PlaceAgainstWall(PlacedObject o, int wall_index = -1, double s_hint = -1, double z0 = 0.0,
                       bool check = true) {
    for (int attempt = 0; attempt < 25; ++attempt) {
      int wi = wall_index;
      if (wi < 0) {  // length-weighted wall choice
        double total = 0;
        for (const auto& w : walls_) total += w.length;
        double r = rng_.Uniform(0, total);
        wi = 0;
        for (; wi + 1 < static_cast<int>(walls_.size()); ++wi) {
          if (r < walls_[wi].length) break;
          r -= walls_[wi].length;
        }
      }
      const Wall& w = walls_[wi];
      const double half = o.scale.y() / 2 + 0.02;
      if (w.length < 2 * half) continue;
      double s = (s_hint >= 0 && attempt < 6) ? s_hint + rng_.Uniform(-0.3, 0.3) * attempt
                                              : rng_.Uniform(half, w.length - half);
      if (attempt % 5 == 4) s = rng_.Bernoulli(0.5) ? half : w.length - half;  // corners
      s = std::clamp(s, half, w.length - half);
      const double off = o.scale.x() / 2 + rng_.Uniform(0.005, 0.04);
      const Vec2 p = w.a + w.dir * s + w.normal * off;
      o.yaw = std::atan2(w.normal.y(), w.normal.x());
      o.translation = Vec3(p.x(), p.y(), z0 + o.scale.z() / 2);
      if (!check || Free(o.Box(), cfg_.clearance)) {
        last_wall_ = wi;
        last_s_ = s;
        return Add(std::move(o));
      }
    }
    return -1;
  }

  // Places `o` freely on the floor (inside the room, random or given yaw).
  int PlaceFree(PlacedObject o, double yaw = std::numeric_limits<double>::quiet_NaN(),
                double margin = 0.4) {
    for (int attempt = 0; attempt < 40; ++attempt) {
      const auto& r = rng_.Pick(rects_);
      const Vec2 lo = r.first + Vec2::Constant(margin), hi = r.second - Vec2::Constant(margin);
      if ((hi.array() <= lo.array()).any()) continue;
      o.translation =
          Vec3(rng_.Uniform(lo.x(), hi.x()), rng_.Uniform(lo.y(), hi.y()), o.scale.z() / 2);
      o.yaw = std::isnan(yaw) ? rng_.Uniform(-kPi, kPi) : yaw;
      if (Free(o.Box(), cfg_.clearance)) return Add(std::move(o));
    }
    return -1;
  }

  // Places `o` on the top surface of object `support`; `back` = put it near the support's
  // back edge facing the support's forward direction (displays on desks).
  int PlaceOnTop(PlacedObject o, int support, bool back) {
    const PlacedObject& s = room_.objects[support];
    const double top = s.translation.z() + s.scale.z() / 2;
    if (top + o.scale.z() > room_.height - 0.1) return -1;
    for (int attempt = 0; attempt < 15; ++attempt) {
      double fx, fy, yaw;
      if (back) {
        fx = -(s.scale.x() / 2 - o.scale.x() / 2 - 0.04);
        fy = rng_.Uniform(-0.2, 0.2) * std::max(0.0, s.scale.y() - o.scale.y());
        yaw = s.yaw + rng_.Uniform(-0.15, 0.15);
      } else {
        const double mx = std::max(0.0, s.scale.x() / 2 - o.scale.maxCoeff() / 2 - 0.02);
        const double my = std::max(0.0, s.scale.y() / 2 - o.scale.maxCoeff() / 2 - 0.02);
        fx = rng_.Uniform(-mx, mx);
        fy = rng_.Uniform(-my, my);
        yaw = rng_.Uniform(-kPi, kPi);
      }
      o.translation = s.translation + Rz(s.yaw) * Vec3(fx, fy, 0.0);
      o.translation.z() = top + o.scale.z() / 2 + 0.001;
      o.yaw = WrapAngle(yaw);
      // The footprint must rest on the support.
      bool on = true;
      for (int k = 0; k < 4; ++k) {
        const Vec3 corner = o.translation + Rz(o.yaw) * Vec3((k & 1 ? 0.5 : -0.5) * o.scale.x(),
                                                             (k & 2 ? 0.5 : -0.5) * o.scale.y(), 0);
        const Vec3 d = Rz(s.yaw).transpose() * (corner - s.translation);
        if (std::abs(d.x()) > s.scale.x() / 2 + 1e-6 || std::abs(d.y()) > s.scale.y() / 2 + 1e-6)
          on = false;
      }
      if (on && Free(o.Box(), 0.01)) return Add(std::move(o), support);
    }
    return -1;
  }

  bool Budget(int n = 1) const { return placed_ + n <= target_; }

  // ------------------------------------------------------------------ groups
  void TableWithChairs() {
    if (!Budget(3)) return;
    CadModel tm = PickCad(kCadTable, [](const CadModel& m) {
      return m.rfs_class != kDesk && m.nominal_size.z() > 0.6;
    });
    PlacedObject table = FromModel(tm, SizeFor(tm));
    table.scale.z() = std::clamp(table.scale.z(), 0.68, 0.8);
    const double yaw =
        (rng_.Bernoulli(0.8) ? rng_.UniformInt(0, 3) * kPi / 2 : rng_.Uniform(-kPi, kPi)) +
        rng_.Uniform(-0.05, 0.05);
    const int ti = PlaceFree(table, yaw, 1.0);
    if (ti < 0) return;
    const CadModel cm = PickCad(kCadChair, [](const CadModel& m) {
      return m.rfs_class == kChair && m.nominal_size.z() > 0.7;
    });
    const Vec3 chair_size = SizeFor(cm);
    const PlacedObject& t = room_.objects[ti];
    const Vec3 tc = t.translation, ts = t.scale;
    const double ty = t.yaw;
    // Candidate seats: along both long sides and at the two ends.
    struct Seat {
      double side_yaw;
      double offset;
      double half_depth;
    };
    std::vector<Seat> seats;
    const int per_side = std::max(1, static_cast<int>(ts.y() / 0.6));
    for (int k = 0; k < per_side; ++k) {
      const double off = (k + 0.5) * ts.y() / per_side - ts.y() / 2;
      seats.push_back({0.0, off, ts.x() / 2});
      seats.push_back({kPi, -off, ts.x() / 2});
    }
    if (ts.x() > 0.55) {
      seats.push_back({kPi / 2, 0.0, ts.y() / 2});
      seats.push_back({-kPi / 2, 0.0, ts.y() / 2});
    }
    const int want = rng_.UniformInt(2, std::min<int>(8, seats.size()));
    for (int k = 0; k < static_cast<int>(seats.size()) && want > 0; ++k) {
      const int j = rng_.UniformInt(k, static_cast<int>(seats.size()) - 1);
      std::swap(seats[k], seats[j]);
    }
    int made = 0;
    for (const Seat& seat : seats) {
      if (made >= want || !Budget()) break;
      PlacedObject chair = FromModel(cm, chair_size);
      const double dir = ty + seat.side_yaw;  // from the table centre towards the seat
      const double dist = seat.half_depth + chair.scale.x() / 2 + rng_.Uniform(0.06, 0.25);
      const Vec3 c = tc + Rz(dir) * Vec3(dist, seat.offset, 0.0);
      chair.translation = Vec3(c.x(), c.y(), chair.scale.z() / 2);
      chair.yaw = WrapAngle(dir + kPi + rng_.Uniform(-0.15, 0.15));  // faces the table
      if (Free(chair.Box(), cfg_.clearance)) {
        Add(std::move(chair));
        ++made;
      }
    }
    TableTopClutter(ti, rng_.UniformInt(0, 3));
  }

  void DeskGroup() {
    if (!Budget(2)) return;
    CadModel dm = PickCad(kCadTable, [](const CadModel& m) {
      return m.rfs_class == kDesk || m.nominal_size.z() > 0.65;
    });
    PlacedObject desk = FromModel(dm, SizeFor(dm));
    desk.scale.z() = std::clamp(desk.scale.z(), 0.68, 0.8);
    const int di = PlaceAgainstWall(desk);
    if (di < 0) return;
    const PlacedObject& d = room_.objects[di];
    const Vec3 dc = d.translation, ds = d.scale;
    const double dy = d.yaw;
    if (Budget()) {
      const CadModel cm = PickCad(kCadChair, [](const CadModel& m) {
        return m.rfs_class == kChair && m.nominal_size.z() > 0.7;
      });
      PlacedObject chair = FromModel(cm, SizeFor(cm));
      const Vec3 c = dc + Rz(dy) * Vec3(ds.x() / 2 + chair.scale.x() / 2 + rng_.Uniform(0.05, 0.3),
                                        rng_.Uniform(-0.2, 0.2) * ds.y(), 0.0);
      chair.translation = Vec3(c.x(), c.y(), chair.scale.z() / 2);
      chair.yaw = WrapAngle(dy + kPi + rng_.Uniform(-0.4, 0.4));
      if (Free(chair.Box(), cfg_.clearance)) Add(std::move(chair));
    }
    if (Budget() && rng_.Bernoulli(0.8)) {
      const CadModel mm = PickCad(kCadDisplay, [](const CadModel& m) {
        return m.family.find("wall") == std::string::npos && m.nominal_size.z() < 0.8;
      });
      PlacedObject disp = FromModel(mm, SizeFor(mm));
      disp.scale.x() = std::min(disp.scale.x(), 0.4 * ds.x());
      PlaceOnTop(disp, di, true);
    }
    if (Budget() && rng_.Bernoulli(0.5)) {
      const CadModel bm = PickCad(kCadTrashBin);
      PlacedObject bin = FromModel(bm, SizeFor(bm));
      PlaceAgainstWall(
          bin, last_wall_,
          last_s_ + (rng_.Bernoulli(0.5) ? 1 : -1) * (ds.y() / 2 + bin.scale.y() / 2 + 0.1));
    }
    TableTopClutter(di, rng_.UniformInt(0, 2));
  }

  void SofaGroup() {
    if (!Budget(2)) return;
    const CadModel sm = PickCad(kCadSofa);
    PlacedObject sofa = FromModel(sm, SizeFor(sm));
    const int si = PlaceAgainstWall(sofa);
    if (si < 0) return;
    const Vec3 sc = room_.objects[si].translation, ss = room_.objects[si].scale;
    const double sy = room_.objects[si].yaw;
    if (Budget() && rng_.Bernoulli(0.75)) {  // coffee table in front of the sofa
      const CadModel tm = PickCad(kCadTable, [](const CadModel& m) {
        return m.nominal_size.z() < 0.6 && m.rfs_class != kDesk;
      });
      PlacedObject table = FromModel(tm, SizeFor(tm));
      table.scale.z() = std::clamp(table.scale.z(), 0.35, 0.55);
      table.scale.y() = std::min(table.scale.y(), 0.9 * ss.y());
      const Vec3 c =
          sc + Rz(sy) * Vec3(ss.x() / 2 + table.scale.x() / 2 + rng_.Uniform(0.3, 0.5), 0.0, 0.0);
      table.translation = Vec3(c.x(), c.y(), table.scale.z() / 2);
      table.yaw = sy + (rng_.Bernoulli(0.5) ? 0.0 : kPi);
      if (Free(table.Box(), cfg_.clearance)) {
        const int ti = Add(std::move(table));
        TableTopClutter(ti, rng_.UniformInt(0, 2));
      }
    }
    if (Budget(2)) {  // display on a cabinet on the wall the sofa faces
      const Vec2 o(sc.x(), sc.y()), f(std::cos(sy), std::sin(sy));
      int best = -1;
      double best_t = 1e9, best_s = 0;
      for (int wi = 0; wi < static_cast<int>(walls_.size()); ++wi) {
        const Wall& w = walls_[wi];
        if (w.normal.dot(f) > -0.7) continue;  // must face the sofa
        // o + t f = a + s dir
        Eigen::Matrix2d m;
        m << f.x(), -w.dir.x(), f.y(), -w.dir.y();
        if (std::abs(m.determinant()) < 1e-9) continue;
        const Vec2 ts = m.inverse() * (w.a - o);
        if (ts.x() > 0 && ts.y() > 0 && ts.y() < w.length && ts.x() < best_t) {
          best = wi;
          best_t = ts.x();
          best_s = ts.y();
        }
      }
      if (best >= 0) {
        const CadModel cm =
            PickCad(kCadCabinet, [](const CadModel& m) { return m.nominal_size.z() < 1.0; });
        PlacedObject stand = FromModel(cm, SizeFor(cm));
        stand.scale.z() = std::min(stand.scale.z(), 0.75);
        const int ci = PlaceAgainstWall(stand, best, best_s);
        const CadModel mm = PickCad(kCadDisplay);
        PlacedObject disp = FromModel(mm, SizeFor(mm));
        if (ci >= 0 && mm.family.find("wall") == std::string::npos) {
          disp.scale.x() = std::min(disp.scale.x(), 0.5 * room_.objects[ci].scale.x());
          PlaceOnTop(disp, ci, true);
        } else if (Budget()) {
          disp.wall_mounted = true;
          PlaceAgainstWall(disp, best, best_s, rng_.Uniform(0.8, 1.2));
        }
      }
    }
  }

  void WallSingle(int cad) {
    if (!Budget()) return;
    const CadModel m =
        PickCad(cad, [](const CadModel& x) { return x.family.find("wall") == std::string::npos; });
    PlacedObject o = FromModel(m, SizeFor(m));
    const int i = PlaceAgainstWall(o);
    if (i >= 0 && (cad == kCadCabinet || cad == kCadBookshelf) &&
        room_.objects[i].scale.z() < 1.3 && rng_.Bernoulli(0.5)) {
      TableTopClutter(i, rng_.UniformInt(1, 2));
    }
  }

  void Armchair() {
    if (!Budget()) return;
    const CadModel m = PickCad(kCadChair);
    PlacedObject o = FromModel(m, SizeFor(m));
    // Face roughly towards the room centre.
    Vec2 c = Vec2::Zero();
    for (const auto& p : room_.outline) c += p;
    c /= static_cast<double>(room_.outline.size());
    for (int attempt = 0; attempt < 5; ++attempt) {
      PlacedObject tmp = o;
      const int i = PlaceFree(tmp, 0.0, 0.5);
      if (i < 0) return;
      PlacedObject& placed = room_.objects[i];
      const Vec2 p(placed.translation.x(), placed.translation.y());
      placed.yaw = WrapAngle(std::atan2(c.y() - p.y(), c.x() - p.x()) + rng_.Uniform(-0.5, 0.5));
      PlacedObject moved = placed;
      room_.objects.pop_back();
      --placed_;
      if (Free(moved.Box(), cfg_.clearance)) {
        Add(std::move(moved));
        return;
      }
    }
  }

  void WallMounted() {
    if (!Budget()) return;
    CadModel m;
    DistractorUseInfo info;
    double bottom = 0;
    if (rng_.Bernoulli(0.8) && PickDistractor(DistractorUse::kWallMounted, &m, &info)) {
      bottom = rng_.Uniform(info.bottom_min, info.bottom_max);
    } else {
      m = PickCad(kCadDisplay,
                  [](const CadModel& x) { return x.family.find("wall") != std::string::npos; });
      bottom = rng_.Uniform(0.8, 1.2);
    }
    PlacedObject o = FromModel(m, SizeFor(m));
    o.wall_mounted = true;
    if (bottom + o.scale.z() > room_.height - 0.1) return;
    PlaceAgainstWall(o, -1, -1, bottom);
  }

  void FloorDistractor(DistractorUse use) {
    if (!Budget()) return;
    CadModel m;
    if (!PickDistractor(use, &m)) return;
    PlacedObject o = FromModel(m, SizeFor(m));
    if (use == DistractorUse::kFloorAgainstWall || rng_.Bernoulli(0.7)) {
      PlaceAgainstWall(o);
    } else {
      PlaceFree(o, std::numeric_limits<double>::quiet_NaN(), 0.3);
    }
  }

  void TableTopClutter(int support, int count) {
    for (int k = 0; k < count && Budget(); ++k) {
      CadModel m;
      if (!PickDistractor(DistractorUse::kTableTop, &m)) return;
      PlacedObject o = FromModel(m, SizeFor(m));
      const PlacedObject& s = room_.objects[support];
      const double limit = 0.6 * std::min(s.scale.x(), s.scale.y());
      if (o.scale.x() > limit || o.scale.y() > limit)
        o.scale *= limit / o.scale.head<2>().maxCoeff();
      PlaceOnTop(o, support, false);
    }
  }

  void FillFurniture() {
    const std::string type = room_.room_type;
    if (type == "office") {
      const int desks = rng_.UniformInt(1, 4);
      for (int k = 0; k < desks; ++k) DeskGroup();
      if (rng_.Bernoulli(0.3)) TableWithChairs();
      WallSingle(kCadBookshelf);
      WallSingle(kCadCabinet);
    } else if (type == "living") {
      SofaGroup();
      if (rng_.Bernoulli(0.6)) Armchair();
      WallSingle(kCadBookshelf);
      if (rng_.Bernoulli(0.4)) WallSingle(kCadSofa);
    } else if (type == "dining") {
      TableWithChairs();
      if (rng_.Bernoulli(0.3)) TableWithChairs();
      WallSingle(kCadCabinet);
    } else if (type == "bedroom") {
      FloorDistractor(DistractorUse::kFloorAgainstWall);
      WallSingle(kCadCabinet);
      if (rng_.Bernoulli(0.6)) DeskGroup();
      WallSingle(kCadBookshelf);
    } else if (type == "studio") {
      // An apartment in one room: living, sleeping / kitchen units, storage, work or dining.
      SofaGroup();
      WallSingle(kCadBookshelf);
      const int units = rng_.UniformInt(2, 4);
      for (int k = 0; k < units; ++k) WallSingle(kCadCabinet);
      FloorDistractor(DistractorUse::kFloorAgainstWall);
      FloorDistractor(DistractorUse::kFloorAgainstWall);
      if (rng_.Bernoulli(0.6)) DeskGroup();
      if (rng_.Bernoulli(0.5)) TableWithChairs();
      if (rng_.Bernoulli(0.3)) WallSingle(kCadBathtub);
    } else {  // bathroom
      WallSingle(kCadBathtub);
      WallSingle(kCadCabinet);
      WallSingle(kCadTrashBin);
    }
    // Fill up to the target with singles, clutter and pictures.
    for (int round = 0; round < 60 && placed_ < target_; ++round) {
      const double r = rng_.Uniform();
      if (r < 0.12) {
        WallSingle(kCadTrashBin);
      } else if (r < 0.22) {
        WallSingle(kCadCabinet);
      } else if (r < 0.30) {
        WallSingle(kCadBookshelf);
      } else if (r < 0.40) {
        WallMounted();
      } else if (r < 0.48) {
        FloorDistractor(DistractorUse::kFloorClutter);
      } else if (r < 0.53) {
        FloorDistractor(DistractorUse::kFloorAgainstWall);
      } else if (r < 0.60) {
        Armchair();
      } else if (r < 0.66 && type != "bathroom") {
        DeskGroup();
      } else if (r < 0.70 && type != "bathroom") {
        TableWithChairs();
      } else {
        std::vector<int> supports;
        for (int i = 0; i < static_cast<int>(room_.objects.size()); ++i) {
          const auto& o = room_.objects[i];
          if ((o.cad_class == kCadTable || o.cad_class == kCadCabinet) && o.support < 0 &&
              o.scale.z() < 1.3)
            supports.push_back(i);
        }
        if (supports.empty()) {
          WallSingle(kCadTrashBin);
        } else {
          TableTopClutter(rng_.Pick(supports), 1);
        }
      }
    }
  }

  const RoomConfig& cfg_;
  Rng rng_;
  const ModelSource& src_;
  Room room_;
  std::vector<Wall> walls_;
  std::vector<Opening> openings_;
  std::vector<std::pair<Vec2, Vec2>> rects_;
  std::vector<OrientedBox> reserved_;
  std::vector<DistractorUseInfo> distractors_;
  int target_ = 0;
  int placed_ = 0;
  int last_wall_ = 0;
  double last_s_ = 0;
};

}  // namespace

const char* ObjectRoleName(ObjectRole role) {
  switch (role) {
    case ObjectRole::kWall:
      return "wall";
    case ObjectRole::kFloor:
      return "floor";
    case ObjectRole::kCeiling:
      return "ceiling";
    case ObjectRole::kDoor:
      return "door";
    case ObjectRole::kWindow:
      return "window";
    case ObjectRole::kFurniture:
      return "furniture";
    case ObjectRole::kClutter:
      return "clutter";
  }
  return "unknown";
}

Eigen::Matrix3d PlacedObject::Rotation() const { return Rz(yaw); }

geometry::OrientedBox PlacedObject::Box() const {
  OrientedBox b;
  b.center = translation;
  b.size = scale;
  b.heading = yaw;
  return b;
}

geometry::TriangleMesh PlacedObject::WorldMesh() const {
  TriangleMesh m;
  m.vertices.reserve(mesh.vertices.size());
  const Eigen::Matrix3d r = Rz(yaw);
  for (const auto& v : mesh.vertices) m.vertices.push_back(translation + r * v.cwiseProduct(scale));
  m.faces = mesh.faces;
  return m;
}

bool Room::Inside(const Eigen::Vector2d& p) const {
  bool in = false;
  const std::size_t n = outline.size();
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const auto& a = outline[i];
    const auto& b = outline[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

double Room::FloorArea() const {
  double a = 0;
  const std::size_t n = outline.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto& p = outline[i];
    const auto& q = outline[(i + 1) % n];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * a;
}

void RoomConfig::Validate() const {
  auto fail = [](const std::string& m) { throw InvalidArgument("RoomConfig: " + m); };
  if (min_objects < 0 || max_objects < min_objects || max_objects > 200)
    fail("need 0 <= min_objects <= max_objects <= 200");
  if (!(l_shape_probability >= 0 && l_shape_probability <= 1))
    fail("l_shape_probability must be in [0, 1]");
  if (!(min_side >= 2.0 && max_side >= min_side && max_side <= 30.0))
    fail("need 2 <= min_side <= max_side <= 30 (metres)");
  if (!(min_height >= 2.2 && max_height >= min_height && max_height <= 6.0))
    fail("need 2.2 <= min_height <= max_height <= 6 (metres)");
  if (!(wall_thickness > 0.01 && wall_thickness < 1.0)) fail("wall_thickness must be in (0.01, 1)");
  if (max_doors < 1 || max_doors > 6) fail("max_doors must be in [1, 6]");
  if (max_windows < 0 || max_windows > 10) fail("max_windows must be in [0, 10]");
  if (!(window_pane >= 0 && window_pane <= 1)) fail("window_pane must be in [0, 1]");
  if (!(door_closed >= 0 && door_closed <= 1)) fail("door_closed must be in [0, 1]");
  if (!(studio >= 0 && studio <= 1)) fail("studio must be in [0, 1]");
  if (!(clearance >= 0 && clearance < 0.5)) fail("clearance must be in [0, 0.5)");
  if (!(size_jitter >= 0 && size_jitter < 0.5)) fail("size_jitter must be in [0, 0.5)");
}

ModelSource DefaultModelSource() {
  ModelSource s;
  s.cad = &GenerateCadModel;
  s.distractor = &GenerateDistractor;
  s.distractor_info = &GetDistractorInfo;
  s.num_distractor_kinds = NumDistractorKinds();
  return s;
}

Room ComposeRoom(const RoomConfig& config, std::uint64_t seed, const ModelSource& source) {
  config.Validate();
  if (!source.cad) throw InvalidArgument("ComposeRoom: the model source has no CAD generator");
  if (source.num_distractor_kinds > 0 && (!source.distractor || !source.distractor_info))
    throw InvalidArgument("ComposeRoom: the model source has no distractor generator");
  Composer c(config, seed, source);
  return c.Run();
}

bool BoxesOverlap(const geometry::OrientedBox& a, const geometry::OrientedBox& b, double gap) {
  const double az0 = a.center.z() - a.size.z() / 2, az1 = a.center.z() + a.size.z() / 2;
  const double bz0 = b.center.z() - b.size.z() / 2, bz1 = b.center.z() + b.size.z() / 2;
  if (az1 <= bz0 + 1e-6 || bz1 <= az0 + 1e-6) return false;
  const Eigen::Vector2d axes[4] = {{std::cos(a.heading), std::sin(a.heading)},
                                   {-std::sin(a.heading), std::cos(a.heading)},
                                   {std::cos(b.heading), std::sin(b.heading)},
                                   {-std::sin(b.heading), std::cos(b.heading)}};
  const Eigen::Vector2d d = (b.center - a.center).head<2>();
  for (const auto& ax : axes) {
    const double ra =
        0.5 * (a.size.x() * std::abs(axes[0].dot(ax)) + a.size.y() * std::abs(axes[1].dot(ax)));
    const double rb =
        0.5 * (b.size.x() * std::abs(axes[2].dot(ax)) + b.size.y() * std::abs(axes[3].dot(ax)));
    if (std::abs(d.dot(ax)) >= ra + rb + gap) return false;
  }
  return true;
}

void CadSizeRange(int cad_class, geometry::Vec3* min_size, geometry::Vec3* max_size) {
  // forward (depth), left (width), up (height), metres.
  static const double kRanges[kNumCadClasses][6] = {
      {0.35, 0.35, 0.3, 1.3, 2.4, 0.85},   // table (incl. coffee tables and desks)
      {0.35, 0.35, 0.4, 1.0, 1.0, 1.3},    // chair (incl. stools, armchairs)
      {0.2, 0.4, 0.7, 0.6, 2.2, 2.3},      // bookshelf
      {0.6, 1.0, 0.55, 2.0, 3.2, 1.1},     // sofa (>= 2 seats: narrower is an armchair)
      {0.18, 0.18, 0.2, 0.6, 0.6, 0.9},    // trash bin
      {0.3, 0.3, 0.4, 0.9, 2.2, 2.1},      // cabinet
      {0.03, 0.25, 0.2, 0.4, 1.8, 1.1},    // display
      {0.55, 1.2, 0.35, 1.1, 2.0, 0.75}};  // bathtub
  if (cad_class < 0 || cad_class >= kNumCadClasses)
    throw InvalidArgument("CadSizeRange: cad_class " + std::to_string(cad_class) +
                          " out of range [0, 7]");
  const double* r = kRanges[cad_class];
  *min_size = Vec3(r[0], r[1], r[2]);
  *max_size = Vec3(r[3], r[4], r[5]);
}

}  // namespace dimr::data
