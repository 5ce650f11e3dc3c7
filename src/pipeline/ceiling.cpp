#include "dimr/pipeline/ceiling.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "dimr/core/error.h"
#include "dimr/core/quantile.h"
#include "dimr/geometry/grid_key.h"

namespace dimr::pipeline {
namespace {

std::int64_t CellKey(float x, float y, double cell) {
  return geometry::PackCell2(geometry::CellOf(x, cell), geometry::CellOf(y, cell));
}

}  // namespace

void CeilingConfig::Validate() const {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw InvalidArgument(std::string("ceiling removal: ") + what);
  };
  need(min_height > 0 && min_height < 20, "min_height must be in (0, 20) m");
  need(floor_quantile >= 0 && floor_quantile < 0.5, "floor_quantile must be in [0, 0.5)");
  need(bin > 0.001 && bin <= 0.5, "bin must be in (0.001, 0.5] m");
  need(band > 0 && band <= 1, "band must be in (0, 1] m");
  need(edge >= 0 && edge <= band, "edge must be in [0, band] m");
  need(top_quantile > 0.5 && top_quantile <= 1, "top_quantile must be in (0.5, 1]");
  need(top_margin >= 0 && top_margin <= 5, "top_margin must be in [0, 5] m");
  need(cell > 0.005 && cell <= 2, "cell must be in (0.005, 2] m");
  need(max_cell_z_std > 0 && max_cell_z_std <= 1, "max_cell_z_std must be in (0, 1] m");
  need(min_area >= 0 && std::isfinite(min_area), "min_area must be >= 0");
  need(min_area_fraction >= 0 && min_area_fraction <= 1, "min_area_fraction must be in [0, 1]");
}

namespace {

// Steps 1-3 of the rule (header): fills floor_z / ceiling_z / area / found of *out and, when a
// ceiling is found, the layer's flat cells. The input is already validated.
void FindCeiling(const PointCloudInput& input, const CeilingConfig& config, CeilingRemoval* out,
                 std::unordered_set<std::int64_t>* flat_cells) {
  const std::size_t n = input.points.size();
  if (!config.enabled || n == 0) return;
  std::vector<float> z(n);
  for (std::size_t i = 0; i < n; ++i) z[i] = input.points[i].z();
  out->floor_z = NearestRankQuantile(&z, config.floor_quantile);
  const float top = NearestRankQuantile(&z, config.top_quantile);
  const double low = out->floor_z + config.min_height;
  if (top < low) return;

  // 2. The densest layer above floor + min_height (three bins summed).
  const int bins = static_cast<int>(std::ceil((top + config.band - low) / config.bin)) + 1;
  std::vector<std::size_t> hist(static_cast<std::size_t>(bins) + 2, 0);
  for (const auto& p : input.points) {
    if (p.z() < low) continue;
    const int b = static_cast<int>((p.z() - low) / config.bin);
    if (b < bins) ++hist[static_cast<std::size_t>(b) + 1];
  }
  std::size_t best = 0, best_count = 0;
  for (std::size_t b = 1; b + 1 < hist.size(); ++b) {
    const std::size_t c = hist[b - 1] + hist[b] + hist[b + 1];
    if (c > best_count) best_count = c, best = b;
  }
  if (best_count == 0) return;
  const double peak = low + (static_cast<double>(best) - 0.5) * config.bin;
  double sum = 0;
  std::size_t count = 0;
  for (const auto& p : input.points) {
    if (std::abs(p.z() - peak) <= config.bin) sum += p.z(), ++count;
  }
  const double zc = count > 0 ? sum / static_cast<double>(count) : peak;
  out->ceiling_z = zc;
  // 3a. The top of the cloud.
  if (top > zc + config.top_margin) return;
  // 3b. Horizontal, large: per x-y cell the z spread of the layer's points.
  struct Acc {
    double s = 0, s2 = 0;
    int n = 0, low = 0;  // low: points lower than z_c - edge
  };
  std::unordered_map<std::int64_t, Acc> layer;
  std::unordered_set<std::int64_t> footprint;
  layer.reserve(n / 16 + 1);
  footprint.reserve(n / 16 + 1);
  for (const auto& p : input.points) {
    const std::int64_t key = CellKey(p.x(), p.y(), config.cell);
    footprint.insert(key);
    const double d = p.z() - zc;
    if (std::abs(d) > config.band) continue;
    Acc& a = layer[key];
    a.s += d, a.s2 += d * d, ++a.n;
    if (d < -config.edge) ++a.low;
  }
  for (const auto& kv : layer) {
    const Acc& a = kv.second;
    if (a.n < 3) continue;
    const double mean = a.s / a.n;
    const double var = std::max(0.0, a.s2 / a.n - mean * mean);
    // Flat, and not a wall's column under the ceiling's rim (whose points spread below it).
    if (std::sqrt(var) < config.max_cell_z_std && a.low * 10 <= a.n) flat_cells->insert(kv.first);
  }
  const double cell_area = config.cell * config.cell;
  out->area = static_cast<double>(flat_cells->size()) * cell_area;
  const double footprint_area = static_cast<double>(footprint.size()) * cell_area;
  out->found =
      out->area >= config.min_area && out->area >= config.min_area_fraction * footprint_area;
}

}  // namespace

