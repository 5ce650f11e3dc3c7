// SynthScan virtual RGB-D scanner (see scanner.h).
#include "dimr/data/scanner.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>

#include "dimr/core/parallel.h"
#include "dimr/data/labels.h"
#include "dimr/data/synth_random.h"
#include "dimr/data/tsdf_fusion.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/kdtree.h"

#ifdef DIMR_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

namespace dimr::data {
namespace {

using synth::HashCombine;
using synth::Mix64;
using synth::Rng;

using geometry::Color;
using geometry::Vec3;
using Vec2 = Eigen::Vector2d;
constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxSensorFrames = 256;

double Deg(double d) { return d * kPi / 180.0; }

// Smooth 3-D value noise in [-1, 1] (trilinear interpolation of hashed lattice values).
double ValueNoise(const Vec3& p, std::uint64_t salt) {
  const Vec3 f(std::floor(p.x()), std::floor(p.y()), std::floor(p.z()));
  const Vec3 t = p - f;
  const std::int64_t ix = static_cast<std::int64_t>(f.x()), iy = static_cast<std::int64_t>(f.y()),
                     iz = static_cast<std::int64_t>(f.z());
  auto lattice = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
    const std::uint64_t h = HashCombine(HashCombine(HashCombine(salt, x), y), z);
    return static_cast<double>(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;
  };
  auto smooth = [](double x) { return x * x * (3 - 2 * x); };
  const double sx = smooth(t.x()), sy = smooth(t.y()), sz = smooth(t.z());
  double v = 0;
  for (int k = 0; k < 8; ++k) {
    const int dx = k & 1, dy = (k >> 1) & 1, dz = (k >> 2) & 1;
    const double w = (dx ? sx : 1 - sx) * (dy ? sy : 1 - sy) * (dz ? sz : 1 - sz);
    v += w * lattice(ix + dx, iy + dy, iz + dz);
  }
  return v;
}

Color Shade(const PlacedObject& obj, const Vec3& albedo, std::uint64_t salt, const Vec3& p,
            const Vec3& n, const Vec3& view_dir, Rng* rng) {
  const Material& m = obj.material;
  const double tex =
      1.0 + m.texture_amplitude * (ValueNoise(p / m.texture_scale, salt) +
                                   0.5 * ValueNoise(p / (0.25 * m.texture_scale), salt + 1));
  static const Vec3 kLight = Vec3(0.3, 0.2, 0.93).normalized();
  const double shade = 0.45 + 0.4 * std::max(0.0, n.dot(kLight)) + 0.2 * std::abs(n.dot(view_dir));
  Color c;
  for (int k = 0; k < 3; ++k) {
    double v = albedo[k] * tex * shade;
    v = std::pow(std::clamp(v, 0.0, 1.0), 1.0 / 2.2) * 255.0 + rng->Normal(0.0, 2.0);
    c[k] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
  }
  return c;
}

// Per-scene look of SynthScan v2 (colour realism): per-object albedo and gloss, white balance
// and exposure, one point light.
struct SceneLook {
  std::vector<Vec3> albedo;
  std::vector<double> gloss;
  Vec3 gain = Vec3::Ones();
  Vec3 light = Vec3::Zero();
  double ambient = 0.35;
  // Floor pattern: 0 none (carpet), 1 planks, 2 tiles.
  int floor_kind = 0;
  int floor_axis = 0;  // planks run along x (0) or y (1)
  double floor_width = 0.15;
  double floor_sigma = 0;
  std::uint64_t floor_salt = 0;
};

// Brightness factor of the floor pattern at p (planks: one log-normal factor per board,
// boards staggered in length; tiles: one per tile and dark grout lines).
double FloorPattern(const SceneLook& look, const Vec3& p) {
  if (look.floor_kind == 0 || look.floor_sigma <= 0) return 1.0;
  auto unit_normal = [](std::uint64_t h) {
    // Sum of 4 uniforms (Irwin-Hall), scaled to unit variance: a cheap normal-like draw.
    double s = 0;
    for (int k = 0; k < 4; ++k) {
      h = Mix64(h + 0x9e3779b97f4a7c15ULL);
      s += static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
    }
    return (s - 2.0) * std::sqrt(3.0);
  };
  const double a = look.floor_axis == 0 ? p.y() : p.x();  // across the boards
  const double b = look.floor_axis == 0 ? p.x() : p.y();  // along the boards
  if (look.floor_kind == 1) {
    const std::int64_t board = static_cast<std::int64_t>(std::floor(a / look.floor_width));
    // Boards of 1.2 m, staggered per row.
    const double offset = 0.37 * static_cast<double>(board % 3);
    const std::int64_t piece = static_cast<std::int64_t>(std::floor((b + offset) / 1.2));
    const std::uint64_t h = HashCombine(HashCombine(look.floor_salt, board), piece);
    return std::exp(look.floor_sigma * unit_normal(h));
  }
  const std::int64_t ia = static_cast<std::int64_t>(std::floor(a / look.floor_width));
  const std::int64_t ib = static_cast<std::int64_t>(std::floor(b / look.floor_width));
  const double fa = a - look.floor_width * ia, fb = b - look.floor_width * ib;
  const double grout = 0.006;
  if (fa < grout || fb < grout) return 0.45;
  return std::exp(look.floor_sigma / 3.0 *
                  unit_normal(HashCombine(HashCombine(look.floor_salt, ia), ib)));
}

SceneLook MakeLook(const Room& room, const ScannerConfig& cfg, std::uint64_t seed) {
  // Linear-RGB palettes of real interiors (paints, woods, tiles, carpets, upholstery).
  static const std::vector<Vec3> kWalls = {
      {0.80, 0.80, 0.78}, {0.78, 0.72, 0.62}, {0.55, 0.56, 0.58}, {0.62, 0.50, 0.36},
      {0.45, 0.55, 0.68}, {0.50, 0.60, 0.45}, {0.75, 0.62, 0.30}, {0.35, 0.30, 0.27},
      {0.85, 0.84, 0.82}, {0.70, 0.66, 0.60}};
  static const std::vector<Vec3> kFloors = {
      {0.55, 0.36, 0.18}, {0.18, 0.10, 0.05}, {0.42, 0.26, 0.12}, {0.22, 0.22, 0.24},
      {0.08, 0.12, 0.25}, {0.65, 0.60, 0.50}, {0.75, 0.75, 0.73}, {0.10, 0.10, 0.10},
      {0.30, 0.06, 0.05}, {0.35, 0.30, 0.22}};
  static const std::vector<Vec3> kDoors = {
      {0.78, 0.78, 0.76}, {0.45, 0.28, 0.14}, {0.15, 0.09, 0.05}, {0.40, 0.40, 0.42}};
  static const std::vector<Vec3> kFurniture = {
      {0.03, 0.03, 0.03}, {0.80, 0.80, 0.80}, {0.50, 0.05, 0.04}, {0.04, 0.06, 0.25},
      {0.10, 0.30, 0.08}, {0.60, 0.40, 0.05}, {0.25, 0.10, 0.04}, {0.25, 0.25, 0.27}};
  Rng rng(HashCombine(seed, 0x1007c0ULL));
  SceneLook look;
  look.ambient = cfg.ambient;
  const double v = cfg.material_variety;
  const Vec3 paint = rng.Pick(kWalls), accent = rng.Pick(kWalls);
  const Vec3 floor = rng.Pick(kFloors), door = rng.Pick(kDoors);
  for (const auto& o : room.objects) {
    Vec3 target = o.material.albedo;
    double gloss = 0;
    const bool textured = !o.mesh.vertex_colors.empty();  // real furniture keeps its texture
    switch (textured ? ObjectRole::kCeiling : o.role) {
      case ObjectRole::kCeiling:
        break;
      case ObjectRole::kWall:
        // One paint per room (a quarter accent walls); each wall lit differently (windows,
        // lamps: log-normal sigma 0.2 of its brightness).
        target = (rng.Bernoulli(0.25) ? accent : paint) * std::exp(rng.Normal(0, 0.2));
        break;
      case ObjectRole::kFloor:
        target = floor;
        gloss = 0.2;
        break;
      case ObjectRole::kDoor:
      case ObjectRole::kWindow:
        if (IsWindowPane(o)) {
          // A pane keeps its own colour (daylight, sky, blinds), glass is glossy.
          target = o.material.albedo * std::exp(rng.Normal(0, 0.1));
          gloss = o.family == kWindowGlassFamily ? 0.8 : 0.0;
        } else {
          target = door * std::exp(rng.Normal(0, 0.05));
        }
        break;
      default: {
        if (rng.Bernoulli(0.3)) {
          target = rng.Pick(kFurniture);
        } else {
          const double b = std::exp(rng.Normal(0, 0.6));
          for (int k = 0; k < 3; ++k) target[k] *= b * std::exp(rng.Normal(0, 0.15));
        }
        if (o.cad_class == kCadDisplay) {
          gloss = 1.0;
        } else if (rng.Bernoulli(0.25)) {
          gloss = 0.6;
        }
      }
    }
    target = target.cwiseMax(0.01).cwiseMin(0.92);
    look.albedo.push_back((1 - v) * o.material.albedo + v * target);
    look.gloss.push_back(v > 0 ? gloss : (o.cad_class == kCadDisplay ? 1.0 : 0.0));
  }
  // Point light under the ceiling near the room centre.
  Vec3 lo = Vec3::Constant(1e9), hi = Vec3::Constant(-1e9);
  for (const auto& p : room.outline) {
    lo.head<2>() = lo.head<2>().cwiseMin(p);
    hi.head<2>() = hi.head<2>().cwiseMax(p);
  }
  look.light = Vec3(rng.Uniform(0.3, 0.7) * (hi.x() - lo.x()) + lo.x(),
                    rng.Uniform(0.3, 0.7) * (hi.y() - lo.y()) + lo.y(), room.height - 0.2);
  if (cfg.floor_pattern > 0) {
    // Own stream: the palette draws above stay as they were.
    Rng frng(HashCombine(seed, 0xf100bULL));
    const double kind = frng.Uniform();
    look.floor_kind = kind < 0.55 ? 1 : (kind < 0.8 ? 2 : 0);
    look.floor_axis = frng.Bernoulli(0.5) ? 1 : 0;
    look.floor_width = look.floor_kind == 1 ? frng.Uniform(0.09, 0.22) : frng.Uniform(0.3, 0.6);
    look.floor_sigma = cfg.floor_pattern;
    look.floor_salt = frng.Fork();
  }
  const double exposure = std::exp(rng.Normal(0, cfg.exposure_jitter));
  for (int k = 0; k < 3; ++k)
    look.gain[k] = exposure * std::exp(rng.Normal(0, cfg.white_balance_jitter));
  return look;
}

double Texture(const Material& m, std::uint64_t salt, const Vec3& p, double gain) {
  const double t = 1.0 + gain * m.texture_amplitude *
                             (ValueNoise(p / m.texture_scale, salt) +
                              0.5 * ValueNoise(p / (0.25 * m.texture_scale), salt + 1));
  return std::max(t, 0.05);
}

double Luminance(const Vec3& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

// v2 shading: albedo x texture x (ambient + Lambert from the point light with distance
// fall-off), white balance and exposure, gamma, sensor noise. `n` faces the camera.
Color ShadeV2(const Vec3& albedo, double tex, const SceneLook& look, double frame_gain,
              const Vec3& p, const Vec3& n, double direct_share, Rng* rng) {
  Vec3 l = look.light - p;
  const double d = std::max(l.norm(), 1e-6);
  l /= d;
  const double falloff = std::min(1.0, (2.0 / d) * (2.0 / d));
  const double irradiance =
      look.ambient + (1 - look.ambient) * std::max(0.0, n.dot(l)) * falloff * direct_share;
  Color c;
  for (int k = 0; k < 3; ++k) {
    double v = 1.3 * albedo[k] * tex * irradiance * look.gain[k] * frame_gain;
    v = std::pow(std::clamp(v, 0.0, 1.0), 1.0 / 2.2) * 255.0 + rng->Normal(0.0, 2.0);
    c[k] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
  }
  return c;
}

// Inward offset of an orthogonal, counter-clockwise polygon.
std::vector<Vec2> InsetPolygon(const std::vector<Vec2>& poly, double d) {
  const std::size_t n = poly.size();
  std::vector<Vec2> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2& prev = poly[(i + n - 1) % n];
    const Vec2& cur = poly[i];
    const Vec2& next = poly[(i + 1) % n];
    const Vec2 e0 = (cur - prev).normalized(), e1 = (next - cur).normalized();
    const Vec2 n0(-e0.y(), e0.x()), n1(-e1.y(), e1.x());
    out[i] = cur + d * (n0 + n1);
  }
  return out;
}

struct Return {
  Eigen::Vector3f world;
  Eigen::Vector3f bin;  // noise-free depth in the (drifted) estimated frame
  Eigen::Vector3f cam;
  Color color;
  float weight;  // 1 / sigma^2 of the depth measurement
  int object;
  int u;               // pixel column
  bool keep_frame;     // on the frame (rosbag) pixel grid
  bool keep_raw;       // on the raw-density pixel grid
  std::uint64_t cell;  // (object, 1 cm cell) of the true surface point
};

// Open-addressing accumulator keyed by (voxel, object).
class VoxelAccumulator {
 public:
  struct Entry {
    std::uint64_t voxel = 0;
    std::int32_t object = -1;  // -1 = empty slot
    std::uint32_t count = 0;
    double w = 0;  // sum of weights (1 / sigma^2 of the observations)
    double sx = 0, sy = 0, sz = 0;
    std::uint32_t r = 0, g = 0, b = 0;
  };
  // `offset`: the grid is shifted by this fraction of a voxel (voxel k spans [k - offset,
  // k + 1 - offset) voxels).
  VoxelAccumulator(double voxel, double offset) : inv_(1.0 / voxel), offset_(offset) {
    slots_.resize(1 << 16);
  }

