// Stage-2 samples, cache, augmentation and batches (include/dimr/nn/stage2_data.h). Torch-free.
#include "dimr/nn/stage2_data.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "dimr/core/binary_io.h"
#include "dimr/geometry/error.h"

namespace dimr::nn {

namespace {

constexpr char kMagic[8] = {'D', 'I', 'M', 'R', 'S', 'T', '2', 'S'};
constexpr std::uint32_t kVersion = 1;

bool Finite(const Eigen::Vector3f& v) { return v.allFinite(); }

}  // namespace

// ---------------------------------------------------------------- sample
void Stage2Sample::Validate() const {
  const std::string who = "Stage2Sample of '" + scene + "'";
  if (local.empty()) throw InvalidArgument(who + ": no points");
  if (feature_dim < 0 || feature_dim > 4096) {
    throw InvalidArgument(who + ": feature_dim " + std::to_string(feature_dim));
  }
  if (features.size() != local.size() * static_cast<std::size_t>(feature_dim)) {
    throw InvalidArgument(who + ": features has " + std::to_string(features.size()) +
                          " values for " + std::to_string(local.size()) + " points x " +
                          std::to_string(feature_dim));
  }
  if (proposal_class < 0 || proposal_class >= kStage2CadClasses) {
    throw InvalidArgument(who + ": proposal_class " + std::to_string(proposal_class) +
                          " outside 0..7");
  }
  for (std::size_t i = 0; i < local.size(); ++i) {
    if (!Finite(local[i])) {
      throw InvalidArgument(who + ": local[" + std::to_string(i) + "] is not finite");
    }
  }
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (!std::isfinite(features[i])) {
      throw InvalidArgument(who + ": features[" + std::to_string(i) + "] is not finite");
    }
  }
  if (!Finite(extent) || (extent.array() < 0).any()) {
    throw InvalidArgument(who + ": extent is negative or not finite");
  }
  if (!std::isfinite(center_height) || !std::isfinite(prior_score) ||
      !std::isfinite(heading_target)) {
    throw InvalidArgument(who + ": center_height / prior_score / heading_target not finite");
  }
  if (!(iou >= 0 && iou <= 1.0001f)) throw InvalidArgument(who + ": iou outside [0, 1]");
  if (gt_class < -1 || gt_class >= kStage2CadClasses) {
    throw InvalidArgument(who + ": gt_class " + std::to_string(gt_class) + " outside -1..7");
  }
  if (!Finite(center_target) || !Finite(size_target)) {
    throw InvalidArgument(who + ": box target not finite");
  }
  for (float v : code) {
    if (!std::isfinite(v)) throw InvalidArgument(who + ": code is not finite");
  }
  if (gt_class < 0 && !code.empty()) throw InvalidArgument(who + ": a code without a gt_class");
}

// ---------------------------------------------------------------- cache
void WriteStage2Samples(const std::string& path, const std::vector<Stage2Sample>& samples) {
  for (std::size_t i = 0; i < samples.size(); ++i) {
    try {
      samples[i].Validate();
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("WriteStage2Samples(" + path + "): sample " + std::to_string(i) + ": " +
                            e.what());
    }
  }
  BinaryWriter w;
  w.PutBytes(kMagic, sizeof(kMagic));
  w.Put(kVersion);
  w.Put(static_cast<std::uint64_t>(samples.size()));
  for (const Stage2Sample& s : samples) {
    w.Put(static_cast<std::uint32_t>(s.scene.size()));
    w.PutBytes(s.scene.data(), s.scene.size());
    w.Put(static_cast<std::int32_t>(s.proposal_class));
    w.Put(static_cast<std::int32_t>(s.feature_dim));
    w.Put(static_cast<std::uint64_t>(s.local.size()));
    for (const auto& p : s.local) w.PutBytes(p.data(), 3 * sizeof(float));
    w.PutBytes(s.features.data(), s.features.size() * sizeof(float));
    w.PutBytes(s.extent.data(), 3 * sizeof(float));
    w.Put(s.center_height);
    w.Put(s.prior_score);
    w.Put(s.iou);
    w.Put(static_cast<std::int32_t>(s.gt_class));
    w.PutBytes(s.center_target.data(), 3 * sizeof(float));
    w.PutBytes(s.size_target.data(), 3 * sizeof(float));
    w.Put(s.heading_target);
    w.Put(static_cast<std::uint32_t>(s.code.size()));
    w.PutBytes(s.code.data(), s.code.size() * sizeof(float));
  }
  // Written next to the target and renamed, so a crash never leaves a half-written cache.
  const std::string tmp = path + ".tmp";
  w.WriteFile(tmp);
  std::filesystem::rename(tmp, path);
}

