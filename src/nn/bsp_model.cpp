// BSP-CVAE in LibTorch (see include/dimr/nn/bsp_model.h and dimr-method.md sections 5-6).
//
// Deviations from the reference, all deliberate:
//  - Reparameterisation uses std = exp(0.5 * logvar), consistent with the KL term (the
//    reference uses 0.5 * exp(logvar), dimr-method.md 5.5 "BUG-ish").
//  - The KL weight is annealed linearly to `kl_weight` over the whole run and clamped there
//    (the reference's 0.1 * epoch / 600 keeps growing).
//  - Encoder voxel channels are [occupied, x, y, z] with (x, y, z) the normalised voxel centre
//    (the reference stores the last inside sample point that fell into the voxel).
#include "dimr/nn/bsp_model.h"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <sstream>

#include "dimr/core/config_fields.h"
#include "dimr/core/timing.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/model_archive.h"

namespace dimr::nn {

// ---------------------------------------------------------------------------------------
// Config
// ---------------------------------------------------------------------------------------

BspConfig BspConfig::Reference() {
  BspConfig c;
  c.resolution = 64;
  c.latent_dim = 128;
  c.encoder_width = 32;
  c.num_planes = 4096;
  c.num_convexes = 256;
  c.decoder_widths = {512, 1024, 2048};
  return c;
}

namespace {

// The text form of a BspConfig (model archives, --config): one declaration per key.
const config::Fields<BspConfig>& BspConfigFields() {
  using C = BspConfig;
  static const config::Fields<C> fields =
      config::Fields<C>("BspConfig")
          .Number(
              "resolution", [](C& c) -> int& { return c.resolution; }, "voxels",
              "encoder input grid (a power of two)", 8, 256)
          .Check([](const C& c) -> std::string {
            return (c.resolution & (c.resolution - 1)) != 0 ? "must be a power of two" : "";
          })
          .Number(
              "latent_dim", [](C& c) -> int& { return c.latent_dim; }, "", "latent size", 1, 4096)
          .Number(
              "encoder_width", [](C& c) -> int& { return c.encoder_width; }, "channels",
              "first encoder conv", 1, 1024)
          .Number(
              "num_planes", [](C& c) -> int& { return c.num_planes; }, "", "planes P", 4, 65536)
          .Number(
              "num_convexes", [](C& c) -> int& { return c.num_convexes; }, "", "convexes C", 1,
              4096)
          .Number(
              "num_classes", [](C& c) -> int& { return c.num_classes; }, "", "classes", 1, 64)
          .NumberList(
              "decoder_widths", [](C& c) -> std::vector<int>& { return c.decoder_widths; },
              "channels", "decoder hidden layers", 1, 65536);
  return fields;
}

}  // namespace

void BspConfig::Validate() const { BspConfigFields().Validate(*this); }

std::string BspConfig::ToString() const { return BspConfigFields().Format(*this); }

BspConfig BspConfig::FromString(const std::string& text) {
  const BspConfig c = BspConfigFields().Parse(text);
  c.Validate();
  return c;
}

// ---------------------------------------------------------------------------------------
// Network
// ---------------------------------------------------------------------------------------

namespace {

constexpr double kLeak = 0.01;
constexpr float kConvexThreshold = 0.01f;

struct EncoderImpl : torch::nn::Module {
  std::vector<torch::nn::Conv3d> convs;
  std::vector<torch::nn::BatchNorm3d> bns;
  torch::nn::Conv3d out{nullptr};

  explicit EncoderImpl(const BspConfig& c) {
    int in = 4 + c.num_classes;
    int ch = c.encoder_width;
    int size = c.resolution;
    int level = 1;
    while (size > 4) {
      convs.push_back(register_module(
          "conv_" + std::to_string(level),
          torch::nn::Conv3d(torch::nn::Conv3dOptions(in, ch, 4).stride(2).padding(1))));
      bns.push_back(register_module("bn_" + std::to_string(level), torch::nn::BatchNorm3d(ch)));
      in = ch;
      ch = std::min(ch * 2, 512);
      size /= 2;
      ++level;
    }
    out = register_module(
        "conv_out",
        torch::nn::Conv3d(torch::nn::Conv3dOptions(in, 2 * c.latent_dim, 4).stride(1).padding(0)));
    for (auto& conv : convs) {
      torch::nn::init::xavier_uniform_(conv->weight);
      torch::nn::init::zeros_(conv->bias);
    }
    torch::nn::init::xavier_uniform_(out->weight);
    torch::nn::init::zeros_(out->bias);
  }

  torch::Tensor forward(torch::Tensor x) {
    for (std::size_t i = 0; i < convs.size(); ++i) {
      x = torch::leaky_relu(bns[i]->forward(convs[i]->forward(x)), kLeak);
    }
    x = out->forward(x);
    return x.view({x.size(0), -1});
  }
};
TORCH_MODULE(Encoder);

struct DecoderImpl : torch::nn::Module {
  std::vector<torch::nn::Linear> linears;
  std::vector<torch::nn::BatchNorm1d> bns;

