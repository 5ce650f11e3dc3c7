#include "dimr/eval/cloud_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_set>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"
#include "dimr/core/parallel.h"
#include "dimr/geometry/grid_key.h"
#include "dimr/geometry/kdtree.h"

namespace dimr::eval {
namespace {

constexpr int kWallLabel = labels::kWall;
constexpr int kFloorLabel = labels::kFloor;

Histogram AngleHistogram() { return Histogram(0.0, 90.0, 9); }
Histogram CurvatureHistogram() { return Histogram(0.0, 1.0 / 3.0, 10); }

std::size_t Occupied(const std::vector<geometry::Vec3>& points, double voxel) {
  std::unordered_set<std::uint64_t> cells;
  cells.reserve(points.size());
  for (const auto& p : points) {
    // 21 bits per axis (2^21 cells: 10 km at 5 mm) is plenty for a room.
    cells.insert(geometry::PackCell3(geometry::CellOf(p.x(), voxel), geometry::CellOf(p.y(), voxel),
                                     geometry::CellOf(p.z(), voxel)));
  }
  return cells.size();
}

nlohmann::json QuantilesJson(const Quantiles& q) {
  return {{"p10", q.p10},   {"p50", q.p50}, {"p90", q.p90},
          {"mean", q.mean}, {"std", q.std}, {"n", q.n}};
}

nlohmann::json HistogramJson(const Histogram& h) {
  return {{"lo", h.lo}, {"hi", h.hi}, {"counts", h.counts}, {"fractions", h.Fractions()}};
}

nlohmann::json SurfaceJson(const SurfaceStats& s) {
  return {{"points", s.points},
          {"surface_variation", QuantilesJson(s.surface_variation)},
          {"normal_angle_deg", HistogramJson(s.normal_angle)},
          {"curvature", HistogramJson(s.curvature)}};
}

std::string FractionsText(const Histogram& h) {
  std::string out;
  for (double f : h.Fractions()) {
    char buf[16];
    std::snprintf(buf, sizeof(buf), "%s%.2f", out.empty() ? "" : " ", f);
    out += buf;
  }
  return out;
}

}  // namespace

void CloudStatsOptions::Validate() const {
  if (neighbours < 3 || neighbours > 256)
    throw InvalidArgument("cloud stats: neighbours must be in [3, 256], got " +
                          std::to_string(neighbours));
  for (double v : voxels)
    if (!(v > 0.0) || !std::isfinite(v))
      throw InvalidArgument("cloud stats: voxel edges must be positive, got " + std::to_string(v));
}

void Histogram::Add(double v) {
  if (counts.empty() || std::isnan(v)) return;
  const int bins = static_cast<int>(counts.size());
  int b = static_cast<int>(std::floor((v - lo) / (hi - lo) * bins));
  b = std::clamp(b, 0, bins - 1);
  ++counts[b];
}

long long Histogram::total() const {
  long long t = 0;
  for (long long c : counts) t += c;
  return t;
}

std::vector<double> Histogram::Fractions() const {
  const long long t = total();
  std::vector<double> f(counts.size(), 0.0);
  if (t == 0) return f;
  for (std::size_t i = 0; i < counts.size(); ++i) f[i] = static_cast<double>(counts[i]) / t;
  return f;
}

Quantiles ComputeQuantiles(std::vector<double>* v) {
  Quantiles q;
  q.n = v->size();
  if (v->empty()) return q;
  std::sort(v->begin(), v->end());
  auto at = [&](double p) {
    const double pos = p * static_cast<double>(v->size() - 1);
    const std::size_t i = static_cast<std::size_t>(std::floor(pos));
    const std::size_t j = std::min(i + 1, v->size() - 1);
    const double t = pos - static_cast<double>(i);
    return (*v)[i] * (1.0 - t) + (*v)[j] * t;
  };
  q.p10 = at(0.1);
  q.p50 = at(0.5);
  q.p90 = at(0.9);
  double s = 0, s2 = 0;
  for (double x : *v) s += x;
  q.mean = s / static_cast<double>(v->size());
  for (double x : *v) s2 += (x - q.mean) * (x - q.mean);
  q.std = std::sqrt(s2 / static_cast<double>(v->size()));
  return q;
}

std::vector<PointShape> PointShapes(const std::vector<geometry::Vec3>& points, int neighbours,
                                    int threads) {
  if (neighbours < 3) throw InvalidArgument("PointShapes: neighbours must be >= 3");
  if (points.size() < static_cast<std::size_t>(neighbours))
    throw InvalidArgument("PointShapes: " + std::to_string(points.size()) +
                          " points, need at least " + std::to_string(neighbours));
  const geometry::KdTree tree(points);
  std::vector<PointShape> out(points.size());
  ParallelRanges(points.size(), threads, 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const auto nn = tree.KNearest(points[i], neighbours);
      // The query point is among its own neighbours (distance 0); the spacing is the nearest
      // *other* point, which is nn[1] (a duplicate vertex gives 0, as it should).
      double d2 = nn.size() > 1 ? nn[1].second : 0.0;
      for (const auto& [idx, dd] : nn) {
        if (static_cast<std::size_t>(idx) != i) {
          d2 = dd;
          break;
        }
      }
      const geometry::NeighbourhoodPca pca = geometry::PcaOfNeighbours(points, nn);
      const Eigen::Vector3d lam = pca.eigenvalues.cwiseMax(0.0);  // ascending
      const double sum = lam.sum();
      PointShape& s = out[i];
      s.spacing = std::sqrt(d2);
      s.surface_variation = sum > 0.0 ? lam(0) / sum : 0.0;
      const Eigen::Vector3d n = pca.normal;
      const double c = std::min(1.0, std::abs(n.z()));
      s.normal_angle_deg = std::acos(c) * 180.0 / M_PI;
    }
  });
  return out;
}

