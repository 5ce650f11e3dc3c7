// SynthScan scene generation, ground truth, statistics and the synthscan.yaml index.
#include "dimr/data/synthscan.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "dimr/data/labels.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/data/synth_random.h"
#include "dimr/geometry/error.h"

namespace dimr::data {
namespace {

using geometry::Vec3;
using synth::HashCombine;
using synth::HashString;
using synth::Rng;

std::uint64_t GridKey(const Vec3& p, double cell) {
  const auto q = [&](double v) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / cell)) + (1 << 20)) &
           0x1fffff;
  };
  return q(p.x()) | (q(p.y()) << 21) | (q(p.z()) << 42);
}

// Area-weighted surface samples of a mesh (deterministic).
std::vector<Vec3> SampleMesh(const geometry::TriangleMesh& m, int n, std::uint64_t seed) {
  std::vector<double> cum;
  cum.reserve(m.faces.size());
  double total = 0;
  for (const auto& f : m.faces) {
    total +=
        0.5 *
        (m.vertices[f[1]] - m.vertices[f[0]]).cross(m.vertices[f[2]] - m.vertices[f[0]]).norm();
    cum.push_back(total);
  }
  std::vector<Vec3> out;
  if (total <= 0) return out;
  Rng rng(seed);
  out.reserve(n);
  for (int i = 0; i < n; ++i) {
    const double r = rng.Uniform(0, total);
    const std::size_t fi = std::min<std::size_t>(
        std::upper_bound(cum.begin(), cum.end(), r) - cum.begin(), cum.size() - 1);
    const auto& f = m.faces[fi];
    double a = rng.Uniform(), b = rng.Uniform();
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    out.push_back(m.vertices[f[0]] + a * (m.vertices[f[1]] - m.vertices[f[0]]) +
                  b * (m.vertices[f[2]] - m.vertices[f[0]]));
  }
  return out;
}

// Scan2CAD alignment of a placed object (see SynthInstance).
void SetAlignment(const PlacedObject& o, SynthInstance* inst) {
  const Eigen::Matrix3d rz = o.Rotation();
  inst->translation = o.translation;
  if (o.cad_class >= 0 && o.model) {
    // p_world = t + Rz diag(scale) p,  p = diag(|s|/s) A^T q  (shapenet_io.h)
    const Vec3 s = o.model->nominal_size;
    const Vec3 v = o.scale.cwiseProduct(Vec3::Constant(s.norm()).cwiseQuotient(s));
    const Eigen::Matrix3d a = CanonicalToShapeNetAxes();
    inst->rotation = Eigen::Quaterniond(rz * a.transpose()).normalized();
    inst->scale = (a * v).cwiseAbs();
  } else {
    inst->rotation = Eigen::Quaterniond(rz).normalized();
    inst->scale = o.scale;
  }
}

}  // namespace

const SynthInstance* SynthScene::FindInstance(int id) const {
  for (const auto& i : instances) {
    if (i.id == id) return &i;
  }
  return nullptr;
}

void SynthScene::Validate() const {
  const std::size_t n = points.size();
  auto fail = [&](const std::string& m) { throw InvalidArgument("scene " + name + ": " + m); };
  if (colors.size() != n || semantic.size() != n || instance.size() != n || segment.size() != n)
    fail("per-point arrays differ in length");
  std::unordered_map<int, int> label_of;
  for (const auto& i : instances) {
    if (i.id < 1) fail("instance id " + std::to_string(i.id) + " < 1");
    if (label_of.count(i.id)) fail("duplicate instance id " + std::to_string(i.id));
    label_of[i.id] = i.rfs_class < 0 ? kSemanticIgnore : i.rfs_class;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const int s = semantic[k];
    if (!(s == kSemanticIgnore || (s >= 0 && s < kNumRfsClasses)))
      fail("point " + std::to_string(k) + " has semantic label " + std::to_string(s));
    if (instance[k] == 0) continue;
    auto it = label_of.find(instance[k]);
    if (it == label_of.end())
      fail("point " + std::to_string(k) + " refers to unknown instance " +
           std::to_string(instance[k]));
    if (it->second != s)
      fail("point " + std::to_string(k) + " label " + std::to_string(s) +
           " differs from its instance's " + std::to_string(it->second));
  }
}

