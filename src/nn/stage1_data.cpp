// Stage-1 data layer: heading codes, sample cache, network frame, augmentation, batches and
// the background loader. Plain C++ / Eigen on purpose (no LibTorch headers: compiles fast).
#include "dimr/nn/stage1_data.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>
#include <unordered_set>
#include <utility>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"
#include "stage1_heads.h"

namespace dimr::nn {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2.0 * kPi;
constexpr double kBinWidth = kPi / 6.0;
constexpr double kHalfBin = kPi / 12.0;

// ---------------------------------------------------------------- portable random numbers
// std::normal_distribution / uniform_real_distribution differ between standard libraries; these
// helpers use only the raw mt19937_64 output, so the same seed gives the same bytes everywhere.
double Uniform01(std::mt19937_64* rng) {
  return static_cast<double>((*rng)() >> 11) * (1.0 / 9007199254740992.0);  // [0, 1)
}

double Normal(std::mt19937_64* rng) {  // Box-Muller, one value per call
  double u1 = Uniform01(rng);
  const double u2 = Uniform01(rng);
  if (u1 < 1e-300) u1 = 1e-300;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

std::uint64_t Mix(std::uint64_t x) {  // SplitMix64 finaliser
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

std::uint64_t HashSeed(std::uint64_t a, std::uint64_t b, std::uint64_t c = 0) {
  return Mix(Mix(Mix(a) ^ (b + 0x632be59bd9b4e019ull)) ^ (c + 0x8cb92ba72f3d8dd7ull));
}

double WrapPi(double h) {  // to [-pi, pi)
  double a = std::fmod(h + kPi, kTwoPi);
  if (a < 0) a += kTwoPi;
  if (a >= kTwoPi) a -= kTwoPi;
  return a - kPi;
}

bool Finite(const Eigen::Vector3f& p) { return p.allFinite(); }

// ---------------------------------------------------------------- binary little-endian I/O
constexpr char kMagic[8] = {'D', 'I', 'M', 'R', 'S', 'T', '1', 'S'};
constexpr std::uint32_t kVersion = 1;

constexpr bool kBigEndian =
#if defined(__BYTE_ORDER__) && defined(__ORDER_BIG_ENDIAN__) && \
    __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    true;
#else
    false;
#endif

template <typename T>
void SwapBytes(T* values, std::size_t n) {
  if constexpr (kBigEndian && sizeof(T) > 1) {
    for (std::size_t i = 0; i < n; ++i) {
      auto* b = reinterpret_cast<unsigned char*>(values + i);
      std::reverse(b, b + sizeof(T));
    }
  }
}

class Writer {
 public:
  explicit Writer(const std::string& path) : path_(path), f_(path, std::ios::binary) {
    if (!f_) throw Error("cannot open '" + path + "' for writing");
  }
  template <typename T>
  void Put(T v) {
    PutArray(&v, 1);
  }
  template <typename T>
  void PutArray(const T* v, std::size_t n) {
    if (n == 0) return;
    if constexpr (kBigEndian) {
      std::vector<T> tmp(v, v + n);
      SwapBytes(tmp.data(), n);
      Raw(tmp.data(), n * sizeof(T));
    } else {
      Raw(v, n * sizeof(T));
    }
  }
  void Raw(const void* data, std::size_t n) {
    f_.write(static_cast<const char*>(data), static_cast<std::streamsize>(n));
    if (!f_) throw Error("failed writing '" + path_ + "'");
  }
  void Close() {
    f_.close();
    if (!f_) throw Error("failed writing '" + path_ + "'");
  }

 private:
  std::string path_;
  std::ofstream f_;
};

class Reader {
 public:
  explicit Reader(const std::string& path) : path_(path), f_(path, std::ios::binary) {
    if (!f_) throw ParseError(path, "cannot open file");
    f_.seekg(0, std::ios::end);
    const std::streamoff end = f_.tellg();
    if (end < 0) throw ParseError(path, "cannot determine the file size");
    size_ = static_cast<std::uint64_t>(end);
    f_.seekg(0, std::ios::beg);
  }
  std::uint64_t Remaining() const { return size_ - pos_; }
  // Checks that `count` elements of `elem` bytes fit into the rest of the file.
  void Need(std::uint64_t count, std::uint64_t elem, const std::string& what) const {
    if (elem != 0 && count > Remaining() / elem) {
      throw ParseError(path_, what + ": needs " + std::to_string(count) + " x " +
                                  std::to_string(elem) + " bytes, only " +
                                  std::to_string(Remaining()) + " left (truncated or corrupt)");
    }
  }
  template <typename T>
  T Get(const std::string& what) {
    T v;
    GetArray(&v, 1, what);
    return v;
  }
  template <typename T>
  void GetArray(T* v, std::size_t n, const std::string& what) {
    Need(n, sizeof(T), what);
    if (n == 0) return;
    f_.read(reinterpret_cast<char*>(v), static_cast<std::streamsize>(n * sizeof(T)));
    if (!f_) throw ParseError(path_, what + ": read failed");
    pos_ += n * sizeof(T);
    SwapBytes(v, n);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::ifstream f_;
  std::uint64_t size_ = 0;
  std::uint64_t pos_ = 0;
};

void PutVec3(Writer* w, const std::vector<Eigen::Vector3f>& v) {
  std::vector<float> flat(v.size() * 3);
  for (std::size_t i = 0; i < v.size(); ++i) {
    for (int k = 0; k < 3; ++k) flat[3 * i + k] = v[i][k];
  }
  w->PutArray(flat.data(), flat.size());
}

void GetVec3(Reader* r, std::uint64_t n, std::vector<Eigen::Vector3f>* out,
             const std::string& what) {
  r->Need(n, 12, what);
  std::vector<float> flat(n * 3);
  r->GetArray(flat.data(), flat.size(), what);
  out->resize(n);
  for (std::size_t i = 0; i < n; ++i) (*out)[i] = {flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]};
}

void PutInts(Writer* w, const std::vector<int>& v) {
  std::vector<std::int32_t> tmp(v.begin(), v.end());
  w->PutArray(tmp.data(), tmp.size());
}

void GetInts(Reader* r, std::uint64_t n, std::vector<int>* out, const std::string& what) {
  r->Need(n, 4, what);
  std::vector<std::int32_t> tmp(n);
  r->GetArray(tmp.data(), tmp.size(), what);
  out->assign(tmp.begin(), tmp.end());
}

// ---------------------------------------------------------------- elastic helpers
// Zero-padded 3-tap box filter (1/3, 1/3, 1/3) along `axis` of a dense grid (x slowest).
void Blur(std::vector<float>* g, const int dims[3], int axis) {
  const std::ptrdiff_t stride[3] = {static_cast<std::ptrdiff_t>(dims[1]) * dims[2], dims[2], 1};
  const std::vector<float> src = *g;
  for (int x = 0; x < dims[0]; ++x) {
    for (int y = 0; y < dims[1]; ++y) {
      for (int z = 0; z < dims[2]; ++z) {
        const int c[3] = {x, y, z};
        const std::ptrdiff_t i = x * stride[0] + y * stride[1] + z;
        float s = src[i];
        if (c[axis] > 0) s += src[i - stride[axis]];
        if (c[axis] + 1 < dims[axis]) s += src[i + stride[axis]];
        (*g)[i] = s / 3.0f;
      }
    }
  }
}

std::string SampleLabel(const Stage1Sample& s) { return "Stage1Sample '" + s.name + "'"; }

}  // namespace

// ---------------------------------------------------------------- heading
HeadingCode EncodeHeading(double heading) {
  HeadingCode code;
  if (!std::isfinite(heading)) throw InvalidArgument("EncodeHeading: non-finite heading");
  double a = std::fmod(heading, kTwoPi);
  if (a < 0) a += kTwoPi;
  double s = std::fmod(a + kHalfBin, kTwoPi);
  if (s < 0) s += kTwoPi;
  int k = static_cast<int>(std::floor(s / kBinWidth));
  if (k >= kHeadingBins) {  // s rounded up to 2 pi
    k = 0;
    s -= kTwoPi;
  }
  k = std::max(0, k);
  const double r = (s - (k * kBinWidth + kHalfBin)) / kHalfBin;
  code.bin = k;
  code.residual = std::min(std::max(r, -1.0), std::nextafter(1.0, 0.0));
  return code;
}

double DecodeHeading(int bin, double residual) {
  // Predicted residuals are unbounded, so wrap fully (fmod), not just once.
  double h = std::fmod(bin * kBinWidth + residual * kHalfBin, kTwoPi);
  if (h > kPi) {
    h -= kTwoPi;
  } else if (h <= -kPi) {
    h += kTwoPi;
  }
  return h;
}

// ---------------------------------------------------------------- samples
void Stage1Sample::Validate() const {
  const std::string who = SampleLabel(*this);
  const std::size_t n = points.size();
  if (!colors.empty() && colors.size() != n) {
    throw InvalidArgument(who + ": colors has " + std::to_string(colors.size()) + " entries for " +
                          std::to_string(n) + " points");
  }
  if (semantic.size() != n) {
    throw InvalidArgument(who + ": semantic has " + std::to_string(semantic.size()) +
                          " entries for " + std::to_string(n) + " points");
  }
  if (instance.size() != n) {
    throw InvalidArgument(who + ": instance has " + std::to_string(instance.size()) +
                          " entries for " + std::to_string(n) + " points");
  }
  const int num_inst = static_cast<int>(instances.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (!Finite(points[i])) {
      throw InvalidArgument(who + ": points[" + std::to_string(i) + "] is not finite");
    }
    if (!colors.empty() && !Finite(colors[i])) {
      throw InvalidArgument(who + ": colors[" + std::to_string(i) + "] is not finite");
    }
    const int s = semantic[i];
    if (s != kStage1Ignore && (s < 0 || s >= kStage1Classes)) {
      throw InvalidArgument(who + ": semantic[" + std::to_string(i) + "] = " + std::to_string(s) +
                            " is neither 0..24 nor kStage1Ignore");
    }
    if (instance[i] < -1 || instance[i] >= num_inst) {
      throw InvalidArgument(who + ": instance[" + std::to_string(i) +
                            "] = " + std::to_string(instance[i]) + " is out of range [-1, " +
                            std::to_string(num_inst) + ")");
    }
  }
  for (int k = 0; k < num_inst; ++k) {
    const Stage1Instance& in = instances[k];
    const std::string field = who + ": instances[" + std::to_string(k) + "]";
    if (in.semantic != kStage1Ignore && (in.semantic < 0 || in.semantic >= kStage1Classes)) {
      throw InvalidArgument(field + ".semantic = " + std::to_string(in.semantic) + " out of range");
    }
    if (in.cad_class < -1 || in.cad_class >= 8) {
      throw InvalidArgument(field + ".cad_class = " + std::to_string(in.cad_class) +
                            " out of range [-1, 8)");
    }
    if (!std::isfinite(in.heading)) throw InvalidArgument(field + ".heading is not finite");
  }
  if (!weight.empty()) {
    if (weight.size() != n) {
      throw InvalidArgument(who + ": weight has " + std::to_string(weight.size()) +
                            " entries for " + std::to_string(n) + " points");
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!(weight[i] > 0) || !std::isfinite(weight[i])) {
        throw InvalidArgument(who + ": weight[" + std::to_string(i) +
                              "] = " + std::to_string(weight[i]) + " is not finite and > 0");
      }
    }
  }
}

void WriteStage1Samples(const std::string& path, const std::vector<Stage1Sample>& samples) {
  for (std::size_t i = 0; i < samples.size(); ++i) {
    try {
      samples[i].Validate();
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("WriteStage1Samples(" + path + "): sample " + std::to_string(i) + ": " +
                            e.what());
    }
  }
  Writer w(path);
  w.Raw(kMagic, sizeof(kMagic));
  w.Put(kVersion);
  w.Put(static_cast<std::uint64_t>(samples.size()));
  for (const Stage1Sample& s : samples) {
    w.Put(static_cast<std::uint32_t>(s.name.size()));
    w.Raw(s.name.data(), s.name.size());
    w.Put(static_cast<std::uint64_t>(s.points.size()));
    PutVec3(&w, s.points);
    w.Put(static_cast<std::uint8_t>(s.colors.empty() ? 0 : 1));
    PutVec3(&w, s.colors);
    PutInts(&w, s.semantic);
    PutInts(&w, s.instance);
    w.Put(static_cast<std::uint64_t>(s.instances.size()));
    for (const Stage1Instance& in : s.instances) {
      w.Put(static_cast<std::int32_t>(in.semantic));
      w.Put(static_cast<std::int32_t>(in.cad_class));
      w.Put(static_cast<std::uint8_t>(in.has_heading ? 1 : 0));
      w.Put(in.heading);
    }
  }
  w.Close();
}

std::vector<Stage1Sample> ReadStage1Samples(const std::string& path) {
  Reader r(path);
  char magic[8];
  r.GetArray(magic, 8, "magic");
  if (std::memcmp(magic, kMagic, 8) != 0) {
    throw ParseError(path, "not a dimr stage-1 sample cache (bad magic)");
  }
  const auto version = r.Get<std::uint32_t>("version");
  if (version != kVersion) {
    throw ParseError(path, "unsupported stage-1 cache version " + std::to_string(version));
  }
  const auto count = r.Get<std::uint64_t>("sample count");
  // Smallest sample: name length + point count + colour flag + instance count = 21 bytes.
  r.Need(count, 21, "sample count " + std::to_string(count));
  std::vector<Stage1Sample> out(count);
  for (std::uint64_t i = 0; i < count; ++i) {
    const std::string where = "sample " + std::to_string(i);
    Stage1Sample& s = out[i];
    const auto name_len = r.Get<std::uint32_t>(where + ": name length");
    s.name.resize(name_len);
    r.GetArray(s.name.data(), name_len, where + ": name");
    const auto n = r.Get<std::uint64_t>(where + ": point count");
    r.Need(n, 12 + 4 + 4, where + ": " + std::to_string(n) + " points");
    GetVec3(&r, n, &s.points, where + ": points");
    const auto has_colors = r.Get<std::uint8_t>(where + ": colour flag");
    if (has_colors > 1) {
      throw ParseError(path, where + ": colour flag " + std::to_string(has_colors) + " is not 0/1");
    }
    if (has_colors) GetVec3(&r, n, &s.colors, where + ": colors");
    GetInts(&r, n, &s.semantic, where + ": semantic");
    GetInts(&r, n, &s.instance, where + ": instance");
    const auto num_inst = r.Get<std::uint64_t>(where + ": instance count");
    r.Need(num_inst, 17, where + ": " + std::to_string(num_inst) + " instances");
    s.instances.resize(num_inst);
    for (auto& in : s.instances) {
      in.semantic = r.Get<std::int32_t>(where + ": instance semantic");
      in.cad_class = r.Get<std::int32_t>(where + ": instance cad_class");
      const auto has = r.Get<std::uint8_t>(where + ": instance heading flag");
      if (has > 1) throw ParseError(path, where + ": heading flag is not 0/1");
      in.has_heading = has != 0;
      in.heading = r.Get<double>(where + ": instance heading");
    }
    try {
      s.Validate();
    } catch (const InvalidArgument& e) {
      throw ParseError(path, where + ": " + e.what());
    }
  }
  if (r.Remaining() != 0) {
    throw ParseError(path, std::to_string(r.Remaining()) + " trailing bytes after the last sample");
  }
  return out;
}

// ---------------------------------------------------------------- hard examples
void InWallPlaneConfig::Validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v))
      throw InvalidArgument(std::string("InWallPlaneConfig: '") + name +
                            "' must be finite and > 0");
  };
  positive(distance, "distance");
  positive(max_thickness, "max_thickness");
  if (!(margin >= 0) || !std::isfinite(margin))
    throw InvalidArgument("InWallPlaneConfig: 'margin' must be finite and >= 0");
  if (min_points < 3) throw InvalidArgument("InWallPlaneConfig: 'min_points' must be >= 3");
  if (!(min_instance_share >= 0 && min_instance_share <= 1))
    throw InvalidArgument("InWallPlaneConfig: 'min_instance_share' must be in [0, 1]");
  if (!(wall_context >= 0) || !std::isfinite(wall_context))
    throw InvalidArgument("InWallPlaneConfig: 'wall_context' must be finite and >= 0");
}

