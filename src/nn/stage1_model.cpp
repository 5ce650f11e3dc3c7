// Stage-1 point-wise network of DIMR in LibTorch (include/dimr/nn/stage1_model.h, spec
// dimr-method.md sections 2.3-2.5 and 11).
//
// Deviations from the reference, all deliberate (docs/models.md, "Stage 1"):
//  - Input features are network-frame coordinates (x-y centred, floor at z = 0; stage1_data.h),
//    not absolute ScanNet coordinates.
//  - Training does not zero the heading logits of points *predicted* as non-CAD (the reference
//    does, which gives those points a constant log 12 and no gradient early in training); the
//    heading loss covers every point of a GT CAD instance. (At inference the heading of non-CAD
//    points is never used, so there is nothing to zero.)
//  - The learning rate decays continuously per step: lr0 * decay^(step / total_steps).
#include "dimr/nn/stage1_model.h"

#include <torch/cuda.h>
#include <torch/torch.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/model_archive.h"
#include "dimr/nn/sparse_ops.h"
#include "dimr/nn/sparse_unet.h"
#include "stage1_heads.h"

namespace dimr::nn {

// ---------------------------------------------------------------------------------------
// Config
// ---------------------------------------------------------------------------------------

Stage1Config Stage1Config::Reference() {
  Stage1Config c;
  c.input.scale = 50;
  c.widths = {32, 32, 64, 64, 96, 96, 128};
  c.reps = 2;
  return c;
}

namespace {

// The text form of a Stage1Config (model archives, --config): one declaration per key.
const config::Fields<Stage1Config>& Stage1ConfigFields() {
  static const config::Fields<Stage1Config> fields =
      config::Fields<Stage1Config>("stage1 config")
          .Number(
              "scale", [](Stage1Config& c) -> double& { return c.input.scale; }, "1/m",
              "voxels per metre (20 = 5 cm)", 1e-6, 1000.0)
          .Flag(
              "rgb", [](Stage1Config& c) -> bool& { return c.input.use_rgb; },
              "feed colours besides xyz")
          .NumberList(
              "widths", [](Stage1Config& c) -> std::vector<std::int64_t>& { return c.widths; },
              "channels", "U-Net level widths", std::int64_t{1}, std::int64_t{4096})
          .Check([](const Stage1Config& c) -> std::string {
            return c.widths.size() > 12 ? "more than 12 levels" : "";
          })
          .Number(
              "reps", [](Stage1Config& c) -> int& { return c.reps; }, "",
              "residual blocks per level and side", 1, 8)
          .Number(
              "classes", [](Stage1Config& c) -> int& { return c.num_classes; }, "",
              "semantic classes", 2, 1000);
  return fields;
}

}  // namespace

void Stage1Config::Validate() const {
  input.Validate();
  Stage1ConfigFields().Validate(*this);
}

std::string Stage1Config::ToString() const { return Stage1ConfigFields().Format(*this); }

Stage1Config Stage1Config::FromString(const std::string& text) {
  const Stage1Config c = Stage1ConfigFields().Parse(text);
  c.Validate();
  return c;
}

// ---------------------------------------------------------------------------------------
// Network
// ---------------------------------------------------------------------------------------

namespace {

torch::nn::BatchNorm1d HeadNorm(int64_t c) {
  return torch::nn::BatchNorm1d(torch::nn::BatchNorm1dOptions(c).eps(1e-4).momentum(0.1));
}

struct HeadOutput {
  torch::Tensor semantic;  // [N, 25] logits
  torch::Tensor offset;    // [N, 3]
  torch::Tensor heading;   // [N, 24]: 12 bin logits, 12 normalised residuals
  torch::Tensor features;  // [N, C0]
};

class Stage1NetImpl : public torch::nn::Module {
 public:
  explicit Stage1NetImpl(const Stage1Config& c) {
    SparseUNetConfig u;
    u.in_channels = c.input.feature_channels();
    u.widths = c.widths;
    u.reps = c.reps;
    backbone = register_module("backbone", SparseUNet(u));
    const int64_t c0 = c.widths[0];
    linear = register_module("linear", torch::nn::Linear(c0, c.num_classes));
    offset = register_module(
        "offset", torch::nn::Sequential(
                      torch::nn::Linear(c0, 16), HeadNorm(16),
                      torch::nn::LeakyReLU(torch::nn::LeakyReLUOptions().negative_slope(0.01))));
    offset_linear = register_module("offset_linear", torch::nn::Linear(16, 3));
    angle = register_module(
        "angle", torch::nn::Sequential(
                     torch::nn::Linear(c0, c0), HeadNorm(c0),
                     torch::nn::LeakyReLU(torch::nn::LeakyReLUOptions().negative_slope(0.01))));
    angle_linear = register_module("angle_linear", torch::nn::Linear(c0, 2 * kHeadingBins));
  }

  HeadOutput Heads(const torch::Tensor& f) {
    HeadOutput h;
    h.features = f;
    h.semantic = linear->forward(f);
    h.offset = offset_linear->forward(offset->forward(f));
    h.heading = angle_linear->forward(angle->forward(f));
    return h;
  }

  // The heads at inference (eval mode only): Linear -> BatchNorm -> LeakyReLU folded into one
  // addmm per MLP (W' = diag(g / sqrt(var + eps)) W, b' = (b - mean) g / sqrt(var + eps) +
  // beta), the same function as Heads() up to float rounding and one op instead of three. The
  // folded weights are computed once per prediction (FoldHeads), not once per pass.
  struct FoldedHeads {
    torch::Tensor offset_w, offset_b, angle_w, angle_b;  // W'^T [in, hidden], b' [hidden]
  };
  FoldedHeads FoldHeads() {
    auto fold = [](torch::nn::Sequential& seq, torch::Tensor* w, torch::Tensor* b) {
      auto lin = seq[0]->as<torch::nn::Linear>();
      auto bn = seq[1]->as<torch::nn::BatchNorm1d>();
      const torch::Tensor k = bn->weight / torch::sqrt(bn->running_var + bn->options.eps());
      *w = (lin->weight * k.unsqueeze(1)).t();
      *b = (lin->bias - bn->running_mean) * k + bn->bias;
    };
    FoldedHeads f;
    fold(offset, &f.offset_w, &f.offset_b);
    fold(angle, &f.angle_w, &f.angle_b);
    return f;
  }
  HeadOutput HeadsFolded(const torch::Tensor& f, const FoldedHeads& w) {
    auto mlp = [&](const torch::Tensor& wt, const torch::Tensor& b, torch::nn::Linear& last) {
      torch::Tensor hidden = Affine(f, wt, b);
      torch::leaky_relu_(hidden, 0.01);
      return Affine(hidden, last->weight.t(), last->bias);
    };
    HeadOutput h;
    h.features = f;
    h.semantic = Affine(f, linear->weight.t(), linear->bias);
    h.offset = mlp(w.offset_w, w.offset_b, offset_linear);
    h.heading = mlp(w.angle_w, w.angle_b, angle_linear);
    return h;
  }