  static std::uint64_t Pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    const std::int64_t o = 1 << 20;
    return (static_cast<std::uint64_t>(x + o) & 0x1fffff) |
           ((static_cast<std::uint64_t>(y + o) & 0x1fffff) << 21) |
           ((static_cast<std::uint64_t>(z + o) & 0x1fffff) << 42);
  }
  // Adds the measurement `p` to the voxel of `bin` (the noise-free measurement: binning by
  // the noisy point would bias the voxels next to a surface towards the noise tails).
  void Add(const Eigen::Vector3f& bin, const Eigen::Vector3f& p, const Color& c, int object,
           double weight) {
    const std::uint64_t key = Pack(static_cast<std::int64_t>(std::floor(bin.x() * inv_ + offset_)),
                                   static_cast<std::int64_t>(std::floor(bin.y() * inv_ + offset_)),
                                   static_cast<std::int64_t>(std::floor(bin.z() * inv_ + offset_)));
    if (size_ * 2 >= slots_.size()) Grow();
    Entry& e = Find(key, object);
    if (e.object < 0) {
      e.voxel = key;
      e.object = object;
      ++size_;
    }
    ++e.count;
    e.w += weight;
    e.sx += weight * p.x();
    e.sy += weight * p.y();
    e.sz += weight * p.z();
    e.r += c[0];
    e.g += c[1];
    e.b += c[2];
  }
  std::vector<Entry> Entries() const {
    std::vector<Entry> out;
    out.reserve(size_);
    for (const auto& e : slots_) {
      if (e.object >= 0) out.push_back(e);
    }
    std::sort(out.begin(), out.end(), [](const Entry& a, const Entry& b) {
      return a.voxel != b.voxel ? a.voxel < b.voxel : a.object < b.object;
    });
    return out;
  }