CloudStatsAccumulator::CloudStatsAccumulator(CloudStatsOptions options)
    : options_(std::move(options)),
      angle_all_(AngleHistogram()),
      angle_wall_(AngleHistogram()),
      angle_floor_(AngleHistogram()),
      curv_all_(CurvatureHistogram()),
      curv_wall_(CurvatureHistogram()),
      curv_floor_(CurvatureHistogram()),
      color_hist_{Histogram(0, 256, 16), Histogram(0, 256, 16), Histogram(0, 256, 16)},
      occupied_(options_.voxels.size(), 0) {
  options_.Validate();
}

void CloudStatsAccumulator::Add(const CloudStatsInput& c) {
  const std::string what = "cloud stats of '" + c.name + "'";
  if (!c.points) throw InvalidArgument(what + ": no points");
  const auto& pts = *c.points;
  const std::size_t n = pts.size();
  for (std::size_t i = 0; i < n; ++i)
    if (!pts[i].allFinite())
      throw InvalidArgument(what + ": point " + std::to_string(i) + " is not finite");
  const bool colors = c.colors && !c.colors->empty();
  const bool sem = c.semantic && !c.semantic->empty();
  const bool inst = c.instance && !c.instance->empty();
  if (colors && c.colors->size() != n)
    throw InvalidArgument(what + ": " + std::to_string(c.colors->size()) + " colours for " +
                          std::to_string(n) + " points");
  if (sem && c.semantic->size() != n)
    throw InvalidArgument(what + ": " + std::to_string(c.semantic->size()) + " labels for " +
                          std::to_string(n) + " points");
  if (inst && c.instance->size() != n)
    throw InvalidArgument(what + ": " + std::to_string(c.instance->size()) + " instance ids for " +
                          std::to_string(n) + " points");
  if (n < static_cast<std::size_t>(options_.neighbours))
    throw InvalidArgument(what + ": " + std::to_string(n) + " points, need at least " +
                          std::to_string(options_.neighbours));

  const std::vector<PointShape> shapes = PointShapes(pts, options_.neighbours, options_.threads);
  for (std::size_t i = 0; i < n; ++i) {
    const PointShape& s = shapes[i];
    spacing_cm_.push_back(100.0 * s.spacing);
    sv_all_.push_back(s.surface_variation);
    angle_all_.Add(s.normal_angle_deg);
    curv_all_.Add(s.surface_variation);
    if (sem) {
      const int l = (*c.semantic)[i];
      if (l == kWallLabel) {
        sv_wall_.push_back(s.surface_variation);
        angle_wall_.Add(s.normal_angle_deg);
        curv_wall_.Add(s.surface_variation);
      } else if (l == kFloorLabel) {
        sv_floor_.push_back(s.surface_variation);
        angle_floor_.Add(s.normal_angle_deg);
        curv_floor_.Add(s.surface_variation);
      }
    }
  }
  if (colors) {
    any_colors_ = true;
    for (const auto& col : *c.colors) {
      for (int k = 0; k < 3; ++k) {
        const double v = col(k);
        sum_[k] += v;
        sum2_[k] += v * v;
        color_hist_[k].Add(v);
      }
    }
    colored_points_ += n;
  } else {
    all_colors_ = false;
  }
  for (std::size_t v = 0; v < options_.voxels.size(); ++v)
    occupied_[v] += Occupied(pts, options_.voxels[v]);
  if (sem) any_labels_ = true;
  if (inst) {
    std::map<int, std::map<int, int>> label_votes;  // instance -> label -> points
    std::map<int, int> counts;
    for (std::size_t i = 0; i < n; ++i) {
      const int id = (*c.instance)[i];
      if (id <= 0) continue;
      ++counts[id];
      if (sem) ++label_votes[id][(*c.semantic)[i]];
    }
    for (const auto& [id, count] : counts) {
      std::string label = "unlabelled";
      if (sem) {
        int best = -1, best_n = -1;
        for (const auto& [l, k] : label_votes[id])
          if (k > best_n) best = l, best_n = k;
        if (best >= 0 && best < labels::kNumRfsClasses) label = labels::RfsClassNames()[best];
      }
      auto& oc = objects_[label];
      oc.label = label;
      oc.counts.push_back(count);
    }
  }
  points_ += n;
  ++clouds_;
}