  // b + x wt, as Linear computes it (addmm, beta = alpha = 1: the bias rows, then the GEMM
  // accumulates onto them). On the CPU the bias rows are written by a plain row copy and addmm
  // runs in place on them: ATen's broadcast copy of the bias cost as much as the GEMM itself.
  static torch::Tensor Affine(const torch::Tensor& x, const torch::Tensor& wt,
                              const torch::Tensor& b) {
    if (!x.is_cpu() || x.scalar_type() != torch::kFloat32 || x.dim() != 2) {
      return torch::addmm(b, x, wt);
    }
    const int64_t rows = x.size(0), cols = b.size(0);
    torch::Tensor out = torch::empty({rows, cols}, x.options());
    const torch::Tensor bias = b.contiguous();
    const float* pb = bias.data_ptr<float>();
    float* po = out.data_ptr<float>();
    // The first rows one by one, then copies of that block (it stays in L1).
    const int64_t head = std::min<int64_t>(rows, 64);
    for (int64_t r = 0; r < head; ++r) std::memcpy(po + r * cols, pb, sizeof(float) * cols);
    for (int64_t r = head; r < rows; r += head) {
      std::memcpy(po + r * cols, po, sizeof(float) * cols * std::min(head, rows - r));
    }
    torch::addmm_out(out, out, x, wt);
    return out;
  }