std::vector<std::uint8_t> InWallPlanePoints(const Stage1Sample& sample,
                                            const InWallPlaneConfig& config) {
  sample.Validate();
  config.Validate();
  constexpr int kWall = 0, kFloor = 1;  // RFS classes (core/labels.h)
  const std::size_t n = sample.points.size();
  std::vector<std::uint8_t> out(n, 0);
  // Wall points per instance.
  std::vector<std::vector<std::size_t>> members(sample.instances.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (sample.semantic[i] == kWall && sample.instance[i] >= 0)
      members[sample.instance[i]].push_back(i);
  }
  struct Plane {
    Eigen::Vector2d centre, normal, along;
    double u0, u1, z0, z1;
    int wall;  // instance
  };
  std::vector<Plane> planes;
  for (std::size_t w = 0; w < members.size(); ++w) {
    const std::vector<std::size_t>& idx = members[w];
    if (static_cast<int>(idx.size()) < config.min_points) continue;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (std::size_t i : idx) mean += sample.points[i].head<2>().cast<double>();
    mean /= static_cast<double>(idx.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (std::size_t i : idx) {
      const Eigen::Vector2d d = sample.points[i].head<2>().cast<double>() - mean;
      cov += d * d.transpose();
    }
    cov /= static_cast<double>(idx.size());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);  // ascending eigenvalues
    if (std::sqrt(std::max(0.0, eig.eigenvalues()[0])) > config.max_thickness) continue;
    Plane p;
    p.wall = static_cast<int>(w);
    p.centre = mean;
    p.normal = eig.eigenvectors().col(0);
    p.along = eig.eigenvectors().col(1);
    p.u0 = p.z0 = INFINITY;
    p.u1 = p.z1 = -INFINITY;
    for (std::size_t i : idx) {
      const double u = p.along.dot(sample.points[i].head<2>().cast<double>() - mean);
      p.u0 = std::min(p.u0, u);
      p.u1 = std::max(p.u1, u);
      p.z0 = std::min(p.z0, static_cast<double>(sample.points[i].z()));
      p.z1 = std::max(p.z1, static_cast<double>(sample.points[i].z()));
    }
    planes.push_back(p);
  }
  if (planes.empty()) return out;
  std::vector<int> plane_of(n, -1);  // of the points marked 1
  for (std::size_t i = 0; i < n; ++i) {
    const int s = sample.semantic[i];
    if (s == kStage1Ignore || s == kWall || s == kFloor) continue;
    const Eigen::Vector3f& q = sample.points[i];
    for (std::size_t k = 0; k < planes.size(); ++k) {
      const Plane& p = planes[k];
      const Eigen::Vector2d d = q.head<2>().cast<double>() - p.centre;
      const double u = p.along.dot(d);
      if (std::abs(p.normal.dot(d)) <= config.distance && u >= p.u0 - config.margin &&
          u <= p.u1 + config.margin && q.z() >= p.z0 - config.margin &&
          q.z() <= p.z1 + config.margin) {
        out[i] = 1;
        plane_of[i] = static_cast<int>(k);
        break;
      }
    }
  }
  if (config.min_instance_share > 0) {
    // Keep the objects that are flat in a wall plane.
    std::vector<std::size_t> total(sample.instances.size(), 0), inside(sample.instances.size(), 0);
    for (std::size_t i = 0; i < n; ++i) {
      const int k = sample.instance[i];
      if (k < 0) continue;
      ++total[k];
      inside[k] += out[i];
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!out[i]) continue;
      const int k = sample.instance[i];
      if (k < 0 || static_cast<double>(inside[k]) <
                       config.min_instance_share * static_cast<double>(total[k]))
        out[i] = 0;
    }
  }
  if (config.wall_context <= 0) return out;
  // Wall context: per plane, the 5 cm cells (along the wall, z) of its marked object points,
  // dilated by a disc of radius wall_context; the plane's own wall points in them get 2.
  constexpr double kCell = 0.05;
  const int reach = static_cast<int>(std::ceil(config.wall_context / kCell));
  std::vector<std::pair<int, int>> disc;
  for (int da = -reach; da <= reach; ++da) {
    for (int db = -reach; db <= reach; ++db) {
      if ((da * da + db * db) * kCell * kCell <= config.wall_context * config.wall_context)
        disc.emplace_back(da, db);
    }
  }
  auto key = [](long long a, long long b) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
           static_cast<std::uint32_t>(b);
  };
  for (std::size_t k = 0; k < planes.size(); ++k) {
    const Plane& p = planes[k];
    auto cell = [&](std::size_t i, long long* a, long long* b) {
      const Eigen::Vector2d d = sample.points[i].head<2>().cast<double>() - p.centre;
      *a = static_cast<long long>(std::floor(p.along.dot(d) / kCell));
      *b = static_cast<long long>(std::floor(sample.points[i].z() / kCell));
    };
    std::unordered_set<std::uint64_t> seeds, near;
    for (std::size_t i = 0; i < n; ++i) {
      if (out[i] != 1 || plane_of[i] != static_cast<int>(k)) continue;
      long long a, b;
      cell(i, &a, &b);
      if (!seeds.insert(key(a, b)).second) continue;
      for (const auto& [da, db] : disc) near.insert(key(a + da, b + db));
    }
    if (near.empty()) continue;
    for (std::size_t i : members[p.wall]) {
      long long a, b;
      cell(i, &a, &b);
      if (near.count(key(a, b))) out[i] = 2;
    }
  }
  return out;
}

