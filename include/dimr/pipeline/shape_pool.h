// The latent CAD pool: (mu, log-variance) codes of every CAD model of a tree, with class and
// model id (`dimr encode-pool`). Answers k-nearest-neighbour queries per class on mu
// (retrieval) and projects a code onto the affine hull of its k nearest pool codes (the
// paper's projection; dimr-method.md section 9: k = 1 returns the nearest code, k >= 2 the
// least-squares projection x0 + A (A^T A)^+ A^T (z - x0) with A = [x1 - x0, ...], in the full
// [mu, logvar] space). LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace dimr::pipeline {

struct PoolEntry {
  std::string model_id;
  int cad_class = 0;
  Eigen::VectorXf code;  // [mu, logvar], 2 * latent_dim
  // Where the entry's CAD mesh is (retrieval): a mesh file (.obj in ShapeNet axes, y up,
  // -z forward, as model_normalized.obj; or .ply/.obj in canonical axes when it ends in
  // ".canonical.ply"); empty = unknown. Relative paths in a pool file are resolved against the
  // file's folder on Load. Not part of ContentHash (the codes are).
  std::string mesh_path = "";
};

struct PoolMatch {
  int index = -1;         // into ShapePool::entries()
  double distance = 0.0;  // Euclidean distance on mu
};

struct Projection {
  Eigen::VectorXf code;         // projected [mu, logvar]
  std::vector<int> neighbors;   // the k pool entries used (nearest first)
  std::vector<double> weights;  // affine weights of the neighbours (sum to 1)
  double residual = 0.0;        // distance from the input code to the projection
};

class ShapePool {
 public:
  ShapePool() = default;
  explicit ShapePool(int latent_dim) : latent_dim_(latent_dim) {}

  int latent_dim() const { return latent_dim_; }
  std::size_t size() const { return entries_.size(); }
  const std::vector<PoolEntry>& entries() const { return entries_; }
  // Throws dimr::InvalidArgument on a wrong code size, non-finite values or a duplicate id.
  void Add(PoolEntry entry);
  // 64-bit content hash (FNV-1a over ids, classes and code bytes), hex.
  std::string ContentHash() const;

  // k nearest entries of class `cad_class` to `mu` (first latent_dim values of `code` if a
  // full code is passed), nearest first. Fewer if the class has fewer entries.
  std::vector<PoolMatch> Nearest(const Eigen::VectorXf& code, int cad_class, int k) const;
  // Projection onto the affine hull of the k nearest codes of the class. Throws if the class
  // has no entries.
  Projection Project(const Eigen::VectorXf& code, int cad_class, int k) const;

  // Fills mesh_path of every entry whose `<root>/<synset>/<model_id>/models/model_normalized.obj`
  // exists (any synset folder of the ShapeNet-style tree `root`). Returns how many entries got
  // a path. Throws dimr::InvalidArgument if `root` is not a folder.
  int AttachMeshTree(const std::string& root);
  // Sets one entry's mesh path (index into entries()).
  void SetMeshPath(std::size_t index, const std::string& path);
  // Number of entries with a mesh path.
  int NumWithMeshes() const;

  // Binary file with magic, version, latent size and the content hash (verified on load).
  // Version 1 (no mesh paths) is written when no entry has a mesh path, version 2 (a path per
  // entry) otherwise; both load.
  void Save(const std::string& path) const;
  static ShapePool Load(const std::string& path);

 private:
  int latent_dim_ = 0;
  std::vector<PoolEntry> entries_;
};

// Linear interpolation between two codes (t in [0, 1]).
Eigen::VectorXf InterpolateCodes(const Eigen::VectorXf& a, const Eigen::VectorXf& b, double t);
// A sample mu + eps * exp(0.5 * logvar) of a full code, seeded.
Eigen::VectorXf SampleCode(const Eigen::VectorXf& code, std::uint64_t seed);

}  // namespace dimr::pipeline