  explicit DecoderImpl(const BspConfig& c) {
    int in = c.latent_dim + c.num_classes;
    int index = 1;
    for (int w : c.decoder_widths) {
      linears.push_back(
          register_module("linear_" + std::to_string(index), torch::nn::Linear(in, w)));
      bns.push_back(register_module("bn_" + std::to_string(index), torch::nn::BatchNorm1d(w)));
      in = w;
      ++index;
    }
    linears.push_back(register_module("linear_" + std::to_string(index),
                                      torch::nn::Linear(in, 4 * c.num_planes)));
  }

  torch::Tensor forward(torch::Tensor x) {
    for (std::size_t i = 0; i + 1 < linears.size(); ++i) {
      x = torch::leaky_relu(bns[i]->forward(linears[i]->forward(x)), kLeak);
    }
    return linears.back()->forward(x);
  }
};
TORCH_MODULE(Decoder);

struct GeneratorImpl : torch::nn::Module {
  torch::Tensor convex_layer_weights;   // [P, C]
  torch::Tensor concave_layer_weights;  // [C, 1]
  explicit GeneratorImpl(const BspConfig& c) {
    convex_layer_weights = register_parameter("convex_layer_weights",
                                              torch::randn({c.num_planes, c.num_convexes}) * 0.02);
    concave_layer_weights = register_parameter("concave_layer_weights",
                                               torch::randn({c.num_convexes, 1}) * 0.02 + 1e-5);
  }
};
TORCH_MODULE(Generator);

struct BspNetImpl : torch::nn::Module {
  BspConfig config;
  Encoder encoder{nullptr};
  Decoder decoder{nullptr};
  Generator generator{nullptr};

  explicit BspNetImpl(const BspConfig& c) : config(c) {
    encoder = register_module("encoder", Encoder(c));
    decoder = register_module("decoder", Decoder(c));
    generator = register_module("generator", Generator(c));
  }

  torch::Tensor OneHot(const torch::Tensor& classes) const {
    return torch::one_hot(classes, config.num_classes).to(torch::kFloat);
  }

  // grids: [B, R, R, R] uint8 (z, y, x order = x fastest in memory); classes: [B] int64.
  torch::Tensor EncoderInput(const torch::Tensor& grids, const torch::Tensor& classes) const {
    const int64_t B = grids.size(0), R = config.resolution;
    auto occ = grids.to(torch::kFloat).unsqueeze(1);  // [B,1,R,R,R]
    auto lin = (torch::arange(R, occ.options()) * 2 + 1) / static_cast<double>(R) - 1.0;
    auto x = lin.view({1, 1, 1, 1, R}).expand({1, 1, R, R, R});
    auto y = lin.view({1, 1, 1, R, 1}).expand({1, 1, R, R, R});
    auto z = lin.view({1, 1, R, 1, 1}).expand({1, 1, R, R, R});
    auto coords = torch::cat({x, y, z}, 1) * occ;  // [B,3,R,R,R]
    auto onehot = OneHot(classes)
                      .view({B, config.num_classes, 1, 1, 1})
                      .expand({B, config.num_classes, R, R, R});
    return torch::cat({occ, coords, onehot}, 1);
  }

  // -> [B, 2*latent] = [mu, logvar]
  torch::Tensor Encode(const torch::Tensor& grids, const torch::Tensor& classes) {
    return encoder->forward(EncoderInput(grids, classes));
  }

  // z: [B, latent] -> planes [B, 4, P]
  torch::Tensor Planes(const torch::Tensor& z, const torch::Tensor& classes) {
    auto out = decoder->forward(torch::cat({z, OneHot(classes)}, 1));
    return out.view({z.size(0), 4, config.num_planes});
  }