 private:
  Entry& Find(std::uint64_t key, int object) {
    const std::size_t mask = slots_.size() - 1;
    std::size_t i = Mix64(key * 131 + static_cast<std::uint64_t>(object)) & mask;
    while (slots_[i].object >= 0 && (slots_[i].voxel != key || slots_[i].object != object))
      i = (i + 1) & mask;
    return slots_[i];
  }
  void Grow() {
    std::vector<Entry> old;
    old.swap(slots_);
    slots_.assign(old.size() * 2, Entry());
    for (const auto& e : old) {
      if (e.object >= 0) Find(e.voxel, e.object) = e;
    }
  }
  double inv_;
  double offset_;
  std::vector<Entry> slots_;
  std::size_t size_ = 0;
};

// Open-addressing set of 64-bit keys (key ~0 is reserved as "empty").
class HashSet64 {
 public:
  HashSet64() : slots_(1 << 16, kEmpty) {}
  void Insert(std::uint64_t key) {
    if (size_ * 2 >= slots_.size()) Grow();
    if (Put(key)) ++size_;
  }
  std::vector<std::uint64_t> Sorted() const {
    std::vector<std::uint64_t> out;
    out.reserve(size_);
    for (auto k : slots_) {
      if (k != kEmpty) out.push_back(k);
    }
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  static constexpr std::uint64_t kEmpty = ~0ULL;
  bool Put(std::uint64_t key) {
    const std::size_t mask = slots_.size() - 1;
    std::size_t i = Mix64(key) & mask;
    while (slots_[i] != kEmpty) {
      if (slots_[i] == key) return false;
      i = (i + 1) & mask;
    }
    slots_[i] = key;
    return true;
  }
  void Grow() {
    std::vector<std::uint64_t> old(slots_.size() * 2, kEmpty);
    old.swap(slots_);
    for (auto k : old) {
      if (k != kEmpty) Put(k);
    }
  }
  std::vector<std::uint64_t> slots_;
  std::size_t size_ = 0;
};

#ifdef DIMR_HAVE_EMBREE
// Embree picks its kernels at run time, and its kernels for different instruction sets return
// hit distances that differ in the last bits. Mesh-mode scans bin the noise-free hits into
// voxels; where a surface lies on a voxel boundary (the floor at z = 0) those bits move hits
// between two voxel layers and so change which voxels reach min_observations: one seed's scan
// had 15079 points on the machine that pinned it, 14728 with AVX2 kernels, 14888 with SSE4.2
// (ScannerTest.DefaultModesArePinned). Capping Embree at AVX2, which every supported machine
// has, makes `dimr synth` give the same rooms on every machine. One thread: the scanner
// parallelises over image rows itself.
constexpr const char* kEmbreeConfig = "threads=1,max_isa=avx2";

RTCDevice SharedDevice() {
  static std::once_flag once;
  static RTCDevice device = nullptr;
  std::call_once(once, []() { device = rtcNewDevice(kEmbreeConfig); });
  if (!device) throw Error("Embree: rtcNewDevice failed");
  return device;
}

class EmbreeScene {
 public:
  explicit EmbreeScene(const Room& room) {
    scene_ = rtcNewScene(SharedDevice());
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_MEDIUM);
    for (std::size_t i = 0; i < room.objects.size(); ++i) {
      const geometry::TriangleMesh m = room.objects[i].WorldMesh();
      if (m.faces.empty()) continue;
      RTCGeometry g = rtcNewGeometry(SharedDevice(), RTC_GEOMETRY_TYPE_TRIANGLE);
      float* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertices.size()));
      unsigned* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.faces.size()));
      for (std::size_t v = 0; v < m.vertices.size(); ++v) {
        for (int k = 0; k < 3; ++k) vb[3 * v + k] = static_cast<float>(m.vertices[v][k]);
      }
      for (std::size_t f = 0; f < m.faces.size(); ++f) {
        for (int k = 0; k < 3; ++k) ib[3 * f + k] = static_cast<unsigned>(m.faces[f][k]);
      }
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(scene_, g, static_cast<unsigned>(i));
      rtcReleaseGeometry(g);
    }
    rtcCommitScene(scene_);
  }
  ~EmbreeScene() { rtcReleaseScene(scene_); }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // Returns the object index hit (or -1), the distance and the unit geometric normal.
  // `prim` / (`bu`, `bv`): the triangle hit and the barycentric weights of its 2nd and 3rd vertex.
  int Cast(const Vec3& o, const Vec3& d, double tfar, double* t, Vec3* n, int* prim, double* bu,
           double* bv) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray.org_x = static_cast<float>(o.x());
    rh.ray.org_y = static_cast<float>(o.y());
    rh.ray.org_z = static_cast<float>(o.z());
    rh.ray.dir_x = static_cast<float>(d.x());
    rh.ray.dir_y = static_cast<float>(d.y());
    rh.ray.dir_z = static_cast<float>(d.z());
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = static_cast<float>(tfar);
    rh.ray.mask = 0xffffffffu;
    rh.ray.flags = 0;
    rh.ray.time = 0.0f;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return -1;
    *t = rh.ray.tfar;
    *n = Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    const double len = n->norm();
    *n = len > 0 ? Vec3(*n / len) : Vec3::UnitZ();
    *prim = static_cast<int>(rh.hit.primID);
    *bu = rh.hit.u;
    *bv = rh.hit.v;
    return static_cast<int>(rh.hit.geomID);
  }

 private:
  RTCScene scene_ = nullptr;
};
#endif

}  // namespace

std::uint64_t CellKey(const geometry::Vec3& p, int object) {
  const auto q = [](double v) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v / kObservedCell)) +
                                      (1 << 15)) &
           0xffff;
  };
  return q(p.x()) | (q(p.y()) << 16) | (q(p.z()) << 32) |
         (static_cast<std::uint64_t>(object & 0x7fff) << 48);
}

bool ObservedNear(const ScanResult& scan, int object, const geometry::Vec3& p) {
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz) {
        const std::uint64_t key = CellKey(p + kObservedCell * Vec3(dx, dy, dz), object);
        if (std::binary_search(scan.observed_cells.begin(), scan.observed_cells.end(), key))
          return true;
      }
    }
  }
  return false;
}

const char* ScanDensityName(ScanDensity d) {
  switch (d) {
    case ScanDensity::kMesh:
      return "mesh";
    case ScanDensity::kRaw:
      return "raw";
    case ScanDensity::kScanNet:
      return "scannet";
  }
  return "?";
}

ScanDensity ScanDensityFromName(const std::string& name) {
  if (name == "mesh") return ScanDensity::kMesh;
  if (name == "raw") return ScanDensity::kRaw;
  if (name == "scannet") return ScanDensity::kScanNet;
  throw InvalidArgument("density: expected 'mesh', 'raw' or 'scannet', got '" + name + "'");
}

double AxialSigma(const ScannerConfig& c, double z) {
  return c.axial_noise_base + c.axial_noise_quad * (z - c.axial_noise_z0) * (z - c.axial_noise_z0);
}

double MeasuredDepth(const ScannerConfig& c, double z, double standard_normal) {
  const double sigma = AxialSigma(c, z);
  double zm = z + sigma * std::clamp(standard_normal, -c.noise_clip, c.noise_clip);
  if (c.disparity_quantum > 0 && zm > 0) {
    const double q = c.disparity_quantum;
    const double inv = std::max(1.0, std::round(1.0 / (zm * q)));
    zm = 1.0 / (inv * q);
  }
  return zm;
}

