// Realism statistics of a point cloud (issue 22): the numbers that tell a real ScanNet scan
// from a SynthScan room. Per point, from its 16 nearest neighbours (PCA of their covariance):
// nearest-neighbour spacing, surface variation lambda_0 / sum(lambda) (0 on a plane, 1/3 for
// isotropic noise) and the normal (eigenvector of the smallest eigenvalue); per cloud: spacing
// quantiles and coefficient of variation, colour mean / std / histogram per channel, points
// per occupied voxel, normal-angle and curvature histograms of wall and floor points (by the
// RFS label when there are labels), and point counts per instance.
//
// Several clouds (the rooms of a SynthScan split) are pooled with CloudStatsAccumulator: the
// per-point values of every cloud go into one distribution, so quantiles are over all points.
#pragma once

#include <array>
#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::eval {

struct CloudStatsOptions {
  int neighbours = 16;  // k of the PCA neighbourhood (the point itself included)
  std::vector<double> voxels = {0.02, 0.05};  // edges (m) for points per occupied voxel
  int threads = 0;                            // <= 0: all cores
  void Validate() const;                      // dimr::InvalidArgument naming the field
};

// One cloud. `semantic` (optional, per point): RFS 25 labels, anything outside [0, 25) is
// unlabelled. `instance` (optional, per point): ids > 0, 0 / negative = none.
struct CloudStatsInput {
  std::string name;
  const std::vector<geometry::Vec3>* points = nullptr;
  const std::vector<geometry::Color>* colors = nullptr;  // may be null or empty
  const std::vector<int>* semantic = nullptr;            // may be null or empty
  const std::vector<int>* instance = nullptr;            // may be null or empty
};

// Fixed-range histogram: counts[i] covers [lo + i w, lo + (i+1) w), w = (hi - lo) / bins; values
// outside are clamped into the end bins.
struct Histogram {
  double lo = 0.0, hi = 1.0;
  std::vector<long long> counts;
  Histogram() = default;
  Histogram(double lo_, double hi_, int bins) : lo(lo_), hi(hi_), counts(bins, 0) {}
  void Add(double v);
  long long total() const;
  std::vector<double> Fractions() const;  // counts / total (zeros when empty)
};

struct Quantiles {
  double p10 = 0, p50 = 0, p90 = 0, mean = 0, std = 0;
  std::size_t n = 0;
};
// Quantiles (linear interpolation between order statistics) of `v` (sorted in place).
Quantiles ComputeQuantiles(std::vector<double>* v);

// Statistics of one group of points (all, wall, floor).
struct SurfaceStats {
  std::size_t points = 0;
  Quantiles surface_variation;  // lambda_0 / sum(lambda)
  Histogram normal_angle;       // angle between the normal and +z, degrees in [0, 90], 9 bins
  Histogram curvature;          // surface variation in [0, 1/3], 10 bins
};

struct ObjectCounts {
  std::string label;  // RFS class name of the instance's majority label, or "unlabelled"
  std::vector<int> counts;
};

struct CloudStats {
  std::size_t clouds = 0;
  std::size_t points = 0;
  Quantiles spacing_cm;     // nearest-neighbour distance in cm (duplicates count as 0)
  double spacing_cv = 0.0;  // std / mean of the spacing
  SurfaceStats all, wall, floor;
  bool has_colors = false;
  std::array<double, 3> color_mean{}, color_std{};  // per channel, 0..255
  std::array<Histogram, 3> color_hist;              // 16 bins over [0, 256)
  std::vector<double> voxels;                       // edges (m)
  std::vector<double> points_per_voxel;             // points / occupied voxels, per edge
  bool has_labels = false;
  std::map<std::string, ObjectCounts> objects;  // by label; only with instance ids
};

class CloudStatsAccumulator {
 public:
  explicit CloudStatsAccumulator(CloudStatsOptions options = {});
  // Adds one cloud. Throws dimr::InvalidArgument naming the cloud for fewer than
  // `neighbours` points, a non-finite coordinate or per-point arrays of the wrong length.
  void Add(const CloudStatsInput& cloud);
  CloudStats Finish() const;

 private:
  CloudStatsOptions options_;
  std::size_t clouds_ = 0;
  std::vector<double> spacing_cm_;
  std::vector<double> sv_all_, sv_wall_, sv_floor_;
  Histogram angle_all_, angle_wall_, angle_floor_, curv_all_, curv_wall_, curv_floor_;
  bool any_colors_ = false, all_colors_ = true, any_labels_ = false;
  std::array<double, 3> sum_{}, sum2_{};
  std::size_t colored_points_ = 0;
  std::array<Histogram, 3> color_hist_;
  std::vector<std::size_t> occupied_;
  std::size_t points_ = 0;
  std::map<std::string, ObjectCounts> objects_;
};

// Convenience: one cloud.
CloudStats ComputeCloudStats(const CloudStatsInput& cloud, const CloudStatsOptions& options = {});

// Per-point neighbourhood values of one cloud (exposed for tests): nn spacing (m), surface
// variation, |normal . z| angle in degrees.
struct PointShape {
  double spacing = 0, surface_variation = 0, normal_angle_deg = 0;
};
std::vector<PointShape> PointShapes(const std::vector<geometry::Vec3>& points, int neighbours,
                                    int threads = 0);

// JSON text (objects, arrays of numbers) and a Markdown summary table of `stats`.
std::string CloudStatsJson(const CloudStats& stats);
std::string CloudStatsMarkdown(const CloudStats& stats, const std::string& title);

}  // namespace dimr::eval
