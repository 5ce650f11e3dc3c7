#include "dimr/pipeline/shape_pool.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <set>
#include <string>

#include "dimr/core/binary_io.h"
#include "dimr/core/error.h"
#include "dimr/core/hash.h"

namespace dimr::pipeline {
namespace {

constexpr char kMagic[8] = {'D', 'I', 'M', 'R', 'P', 'O', 'O', 'L'};
constexpr std::uint32_t kVersion = 1;        // codes only
constexpr std::uint32_t kVersionMeshes = 2;  // codes + a mesh path per entry
constexpr std::uint32_t kMaxMeshPathLength = 4096;

}  // namespace

void ShapePool::Add(PoolEntry entry) {
  if (latent_dim_ <= 0) throw InvalidArgument("ShapePool: latent_dim not set");
  if (entry.code.size() != 2 * latent_dim_) {
    throw InvalidArgument("ShapePool: code of '" + entry.model_id + "' has " +
                          std::to_string(entry.code.size()) + " values, expected " +
                          std::to_string(2 * latent_dim_));
  }
  if (!entry.code.allFinite()) {
    throw InvalidArgument("ShapePool: code of '" + entry.model_id + "' is not finite");
  }
  for (const auto& e : entries_) {
    if (e.model_id == entry.model_id) {
      throw InvalidArgument("ShapePool: duplicate model id '" + entry.model_id + "'");
    }
  }
  entries_.push_back(std::move(entry));
}

std::string ShapePool::ContentHash() const {
  std::uint64_t h = Fnv1a(&latent_dim_, sizeof(latent_dim_));
  for (const auto& e : entries_) {
    h = Fnv1a(e.model_id, h);
    h = Fnv1a(&e.cad_class, sizeof(e.cad_class), h);
    h = Fnv1a(e.code.data(), static_cast<std::size_t>(e.code.size()) * sizeof(float), h);
  }
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

std::vector<PoolMatch> ShapePool::Nearest(const Eigen::VectorXf& code, int cad_class, int k) const {
  if (code.size() != latent_dim_ && code.size() != 2 * latent_dim_) {
    throw InvalidArgument("ShapePool::Nearest: query has " + std::to_string(code.size()) +
                          " values, expected " + std::to_string(latent_dim_) + " or " +
                          std::to_string(2 * latent_dim_));
  }
  const Eigen::VectorXf mu = code.head(latent_dim_);
  std::vector<PoolMatch> all;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (entries_[i].cad_class != cad_class) continue;
    all.push_back({static_cast<int>(i), (entries_[i].code.head(latent_dim_) - mu).norm()});
  }
  const std::size_t kk = std::min<std::size_t>(std::max(k, 0), all.size());
  std::partial_sort(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(kk), all.end(),
                    [](const PoolMatch& a, const PoolMatch& b) {
                      return a.distance != b.distance ? a.distance < b.distance : a.index < b.index;
                    });
  all.resize(kk);
  return all;
}

Projection ShapePool::Project(const Eigen::VectorXf& code, int cad_class, int k) const {
  if (code.size() != 2 * latent_dim_) {
    throw InvalidArgument("ShapePool::Project: code must have " + std::to_string(2 * latent_dim_) +
                          " values, got " + std::to_string(code.size()));
  }
  if (k < 1) throw InvalidArgument("ShapePool::Project: k must be >= 1");
  const auto nn = Nearest(code, cad_class, k);
  if (nn.empty()) {
    throw InvalidArgument("ShapePool::Project: the pool has no entry of class " +
                          std::to_string(cad_class));
  }
  Projection out;
  for (const auto& m : nn) out.neighbors.push_back(m.index);
  const Eigen::VectorXf x0 = entries_[nn[0].index].code;
  if (nn.size() == 1) {
    out.code = x0;
    out.weights = {1.0};
  } else {
    const Eigen::Index m = static_cast<Eigen::Index>(nn.size()) - 1;
    Eigen::MatrixXd A(code.size(), m);
    for (Eigen::Index j = 0; j < m; ++j) {
      A.col(j) = (entries_[nn[j + 1].index].code - x0).cast<double>();
    }
    const Eigen::VectorXd rhs = (code - x0).cast<double>();
    // Least squares with rank detection: duplicate / collinear neighbours are handled.
    const Eigen::VectorXd w = A.completeOrthogonalDecomposition().solve(rhs);
    out.code = (x0.cast<double>() + A * w).cast<float>();
    out.weights.assign(nn.size(), 0.0);
    out.weights[0] = 1.0 - w.sum();
    for (Eigen::Index j = 0; j < m; ++j) out.weights[j + 1] = w[j];
  }
  out.residual = (code - out.code).norm();
  return out;
}

int ShapePool::AttachMeshTree(const std::string& root) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(root, ec)) {
    throw InvalidArgument("ShapePool::AttachMeshTree: '" + root + "' is not a folder");
  }
  std::vector<fs::path> synsets;
  for (const auto& d : fs::directory_iterator(root, ec)) {
    if (d.is_directory(ec)) synsets.push_back(d.path());
  }
  std::sort(synsets.begin(), synsets.end());
  int found = 0;
  for (auto& e : entries_) {
    for (const auto& s : synsets) {
      const fs::path p = s / e.model_id / "models" / "model_normalized.obj";
      if (fs::is_regular_file(p, ec)) {
        e.mesh_path = p.string();
        ++found;
        break;
      }
    }
  }
  return found;
}