const config::Fields<ScannerConfig>& ScannerFields() {
  using C = ScannerConfig;
  static const config::Fields<C> fields =
      config::Fields<C>("scanner")
          .Number(
              "width", [](C& c) -> int& { return c.width; }, "px", "depth image width", 8, 4096)
          .Number(
              "height", [](C& c) -> int& { return c.height; }, "px", "depth image height", 8, 4096)
          .Number(
              "axial_noise_base", [](C& c) -> double& { return c.axial_noise_base; }, "m",
              "sigma(z) = base + quad (z - z0)^2", 0.0, 0.1)
          .Number(
              "axial_noise_quad", [](C& c) -> double& { return c.axial_noise_quad; }, "1/m",
              "sigma(z) = base + quad (z - z0)^2", 0.0, 0.1)
          .Number(
              "axial_noise_z0", [](C& c) -> double& { return c.axial_noise_z0; }, "m",
              "sigma(z) = base + quad (z - z0)^2", 0.0, 20.0)
          .Number(
              "noise_clip", [](C& c) -> double& { return c.noise_clip; }, "sigma",
              "axial noise truncation", 0.1, 10.0)
          .Number(
              "lateral_noise_px", [](C& c) -> double& { return c.lateral_noise_px; }, "px",
              "pixel jitter", 0.0, 5.0)
          .Number(
              "disparity_quantum", [](C& c) -> double& { return c.disparity_quantum; }, "1/m",
              "inverse-depth step (0 = off)", 0.0, 0.1)
          .Number(
              "sensor_frames", [](C& c) -> int& { return c.sensor_frames; }, "",
              "sensor frames averaged per rendered frame", 1, kMaxSensorFrames)
          .Number(
              "flying_pixel_probability",
              [](C& c) -> double& { return c.flying_pixel_probability; }, "",
              "flying pixels at depth edges", 0.0, 1.0)
          .Number(
              "dark_dropout", [](C& c) -> double& { return c.dark_dropout; }, "",
              "extra dropout on black", 0.0, 1.0)
          .Number(
              "glossy_dropout", [](C& c) -> double& { return c.glossy_dropout; }, "",
              "extra dropout on glossy surfaces head-on", 0.0, 1.0)
          .Number(
              "dropout", [](C& c) -> double& { return c.dropout; }, "", "random dropout", 0.0, 0.99)
          .Number(
              "drift_translation", [](C& c) -> double& { return c.drift_translation; }, "m",
              "pose random-walk step", 0.0, 0.05)
          .Number(
              "drift_rotation_deg", [](C& c) -> double& { return c.drift_rotation_deg; }, "deg",
              "pose random-walk step", 0.0, 2.0)
          .Flag(
              "loop_closure", [](C& c) -> bool& { return c.loop_closure; },
              "distribute the end drift back along the loop")
          .Number(
              "min_coverage", [](C& c) -> double& { return c.min_coverage; }, "",
              "walked part of the loop drawn in [min_coverage, 1]", 0.1, 1.0)
          .Number(
              "mesh_grid_offset", [](C& c) -> double& { return c.mesh_grid_offset; }, "voxels",
              "mesh mode's grid shift (0.5: one floor layer)", 0.0, 0.99)
          .Number(
              "height_cap_probability", [](C& c) -> double& { return c.height_cap_probability; },
              "", "scans that stop at a height", 0.0, 1.0)
          .Number(
              "ceiling_probability", [](C& c) -> double& { return c.ceiling_probability; }, "",
              "scans that keep the ceiling's returns", 0.0, 1.0)
          .Number(
              "ceiling_look_up_fraction",
              [](C& c) -> double& { return c.ceiling_look_up_fraction; }, "",
              "share of frames with a twin looking up (ceiling scans)", 0.0, 1.0)
          .Number(
              "ceiling_max_up_deg", [](C& c) -> double& { return c.ceiling_max_up_deg; }, "deg",
              "largest upward pitch of those twins", 10.0, 80.0)
          .Number(
              "white_balance_jitter", [](C& c) -> double& { return c.white_balance_jitter; }, "",
              "per-channel log gain sigma", 0.0, 1.0)
          .Number(
              "exposure_jitter", [](C& c) -> double& { return c.exposure_jitter; }, "",
              "per-scene log gain sigma", 0.0, 1.0)
          .Number(
              "frame_exposure_jitter", [](C& c) -> double& { return c.frame_exposure_jitter; }, "",
              "per-frame log gain sigma", 0.0, 1.0)
          .Flag(
              "lambert_shading", [](C& c) -> bool& { return c.lambert_shading; },
              "point-light Lambert shading")
          .Number(
              "ambient", [](C& c) -> double& { return c.ambient; }, "", "ambient share", 0.0, 1.0)
          .Number(
              "material_variety", [](C& c) -> double& { return c.material_variety; }, "",
              "weight of the v2 palettes", 0.0, 1.0)
          .Number(
              "shadow_strength", [](C& c) -> double& { return c.shadow_strength; }, "",
              "share of direct light a cast shadow removes", 0.0, 1.0)
          .Number(
              "exposure_drift", [](C& c) -> double& { return c.exposure_drift; }, "",
              "smooth auto-exposure log-gain sigma", 0.0, 1.0)
          .Number(
              "texture_gain", [](C& c) -> double& { return c.texture_gain; }, "",
              "material texture amplitude multiplier", 0.0, 20.0)
          .Number(
              "floor_pattern", [](C& c) -> double& { return c.floor_pattern; }, "",
              "log brightness sigma of floor boards / tiles", 0.0, 2.0)
          .Number(
              "tsdf_voxel_size", [](C& c) -> double& { return c.tsdf.voxel_size; }, "m",
              "TSDF voxel", 0.002, 0.2)
          .Number(
              "tsdf_truncation", [](C& c) -> double& { return c.tsdf.truncation; }, "m",
              "TSDF truncation", 0.004, 1.0)
          .Number(
              "tsdf_min_component_triangles",
              [](C& c) -> int& { return c.tsdf.min_component_triangles; }, "", "cleaning threshold",
              0, 100000000)
          .Number(
              "tsdf_target_spacing", [](C& c) -> double& { return c.tsdf.target_spacing; }, "m",
              "decimation lattice edge", 0.002, 0.5)
          .Number(
              "tsdf_open3d_simplify", [](C& c) -> int& { return c.tsdf.open3d_simplify; }, "",
              "1 = Open3D's cleaning + decimation instead of dimr's (A/B)", 0, 1);
  return fields;
}

double AveragedDepth(const ScannerConfig& c, double z, const double* standard_normals, int count) {
  if (count < 1 || standard_normals == nullptr)
    throw InvalidArgument("AveragedDepth: need at least one standard normal");
  double sum = 0;
  for (int i = 0; i < count; ++i) sum += MeasuredDepth(c, z, standard_normals[i]);
  return sum / count;
}

void ScannerConfig::EnableRealism() {
  // Structured-light sensor (Kinect v1 / Structure-like): sigma(z) = 0.0005 + 0.0025 z^2
  // (1.0 cm at 2 m, 2.3 cm at 3 m), 1/8-pixel disparity steps, flying pixels, dark / glossy
  // dropout.
  axial_noise_base = 0.0005;
  axial_noise_quad = 0.0025;
  axial_noise_z0 = 0.0;
  lateral_noise_px = 0.6;
  disparity_quantum = 0.0029;
  // A 30 Hz scan of a room has thousands of frames, SynthScan renders 60: each stands for 40
  // averaged sensor frames (tuned: surface variation of the fused mesh in the real range,
  // docs/synthscan.md).
  sensor_frames = 40;
  flying_pixel_probability = 0.5;
  dark_dropout = 0.6;
  glossy_dropout = 0.5;
  dropout = 0.03;
  // Hand-held SLAM scan.
  drift_translation = std::max(drift_translation, 0.0015);
  drift_rotation_deg = std::max(drift_rotation_deg, 0.05);
  loop_closure = true;
  min_coverage = 0.6;
  height_cap_probability = 0.15;
  // Colour.
  white_balance_jitter = 0.08;
  exposure_jitter = 0.25;
  frame_exposure_jitter = 0.08;
  lambert_shading = true;
  ambient = 0.1;
  shadow_strength = 0.8;
  exposure_drift = 0.8;
  texture_gain = 3.0;
  floor_pattern = 0.35;
  material_variety = 1.0;
}