  SparseUNet backbone{nullptr};
  torch::nn::Linear linear{nullptr}, offset_linear{nullptr}, angle_linear{nullptr};
  torch::nn::Sequential offset{nullptr}, angle{nullptr};
};
TORCH_MODULE(Stage1Net);

template <typename T>
torch::Tensor FromVector(const std::vector<T>& v, torch::Dtype dtype, std::vector<int64_t> shape) {
  if (v.empty()) return torch::zeros(shape, torch::TensorOptions().dtype(dtype));
  return torch::from_blob(const_cast<T*>(v.data()), shape, torch::TensorOptions().dtype(dtype))
      .clone();
}

struct BatchTensors {
  torch::Tensor voxel, features, semantic, offset_target, offset_valid, heading_bin,
      heading_residual;
  torch::Tensor semantic_weight;  // [N] or undefined (unweighted points)
  int64_t batch_size = 0;
};

BatchTensors ToTensors(const Stage1Batch& b, const torch::Device& device) {
  const int64_t n = b.num_points();
  if (n == 0) throw InvalidArgument("stage1: empty batch (no points)");
  if (static_cast<int64_t>(b.voxel.size()) != 4 * n ||
      static_cast<int64_t>(b.features.size()) != n * b.feature_channels ||
      static_cast<int64_t>(b.offset_target.size()) != 3 * n ||
      static_cast<int64_t>(b.offset_valid.size()) != n ||
      static_cast<int64_t>(b.heading_bin.size()) != n ||
      static_cast<int64_t>(b.heading_residual.size()) != n ||
      (!b.semantic_weight.empty() && static_cast<int64_t>(b.semantic_weight.size()) != n)) {
    throw InvalidArgument("stage1: inconsistent batch array sizes");
  }
  BatchTensors t;
  t.batch_size = b.batch_size;
  t.voxel = FromVector(b.voxel, torch::kInt32, {n, 4});
  t.features = FromVector(b.features, torch::kFloat32, {n, b.feature_channels}).to(device);
  t.semantic = FromVector(b.semantic, torch::kInt64, {n}).to(device);
  t.offset_target = FromVector(b.offset_target, torch::kFloat32, {n, 3}).to(device);
  t.offset_valid = FromVector(b.offset_valid, torch::kUInt8, {n}).to(torch::kFloat32).to(device);
  t.heading_bin = FromVector(b.heading_bin, torch::kInt64, {n}).to(device);
  t.heading_residual = FromVector(b.heading_residual, torch::kFloat32, {n}).to(device);
  if (!b.semantic_weight.empty())
    t.semantic_weight = FromVector(b.semantic_weight, torch::kFloat32, {n}).to(device);
  return t;
}

struct LossOut {
  torch::Tensor total;
  Stage1LossTerms terms;
};

// class_weight: [num_classes] or undefined (unweighted).
LossOut ComputeLoss(const HeadOutput& h, const BatchTensors& t,
                    const torch::Tensor& class_weight = {}) {
  LossOut out;
  // Semantic cross-entropy, ignore -100, (weighted) mean over the labelled points. With
  // per-point weights w_i: sum_i w_i c_{y_i} ce_i / sum_i w_i c_{y_i} (c: class weights or 1),
  // which is the class-weighted mean when every w_i is 1.
  torch::Tensor sem;
  const torch::Tensor labelled = t.semantic != kStage1Ignore;
  if (labelled.any().item<bool>()) {
    auto options = torch::nn::functional::CrossEntropyFuncOptions().ignore_index(kStage1Ignore);
    if (class_weight.defined()) options.weight(class_weight);
    if (t.semantic_weight.defined()) {
      options.reduction(torch::kNone);  // c_{y_i} ce_i, 0 where ignored
      const torch::Tensor ce =
          torch::nn::functional::cross_entropy(h.semantic, t.semantic, options);
      const torch::Tensor c = class_weight.defined()
                                  ? class_weight.index_select(0, t.semantic.clamp_min(0))
                                  : torch::ones_like(t.semantic_weight);
      const torch::Tensor w = t.semantic_weight * c * labelled.to(torch::kFloat32);
      sem = (ce * t.semantic_weight).sum() / w.sum();
    } else {
      sem = torch::nn::functional::cross_entropy(h.semantic, t.semantic, options);
    }
  } else {
    sem = h.semantic.sum() * 0;
  }
  // Offsets: L1 norm and negative cosine over points of any instance.
  const torch::Tensor valid = t.offset_valid;
  const torch::Tensor denom = valid.sum() + 1e-6;
  const torch::Tensor off_norm = ((h.offset - t.offset_target).abs().sum(1) * valid).sum() / denom;
  const torch::Tensor pred_dir = h.offset / (h.offset.norm(2, 1, true) + 1e-8);
  const torch::Tensor gt_dir = t.offset_target / (t.offset_target.norm(2, 1, true) + 1e-8);
  const torch::Tensor off_dir = -((pred_dir * gt_dir).sum(1) * valid).sum() / denom;
  // Heading: bin CE + smooth-L1 residual of the GT bin, over points of CAD-box instances.
  const torch::Tensor ang_valid = (t.heading_bin != kStage1Ignore).to(torch::kFloat32);
  const torch::Tensor ang_denom = ang_valid.sum() + 1e-6;
  const torch::Tensor bins = t.heading_bin.clamp_min(0);
  const torch::Tensor logits = h.heading.slice(1, 0, kHeadingBins);
  const torch::Tensor residuals = h.heading.slice(1, kHeadingBins, 2 * kHeadingBins);
  const torch::Tensor ce = torch::nn::functional::cross_entropy(
      logits, bins, torch::nn::functional::CrossEntropyFuncOptions().reduction(torch::kNone));
  const torch::Tensor ang_cls = (ce * ang_valid).sum() / ang_denom;
  const torch::Tensor res = residuals.gather(1, bins.unsqueeze(1)).squeeze(1);
  const torch::Tensor sl1 = torch::nn::functional::smooth_l1_loss(
      res, t.heading_residual,
      torch::nn::functional::SmoothL1LossFuncOptions().reduction(torch::kNone));
  const torch::Tensor ang_res = (sl1 * ang_valid).sum() / ang_denom;
  out.total = sem + off_norm + off_dir + ang_cls + ang_res;
  out.terms.semantic = sem.item<double>();
  out.terms.offset_norm = off_norm.item<double>();
  out.terms.offset_dir = off_dir.item<double>();
  out.terms.heading_cls = ang_cls.item<double>();
  out.terms.heading_res = ang_res.item<double>();
  out.terms.total = out.total.item<double>();
  return out;
}

double Ms(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Stage1Model
// ---------------------------------------------------------------------------------------

std::vector<float> SemanticClassWeights(const std::vector<Stage1Sample>& samples, int num_classes,
                                        double min_w, double max_w, double power) {
  if (num_classes < 1) throw InvalidArgument("SemanticClassWeights: num_classes must be >= 1");
  if (!(power > 0 && power <= 2))
    throw InvalidArgument("SemanticClassWeights: need 0 < power <= 2");
  if (!(min_w > 0 && min_w <= max_w)) {
    throw InvalidArgument("SemanticClassWeights: need 0 < min_w <= max_w");
  }
  std::vector<double> count(num_classes, 0.0);
  double total = 0;
  for (const auto& s : samples) {
    for (int c : s.semantic) {
      if (c >= 0 && c < num_classes) {
        count[c] += 1;
        total += 1;
      }
    }
  }
  std::vector<float> w(num_classes, 1.0f);
  std::vector<double> present;
  for (double n : count) {
    if (n > 0) present.push_back(n / total);
  }
  if (present.empty()) return w;
  std::sort(present.begin(), present.end());
  const std::size_t m = present.size();
  const double median = m % 2 ? present[m / 2] : 0.5 * (present[m / 2 - 1] + present[m / 2]);
  for (int c = 0; c < num_classes; ++c) {
    if (count[c] > 0) {
      w[c] = static_cast<float>(
          std::clamp(std::pow(median / (count[c] / total), power), min_w, max_w));
    }
  }
  return w;
}

std::string SparseKernelsInUse() { return SparseKernelPathName(ResolveSparseKernelPath()); }

// The heads' kernels (network input, softmax, TTA mean) follow the sparse-kernel path in force
// (DIMR_SPARSE_KERNELS or SetSparseKernelPath): stage1_heads::HeadsIsaOfSparsePath.
std::string Stage1HeadsKernelsInUse() {
  return stage1_heads::HeadsIsaName(stage1_heads::HeadsIsaOfSparsePath());
}

void SetIntraOpThreads(int threads) {
  if (threads < 1) throw InvalidArgument("threads must be >= 1, got " + std::to_string(threads));
  torch::set_num_threads(threads);
}

struct Stage1Model::Impl {
  Stage1Config config;
  Stage1Net net{nullptr};
  torch::Device device = torch::kCPU;
  explicit Impl(const Stage1Config& c) : config(c), net(c) {}

  // The U-Net on voxelised points; `voxel_heads` runs the heads on its voxel rows (inference)
  // instead of the gathered point rows (training: BatchNorm statistics are per point).
  struct Pass {
    // [N, ...] point rows, or [M, ...] voxel rows (voxel heads: CPU, contiguous logits, which
    // stage1_heads' softmax turns into probabilities in place).
    HeadOutput h;
    torch::Tensor point_to_voxel, voxel_offsets, voxel_points;  // voxel heads: the map, int64
  };
  // `heads` (voxel heads): the folded head weights of this prediction.
  Pass Run(const torch::Tensor& voxel, const torch::Tensor& features, int64_t batch_size,
           const Stage1NetImpl::FoldedHeads* heads, Stage1Timing* timing) {
    const bool voxel_heads = heads != nullptr;
    const auto t0 = std::chrono::steady_clock::now();
    // Every U-Net level halves the grid (k2 s2): at least 2^(levels - 1) voxels per axis, or a
    // flat room (1.37 m high at 5 cm: 28 voxels for 6 levels), a plane or one point could not
    // be down-sampled to the last level. Padding adds no sites, so wider grids are unchanged.
    const int64_t min_extent = int64_t{1} << (config.widths.size() - 1);
    Voxelized v = Voxelize(voxel, features, batch_size, {min_extent, min_extent, min_extent});
    const auto t1 = std::chrono::steady_clock::now();
    v.tensor.context()->BuildKernelMaps(static_cast<int>(config.widths.size()));
    const auto t1b = std::chrono::steady_clock::now();
    const SparseTensor y = net->backbone->forward(v.tensor);
    const auto t2 = std::chrono::steady_clock::now();
    Pass pass;
    if (voxel_heads) {
      pass.h = net->HeadsFolded(y.features(), *heads);
      const auto cpu = [](const torch::Tensor& t) { return t.to(torch::kCPU).contiguous(); };
      pass.h.semantic = cpu(pass.h.semantic);
      pass.h.offset = cpu(pass.h.offset);
      pass.h.heading = cpu(pass.h.heading);
      // Logits: the caller takes the softmax (stage1_heads), alone for one pass or fused with
      // the input-frame rows of a test-time-augmentation pass.
      pass.point_to_voxel = cpu(v.map.point_to_voxel.to(torch::kInt64));
      pass.voxel_offsets = cpu(v.map.voxel_offsets.to(torch::kInt64));
      pass.voxel_points = cpu(v.map.voxel_points.to(torch::kInt64));
    } else {
      pass.h = net->Heads(Devoxelize(y.features(), v.map));
    }
    if (timing) {
      const auto t3 = std::chrono::steady_clock::now();
      timing->voxelize_ms = Ms(t0, t1);
      timing->kernel_map_ms = Ms(t1, t1b);
      timing->unet_ms = Ms(t1b, t2);
      timing->heads_ms = Ms(t2, t3);
    }
    return pass;
  }

  HeadOutput Forward(const BatchTensors& t, Stage1Timing* timing) {
    return Run(t.voxel, t.features, t.batch_size, /*heads=*/nullptr, timing).h;
  }

  // One network pass on a scene view (eval mode, no gradient: the caller's guard), with the
  // heads run on the voxels instead of the points. Devoxelize is a gather and every head is a
  // row-wise function of its input (eval-mode BatchNorm uses the running statistics), so a
  // point's outputs are its voxel's row: the same numbers as heads on the gathered point
  // features, for ~3-5x fewer rows at 5 cm (a 100k-point room has ~25k voxels).
  Pass ForwardSceneVoxels(const ScenePoints& scene, const Stage1NetImpl::FoldedHeads& heads,
                          Stage1Timing* timing, NetworkFrame* frame) {
    // MakeStage1NetworkInput's numbers written straight into uninitialised tensors (no zero
    // fill, no copy).
    // (An empty scene gets empty tensors; WriteStage1NetworkInput refuses it by name.)
    const int64_t n = static_cast<int64_t>(scene.size);
    torch::Tensor voxel = torch::empty({n, 4}, torch::kInt32);
    torch::Tensor features = torch::empty({n, config.input.feature_channels()}, torch::kFloat32);
    std::array<std::int64_t, 3> extent;
    *frame = WriteStage1NetworkInput(scene, config.input, &extent, features.data_ptr<float>(),
                                     voxel.data_ptr<std::int32_t>());
    return Run(voxel, features.to(device), 1, &heads, timing);
  }

  // The same for the scene moved by p -> centre + R(theta) (sign * (p - centre)) in x-y (z
  // kept), without MakeStage1NetworkInput: the moved z are the scene's, so the network frame's
  // floor is the plain pass's `floor_z` (no second floor search) and only its x-y centre is new;
  // voxels and features are written straight into the tensors with MakeStage1NetworkInput's
  // arithmetic (the same numbers; Stage1Heads.AugmentedPassesMatchPerPointAccumulation
  // compares with Predict on the moved points). `moved` is scratch.
  Pass ForwardMovedScene(const ScenePoints& scene, const Eigen::Vector2d& centre, double sign,
                         double theta, float floor_z, const Stage1NetImpl::FoldedHeads& heads,
                         stage1_heads::MovedPoints* moved, Stage1Timing* timing) {
    const std::size_t n = scene.size;
    stage1_heads::MoveScenePoints(scene.points, n, centre.x(), centre.y(), sign, std::cos(theta),
                                  std::sin(theta), moved, stage1_heads::HeadsIsaOfSparsePath());
    const Eigen::Vector3f lo(moved->lo[0], moved->lo[1], moved->lo[2]);
    const Eigen::Vector3f hi(moved->hi[0], moved->hi[1], moved->hi[2]);
    // (A colour model's scene has colours: the plain pass, which always runs first, checked.)
    const std::string who = "stage1 input: scene '" + scene.name + "'";
    if (!lo.allFinite() || !hi.allFinite()) {
      throw InvalidArgument(who + ": a rotated point is not finite");
    }
    const Stage1InputConfig& input = config.input;
    const Eigen::Vector3f origin(0.5f * (lo.x() + hi.x()), 0.5f * (lo.y() + hi.y()), floor_z);
    const int C = input.feature_channels();
    const float scale = static_cast<float>(input.scale);
    // Float rounding is monotone, so the smallest / largest (p - origin) * scale over the points
    // are those of the box corners: MakeStage1NetworkInput's minimum without its first loop.
    const Eigen::Vector3f qmin = (lo - origin) * scale;
    const Eigen::Vector3f qmax = (hi - origin) * scale;
    for (int a = 0; a < 3; ++a) {
      const double span = std::floor(static_cast<double>(qmax[a]) - qmin[a]) + 1;
      if (!(span <= 65536)) {
        char buf[160];
        std::snprintf(buf, sizeof(buf),
                      " spans %.1f m along %c = %.0f voxels at scale %g (at most 65536) when "
                      "rotated for test-time augmentation",
                      (qmax[a] - qmin[a]) / scale, "xyz"[a], span, input.scale);
        throw InvalidArgument(who + buf);
      }
    }
    torch::Tensor voxel = torch::empty({static_cast<int64_t>(n), 4}, torch::kInt32);
    torch::Tensor features = torch::empty({static_cast<int64_t>(n), C}, torch::kFloat32);
    stage1_heads::WriteMovedNetworkInput(*moved, input.use_rgb ? scene.colors : nullptr, n,
                                         origin.data(), scale, qmin.data(),
                                         features.data_ptr<float>(), voxel.data_ptr<std::int32_t>(),
                                         stage1_heads::HeadsIsaOfSparsePath());
    return Run(voxel, features.to(device), 1, &heads, timing);
  }

  // The voxel-head tensors of a pass as the raw views stage1_heads reads.
  static stage1_heads::VoxelHeads HeadsView(const Pass& p) {
    stage1_heads::VoxelHeads h;
    h.prob = p.h.semantic.data_ptr<float>();
    h.offset = p.h.offset.data_ptr<float>();
    h.heading = p.h.heading.data_ptr<float>();
    h.voxels = p.h.semantic.size(0);
    h.classes = static_cast<int>(p.h.semantic.size(1));
    return h;
  }
};

Stage1Model::Stage1Model(const Stage1Config& config, std::uint64_t seed) {
  config.Validate();
  torch::manual_seed(seed);
  impl_ = std::make_unique<Impl>(config);
  impl_->net->eval();
}
Stage1Model::~Stage1Model() = default;
Stage1Model::Stage1Model(Stage1Model&&) noexcept = default;
Stage1Model& Stage1Model::operator=(Stage1Model&&) noexcept = default;

const Stage1Config& Stage1Model::config() const { return impl_->config; }

std::int64_t Stage1Model::NumParameters() const {
  std::int64_t n = 0;
  for (const auto& p : impl_->net->parameters()) n += p.numel();
  return n;
}

void Stage1Model::Save(const std::string& path, bool half) const {
  SaveModelArchive(*impl_->net, path, "stage1", impl_->config.ToString(), half);
}

Stage1Model Stage1Model::Load(const std::string& path) {
  const ModelArchiveReader archive(path, "stage1", "stage-1");
  Stage1Config config;
  try {
    config = Stage1Config::FromString(archive.config());
  } catch (const InvalidArgument& e) {
    throw ParseError(path, e.what());
  }
  Stage1Model model(config);
  archive.LoadInto(*model.impl_->net);
  return model;
}

Stage1Model Stage1Model::Average(const std::vector<std::string>& paths) {
  if (paths.empty()) throw InvalidArgument("stage1 average: no model files given");
  Stage1Model mean = Load(paths[0]);
  if (paths.size() == 1) return mean;
  torch::NoGradGuard no_grad;
  const std::string config = mean.config().ToString();
  auto floating = [](const torch::nn::Module& m) {
    std::vector<torch::Tensor> out;
    for (const auto& p : m.parameters()) out.push_back(p);
    for (const auto& b : m.buffers()) {
      if (b.is_floating_point()) out.push_back(b);
    }
    return out;
  };
  std::vector<torch::Tensor> target = floating(*mean.impl_->net);  // written in place
  std::vector<torch::Tensor> acc;                                  // double sums
  for (const auto& t : target) acc.push_back(t.to(torch::kDouble));
  for (std::size_t i = 1; i < paths.size(); ++i) {
    const Stage1Model other = Load(paths[i]);
    if (other.config().ToString() != config) {
      throw InvalidArgument("stage1 average: '" + paths[i] + "' has configuration '" +
                            other.config().ToString() + "', '" + paths[0] + "' has '" + config +
                            "'");
    }
    const std::vector<torch::Tensor> t = floating(*other.impl_->net);
    for (std::size_t k = 0; k < acc.size(); ++k) acc[k] += t[k].to(torch::kDouble);
  }
  const double n = static_cast<double>(paths.size());
  for (std::size_t k = 0; k < acc.size(); ++k) target[k].copy_((acc[k] / n).to(target[k].dtype()));
  return mean;
}

Stage1Model Stage1Model::LoadWithoutColour(const std::string& path) {
  const Stage1Model colour = Load(path);
  if (!colour.config().input.use_rgb) {
    throw InvalidArgument("stage1: '" + path + "' has no colour input (configuration '" +
                          colour.config().ToString() + "'), nothing to drop");
  }
  Stage1Config config = colour.config();
  config.input.use_rgb = false;
  Stage1Model geometry(config);
  torch::NoGradGuard no_grad;
  const auto source_params = colour.impl_->net->named_parameters();
  const auto source_buffers = colour.impl_->net->named_buffers();
  const int64_t xyz = config.input.feature_channels();
  auto copy = [&](const std::string& name, const torch::Tensor& from, torch::Tensor& to) {
    if (from.sizes() == to.sizes()) {
      to.copy_(from);
      return;
    }
    // The only tensor whose shape depends on the input channels: the input convolution's
    // [k, k, k, cin, cout] weight; its first `xyz` input channels are the coordinates.
    if (from.dim() == 5 && to.dim() == 5 && from.size(3) > xyz && to.size(3) == xyz &&
        from.size(4) == to.size(4)) {
      to.copy_(from.narrow(3, 0, xyz));
      return;
    }
    std::ostringstream msg;
    msg << "stage1: cannot drop the colour input of '" << path << "': tensor '" << name
        << "' has shape " << from.sizes() << ", the geometry-only model expects " << to.sizes();
    throw InvalidArgument(msg.str());
  };
  for (auto& item : geometry.impl_->net->named_parameters()) {
    copy(item.key(), source_params[item.key()], item.value());
  }
  for (auto& item : geometry.impl_->net->named_buffers()) {
    copy(item.key(), source_buffers[item.key()], item.value());
  }
  return geometry;
}

Stage1Model Stage1Model::LoadAtScale(const std::string& path, double scale) {
  Stage1Model model = Load(path);
  Stage1Config config = model.config();
  config.input.scale = scale;
  try {
    config.Validate();
  } catch (const InvalidArgument& e) {
    throw InvalidArgument("stage1: cannot load '" + path + "' at scale " + std::to_string(scale) +
                          ": " + e.what());
  }
  // The network never reads the voxel size (only the voxelisation of its input does), so the
  // loaded tensors, BatchNorm statistics included, serve the new grid as they are.
  model.impl_->config = config;
  return model;
}

Stage1Model Stage1Model::LoadDeeper(const std::string& path, int reps) {
  const Stage1Model shallow = Load(path);
  const int stored = shallow.config().reps;
  if (reps <= stored) {
    throw InvalidArgument("stage1: cannot deepen '" + path + "' to reps=" + std::to_string(reps) +
                          ": it already has reps=" + std::to_string(stored));
  }
  Stage1Config config = shallow.config();
  config.reps = reps;
  config.Validate();
  Stage1Model deep(config);
  torch::NoGradGuard no_grad;
  // A residual block's name holds ".block<k>." (k = its index within its level and side).
  auto block_index = [](const std::string& name) -> int {
    static const std::regex kBlock(R"(\.block([0-9]+)\.)");
    std::smatch m;
    return std::regex_search(name, m, kBlock) ? std::stoi(m[1].str()) : -1;
  };
  auto carry = [&](const torch::OrderedDict<std::string, torch::Tensor>& from,
                   torch::OrderedDict<std::string, torch::Tensor>& to) {
    std::size_t carried = 0;
    for (auto& item : to) {
      const torch::Tensor* source = from.find(item.key());
      if (block_index(item.key()) >= stored) {
        if (source != nullptr) {
          throw InvalidArgument("stage1: cannot deepen '" + path + "': tensor '" + item.key() +
                                "' belongs to an added block but is stored");
        }
        // conv_branch = BN, ReLU, conv0 ("2"), BN, ReLU, conv1 ("5"): zero conv1.
        if (item.key().find("conv_branch.5.weight") != std::string::npos) item.value().zero_();
        continue;
      }
      if (source == nullptr || source->sizes() != item.value().sizes()) {
        std::ostringstream msg;
        msg << "stage1: cannot deepen '" << path << "': tensor '" << item.key() << "' ";
        if (source == nullptr) {
          msg << "is not stored";
        } else {
          msg << "has shape " << source->sizes();
        }
        msg << ", the deeper network expects " << item.value().sizes();
        throw InvalidArgument(msg.str());
      }
      item.value().copy_(*source);
      ++carried;
    }
    if (carried != from.size()) {
      throw InvalidArgument("stage1: cannot deepen '" + path +
                            "': " + std::to_string(from.size() - carried) +
                            " stored tensors have no place in the deeper network");
    }
  };
  auto params = deep.impl_->net->named_parameters();
  carry(shallow.impl_->net->named_parameters(), params);
  auto buffers = deep.impl_->net->named_buffers();
  carry(shallow.impl_->net->named_buffers(), buffers);
  return deep;
}

Stage1LossTerms Stage1Model::EvaluateLoss(const Stage1Batch& batch) const {
  torch::NoGradGuard no_grad;
  const bool was_training = impl_->net->is_training();
  impl_->net->eval();
  const BatchTensors t = ToTensors(batch, impl_->device);
  const HeadOutput h = impl_->Forward(t, nullptr);
  const LossOut l = ComputeLoss(h, t);
  if (was_training) impl_->net->train();
  return l.terms;
}

Stage1Output Stage1Model::Predict(const Stage1Sample& sample, bool with_features,
                                  Stage1Timing* timing) const {
  if (impl_->config.input.use_rgb && sample.colors.size() != sample.points.size()) {
    throw InvalidArgument("stage1 predict: the model uses colour but scene '" + sample.name +
                          "' has " + std::to_string(sample.colors.size()) + " colours for " +
                          std::to_string(sample.points.size()) + " points");
  }
  return Predict(ScenePoints(sample.points, &sample.colors, sample.name), with_features, timing);
}

Stage1Output Stage1Model::PredictAugmented(const Stage1Sample& sample, int rotations, bool mirror,
                                           bool with_features, Stage1Timing* timing) const {
  if (impl_->config.input.use_rgb && sample.colors.size() != sample.points.size()) {
    throw InvalidArgument("stage1 predict: the model uses colour but scene '" + sample.name +
                          "' has " + std::to_string(sample.colors.size()) + " colours for " +
                          std::to_string(sample.points.size()) + " points");
  }
  return PredictAugmented(ScenePoints(sample.points, &sample.colors, sample.name), rotations,
                          mirror, with_features, timing);
}

Stage1Output Stage1Model::Predict(const ScenePoints& scene, bool with_features,
                                  Stage1Timing* timing) const {
  return PredictAugmented(scene, 1, false, with_features, timing);
}

Stage1Output Stage1Model::PredictAugmented(const ScenePoints& scene, int rotations, bool mirror,
                                           bool with_features, Stage1Timing* timing,
                                           double scene_norm) const {
  if (rotations < 1 || kHeadingBins % rotations != 0) {
    throw InvalidArgument("stage1 predict: rotations must divide " + std::to_string(kHeadingBins) +
                          " (1, 2, 3, 4, 6, 12), got " + std::to_string(rotations));
  }
  if (!(scene_norm >= 0.0 && scene_norm <= 1.0)) {
    throw InvalidArgument("stage1 predict: scene_norm must be in [0, 1], got " +
                          std::to_string(scene_norm));
  }
  const ScopedSceneNormalisation scene_statistics(scene_norm);
  const auto t_start = std::chrono::steady_clock::now();
  torch::NoGradGuard no_grad;
  impl_->net->eval();
  Stage1Timing local;
  auto add_network_time = [&](const Stage1Timing& t) {
    local.voxelize_ms += t.voxelize_ms;
    local.kernel_map_ms += t.kernel_map_ms;
    local.unet_ms += t.unet_ms;
  };
  Stage1Output out;
  const std::size_t n = scene.size;
  const stage1_heads::RowLayout layout(impl_->config.num_classes);
  const int passes = rotations * (mirror ? 2 : 1);
  Stage1Timing t;
  const Stage1NetImpl::FoldedHeads heads = impl_->net->FoldHeads();
  const Impl::Pass plain = impl_->ForwardSceneVoxels(scene, heads, &t, &out.frame);
  add_network_time(t);
  if (with_features) {
    const torch::Tensor f = plain.h.features.to(torch::kCPU).contiguous();
    const int64_t c0 = f.size(1);
    const float* pf = f.data_ptr<float>();
    const int64_t* p2v = plain.point_to_voxel.data_ptr<int64_t>();
    out.features.resize(n * c0);
    for (std::size_t i = 0; i < n; ++i) {
      std::copy_n(pf + p2v[i] * c0, c0, out.features.data() + i * c0);
    }
  }
  if (passes == 1) {
    // The semantic and heading-bin softmax in place (one sweep over the rows, no slice copies;
    // ATen's softmax on 25- and 12-wide rows cost ~5 ms per pass).
    std::vector<int> argmax(static_cast<std::size_t>(plain.h.semantic.size(0)));
    stage1_heads::SoftmaxInPlace(Impl::HeadsView(plain), argmax.data(),
                                 stage1_heads::HeadsIsaOfSparsePath());
    stage1_heads::CopyOutOnePass(Impl::HeadsView(plain), argmax.data(),
                                 plain.point_to_voxel.data_ptr<int64_t>(), n, &out);
  } else {
    // Every pass's voxel rows in the input frame, and for every further pass the voxel of
    // each point, listed in the plain pass's voxel order (uninitialised buffers: every
    // element is written).
    std::vector<std::unique_ptr<float[]>> rows;
    std::vector<std::unique_ptr<std::int32_t[]>> voxel_of;
    auto add_rows = [&](const Impl::Pass& pass, bool mirrored, int k, int of_rotations) {
      const stage1_heads::VoxelHeads h = Impl::HeadsView(pass);
      rows.emplace_back(new float[static_cast<std::size_t>(h.voxels) * layout.stride]);
      stage1_heads::SoftmaxToInputFrameRows(h, layout, mirrored, k, of_rotations, rows.back().get(),
                                            stage1_heads::HeadsIsaOfSparsePath());
    };
    add_rows(plain, false, 0, 1);
    voxel_of.emplace_back();  // the plain pass: its voxel order itself
    const int64_t* order = plain.voxel_points.data_ptr<int64_t>();
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < n; ++i) centre += scene.points[i].head<2>().cast<double>();
    centre /= static_cast<double>(n);
    stage1_heads::MovedPoints moved;
    for (int m = 0; m < (mirror ? 2 : 1); ++m) {
      for (int k = 0; k < rotations; ++k) {
        if (k == 0 && m == 0) continue;  // the plain pass above
        const Impl::Pass pass =
            impl_->ForwardMovedScene(scene, centre, m == 1 ? -1.0 : 1.0, 2.0 * M_PI * k / rotations,
                                     out.frame.floor_z, heads, &moved, &t);
        add_network_time(t);
        add_rows(pass, m == 1, k, rotations);
        const int64_t* p2v = pass.point_to_voxel.data_ptr<int64_t>();
        voxel_of.emplace_back(new std::int32_t[n]);
        std::int32_t* of = voxel_of.back().get();
        for (std::size_t j = 0; j < n; ++j) of[j] = static_cast<std::int32_t>(p2v[order[j]]);
      }
    }
    std::vector<const float*> row_tables;
    std::vector<const std::int32_t*> indexes;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      row_tables.push_back(rows[k].get());
      indexes.push_back(voxel_of[k].get());
    }
    stage1_heads::AverageInVoxelOrder(plain.voxel_offsets.data_ptr<int64_t>(),
                                      plain.voxel_offsets.size(0) - 1, order, n, row_tables,
                                      indexes, layout, &out, stage1_heads::HeadsIsaOfSparsePath());
  }
  // heads = everything but the voxelisation, rulebooks and convolutions: network input, head
  // MLPs, softmax, mapping back, averaging and copy-out.
  local.heads_ms = Ms(t_start, std::chrono::steady_clock::now()) - local.voxelize_ms -
                   local.kernel_map_ms - local.unet_ms;
  if (timing) *timing = local;
  return out;
}

// ---------------------------------------------------------------------------------------
// Training
// ---------------------------------------------------------------------------------------

std::vector<Stage1StepLog> Stage1Model::Train(const std::vector<Stage1Sample>& train,
                                              const Stage1TrainOptions& opt,
                                              const std::function<void(const Stage1StepLog&)>& log,
                                              const EpochCallback& on_epoch) {
  if (train.empty()) throw InvalidArgument("stage1 train: no training scenes");
  if (opt.epochs < 1) throw InvalidArgument("stage1 train: 'epochs' must be >= 1");
  if (opt.batch_size < 1) throw InvalidArgument("stage1 train: 'batch_size' must be >= 1");
  if (!(opt.learning_rate > 0)) throw InvalidArgument("stage1 train: 'learning_rate' must be > 0");
  if (!(opt.lr_decay > 0 && opt.lr_decay <= 1)) {
    throw InvalidArgument("stage1 train: 'lr_decay' must be in (0, 1]");
  }
  opt.augment.Validate();
  if (opt.threads > 0) torch::set_num_threads(opt.threads);
  if (opt.device == "cuda") {
    if (!torch::cuda::is_available()) {
      throw InvalidArgument("stage1 train: device 'cuda' requested but not available");
    }
    impl_->device = torch::Device(torch::kCUDA);
  } else if (opt.device != "cpu") {
    throw InvalidArgument("stage1 train: unknown device '" + opt.device + "' (cpu or cuda)");
  }
  auto& net = impl_->net;
  net->to(impl_->device);

  torch::Tensor class_weight;
  if (!opt.class_weights.empty()) {
    if (static_cast<int>(opt.class_weights.size()) != impl_->config.num_classes) {
      throw InvalidArgument("stage1 train: class_weights has " +
                            std::to_string(opt.class_weights.size()) + " entries for " +
                            std::to_string(impl_->config.num_classes) + " classes");
    }
    for (float w : opt.class_weights) {
      if (!(w > 0) || !std::isfinite(w)) {
        throw InvalidArgument("stage1 train: class weights must be finite and > 0");
      }
    }
    class_weight = FromVector(opt.class_weights, torch::kFloat32,
                              {static_cast<int64_t>(opt.class_weights.size())})
                       .to(impl_->device);
  }
  const int batch_size = std::min<int>(opt.batch_size, static_cast<int>(train.size()));
  Stage1Loader loader(&train, impl_->config.input, opt.augment, batch_size, opt.seed,
                      std::max(1, opt.loader_threads));
  const int per_epoch = loader.batches_per_epoch();
  const int64_t total_steps = static_cast<int64_t>(per_epoch) * opt.epochs;

  torch::optim::Adam optimizer(net->parameters(), torch::optim::AdamOptions(opt.learning_rate));
  int64_t step = 0;  // completed steps
  const std::vector<int64_t> resumed =
      opt.resume ? ResumeTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "stage1",
                                            "stage-1", impl_->config.ToString(), 2)
                 : std::vector<int64_t>{};
  if (!resumed.empty()) {
    step = resumed[0];
    if (step < 0) throw ParseError(opt.checkpoint_path + ".state", "negative step");
    if (resumed[1] != per_epoch) {
      std::fprintf(stderr,
                   "warning: %s: %lld batches per epoch before, %d now (other data or batch "
                   "size); continuing at step %lld\n",
                   opt.checkpoint_path.c_str(), static_cast<long long>(resumed[1]), per_epoch,
                   static_cast<long long>(step));
    }
    std::fprintf(stderr, "resuming from %s at step %lld\n", opt.checkpoint_path.c_str(),
                 static_cast<long long>(step));
  }

