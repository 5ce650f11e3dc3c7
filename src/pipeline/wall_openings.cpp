#include "dimr/pipeline/wall_openings.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"
#include "dimr/core/quantile.h"
#include "dimr/geometry/grid_key.h"

namespace dimr::pipeline {
namespace {

// The classes an opening can take; their probabilities summed are the opening probability.
constexpr std::array<int, 4> kOpeningClasses = {labels::kDoor, labels::kWindow, labels::kCurtain,
                                                labels::kPicture};
constexpr double kOnPlane = 0.02;       // m: a cell this close to the plane can define its colour
constexpr double kMinColourMad = 0.02;  // floor of the wall colour's spread (0..1 colours)
constexpr double kMinPointsPerCell = 1.5;  // fewer per occupied cell: the raster is too fine

struct Cell {
  std::vector<int> points;
  Eigen::Vector3d colour = Eigen::Vector3d::Zero();  // mean
  double depth = 0;                                  // mean, > 0 behind the plane
  double open = 0;                                   // mean opening probability
  double wall = 0;                                   // mean P(wall)
  bool in = false;
};

double OpeningProbability(const float* prob) {
  double open = 0;
  for (int cls : kOpeningClasses) open += prob[cls];
  return open;
}

}  // namespace

void WallOpeningConfig::Validate() const {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw InvalidArgument(std::string("wall openings: ") + what);
  };
  need(cell >= 0.01 && cell <= 0.5, "cell must be in [0.01, 0.5] m");
  need(front >= 0 && front <= 0.5, "front must be in [0, 0.5] m");
  need(back >= 0 && back <= 1, "back must be in [0, 1] m");
  need(seed_prob > 0 && seed_prob <= 1, "seed_prob must be in (0, 1]");
  need(weak_prob >= 0 && weak_prob <= 1, "weak_prob must be in [0, 1]");  // > seed_prob: moot
  need(contrast > 0 && contrast <= 100, "contrast must be in (0, 100]");
  need(recess > 0 && recess <= 1, "recess must be in (0, 1] m");
  need(min_area >= 0 && min_area <= 100, "min_area must be in [0, 100] m²");
  need(min_side >= 0 && min_side <= 10, "min_side must be in [0, 10] m");
  need(min_fill >= 0 && min_fill <= 1, "min_fill must be in [0, 1]");
  need(erode >= 0 && erode <= 20, "erode must be in [0, 20] cells");
}