  // points [B, N, 3] -> h1 [B, N, P]
  // `dilation` moves every plane outwards (as BspMeshOptions::dilation).
  static torch::Tensor PlaneExcess(const torch::Tensor& points, const torch::Tensor& planes,
                                   double dilation = 0.0) {
    auto ones = torch::ones({points.size(0), points.size(1), 1}, points.options());
    auto v = torch::bmm(torch::cat({points, ones}, 2), planes);
    return torch::relu(dilation > 0 ? v - dilation : v);
  }
};
TORCH_MODULE(BspNet);

torch::Tensor KlTerm(const torch::Tensor& mu, const torch::Tensor& logvar) {
  return -0.5 * torch::mean(1 + logvar - torch::exp(logvar) - mu * mu);
}

// A latent code (mu, or mu + logvar) and a class a model of config `c` can decode; `who`
// names the caller in the error.
void CheckLatent(const BspConfig& c, const Eigen::VectorXf& latent, int cad_class,
                 const char* who) {
  if (latent.size() != c.latent_dim && latent.size() != 2 * c.latent_dim) {
    throw InvalidArgument(std::string(who) + ": latent has " + std::to_string(latent.size()) +
                          " values, expected " + std::to_string(c.latent_dim) + " (mu) or " +
                          std::to_string(2 * c.latent_dim) + " (mu, logvar)");
  }
  if (cad_class < 0 || cad_class >= c.num_classes) {
    throw InvalidArgument(std::string(who) + ": class " + std::to_string(cad_class) +
                          " out of range");
  }
  if (!latent.allFinite()) throw InvalidArgument(std::string(who) + ": latent code is not finite");
}

}  // namespace

// ---------------------------------------------------------------------------------------
// BspModel
// ---------------------------------------------------------------------------------------

struct BspModel::Impl {
  BspConfig config;
  BspNet net{nullptr};
  int phase = 0;
  torch::Device device = torch::kCPU;
  explicit Impl(const BspConfig& c) : config(c), net(c) {}
};

BspModel::BspModel(const BspConfig& config, std::uint64_t seed) {
  config.Validate();
  torch::manual_seed(seed);
  impl_ = std::make_unique<Impl>(config);
  impl_->net->eval();
}
BspModel::~BspModel() = default;
BspModel::BspModel(BspModel&&) noexcept = default;
BspModel& BspModel::operator=(BspModel&&) noexcept = default;

const BspConfig& BspModel::config() const { return impl_->config; }
int BspModel::phase() const { return impl_->phase; }

std::int64_t BspModel::NumParameters() const {
  std::int64_t n = 0;
  for (const auto& p : impl_->net->parameters()) n += p.numel();
  return n;
}

void BspModel::Save(const std::string& path, bool half) const {
  SaveModelArchive(*impl_->net, path, "bsp_cvae", impl_->config.ToString(), half,
                   {{"phase", impl_->phase}});
}

BspModel BspModel::Load(const std::string& path) {
  const ModelArchiveReader archive(path, "bsp_cvae", "BSP-CVAE", {"phase"});
  BspConfig config;
  try {
    config = BspConfig::FromString(archive.config());
  } catch (const InvalidArgument& e) {
    throw ParseError(path, e.what());
  }
  BspModel model(config);
  model.impl_->phase = static_cast<int>(archive.Int("phase"));
  archive.LoadInto(*model.impl_->net);
  return model;
}

namespace {

// Stacks the grids and classes of `indices`.
std::pair<torch::Tensor, torch::Tensor> GridBatch(const BspDataset& data,
                                                  const std::vector<std::size_t>& indices) {
  const int64_t R = data.resolution;
  const int64_t cells = R * R * R;
  auto grids = torch::empty({static_cast<int64_t>(indices.size()), R, R, R}, torch::kUInt8);
  auto classes = torch::empty({static_cast<int64_t>(indices.size())}, torch::kLong);
  auto* g = grids.data_ptr<std::uint8_t>();
  auto* c = classes.data_ptr<int64_t>();
  for (std::size_t b = 0; b < indices.size(); ++b) {
    const BspSample& s = data.samples[indices[b]];
    std::copy(s.grid.begin(), s.grid.end(), g + b * cells);
    c[b] = s.cad_class;
  }
  return {grids, classes};
}

void CheckDataset(const BspDataset& data, const BspConfig& config, const std::string& what) {
  if (data.resolution != config.resolution) {
    throw InvalidArgument(what + " has resolution " + std::to_string(data.resolution) +
                          " but the model expects " + std::to_string(config.resolution));
  }
  const std::size_t cells =
      static_cast<std::size_t>(data.resolution) * data.resolution * data.resolution;
  for (std::size_t i = 0; i < data.samples.size(); ++i) {
    const auto& s = data.samples[i];
    if (s.cad_class < 0 || s.cad_class >= config.num_classes) {
      throw InvalidArgument(what + " sample " + std::to_string(i) + " has class " +
                            std::to_string(s.cad_class) + " outside [0, " +
                            std::to_string(config.num_classes) + ")");
    }
    if (s.grid.size() != cells || (!s.iou_grid.empty() && s.iou_grid.size() != cells)) {
      throw InvalidArgument(what + " sample " + std::to_string(i) + " has a wrong grid size");
    }
  }
}

// Voxel-centre coordinates of an R^3 grid, [R^3, 3], x fastest.
torch::Tensor GridCenters(int R) {
  auto lin = (torch::arange(R, torch::kFloat) * 2 + 1) / static_cast<double>(R) - 1.0;
  auto zz = lin.view({R, 1, 1}).expand({R, R, R});
  auto yy = lin.view({1, R, 1}).expand({R, R, R});
  auto xx = lin.view({1, 1, R}).expand({R, R, R});
  return torch::stack({xx, yy, zz}, 3).reshape({R * R * R, 3});
}

}  // namespace

std::pair<Eigen::VectorXf, Eigen::VectorXf> BspModel::Encode(const std::vector<std::uint8_t>& grid,
                                                             int cad_class) const {
  BspDataset one;
  one.resolution = impl_->config.resolution;
  one.samples.push_back(BspSample{cad_class, "", grid, grid, {}, {}});
  Eigen::MatrixXf all = EncodeAll(one);
  const int L = impl_->config.latent_dim;
  return {all.row(0).head(L).transpose(), all.row(0).tail(L).transpose()};
}

Eigen::MatrixXf BspModel::EncodeAll(const BspDataset& data) const {
  CheckDataset(data, impl_->config, "encoder input");
  torch::NoGradGuard no_grad;
  impl_->net->eval();
  const int D = 2 * impl_->config.latent_dim;
  Eigen::MatrixXf out(static_cast<Eigen::Index>(data.samples.size()), D);
  const std::size_t batch = 32;
  for (std::size_t start = 0; start < data.samples.size(); start += batch) {
    std::vector<std::size_t> idx;
    for (std::size_t i = start; i < std::min(start + batch, data.samples.size()); ++i) {
      idx.push_back(i);
    }
    auto [grids, classes] = GridBatch(data, idx);
    auto codes = impl_->net->Encode(grids.to(impl_->device), classes.to(impl_->device))
                     .to(torch::kCPU)
                     .contiguous();
    const float* p = codes.data_ptr<float>();
    for (std::size_t b = 0; b < idx.size(); ++b) {
      for (int d = 0; d < D; ++d) out(static_cast<Eigen::Index>(start + b), d) = p[b * D + d];
    }
  }
  return out;
}

Eigen::MatrixXf BspModel::DecodePlanes(const Eigen::VectorXf& latent, int cad_class) const {
  const auto& c = impl_->config;
  CheckLatent(c, latent, cad_class, "DecodePlanes");
  torch::NoGradGuard no_grad;
  impl_->net->eval();
  auto z = torch::from_blob(const_cast<float*>(latent.data()), {1, c.latent_dim}, torch::kFloat)
               .clone()
               .to(impl_->device);
  auto cls = torch::full({1}, cad_class, torch::kLong).to(impl_->device);
  auto planes = impl_->net->Planes(z, cls).to(torch::kCPU).contiguous();  // [1, 4, P]
  Eigen::MatrixXf out(c.num_planes, 4);
  const float* p = planes.data_ptr<float>();
  for (int k = 0; k < 4; ++k) {
    for (int i = 0; i < c.num_planes; ++i) out(i, k) = p[k * c.num_planes + i];
  }
  return out;
}

std::vector<Eigen::MatrixXf> BspModel::DecodePlanesBatch(const Eigen::MatrixXf& latents,
                                                         const std::vector<int>& classes) const {
  const auto& c = impl_->config;
  if (static_cast<std::size_t>(latents.rows()) != classes.size()) {
    throw InvalidArgument("DecodePlanesBatch: " + std::to_string(latents.rows()) + " latents but " +
                          std::to_string(classes.size()) + " classes");
  }
  if (latents.rows() > 0 && latents.cols() != c.latent_dim) {
    throw InvalidArgument("DecodePlanesBatch: latents have " + std::to_string(latents.cols()) +
                          " columns, expected " + std::to_string(c.latent_dim) + " (mu)");
  }
  for (std::size_t b = 0; b < classes.size(); ++b) {
    const Eigen::VectorXf mu = latents.row(static_cast<Eigen::Index>(b)).transpose();
    CheckLatent(c, mu, classes[b], ("DecodePlanesBatch: code " + std::to_string(b)).c_str());
  }
  std::vector<Eigen::MatrixXf> out;
  if (classes.empty()) return out;
  const int64_t B = static_cast<int64_t>(classes.size());
  torch::NoGradGuard no_grad;
  impl_->net->eval();
  const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rows = latents;
  auto z = torch::from_blob(const_cast<float*>(rows.data()), {B, c.latent_dim}, torch::kFloat)
               .clone()
               .to(impl_->device);
  std::vector<int64_t> cls64(classes.begin(), classes.end());
  auto cls = torch::tensor(cls64, torch::kLong).to(impl_->device);
  auto planes = impl_->net->Planes(z, cls).to(torch::kCPU).contiguous();  // [B, 4, P]
  const float* p = planes.data_ptr<float>();
  out.reserve(classes.size());
  for (int64_t b = 0; b < B; ++b) {
    Eigen::MatrixXf m(c.num_planes, 4);
    const float* pb = p + b * 4 * c.num_planes;
    for (int k = 0; k < 4; ++k) {
      for (int i = 0; i < c.num_planes; ++i) m(i, k) = pb[k * c.num_planes + i];
    }
    out.push_back(std::move(m));
  }
  return out;
}

std::vector<std::vector<int>> BspModel::ConvexPlanes() const {
  auto T = impl_->net->generator->convex_layer_weights.detach().to(torch::kCPU).contiguous();
  const auto& c = impl_->config;
  std::vector<std::vector<int>> out(c.num_convexes);
  const float* t = T.data_ptr<float>();
  for (int p = 0; p < c.num_planes; ++p) {
    for (int k = 0; k < c.num_convexes; ++k) {
      if (t[p * c.num_convexes + k] > kConvexThreshold) out[k].push_back(p);
    }
  }
  return out;
}

std::vector<std::uint8_t> BspModel::Occupancy(const Eigen::VectorXf& latent, int cad_class,
                                              const Eigen::MatrixX3f& points, double dilation,
                                              double distance_dilation) const {
  if (!(dilation >= 0) || !std::isfinite(dilation) || !(distance_dilation >= 0) ||
      !std::isfinite(distance_dilation)) {
    throw InvalidArgument("Occupancy: dilations must be finite and >= 0");
  }
  const auto& c = impl_->config;
  Eigen::MatrixXf planes = DecodePlanes(latent.head(c.latent_dim), cad_class);
  torch::NoGradGuard no_grad;
  auto P = torch::from_blob(planes.data(), {4, c.num_planes}, torch::kFloat);  // col-major P x 4
  // Eigen stores P x 4 column-major: memory is [4][P], i.e. exactly a row-major [4, P].
  auto planes_t = P.clone().unsqueeze(0).to(impl_->device);
  if (distance_dilation > 0) {                          // d -= distance * |(a, b, c)|
    auto normals = planes_t.slice(1, 0, 3).norm(2, 1);  // [1, P]
    planes_t.select(1, 3).sub_(normals * distance_dilation);
  }
  auto B =
      (impl_->net->generator->convex_layer_weights.detach() > kConvexThreshold).to(torch::kFloat);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(points.rows()));
  const int64_t chunk = 8192;
  Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor> rows = points;
  for (int64_t start = 0; start < points.rows(); start += chunk) {
    const int64_t n = std::min<int64_t>(chunk, points.rows() - start);
    auto pts = torch::from_blob(rows.data() + start * 3, {1, n, 3}, torch::kFloat)
                   .clone()
                   .to(impl_->device);
    auto h1 = BspNetImpl::PlaneExcess(pts, planes_t, dilation);  // [1, n, P]
    auto h2 = torch::matmul(h1, B);                              // [1, n, C]
    auto inside = (std::get<0>(h2.min(2)) < kConvexThreshold).to(torch::kCPU).contiguous();
    const bool* in = inside.data_ptr<bool>();
    for (int64_t i = 0; i < n; ++i) out[static_cast<std::size_t>(start + i)] = in[i] ? 1 : 0;
  }
  return out;
}

