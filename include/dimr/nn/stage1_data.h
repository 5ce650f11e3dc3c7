// Training / inference data of the stage-1 network (point-wise semantic, offset and heading),
// independent of LibTorch. Spec: ../shared/reference/dimr-method.md sections 1, 2.4, 2.5, 8.5.
//
// A Stage1Sample is one room: metric points (z up), optional colours, per-point 25-class RFS
// labels and instance ids, and per instance its class and (when it is matched to a CAD box)
// the box heading. Differences from the reference, on purpose (docs/architecture.md section 4):
//  - the network frame is origin-free: x-y centred on the cloud's bounding-box centre, z = 0 at
//    the estimated floor (EstimateNetworkFrame), so a robot map's arbitrary origin does not
//    matter; the input features are these network-frame coordinates (+ optional colour);
//  - the heading-mirror bug (section 13) is fixed: the mirror formula is applied only when x is
//    flipped.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace dimr::nn {

constexpr int kStage1Classes = 25;  // RFS classes (network output order, data/labels.h)
constexpr int kHeadingBins = 12;    // 30-degree bins centred at k * 30 degrees
constexpr int kStage1Ignore = -100;

// ---------------------------------------------------------------- heading (section 2.4)
struct HeadingCode {
  int bin = 0;          // 0..11
  double residual = 0;  // normalised residual in [-1, 1): (angle - bin centre) / (pi / 12)
};
// Encodes a heading (radians, any value).
HeadingCode EncodeHeading(double heading);
// Decodes to (-pi, pi]: h = bin * pi/6 + residual * pi/12, wrapped (any residual).
double DecodeHeading(int bin, double residual);

// ---------------------------------------------------------------- samples
struct Stage1Instance {
  int semantic = kStage1Ignore;  // RFS class of the instance (0..24) or kStage1Ignore
  int cad_class = -1;            // 0..7, or -1 for non-CAD instances (walls, doors, clutter)
  bool has_heading = false;      // matched to a CAD box (heading loss applies to its points)
  double heading = 0;            // box heading (radians, about +z) when has_heading
};

struct Stage1Sample {
  std::string name;
  std::vector<Eigen::Vector3f> points;  // metres, gravity aligned (z up), any origin
  std::vector<Eigen::Vector3f> colors;  // RGB in [0, 1], empty or one per point
  std::vector<int> semantic;            // per point 0..24 or kStage1Ignore
  std::vector<int> instance;            // per point index into `instances`, or -1
  std::vector<Stage1Instance> instances;
  // Per-point weight of the semantic loss: empty = 1 everywhere (the reference), else one
  // finite weight > 0 per point (hard examples, SetInWallPlaneWeights). Set at training time,
  // not stored in the sample cache.
  std::vector<float> weight;

  // Throws dimr::InvalidArgument naming the sample and the field on inconsistent sizes,
  // labels out of range, non-finite points, instance indices out of range or a weight that is
  // not finite and > 0.
  void Validate() const;
};

// Binary cache of samples (magic "DIMRST1S", version, count, per sample the fields above).
// Read checks every count against the file size and throws dimr::ParseError naming the file and
// the sample on any inconsistency.
void WriteStage1Samples(const std::string& path, const std::vector<Stage1Sample>& samples);
std::vector<Stage1Sample> ReadStage1Samples(const std::string& path);

// ---------------------------------------------------------------- hard examples
// Issue 22: stage 1 labels any flat surface in a wall's plane wall, whatever its colour -
// closed doors, flat curtains, windows, posters (docs/real.md, "Capacity ..."): 13 of 20 closed
// doors and 6 of 6 flat curtains of 40 SynthScan v2 test rooms mostly wall, and the same on the
// network's own training rooms, because geometry alone cannot tell them from the wall and
// they are a tiny share of the wall-plane points. These points are found from the labels:
// every instance whose points are labelled wall (RFS class 0) and form a vertical plane
// (2-D PCA of its x-y coordinates: RMS distance to the line <= max_thickness, at least
// min_points points) defines a plane and its extent (along the wall and in z, widened by
// `margin`); a labelled point of another class except floor within `distance` of such a plane
// and inside its extent is "in a wall plane" when its object is flat in that plane: at least
// `min_instance_share` of its instance's points are within `distance` of a wall plane (a
// closed door, a poster - not the back of a bookshelf or a chair pushed against the wall; 0
// takes every such point, also those without an instance).
struct InWallPlaneConfig {
  double distance = 0.08;           // m, |distance| to the wall's plane
  double margin = 0.10;             // m, beyond the wall points' extent along the wall and in z
  double max_thickness = 0.05;      // m, RMS distance of the wall's points to its plane
  int min_points = 100;             // points of a wall instance
  double min_instance_share = 0.5;  // of an object's points in a wall plane, in [0, 1]
  // m, >= 0; 0 = off. The wall's own points within this in-plane distance (along the wall and
  // in z, on a 5 cm grid: +-5 cm) of an object point in its plane are its context: the wall
  // around a closed door, so that a weight on both sides teaches the boundary, not a prior.
  double wall_context = 0.0;
  void Validate() const;  // throws dimr::InvalidArgument naming the field
};
// Per point of `sample`: 1 when it is in a wall plane (above), 2 when it is a wall point in the
// context of such an object (`wall_context` > 0), else 0. Wall points without an instance, and
// walls that are not planar (a corner, a curved wall), define no plane.
// Throws dimr::InvalidArgument for an invalid sample or configuration.
std::vector<std::uint8_t> InWallPlanePoints(const Stage1Sample& sample,
                                            const InWallPlaneConfig& config = {});