std::size_t SetInWallPlaneWeights(Stage1Sample* sample, float weight,
                                  const InWallPlaneConfig& config) {
  if (sample == nullptr) throw InvalidArgument("SetInWallPlaneWeights: null sample");
  if (!(weight > 0) || !std::isfinite(weight)) {
    throw InvalidArgument("SetInWallPlaneWeights: weight " + std::to_string(weight) +
                          " is not finite and > 0");
  }
  sample->weight.clear();
  const std::vector<std::uint8_t> in = InWallPlanePoints(*sample, config);
  const std::size_t count =
      in.size() - static_cast<std::size_t>(std::count(in.begin(), in.end(), 0));
  if (weight == 1.0f) return count;
  sample->weight.resize(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) sample->weight[i] = in[i] ? weight : 1.0f;
  return count;
}

// ---------------------------------------------------------------- network frame
namespace {

// The floor search of EstimateNetworkFrame as the sorted sweep it was first written as: sort z,
// walk the occupied 2 cm bins upwards from the lowest point, take the first bin with `need`
// points and the median of it and the next bin. Only for clouds EstimateNetworkFrame's
// histogram does not cover.
double FloorBySortedSweep(std::vector<float> z, std::size_t need, double z0, double bin) {
  std::sort(z.begin(), z.end());
  const std::size_t n = z.size();
  auto bin_of = [&](float v) { return static_cast<long long>(std::floor((v - z0) / bin)); };
  double floor_z = z[std::min(n - 1, static_cast<std::size_t>(0.01 * (n - 1)))];
  for (std::size_t begin = 0; begin < n;) {
    const long long b = bin_of(z[begin]);
    std::size_t end = begin;
    while (end < n && bin_of(z[end]) == b) ++end;
    if (end - begin >= need) {
      // The floor: median of this bin and the next one (the floor's noise may straddle a
      // bin boundary).
      std::size_t stop = end;
      while (stop < n && bin_of(z[stop]) <= b + 1) ++stop;
      floor_z = z[begin + (stop - begin) / 2];
      break;
    }
    begin = end;
  }
  return floor_z;
}

// EstimateNetworkFrame on n >= 1 finite points whose bounding box is [lo, hi] (the callers
// find it in their own checking loop).
NetworkFrame FrameInBounds(const Eigen::Vector3f* points, std::size_t n, const Eigen::Vector3f& lo,
                           const Eigen::Vector3f& hi) {
  const std::size_t need = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(0.02 * n)));
  constexpr double kBin = 0.02;
  const double z0 = lo.z();
  // The sorted sweep's answer without sorting (a sort of z was ~6 ms of every 100k-point
  // pass): the lowest bin b holding >= need points, found on a histogram of the bins
  // [0, kBins) above the lowest point; the floor is the element of rank (count(b) +
  // count(b + 1)) / 2 among the points of bins b and b + 1 (nth_element: the same value the
  // sweep reads from the sorted array). Bin numbers are the sweep's floor((z - z0) / bin).
  // Clouds whose answer lies beyond the histogram (no such bin below kBins - 1 although
  // some point is above it) take the sweep itself.
  constexpr long long kBins = 1 << 16;  // 1.3 km of 2 cm bins
  std::vector<std::uint32_t> count(kBins, 0);
  bool beyond = false;
  // (z - z0) / kBin >= 0, so its floor is its truncation (no libm floor call per point).
  for (std::size_t i = 0; i < n; ++i) {
    const double b = (points[i].z() - z0) / kBin;
    if (b < kBins) {
      ++count[static_cast<std::size_t>(b)];
    } else {
      beyond = true;
    }
  }
  long long found = -1;
  for (long long b = 0; b < kBins - 1; ++b) {
    if (count[b] >= need) {
      found = b;
      break;
    }
  }
  double floor_z = 0;
  if (found >= 0) {
    const std::size_t rank = (count[found] + count[found + 1]) / 2;
    // Branch-free compaction of the points of bins found and found + 1 (a few tens of % of a
    // room's points, in no predictable order: the push_back loop mispredicted ~0.5-1 ms per
    // 100k points): every z is written, the index advances only for those kept; one spare slot
    // takes the writes past the last kept one. The kept z are then split into sub-bins,
    // sub = min(floor(float(b - found) * 512), 1023): b - found is in [0, 2), every step is a
    // monotone rounding, so sub is a non-decreasing function of z and the element of rank
    // `rank` is the element of rank (rank - points in lower sub-bins) of its sub-bin:
    // nth_element on a few hundred values instead of tens of thousands (~0.5 ms per 100k).
    constexpr int kSub = 1024;
    const std::size_t kept = count[found] + count[found + 1];
    std::vector<float> z(kept + 1), d(kept + 1);
    float* zp = z.data();
    float* dp = d.data();
    std::size_t m = 0;
    const double lo_b = static_cast<double>(found), hi_b = static_cast<double>(found + 2);
    for (std::size_t i = 0; i < n; ++i) {
      const double b = (points[i].z() - z0) / kBin;  // floor(b) is found or found + 1
      zp[m] = points[i].z();
      dp[m] = static_cast<float>(b - lo_b);
      m += static_cast<std::size_t>((b >= lo_b) & (b < hi_b));
      if (m > kept) m = kept;  // (cannot happen: the histogram counted these bins)
    }
    const auto sub_of = [](float x) {  // x in [0, 2]
      return std::min(static_cast<int>(x * (kSub / 2)), kSub - 1);
    };
    std::vector<std::uint32_t> sub_count(kSub, 0);
    for (std::size_t i = 0; i < m; ++i) ++sub_count[sub_of(dp[i])];
    int j = 0;
    std::size_t below = 0;
    while (j < kSub - 1 && below + sub_count[j] <= rank) below += sub_count[j++];
    std::size_t q = 0;
    for (std::size_t i = 0; i < m; ++i) {
      zp[q] = zp[i];  // q <= i: in place
      q += static_cast<std::size_t>(sub_of(dp[i]) == j);
    }
    const std::size_t r = rank - below;  // < q: sub-bin j holds the element of rank `rank`
    std::nth_element(z.begin(), z.begin() + r, z.begin() + q);
    floor_z = z[r];
  } else if (!beyond && count[kBins - 1] < need) {
    // No bin qualifies: the 1st percentile.
    std::vector<float> z(n);
    for (std::size_t i = 0; i < n; ++i) z[i] = points[i].z();
    const std::size_t k = std::min(n - 1, static_cast<std::size_t>(0.01 * (n - 1)));
    std::nth_element(z.begin(), z.begin() + k, z.end());
    floor_z = z[k];
  } else {
    std::vector<float> z(n);
    for (std::size_t i = 0; i < n; ++i) z[i] = points[i].z();
    floor_z = FloorBySortedSweep(std::move(z), need, z0, kBin);
  }
  NetworkFrame frame;
  frame.origin = Eigen::Vector3f(0.5f * (lo.x() + hi.x()), 0.5f * (lo.y() + hi.y()),
                                 static_cast<float>(floor_z));
  frame.floor_z = frame.origin.z();
  return frame;
}