void ScannerConfig::Validate() const {
  auto fail = [](const std::string& m) { throw InvalidArgument("ScannerConfig: " + m); };
  if (width < 8 || height < 8 || width > 4096 || height > 4096)
    fail("width/height must be in [8, 4096]");
  if (!(fov_x_deg > 10 && fov_x_deg < 170)) fail("fov_x_deg must be in (10, 170)");
  if (!(min_range >= 0 && max_range > min_range && max_range <= 20))
    fail("need 0 <= min_range < max_range <= 20 (metres)");
  if (frames < 1 || frames > 10000) fail("frames must be in [1, 10000]");
  if (!(min_camera_height > 0.2 && max_camera_height >= min_camera_height))
    fail("need 0.2 < min_camera_height <= max_camera_height");
  if (!(path_inset > 0.1)) fail("path_inset must be > 0.1 m");
  if (!(min_tilt_deg >= -60 && max_tilt_deg >= min_tilt_deg && max_tilt_deg <= 80))
    fail("need -60 <= min_tilt_deg <= max_tilt_deg <= 80");
  if (!(yaw_sweep_deg >= 0 && yaw_sweep_deg <= 90)) fail("yaw_sweep_deg must be in [0, 90]");
  if (!(axial_noise_base >= 0 && axial_noise_quad >= 0 && noise_clip > 0))
    fail("axial noise parameters must be >= 0 and noise_clip > 0");
  if (!(lateral_noise_px >= 0)) fail("lateral_noise_px must be >= 0");
  if (sensor_frames < 1 || sensor_frames > kMaxSensorFrames)
    fail("sensor_frames must be in [1, " + std::to_string(kMaxSensorFrames) + "]");
  if (!(dropout >= 0 && dropout < 1)) fail("dropout must be in [0, 1)");
  if (!(grazing_start_deg > 0 && grazing_end_deg > grazing_start_deg && grazing_end_deg <= 90))
    fail("need 0 < grazing_start_deg < grazing_end_deg <= 90");
  if (!(drift_translation >= 0 && drift_rotation_deg >= 0)) fail("drift must be >= 0");
  if (!(axial_noise_z0 >= 0 && axial_noise_z0 <= max_range))
    fail("axial_noise_z0 must be in [0, max_range]");
  if (!(disparity_quantum >= 0 && disparity_quantum <= 0.1))
    fail("disparity_quantum must be in [0, 0.1] 1/m");
  if (!(flying_pixel_probability >= 0 && flying_pixel_probability <= 1 && flying_pixel_edge > 0))
    fail("need flying_pixel_probability in [0, 1] and flying_pixel_edge > 0");
  if (!(dark_dropout >= 0 && dark_dropout <= 1 && dark_luminance > 0 && glossy_dropout >= 0 &&
        glossy_dropout <= 1))
    fail("need dark_dropout, glossy_dropout in [0, 1] and dark_luminance > 0");
  if (!(min_coverage >= 0.1 && min_coverage <= 1)) fail("min_coverage must be in [0.1, 1]");
  if (!(height_cap_probability >= 0 && height_cap_probability <= 1 && height_cap_min > 0.2 &&
        height_cap_max >= height_cap_min))
    fail("need height_cap_probability in [0, 1] and 0.2 < height_cap_min <= height_cap_max");
  if (!(ceiling_probability >= 0 && ceiling_probability <= 1 && ceiling_look_up_fraction >= 0 &&
        ceiling_look_up_fraction <= 1 && ceiling_max_up_deg >= 10 && ceiling_max_up_deg <= 80))
    fail(
        "need ceiling_probability, ceiling_look_up_fraction in [0, 1] and ceiling_max_up_deg in "
        "[10, 80]");
  if (!(white_balance_jitter >= 0 && white_balance_jitter <= 1 && exposure_jitter >= 0 &&
        exposure_jitter <= 1 && frame_exposure_jitter >= 0 && frame_exposure_jitter <= 1))
    fail("colour jitters must be in [0, 1]");
  if (!(ambient >= 0 && ambient <= 1)) fail("ambient must be in [0, 1]");
  if (!(material_variety >= 0 && material_variety <= 1)) fail("material_variety must be in [0, 1]");
  if (!(shadow_strength >= 0 && shadow_strength <= 1)) fail("shadow_strength must be in [0, 1]");
  if (!(exposure_drift >= 0 && exposure_drift <= 1)) fail("exposure_drift must be in [0, 1]");
  if (!(texture_gain >= 0 && texture_gain <= 20)) fail("texture_gain must be in [0, 20]");
  if (!(floor_pattern >= 0 && floor_pattern <= 2)) fail("floor_pattern must be in [0, 2]");
  if (density == ScanDensity::kScanNet) tsdf.Validate();
  if (!(mesh_voxel_size >= 0.005 && mesh_voxel_size <= 0.5))
    fail("mesh_voxel_size must be in [0.005, 0.5] m");
  if (!(mesh_grid_offset >= 0 && mesh_grid_offset <= 0.99))
    fail("mesh_grid_offset must be in [0, 0.99] voxels");  // the --scanner parser's range
  if (min_observations < 1) fail("min_observations must be >= 1");
  if (!(max_fused_sigma > 0)) fail("max_fused_sigma must be > 0");
  if (raw_pixel_stride < 1 || frame_pixel_stride < 1) fail("pixel strides must be >= 1");
  if (threads < 0) fail("threads must be >= 0");
}

// Camera optical frame (x right, y down, z forward) in the world for a heading `yaw`, a
// downward pitch `tilt` (negative: looking up) and a roll about the optical axis (radians).
static Eigen::Matrix3d CameraRotation(double yaw, double tilt, double roll) {
  const Vec3 fwd(std::cos(yaw) * std::cos(tilt), std::sin(yaw) * std::cos(tilt), -std::sin(tilt));
  const Vec3 right = fwd.cross(Vec3::UnitZ()).normalized();
  const Vec3 down = fwd.cross(right);
  Eigen::Matrix3d r;
  r.col(0) = right;
  r.col(1) = down;
  r.col(2) = fwd;
  return r * Eigen::AngleAxisd(roll, Vec3::UnitZ()).toRotationMatrix();
}