// sample->weight = `weight` on the points in a wall plane and their wall context (values 1 and 2
// of InWallPlanePoints), 1 elsewhere (weight 1 clears it: empty). Returns how many points got
// `weight`. Throws dimr::InvalidArgument for a weight that is not finite and > 0, and as
// InWallPlanePoints.
std::size_t SetInWallPlaneWeights(Stage1Sample* sample, float weight,
                                  const InWallPlaneConfig& config = {});

// ---------------------------------------------------------------- network frame
// p_net = p - origin, where origin = (x-y centre of the points' bounding box, floor height).
struct NetworkFrame {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  float floor_z = 0;  // = origin.z()
};
// The floor is the lowest well-populated height: the lowest 2 cm z-bin holding at least 2 % of
// the points (falls back to the 1st percentile of z for clouds without a dominant floor).
// Throws dimr::InvalidArgument for an empty cloud or non-finite points.
NetworkFrame EstimateNetworkFrame(const std::vector<Eigen::Vector3f>& points);

// ---------------------------------------------------------------- augmentation (section 1.3)
// Real-scan augmentation (issue 22: SynthScan's surfaces are 10-30x smoother and its colours
// 3x flatter than ScanNet's, docs/synthscan.md). Every field is off by default, so a model
// trained without them is reproduced bit for bit (these draws use their own random stream).
// Text form (`dimr train stage1 --augment`, model cards): "color_jitter=0.1 point_noise=0.004".
// Per scene, in this order, after the affine part: scale U[scale_min, scale_max] about the
// network origin; per-point Gaussian displacement (point_noise, m); then, after elastic and
// crop, a fraction U[0, point_dropout] of the points dropped (at least one point kept).
// Colours (only fed with rgb): with probability color_drop every colour becomes 0.5 (no colour
// information); else with probability greyscale the luminance 0.299 r + 0.587 g + 0.114 b
// replaces each channel; then contrast about the scene's mean colour by a factor U[1,
// color_contrast], per-channel gain 1 + color_jitter N and offset color_jitter / 2 N (white
// balance / exposure), per-point noise color_noise N, clamped to [0, 1].
struct RealismAugment {
  double color_jitter = 0;
  double color_contrast = 1;
  double color_noise = 0;
  double greyscale = 0;    // probability
  double color_drop = 0;   // probability
  double point_noise = 0;  // m
  double scale_min = 1, scale_max = 1;
  double point_dropout = 0;  // largest dropped fraction
  // Instance mixing (issue 22 item 6, context mixing across rooms): with probability
  // instance_mix a scene of a batch receives up to instance_mix_count CAD-class instances of
  // the next scene of the batch (MixInstances below); needs batches of >= 2 scenes.
  double instance_mix = 0;
  int instance_mix_count = 3;
  // Cuboid mixing (issue 22 item 6; DODA's cuboid mixing, ECCV 2022): with probability
  // cuboid_mix a scene of a batch has some of its four x-y quadrants replaced by the
  // quadrants of the next scene of the batch (MixCuboids below) - objects meet neighbours
  // and walls of another room, so the network cannot lean on whole-room context; needs
  // batches of >= 2 scenes. Applied before instance mixing.
  double cuboid_mix = 0;
  bool any() const;  // the point / colour part (not instance mixing)
  bool any_color() const;
  void Validate() const;         // throws dimr::InvalidArgument naming the key
  std::string ToString() const;  // every key ("color_jitter=0 ... point_dropout=0")
  // Keys on top of the defaults; strict values (config_fields.h). Throws dimr::InvalidArgument.
  static RealismAugment FromString(const std::string& text);
};