// The bounding box [*lo, *hi] of n >= 1 points, checked in the same pass: a non-finite point
// (or colour, if `colors` is given) throws InvalidArgument "<who> point <i> is not finite"
// ("... colour <i> ..."); a NaN fails allFinite before it could enter the min / max.
void CheckedBounds(const Eigen::Vector3f* points, const Eigen::Vector3f* colors, std::size_t n,
                   const std::string& who, Eigen::Vector3f* lo, Eigen::Vector3f* hi) {
  *lo = points[0];
  *hi = points[0];
  for (std::size_t i = 0; i < n; ++i) {
    if (!Finite(points[i])) {
      throw InvalidArgument(who + " point " + std::to_string(i) + " is not finite");
    }
    if (colors != nullptr && !Finite(colors[i])) {
      throw InvalidArgument(who + " colour " + std::to_string(i) + " is not finite");
    }
    *lo = lo->cwiseMin(points[i]);
    *hi = hi->cwiseMax(points[i]);
  }
}

// EstimateNetworkFrame on n points (a view without a copy).
NetworkFrame EstimateFrame(const Eigen::Vector3f* points, std::size_t n) {
  if (n == 0) throw InvalidArgument("EstimateNetworkFrame: empty point cloud");
  Eigen::Vector3f lo, hi;
  CheckedBounds(points, nullptr, n, "EstimateNetworkFrame:", &lo, &hi);
  return FrameInBounds(points, n, lo, hi);
}

}  // namespace

NetworkFrame EstimateNetworkFrame(const std::vector<Eigen::Vector3f>& points) {
  return EstimateFrame(points.data(), points.size());
}

// ---------------------------------------------------------------- configs
void AugmentConfig::Validate() const {
  auto fail = [](const std::string& what) { throw InvalidArgument("AugmentConfig." + what); };
  if (!(jitter >= 0 && jitter < 10)) fail("jitter must be in [0, 10)");
  if (!(elastic_gran0 > 0 && std::isfinite(elastic_gran0))) fail("elastic_gran0 must be > 0");
  if (!(elastic_gran1 > 0 && std::isfinite(elastic_gran1))) fail("elastic_gran1 must be > 0");
  if (!(elastic_mag0 >= 0 && std::isfinite(elastic_mag0))) fail("elastic_mag0 must be >= 0");
  if (!(elastic_mag1 >= 0 && std::isfinite(elastic_mag1))) fail("elastic_mag1 must be >= 0");
  if (max_points < 1) fail("max_points must be >= 1");
  realism.Validate();
}

namespace {
const config::Fields<RealismAugment>& RealismFields() {
  using R = RealismAugment;
  static const config::Fields<R> fields =
      config::Fields<R>("stage1 realism augmentation")
          .Number(
              "color_jitter", [](R& c) -> double& { return c.color_jitter; }, "",
              "sigma of the per-scene channel gain (offset: half of it)", 0.0, 1.0)
          .Number(
              "color_contrast", [](R& c) -> double& { return c.color_contrast; }, "",
              "largest per-scene contrast stretch about the mean colour", 1.0, 10.0)
          .Number(
              "color_noise", [](R& c) -> double& { return c.color_noise; }, "",
              "sigma of per-point colour noise", 0.0, 1.0)
          .Number(
              "greyscale", [](R& c) -> double& { return c.greyscale; }, "",
              "probability of a greyscale scene", 0.0, 1.0)
          .Number(
              "color_drop", [](R& c) -> double& { return c.color_drop; }, "",
              "probability of a scene without colour (all 0.5)", 0.0, 1.0)
          .Number(
              "point_noise", [](R& c) -> double& { return c.point_noise; }, "m",
              "sigma of per-point Gaussian displacement", 0.0, 0.1)
          .Number(
              "scale_min", [](R& c) -> double& { return c.scale_min; }, "",
              "smallest per-scene isotropic scale", 0.5, 2.0)
          .Number(
              "scale_max", [](R& c) -> double& { return c.scale_max; }, "",
              "largest per-scene isotropic scale", 0.5, 2.0)
          .Check([](const R& c) -> std::string {
            return c.scale_min > c.scale_max ? "scale_min > scale_max" : "";
          })
          .Number(
              "point_dropout", [](R& c) -> double& { return c.point_dropout; }, "",
              "largest fraction of points dropped per scene", 0.0, 0.9)
          .Number(
              "instance_mix", [](R& c) -> double& { return c.instance_mix; }, "",
              "probability that a scene receives CAD instances of another scene of the batch", 0.0,
              1.0)
          .Number(
              "instance_mix_count", [](R& c) -> int& { return c.instance_mix_count; }, "",
              "instances pasted per mixed scene (at most)", 0, 64)
          .Number(
              "cuboid_mix", [](R& c) -> double& { return c.cuboid_mix; }, "",
              "probability that a scene takes 1-3 of its x-y quadrants from another scene of the "
              "batch",
              0.0, 1.0);
  return fields;
}
}  // namespace

bool RealismAugment::any() const {
  return any_color() || point_noise > 0 || scale_min != 1 || scale_max != 1 || point_dropout > 0;
}

