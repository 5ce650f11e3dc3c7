// Stage1PointRows (include/dimr/nn/stage1_model.h): the per-row probability tables of stage 1.
#include <algorithm>
#include <string>
#include <utility>

#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_model.h"

namespace dimr::nn {

void Stage1PointRows::CheckShape(const std::string& who, std::size_t points, int classes) const {
  const std::size_t c = static_cast<std::size_t>(classes);
  if (classes < 1 || semantic_prob.size() % c != 0) {
    throw InvalidArgument(who + ": semantic_prob has " + std::to_string(semantic_prob.size()) +
                          " values, not whole rows of " + std::to_string(classes) + " classes");
  }
  const std::size_t rows = semantic_prob.size() / c;
  const auto check = [&](const char* name, std::size_t got) {
    if (got != rows * kHeadingBins) {
      throw InvalidArgument(who + ": " + name + " has " + std::to_string(got) + " values, " +
                            std::to_string(rows) + " rows x 12 expected");
    }
  };
  check("heading_prob", heading_prob.size());
  check("heading_residual", heading_residual.size());
  if (point_row.empty()) {
    if (rows != points) {
      throw InvalidArgument(who + ": " + std::to_string(rows) + " probability rows for " +
                            std::to_string(points) + " points and no point_row map");
    }
    return;
  }
  if (point_row.size() != points) {
    throw InvalidArgument(who + ": point_row has " + std::to_string(point_row.size()) +
                          " entries for " + std::to_string(points) + " points");
  }
  for (std::size_t i = 0; i < points; ++i) {
    if (point_row[i] < 0 || static_cast<std::size_t>(point_row[i]) >= rows) {
      throw InvalidArgument(who + ": point_row[" + std::to_string(i) +
                            "] = " + std::to_string(point_row[i]) + " is not in [0, " +
                            std::to_string(rows) + ")");
    }
  }
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