std::vector<Stage2Sample> ReadStage2Samples(const std::string& path) {
  const std::string bytes = ReadFileBytes(path);
  BinaryReader r(path, bytes);
  r.ExpectMagic(std::string_view(kMagic, sizeof(kMagic)), "a dimr stage-2 sample cache");
  const auto version = r.Get<std::uint32_t>("version");
  if (version != kVersion) {
    throw ParseError(path, "unsupported stage-2 cache version " + std::to_string(version));
  }
  // Smallest sample: 4 + 4 + 4 + 8 + 12 + 4 + 4 + 4 + 4 + 24 + 4 + 4 = 80 bytes.
  const std::size_t count = r.Count(r.Get<std::uint64_t>("sample count"), 80, "samples");
  std::vector<Stage2Sample> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::string where = "sample " + std::to_string(i) + ": ";
    const auto at = [&where](const char* field) { return where + field; };
    Stage2Sample& s = out[i];
    s.scene = r.GetString(r.Get<std::uint32_t>(at("scene name length").c_str()),
                          at("scene name").c_str());
    s.proposal_class = r.Get<std::int32_t>(at("proposal class").c_str());
    s.feature_dim = r.Get<std::int32_t>(at("feature dim").c_str());
    if (s.feature_dim < 0 || s.feature_dim > 4096) {
      throw ParseError(path, at("feature dim ") + std::to_string(s.feature_dim));
    }
    const std::size_t n =
        r.Count(r.Get<std::uint64_t>(at("point count").c_str()),
                12 + 4 * static_cast<std::size_t>(s.feature_dim), at("points").c_str());
    s.local.resize(n);
    for (auto& p : s.local) r.GetInto(p.data(), 3, at("points").c_str());
    r.GetArray(n * static_cast<std::size_t>(s.feature_dim), &s.features, at("features").c_str());
    r.GetInto(s.extent.data(), 3, at("extent").c_str());
    s.center_height = r.Get<float>(at("centre height").c_str());
    s.prior_score = r.Get<float>(at("prior score").c_str());
    s.iou = r.Get<float>(at("iou").c_str());
    s.gt_class = r.Get<std::int32_t>(at("gt class").c_str());
    r.GetInto(s.center_target.data(), 3, at("centre target").c_str());
    r.GetInto(s.size_target.data(), 3, at("size target").c_str());
    s.heading_target = r.Get<float>(at("heading target").c_str());
    r.GetArray(r.Get<std::uint32_t>(at("code size").c_str()), &s.code, at("code").c_str());
    try {
      s.Validate();
    } catch (const InvalidArgument& e) {
      throw ParseError(path, where + e.what());
    }
  }
  r.ExpectEnd("the last sample");
  return out;
}

// ---------------------------------------------------------------- voxels, targets
void Stage2VoxelCoords(const std::vector<Eigen::Vector3f>& local, int grid,
                       std::vector<std::int32_t>* out) {
  if (grid < 2 || grid > 1024)
    throw InvalidArgument("Stage2VoxelCoords: grid " + std::to_string(grid));
  if (local.empty()) return;
  Eigen::Vector3f lo = local[0], hi = local[0];
  for (const auto& p : local) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Bounded scale: a degenerate proposal (all points equal) lands in voxel 0.
  const float longest = std::max((hi - lo).maxCoeff(), 1e-4f);
  const float lambda = static_cast<float>(grid) / longest;
  for (const auto& p : local) {
    for (int a = 0; a < 3; ++a) {
      int v = static_cast<int>(lambda * (p[a] - lo[a]));  // trunc (non-negative)
      out->push_back(std::clamp(v, 0, grid - 1));         // index `grid` -> grid - 1
    }
  }
}