bool operator==(const SynthInstance& a, const SynthInstance& b) {
  return a.id == b.id && a.category == b.category && a.rfs_class == b.rfs_class &&
         a.cad_class == b.cad_class && a.synset == b.synset && a.model_id == b.model_id &&
         a.family == b.family && a.symmetric == b.symmetric && a.translation == b.translation &&
         a.rotation.coeffs() == b.rotation.coeffs() && a.scale == b.scale &&
         a.box.center == b.box.center && a.box.size == b.box.size &&
         a.box.heading == b.box.heading && a.num_points == b.num_points &&
         a.visible_fraction == b.visible_fraction;
}

bool operator==(const SynthScene& a, const SynthScene& b) {
  return a.name == b.name && a.axis_alignment == b.axis_alignment && a.points == b.points &&
         a.colors == b.colors && a.semantic == b.semantic && a.instance == b.instance &&
         a.segment == b.segment && a.instances == b.instances && a.room_shape == b.room_shape &&
         a.room_type == b.room_type && a.floor_area == b.floor_area &&
         a.room_height == b.room_height;
}

void SynthConfig::Validate() const {
  room.Validate();
  scanner.Validate();
  auto fail = [](const std::string& m) { throw InvalidArgument("SynthConfig: " + m); };
  if (!(segment_size > 0.05 && segment_size <= 5)) fail("segment_size must be in (0.05, 5] m");
  if (min_instance_points < 1) fail("min_instance_points must be >= 1");
  if (visibility_samples < 10) fail("visibility_samples must be >= 10");
}

std::uint64_t SceneSeed(std::uint64_t seed, const std::string& split, int index) {
  return HashCombine(HashCombine(seed, HashString(split)), static_cast<std::uint64_t>(index));
}

int MaxScenes(const std::string& split) {
  if (split == "train") return 5000;
  if (split == "val") return 3000;
  if (split == "test") return 2000;
  throw InvalidArgument("split: expected train, val or test, got '" + split + "'");
}

std::string SceneName(const std::string& split, int index) {
  const int max = MaxScenes(split);
  if (index < 0 || index >= max)
    throw InvalidArgument("scene index " + std::to_string(index) + " out of range for split " +
                          split + " (max " + std::to_string(max) + ")");
  const int offset = split == "train" ? 0 : split == "val" ? 5000 : 8000;
  char buf[32];
  std::snprintf(buf, sizeof(buf), "scene%04d_00", offset + index);
  return buf;
}