CeilingRemoval RemoveCeiling(const PointCloudInput& input, const CeilingConfig& config) {
  config.Validate();  // before the copy: nothing to do for a bad configuration
  return RemoveCeiling(PointCloudInput(input), config);
}

CeilingRemoval RemoveCeiling(PointCloudInput&& input, const CeilingConfig& config) {
  config.Validate();
  try {
    input.ValidateShape();
  } catch (const InvalidArgument& e) {
    throw InvalidArgument("ceiling removal: " + std::string(e.what()));
  }
  CeilingRemoval out;
  std::unordered_set<std::int64_t> flat_cells;
  FindCeiling(input, config, &out, &flat_cells);
  const std::size_t n = input.points.size();
  if (!out.found) {
    out.kept.resize(n);
    for (std::size_t i = 0; i < n; ++i) out.kept[i] = static_cast<int>(i);
    out.cloud = std::move(input);
    return out;
  }

  // 4. Drop the layer in its flat cells, the top `edge` of it elsewhere (where walls meet the
  // ceiling: the walls stay up to just below it), and everything above it. In place: the
  // kept points move to the front.
  const double zc = out.ceiling_z;
  const bool colours = input.has_colors(), normals = input.has_normals();
  std::size_t w = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p = input.points[i];
    const double d = p.z() - zc;
    const bool ceiling =
        d > config.band || d >= -config.edge ||
        (d >= -config.band && flat_cells.count(CellKey(p.x(), p.y(), config.cell)) > 0);
    if (ceiling) continue;
    out.kept.push_back(static_cast<int>(i));
    input.points[w] = p;
    if (colours) input.colors[w] = input.colors[i];
    if (normals) input.normals[w] = input.normals[i];
    ++w;
  }
  out.removed = n - w;
  input.points.resize(w);
  if (colours) input.colors.resize(w);
  if (normals) input.normals.resize(w);
  out.cloud = std::move(input);
  return out;
}

std::vector<int> ExpandKeptLabels(const std::vector<int>& values, const std::vector<int>& kept,
                                  std::size_t input_size, int fill) {
  if (values.size() != kept.size())
    throw InvalidArgument("ExpandKeptLabels: " + std::to_string(values.size()) + " values for " +
                          std::to_string(kept.size()) + " kept points");
  std::vector<int> out(input_size, fill);
  for (std::size_t j = 0; j < kept.size(); ++j) {
    if (kept[j] < 0 || static_cast<std::size_t>(kept[j]) >= input_size)
      throw InvalidArgument("ExpandKeptLabels: kept index " + std::to_string(kept[j]) +
                            " outside the input's " + std::to_string(input_size) + " points");
    out[static_cast<std::size_t>(kept[j])] = values[j];
  }
  return out;
}

std::vector<int> ExpandKeptPoints(const std::vector<int>& points, const std::vector<int>& kept) {
  std::vector<int> out;
  out.reserve(points.size());
  for (int p : points) {
    if (p < 0 || static_cast<std::size_t>(p) >= kept.size())
      throw InvalidArgument("ExpandKeptPoints: point " + std::to_string(p) + " outside the " +
                            std::to_string(kept.size()) + " kept points");
    out.push_back(kept[static_cast<std::size_t>(p)]);
  }
  return out;
}

}  // namespace dimr::pipeline
