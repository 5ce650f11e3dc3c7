// `dimr bench sparse`: procedural scanned room, SubM3 layers (fused vs torch-ops) and the
// stage-1 U-Net, with timings, GFLOP/s and peak memory.
#include "dimr/nn/sparse_bench.h"

#include <ATen/Parallel.h>
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <tuple>
#include <unordered_set>
#include <utility>

#include "dimr/geometry/error.h"
#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_unet.h"

namespace dimr::nn {
namespace {

using Vec3 = std::array<double, 3>;
constexpr double kPi = 3.14159265358979323846;

Vec3 Add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 Scale(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }

class RoomSampler {
 public:
  RoomSampler(uint64_t seed, RoomCloud* out) : rng_(seed), out_(out) {}

  // Rectangle origin + s*a + t*b, s, t in [0, 1], sampled on a 2 cm grid with in-plane
  // jitter and normal noise (a depth scanner's ~3 mm).
  void Rect(const Vec3& o, const Vec3& a, const Vec3& b) {
    const double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    const double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    const int na = std::max(1, static_cast<int>(std::round(la / kStep)));
    const int nb = std::max(1, static_cast<int>(std::round(lb / kStep)));
    Vec3 n{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    const double ln = std::max(1e-12, std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]));
    n = Scale(n, 1.0 / ln);
    std::uniform_real_distribution<double> jit(-0.4, 0.4);
    std::normal_distribution<double> noise(0.0, 0.003);
    for (int i = 0; i < na; ++i) {
      for (int j = 0; j < nb; ++j) {
        const double s = std::clamp((i + 0.5 + jit(rng_)) / na, 0.0, 1.0);
        const double t = std::clamp((j + 0.5 + jit(rng_)) / nb, 0.0, 1.0);
        Vec3 p = Add(Add(o, Scale(a, s)), Scale(b, t));
        p = Add(p, Scale(n, noise(rng_)));
        out_->points.push_back(
            {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])});
      }
    }
  }

  // Yawed box (centre cx, cy; base z0; size w x d x h): top and four sides (no bottom).
  void Box(double cx, double cy, double z0, double w, double d, double h, double yaw,
           bool top = true, bool sides = true) {
    const Vec3 ex{std::cos(yaw) * w, std::sin(yaw) * w, 0};
    const Vec3 ey{-std::sin(yaw) * d, std::cos(yaw) * d, 0};
    const Vec3 ez{0, 0, h};
    const Vec3 c0 = Add(Add(Vec3{cx, cy, z0}, Scale(ex, -0.5)), Scale(ey, -0.5));
    if (top) Rect(Add(c0, ez), ex, ey);
    if (sides) {
      Rect(c0, ex, ez);
      Rect(Add(c0, ey), ex, ez);
      Rect(c0, ey, ez);
      Rect(Add(c0, ex), ey, ez);
    }
  }

  void Table(double cx, double cy, double w, double d, double h, double yaw) {
    Box(cx, cy, h - 0.04, w, d, 0.04, yaw);  // top slab
    const double lx = w / 2 - 0.05, ly = d / 2 - 0.05;
    for (int sx : {-1, 1}) {
      for (int sy : {-1, 1}) {
        const double px = cx + std::cos(yaw) * sx * lx - std::sin(yaw) * sy * ly;
        const double py = cy + std::sin(yaw) * sx * lx + std::cos(yaw) * sy * ly;
        Box(px, py, 0.0, 0.05, 0.05, h - 0.04, yaw, false, true);
      }
    }
  }

  void Chair(double cx, double cy, double yaw) {
    Table(cx, cy, 0.45, 0.45, 0.46, yaw);  // seat on four legs
    const double bx = cx - std::sin(yaw) * 0.21, by = cy + std::cos(yaw) * 0.21;
    Box(bx, by, 0.46, 0.45, 0.04, 0.45, yaw);  // backrest
  }

  std::mt19937_64& rng() { return rng_; }

 private:
  static constexpr double kStep = 0.02;
  std::mt19937_64 rng_;
  RoomCloud* out_;
};