GeneratedScene GenerateScene(const SynthConfig& config, std::uint64_t seed, const std::string& name,
                             const ModelSource& source) {
  config.Validate();
  GeneratedScene g;
  g.room = ComposeRoom(config.room, HashCombine(seed, 1), source);
  g.scan = ScanRoom(g.room, config.scanner, HashCombine(seed, 2));
  const Room& room = g.room;
  const ScanResult& scan = g.scan;
  SynthScene& s = g.scene;
  s.name = name;
  s.room_shape = room.shape;
  s.room_type = room.room_type;
  s.floor_area = room.FloorArea();
  s.room_height = room.height;

  // Instances: objects (never the ceiling) with enough points, in room order.
  std::vector<int> count(room.objects.size(), 0);
  for (int o : scan.object) ++count[o];
  std::vector<int> instance_of(room.objects.size(), 0);
  int next = 1;
  for (std::size_t o = 0; o < room.objects.size(); ++o) {
    const PlacedObject& obj = room.objects[o];
    if (obj.role == ObjectRole::kCeiling || count[o] < config.min_instance_points) continue;
    instance_of[o] = next;
    SynthInstance inst;
    inst.id = next++;
    inst.category = obj.category;
    inst.rfs_class = obj.rfs_class;
    inst.cad_class = obj.cad_class;
    inst.synset = obj.synset;
    inst.model_id = obj.model_id;
    inst.family = obj.family;
    inst.symmetric = obj.symmetric;
    SetAlignment(obj, &inst);
    inst.box = obj.Box();
    inst.num_points = count[o];
    s.instances.push_back(inst);
    g.object_of_instance[inst.id] = static_cast<int>(o);
  }
  // Per-point labels and segments.
  const std::size_t n = scan.points.size();
  s.points.resize(n);
  s.colors = scan.colors;
  s.semantic.resize(n);
  s.instance.resize(n);
  s.segment.resize(n);
  std::unordered_map<std::uint64_t, int> segment_ids;
  for (std::size_t k = 0; k < n; ++k) {
    s.points[k] = scan.points[k].cast<float>().cast<double>();
    const int o = scan.object[k];
    const int id = instance_of[o];
    s.instance[k] = id;
    const int rfs = room.objects[o].rfs_class;
    s.semantic[k] = (id == 0 || rfs < 0) ? kSemanticIgnore : rfs;
    const std::uint64_t key =
        HashCombine(GridKey(s.points[k], config.segment_size), static_cast<std::uint64_t>(o));
    auto it = segment_ids.emplace(key, static_cast<int>(segment_ids.size())).first;
    s.segment[k] = it->second;
  }
  // Visible fraction: surface samples of the placed mesh near a point of the instance.
  for (auto& inst : s.instances) {
    const PlacedObject& obj = room.objects[g.object_of_instance[inst.id]];
    const std::vector<Vec3> samples =
        SampleMesh(obj.WorldMesh(), config.visibility_samples, HashCombine(seed, 100 + inst.id));
    const int object = g.object_of_instance[inst.id];
    int seen = 0;
    for (const auto& q : samples) {
      if (ObservedNear(scan, object, q)) ++seen;
    }
    inst.visible_fraction = samples.empty() ? 0.0 : static_cast<double>(seen) / samples.size();
  }
  // Unique CAD models (for the ShapeNet tree).
  std::unordered_set<std::string> seen_models;
  for (const auto& o : room.objects) {
    if (o.cad_class >= 0 && o.model && seen_models.insert(o.model_id).second)
      g.cad_models.push_back(o.model);
  }
  return g;
}

std::size_t OccupiedVoxels(const std::vector<geometry::Vec3>& points, double voxel) {
  std::unordered_set<std::uint64_t> cells;
  cells.reserve(points.size());
  for (const auto& p : points) cells.insert(GridKey(p, voxel));
  return cells.size();
}

SceneSummary Summarize(const GeneratedScene& g) {
  SceneSummary s;
  s.name = g.scene.name;
  s.shape = g.room.shape;
  s.room_type = g.room.room_type;
  s.floor_area = g.room.FloorArea();
  s.frames = static_cast<int>(g.scan.poses.size());
  s.rays = g.scan.rays;
  s.returns = g.scan.returns;
  s.num_points = g.scene.points.size();
  s.occupied_2cm = OccupiedVoxels(g.scene.points, 0.02);
  s.occupied_5cm = OccupiedVoxels(g.scene.points, 0.05);
  for (const auto& i : g.scene.instances) {
    SceneSummary::Object o;
    o.id = i.id;
    o.category = i.category;
    o.rfs_class = i.rfs_class;
    o.cad_class = i.cad_class;
    o.num_points = i.num_points;
    o.visible_fraction = i.visible_fraction;
    s.objects.push_back(o);
  }
  return s;
}