void ShapePool::SetMeshPath(std::size_t index, const std::string& path) {
  if (index >= entries_.size()) {
    throw InvalidArgument("ShapePool::SetMeshPath: index " + std::to_string(index) +
                          " out of range (" + std::to_string(entries_.size()) + " entries)");
  }
  if (path.size() > kMaxMeshPathLength) {
    throw InvalidArgument("ShapePool::SetMeshPath: path longer than " +
                          std::to_string(kMaxMeshPathLength) + " characters");
  }
  entries_[index].mesh_path = path;
}

int ShapePool::NumWithMeshes() const {
  int n = 0;
  for (const auto& e : entries_) n += e.mesh_path.empty() ? 0 : 1;
  return n;
}

void ShapePool::Save(const std::string& path) const {
  const bool meshes = NumWithMeshes() > 0;
  BinaryWriter out;
  out.PutBytes(kMagic, sizeof(kMagic));
  out.Put(meshes ? kVersionMeshes : kVersion);
  out.Put(static_cast<std::int32_t>(latent_dim_));
  out.Put(static_cast<std::uint64_t>(entries_.size()));
  out.PutString(ContentHash());
  for (const auto& e : entries_) {
    out.Put(static_cast<std::int32_t>(e.cad_class));
    out.Put(static_cast<std::uint32_t>(e.model_id.size()));
    out.PutString(e.model_id);
    out.PutArray(e.code.data(), static_cast<std::size_t>(e.code.size()));
    if (meshes) {
      out.Put(static_cast<std::uint32_t>(e.mesh_path.size()));
      out.PutString(e.mesh_path);
    }
  }
  out.WriteFile(path);
}

ShapePool ShapePool::Load(const std::string& path) {
  const std::string bytes = ReadFileBytes(path);
  BinaryReader r(path, bytes);
  r.ExpectMagic(std::string_view(kMagic, sizeof(kMagic)), "a dimr shape pool");
  const auto version = r.Get<std::uint32_t>("version");
  if (version != kVersion && version != kVersionMeshes) {
    r.Fail("unsupported pool version " + std::to_string(version));
  }
  const bool meshes = version == kVersionMeshes;
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  const auto dim = r.Get<std::int32_t>("latent size");
  if (dim < 1 || dim > 65536) r.Fail("latent size " + std::to_string(dim) + " out of range");
  const std::size_t code_floats = 2 * static_cast<std::size_t>(dim);
  // Each entry holds at least its class, id length and code.
  const std::size_t count =
      r.Count(r.Get<std::uint64_t>("entry count"), 8 + code_floats * sizeof(float), "entries");
  const std::string stored_hash = r.GetString(16, "content hash");
  ShapePool pool(dim);
  for (std::size_t i = 0; i < count; ++i) {
    const std::string where = "entry " + std::to_string(i);
    PoolEntry e;
    e.cad_class = r.Get<std::int32_t>((where + " class").c_str());
    const auto len = r.Get<std::uint32_t>((where + " id length").c_str());
    e.model_id = r.GetString(len, (where + " id").c_str());
    e.code.resize(static_cast<Eigen::Index>(code_floats));
    r.GetInto(e.code.data(), code_floats, (where + " code").c_str());
    if (meshes) {
      const auto mlen = r.Get<std::uint32_t>((where + " mesh path length").c_str());
      if (mlen > kMaxMeshPathLength) {
        throw ParseError(path, where + ": mesh path length " + std::to_string(mlen) + " exceeds " +
                                   std::to_string(kMaxMeshPathLength));
      }
      e.mesh_path = r.GetString(mlen, (where + " mesh path").c_str());
      if (!e.mesh_path.empty() && std::filesystem::path(e.mesh_path).is_relative()) {
        e.mesh_path = (folder / e.mesh_path).string();
      }
    }
    try {
      pool.Add(std::move(e));
    } catch (const InvalidArgument& err) {
      throw ParseError(path, where + ": " + err.what());
    }
  }
  r.ExpectEnd("the last entry");
  if (pool.ContentHash() != stored_hash) {
    throw ParseError(path, "content hash mismatch (stored " + stored_hash + ", computed " +
                               pool.ContentHash() + "): the file is corrupt");
  }
  return pool;
}

Eigen::VectorXf InterpolateCodes(const Eigen::VectorXf& a, const Eigen::VectorXf& b, double t) {
  if (a.size() != b.size()) throw InvalidArgument("InterpolateCodes: size mismatch");
  return ((1.0 - t) * a.cast<double>() + t * b.cast<double>()).cast<float>();
}

Eigen::VectorXf SampleCode(const Eigen::VectorXf& code, std::uint64_t seed) {
  if (code.size() % 2 != 0) throw InvalidArgument("SampleCode: code must be [mu, logvar]");
  const Eigen::Index d = code.size() / 2;
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  Eigen::VectorXf out = code;
  for (Eigen::Index i = 0; i < d; ++i)
    out[i] = code[i] + normal(rng) * std::exp(0.5f * code[d + i]);
  return out;
}

}  // namespace dimr::pipeline