CloudStats CloudStatsAccumulator::Finish() const {
  CloudStats s;
  s.clouds = clouds_;
  s.points = points_;
  std::vector<double> v = spacing_cm_;
  s.spacing_cm = ComputeQuantiles(&v);
  s.spacing_cv = s.spacing_cm.mean > 0 ? s.spacing_cm.std / s.spacing_cm.mean : 0.0;
  auto surface = [](std::vector<double> sv, const Histogram& a, const Histogram& c) {
    SurfaceStats out;
    out.points = sv.size();
    out.surface_variation = ComputeQuantiles(&sv);
    out.normal_angle = a;
    out.curvature = c;
    return out;
  };
  s.all = surface(sv_all_, angle_all_, curv_all_);
  s.wall = surface(sv_wall_, angle_wall_, curv_wall_);
  s.floor = surface(sv_floor_, angle_floor_, curv_floor_);
  s.has_colors = any_colors_ && all_colors_;
  if (colored_points_ > 0) {
    for (int k = 0; k < 3; ++k) {
      const double m = sum_[k] / static_cast<double>(colored_points_);
      s.color_mean[k] = m;
      s.color_std[k] =
          std::sqrt(std::max(0.0, sum2_[k] / static_cast<double>(colored_points_) - m * m));
    }
  }
  s.color_hist = color_hist_;
  s.voxels = options_.voxels;
  for (std::size_t v2 = 0; v2 < occupied_.size(); ++v2)
    s.points_per_voxel.push_back(
        occupied_[v2] ? static_cast<double>(points_) / static_cast<double>(occupied_[v2]) : 0.0);
  s.has_labels = any_labels_;
  s.objects = objects_;
  return s;
}

CloudStats ComputeCloudStats(const CloudStatsInput& cloud, const CloudStatsOptions& options) {
  CloudStatsAccumulator acc(options);
  acc.Add(cloud);
  return acc.Finish();
}