namespace {

struct ClassStats {
  std::vector<double> points, visible;
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const std::size_t i = static_cast<std::size_t>(pos);
  const double f = pos - i;
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

std::map<std::string, ClassStats> PerCategory(const std::vector<SceneSummary>& scenes) {
  std::map<std::string, ClassStats> m;
  for (const auto& s : scenes) {
    for (const auto& o : s.objects) {
      std::string key = o.category;
      if (o.rfs_class >= 0) key = RfsClassNames()[o.rfs_class];
      if (o.rfs_class < 0) key = "clutter(" + o.category + ")";
      m[key].points.push_back(o.num_points);
      m[key].visible.push_back(o.visible_fraction);
    }
  }
  return m;
}

}  // namespace

void WriteSynthIndex(const std::string& path, const SynthConfig& c, std::uint64_t seed,
                     const std::string& split, int shard, int num_shards,
                     const std::vector<SceneSummary>& scenes) {
  YAML::Emitter y;
  y.SetDoublePrecision(10);
  y << YAML::BeginMap;
  y << YAML::Key << "synthscan" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "version" << YAML::Value << 1;
  y << YAML::Key << "seed" << YAML::Value << seed;
  y << YAML::Key << "split" << YAML::Value << split;
  y << YAML::Key << "shard" << YAML::Value << shard;
  y << YAML::Key << "num_shards" << YAML::Value << num_shards;
  y << YAML::Key << "label_set" << YAML::Value << "rfs25 (ScanNet labels.ply: nyu40 ids)";
  y << YAML::EndMap;
  y << YAML::Key << "config" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "room" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "min_objects" << YAML::Value << c.room.min_objects;
  y << YAML::Key << "max_objects" << YAML::Value << c.room.max_objects;
  y << YAML::Key << "l_shape_probability" << YAML::Value << c.room.l_shape_probability;
  y << YAML::Key << "min_side" << YAML::Value << c.room.min_side;
  y << YAML::Key << "max_side" << YAML::Value << c.room.max_side;
  y << YAML::Key << "min_height" << YAML::Value << c.room.min_height;
  y << YAML::Key << "max_height" << YAML::Value << c.room.max_height;
  y << YAML::Key << "wall_thickness" << YAML::Value << c.room.wall_thickness;
  y << YAML::Key << "max_doors" << YAML::Value << c.room.max_doors;
  y << YAML::Key << "max_windows" << YAML::Value << c.room.max_windows;
  y << YAML::Key << "window_pane" << YAML::Value << c.room.window_pane;
  y << YAML::Key << "door_closed" << YAML::Value << c.room.door_closed;
  y << YAML::Key << "studio" << YAML::Value << c.room.studio;
  y << YAML::Key << "clearance" << YAML::Value << c.room.clearance;
  y << YAML::Key << "size_jitter" << YAML::Value << c.room.size_jitter;
  y << YAML::EndMap;
  const ScannerConfig& k = c.scanner;
  y << YAML::Key << "scanner" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "width" << YAML::Value << k.width;
  y << YAML::Key << "height" << YAML::Value << k.height;
  y << YAML::Key << "fov_x_deg" << YAML::Value << k.fov_x_deg;
  y << YAML::Key << "min_range" << YAML::Value << k.min_range;
  y << YAML::Key << "max_range" << YAML::Value << k.max_range;
  y << YAML::Key << "frames" << YAML::Value << k.frames;
  y << YAML::Key << "axial_noise_base" << YAML::Value << k.axial_noise_base;
  y << YAML::Key << "axial_noise_quad" << YAML::Value << k.axial_noise_quad;
  y << YAML::Key << "lateral_noise_px" << YAML::Value << k.lateral_noise_px;
  y << YAML::Key << "dropout" << YAML::Value << k.dropout;
  y << YAML::Key << "drift_translation" << YAML::Value << k.drift_translation;
  y << YAML::Key << "drift_rotation_deg" << YAML::Value << k.drift_rotation_deg;
  y << YAML::Key << "density" << YAML::Value << ScanDensityName(k.density);
  y << YAML::Key << "mesh_voxel_size" << YAML::Value << k.mesh_voxel_size;
  y << YAML::Key << "fields" << YAML::Value << ScannerFields().Format(k);
  y << YAML::EndMap;
  y << YAML::EndMap;
  // Summary.
  std::size_t total_points = 0;
  std::map<std::string, int> per_class;
  for (const auto& s : scenes) {
    total_points += s.num_points;
    for (const auto& o : s.objects) {
      if (o.cad_class >= 0) ++per_class[CadClassNames()[o.cad_class]];
    }
  }
  y << YAML::Key << "summary" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "scenes" << YAML::Value << scenes.size();
  y << YAML::Key << "points" << YAML::Value << total_points;
  y << YAML::Key << "cad_objects_per_class" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, n] : per_class) y << YAML::Key << name << YAML::Value << n;
  y << YAML::EndMap;
  y << YAML::Key << "per_category" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, st] : PerCategory(scenes)) {
    y << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap;
    y << YAML::Key << "count" << YAML::Value << st.points.size();
    y << YAML::Key << "points_median" << YAML::Value << Percentile(st.points, 0.5);
    y << YAML::Key << "visible_median" << YAML::Value << Percentile(st.visible, 0.5);
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
  y << YAML::EndMap;
  y << YAML::Key << "scenes" << YAML::Value << YAML::BeginSeq;
  for (const auto& s : scenes) {
    y << YAML::BeginMap;
    y << YAML::Key << "name" << YAML::Value << s.name;
    y << YAML::Key << "seed" << YAML::Value << s.seed;
    y << YAML::Key << "shape" << YAML::Value << s.shape;
    y << YAML::Key << "room_type" << YAML::Value << s.room_type;
    y << YAML::Key << "floor_area" << YAML::Value << s.floor_area;
    y << YAML::Key << "frames" << YAML::Value << s.frames;
    y << YAML::Key << "points" << YAML::Value << s.num_points;
    y << YAML::Key << "occupied_2cm" << YAML::Value << s.occupied_2cm;
    y << YAML::Key << "objects" << YAML::Value << YAML::BeginSeq;
    for (const auto& o : s.objects) {
      y << YAML::Flow << YAML::BeginMap;
      y << YAML::Key << "id" << YAML::Value << o.id;
      y << YAML::Key << "category" << YAML::Value << o.category;
      y << YAML::Key << "rfs" << YAML::Value << o.rfs_class;
      y << YAML::Key << "cad" << YAML::Value << o.cad_class;
      y << YAML::Key << "points" << YAML::Value << o.num_points;
      y << YAML::Key << "visible" << YAML::Value << std::round(o.visible_fraction * 1000) / 1000;
      y << YAML::EndMap;
    }
    y << YAML::EndSeq;
    y << YAML::EndMap;
  }
  y << YAML::EndSeq;
  y << YAML::EndMap;
  std::ofstream f(path, std::ios::binary);
  if (!f) throw Error("cannot write the SynthScan index '" + path + "'");
  f << y.c_str() << "\n";
  if (!f) throw Error("error writing the SynthScan index '" + path + "'");
}