bool RealismAugment::any_color() const {
  return color_jitter > 0 || color_contrast > 1 || color_noise > 0 || greyscale > 0 ||
         color_drop > 0;
}

void RealismAugment::Validate() const { RealismFields().Validate(*this); }

Stage1Sample MixInstances(const Stage1Sample& dst, const Stage1Sample& src, int count,
                          std::mt19937_64* rng, int min_points) {
  dst.Validate();
  src.Validate();
  if (count < 0) throw InvalidArgument("MixInstances: count must be >= 0");
  if (rng == nullptr) throw InvalidArgument("MixInstances: null random generator");
  Stage1Sample out = dst;
  if (count == 0 || dst.points.empty() || src.points.empty()) return out;
  // Eligible source instances and their points.
  std::vector<std::vector<std::size_t>> members(src.instances.size());
  for (std::size_t i = 0; i < src.points.size(); ++i) {
    if (src.instance[i] >= 0) members[src.instance[i]].push_back(i);
  }
  std::vector<int> eligible;
  for (std::size_t k = 0; k < src.instances.size(); ++k) {
    if (src.instances[k].cad_class >= 0 && static_cast<int>(members[k].size()) >= min_points)
      eligible.push_back(static_cast<int>(k));
  }
  if (eligible.empty()) return out;
  for (std::size_t i = eligible.size(); i-- > 1;) {  // Fisher-Yates on our portable uniform
    const auto j =
        std::min(i, static_cast<std::size_t>(Uniform01(rng) * static_cast<double>(i + 1)));
    std::swap(eligible[i], eligible[j]);
  }
  if (static_cast<int>(eligible.size()) > count) eligible.resize(count);
  Eigen::Vector3f lo = dst.points[0], hi = dst.points[0];
  for (const auto& p : dst.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const float floor_z = EstimateNetworkFrame(dst.points).floor_z;
  const bool colours = !dst.colors.empty();
  for (const int k : eligible) {
    const std::vector<std::size_t>& idx = members[k];
    Eigen::Vector3f ilo = src.points[idx[0]], ihi = src.points[idx[0]];
    for (std::size_t i : idx) {
      ilo = ilo.cwiseMin(src.points[i]);
      ihi = ihi.cwiseMax(src.points[i]);
    }
    const Eigen::Vector2f centre = 0.5f * (ilo + ihi).head<2>();
    const double angle = 2.0 * M_PI * Uniform01(rng);
    const float c = static_cast<float>(std::cos(angle)), sn = static_cast<float>(std::sin(angle));
    // Rotated footprint radius: the half-diagonal bounds it for every angle.
    const float radius = 0.5f * (ihi - ilo).head<2>().norm();
    Eigen::Vector2f target;
    for (int a = 0; a < 2; ++a) {
      const float span = hi[a] - lo[a] - 2 * radius;
      target[a] = span > 0 ? lo[a] + radius + static_cast<float>(Uniform01(rng)) * span
                           : 0.5f * (lo[a] + hi[a]);
    }
    const int new_index = static_cast<int>(out.instances.size());
    Stage1Instance inst = src.instances[k];
    if (inst.has_heading) inst.heading += angle;
    out.instances.push_back(inst);
    const float dz = floor_z - ilo.z();
    for (std::size_t i : idx) {
      const Eigen::Vector3f& p = src.points[i];
      const float x = p.x() - centre.x(), y = p.y() - centre.y();
      out.points.emplace_back(c * x - sn * y + target.x(), sn * x + c * y + target.y(), p.z() + dz);
      if (colours) {
        out.colors.push_back(src.colors.empty() ? Eigen::Vector3f::Constant(0.5f) : src.colors[i]);
      }
      out.semantic.push_back(src.semantic[i]);
      out.instance.push_back(new_index);
      if (!out.weight.empty()) out.weight.push_back(1.0f);
    }
  }
  return out;
}

Stage1Sample MixCuboids(const Stage1Sample& dst, const Stage1Sample& src, std::mt19937_64* rng) {
  dst.Validate();
  src.Validate();
  if (rng == nullptr) throw InvalidArgument("MixCuboids: null random generator");
  if (dst.points.empty() || src.points.empty()) return dst;
  // Split points (x, y) in the middle of each scene's footprint.
  const auto split = [rng](const std::vector<Eigen::Vector3f>& pts) {
    Eigen::Vector2f lo = pts[0].head<2>(), hi = pts[0].head<2>();
    for (const auto& p : pts) {
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
    Eigen::Vector2f c;
    for (int a = 0; a < 2; ++a) {
      c[a] = lo[a] + static_cast<float>(0.3 + 0.4 * Uniform01(rng)) * (hi[a] - lo[a]);
    }
    return c;
  };
  const Eigen::Vector2f cd = split(dst.points), cs = split(src.points);
  // Which quadrants come from src: 1..3 of the 4.
  int from_src = 0;
  while (from_src == 0 || from_src == 15) {
    from_src = 0;
    for (int q = 0; q < 4; ++q) from_src |= (Uniform01(rng) < 0.5 ? 1 : 0) << q;
  }
  const auto quadrant = [](const Eigen::Vector3f& p, const Eigen::Vector2f& c) {
    return (p.x() >= c.x() ? 1 : 0) + (p.y() >= c.y() ? 2 : 0);
  };
  const Eigen::Vector3f shift(
      cd.x() - cs.x(), cd.y() - cs.y(),
      EstimateNetworkFrame(dst.points).floor_z - EstimateNetworkFrame(src.points).floor_z);
  Stage1Sample out;
  out.name = dst.name;
  const bool colours = !dst.colors.empty();
  const bool weights = !dst.weight.empty() || !src.weight.empty();
  std::vector<int> dst_map(dst.instances.size(), -1), src_map(src.instances.size(), -1);
  const auto take = [&](const Stage1Sample& s, std::size_t i, const Eigen::Vector3f& offset,
                        std::vector<int>* map) {
    out.points.push_back(s.points[i] + offset);
    if (colours) {
      out.colors.push_back(s.colors.empty() ? Eigen::Vector3f::Constant(0.5f) : s.colors[i]);
    }
    out.semantic.push_back(s.semantic[i]);
    int inst = s.instance[i];
    if (inst >= 0) {
      if ((*map)[inst] < 0) {
        (*map)[inst] = static_cast<int>(out.instances.size());
        out.instances.push_back(s.instances[inst]);
      }
      inst = (*map)[inst];
    }
    out.instance.push_back(inst);
    if (weights) out.weight.push_back(s.weight.empty() ? 1.0f : s.weight[i]);
  };
  for (std::size_t i = 0; i < dst.points.size(); ++i) {
    if (!((from_src >> quadrant(dst.points[i], cd)) & 1)) {
      take(dst, i, Eigen::Vector3f::Zero(), &dst_map);
    }
  }
  for (std::size_t i = 0; i < src.points.size(); ++i) {
    if ((from_src >> quadrant(src.points[i], cs)) & 1) take(src, i, shift, &src_map);
  }
  if (out.points.empty()) return dst;  // both kept sides empty (degenerate scenes)
  return out;
}

std::string RealismAugment::ToString() const { return RealismFields().Format(*this); }

RealismAugment RealismAugment::FromString(const std::string& text) {
  const RealismAugment r = RealismFields().Parse(text);
  r.Validate();
  return r;
}

void AugmentRealismPoints(std::vector<Eigen::Vector3f>* points, const RealismAugment& c,
                          std::mt19937_64* rng) {
  const double scale = c.scale_min + (c.scale_max - c.scale_min) * Uniform01(rng);
  if (scale != 1.0) {
    for (auto& p : *points) p *= static_cast<float>(scale);
  }
  if (c.point_noise > 0) {
    for (auto& p : *points) {
      for (int k = 0; k < 3; ++k) p[k] += static_cast<float>(c.point_noise * Normal(rng));
    }
  }
}

std::vector<Eigen::Vector3f> AugmentRealismColors(const std::vector<Eigen::Vector3f>& colors,
                                                  const RealismAugment& c, std::mt19937_64* rng) {
  std::vector<Eigen::Vector3f> out = colors;
  if (out.empty()) return out;
  // Draws in a fixed order, all of them every time, so one option does not shift the others.
  const double u_drop = Uniform01(rng), u_grey = Uniform01(rng), u_con = Uniform01(rng);
  Eigen::Vector3d gain, offset;
  for (int k = 0; k < 3; ++k) gain[k] = 1.0 + c.color_jitter * Normal(rng);
  for (int k = 0; k < 3; ++k) offset[k] = 0.5 * c.color_jitter * Normal(rng);
  if (u_drop < c.color_drop) {
    for (auto& v : out) v.setConstant(0.5f);
    return out;
  }
  if (u_grey < c.greyscale) {
    for (auto& v : out) v.setConstant(0.299f * v[0] + 0.587f * v[1] + 0.114f * v[2]);
  }
  const double contrast = 1.0 + (c.color_contrast - 1.0) * u_con;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& v : out) mean += v.cast<double>();
  mean /= static_cast<double>(out.size());
  for (auto& v : out) {
    for (int k = 0; k < 3; ++k) {
      double x = mean[k] + contrast * (v[k] - mean[k]);
      x = gain[k] * x + offset[k];
      if (c.color_noise > 0) x += c.color_noise * Normal(rng);
      v[k] = static_cast<float>(std::clamp(x, 0.0, 1.0));
    }
  }
  return out;
}

void AugmentRealismDropout(std::vector<std::size_t>* keep, const RealismAugment& c,
                           std::mt19937_64* rng) {
  if (!(c.point_dropout > 0) || keep->size() < 2) return;
  const double fraction = c.point_dropout * Uniform01(rng);
  std::vector<std::size_t> kept;
  kept.reserve(keep->size());
  for (std::size_t i : *keep) {
    if (Uniform01(rng) >= fraction) kept.push_back(i);
  }
  if (kept.empty()) kept.push_back((*keep)[0]);
  *keep = std::move(kept);
}

void Stage1InputConfig::Validate() const {
  if (!(scale > 0 && scale <= 1000)) {
    throw InvalidArgument("Stage1InputConfig.scale must be in (0, 1000] voxels per metre");
  }
}

// ---------------------------------------------------------------- augmentation
// Convention (column vectors): p' = m p with m = Rz(theta) * F * (I + jitter * N), F = diag(-1,
// 1, 1) when flipped, else I. A heading h is the direction (cos h, sin h, 0) of the object's
// front; the new heading is the direction of m (cos h, sin h, 0) in x-y, so the box still faces
// the same physical front: with jitter = 0 that is exactly h + theta (no flip) or pi - h + theta
// (flip), wrapped to [-pi, pi). Random draws, in this order: 9 normals, 1 uniform (flip), 1
// uniform (theta); all are drawn even when a part is disabled so the stream stays aligned.
void AugmentAffine(Stage1Sample* sample, const AugmentConfig& config, std::mt19937_64* rng,
                   Eigen::Matrix3f* affine) {
  config.Validate();
  Eigen::Matrix3d jit = Eigen::Matrix3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) jit(r, c) += config.jitter * Normal(rng);
  }
  const bool flip = Uniform01(rng) < 0.5 && config.flip;
  const double theta = Uniform01(rng) * kTwoPi;
  Eigen::Matrix3d m = jit;
  if (flip) m.row(0) *= -1.0;
  if (config.rotate) {
    Eigen::Matrix3d rz;
    rz << std::cos(theta), -std::sin(theta), 0, std::sin(theta), std::cos(theta), 0, 0, 0, 1;
    m = rz * m;
  }
  const Eigen::Matrix3f mf = m.cast<float>();
  for (auto& p : sample->points) p = mf * p;
  for (auto& in : sample->instances) {
    if (!in.has_heading) continue;
    const Eigen::Vector3d f = m * Eigen::Vector3d(std::cos(in.heading), std::sin(in.heading), 0);
    if (f.head<2>().norm() < 1e-9) {  // degenerate jitter: fall back to the rigid formula
      in.heading = WrapPi((flip ? kPi - in.heading : in.heading) + (config.rotate ? theta : 0));
    } else {
      in.heading = WrapPi(std::atan2(f.y(), f.x()));
    }
  }
  if (affine) *affine = mf;
}