// Applies the geometric part (scale, point noise) to `points` and returns the colours of the
// colour part for `colors` (empty in, empty out). Deterministic in `rng`.
void AugmentRealismPoints(std::vector<Eigen::Vector3f>* points, const RealismAugment& config,
                          std::mt19937_64* rng);
std::vector<Eigen::Vector3f> AugmentRealismColors(const std::vector<Eigen::Vector3f>& colors,
                                                  const RealismAugment& config,
                                                  std::mt19937_64* rng);
// Instance mixing: a copy of `dst` with up to `count` CAD-class instances of `src` (those with
// cad_class >= 0 and at least `min_points` points, drawn without replacement) appended: each
// instance's points, colours (0.5 grey when src has none and dst has colours), semantic labels
// and heading, rotated about z through its own x-y centre by a uniform angle (the heading turns
// with it), moved to a uniform x-y position that keeps its footprint inside dst's x-y bounding
// box when it fits (else dst's centre), and lifted or lowered so that its lowest point sits on
// dst's floor (EstimateNetworkFrame). Points may interpenetrate dst's objects (clutter-like);
// the pasted instances get new instance indices after dst's (and weight 1 where dst has
// weights). Deterministic in `rng`; count 0 or
// no eligible instance returns dst unchanged. Throws dimr::InvalidArgument for invalid samples.
Stage1Sample MixInstances(const Stage1Sample& dst, const Stage1Sample& src, int count,
                          std::mt19937_64* rng, int min_points = 50);

// Cuboid mixing: `dst` and `src` are each cut into four x-y quadrants at a split point drawn
// uniformly in the middle 30-70 % of their x-y bounding box (one draw per axis and scene); one
// to three of dst's quadrants (each with probability 1/2, redrawn until it is neither none nor
// all) are replaced by src's quadrant of the same index, translated so that src's split point
// lands on dst's and src's floor on dst's (EstimateNetworkFrame); the rest of dst stays as it
// was, in order, followed by the src points. Colours, semantic labels, headings and weights
// (1 where src has none) come along; instances are renumbered in order of first appearance
// (dst's before src's), an instance cut by a quadrant border keeps only its points on the kept
// side (the offset target becomes that part's centre, as in DODA), and instances left without
// points are dropped. Deterministic in `rng`; a scene without points returns dst unchanged.
// Throws dimr::InvalidArgument for invalid samples or a null `rng`.
Stage1Sample MixCuboids(const Stage1Sample& dst, const Stage1Sample& src, std::mt19937_64* rng);

// Drops a fraction U[0, config.point_dropout] of `keep` (order kept, at least one left).
void AugmentRealismDropout(std::vector<std::size_t>* keep, const RealismAugment& config,
                           std::mt19937_64* rng);

struct AugmentConfig {
  bool enabled = true;
  double jitter = 0.1;  // m = I + jitter * N(0,1)^{3x3}
  bool flip = true;     // x-flip with p = 0.5 (heading mirrored only then: bug fixed)
  bool rotate = true;   // uniform rotation about z
  bool elastic = true;  // two elastic passes on the voxel coordinates
  double elastic_gran0 = 6, elastic_mag0 = 40;    // in voxels of scale 50 (rescaled to scale)
  double elastic_gran1 = 20, elastic_mag1 = 160;  //
  int max_points = 250000;                        // random crop above this many points per scene
  RealismAugment realism;                         // off by default (above)
  void Validate() const;                          // throws dimr::InvalidArgument naming the field
};

// Applies the affine part (jitter, flip, rotation) to the points of a sample (network frame,
// rotation about its origin) and the same rotation/mirror to the instance headings.
// `affine` (optional) receives the 3x3 matrix m with p' = m * p (column vectors).
void AugmentAffine(Stage1Sample* sample, const AugmentConfig& config, std::mt19937_64* rng,
                   Eigen::Matrix3f* affine = nullptr);

// Elastic distortion of scaled (voxel-unit) coordinates, in place (N x 3): Gaussian noise on a
// coarse grid of spacing `gran` blurred by 3-tap box filters, trilinear interpolation,
// displacement * `mag` (SparseConvNet style).
void ElasticDistortion(std::vector<Eigen::Vector3f>* coords, double gran, double mag,
                       std::mt19937_64* rng);

// ---------------------------------------------------------------- batches
struct Stage1InputConfig {
  double scale = 20;     // voxels per metre (the reference: 50 = 2 cm)
  bool use_rgb = false;  // input features = xyz (network frame) [+ rgb - 0.5]
  int feature_channels() const { return use_rgb ? 6 : 3; }
  void Validate() const;
};

