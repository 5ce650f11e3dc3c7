// Stage1PointRows (include/dimr/nn/stage1_model.h): the per-row probability tables of stage 1.
#include <algorithm>
#include <string>
#include <utility>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_model.h"

namespace dimr::nn {

std::size_t CheckPointRows(const std::string& who, const char* table, std::size_t table_size,
                           std::size_t dim, std::size_t points,
                           const std::vector<std::int64_t>& point_row) {
  if (point_row.empty()) {
    if (table_size != points * dim) {
      throw InvalidArgument(who + ": " + table + " has " + std::to_string(table_size) +
                            " values, expected " + std::to_string(points * dim) +
                            " (no point_row map)");
    }
    return points;
  }
  if (dim == 0 || point_row.size() != points || table_size % dim != 0) {
    throw InvalidArgument(who + ": point_row has " + std::to_string(point_row.size()) +
                          " entries for " + std::to_string(points) + " points, " + table + " " +
                          std::to_string(table_size) + " values (rows of " + std::to_string(dim) +
                          ")");
  }
  const std::size_t rows = table_size / dim;
  for (std::size_t i = 0; i < points; ++i) {
    if (point_row[i] < 0 || static_cast<std::size_t>(point_row[i]) >= rows) {
      throw InvalidArgument(who + ": point_row[" + std::to_string(i) +
                            "] = " + std::to_string(point_row[i]) + " is not in [0, " +
                            std::to_string(rows) + ")");
    }
  }
  return rows;
}

void Stage1PointRows::CheckShape(const std::string& who, std::size_t points, int classes) const {
  if (classes < 1) {
    throw InvalidArgument(who + ": " + std::to_string(classes) + " classes (must be >= 1)");
  }
  const std::size_t rows = CheckPointRows(who, "semantic_prob", semantic_prob.size(),
                                          static_cast<std::size_t>(classes), points, point_row);
  const auto check = [&](const char* name, std::size_t got) {
    if (got != rows * kHeadingBins) {
      throw InvalidArgument(who + ": " + name + " has " + std::to_string(got) + " values, " +
                            std::to_string(rows) + " rows x 12 expected");
    }
  };
  check("heading_prob", heading_prob.size());
  check("heading_residual", heading_residual.size());
}

void Stage1PointRows::ExpandToPoints(std::size_t points, int classes) {
  CheckShape("Stage1PointRows::ExpandToPoints", points, classes);
  if (point_row.empty()) return;
  const auto spread = [&](std::vector<float>* table, std::size_t dim) {
    std::vector<float> out(points * dim);
    for (std::size_t i = 0; i < points; ++i) {
      const float* src = table->data() + static_cast<std::size_t>(point_row[i]) * dim;
      std::copy(src, src + dim, out.data() + i * dim);
    }
    *table = std::move(out);
  };
  spread(&semantic_prob, static_cast<std::size_t>(classes));
  spread(&heading_prob, kHeadingBins);
  spread(&heading_residual, kHeadingBins);
  point_row.clear();
}

}  // namespace dimr::nn
