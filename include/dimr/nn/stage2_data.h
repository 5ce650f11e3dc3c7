// Training / inference data of the stage-2 network (proposal-wise score, box residuals and
// latent code), independent of LibTorch. Spec: ../shared/reference/dimr-method.md section 4.
//
// A Stage2Sample is one canonicalised proposal (pipeline/stage2_proposals.h makes them): its
// points in the proposal's canonical frame (rotated by -heading, centred on the centre of the
// canonical bounding box), the stage-1 point features, the canonical extents s0, the height of
// the box centre above the floor and, for training, the targets of its matched GT instance.
// Deliberate differences from the reference (docs/stage2.md):
//  - nothing depends on the map origin: no absolute centre is fed (the reference concatenates
//    the world AABB centre); the network sees canonical coordinates, the height of every point
//    above the floor and the height of the proposal's centre;
//  - the centre c0 is the centre of the canonical (heading-aligned) bounding box, not of the
//    world axis-aligned one, and the centre residual lives in the canonical frame (rotated by
//    the heading at decode time), so the network never needs the world orientation;
//  - the 20^3 grid is hashed per proposal (no aliasing); index 20 is clamped to 19.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace dimr::nn {

constexpr int kStage2CadClasses = 8;
constexpr int kStage2Grid = 20;  // per-proposal voxel grid (score_fullscale)

struct Stage2Sample {
  std::string scene;  // for messages / grouping
  int proposal_class =
      -1;  // CAD class of the proposal's points (0..7): selects the residuals at test
  // Canonical frame: u = Rz(-heading) (p - c0); c0 = centre of the canonical bounding box.
  std::vector<Eigen::Vector3f> local;  // N points (metres)
  std::vector<float> features;         // N x feature_dim stage-1 point features
  int feature_dim = 0;
  Eigen::Vector3f extent = Eigen::Vector3f::Zero();  // s0 = max u - min u (metres)
  float center_height = 0;  // c0.z - floor (metres); point height = center_height + u.z
  float prior_score = 0;    // stage 1's score of the proposal (mean class probability)
  // ---- targets (training; defaults = "no target")
  float iou = 0;      // point IoU with the best-matching GT instance (any class)
  int gt_class = -1;  // CAD class of that instance, -1 if it has none (or no code)
  Eigen::Vector3f center_target = Eigen::Vector3f::Zero();  // Rz(-heading) (c_gt - c0)
  Eigen::Vector3f size_target = Eigen::Vector3f::Zero();    // GT box size (forward, left, up)
  float heading_target = 0;  // GT heading - proposal heading, wrapped to (-pi, pi] (evaluation)
  std::vector<float> code;   // GT latent [mu, logvar] (empty when gt_class < 0)

  bool has_box_target() const { return gt_class >= 0 && !code.empty(); }
  // Throws dimr::InvalidArgument naming the field for empty / inconsistent / non-finite data.
  void Validate() const;
};

// Binary cache (magic "DIMRST2S", version, count, per sample the fields above). Read checks
// every count against the remaining bytes and throws dimr::ParseError naming the file and the
// sample on any inconsistency.
void WriteStage2Samples(const std::string& path, const std::vector<Stage2Sample>& samples);
std::vector<Stage2Sample> ReadStage2Samples(const std::string& path);

// Per-proposal voxel coordinates of canonical points: lambda = grid / max(extent, 1e-4),
// w = trunc(lambda (u - min u)) with index `grid` clamped to grid - 1 (dimr-method.md 4.1,
// the edge case). Appends N (x, y, z) triples to `out`.
void Stage2VoxelCoords(const std::vector<Eigen::Vector3f>& local, int grid,
                       std::vector<std::int32_t>* out);

// Soft score target (section 4.3): 1 above fg, 0 below bg, (iou - bg) / (fg - bg) between
// (with the reference's fg 0.75 / bg 0.25 exactly 2 iou - 0.5).
float SoftScoreTarget(float iou, float fg = 0.75f, float bg = 0.25f);

struct Stage2Augment {
  bool enabled = false;
  double keep_min = 0.7;  // keep a random fraction in [keep_min, 1] of the points
  double jitter = 0.005;  // Gaussian noise on the canonical coordinates (metres)
  void Validate() const;
};

// Subsample / jitter a proposal and re-centre it on its new canonical box (extent, centre
// height and centre target follow). Deterministic in rng.
Stage2Sample AugmentStage2Sample(const Stage2Sample& s, const Stage2Augment& aug,
                                 std::mt19937_64* rng);

// Several proposals flattened for the network. B = proposals, N = points.
struct Stage2Batch {
  int batch_size = 0;
  int channels = 0;                          // input channels per point
  std::vector<std::int32_t> voxel;           // N x 4 (b, x, y, z), b = proposal
  std::vector<float> features;               // N x channels: [stage-1 feature, u (3), height (1)?]
  std::vector<float> extent;                 // B x 3
  std::vector<float> center_height;          // B
  std::vector<std::int64_t> proposal_class;  // B (0..7)
  // targets
  std::vector<float> score_target;     // B soft targets
  std::vector<float> box_weight;       // B: score target * valid (0 without a code)
  std::vector<float> class_weight;     // B: class-balance weight of the GT class (1 if invalid)
  std::vector<std::int64_t> gt_class;  // B (0 where not valid)
  std::vector<float> center_target;    // B x 3
  std::vector<float> size_target;      // B x 3
  std::vector<float> code;             // B x code_dim (0 where not valid)
  int code_dim = 0;
  std::int64_t num_points() const { return static_cast<std::int64_t>(voxel.size() / 4); }
};

struct Stage2InputConfig {
  int feature_dim = 16;      // stage-1 point features (its widths[0])
  bool point_height = true;  // append the point's height above the floor
  int grid = kStage2Grid;
  int channels() const { return feature_dim + 3 + (point_height ? 1 : 0); }
  void Validate() const;
};

// class_weights: 8 entries (or empty = 1). Throws dimr::InvalidArgument for a sample whose
// feature_dim differs from the config, a class out of range or inconsistent codes.
Stage2Batch MakeStage2Batch(const std::vector<const Stage2Sample*>& samples,
                            const Stage2InputConfig& input,
                            const std::vector<float>& class_weights = {}, float fg = 0.75f,
                            float bg = 0.25f);

// Class-balance weights from the GT classes of the samples with a box target: w_c = total /
// (classes_present * count_c) (mean 1 over the matched samples), 1 for classes without samples.
std::vector<float> Stage2ClassWeights(const std::vector<Stage2Sample>& samples);
// The reference's table (section 4.4, ScanNet counts, not normalised).
std::vector<float> Stage2ReferenceClassWeights();

}  // namespace dimr::nn