// Several scenes flattened, ready for the network. N = total points.
struct Stage1Batch {
  int batch_size = 0;
  int feature_channels = 3;
  std::vector<std::string> names;
  std::vector<std::int64_t> point_offsets;  // batch_size + 1, points of scene b: [o[b], o[b+1])
  std::vector<float> points;                // N x 3, network frame after augmentation (metres)
  std::vector<float> features;              // N x C
  std::vector<std::int32_t> voxel;          // N x 4: (b, x, y, z) = floor(scale*p - min) per scene
  std::vector<std::int64_t> semantic;       // N, 0..24 or kStage1Ignore
  std::vector<std::int64_t> instance;       // N, batch-unique instance id or -1
  std::vector<float> offset_target;         // N x 3: instance AABB centre - point (0 if none)
  std::vector<std::uint8_t> offset_valid;   // N: point belongs to an instance
  std::vector<std::int64_t> heading_bin;    // N: GT bin or kStage1Ignore (no CAD box)
  std::vector<float> heading_residual;      // N: normalised GT residual (0 if none)
  // N per-point semantic-loss weights (Stage1Sample::weight, 1 for samples without), or empty
  // when no sample of the batch has weights (the unweighted loss, bit for bit).
  std::vector<float> semantic_weight;
  std::vector<NetworkFrame> frames;  // per scene: the frame that was subtracted
  std::int64_t num_points() const { return static_cast<std::int64_t>(semantic.size()); }
};

// Builds a batch: network frame per scene, (optional) augmentation with `seed`, voxel coords,
// features and all targets. augment == nullptr or !augment->enabled: no augmentation.
Stage1Batch MakeStage1Batch(const std::vector<const Stage1Sample*>& samples,
                            const Stage1InputConfig& input, const AugmentConfig* augment,
                            std::uint64_t seed);

// ---------------------------------------------------------------- inference input
// A view of one scene for inference, without labels (not a training sample): `size` points
// (metres, z up, any origin) and optionally `size` colours in [0, 1] (colors == nullptr: none).
// The arrays must outlive the call that takes the view.
struct ScenePoints {
  const Eigen::Vector3f* points = nullptr;
  const Eigen::Vector3f* colors = nullptr;
  std::size_t size = 0;
  std::string name;  // for error messages
  ScenePoints() = default;
  ScenePoints(const std::vector<Eigen::Vector3f>& p, const std::vector<Eigen::Vector3f>* c,
              std::string n = "")
      : points(p.data()),
        colors(c && !c->empty() ? c->data() : nullptr),
        size(p.size()),
        name(std::move(n)) {}
};

// What the network reads of one scene: the network frame, per point its voxel (b = 0, x, y,
// z) = floor(scale * (p - origin) - min) and features (network-frame xyz [+ rgb - 0.5]) -
// exactly what MakeStage1Batch builds for one sample without augmentation.
struct Stage1NetworkInput {
  NetworkFrame frame;
  int feature_channels = 3;
  std::vector<std::int32_t> voxel;              // N x 4
  std::vector<float> features;                  // N x feature_channels
  std::array<std::int64_t, 3> extent{0, 0, 0};  // voxels per axis (max + 1)
};

// Throws dimr::InvalidArgument naming the scene for an empty cloud, a non-finite point (its
// index), missing colours when input.use_rgb, or a cloud spanning more than 65535 voxels along
// an axis (e.g. a cloud in millimetres: the message says so).
Stage1NetworkInput MakeStage1NetworkInput(const ScenePoints& scene, const Stage1InputConfig& input);
// The same written into the caller's buffers (features: scene.size x input.feature_channels()
// floats, voxel: scene.size x 4; every element is written, so they may be uninitialised);
// returns the frame and sets *extent. The same checks and messages.
NetworkFrame WriteStage1NetworkInput(const ScenePoints& scene, const Stage1InputConfig& input,
                                     std::array<std::int64_t, 3>* extent, float* features,
                                     std::int32_t* voxel);

// Shuffled epochs of batches built by `threads` background threads (prefetching `prefetch`
// batches). Deterministic: batch k of epoch e depends only on (seed, e, k), not on threads.
class Stage1Loader {
 public:
  Stage1Loader(const std::vector<Stage1Sample>* samples, Stage1InputConfig input,
               AugmentConfig augment, int batch_size, std::uint64_t seed, int threads = 1,
               int prefetch = 4, bool drop_last = true);
  ~Stage1Loader();
  Stage1Loader(const Stage1Loader&) = delete;
  Stage1Loader& operator=(const Stage1Loader&) = delete;

  int batches_per_epoch() const;
  // Starts (or restarts) producing the batches of `epoch` from batch index `first_batch` on.
  void StartEpoch(int epoch, int first_batch = 0);
  // Next batch of the current epoch in order; false when the epoch is exhausted.
  bool Next(Stage1Batch* batch);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace dimr::nn
