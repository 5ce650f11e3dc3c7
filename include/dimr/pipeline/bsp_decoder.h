// The BSP shape decoder of the pipeline: a trained BSP-CVAE (nn::BspModel) plus the decoding
// settings of its model card, behind one object. Latent code + CAD class in, canonical mesh
// or occupancy out; CAD mesh in, code out.
//
// Canonical object frame (the frame of every mesh, point and code here): the frame of a CAD
// model in the procedural library (data/cad_library.h) and of a ShapeNet model read by
// data::ReadShapeNetModel: x forward (the side a person faces / uses), y left, z up, origin at
// the centre of the object's bounding box. The BSP networks work in a box-normalised copy of it
// (pipeline::NormalizeForBsp, bsp_data.h): each axis is scaled on its own so that the bounding
// box becomes [-s, s]^3 with s = 1 - 1/R (R = the encoder grid, 32: s = 0.96875); a CAD model's
// unit box [-0.5, 0.5]^3 maps by p -> 2 s p. Decoded meshes lie inside [-1, 1]^3 (polytopes
// are clipped to it) and fill [-s, s] on every axis up to the decoder's error. The object's real
// proportions are not in the code: placing a mesh in a scene scales it by the object's box (stage
// 2) again.
//
// Decoding = planes (decoder network) -> the card's dilations (recommended_dilation,
// recommended_distance_dilation) -> occupancy / exact convex polytopes (pipeline::
// ExtractBspMesh). A code is mu (latent_dim values) or [mu, logvar] (2 * latent_dim, as the
// pool and stage 2 store it); decoding uses mu.
//
// Thread safety: every const member may be called from several threads at once on one
// decoder; the network calls (Planes, Encode*) are serialised by an internal mutex (LibTorch's
// own threads run inside them), mesh extraction and occupancy run concurrently.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"
#include "dimr/pipeline/bsp_mesher.h"

namespace dimr::nn {
class BspModel;
struct BspSample;
}  // namespace dimr::nn

namespace dimr::pipeline {

// Dilations asked for by a caller (a command's --dilation / --distance-dilation); a negative
// value means "the model card's recommended value, else 0 (the reference)".
struct BspDilationRequest {
  float plane = -1.0f;     // BspMeshOptions::dilation (plane units)
  float distance = -1.0f;  // BspMeshOptions::distance_dilation (Euclidean, normalised cube)
};

// The mesh options of a model: each requested dilation when >= 0, else the card's
// `recommended_dilation:` / `recommended_distance_dilation:` (model.yaml beside the weights),
// else 0. Throws dimr::ParseError naming the card for a malformed card or a value that is not
// a number >= 0.
BspMeshOptions BspDecodingOptions(const std::string& model_path,
                                  const BspDilationRequest& request = BspDilationRequest());

// Encoding of a CAD mesh (EncodeMesh).
struct BspEncodeOptions {
  // Latent refinement (nn::BspModel::RefineLatent) of mu on the shape's own inside/outside
  // points, as `dimr encode-pool --refine-steps` (the shipped pool: 30 steps, lr 0.01).
  int refine_steps = 0;
  double refine_lr = 0.01;
  std::uint64_t sample_seed = 1;  // seed of the query points refinement uses
};

class BspDecoder {
 public:
  // Weights saved by `dimr train bsp` and the card beside them (a model without a card decodes
  // with the reference settings). Throws dimr::ParseError naming the file for missing, truncated
  // or corrupt weights and for a malformed card.
  static BspDecoder Load(const std::string& model_path,
                         const BspDilationRequest& request = BspDilationRequest());
  ~BspDecoder();
  BspDecoder(BspDecoder&&) noexcept;
  BspDecoder& operator=(BspDecoder&&) noexcept;

  int latent_dim() const;
  int num_classes() const;
  int resolution() const;  // encoder grid R
  const std::string& model_path() const;
  // The decoding settings (the card's dilations, or the request's).
  const BspMeshOptions& mesh_options() const;
  // Per convex, the planes it uses (fixed for a model).
  const std::vector<std::vector<int>>& convex_planes() const;
  // The network itself, for batched encoding, training-set evaluation and refinement (include
  // dimr/nn/bsp_model.h to use it; not synchronised with the calls below).
  const nn::BspModel& model() const;

  // P x 4 decoded planes (a, b, c, d; inside iff a x + b y + c z + d <= 0) of a code. Throws
  // dimr::InvalidArgument for a code of another size than latent_dim or 2 * latent_dim, a
  // non-finite code or a class outside [0, num_classes).
  Eigen::MatrixXf Planes(const Eigen::VectorXf& code, int cad_class) const;
  // Planes of many codes in one network call (one lock, LibTorch's threads on one batched
  // product): entry b is Planes(codes[b], cad_classes[b]) up to float rounding (the batched
  // product may sum in another order), and the same batch always gives the same planes. Throws
  // as Planes, naming the code's index, or for sizes that differ.
  std::vector<Eigen::MatrixXf> PlanesBatch(const std::vector<Eigen::VectorXf>& codes,
                                           const std::vector<int>& cad_classes) const;
  // The mesh of the code: closed convex polytopes (concatenated, possibly overlapping) in the
  // normalised canonical frame, inside [-1, 1]^3; empty when the code decodes to nothing.
  geometry::TriangleMesh Mesh(const Eigen::VectorXf& code, int cad_class) const;
  // The same with the kept convexes and the convex of every triangle.
  BspMeshResult Decode(const Eigen::VectorXf& code, int cad_class) const;
  // Inside (1) / outside (0) of points (N x 3, normalised canonical frame) under the same
  // decoding as Mesh.
  std::vector<std::uint8_t> Occupancy(const Eigen::VectorXf& code, int cad_class,
                                      const Eigen::MatrixX3f& points) const;
  // Mesh / occupancy from planes already decoded (one Planes call for both).
  BspMeshResult MeshFromPlanes(const Eigen::MatrixXf& planes) const;
  std::vector<std::uint8_t> OccupancyFromPlanes(const Eigen::MatrixXf& planes,
                                                const Eigen::MatrixX3f& points) const;

  // [mu, logvar] (2 * latent_dim) of an occupancy grid (resolution^3 cells, x fastest).
  Eigen::VectorXf Encode(const std::vector<std::uint8_t>& grid, int cad_class) const;
  // [mu, logvar] of a training sample, mu refined on its points when refine_steps > 0.
  Eigen::VectorXf EncodeSample(const nn::BspSample& sample, int refine_steps = 0,
                               double refine_lr = 0.01) const;
  // [mu, logvar] of a CAD mesh in the canonical frame (any scale: it is box-normalised first,
  // as `dimr bsp prepare` / `dimr encode-pool` do through pipeline::MakeBspSample). For a
  // ShapeNet-format model_normalized.obj: EncodeMesh(data::ReadShapeNetModel(path, synset).mesh,
  // class). Throws dimr::InvalidArgument for an empty or flat mesh or a bad class.
  Eigen::VectorXf EncodeMesh(const geometry::TriangleMesh& mesh, int cad_class,
                             const BspEncodeOptions& options = BspEncodeOptions()) const;

 private:
  struct Impl;
  explicit BspDecoder(std::unique_ptr<Impl> impl);
  Eigen::VectorXf MuOf(const Eigen::VectorXf& code, int cad_class, const char* what) const;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dimr::pipeline