RoomCloud MakeRoom(double w, double d, uint64_t seed) {
  RoomCloud room;
  const double h = 2.4;
  room.size = {static_cast<float>(w), static_cast<float>(d), static_cast<float>(h)};
  RoomSampler s(seed, &room);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto& rng = s.rng();
  s.Rect({0, 0, 0}, {w, 0, 0}, {0, d, 0});  // floor
  // Walls; the y = 0 wall has a 0.9 m x 2.0 m door gap.
  const double door = 0.3 * w;
  s.Rect({0, 0, 0}, {door, 0, 0}, {0, 0, h});
  s.Rect({door + 0.9, 0, 0}, {w - door - 0.9, 0, 0}, {0, 0, h});
  s.Rect({door, 0, 2.0}, {0.9, 0, 0}, {0, 0, h - 2.0});
  s.Rect({0, d, 0}, {w, 0, 0}, {0, 0, h});
  s.Rect({0, 0, 0}, {0, d, 0}, {0, 0, h});
  s.Rect({w, 0, 0}, {0, d, 0}, {0, 0, h});
  // Dining table with four chairs.
  const double tx = 0.55 * w + 0.1 * u(rng), ty = 0.5 * d + 0.1 * u(rng);
  const double tyaw = 0.3 * u(rng);
  s.Table(tx, ty, 1.4, 0.8, 0.75, tyaw);
  for (int k = 0; k < 4; ++k) {
    const double side = k < 2 ? -1.0 : 1.0, along = (k % 2 == 0 ? -0.35 : 0.35);
    const double lx = along, ly = side * 0.6;
    const double cx = tx + std::cos(tyaw) * lx - std::sin(tyaw) * ly;
    const double cy = ty + std::sin(tyaw) * lx + std::cos(tyaw) * ly;
    s.Chair(cx, cy, tyaw + (side > 0 ? kPi : 0.0) + 0.15 * u(rng));
  }
  // Cabinets / shelf against the walls, a box and a desk in a corner.
  s.Box(0.25, 0.3 * d, 0.0, 0.45, 1.0, 0.9, kPi / 2);
  s.Box(0.8 * w, d - 0.22, 0.0, 0.9, 0.4, 1.8, 0.0);
  s.Box(0.15 * w + 0.3, d - 0.6, 0.0, 0.5, 0.4, 0.45, 0.6 * u(rng));
  s.Table(w - 0.45, 0.6, 0.7, 1.2, 0.72, 0.0);
  s.Chair(w - 1.0, 0.6, -kPi / 2 + 0.2 * u(rng));
  return room;
}

std::vector<std::array<int64_t, 3>> VoxelKeys(const RoomCloud& room, double voxel) {
  std::array<double, 3> mn{1e30, 1e30, 1e30};
  for (const auto& p : room.points) {
    for (int a = 0; a < 3; ++a) mn[a] = std::min(mn[a], static_cast<double>(p[a]));
  }
  std::vector<std::array<int64_t, 3>> keys;
  keys.reserve(room.points.size());
  for (const auto& p : room.points) {
    keys.push_back({static_cast<int64_t>(std::floor((p[0] - mn[0]) / voxel)),
                    static_cast<int64_t>(std::floor((p[1] - mn[1]) / voxel)),
                    static_cast<int64_t>(std::floor((p[2] - mn[2]) / voxel))});
  }
  return keys;
}

uint64_t PackKey(int64_t x, int64_t y, int64_t z) {
  return (static_cast<uint64_t>(x + 1) << 42) | (static_cast<uint64_t>(y + 1) << 21) |
         static_cast<uint64_t>(z + 1);
}

double PeakRssMb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;
}

using Clock = std::chrono::steady_clock;