BspModel::Refined BspModel::RefineLatent(const Eigen::VectorXf& latent, const BspSample& sample,
                                         int steps, double lr, double prior_weight) const {
  const auto& c = impl_->config;
  CheckLatent(c, latent, sample.cad_class, "RefineLatent");
  if (steps < 0) throw InvalidArgument("RefineLatent: steps must be >= 0");
  if (!(lr > 0) || !std::isfinite(lr)) throw InvalidArgument("RefineLatent: lr must be > 0");
  if (!(prior_weight >= 0) || !std::isfinite(prior_weight)) {
    throw InvalidArgument("RefineLatent: prior_weight must be >= 0");
  }
  const std::size_t n_in = sample.inside_points.size() / 3;
  const std::size_t n_out = sample.outside_points.size() / 3;
  if (n_in == 0 || n_out == 0 || sample.inside_points.size() % 3 != 0 ||
      sample.outside_points.size() % 3 != 0) {
    throw InvalidArgument("RefineLatent: sample '" + sample.model_id +
                          "' needs inside and outside points (3 floats each)");
  }
  Eigen::VectorXf mu = latent.head(c.latent_dim);
  impl_->net->eval();
  std::vector<float> pts_v(sample.inside_points);
  pts_v.insert(pts_v.end(), sample.outside_points.begin(), sample.outside_points.end());
  std::vector<float> occ_v(n_in, 1.0f);
  occ_v.resize(n_in + n_out, 0.0f);
  const int64_t n = static_cast<int64_t>(n_in + n_out);
  auto pts = torch::from_blob(pts_v.data(), {1, n, 3}, torch::kFloat).clone().to(impl_->device);
  auto occ = torch::from_blob(occ_v.data(), {1, n, 1}, torch::kFloat).clone().to(impl_->device);
  // Balance inside and outside points as training does (half each).
  auto weight = torch::where(occ > 0.5f, torch::full_like(occ, 0.5f / static_cast<float>(n_in)),
                             torch::full_like(occ, 0.5f / static_cast<float>(n_out)));
  auto start =
      torch::from_blob(mu.data(), {1, c.latent_dim}, torch::kFloat).clone().to(impl_->device);
  auto z = start.clone().requires_grad_(true);
  auto cls = torch::full({1}, sample.cad_class, torch::kLong).to(impl_->device);
  auto B =
      (impl_->net->generator->convex_layer_weights.detach() > kConvexThreshold).to(torch::kFloat);
  auto recon_of = [&](const torch::Tensor& code) {
    auto planes = impl_->net->Planes(code, cls);
    auto h1 = BspNetImpl::PlaneExcess(pts, planes);
    auto h3 = std::get<0>(torch::matmul(h1, B).min(2, /*keepdim=*/true));
    return torch::sum(weight *
                      ((1 - occ) * (1 - torch::clamp_max(h3, 1)) + occ * torch::clamp_min(h3, 0)));
  };
  Refined r;
  {
    torch::NoGradGuard no_grad;
    r.loss_before = recon_of(start).item<double>();
  }
  torch::optim::Adam opt({z}, torch::optim::AdamOptions(lr));
  for (int step = 0; step < steps; ++step) {
    auto loss = recon_of(z) + prior_weight * torch::mean(torch::pow(z - start, 2));
    // The gradient of the code only: backward() would also compute (and accumulate into the
    // shared model) the gradients of every decoder weight.
    z.mutable_grad() = torch::autograd::grad({loss}, {z})[0];
    opt.step();
  }
  torch::NoGradGuard no_grad;
  r.loss_after = recon_of(z).item<double>();
  auto out = z.detach().to(torch::kCPU).contiguous();
  r.mu.resize(c.latent_dim);
  std::copy(out.data_ptr<float>(), out.data_ptr<float>() + c.latent_dim, r.mu.data());
  return r;
}