std::string CloudStatsJson(const CloudStats& s) {
  nlohmann::json j;
  j["clouds"] = s.clouds;
  j["points"] = s.points;
  j["spacing_cm"] = QuantilesJson(s.spacing_cm);
  j["spacing_cv"] = s.spacing_cv;
  j["all"] = SurfaceJson(s.all);
  if (s.has_labels) {
    j["wall"] = SurfaceJson(s.wall);
    j["floor"] = SurfaceJson(s.floor);
  }
  if (s.has_colors) {
    j["color_mean"] = s.color_mean;
    j["color_std"] = s.color_std;
    const char* names[3] = {"red", "green", "blue"};
    for (int k = 0; k < 3; ++k) j["color_hist"][names[k]] = HistogramJson(s.color_hist[k]);
  }
  for (std::size_t v = 0; v < s.voxels.size(); ++v) {
    char key[32];
    std::snprintf(key, sizeof(key), "%.0fcm", 100.0 * s.voxels[v]);
    j["points_per_voxel"][key] = s.points_per_voxel[v];
  }
  for (const auto& [label, oc] : s.objects) {
    std::vector<double> c(oc.counts.begin(), oc.counts.end());
    j["objects"][label] = QuantilesJson(ComputeQuantiles(&c));
  }
  return j.dump(1);
}

std::string CloudStatsMarkdown(const CloudStats& s, const std::string& title) {
  std::ostringstream o;
  char buf[512];
  o << "### " << title << "\n\n| statistic | value |\n|---|---|\n";
  std::snprintf(buf, sizeof(buf), "| clouds / points | %zu / %zu |\n", s.clouds, s.points);
  o << buf;
  std::snprintf(buf, sizeof(buf),
                "| nearest-neighbour spacing p10 / p50 / p90 (cm) | %.2f / %.2f / %.2f |\n",
                s.spacing_cm.p10, s.spacing_cm.p50, s.spacing_cm.p90);
  o << buf;
  std::snprintf(buf, sizeof(buf), "| spacing coefficient of variation | %.3f |\n", s.spacing_cv);
  o << buf;
  auto sv = [&](const char* name, const SurfaceStats& st) {
    std::snprintf(buf, sizeof(buf),
                  "| surface variation %s median / p90 (%zu points) | %.4f / %.4f |\n", name,
                  st.points, st.surface_variation.p50, st.surface_variation.p90);
    o << buf;
  };
  sv("all", s.all);
  if (s.has_labels) {
    sv("wall", s.wall);
    sv("floor", s.floor);
  }
  if (s.has_colors) {
    std::snprintf(buf, sizeof(buf), "| colour std R / G / B | %.1f / %.1f / %.1f |\n",
                  s.color_std[0], s.color_std[1], s.color_std[2]);
    o << buf;
    std::snprintf(buf, sizeof(buf), "| colour mean R / G / B | %.1f / %.1f / %.1f |\n",
                  s.color_mean[0], s.color_mean[1], s.color_mean[2]);
    o << buf;
  }
  for (std::size_t v = 0; v < s.voxels.size(); ++v) {
    std::snprintf(buf, sizeof(buf), "| points per occupied %.0f cm voxel | %.3f |\n",
                  100.0 * s.voxels[v], s.points_per_voxel[v]);
    o << buf;
  }
  o << "| normal angle to z, 10-degree bins 0..90 (all) | " << FractionsText(s.all.normal_angle)
    << " |\n";
  o << "| surface variation, 10 bins 0..1/3 (all) | " << FractionsText(s.all.curvature) << " |\n";
  if (s.has_labels) {
    o << "| normal angle (wall) | " << FractionsText(s.wall.normal_angle) << " |\n";
    o << "| normal angle (floor) | " << FractionsText(s.floor.normal_angle) << " |\n";
    o << "| surface variation bins (wall) | " << FractionsText(s.wall.curvature) << " |\n";
    o << "| surface variation bins (floor) | " << FractionsText(s.floor.curvature) << " |\n";
  }
  if (s.has_colors) {
    const char* names[3] = {"red", "green", "blue"};
    for (int k = 0; k < 3; ++k)
      o << "| colour histogram " << names[k] << ", 16 bins | " << FractionsText(s.color_hist[k])
        << " |\n";
  }
  if (!s.objects.empty()) {
    o << "\n| class | objects | points p10 | median | p90 |\n|---|---|---|---|---|\n";
    for (const auto& [label, oc] : s.objects) {
      std::vector<double> c(oc.counts.begin(), oc.counts.end());
      const Quantiles q = ComputeQuantiles(&c);
      std::snprintf(buf, sizeof(buf), "| %s | %zu | %.0f | %.0f | %.0f |\n", label.c_str(), q.n,
                    q.p10, q.p50, q.p90);
      o << buf;
    }
  }
  return o.str();
}

}  // namespace dimr::eval
