#include "dimr/pipeline/point_cloud_input.h"

#include <cmath>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {

namespace {
std::string Who(const std::string& name) {
  return "point cloud" + (name.empty() ? std::string() : " '" + name + "'");
}
}  // namespace

void PointCloudInput::ValidateShape() const {
  const std::string who = Who(name);
  const std::size_t n = points.size();
  if (!colors.empty() && colors.size() != n) {
    throw InvalidArgument(who + ": " + std::to_string(colors.size()) + " colours for " +
                          std::to_string(n) + " points");
  }
  if (!normals.empty() && normals.size() != n) {
    throw InvalidArgument(who + ": " + std::to_string(normals.size()) + " normals for " +
                          std::to_string(n) + " points");
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument(who + ": point " + std::to_string(i) + " is not finite");
    }
  }
}

void PointCloudInput::Validate() const {
  const std::string who = Who(name);
  if (points.empty()) throw InvalidArgument(who + " has no points");
  ValidateShape();
  for (std::size_t i = 0; i < colors.size(); ++i) {
    const Eigen::Vector3f& c = colors[i];
    if (!c.allFinite() || c.minCoeff() < 0.0f || c.maxCoeff() > 1.0f) {
      throw InvalidArgument(who + ": colour " + std::to_string(i) +
                            " is not in [0, 1] (colours are RGB fractions, not 0..255)");
    }
  }
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const float len = normals[i].norm();
    if (!normals[i].allFinite() || (len != 0.0f && std::abs(len - 1.0f) > 0.01f)) {
      throw InvalidArgument(who + ": normal " + std::to_string(i) +
                            " is neither unit length nor zero");
    }
  }
}

void PointCloudInput::Rotate(const Eigen::Matrix3f& r) {
  for (auto& p : points) p = r * p;
  for (auto& n : normals) n = r * n;
}

PointCloudInput PointCloudInput::FromPointCloud(const geometry::PointCloud& cloud,
                                                const std::string& name) {
  PointCloudInput in;
  in.name = name;
  in.points.reserve(cloud.points.size());
  for (const auto& p : cloud.points) in.points.push_back(p.cast<float>());
  in.colors.reserve(cloud.colors.size());
  for (const auto& c : cloud.colors) in.colors.push_back(c.cast<float>() / 255.0f);
  in.normals.reserve(cloud.normals.size());
  for (const auto& v : cloud.normals) in.normals.push_back(v.cast<float>());
  return in;
}

}  // namespace dimr::pipeline