  auto checkpoint = [&]() {
    if (opt.checkpoint_path.empty()) return;
    SaveTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "stage1", impl_->config.ToString(),
                           {step, per_epoch});
  };
  auto run_epoch_callback = [&](int epoch) {
    if (!on_epoch) return;
    net->eval();
    const auto saved_device = impl_->device;
    const auto metrics = on_epoch(epoch, *this);
    impl_->device = saved_device;
    if (!metrics.empty()) {
      std::fprintf(stderr, "\nepoch %d:", epoch);
      for (const auto& [k, v] : metrics) std::fprintf(stderr, " %s=%.4f", k.c_str(), v);
      std::fprintf(stderr, "\n");
    }
  };

  std::vector<Stage1StepLog> logs;
  const auto t_start = std::chrono::steady_clock::now();
  auto elapsed_s = [&]() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  };
  Stage1LossTerms running;
  int running_n = 0;
  std::array<double, 3> running_ms{0, 0, 0};  // data, forward (+ loss), backward (+ optimiser)
  bool out_of_time = false;
  while (step < total_steps && !out_of_time) {
    const int epoch = static_cast<int>(step / per_epoch);  // 0-based
    const int first = static_cast<int>(step % per_epoch);
    loader.StartEpoch(epoch, first);
    net->train();
    Stage1Batch batch;
    auto t_wait = std::chrono::steady_clock::now();
    while (step < total_steps && loader.Next(&batch)) {
      const auto t_data = std::chrono::steady_clock::now();
      double progress = static_cast<double>(step) / static_cast<double>(total_steps);
      if (opt.lr_by_time && opt.max_minutes > 0) {
        progress = std::min(1.0, std::max(progress, elapsed_s() / (60.0 * opt.max_minutes)));
      }
      const double lr = std::max(opt.learning_rate * std::pow(opt.lr_decay, progress), 1e-6);
      for (auto& group : optimizer.param_groups()) {
        static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
      }
      const BatchTensors t = ToTensors(batch, impl_->device);
      optimizer.zero_grad();
      Stage1Timing timing;
      const HeadOutput h = impl_->Forward(t, &timing);
      const auto t_fwd = std::chrono::steady_clock::now();
      LossOut l = ComputeLoss(h, t, class_weight);
      if (!std::isfinite(l.terms.total)) {
        throw Error("stage1 train: the loss became non-finite at step " + std::to_string(step + 1) +
                    " (batch " + batch.names.front() + "...); lower the learning rate");
      }
      const auto t_loss = std::chrono::steady_clock::now();
      const bool cuda = impl_->device.is_cuda();
      l.total.backward();
      if (cuda) torch::cuda::synchronize();
      const auto t_bwd = std::chrono::steady_clock::now();
      optimizer.step();
      if (cuda) torch::cuda::synchronize();
      const auto t_opt = std::chrono::steady_clock::now();
      ++step;
      Stage1StepLog s;
      s.data_ms = Ms(t_wait, t_data);
      s.voxelize_ms = timing.voxelize_ms;
      s.kernel_map_ms = timing.kernel_map_ms;
      s.unet_ms = timing.unet_ms;
      s.loss_ms = timing.heads_ms + Ms(t_fwd, t_loss);
      s.backward_ms = Ms(t_loss, t_bwd);
      s.optimizer_ms = Ms(t_bwd, t_opt);
      s.epoch = epoch + 1;
      s.step = static_cast<int>(step);
      s.lr = lr;
      s.loss = l.terms;
      s.seconds = elapsed_s();
      logs.push_back(s);
      if (log) log(s);
      running.total += l.terms.total;
      running.semantic += l.terms.semantic;
      running.offset_norm += l.terms.offset_norm;
      running.offset_dir += l.terms.offset_dir;
      running.heading_cls += l.terms.heading_cls;
      running.heading_res += l.terms.heading_res;
      ++running_n;
      running_ms[0] += s.data_ms;
      running_ms[1] += s.voxelize_ms + s.kernel_map_ms + s.unet_ms + s.loss_ms;
      running_ms[2] += s.backward_ms + s.optimizer_ms;
      if (opt.progress) {
        const double k = 1.0 / running_n;
        const int in_epoch = static_cast<int>((step - 1) % per_epoch) + 1;
        std::fprintf(stderr,
                     "\r[epoch %d/%d %4d/%d] loss %.3f sem %.3f off %.3f dir %.3f hcls %.3f "
                     "hres %.3f lr %.1e %.2f s/it (data %.0f fwd %.0f bwd %.0f ms)   ",
                     epoch + 1, opt.epochs, in_epoch, per_epoch, running.total * k,
                     running.semantic * k, running.offset_norm * k, running.offset_dir * k,
                     running.heading_cls * k, running.heading_res * k, lr,
                     s.seconds / std::max<double>(1, static_cast<double>(logs.size())),
                     running_ms[0] * k, running_ms[1] * k, running_ms[2] * k);
        std::fflush(stderr);
      }
      if (opt.checkpoint_every_steps > 0 && step % opt.checkpoint_every_steps == 0) checkpoint();
      t_wait = std::chrono::steady_clock::now();
      if (opt.max_minutes > 0 && elapsed_s() / 60.0 >= opt.max_minutes) {
        out_of_time = true;
        break;
      }
    }
    const bool epoch_done = step % per_epoch == 0 || step >= total_steps;
    if (epoch_done) {
      running = Stage1LossTerms();
      running_n = 0;
      running_ms = {0, 0, 0};
      const int finished = static_cast<int>((step + per_epoch - 1) / per_epoch);
      const bool last = step >= total_steps;
      checkpoint();
      if (last || (opt.validate_every_epochs > 0 && finished % opt.validate_every_epochs == 0)) {
        run_epoch_callback(finished);
      }
    }
  }
  if (out_of_time) {
    checkpoint();
    std::fprintf(stderr, "\ntime budget of %.1f min reached at step %lld\n", opt.max_minutes,
                 static_cast<long long>(step));
    run_epoch_callback(static_cast<int>((step + per_epoch - 1) / per_epoch));
  }
  if (opt.progress) std::fprintf(stderr, "\n");
  net->eval();
  return logs;
}

}  // namespace dimr::nn