float SoftScoreTarget(float iou, float fg, float bg) {
  if (iou > fg) return 1.0f;
  if (iou < bg) return 0.0f;
  return std::clamp((iou - bg) / std::max(fg - bg, 1e-6f), 0.0f, 1.0f);
}

void Stage2Augment::Validate() const {
  if (!(keep_min > 0 && keep_min <= 1)) {
    throw InvalidArgument("stage2 augment: keep_min must be in (0, 1]");
  }
  if (!(jitter >= 0 && jitter < 1)) throw InvalidArgument("stage2 augment: jitter in [0, 1) m");
}

Stage2Sample AugmentStage2Sample(const Stage2Sample& s, const Stage2Augment& aug,
                                 std::mt19937_64* rng) {
  if (!aug.enabled) return s;
  const std::size_t n = s.local.size();
  std::uniform_real_distribution<double> keep_d(aug.keep_min, 1.0);
  const double keep = keep_d(*rng);
  const std::size_t m = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(keep * n)));
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  if (m < n) {
    std::shuffle(order.begin(), order.end(), *rng);
    order.resize(m);
    std::sort(order.begin(), order.end());
  }
  Stage2Sample o;
  o.scene = s.scene;
  o.proposal_class = s.proposal_class;
  o.feature_dim = s.feature_dim;
  o.iou = s.iou;
  o.gt_class = s.gt_class;
  o.size_target = s.size_target;
  o.heading_target = s.heading_target;
  o.prior_score = s.prior_score;
  o.code = s.code;
  o.local.resize(m);
  o.features.resize(m * static_cast<std::size_t>(s.feature_dim));
  std::normal_distribution<float> noise(0.0f, static_cast<float>(aug.jitter));
  for (std::size_t k = 0; k < m; ++k) {
    Eigen::Vector3f p = s.local[order[k]];
    if (aug.jitter > 0) p += Eigen::Vector3f(noise(*rng), noise(*rng), noise(*rng));
    o.local[k] = p;
    std::copy_n(s.features.begin() + order[k] * s.feature_dim, s.feature_dim,
                o.features.begin() + k * s.feature_dim);
  }
  Eigen::Vector3f lo = o.local[0], hi = o.local[0];
  for (const auto& p : o.local) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3f mid = 0.5f * (lo + hi);
  for (auto& p : o.local) p -= mid;
  o.extent = hi - lo;
  o.center_height = s.center_height + mid.z();
  o.center_target = s.center_target - mid;  // the GT centre seen from the new c0
  return o;
}

// ---------------------------------------------------------------- batches
void Stage2InputConfig::Validate() const {
  if (feature_dim < 0 || feature_dim > 4096) {
    throw InvalidArgument("stage2 input: feature_dim " + std::to_string(feature_dim));
  }
  if (grid < 2 || grid > 1024) throw InvalidArgument("stage2 input: grid " + std::to_string(grid));
}