double CpuMs() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
double Ms(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Useful GEMM FLOPs of one SparseUNet forward, from the context's rulebooks.
double UNetForwardFlops(const SparseUNetConfig& cfg, SparseContext& ctx) {
  double flops = 0;
  const auto& w = cfg.widths;
  const int64_t levels = static_cast<int64_t>(w.size());
  const double subm0 = static_cast<double>(ctx.Subm3(1).num_pairs());
  flops += 2.0 * subm0 * cfg.in_channels * w[0];
  int64_t stride = 1;
  for (int64_t l = 0; l < levels; ++l, stride *= 2) {
    const double c = static_cast<double>(w[l]);
    const double p = static_cast<double>(ctx.Subm3(stride).num_pairs());
    const double n = static_cast<double>(ctx.level(stride).coords.size(0));
    flops += 2.0 * p * c * c * 2 * cfg.reps;  // down-path residual blocks
    if (l + 1 < levels) {
      const double c1 = static_cast<double>(w[l + 1]);
      const double d = static_cast<double>(ctx.Down(stride).num_pairs());
      flops += 2.0 * 2.0 * d * c * c1;                // down + inverse conv
      flops += 2.0 * p * (2 * c * c + c * c);         // tail block0: 2c -> c, c -> c
      flops += 2.0 * n * 2 * c * c;                   // tail block0 1x1 identity
      flops += 2.0 * p * c * c * 2 * (cfg.reps - 1);  // remaining tail blocks
    }
  }
  return flops;
}

// "AMD EPYC (family 25, model 17)" from /proc/cpuinfo ("unknown CPU" elsewhere).
std::string CpuModel() {
  std::ifstream f("/proc/cpuinfo");
  std::string line, name, family, model;
  auto value = [](const std::string& l) {
    const size_t c = l.find(':');
    if (c == std::string::npos) return std::string();
    size_t b = l.find_first_not_of(" \t", c + 1);
    return b == std::string::npos ? std::string() : l.substr(b);
  };
  while (std::getline(f, line)) {
    if (name.empty() && line.rfind("model name", 0) == 0) name = value(line);
    if (family.empty() && line.rfind("cpu family", 0) == 0) family = value(line);
    if (model.empty() && line.rfind("model", 0) == 0 && line.rfind("model name", 0) != 0) {
      model = value(line);
    }
    if (!name.empty() && !family.empty() && !model.empty()) break;
  }
  if (name.empty()) return "unknown CPU";
  if (!family.empty()) name += " (family " + family + ", model " + model + ")";
  return name;
}

std::string CpuIsa() {
  std::string isa;
  if (__builtin_cpu_supports("avx512f")) isa += "avx512f ";
  if (__builtin_cpu_supports("avx2")) isa += "avx2 ";
  if (__builtin_cpu_supports("fma")) isa += "fma ";
  if (isa.empty()) return "sse2";
  isa.pop_back();
  return isa;
}

// One-thread sgemm, 2048^3, median of 3 after a warm-up (the reference for the fused rows):
// {GFLOP/s over wall time, over process CPU time}.
std::pair<double, double> OneThreadSgemmGflops() {
  const int saved = at::get_num_threads();
  at::set_num_threads(1);
  const int64_t n = 2048;
  at::Tensor a = at::randn({n, n}), b = at::randn({n, n}), c = at::empty({n, n});
  std::vector<double> ms, cpu;
  for (int r = 0; r < 4; ++r) {
    const double c0 = CpuMs();
    auto t0 = Clock::now();
    at::mm_out(c, a, b);
    if (r > 0) {
      ms.push_back(Ms(t0, Clock::now()));
      cpu.push_back(CpuMs() - c0);
    }
  }
  at::set_num_threads(saved);
  const double flops = 2.0 * n * n * n;
  return {flops / (Median(ms) * 1e6), flops / (Median(cpu) * 1e6)};
}

// The kernel paths named by the options, deduplicated, in order.
std::vector<SparseKernelPath> KernelPaths(const std::vector<std::string>& names) {
  std::vector<SparseKernelPath> out;
  auto add = [&](SparseKernelPath p) {
    if (!SparseKernelPathSupported(p)) {
      throw InvalidArgument(std::string("bench sparse: this CPU cannot run the ") +
                            SparseKernelPathName(p) + " kernels");
    }
    if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
  };
  for (const std::string& n : names) {
    if (n == "all") {
      for (SparseKernelPath p : SupportedSparseKernelPaths()) add(p);
    } else if (n == "auto") {
      add(ResolveSparseKernelPath());
    } else {
      add(ParseSparseKernelPath(n));
    }
  }
  if (out.empty()) out.push_back(ResolveSparseKernelPath());
  return out;
}

// Restores the process-wide backend and kernel path.
class BackendRestore {
 public:
  BackendRestore() : backend_(GetSparseBackend()), path_(GetSparseKernelPath()) {}
  ~BackendRestore() {
    SetSparseBackend(backend_);
    SetSparseKernelPath(path_);
  }

 private:
  SparseBackend backend_;
  SparseKernelPath path_;
};

}  // namespace