double BspModel::EvaluateIoU(const BspDataset& data, double dilation,
                             double distance_dilation) const {
  CheckDataset(data, impl_->config, "evaluation set");
  if (data.samples.empty()) return 0.0;
  const int R = data.resolution;
  Eigen::MatrixXf codes = EncodeAll(data);
  auto centers_t = GridCenters(R).contiguous();
  Eigen::MatrixX3f centers(R * R * R, 3);
  const float* cp = centers_t.data_ptr<float>();
  for (int i = 0; i < R * R * R; ++i) centers.row(i) << cp[3 * i], cp[3 * i + 1], cp[3 * i + 2];
  double sum = 0.0;
  for (std::size_t s = 0; s < data.samples.size(); ++s) {
    const Eigen::VectorXf mu =
        codes.row(static_cast<Eigen::Index>(s)).head(impl_->config.latent_dim);
    const auto pred =
        Occupancy(mu, data.samples[s].cad_class, centers, dilation, distance_dilation);
    const auto& sample = data.samples[s];
    const auto& target = sample.iou_grid.empty() ? sample.grid : sample.iou_grid;
    std::size_t inter = 0, uni = 0;
    for (std::size_t i = 0; i < pred.size(); ++i) {
      const bool a = pred[i] != 0, b = target[i] != 0;
      inter += a && b;
      uni += a || b;
    }
    sum += uni ? static_cast<double>(inter) / static_cast<double>(uni) : 1.0;
  }
  return sum / static_cast<double>(data.samples.size());
}