RgbImage RenderTopDown(const SynthScene& scene, double mpp, bool by_instance) {
  if (!(mpp > 0)) throw InvalidArgument("RenderTopDown: metres_per_pixel must be > 0");
  geometry::AABB b;
  for (const auto& p : scene.points) b.Extend(p);
  if (b.Empty()) throw InvalidArgument("RenderTopDown: scene " + scene.name + " has no points");
  const int margin = 10;
  const int w = static_cast<int>(b.Extent().x() / mpp) + 2 * margin;
  const int h = static_cast<int>(b.Extent().y() / mpp) + 2 * margin;
  if (w > 8000 || h > 8000) throw InvalidArgument("RenderTopDown: image too large");
  RgbImage out;
  out.width = w;
  out.height = h;
  std::vector<std::uint8_t>& img = out.rgb;
  img.assign(static_cast<std::size_t>(w) * h * 3, 255);
  std::vector<float> zbuf(static_cast<std::size_t>(w) * h, -1e9f);
  const int splat = std::max(1, static_cast<int>(std::ceil(0.025 / mpp)));
  for (std::size_t k = 0; k < scene.points.size(); ++k) {
    const Vec3& p = scene.points[k];
    geometry::Color c = scene.colors[k];
    if (by_instance) {
      const std::uint64_t hsh = synth::Mix64(static_cast<std::uint64_t>(scene.instance[k]) + 17);
      c = scene.instance[k] == 0
              ? geometry::Color(128, 128, 128)
              : geometry::Color(60 + (hsh & 0xff) % 190, 60 + ((hsh >> 8) & 0xff) % 190,
                                60 + ((hsh >> 16) & 0xff) % 190);
    }
    const int cx = margin + static_cast<int>((p.x() - b.min.x()) / mpp);
    const int cy = h - 1 - margin - static_cast<int>((p.y() - b.min.y()) / mpp);
    for (int dy = -splat / 2; dy <= splat / 2; ++dy) {
      for (int dx = -splat / 2; dx <= splat / 2; ++dx) {
        const int x = cx + dx, y = cy + dy;
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        if (p.z() <= zbuf[i]) continue;
        zbuf[i] = static_cast<float>(p.z());
        for (int ch = 0; ch < 3; ++ch) img[3 * i + ch] = c[ch];
      }
    }
  }
  return out;
}