void ElasticDistortion(std::vector<Eigen::Vector3f>* coords, double gran, double mag,
                       std::mt19937_64* rng) {
  if (!(gran > 0) || !std::isfinite(gran) || !std::isfinite(mag)) {
    throw InvalidArgument("ElasticDistortion: gran must be > 0 and mag finite");
  }
  if (coords->empty()) return;
  Eigen::Vector3f amax = Eigen::Vector3f::Zero();
  for (std::size_t i = 0; i < coords->size(); ++i) {
    if (!Finite((*coords)[i])) {
      throw InvalidArgument("ElasticDistortion: coordinate " + std::to_string(i) +
                            " is not finite");
    }
    amax = amax.cwiseMax((*coords)[i].cwiseAbs());
  }
  int dims[3];
  double cells = 1;
  for (int k = 0; k < 3; ++k) {
    const double b = std::floor(amax[k] / gran) + 3;
    cells *= b;
    if (b > 1e6 || cells > 6.4e7) {
      throw InvalidArgument("ElasticDistortion: noise grid too large (coordinates up to " +
                            std::to_string(amax.maxCoeff()) + " with gran " + std::to_string(gran) +
                            "); centre the coordinates first");
    }
    dims[k] = static_cast<int>(b);
  }
  const std::size_t total = static_cast<std::size_t>(dims[0]) * dims[1] * dims[2];
  std::vector<float> noise[3];
  for (auto& g : noise) {
    g.resize(total);
    for (auto& v : g) v = static_cast<float>(Normal(rng));
    for (int pass = 0; pass < 2; ++pass) {
      for (int axis = 0; axis < 3; ++axis) Blur(&g, dims, axis);
    }
  }
  // Grid node j of axis k sits at -(b-1) gran + 2 gran j (SparseConvNet's linspace); trilinear
  // interpolation, zero outside.
  const std::ptrdiff_t stride[3] = {static_cast<std::ptrdiff_t>(dims[1]) * dims[2], dims[2], 1};
  for (auto& p : *coords) {
    int i0[3];
    double t[3];
    for (int k = 0; k < 3; ++k) {
      const double u = (p[k] + (dims[k] - 1) * gran) / (2 * gran);
      const double fl = std::floor(u);
      i0[k] = static_cast<int>(fl);
      t[k] = u - fl;
    }
    double d[3] = {0, 0, 0};
    for (int corner = 0; corner < 8; ++corner) {
      double w = 1;
      std::ptrdiff_t idx = 0;
      bool inside = true;
      for (int k = 0; k < 3; ++k) {
        const int bit = (corner >> k) & 1;
        const int j = i0[k] + bit;
        if (j < 0 || j >= dims[k]) inside = false;
        w *= bit ? t[k] : 1 - t[k];
        idx += j * stride[k];
      }
      if (!inside || w == 0) continue;
      for (int c = 0; c < 3; ++c) d[c] += w * noise[c][idx];
    }
    for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(p[c] + d[c] * mag);
  }
}

// ---------------------------------------------------------------- batches
namespace {

// The reference's crop (section 1.3) in voxel units of `scale`: a cube of 512 * scale / 50
// voxels whose x-y extent shrinks by 32 * scale / 50 until at most max_points remain. Returns the
// kept point indices (ascending). `q` are scaled coordinates with min 0.
std::vector<std::size_t> CropIndices(const std::vector<Eigen::Vector3f>& q, double scale,
                                     int max_points, std::mt19937_64* rng) {
  std::vector<std::size_t> keep(q.size());
  for (std::size_t i = 0; i < q.size(); ++i) keep[i] = i;
  if (static_cast<int>(q.size()) <= max_points) return keep;
  Eigen::Vector3d lo = q[0].cast<double>(), hi = lo;
  for (const auto& p : q) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  const Eigen::Vector3d range = hi - lo;
  Eigen::Vector3d full = Eigen::Vector3d::Constant(512.0 * scale / 50.0);
  const double shrink = 32.0 * scale / 50.0;
  while (static_cast<int>(keep.size()) > max_points) {
    Eigen::Vector3d offset;
    for (int k = 0; k < 3; ++k) {
      offset[k] = std::min(full[k] - range[k] + 0.001, 0.0) * Uniform01(rng) - lo[k];
    }
    keep.clear();
    for (std::size_t i = 0; i < q.size(); ++i) {
      const Eigen::Vector3d o = q[i].cast<double>() + offset;
      if (o.minCoeff() >= 0 && o.x() < full.x() && o.y() < full.y() && o.z() < full.z()) {
        keep.push_back(i);
      }
    }
    full.x() -= shrink;
    full.y() -= shrink;
  }
  return keep;
}

}  // namespace