bool ReadKeptEpoch(const std::string& best_path, int* epoch, double* val_iou) {
  std::ifstream in(best_path + ".txt");
  int e = 0;
  double iou = 0;
  if (!(in >> e >> iou) || e < 1 || !std::filesystem::exists(best_path)) return false;
  *epoch = e;
  *val_iou = iou;
  return true;
}

std::vector<BspEpochLog> BspModel::Train(const BspDataset& train, const BspDataset& val,
                                         const BspTrainOptions& opt,
                                         const std::function<void(const BspEpochLog&)>& log) {
  CheckDataset(train, impl_->config, "training set");
  if (!val.samples.empty()) CheckDataset(val, impl_->config, "validation set");
  if (train.samples.empty()) throw InvalidArgument("training set is empty");
  if (!(opt.loss_dilation >= 0) || !std::isfinite(opt.loss_dilation)) {
    throw InvalidArgument("BspTrainOptions: loss_dilation must be finite and >= 0");
  }
  if (!(opt.val_dilation >= 0) || !std::isfinite(opt.val_dilation) ||
      !(opt.val_distance_dilation >= 0) || !std::isfinite(opt.val_distance_dilation)) {
    throw InvalidArgument(
        "BspTrainOptions: val_dilation and val_distance_dilation must be finite and >= 0");
  }
  if (opt.batch_size < 1 || opt.points_per_sample < 2) {
    throw InvalidArgument("BspTrainOptions: batch_size >= 1 and points_per_sample >= 2 required");
  }
  const bool distill = opt.latent_targets.size() > 0;
  if (distill) {
    if (opt.latent_targets.rows() != static_cast<Eigen::Index>(train.samples.size()) ||
        opt.latent_targets.cols() != impl_->config.latent_dim) {
      throw InvalidArgument(
          "BspTrainOptions: latent_targets is " + std::to_string(opt.latent_targets.rows()) +
          " x " + std::to_string(opt.latent_targets.cols()) + ", expected " +
          std::to_string(train.samples.size()) + " x " + std::to_string(impl_->config.latent_dim) +
          " (one mu per training sample)");
    }
    if (!opt.latent_targets.allFinite()) {
      throw InvalidArgument("BspTrainOptions: latent_targets are not all finite");
    }
    if (!(opt.latent_target_weight > 0) || !std::isfinite(opt.latent_target_weight)) {
      throw InvalidArgument("BspTrainOptions: latent_target_weight must be finite and > 0");
    }
  }
  if (!(opt.recon_weight >= 0) || !std::isfinite(opt.recon_weight)) {
    throw InvalidArgument("BspTrainOptions: recon_weight must be finite and >= 0");
  }
  const bool decode = opt.recon_weight > 0;
  if (!decode && !(distill && opt.freeze_decoder)) {
    throw InvalidArgument(
        "BspTrainOptions: recon_weight 0 needs latent targets and a frozen decoder (nothing "
        "else would train)");
  }
  for (std::size_t i = 0; i < train.samples.size(); ++i) {
    if (train.samples[i].inside_points.empty() || train.samples[i].outside_points.empty()) {
      throw InvalidArgument("training sample " + std::to_string(i) + " (" +
                            train.samples[i].model_id + ") has no inside or no outside points");
    }
  }
  if (opt.threads > 0) torch::set_num_threads(opt.threads);
  if (opt.device == "cuda") {
    if (!torch::cuda::is_available())
      throw InvalidArgument("device 'cuda' requested but not available");
    impl_->device = torch::Device(torch::kCUDA);
  } else if (opt.device != "cpu") {
    throw InvalidArgument("unknown device '" + opt.device + "' (cpu or cuda)");
  }
  auto& net = impl_->net;
  net->to(impl_->device);

  // Phase boundaries (epochs); phase 0 may end early on its time budget (phase0_minutes).
  int phase0_end = opt.epochs_phase0;
  int total_epochs = opt.epochs_phase0 + opt.epochs_phase1 + opt.epochs_phase2;
  int start_epoch = 0;
  // With a frozen decoder only the encoder's parameters are optimised; the frozen ones do not
  // track gradients (the code still gets its gradient through them).
  std::vector<torch::Tensor> frozen;
  if (opt.freeze_decoder) {
    for (auto& p : net->decoder->parameters()) frozen.push_back(p);
    for (auto& p : net->generator->parameters()) frozen.push_back(p);
  }
  for (auto& p : frozen) p.set_requires_grad(false);
  struct Unfreeze {
    std::vector<torch::Tensor>& params;
    ~Unfreeze() {
      for (auto& p : params) p.set_requires_grad(true);
    }
  } unfreeze{frozen};
  torch::optim::Adam optimizer(opt.freeze_decoder ? net->encoder->parameters() : net->parameters(),
                               torch::optim::AdamOptions(opt.learning_rate));
  const std::vector<int64_t> resumed =
      opt.resume ? ResumeTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "bsp_cvae",
                                            "BSP-CVAE", impl_->config.ToString(), 2)
                 : std::vector<int64_t>{};
  if (!resumed.empty()) {
    start_epoch = static_cast<int>(resumed[0]);
    const int saved_phase0_end = static_cast<int>(resumed[1]);
    if (saved_phase0_end >= 0 && saved_phase0_end < phase0_end) {
      total_epochs -= phase0_end - saved_phase0_end;
      phase0_end = saved_phase0_end;
    }
    std::fprintf(stderr, "resuming from %s at epoch %d\n", opt.checkpoint_path.c_str(),
                 start_epoch);
  }

  std::mt19937_64 rng(opt.seed);
  for (int skip = 0; skip < start_epoch; ++skip) rng.discard(1000003);
  const int N = opt.points_per_sample;
  const int half = N / 2;
  torch::Tensor targets_all;  // [samples, latent] on the training device
  if (distill) {
    Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> rows = opt.latent_targets;
    targets_all = torch::from_blob(rows.data(), {rows.rows(), rows.cols()}, torch::kFloat)
                      .clone()
                      .to(impl_->device);
  }
  std::vector<BspEpochLog> logs;
  double best_val_iou = 0.0;  // val_iou is -1 when not evaluated
  if (!opt.best_path.empty()) {
    int kept_epoch = 0;
    if (resumed.empty() || !ReadKeptEpoch(opt.best_path, &kept_epoch, &best_val_iou)) {
      best_val_iou = 0.0;
      std::filesystem::remove(opt.best_path);  // a kept model of an earlier run is no candidate
      std::filesystem::remove(opt.best_path + ".txt");
    }
  }
  const Stopwatch run_time;
  auto checkpoint = [&](int epoch_done) {
    if (opt.checkpoint_path.empty()) return;
    SaveTrainingCheckpoint(*net, optimizer, opt.checkpoint_path, "bsp_cvae",
                           impl_->config.ToString(), {epoch_done, phase0_end},
                           {{"phase", impl_->phase}});
  };

  for (int epoch = start_epoch; epoch < total_epochs; ++epoch) {
    if (opt.phase0_minutes > 0 && epoch < phase0_end &&
        run_time.ElapsedSeconds() / 60.0 >= opt.phase0_minutes) {
      std::fprintf(stderr, "phase 0 time budget reached after %d epochs\n", epoch);
      total_epochs -= phase0_end - epoch;
      phase0_end = epoch;
    }
    const int phase = epoch < phase0_end ? 0 : (epoch < phase0_end + opt.epochs_phase1 ? 1 : 2);
    impl_->phase = phase;
    const double lr = opt.learning_rate * std::pow(0.5, epoch / std::max(1, opt.lr_step_epochs));
    for (auto& group : optimizer.param_groups()) {
      static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
    }
    const int warmup = opt.kl_warmup_epochs < 0 ? total_epochs : opt.kl_warmup_epochs;
    const double beta =
        warmup == 0 ? opt.kl_weight
                    : opt.kl_weight * std::min(1.0, static_cast<double>(epoch + 1) / warmup);
    net->train();
    if (opt.freeze_decoder) net->decoder->eval();  // BatchNorm as at inference, stats frozen
    std::vector<std::size_t> order(train.samples.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    double recon_sum = 0, kl_sum = 0, latent_sum = 0;
    int batches = 0;
    const Stopwatch epoch_time;
    for (std::size_t start = 0; start < order.size(); start += opt.batch_size) {
      std::vector<std::size_t> idx(order.begin() + start,
                                   order.begin() + std::min(order.size(), start + opt.batch_size));
      if (idx.size() < 2 && order.size() >= 2) continue;  // BatchNorm needs >= 2 samples
      const int64_t Bn = static_cast<int64_t>(idx.size());
      auto [grids, classes] = GridBatch(train, idx);
      const int64_t Np = decode ? N : 0;  // no query points when only regressing codes
      auto pts = torch::empty({Bn, Np, 3}, torch::kFloat);
      auto occ = torch::empty({Bn, Np, 1}, torch::kFloat);
      float* pp = pts.data_ptr<float>();
      float* op = occ.data_ptr<float>();
      for (int64_t b = 0; decode && b < Bn; ++b) {
        const BspSample& s = train.samples[idx[b]];
        const std::size_t n_in = s.inside_points.size() / 3, n_out = s.outside_points.size() / 3;
        for (int i = 0; i < N; ++i) {
          const bool inside = i < half;
          const auto& src = inside ? s.inside_points : s.outside_points;
          const std::size_t k = rng() % (inside ? n_in : n_out);
          for (int d = 0; d < 3; ++d) pp[(b * N + i) * 3 + d] = src[3 * k + d];
          op[b * N + i] = inside ? 1.0f : 0.0f;
        }
      }
      grids = grids.to(impl_->device);
      classes = classes.to(impl_->device);
      pts = pts.to(impl_->device);
      occ = occ.to(impl_->device);

      auto code = net->Encode(grids, classes);
      const int L = impl_->config.latent_dim;
      auto mu = code.slice(1, 0, L);
      auto logvar = code.slice(1, L, 2 * L);
      auto kl = KlTerm(mu, logvar);
      torch::Tensor latent_mse = torch::zeros({}, mu.options());
      if (distill) {
        std::vector<int64_t> rows(idx.begin(), idx.end());
        auto target =
            targets_all.index_select(0, torch::tensor(rows, torch::kLong).to(impl_->device));
        latent_mse = torch::mean(torch::pow(mu - target, 2));
      }
      // Without decoding (recon_weight 0) the encoder regresses the latent targets only.
      torch::Tensor recon = torch::zeros({}, mu.options());
      torch::Tensor reg = torch::zeros({}, mu.options());
      if (decode) {
        auto z = opt.sample_latent ? mu + torch::randn_like(mu) * torch::exp(0.5 * logvar) : mu;
        auto planes = net->Planes(z, classes);
        auto h1 = BspNetImpl::PlaneExcess(pts, planes, opt.loss_dilation);
        auto T = net->generator->convex_layer_weights;
        auto W = net->generator->concave_layer_weights;
        if (phase == 0) {
          auto h2 = torch::clamp(1 - torch::matmul(h1, T), 0, 1);
          auto h3 = torch::clamp(torch::matmul(h2, W), 0, 1);
          recon = torch::mean(torch::pow(occ - h3, 2));
          // Weight regularisers of the continuous phase (sums, as the reference).
          reg = torch::sum(torch::abs(W - 1)) + torch::sum(torch::relu(T - 1) + torch::relu(-T));
        } else {
          auto Bm = (T.detach() > kConvexThreshold).to(torch::kFloat);
          auto h2 = torch::matmul(h1, Bm);
          auto h3 = std::get<0>(h2.min(2, /*keepdim=*/true));
          recon = torch::mean((1 - occ) * (1 - torch::clamp_max(h3, 1)) +
                              occ * torch::clamp_min(h3, 0));
          if (phase == 2) {
            auto inside_c = (h2 < kConvexThreshold).to(torch::kFloat);
            auto multi = (inside_c.sum(2, true) > 1).to(torch::kFloat);
            recon = recon - torch::mean(h2 * occ * inside_c * multi);
          }
        }
      }
      auto loss = opt.recon_weight * recon + reg + beta * kl;
      if (distill) loss = loss + opt.latent_target_weight * latent_mse;
      optimizer.zero_grad();
      loss.backward();
      optimizer.step();
      recon_sum += recon.item<double>();
      kl_sum += kl.item<double>();
      latent_sum += latent_mse.item<double>();
      ++batches;
    }
    BspEpochLog entry;
    entry.epoch = epoch + 1;
    entry.phase = phase;
    entry.recon_loss = batches ? recon_sum / batches : 0;
    entry.kl = batches ? kl_sum / batches : 0;
    entry.latent_mse = batches ? latent_sum / batches : 0;
    entry.beta = beta;
    entry.seconds = epoch_time.ElapsedSeconds();
    net->eval();
    const bool last = epoch + 1 == total_epochs;
    const double minutes = run_time.ElapsedSeconds() / 60.0;
    const bool out_of_time = opt.max_minutes > 0 && minutes > opt.max_minutes;
    if (!val.samples.empty() &&
        ((epoch + 1) % std::max(1, opt.checkpoint_every) == 0 || last || out_of_time)) {
      if (phase > 0) entry.val_iou = EvaluateIoU(val, opt.val_dilation, opt.val_distance_dilation);
    }
    if (!opt.best_path.empty() && entry.val_iou > best_val_iou) {
      best_val_iou = entry.val_iou;
      Save(opt.best_path, /*half=*/false);
      std::ofstream record(opt.best_path + ".txt");
      record << entry.epoch << " " << entry.val_iou << "\n";
      if (!record) throw Error(opt.best_path + ".txt: cannot write the kept-epoch record");
    }
    logs.push_back(entry);
    if (log) log(entry);
    if ((epoch + 1) % std::max(1, opt.checkpoint_every) == 0 || last || out_of_time) {
      checkpoint(epoch + 1);
    }
    if (out_of_time) {
      std::fprintf(stderr, "stopping after %.1f minutes (max_minutes)\n", minutes);
      break;
    }
  }
  net->eval();
  return logs;
}

}  // namespace dimr::nn