RoomCloud GenerateRoomCloud(int64_t target_voxels, uint64_t seed) {
  if (target_voxels < 1000) {
    throw InvalidArgument("room generator: target_voxels must be >= 1000, got " +
                          std::to_string(target_voxels));
  }
  // Floor + walls dominate: solve 2500 * (L^2 + 9.6 L) ~ target for a square room first.
  double l = (-9.6 + std::sqrt(9.6 * 9.6 + 4.0 * target_voxels / 2500.0)) / 2.0;
  l = std::max(l, 1.6);
  double w = 1.2 * l, d = l / 1.2;
  RoomCloud room;
  for (int it = 0; it < 4; ++it) {
    room = MakeRoom(w, d, seed);
    const double count = static_cast<double>(RoomVoxelCount(room, 0.02));
    const double ratio = target_voxels / count;
    if (std::abs(ratio - 1.0) < 0.01) break;
    // Area scales ~ s^2 (floor, furniture) and ~ s (walls): use the geometric middle.
    const double s = std::pow(ratio, 0.7);
    w = std::max(1.8, w * s);
    d = std::max(1.6, d * s);
  }
  return room;
}

int64_t RoomVoxelCount(const RoomCloud& room, double voxel) {
  std::unordered_set<uint64_t> set;
  for (const auto& k : VoxelKeys(room, voxel)) set.insert(PackKey(k[0], k[1], k[2]));
  return static_cast<int64_t>(set.size());
}

double RoomMeanNeighbours(const RoomCloud& room, double voxel) {
  std::unordered_set<uint64_t> set;
  for (const auto& k : VoxelKeys(room, voxel)) set.insert(PackKey(k[0], k[1], k[2]));
  std::unordered_set<uint64_t> done;
  double total = 0;
  for (const auto& k : VoxelKeys(room, voxel)) {
    if (!done.insert(PackKey(k[0], k[1], k[2])).second) continue;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          if ((dx || dy || dz) && set.count(PackKey(k[0] + dx, k[1] + dy, k[2] + dz))) ++total;
        }
      }
    }
  }
  return set.empty() ? 0.0 : total / static_cast<double>(set.size());
}