std::vector<Eigen::Isometry3d> MakeTrajectory(const Room& room, const ScannerConfig& cfg,
                                              std::uint64_t seed) {
  Rng rng(HashCombine(seed, 0x7a11ULL));
  double min_edge = 1e9;
  for (std::size_t i = 0; i < room.outline.size(); ++i) {
    min_edge =
        std::min(min_edge, (room.outline[(i + 1) % room.outline.size()] - room.outline[i]).norm());
  }
  const double inset = std::min(cfg.path_inset, 0.42 * min_edge);
  const std::vector<Vec2> loop = InsetPolygon(room.outline, inset);
  std::vector<double> cum(loop.size() + 1, 0.0);
  for (std::size_t i = 0; i < loop.size(); ++i)
    cum[i + 1] = cum[i] + (loop[(i + 1) % loop.size()] - loop[i]).norm();
  const double perimeter = cum.back();
  double coverage = 1.0;
  if (cfg.min_coverage < 1.0) {
    Rng cov(HashCombine(seed, 0xc0fe7a6eULL));
    coverage = cov.Uniform(cfg.min_coverage, 1.0);
  }
  auto at = [&](double s) {
    s = std::fmod(s, perimeter);
    if (s < 0) s += perimeter;
    std::size_t i = 0;
    while (i + 1 < loop.size() && cum[i + 1] < s) ++i;
    const Vec2 a = loop[i], b = loop[(i + 1) % loop.size()];
    const double len = cum[i + 1] - cum[i];
    return Vec2(a + (b - a) * (len > 0 ? (s - cum[i]) / len : 0.0));
  };
  const double s0 = rng.Uniform(0, perimeter);
  const double direction = rng.Bernoulli(0.5) ? 1.0 : -1.0;
  const double h_mid = rng.Uniform(cfg.min_camera_height, cfg.max_camera_height);
  const double h_amp = 0.5 * (cfg.max_camera_height - cfg.min_camera_height);
  const double phase[4] = {rng.Uniform(0, 2 * kPi), rng.Uniform(0, 2 * kPi),
                           rng.Uniform(0, 2 * kPi), rng.Uniform(0, 2 * kPi)};
  std::vector<Eigen::Isometry3d> poses;
  const int n = cfg.frames;
  for (int i = 0; i < n; ++i) {
    const double u = static_cast<double>(i) / n;
    const double s = s0 + direction * perimeter * u * coverage;
    Vec2 p = at(s);
    // Hand-held wobble.
    p += Vec2(0.12 * std::sin(2 * kPi * 3 * u + phase[0]),
              0.12 * std::cos(2 * kPi * 2 * u + phase[1]));
    const double z =
        std::clamp(h_mid + h_amp * std::sin(2 * kPi * 2 * u + phase[2]) + rng.Normal(0, 0.01),
                   cfg.min_camera_height, cfg.max_camera_height);
    // Look across the room at the far side of the loop, sweeping left and right.
    const Vec2 target = at(s + 0.5 * perimeter + rng.Normal(0, 0.05 * perimeter));
    double yaw = std::atan2(target.y() - p.y(), target.x() - p.x()) +
                 Deg(cfg.yaw_sweep_deg) * std::sin(2 * kPi * 5 * u + phase[3]);
    const double tilt =
        Deg(0.5 * (cfg.min_tilt_deg + cfg.max_tilt_deg) +
            0.5 * (cfg.max_tilt_deg - cfg.min_tilt_deg) * std::sin(2 * kPi * 4 * u + phase[1]));
    const double roll = Deg(rng.Normal(0, 2.0));
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = CameraRotation(yaw, tilt, roll);
    pose.translation() = Vec3(p.x(), p.y(), z);
    poses.push_back(pose);
  }
  return poses;
}