WallOpeningResult ApplyWallOpenings(const std::vector<Eigen::Vector3f>& points,
                                    const std::vector<Eigen::Vector3f>* colours,
                                    const WallPlaneResult& walls, const nn::Stage1PointRows& rows,
                                    const WallOpeningConfig& config, std::vector<int>* semantic) {
  config.Validate();
  const std::size_t n = points.size();
  if (semantic == nullptr || semantic->size() != n)
    throw InvalidArgument("wall openings: " + std::to_string(n) + " points but " +
                          std::to_string(semantic ? semantic->size() : 0) + " labels");
  if (colours != nullptr && colours->size() != n)
    throw InvalidArgument("wall openings: " + std::to_string(n) + " points but " +
                          std::to_string(colours->size()) + " colours");
  nn::CheckPointRows("wall openings", "semantic_prob", rows.semantic_prob.size(),
                     labels::kNumRfsClasses, n, rows.point_row);
  if (walls.extents.size() != walls.planes.size())
    throw InvalidArgument("wall openings: " + std::to_string(walls.planes.size()) +
                          " wall planes but " + std::to_string(walls.extents.size()) + " extents");

  WallOpeningResult result;
  for (std::size_t k = 0; k < walls.planes.size(); ++k) {
    const Eigen::Vector4f& pl = walls.planes[k];
    const Eigen::Vector4f& ext = walls.extents[k];
    // 1. The band's points, rasterised along the plane (u) and up (z).
    auto rasterise = [&](double cell) {
      std::unordered_map<std::int64_t, Cell> cells;
      for (std::size_t i = 0; i < n; ++i) {
        if ((*semantic)[i] != labels::kWall) continue;  // what the network missed
        const Eigen::Vector3f& p = points[i];
        const double depth = -(pl.x() * p.x() + pl.y() * p.y() + pl.w());  // > 0: behind
        if (depth < -config.front || depth > config.back) continue;
        const double u = -pl.y() * p.x() + pl.x() * p.y();
        if (u < ext.x() - cell || u > ext.y() + cell) continue;
        Cell& c =
            cells[geometry::PackCell2(geometry::CellOf(u, cell), geometry::CellOf(p.z(), cell))];
        c.points.push_back(static_cast<int>(i));
        const float* prob = rows.SemanticProb(i);
        c.open += OpeningProbability(prob);
        c.wall += prob[labels::kWall];
        c.depth += depth;
        if (colours != nullptr) c.colour += (*colours)[i].cast<double>();
      }
      return cells;
    };
    double cell = config.cell;
    std::unordered_map<std::int64_t, Cell> cells = rasterise(cell);
    // A sparse cloud (e.g. 4.5 cm voxel means, `dimr reconstruct --input-voxel auto`, on a wall
    // that is not axis-aligned) leaves empty cells inside surfaces, which the opening below
    // would read as edges: then cells of twice the edge.
    std::size_t band_points = 0;
    for (const auto& [key, c] : cells) band_points += c.points.size();
    if (!cells.empty() &&
        static_cast<double>(band_points) < kMinPointsPerCell * static_cast<double>(cells.size())) {
      cell = 2 * config.cell;
      cells = rasterise(cell);
    }
    if (cells.empty()) continue;
    for (auto& [key, c] : cells) {
      const double m = static_cast<double>(c.points.size());
      c.open /= m, c.wall /= m, c.depth /= m, c.colour /= m;
    }
    // 2. The wall's colour: median and spread over the cells on the plane taken for wall.
    Eigen::Vector3d wall_colour = Eigen::Vector3d::Zero(), wall_mad = Eigen::Vector3d::Ones();
    bool have_colour = false;
    if (colours != nullptr) {
      std::array<std::vector<double>, 3> ch;
      for (const auto& [key, c] : cells) {
        if (std::abs(c.depth) > kOnPlane || c.wall < 0.5) continue;
        for (int j = 0; j < 3; ++j) ch[j].push_back(c.colour[j]);
      }
      if (ch[0].size() >= 20) {
        have_colour = true;
        for (int j = 0; j < 3; ++j) {
          wall_colour[j] = NearestRankQuantile(&ch[j], 0.5);
          for (double& v : ch[j]) v = std::abs(v - wall_colour[j]);
          wall_mad[j] = std::max(1.4826 * NearestRankQuantile(&ch[j], 0.5), kMinColourMad);
        }
      }
    }
    // 3. The cells of openings.
    for (auto& [key, c] : cells) {
      if (c.open >= config.seed_prob) {
        c.in = true;
        continue;
      }
      if (c.open < config.weak_prob) continue;
      bool distinct = c.depth >= config.recess;
      if (!distinct && have_colour) {
        const double z = ((c.colour - wall_colour).cwiseAbs().cwiseQuotient(wall_mad)).maxCoeff();
        distinct = z >= config.contrast;
      }
      c.in = distinct;
    }
    // 4. A morphological opening (erode, then dilate within the cells found) by `erode` cells
    // removes thin bands - the wall around an object the network did find, whose points lean
    // towards it - and keeps solid blocks.
    auto in = [&](std::int64_t q) {
      auto it = cells.find(q);
      return it != cells.end() && it->second.in;
    };
    auto shifted = [](std::int64_t q, int du, int dz) {
      const auto [iu, iz] = geometry::UnpackCell2(q);
      return geometry::PackCell2(std::int64_t{iu} + du, std::int64_t{iz} + dz);
    };
    // The same opening in metres whatever the cell.
    const int r =
        config.erode == 0
            ? 0
            : std::max(1, static_cast<int>(std::lround(config.erode * config.cell / cell)));
    if (r > 0) {
      std::unordered_set<std::int64_t> core;
      for (const auto& [key, c] : cells) {
        if (!c.in) continue;
        bool all = true;
        for (int du = -r; du <= r && all; ++du)
          for (int dz = -r; dz <= r && all; ++dz) all = in(shifted(key, du, dz));
        if (all) core.insert(key);
      }
      std::vector<std::int64_t> drop;
      for (const auto& [key, c] : cells) {
        if (!c.in) continue;
        bool near = false;
        for (int du = -r; du <= r && !near; ++du)
          for (int dz = -r; dz <= r && !near; ++dz) near = core.count(shifted(key, du, dz)) > 0;
        if (!near) drop.push_back(key);
      }
      for (std::int64_t q : drop) cells[q].in = false;
    }
    // 5. Regions: 8-connected, in a fixed order (sorted keys) so the result is deterministic.
    std::vector<std::int64_t> keys;
    for (const auto& [key, c] : cells)
      if (c.in) keys.push_back(key);
    std::sort(keys.begin(), keys.end());
    std::unordered_set<std::int64_t> seen;
    for (std::int64_t seed : keys) {
      if (!seen.insert(seed).second) continue;
      std::vector<std::int64_t> members{seed}, stack{seed};
      while (!stack.empty()) {
        const std::int64_t at = stack.back();
        stack.pop_back();
        for (int du = -1; du <= 1; ++du)
          for (int dz = -1; dz <= 1; ++dz) {
            const std::int64_t q = shifted(at, du, dz);
            if (!in(q) || !seen.insert(q).second) continue;
            members.push_back(q);
            stack.push_back(q);
          }
      }
      // 6. Shape tests, then the class by the summed probabilities.
      std::int32_t u_lo = INT32_MAX, u_hi = INT32_MIN, z_lo = INT32_MAX, z_hi = INT32_MIN;
      for (std::int64_t q : members) {
        const auto [iu, iz] = geometry::UnpackCell2(q);
        u_lo = std::min(u_lo, iu), u_hi = std::max(u_hi, iu);
        z_lo = std::min(z_lo, iz), z_hi = std::max(z_hi, iz);
      }
      const double width = (u_hi - u_lo + 1) * cell, height = (z_hi - z_lo + 1) * cell;
      const double area = static_cast<double>(members.size()) * cell * cell;
      const double fill = area / (width * height);
      if (area < config.min_area || std::min(width, height) < config.min_side ||
          fill < config.min_fill)
        continue;
      std::array<double, kOpeningClasses.size()> sum{};
      std::size_t count = 0;
      for (std::int64_t q : members) {
        for (int i : cells[q].points) {
          const float* prob = rows.SemanticProb(static_cast<std::size_t>(i));
          for (std::size_t j = 0; j < kOpeningClasses.size(); ++j)
            sum[j] += prob[kOpeningClasses[j]];
          ++count;
        }
      }
      std::size_t best =
          static_cast<std::size_t>(std::max_element(sum.begin(), sum.end()) - sum.begin());
      if (config.shape_class) {
        // An opening is in or behind the wall's face; what stands in front of it hangs on it
        // (a picture, a board, a screen).
        double depth = 0;
        for (std::int64_t q : members) depth += cells[q].depth * cells[q].points.size();
        depth /= static_cast<double>(count);
        if (depth < -config.max_proud) continue;
        // The class by shape: from the wall's foot up and tall = door; above it = window.
        const double above = z_lo * cell - ext.z();
        const bool to_top = (z_hi + 1) * cell >= ext.w() - 2 * cell;
        if (above <= config.door_foot && (height >= config.door_height || to_top))
          best = 0;  // door
        else if (above >= config.window_sill && depth >= config.window_recess)
          best = 1;  // window
        else
          continue;
      }
      WallOpeningRegion r;
      r.rfs_class = kOpeningClasses[best];
      r.plane = static_cast<int>(k);
      r.area = area, r.width = width, r.height = height, r.z_min = z_lo * cell;
      r.probability = sum[best] / static_cast<double>(count);
      r.points = count;
      for (std::int64_t q : members) {
        for (int i : cells[q].points) {
          int& label = (*semantic)[static_cast<std::size_t>(i)];
          // A point of the region's border cells that is surely wall stays wall.
          if (OpeningProbability(rows.SemanticProb(static_cast<std::size_t>(i))) < config.weak_prob)
            continue;
          label = r.rfs_class;
          ++r.relabelled;
        }
      }
      if (r.relabelled == 0) continue;
      result.relabelled += r.relabelled;
      result.regions.push_back(r);
    }
  }
  return result;
}

}  // namespace dimr::pipeline