SparseBenchReport RunSparseBench(const SparseBenchOptions& opt) {
  if (opt.repeats < 1) throw InvalidArgument("bench sparse: repeats must be >= 1");
  if (opt.threads < 0) throw InvalidArgument("bench sparse: threads must be >= 0");
  for (int64_t w : opt.widths) {
    if (w < 1 || w > 1024) {
      throw InvalidArgument("bench sparse: width " + std::to_string(w) + " outside [1, 1024]");
    }
  }
  const std::vector<SparseKernelPath> paths = KernelPaths(opt.kernels);
  if (opt.threads > 0) at::set_num_threads(opt.threads);
  BackendRestore restore;
  SparseBenchReport rep;
  rep.cpu_model = CpuModel();
  rep.cpu_isa = CpuIsa();
  rep.default_kernels = SparseKernelPathName(ResolveSparseKernelPath());
  if (opt.sgemm) std::tie(rep.sgemm_gflops, rep.sgemm_cpu_gflops) = OneThreadSgemmGflops();
  rep.threads = at::get_num_threads();
  rep.parallel_info = at::get_parallel_info();
  at::manual_seed(static_cast<uint64_t>(opt.seed));

  RoomCloud room = GenerateRoomCloud(opt.sites, opt.seed);
  const int64_t np = static_cast<int64_t>(room.points.size());
  rep.room_points = np;
  at::Tensor pts = at::from_blob(room.points.data(), {np, 3}, at::kFloat).clone();
  at::Tensor batch = at::zeros({np}, at::kLong);
  at::Tensor pc = PointVoxelCoords(pts, batch, 50.0);
  Voxelized vox = Voxelize(pc, pts, 1, {128, 128, 128});
  rep.room_voxels = vox.tensor.num_sites();

  // Fused rows once per kernel path, then the torch-ops row.
  struct Variant {
    SparseBackend backend;
    SparseKernelPath path;
  };
  std::vector<Variant> fused_variants;
  for (SparseKernelPath path : paths) fused_variants.push_back({SparseBackend::kFused, path});
  auto with_torch_ops = [&](bool torch_ops) {
    std::vector<Variant> v = fused_variants;
    if (torch_ops) v.push_back({SparseBackend::kTorchOps, paths.front()});
    return v;
  };
  auto kernels_name = [](const Variant& v) {
    return v.backend == SparseBackend::kFused ? std::string(SparseKernelPathName(v.path))
                                              : std::string("torch");
  };

  // --- Stage-1 U-Net on the room (first, so that the peak memory is the U-Net's).
  if (opt.unet) {
    SparseUNetConfig cfg = SparseUNetConfig::Stage1();
    SparseUNet net(cfg);
    auto run_forward = [&]() {
      Voxelized v = Voxelize(pc, pts, 1, {128, 128, 128});
      SparseTensor y = net->forward(v.tensor);
      at::Tensor point_feats = Devoxelize(y.features(), v.map);
      return std::make_pair(point_feats, y);
    };
    for (const Variant& var : with_torch_ops(opt.unet_torch_ops)) {
      const SparseBackend be = var.backend;
      SetSparseBackend(be);
      SetSparseKernelPath(var.path);
      const std::string bname = be == SparseBackend::kFused ? "fused" : "torch-ops";
      const int reps = be == SparseBackend::kFused ? opt.repeats : 1;
      net->eval();
      std::vector<double> fw, cpu;
      double flops = 0;
      for (int r = 0; r <= reps; ++r) {
        at::NoGradGuard ng;
        const double c0 = CpuMs();
        auto t0 = Clock::now();
        auto out = run_forward();
        auto t1 = Clock::now();
        if (r > 0 || reps == 1) {
          fw.push_back(Ms(t0, t1));
          cpu.push_back(CpuMs() - c0);
        }
        if (r == 0) flops = UNetForwardFlops(cfg, *out.second.context());
        if (reps == 1) break;
      }
      SparseBenchRow row;
      row.layer = "unet stage1 forward (eval, voxelise+net+devoxelise)";
      row.backend = bname;
      row.kernels = kernels_name(var);
      row.width = cfg.widths[0];
      row.sites = rep.room_voxels;
      row.forward_ms = Median(fw);
      row.total_ms = row.forward_ms;
      row.cpu_ms = Median(cpu);
      row.gflops = flops / (row.total_ms * 1e6);
      rep.rows.push_back(row);
      if (opt.unet_backward && be == SparseBackend::kFused) {
        net->train();
        std::vector<double> f2, b2, cpu2;
        for (int r = 0; r <= opt.repeats; ++r) {
          net->zero_grad();
          const double c0 = CpuMs();
          auto t0 = Clock::now();
          auto out = run_forward();
          at::Tensor loss = out.first.square().mean();
          auto t1 = Clock::now();
          loss.backward();
          auto t2 = Clock::now();
          if (r > 0) {
            f2.push_back(Ms(t0, t1));
            b2.push_back(Ms(t1, t2));
            cpu2.push_back(CpuMs() - c0);
          }
        }
        SparseBenchRow tr;
        tr.layer = "unet stage1 forward+backward (train)";
        tr.backend = bname;
        tr.kernels = row.kernels;
        tr.width = cfg.widths[0];
        tr.sites = rep.room_voxels;
        tr.forward_ms = Median(f2);
        tr.backward_ms = Median(b2);
        tr.total_ms = tr.forward_ms + tr.backward_ms;
        tr.cpu_ms = Median(cpu2);
        tr.gflops = 3.0 * flops / (tr.total_ms * 1e6);
        rep.rows.push_back(tr);
        rep.peak_rss_mb = std::max(rep.peak_rss_mb, PeakRssMb());
      }
    }
  }

  // --- SubM3 C -> C layers on the room voxels.
  SparseTensor base = vox.tensor;
  {
    auto t0 = Clock::now();
    const Rulebook& rb = base.context()->Subm3(1);
    rep.rulebook_ms = Ms(t0, Clock::now());
    (void)rb;
  }
  const int64_t pairs = base.context()->Subm3(1).num_pairs();
  for (int64_t c : opt.widths) {
    at::Tensor x0 = at::randn({rep.room_voxels, c});
    at::Tensor w0 = at::randn({3, 3, 3, c, c}) * (1.0 / std::sqrt(27.0 * c));
    at::Tensor g = at::randn({rep.room_voxels, c});
    for (const Variant& var : with_torch_ops(opt.torch_ops)) {
      const SparseBackend be = var.backend;
      SetSparseBackend(be);
      SetSparseKernelPath(var.path);
      // The torch-ops path is slow: one untimed warm-up and repeats for fused, one run else.
      const int warm = be == SparseBackend::kFused ? 1 : 0;
      const int runs = be == SparseBackend::kFused ? opt.repeats : 1;
      std::vector<double> fw, bw, cpu;
      for (int r = 0; r < warm + runs; ++r) {
        at::Tensor x = x0.clone().set_requires_grad(true);
        at::Tensor w = w0.clone().set_requires_grad(true);
        const double c0 = CpuMs();
        auto t0 = Clock::now();
        at::Tensor y = SubMConv3d(base.WithFeatures(x), w).features();
        auto t1 = Clock::now();
        y.backward(g);
        auto t2 = Clock::now();
        if (r >= warm) {
          fw.push_back(Ms(t0, t1));
          bw.push_back(Ms(t1, t2));
          cpu.push_back(CpuMs() - c0);
        }
      }
      SparseBenchRow row;
      row.layer = "subm3 " + std::to_string(c) + "->" + std::to_string(c);
      row.backend = be == SparseBackend::kFused ? "fused" : "torch-ops";
      row.kernels = kernels_name(var);
      row.width = c;
      row.sites = rep.room_voxels;
      row.pairs = pairs;
      row.forward_ms = Median(fw);
      row.backward_ms = Median(bw);
      row.total_ms = row.forward_ms + row.backward_ms;
      row.cpu_ms = Median(cpu);
      row.gflops = 3.0 * 2.0 * pairs * c * c / (row.total_ms * 1e6);
      rep.rows.push_back(row);
    }
  }
  rep.final_peak_rss_mb = PeakRssMb();
  return rep;
}

}  // namespace dimr::nn