ScanResult ScanRoom(const Room& room, const ScannerConfig& cfg, std::uint64_t seed) {
  cfg.Validate();
#ifndef DIMR_HAVE_EMBREE
  (void)room;
  (void)seed;
  throw Error("ScanRoom: this build of dimr has no Embree (libembree-dev) - cannot ray cast");
#else
  const EmbreeScene scene(room);
  std::vector<Eigen::Isometry3d> poses = MakeTrajectory(room, cfg, seed);
  // Drop poses from inside furniture (a person cannot stand there).
  {
    std::vector<Eigen::Isometry3d> kept;
    for (const auto& p : poses) {
      bool inside = false;
      for (const auto& o : room.objects) {
        if (o.role != ObjectRole::kFurniture && o.role != ObjectRole::kClutter) continue;
        const Vec3 d = o.Rotation().transpose() * (p.translation() - o.translation);
        if ((d.array().abs() < (0.5 * o.scale.array() + 0.15)).all()) inside = true;
      }
      if (!inside) kept.push_back(p);
    }
    poses.swap(kept);
  }
  const int w = cfg.width, h = cfg.height;
  const double fx = 0.5 * w / std::tan(0.5 * Deg(cfg.fov_x_deg)), fy = fx;
  const double cx = 0.5 * w, cy = 0.5 * h;
  const double cos_start = std::cos(Deg(cfg.grazing_start_deg));
  const double cos_end = std::cos(Deg(cfg.grazing_end_deg));
  const int threads = ResolveThreads(cfg.threads);
  std::vector<std::uint64_t> salts(room.objects.size());
  for (std::size_t i = 0; i < salts.size(); ++i) salts[i] = HashCombine(seed, 1000 + i);
  const bool scannet = cfg.density == ScanDensity::kScanNet;
  const bool colour_v2 = cfg.ColourRealism();
  const double lateral =
      cfg.sensor_frames > 1
          ? cfg.lateral_noise_px / std::sqrt(static_cast<double>(cfg.sensor_frames))
          : cfg.lateral_noise_px;
  const SceneLook look = MakeLook(room, cfg, seed);
  // Per-scene draws of the v2 features come from their own generators, so the default
  // configuration reproduces today's scans bit for bit.
  double height_cap = std::numeric_limits<double>::infinity();
  if (cfg.height_cap_probability > 0) {
    Rng cap(HashCombine(seed, 0xca9ULL));
    if (cap.Bernoulli(cfg.height_cap_probability))
      height_cap = cap.Uniform(cfg.height_cap_min, cfg.height_cap_max);
  }
  // Ceiling scans: every k-th frame gets a twin from the same position looking up (inserted
  // after it, so drift stays continuous along the trajectory); a capped scan sees no ceiling.
  bool keep_ceiling = false;
  if (cfg.ceiling_probability > 0 && !std::isfinite(height_cap)) {
    Rng ceil_rng(HashCombine(seed, 0xce11ULL));
    keep_ceiling = ceil_rng.Bernoulli(cfg.ceiling_probability);
    if (keep_ceiling && cfg.ceiling_look_up_fraction > 0 && !poses.empty()) {
      const int every =
          std::max(1, static_cast<int>(std::lround(1.0 / cfg.ceiling_look_up_fraction)));
      std::vector<Eigen::Isometry3d> with_twins;
      for (std::size_t f = 0; f < poses.size(); ++f) {
        with_twins.push_back(poses[f]);
        if (f % every != 0) continue;
        const Vec3 fwd = poses[f].linear().col(2);
        Eigen::Isometry3d up = poses[f];
        up.linear() = CameraRotation(std::atan2(fwd.y(), fwd.x()),
                                     -Deg(ceil_rng.Uniform(10.0, cfg.ceiling_max_up_deg)),
                                     Deg(ceil_rng.Normal(0, 2.0)));
        with_twins.push_back(up);
      }
      poses.swap(with_twins);
    }
  }
  Rng exposure_rng(HashCombine(seed, 0xe7905ULL));
  // Wandering auto exposure: AR(1) log gain, correlation length 25 % of the frames (a pass
  // along one wall keeps its gain; the fusion averages a surface over the frames of a pass).
  std::vector<double> exposure_walk(poses.size(), 1.0);
  if (cfg.exposure_drift > 0 && !poses.empty()) {
    Rng walk_rng(HashCombine(seed, 0xae3a1cULL));
    const double rho = std::exp(-1.0 / std::max(1.0, 0.25 * static_cast<double>(poses.size())));
    double s = walk_rng.Normal();
    for (std::size_t f = 0; f < poses.size(); ++f) {
      if (f > 0) s = rho * s + std::sqrt(1 - rho * rho) * walk_rng.Normal();
      // Unit-mean log-normal: the wandering changes contrast, not the average brightness.
      exposure_walk[f] =
          std::exp(cfg.exposure_drift * s - 0.5 * cfg.exposure_drift * cfg.exposure_drift);
    }
  }

  // Registration drift: a random walk of the pose error; with loop closure the error at the
  // end of the loop is distributed back linearly (zero at both ends, largest in the middle).
  std::vector<Vec3> drift_t(poses.size(), Vec3::Zero()), drift_r(poses.size(), Vec3::Zero());
  {
    Rng drift_rng(HashCombine(seed, 0xd71f7ULL));
    for (std::size_t f = 1; f < poses.size(); ++f) {
      drift_t[f] =
          drift_t[f - 1] + Vec3(drift_rng.Normal(), drift_rng.Normal(), 0.3 * drift_rng.Normal()) *
                               cfg.drift_translation;
      drift_r[f] =
          drift_r[f - 1] + Vec3(drift_rng.Normal(), drift_rng.Normal(), drift_rng.Normal()) *
                               Deg(cfg.drift_rotation_deg);
    }
    if (cfg.loop_closure && poses.size() > 1) {
      const Vec3 end_t = drift_t.back(), end_r = drift_r.back();
      for (std::size_t f = 0; f < poses.size(); ++f) {
        const double a = static_cast<double>(f) / static_cast<double>(poses.size() - 1);
        drift_t[f] -= a * end_t;
        drift_r[f] -= a * end_r;
      }
    }
  }

  ScanResult result;
  // Mesh mode's grid shift: see ScannerConfig::mesh_grid_offset. ScanNet mode's 1 cm label cells
  // are never shifted (only their centroids are used).
  VoxelAccumulator acc(scannet ? 0.01 : cfg.mesh_voxel_size, scannet ? 0.0 : cfg.mesh_grid_offset);
  HashSet64 observed;
  std::unique_ptr<TsdfFusion> fusion;
  if (scannet) fusion = std::make_unique<TsdfFusion>(cfg.tsdf);
  std::vector<std::vector<Return> > rows(h);
  std::vector<float> depth_image;
  for (std::size_t f = 0; f < poses.size(); ++f) {
    const Eigen::Isometry3d& truth = poses[f];
    Eigen::Isometry3d est = truth;
    if (cfg.drift_translation > 0 || cfg.drift_rotation_deg > 0) {
      const double angle = drift_r[f].norm();
      if (angle > 0)
        est.linear() =
            truth.linear() * Eigen::AngleAxisd(angle, drift_r[f] / angle).toRotationMatrix();
      est.translation() += drift_t[f];
    }
    const double frame_gain = cfg.frame_exposure_jitter > 0
                                  ? std::exp(exposure_rng.Normal(0, cfg.frame_exposure_jitter))
                                  : 1.0;
    const Eigen::Matrix3f est_r = est.linear().cast<float>();
    const Eigen::Vector3f est_t = est.translation().cast<float>();
    const Eigen::Matrix3d rot = truth.linear();
    const Vec3 org = truth.translation();
    auto work = [&](int row_begin, int row_end) {
      for (int v = row_begin; v < row_end; ++v) {
        Rng rng(HashCombine(HashCombine(seed, f + 1), static_cast<std::uint64_t>(v)));
        // Draws of the v2 sensor / colour features (never touch `rng`'s sequence).
        Rng rng2(
            HashCombine(HashCombine(seed ^ 0x5e2502ULL, f + 1), static_cast<std::uint64_t>(v)));
        auto& out = rows[v];
        out.clear();
        for (int u = 0; u < w; ++u) {
          // (With sensor_frames K the depth is the mean of K measurements: for a locally flat
          // surface that is the depth at the mean of K jitters, sigma / sqrt(K).)
          const double pu = u + 0.5 + lateral * rng.Normal();
          const double pv = v + 0.5 + lateral * rng.Normal();
          const Vec3 dc((pu - cx) / fx, (pv - cy) / fy, 1.0);
          const Vec3 dcn = dc.normalized();
          const Vec3 dw = rot * dcn;
          double t = 0;
          Vec3 n;
          int prim = -1;
          double bu = 0, bv = 0;
          const int obj =
              scene.Cast(org, dw, cfg.max_range * dc.norm() * 1.05, &t, &n, &prim, &bu, &bv);
          const double r_drop = rng.Uniform();
          const double r_noise = rng.Normal();
          if (obj < 0) continue;
          const PlacedObject& o = room.objects[obj];
          const double z = t * dcn.z();
          if (z < cfg.min_range || z > cfg.max_range) continue;
          const double cosi = std::abs(n.dot(dw));
          double p_drop = cfg.dropout;
          if (cosi < cos_start) {
            p_drop += (cos_start - cosi) / std::max(1e-9, cos_start - cos_end);
          }
          if (r_drop < p_drop) continue;
          if (o.role == ObjectRole::kCeiling && !keep_ceiling) continue;
          const Vec3 hit = org + dw * t;
          if (hit.z() > height_cap) continue;
          // Albedo: the object's (v2: the scene look's), or for real furniture its own texture
          // colour interpolated at the hit (sRGB vertex colours -> linear).
          Vec3 albedo = colour_v2 || cfg.dark_dropout > 0 ? look.albedo[obj] : o.material.albedo;
          if (!o.mesh.vertex_colors.empty() &&
              o.mesh.vertex_colors.size() == o.mesh.vertices.size() && prim >= 0 &&
              prim < static_cast<int>(o.mesh.faces.size())) {
            const geometry::Vec3i& fv = o.mesh.faces[prim];
            const double wgt[3] = {1.0 - bu - bv, bu, bv};
            Vec3 c = Vec3::Zero();
            for (int k = 0; k < 3; ++k) {
              const Color& vc = o.mesh.vertex_colors[fv[k]];
              for (int ch = 0; ch < 3; ++ch) c[ch] += wgt[k] * std::pow(vc[ch] / 255.0, 2.2);
            }
            albedo = c.cwiseMax(0.0).cwiseMin(1.0);
          }
          double tex = 0;
          if (colour_v2 || cfg.dark_dropout > 0)
            tex = Texture(o.material, salts[obj], hit, colour_v2 ? cfg.texture_gain : 1.0);
          if (colour_v2 && o.role == ObjectRole::kFloor && o.mesh.vertex_colors.empty())
            tex *= FloorPattern(look, hit);
          if (cfg.dark_dropout > 0 || cfg.glossy_dropout > 0) {
            double p2 = 0;
            if (cfg.dark_dropout > 0) {
              const double lum = Luminance(albedo * tex);
              p2 += cfg.dark_dropout * std::clamp(1.0 - lum / cfg.dark_luminance, 0.0, 1.0);
            }
            if (cfg.glossy_dropout > 0 && look.gloss[obj] > 0)
              p2 += cfg.glossy_dropout * look.gloss[obj] * std::pow(cosi, 16);
            if (rng2.Uniform() < p2) continue;
          }
          const double sigma = AxialSigma(cfg, z);
          double zm = 0;
          if (cfg.sensor_frames > 1) {
            // Temporal averaging: the first draw is `rng`'s, the others the v2 stream's.
            double normals[kMaxSensorFrames];
            normals[0] = r_noise;
            for (int k = 1; k < cfg.sensor_frames; ++k) normals[k] = rng2.Normal();
            zm = AveragedDepth(cfg, z, normals, cfg.sensor_frames);
          } else {
            zm = MeasuredDepth(cfg, z, r_noise);
          }
          const Vec3 cam = dc * zm;  // dc has unit z
          const Vec3 pw = org + rot * cam;
          Return ret;
          ret.cam = cam.cast<float>();
          ret.world = est_r * ret.cam + est_t;
          ret.bin = est_r * (dc * z).cast<float>() + est_t;
          if (colour_v2) {
            const Vec3 nv = n.dot(dw) > 0 ? Vec3(-n) : n;
            double direct = 1.0;
            if (cfg.shadow_strength > 0) {
              // Shadow ray from just above the surface to the light.
              Vec3 to_light = look.light - hit;
              const double dl = to_light.norm();
              if (dl > 0.05 && nv.dot(to_light) > 0) {
                to_light /= dl;
                double ts = 0, sbu = 0, sbv = 0;
                Vec3 sn;
                int sprim = -1;
                const int blocker =
                    scene.Cast(hit + 0.004 * nv, to_light, dl - 0.02, &ts, &sn, &sprim, &sbu, &sbv);
                if (blocker >= 0) direct = 1.0 - cfg.shadow_strength;
              }
            }
            ret.color =
                ShadeV2(albedo, tex, look, frame_gain * exposure_walk[f], pw, nv, direct, &rng);
          } else {
            ret.color = Shade(o, albedo, salts[obj], pw, n, dw, &rng);
          }
          ret.object = obj;
          ret.u = u;
          ret.weight = static_cast<float>(1.0 / (sigma * sigma));
          ret.cell = CellKey(hit, obj);
          ret.keep_frame = (u % cfg.frame_pixel_stride == 0) && (v % cfg.frame_pixel_stride == 0);
          ret.keep_raw = (u % cfg.raw_pixel_stride == 0) && (v % cfg.raw_pixel_stride == 0);
          out.push_back(ret);
        }
      }
    };
    // Rows are independent (each seeds its own generator): any split gives the same scan.
    {
      ScopedTimer timer(&result.timings, "ray_cast");
      ParallelRanges(static_cast<std::size_t>(h), threads, 1, [&](std::size_t b, std::size_t e) {
        work(static_cast<int>(b), static_cast<int>(e));
      });
    }
    if (cfg.flying_pixel_probability > 0 || scannet) {
      depth_image.assign(static_cast<std::size_t>(w) * h, 0.0f);
      for (int v = 0; v < h; ++v) {
        for (const Return& r : rows[v])
          depth_image[static_cast<std::size_t>(v) * w + r.u] = r.cam.z();
      }
    }
    if (cfg.flying_pixel_probability > 0) {
      // Flying pixels: at a depth edge the sensor mixes the two surfaces.
      const std::vector<float> z0 = depth_image;
      for (int v = 0; v < h; ++v) {
        for (Return& r : rows[v]) {
          const float z = r.cam.z();
          float other = z;
          const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
          for (int k = 0; k < 4; ++k) {
            const int uu = r.u + du[k], vv = v + dv[k];
            if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
            const float zn = z0[static_cast<std::size_t>(vv) * w + uu];
            if (zn > 0 && std::abs(zn - z) > std::abs(other - z)) other = zn;
          }
          if (std::abs(other - z) <= cfg.flying_pixel_edge) continue;
          const std::uint64_t key = HashCombine(HashCombine(seed ^ 0xf1f1ULL, f),
                                                static_cast<std::uint64_t>(v) * w + r.u);
          const double r1 = static_cast<double>(Mix64(key) >> 11) * (1.0 / 9007199254740992.0);
          if (r1 >= cfg.flying_pixel_probability) continue;
          const double r2 = static_cast<double>(Mix64(key + 1) >> 11) * (1.0 / 9007199254740992.0);
          const float zf = static_cast<float>(z + r2 * (other - z));
          r.cam *= zf / z;
          r.world = est_r * r.cam + est_t;
          depth_image[static_cast<std::size_t>(v) * w + r.u] = zf;
        }
      }
    }
    result.rays += static_cast<std::size_t>(w) * h;
    ScanFrame frame;
    frame.pose = est;
    frame.true_pose = truth;
    RgbdFrame rgbd;
    if (scannet) {
      rgbd.width = w;
      rgbd.height = h;
      rgbd.fx = fx;
      rgbd.fy = fy;
      rgbd.cx = cx - 0.5;  // pixel centres at integer coordinates (Open3D's convention)
      rgbd.cy = cy - 0.5;
      rgbd.depth = depth_image;
      rgbd.color.assign(static_cast<std::size_t>(w) * h, Color(0, 0, 0));
      rgbd.pose = est;
    }
    std::uint64_t last_cell = ~0ULL;
    for (int v = 0; v < h; ++v) {
      for (const Return& r : rows[v]) {
        ++result.returns;
        if (r.cell != last_cell) {
          observed.Insert(r.cell);
          last_cell = r.cell;
        }
        if (cfg.density == ScanDensity::kMesh) {
          acc.Add(r.bin, r.world, r.color, r.object, r.weight);
        } else if (scannet) {
          rgbd.color[static_cast<std::size_t>(v) * w + r.u] = r.color;
          // Labels: the noise-free surface returns, in the estimated (fused) frame.
          if (r.keep_raw) acc.Add(r.bin, r.bin, r.color, r.object, 1.0);
        } else if (r.keep_raw) {
          result.points.push_back(r.world.cast<double>());
          result.colors.push_back(r.color);
          result.object.push_back(r.object);
        }
        if (cfg.keep_frames && r.keep_frame) {
          frame.points.push_back(r.cam);
          frame.colors.push_back(r.color);
        }
      }
    }
    if (scannet) fusion->Integrate(rgbd);
    result.poses.push_back(est);
    if (cfg.keep_frames) result.frames.push_back(std::move(frame));
  }
  if (cfg.density == ScanDensity::kMesh) {
    const auto entries = acc.Entries();
    for (std::size_t i = 0; i < entries.size();) {
      std::size_t j = i, best = i;
      while (j < entries.size() && entries[j].voxel == entries[i].voxel) {
        if (entries[j].count > entries[best].count) best = j;
        ++j;
      }
      const auto& e = entries[best];
      // Fused standard error of the weighted mean: keep only well-observed voxels (TSDF-like).
      const double fused_sigma = 1.0 / std::sqrt(std::max(e.w, 1e-12));
      if (static_cast<int>(e.count) >= cfg.min_observations && fused_sigma <= cfg.max_fused_sigma) {
        const double c = e.count;
        const Eigen::Vector3f p(static_cast<float>(e.sx / e.w), static_cast<float>(e.sy / e.w),
                                static_cast<float>(e.sz / e.w));
        result.points.push_back(p.cast<double>());
        result.colors.emplace_back(static_cast<std::uint8_t>(std::lround(e.r / c)),
                                   static_cast<std::uint8_t>(std::lround(e.g / c)),
                                   static_cast<std::uint8_t>(std::lround(e.b / c)));
        result.object.push_back(e.object);
      }
      i = j;
    }
  } else if (scannet) {
    FusedMesh fused = fusion->Extract();
    fusion.reset();
    result.timings.Merge(fused.timings);
    ScopedTimer timer(&result.timings, "labels");
    // Label of a mesh vertex: the object of the nearest surface return (1 cm cell centroids);
    // vertices farther than the truncation from every return (marching-cubes bridges over
    // holes) are dropped with their triangles.
    const auto entries = acc.Entries();
    std::vector<Vec3> centres;
    std::vector<int> owner;
    centres.reserve(entries.size());
    for (const auto& e : entries) {
      centres.emplace_back(e.sx / e.w, e.sy / e.w, e.sz / e.w);
      owner.push_back(e.object);
    }
    const geometry::KdTree tree(std::move(centres));
    const double max_d = std::max(cfg.tsdf.truncation, 0.03);
    std::vector<int> remap(fused.mesh.vertices.size(), -1);
    for (std::size_t i = 0; i < fused.mesh.vertices.size(); ++i) {
      if (tree.empty()) break;
      const auto nn = tree.Nearest(fused.mesh.vertices[i]);
      if (nn.first < 0 || nn.second > max_d * max_d) continue;  // squared distance
      remap[i] = static_cast<int>(result.points.size());
      result.points.push_back(fused.mesh.vertices[i].cast<float>().cast<double>());
      result.colors.push_back(fused.colors[i]);
      result.object.push_back(owner[nn.first]);
    }
    for (const auto& face : fused.mesh.faces) {
      const geometry::Vec3i g(remap[face[0]], remap[face[1]], remap[face[2]]);
      if (g.minCoeff() >= 0) result.faces.push_back(g);
    }
  }
  result.observed_cells = observed.Sorted();
  return result;
#endif
}

}  // namespace dimr::data