Stage1Batch MakeStage1Batch(const std::vector<const Stage1Sample*>& samples,
                            const Stage1InputConfig& input, const AugmentConfig* augment,
                            std::uint64_t seed) {
  input.Validate();
  const bool aug = augment != nullptr && augment->enabled;
  if (aug) augment->Validate();
  Stage1Batch batch;
  batch.batch_size = static_cast<int>(samples.size());
  batch.feature_channels = input.feature_channels();
  batch.point_offsets.push_back(0);
  const int C = batch.feature_channels;
  std::int64_t next_instance = 0;
  // Up front: a scene may take instances from the next one (instance mixing).
  bool weighted = false;
  for (int b = 0; b < batch.batch_size; ++b) {
    if (samples[b] == nullptr)
      throw InvalidArgument("MakeStage1Batch: sample " + std::to_string(b) + " is null");
    weighted = weighted || !samples[b]->weight.empty();
  }
  for (int b = 0; b < batch.batch_size; ++b) {
    const Stage1Sample* src = samples[b];
    src->Validate();
    if (src->points.empty()) {
      throw InvalidArgument("MakeStage1Batch: " + SampleLabel(*src) + " has no points");
    }
    if (input.use_rgb && src->colors.empty()) {
      throw InvalidArgument("MakeStage1Batch: use_rgb but " + SampleLabel(*src) +
                            " has no colours");
    }
    // Cuboid mixing, then instance mixing, each with the batch's next scene and on its own
    // stream (without them the batches are bit for bit as before). Both keep the scene's name.
    const auto mix_with_next = [&](double probability, std::uint64_t stream, Stage1Sample* holder,
                                   const auto& mix) {
      if (probability <= 0 || batch.batch_size < 2) return;
      std::mt19937_64 mix_rng(HashSeed(seed, static_cast<std::uint64_t>(b), stream));
      if (Uniform01(&mix_rng) < probability) {
        *holder = mix(*src, *samples[(b + 1) % batch.batch_size], &mix_rng);
        src = holder;
      }
    };
    Stage1Sample cuboids, mixed;
    if (aug) {
      const RealismAugment& r = augment->realism;
      mix_with_next(r.cuboid_mix, 0xc0b1ull, &cuboids,
                    [](const Stage1Sample& dst, const Stage1Sample& other, std::mt19937_64* g) {
                      return MixCuboids(dst, other, g);
                    });
      mix_with_next(r.instance_mix, 0x3171ull, &mixed,
                    [&r](const Stage1Sample& dst, const Stage1Sample& other, std::mt19937_64* g) {
                      return MixInstances(dst, other, r.instance_mix_count, g);
                    });
    }
    const NetworkFrame frame = EstimateNetworkFrame(src->points);
    batch.frames.push_back(frame);
    batch.names.push_back(src->name);

    Stage1Sample s;  // network frame, augmented: only what changes
    s.points.resize(src->points.size());
    for (std::size_t i = 0; i < s.points.size(); ++i) s.points[i] = src->points[i] - frame.origin;
    s.instances = src->instances;
    std::mt19937_64 rng(HashSeed(seed, static_cast<std::uint64_t>(b)));
    if (aug) AugmentAffine(&s, *augment, &rng);
    // Realism augmentation on its own stream (the default stream above stays as it was).
    const bool real = aug && augment->realism.any();
    std::mt19937_64 real_rng(HashSeed(seed, static_cast<std::uint64_t>(b), 0x7ea1ull));
    if (real) AugmentRealismPoints(&s.points, augment->realism, &real_rng);
    std::vector<Eigen::Vector3f> aug_colors;
    if (real && input.use_rgb && augment->realism.any_color())
      aug_colors = AugmentRealismColors(src->colors, augment->realism, &real_rng);
    const std::vector<Eigen::Vector3f>& colors = aug_colors.empty() ? src->colors : aug_colors;

    std::vector<Eigen::Vector3f> q(s.points.size());
    for (std::size_t i = 0; i < q.size(); ++i) q[i] = s.points[i] * static_cast<float>(input.scale);
    if (aug && augment->elastic) {
      const double f = input.scale / 50.0;
      ElasticDistortion(&q, augment->elastic_gran0 * f, augment->elastic_mag0 * f, &rng);
      ElasticDistortion(&q, augment->elastic_gran1 * f, augment->elastic_mag1 * f, &rng);
    }
    std::vector<std::size_t> keep;
    if (aug) {
      keep = CropIndices(q, input.scale, augment->max_points, &rng);
      if (real) AugmentRealismDropout(&keep, augment->realism, &real_rng);
    } else {
      keep.resize(q.size());
      for (std::size_t i = 0; i < q.size(); ++i) keep[i] = i;
    }
    if (keep.empty()) {
      throw InvalidArgument("MakeStage1Batch: crop of " + SampleLabel(*src) + " kept no points");
    }
    Eigen::Vector3f qmin = q[keep[0]];
    for (std::size_t i : keep) qmin = qmin.cwiseMin(q[i]);

    // Instances that survive, compacted in index order, and their AABBs (metric, augmented).
    const int num_inst = static_cast<int>(s.instances.size());
    std::vector<int> compact(num_inst, -1);
    std::vector<Eigen::Vector3f> ilo(num_inst, Eigen::Vector3f::Constant(INFINITY));
    std::vector<Eigen::Vector3f> ihi(num_inst, Eigen::Vector3f::Constant(-INFINITY));
    for (std::size_t i : keep) {
      const int k = src->instance[i];
      if (k < 0) continue;
      compact[k] = 0;
      ilo[k] = ilo[k].cwiseMin(s.points[i]);
      ihi[k] = ihi[k].cwiseMax(s.points[i]);
    }
    int kept_instances = 0;
    for (int k = 0; k < num_inst; ++k) {
      if (compact[k] == 0) compact[k] = kept_instances++;
    }
    std::vector<HeadingCode> codes(num_inst);
    for (int k = 0; k < num_inst; ++k) {
      if (s.instances[k].has_heading) codes[k] = EncodeHeading(s.instances[k].heading);
    }

    const std::size_t base = batch.semantic.size();
    const std::size_t m = keep.size();
    batch.points.resize((base + m) * 3);
    batch.features.resize((base + m) * C);
    batch.voxel.resize((base + m) * 4);
    batch.semantic.resize(base + m);
    batch.instance.resize(base + m);
    batch.offset_target.resize((base + m) * 3, 0.0f);
    batch.offset_valid.resize(base + m, 0);
    batch.heading_bin.resize(base + m);
    batch.heading_residual.resize(base + m, 0.0f);
    if (weighted) batch.semantic_weight.resize(base + m, 1.0f);
    for (std::size_t j = 0; j < m; ++j) {
      const std::size_t i = keep[j];
      const std::size_t o = base + j;
      const Eigen::Vector3f& p = s.points[i];
      for (int c = 0; c < 3; ++c) {
        batch.points[3 * o + c] = p[c];
        batch.features[C * o + c] = p[c];
        const double v = std::floor(static_cast<double>(q[i][c]) - qmin[c]);
        if (!(v >= 0 && v < 1 << 30)) {
          throw InvalidArgument("MakeStage1Batch: " + SampleLabel(*src) +
                                " spans too many voxels at scale " + std::to_string(input.scale));
        }
        batch.voxel[4 * o + 1 + c] = static_cast<std::int32_t>(v);
      }
      batch.voxel[4 * o] = b;
      if (input.use_rgb) {
        for (int c = 0; c < 3; ++c) batch.features[C * o + 3 + c] = colors[i][c] - 0.5f;
      }
      batch.semantic[o] = src->semantic[i];
      if (weighted && !src->weight.empty()) batch.semantic_weight[o] = src->weight[i];
      const int k = src->instance[i];
      batch.heading_bin[o] = kStage1Ignore;
      if (k < 0) {
        batch.instance[o] = -1;
        continue;
      }
      batch.instance[o] = next_instance + compact[k];
      const Eigen::Vector3f centre = 0.5f * (ilo[k] + ihi[k]);
      for (int c = 0; c < 3; ++c) batch.offset_target[3 * o + c] = centre[c] - p[c];
      batch.offset_valid[o] = 1;
      if (s.instances[k].has_heading) {
        batch.heading_bin[o] = codes[k].bin;
        batch.heading_residual[o] = static_cast<float>(codes[k].residual);
      }
    }
    next_instance += kept_instances;
    batch.point_offsets.push_back(static_cast<std::int64_t>(base + m));
  }
  return batch;
}