std::string RealismReport(const std::vector<SceneSummary>& scenes) {
  // ScanNet figures of issue 3 (scene0000_00_vh_clean_2.ply).
  static const std::map<std::string, std::string> kScanNet = {
      {"trash_bin", "150-250"},   {"table", "177-533"},  {"display", "499 (tv)"},
      {"cabinet", "300-1,840"},   {"sofa", "4,732"},     {"bookshelf", "5,971"},
      {"floor", "9,974"},         {"wall", "800-2,800"}, {"chair", "215-330 (stool)"},
      {"refridgerator", "1,691"}, {"toilet", "361"}};
  std::ostringstream o;
  std::size_t pts = 0, v2 = 0, v5 = 0;
  for (const auto& s : scenes) {
    pts += s.num_points;
    v2 += s.occupied_2cm;
    v5 += s.occupied_5cm;
  }
  char buf[256];
  o << "| statistic | SynthScan | ScanNet scene0000_00 |\n|---|---|---|\n";
  std::snprintf(buf, sizeof(buf), "| points per scene (mean) | %.0f | 81,369 |\n",
                scenes.empty() ? 0.0 : static_cast<double>(pts) / scenes.size());
  o << buf;
  std::snprintf(buf, sizeof(buf), "| points per occupied 2 cm voxel | %.3f | 1.02 |\n",
                v2 ? static_cast<double>(pts) / v2 : 0.0);
  o << buf;
  std::snprintf(buf, sizeof(buf), "| points per occupied 5 cm voxel | %.3f | 1.52 |\n\n",
                v5 ? static_cast<double>(pts) / v5 : 0.0);
  o << buf;
  o << "| class | objects | points p10 | median | p90 | visible fraction median (p10-p90) | "
       "ScanNet points |\n|---|---|---|---|---|---|---|\n";
  for (const auto& [name, st] : PerCategory(scenes)) {
    const auto it = kScanNet.find(name);
    std::snprintf(buf, sizeof(buf), "| %s | %zu | %.0f | %.0f | %.0f | %.2f (%.2f-%.2f) | %s |\n",
                  name.c_str(), st.points.size(), Percentile(st.points, 0.1),
                  Percentile(st.points, 0.5), Percentile(st.points, 0.9),
                  Percentile(st.visible, 0.5), Percentile(st.visible, 0.1),
                  Percentile(st.visible, 0.9), it == kScanNet.end() ? "-" : it->second.c_str());
    o << buf;
  }
  return o.str();
}

}  // namespace dimr::data
