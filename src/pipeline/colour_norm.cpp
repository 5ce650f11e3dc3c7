#include "dimr/pipeline/colour_norm.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"

namespace dimr::pipeline {

std::string ColourStats::ToString() const {
  char buf[128];
  std::snprintf(buf, sizeof(buf), "%.4f,%.4f,%.4f,%.4f,%.4f,%.4f", mean.x(), mean.y(), mean.z(),
                std.x(), std.y(), std.z());
  return buf;
}

bool ColourStats::Parse(const std::string& text, ColourStats* out) {
  const std::vector<std::string> items = config::SplitList(text, /*none_is_empty=*/true);
  if (items.empty()) return false;
  if (items.size() != 6) {
    throw InvalidArgument("colour statistics: " + std::to_string(items.size()) +
                          " values, expected 6 (mean r,g,b then std r,g,b) or none");
  }
  double v[6];
  for (int i = 0; i < 6; ++i) {
    if (!config::ParseDouble(items[i], &v[i])) {
      throw InvalidArgument("colour statistics: '" + items[i] + "' is not a finite number");
    }
    const bool ok = i < 3 ? (v[i] >= 0 && v[i] <= 1) : (v[i] > 0 && v[i] <= 1);
    if (!ok) {
      throw InvalidArgument("colour statistics: " + std::string(i < 3 ? "mean" : "std") + " '" +
                            items[i] + "' is outside " + (i < 3 ? "[0, 1]" : "(0, 1]"));
    }
  }
  out->mean =
      Eigen::Vector3f(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
  out->std =
      Eigen::Vector3f(static_cast<float>(v[3]), static_cast<float>(v[4]), static_cast<float>(v[5]));
  return true;
}

ColourStats MeasureColourStats(const std::vector<Eigen::Vector3f>& colours) {
  if (colours.empty()) throw InvalidArgument("colour statistics of an empty cloud");
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < colours.size(); ++i) {
    if (!colours[i].allFinite()) {
      throw InvalidArgument("colour statistics: colour " + std::to_string(i) + " is not finite");
    }
    sum += colours[i].cast<double>();
  }
  const double n = static_cast<double>(colours.size());
  const Eigen::Vector3d mean = sum / n;
  Eigen::Vector3d sq = Eigen::Vector3d::Zero();
  for (const auto& c : colours) sq += (c.cast<double>() - mean).cwiseAbs2();
  ColourStats s;
  s.mean = mean.cast<float>();
  s.std = (sq / n).cwiseSqrt().cast<float>();
  return s;
}

ColourStats AverageRoomColourStats(const std::vector<ColourStats>& rooms) {
  if (rooms.empty()) throw InvalidArgument("colour statistics: no rooms");
  ColourStats a;
  for (const auto& r : rooms) {
    a.mean += r.mean;
    a.std += r.std;
  }
  a.mean /= static_cast<float>(rooms.size());
  a.std /= static_cast<float>(rooms.size());
  return a;
}

std::vector<Eigen::Vector3f> StandardiseColours(const std::vector<Eigen::Vector3f>& colours,
                                                const ColourStats& target) {
  if (colours.empty()) return {};
  const ColourStats own = MeasureColourStats(colours);
  Eigen::Vector3f gain, offset;
  for (int c = 0; c < 3; ++c) {
    gain[c] = own.std[c] < 1e-4f ? 0.0f : target.std[c] / own.std[c];
    offset[c] = target.mean[c] - gain[c] * own.mean[c];
  }
  std::vector<Eigen::Vector3f> out(colours.size());
  for (std::size_t i = 0; i < colours.size(); ++i) {
    out[i] = (colours[i].cwiseProduct(gain) + offset).cwiseMax(0.0f).cwiseMin(1.0f);
  }
  return out;
}

}  // namespace dimr::pipeline
