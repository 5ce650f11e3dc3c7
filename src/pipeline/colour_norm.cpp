#include "dimr/pipeline/colour_norm.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "dimr/core/config_fields.h"
#include "dimr/geometry/error.h"

namespace dimr::pipeline {

ColourStats ColourRange::Nearest(const ColourStats& s) const {
  ColourStats t;
  t.mean = s.mean.cwiseMax(mean_min).cwiseMin(mean_max);
  t.std = s.std.cwiseMax(std_min).cwiseMin(std_max);
  return t;
}

std::string ColourRange::ToString() const {
  std::string out;
  char buf[32];
  for (const Eigen::Vector3f* v : {&mean_min, &mean_max, &std_min, &std_max}) {
    for (int c = 0; c < 3; ++c) {
      std::snprintf(buf, sizeof(buf), "%s%.4f", out.empty() ? "" : ",", (*v)[c]);
      out += buf;
    }
  }
  return out;
}

bool ColourRange::Parse(const std::string& text, ColourRange* out) {
  const std::vector<std::string> items = config::SplitList(text, /*none_is_empty=*/true);
  if (items.empty()) return false;
  if (items.size() != 12) {
    throw InvalidArgument("colour range: " + std::to_string(items.size()) +
                          " values, expected 12 (mean min r,g,b, mean max r,g,b, std min r,g,b, "
                          "std max r,g,b) or none");
  }
  float v[12];
  for (int i = 0; i < 12; ++i) {
    double d = 0;
    if (!config::ParseDouble(items[i], &d) || d < 0 || d > 1) {
      throw InvalidArgument("colour range: '" + items[i] + "' is not a number in [0, 1]");
    }
    v[i] = static_cast<float>(d);
  }
  ColourRange r;
  r.mean_min = Eigen::Vector3f(v[0], v[1], v[2]);
  r.mean_max = Eigen::Vector3f(v[3], v[4], v[5]);
  r.std_min = Eigen::Vector3f(v[6], v[7], v[8]);
  r.std_max = Eigen::Vector3f(v[9], v[10], v[11]);
  for (int c = 0; c < 3; ++c) {
    if (r.mean_min[c] > r.mean_max[c] || r.std_min[c] > r.std_max[c]) {
      throw InvalidArgument("colour range: a minimum is above its maximum (channel " +
                            std::to_string(c) + ")");
    }
    if (!(r.std_max[c] > 0)) throw InvalidArgument("colour range: a largest spread is 0");
  }
  *out = r;
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

ColourRange RangeOfRooms(const std::vector<ColourStats>& rooms) {
  if (rooms.empty()) throw InvalidArgument("colour range: no rooms");
  ColourRange r;
  r.mean_min = r.mean_max = rooms[0].mean;
  r.std_min = r.std_max = rooms[0].std;
  for (const auto& s : rooms) {
    r.mean_min = r.mean_min.cwiseMin(s.mean);
    r.mean_max = r.mean_max.cwiseMax(s.mean);
    r.std_min = r.std_min.cwiseMin(s.std);
    r.std_max = r.std_max.cwiseMax(s.std);
  }
  return r;
}

std::vector<Eigen::Vector3f> StandardiseColours(const std::vector<Eigen::Vector3f>& colours,
                                                const ColourRange& range, bool* changed) {
  if (changed != nullptr) *changed = false;
  if (colours.empty()) return {};
  const ColourStats own = MeasureColourStats(colours);
  const ColourStats target = range.Nearest(own);
  if (target.mean == own.mean && target.std == own.std) return colours;
  if (changed != nullptr) *changed = true;
  Eigen::Vector3f gain, offset;
  for (int c = 0; c < 3; ++c) {
    gain[c] = own.std[c] < 1e-4f ? 1.0f : target.std[c] / own.std[c];
    offset[c] = target.mean[c] - gain[c] * own.mean[c];
  }
  std::vector<Eigen::Vector3f> out(colours.size());
  for (std::size_t i = 0; i < colours.size(); ++i) {
    out[i] = (colours[i].cwiseProduct(gain) + offset).cwiseMax(0.0f).cwiseMin(1.0f);
  }
  return out;
}

}  // namespace dimr::pipeline