Stage2Batch MakeStage2Batch(const std::vector<const Stage2Sample*>& samples,
                            const Stage2InputConfig& input, const std::vector<float>& class_weights,
                            float fg, float bg) {
  input.Validate();
  if (!class_weights.empty() && class_weights.size() != kStage2CadClasses) {
    throw InvalidArgument("MakeStage2Batch: class_weights needs 8 entries, got " +
                          std::to_string(class_weights.size()));
  }
  Stage2Batch b;
  b.batch_size = static_cast<int>(samples.size());
  b.channels = input.channels();
  for (const Stage2Sample* s : samples) {
    if (s->has_box_target()) {
      if (b.code_dim == 0) b.code_dim = static_cast<int>(s->code.size());
      if (static_cast<int>(s->code.size()) != b.code_dim) {
        throw InvalidArgument("MakeStage2Batch: codes of different sizes (" +
                              std::to_string(s->code.size()) + " vs " + std::to_string(b.code_dim) +
                              ")");
      }
    }
  }
  std::size_t total = 0;
  for (const Stage2Sample* s : samples) total += s->local.size();
  b.voxel.reserve(4 * total);
  b.features.reserve(total * b.channels);
  std::vector<std::int32_t> coords;
  for (int k = 0; k < b.batch_size; ++k) {
    const Stage2Sample& s = *samples[k];
    if (s.feature_dim != input.feature_dim) {
      throw InvalidArgument("MakeStage2Batch: proposal of '" + s.scene + "' has " +
                            std::to_string(s.feature_dim) + "-d features, the model expects " +
                            std::to_string(input.feature_dim));
    }
    if (s.local.empty())
      throw InvalidArgument("MakeStage2Batch: empty proposal of '" + s.scene + "'");
    if (s.proposal_class < 0 || s.proposal_class >= kStage2CadClasses) {
      throw InvalidArgument("MakeStage2Batch: proposal class outside 0..7");
    }
    coords.clear();
    Stage2VoxelCoords(s.local, input.grid, &coords);
    for (std::size_t i = 0; i < s.local.size(); ++i) {
      b.voxel.push_back(k);
      b.voxel.insert(b.voxel.end(), coords.begin() + 3 * i, coords.begin() + 3 * i + 3);
      b.features.insert(b.features.end(), s.features.begin() + i * s.feature_dim,
                        s.features.begin() + (i + 1) * s.feature_dim);
      b.features.insert(b.features.end(), s.local[i].data(), s.local[i].data() + 3);
      if (input.point_height) b.features.push_back(s.center_height + s.local[i].z());
    }
    b.extent.insert(b.extent.end(), s.extent.data(), s.extent.data() + 3);
    b.center_height.push_back(s.center_height);
    b.proposal_class.push_back(s.proposal_class);
    const float t = SoftScoreTarget(s.iou, fg, bg);
    b.score_target.push_back(t);
    const bool valid = s.has_box_target();
    const float w = valid && !class_weights.empty() ? class_weights[s.gt_class] : 1.0f;
    b.box_weight.push_back(valid ? t : 0.0f);
    b.class_weight.push_back(w);
    b.gt_class.push_back(valid ? s.gt_class : 0);
    b.center_target.insert(b.center_target.end(), s.center_target.data(),
                           s.center_target.data() + 3);
    b.size_target.insert(b.size_target.end(), s.size_target.data(), s.size_target.data() + 3);
    if (b.code_dim > 0) {
      if (valid) {
        b.code.insert(b.code.end(), s.code.begin(), s.code.end());
      } else {
        b.code.insert(b.code.end(), b.code_dim, 0.0f);
      }
    }
  }
  return b;
}

std::vector<float> Stage2ClassWeights(const std::vector<Stage2Sample>& samples) {
  std::vector<double> count(kStage2CadClasses, 0.0);
  double total = 0;
  for (const auto& s : samples) {
    if (s.has_box_target()) {
      count[s.gt_class] += 1;
      total += 1;
    }
  }
  int present = 0;
  for (double c : count) present += c > 0 ? 1 : 0;
  std::vector<float> w(kStage2CadClasses, 1.0f);
  for (int c = 0; c < kStage2CadClasses; ++c) {
    if (count[c] > 0) w[c] = static_cast<float>(total / (present * count[c]));
  }
  return w;
}

std::vector<float> Stage2ReferenceClassWeights() {
  const double cnt[kStage2CadClasses] = {555, 1093, 212, 113, 232, 260, 191, 121};
  double sum = 0;
  for (double c : cnt) sum += c;
  std::vector<float> w(kStage2CadClasses);
  for (int c = 0; c < kStage2CadClasses; ++c) w[c] = static_cast<float>(sum / cnt[c]);
  return w;
}

}  // namespace dimr::nn