// ---------------------------------------------------------------- inference input
NetworkFrame WriteStage1NetworkInput(const ScenePoints& scene, const Stage1InputConfig& input,
                                     std::array<std::int64_t, 3>* extent, float* features,
                                     std::int32_t* voxel) {
  input.Validate();
  const std::string who = "stage1 input: scene '" + scene.name + "'";
  if (scene.size == 0 || scene.points == nullptr) throw InvalidArgument(who + " has no points");
  if (input.use_rgb && scene.colors == nullptr) {
    throw InvalidArgument(who + ": the model uses colour but the scene has none");
  }
  const std::size_t n = scene.size;
  const Eigen::Vector3f* pts = scene.points;
  // One checking pass that also gives the bounding box (the frame's x-y centre and the lowest
  // z for the floor search).
  Eigen::Vector3f lo, hi;
  CheckedBounds(pts, input.use_rgb ? scene.colors : nullptr, n, who, &lo, &hi);
  const NetworkFrame frame = FrameInBounds(pts, n, lo, hi);
  // The same float arithmetic as MakeStage1Batch: p - origin, then times the scale. Float
  // subtraction and multiplication by a positive scale are monotone, so the smallest / largest
  // (p - origin) * scale over the points are those of the box corners lo / hi: the voxel
  // minimum is known before the writing pass (one pass over the points, not two).
  const float scale = static_cast<float>(input.scale);
  const Eigen::Vector3f qmin = (lo - frame.origin) * scale;
  const Eigen::Vector3f qmax = (hi - frame.origin) * scale;
  for (int c = 0; c < 3; ++c) {
    const double span = std::floor(static_cast<double>(qmax[c]) - qmin[c]) + 1;
    if (!(span <= 65536)) {
      char buf[160];
      std::snprintf(buf, sizeof(buf),
                    " spans %.1f m along %c = %.0f voxels at scale %g (at most 65536): points "
                    "must be in metres (is the cloud in millimetres?)",
                    (qmax[c] - qmin[c]) / scale, "xyz"[c], span, input.scale);
      throw InvalidArgument(who + buf);
    }
    (*extent)[c] = static_cast<std::int64_t>(span);
  }
  // Per point: p - origin, and the voxel floor(q - qmin) of q = p * scale as the truncation of
  // a difference >= 0 (no libm call); 16 points per step on AVX-512 (the same bits).
  stage1_heads::WriteNetworkInput(pts, input.use_rgb ? scene.colors : nullptr, n,
                                  frame.origin.data(), scale, qmin.data(), features, voxel,
                                  stage1_heads::HeadsIsaOfSparsePath());
  return frame;
}

Stage1NetworkInput MakeStage1NetworkInput(const ScenePoints& scene,
                                          const Stage1InputConfig& input) {
  input.Validate();
  Stage1NetworkInput r;
  r.feature_channels = input.feature_channels();
  r.features.resize(scene.size * r.feature_channels);
  r.voxel.resize(scene.size * 4);
  r.frame = WriteStage1NetworkInput(scene, input, &r.extent, r.features.data(), r.voxel.data());
  return r;
}

// ---------------------------------------------------------------- loader
struct Stage1Loader::State {
  const std::vector<Stage1Sample>* samples = nullptr;
  Stage1InputConfig input;
  AugmentConfig augment;
  int batch_size = 1;
  std::uint64_t seed = 0;
  int prefetch = 4;
  bool drop_last = true;

  std::mutex mu;
  std::condition_variable cv;
  bool stop = false;
  bool started = false;
  std::uint64_t generation = 0;  // bumped by StartEpoch: results of older epochs are dropped
  int epoch = 0;
  std::shared_ptr<const std::vector<int>> order;  // permutation of the current epoch
  int next_claim = 0;                             // next batch index a worker builds
  int next_deliver = 0;                           // next batch index Next() returns
  int end = 0;                                    // batches in the epoch
  struct Result {
    Stage1Batch batch;
    std::exception_ptr error;
  };
  std::map<int, Result> done;
  std::vector<std::thread> workers;

  int BatchesPerEpoch() const {
    const int n = static_cast<int>(samples->size());
    return drop_last ? n / batch_size : (n + batch_size - 1) / batch_size;
  }

  void Work() {
    std::unique_lock<std::mutex> lock(mu);
    for (;;) {
      cv.wait(lock, [&] {
        return stop || (started && next_claim < end && next_claim < next_deliver + prefetch);
      });
      if (stop) return;
      const int k = next_claim++;
      const std::uint64_t gen = generation;
      const int e = epoch;
      const auto perm = order;
      lock.unlock();
      Result result;
      try {
        const int n = static_cast<int>(perm->size());
        std::vector<const Stage1Sample*> ptrs;
        for (int i = k * batch_size; i < std::min(n, (k + 1) * batch_size); ++i) {
          ptrs.push_back(&(*samples)[(*perm)[i]]);
        }
        result.batch = MakeStage1Batch(
            ptrs, input, &augment,
            HashSeed(seed, static_cast<std::uint64_t>(e) + 1, static_cast<std::uint64_t>(k)));
      } catch (...) {
        result.error = std::current_exception();
      }
      lock.lock();
      if (gen == generation && !stop) {
        done[k] = std::move(result);
        cv.notify_all();
      }
    }
  }
};

Stage1Loader::Stage1Loader(const std::vector<Stage1Sample>* samples, Stage1InputConfig input,
                           AugmentConfig augment, int batch_size, std::uint64_t seed, int threads,
                           int prefetch, bool drop_last)
    : state_(std::make_unique<State>()) {
  if (samples == nullptr) throw InvalidArgument("Stage1Loader: samples is null");
  if (batch_size < 1) throw InvalidArgument("Stage1Loader: batch_size must be >= 1");
  if (threads < 1 || threads > 256) throw InvalidArgument("Stage1Loader: threads must be 1..256");
  if (prefetch < 1) throw InvalidArgument("Stage1Loader: prefetch must be >= 1");
  input.Validate();
  if (augment.enabled) augment.Validate();
  State& s = *state_;
  s.samples = samples;
  s.input = input;
  s.augment = augment;
  s.batch_size = batch_size;
  s.seed = seed;
  s.prefetch = prefetch;
  s.drop_last = drop_last;
  for (int t = 0; t < threads; ++t) s.workers.emplace_back([this] { state_->Work(); });
}

Stage1Loader::~Stage1Loader() {
  {
    std::lock_guard<std::mutex> lock(state_->mu);
    state_->stop = true;
  }
  state_->cv.notify_all();
  for (auto& t : state_->workers) t.join();
}

int Stage1Loader::batches_per_epoch() const { return state_->BatchesPerEpoch(); }

void Stage1Loader::StartEpoch(int epoch, int first_batch) {
  State& s = *state_;
  if (epoch < 0) throw InvalidArgument("Stage1Loader::StartEpoch: epoch must be >= 0");
  const int total = s.BatchesPerEpoch();
  if (first_batch < 0 || first_batch > total) {
    throw InvalidArgument("Stage1Loader::StartEpoch: first_batch " + std::to_string(first_batch) +
                          " outside [0, " + std::to_string(total) + "]");
  }
  auto perm = std::make_shared<std::vector<int>>(s.samples->size());
  for (std::size_t i = 0; i < perm->size(); ++i) (*perm)[i] = static_cast<int>(i);
  std::mt19937_64 rng(HashSeed(s.seed, static_cast<std::uint64_t>(epoch) + 1, 0x5eedull));
  for (std::size_t i = perm->size(); i > 1; --i) {
    std::swap((*perm)[i - 1], (*perm)[rng() % i]);
  }
  {
    std::lock_guard<std::mutex> lock(s.mu);
    ++s.generation;
    s.started = true;
    s.epoch = epoch;
    s.order = std::move(perm);
    s.next_claim = first_batch;
    s.next_deliver = first_batch;
    s.end = total;
    s.done.clear();
  }
  s.cv.notify_all();
}

bool Stage1Loader::Next(Stage1Batch* batch) {
  State& s = *state_;
  std::unique_lock<std::mutex> lock(s.mu);
  if (!s.started) throw InvalidArgument("Stage1Loader::Next: call StartEpoch first");
  if (s.next_deliver >= s.end) return false;
  const int k = s.next_deliver;
  s.cv.wait(lock, [&] { return s.done.count(k) > 0; });
  State::Result result = std::move(s.done[k]);
  s.done.erase(k);
  ++s.next_deliver;
  lock.unlock();
  s.cv.notify_all();
  if (result.error) std::rethrow_exception(result.error);
  *batch = std::move(result.batch);
  return true;
}

}  // namespace dimr::nn
