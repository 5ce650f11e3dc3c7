#include "dimr/pipeline/bsp_decoder.h"

#include <cmath>
#include <mutex>
#include <string>
#include <utility>

#include "dimr/core/error.h"
#include "dimr/nn/bsp_model.h"
#include "dimr/pipeline/bsp_data.h"
#include "dimr/pipeline/model_card.h"

namespace dimr::pipeline {
namespace {

float CardDilation(const std::optional<ModelCard>& card, const char* key, float requested) {
  if (requested >= 0.0f) return requested;
  if (!card) return 0.0f;
  const double d = card->GetDouble(key, 0.0);
  if (d < 0.0) {
    throw ParseError(card->path(),
                     std::string(key) + " must be a number >= 0, got " + card->GetString(key));
  }
  return static_cast<float>(d);
}

}  // namespace

BspMeshOptions BspDecodingOptions(const std::string& model_path,
                                  const BspDilationRequest& request) {
  std::optional<ModelCard> card;
  if (request.plane < 0.0f || request.distance < 0.0f) card = ModelCard::LoadIfExists(model_path);
  BspMeshOptions options;
  options.dilation = CardDilation(card, "recommended_dilation", request.plane);
  options.distance_dilation = CardDilation(card, "recommended_distance_dilation", request.distance);
  return options;
}

struct BspDecoder::Impl {
  explicit Impl(nn::BspModel m) : model(std::move(m)) {}
  nn::BspModel model;
  std::string path;
  BspMeshOptions options;
  std::vector<std::vector<int>> convexes;
  mutable std::mutex net_mutex;  // BspModel's const calls switch the modules to eval mode
};

BspDecoder::BspDecoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BspDecoder::~BspDecoder() = default;
BspDecoder::BspDecoder(BspDecoder&&) noexcept = default;
BspDecoder& BspDecoder::operator=(BspDecoder&&) noexcept = default;

BspDecoder BspDecoder::Load(const std::string& model_path, const BspDilationRequest& request) {
  // The card first: a malformed card fails before the (slower) weights are read.
  const BspMeshOptions options = BspDecodingOptions(model_path, request);
  auto impl = std::make_unique<Impl>(nn::BspModel::Load(model_path));
  impl->path = model_path;
  impl->options = options;
  impl->convexes = impl->model.ConvexPlanes();
  return BspDecoder(std::move(impl));
}

int BspDecoder::latent_dim() const { return impl_->model.config().latent_dim; }
int BspDecoder::num_classes() const { return impl_->model.config().num_classes; }
int BspDecoder::resolution() const { return impl_->model.config().resolution; }
const std::string& BspDecoder::model_path() const { return impl_->path; }
const BspMeshOptions& BspDecoder::mesh_options() const { return impl_->options; }
const std::vector<std::vector<int>>& BspDecoder::convex_planes() const { return impl_->convexes; }
const nn::BspModel& BspDecoder::model() const { return impl_->model; }

Eigen::VectorXf BspDecoder::MuOf(const Eigen::VectorXf& code, int cad_class,
                                 const char* what) const {
  const int L = latent_dim();
  if (code.size() != L && code.size() != 2 * L) {
    throw InvalidArgument(std::string("BspDecoder::") + what + ": code has " +
                          std::to_string(code.size()) + " values, expected " + std::to_string(L) +
                          " (mu) or " + std::to_string(2 * L) + " ([mu, logvar]) for model " +
                          impl_->path);
  }
  if (cad_class < 0 || cad_class >= num_classes()) {
    throw InvalidArgument(std::string("BspDecoder::") + what + ": CAD class " +
                          std::to_string(cad_class) + " outside [0, " +
                          std::to_string(num_classes()) + ")");
  }
  const Eigen::VectorXf mu = code.head(L);
  if (!mu.allFinite()) {
    throw InvalidArgument(std::string("BspDecoder::") + what + ": code is not finite");
  }
  return mu;
}

Eigen::MatrixXf BspDecoder::Planes(const Eigen::VectorXf& code, int cad_class) const {
  const Eigen::VectorXf mu = MuOf(code, cad_class, "Planes");
  std::lock_guard<std::mutex> lock(impl_->net_mutex);
  return impl_->model.DecodePlanes(mu, cad_class);
}

std::vector<Eigen::MatrixXf> BspDecoder::PlanesBatch(const std::vector<Eigen::VectorXf>& codes,
                                                     const std::vector<int>& cad_classes) const {
  if (codes.size() != cad_classes.size()) {
    throw InvalidArgument("BspDecoder::PlanesBatch: " + std::to_string(codes.size()) +
                          " codes but " + std::to_string(cad_classes.size()) + " classes");
  }
  Eigen::MatrixXf mu(static_cast<Eigen::Index>(codes.size()), latent_dim());
  for (std::size_t b = 0; b < codes.size(); ++b) {
    const std::string what = "PlanesBatch (code " + std::to_string(b) + ")";
    mu.row(static_cast<Eigen::Index>(b)) = MuOf(codes[b], cad_classes[b], what.c_str()).transpose();
  }
  if (codes.empty()) return {};
  std::lock_guard<std::mutex> lock(impl_->net_mutex);
  return impl_->model.DecodePlanesBatch(mu, cad_classes);
}

BspMeshResult BspDecoder::MeshFromPlanes(const Eigen::MatrixXf& planes) const {
  return ExtractBspMesh(planes, impl_->convexes, impl_->options);
}

std::vector<std::uint8_t> BspDecoder::OccupancyFromPlanes(const Eigen::MatrixXf& planes,
                                                          const Eigen::MatrixX3f& points) const {
  return BspOccupancy(planes, impl_->convexes, points, impl_->options);
}

BspMeshResult BspDecoder::Decode(const Eigen::VectorXf& code, int cad_class) const {
  return MeshFromPlanes(Planes(code, cad_class));
}

geometry::TriangleMesh BspDecoder::Mesh(const Eigen::VectorXf& code, int cad_class) const {
  return Decode(code, cad_class).mesh;
}

std::vector<std::uint8_t> BspDecoder::Occupancy(const Eigen::VectorXf& code, int cad_class,
                                                const Eigen::MatrixX3f& points) const {
  if (!points.allFinite()) throw InvalidArgument("BspDecoder::Occupancy: non-finite points");
  return OccupancyFromPlanes(Planes(code, cad_class), points);
}

Eigen::VectorXf BspDecoder::Encode(const std::vector<std::uint8_t>& grid, int cad_class) const {
  const int L = latent_dim();
  if (cad_class < 0 || cad_class >= num_classes()) {
    throw InvalidArgument("BspDecoder::Encode: CAD class " + std::to_string(cad_class) +
                          " outside [0, " + std::to_string(num_classes()) + ")");
  }
  std::pair<Eigen::VectorXf, Eigen::VectorXf> ml;
  {
    std::lock_guard<std::mutex> lock(impl_->net_mutex);
    ml = impl_->model.Encode(grid, cad_class);
  }
  Eigen::VectorXf code(2 * L);
  code << ml.first, ml.second;
  return code;
}

Eigen::VectorXf BspDecoder::EncodeSample(const nn::BspSample& sample, int refine_steps,
                                         double refine_lr) const {
  Eigen::VectorXf code = Encode(sample.grid, sample.cad_class);
  if (refine_steps > 0) {
    std::lock_guard<std::mutex> lock(impl_->net_mutex);
    code.head(latent_dim()) = impl_->model.RefineLatent(code, sample, refine_steps, refine_lr).mu;
  }
  return code;
}

Eigen::VectorXf BspDecoder::EncodeMesh(const geometry::TriangleMesh& mesh, int cad_class,
                                       const BspEncodeOptions& options) const {
  if (cad_class < 0 || cad_class >= num_classes()) {
    throw InvalidArgument("BspDecoder::EncodeMesh: CAD class " + std::to_string(cad_class) +
                          " outside [0, " + std::to_string(num_classes()) + ")");
  }
  BspSampleOptions sample_options;
  sample_options.resolution = resolution();
  const nn::BspSample sample =
      MakeBspSample(mesh, cad_class, "mesh", sample_options, options.sample_seed);
  return EncodeSample(sample, options.refine_steps, options.refine_lr);
}

}  // namespace dimr::pipeline
