// OctoMap scan integration (see scan_map.h).
#include "dimr/ros/scan_map.h"

#include <octomap/ColorOcTree.h>

#include <algorithm>
#include <cmath>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {

struct ScanMap::Impl {
  explicit Impl(double res) : tree(res) {}
  octomap::ColorOcTree tree;
};

ScanMap::ScanMap(const ScanMapConfig& config) : config_(config) {
  config_.Validate();
  impl_ = std::make_unique<Impl>(config_.resolution);
  impl_->tree.setOccupancyThres(config_.occupancy_threshold);
}

ScanMap::~ScanMap() = default;

void ScanMap::Clear() {
  impl_ = std::make_unique<Impl>(config_.resolution);
  impl_->tree.setOccupancyThres(config_.occupancy_threshold);
  scans_ = 0;
  has_bounds_ = false;
}

std::size_t ScanMap::leaf_count() const { return impl_->tree.getNumLeafNodes(); }
std::size_t ScanMap::memory_bytes() const { return impl_->tree.memoryUsage(); }

ScanInsertStats ScanMap::Insert(const std::vector<Eigen::Vector3f>& points,
                                const std::vector<Eigen::Vector3f>& colors,
                                const Eigen::Vector3f& origin) {
  if (!origin.allFinite()) throw InvalidArgument("ScanMap::Insert: non-finite sensor origin");
  if (!colors.empty() && colors.size() != points.size())
    throw InvalidArgument("ScanMap::Insert: " + std::to_string(colors.size()) + " colours for " +
                          std::to_string(points.size()) + " points");
  octomap::ColorOcTree& tree = impl_->tree;
  if (!has_bounds_) {
    const float h = static_cast<float>(config_.max_extent / 2);
    bmin_ = origin.array() - h;
    bmax_ = origin.array() + h;
    has_bounds_ = true;
    octomap::point3d lo(bmin_.x(), bmin_.y(), bmin_.z()), hi(bmax_.x(), bmax_.y(), bmax_.z());
    tree.setBBXMin(lo);
    tree.setBBXMax(hi);
    tree.useBBXLimit(true);
  }
  ScanInsertStats st;
  octomap::Pointcloud cloud;
  cloud.reserve(points.size());
  std::vector<std::size_t> kept;
  kept.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    if (!p.allFinite() || (p.array() < bmin_.array()).any() || (p.array() > bmax_.array()).any()) {
      ++st.out_of_bounds;
      continue;
    }
    cloud.push_back(p.x(), p.y(), p.z());
    kept.push_back(i);
  }
  st.inserted = kept.size();
  const octomap::point3d o(origin.x(), origin.y(), origin.z());
  if (config_.ray_casting) {
    tree.insertPointCloud(cloud, o, config_.max_range, /*lazy_eval=*/false, /*discretize=*/true);
  } else {
    const double r2 = config_.max_range * config_.max_range;
    for (std::size_t k = 0; k < kept.size(); ++k)
      if ((points[kept[k]] - origin).squaredNorm() <= r2)
        tree.updateNode(cloud[k], true, /*lazy_eval=*/false);
  }
  if (!colors.empty()) {
    const double r2 = config_.max_range * config_.max_range;
    for (std::size_t k = 0; k < kept.size(); ++k) {
      if ((points[kept[k]] - origin).squaredNorm() > r2) continue;
      const Eigen::Vector3f& c = colors[kept[k]];
      auto u8 = [](float v) {
        return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
      };
      octomap::OcTreeKey key;
      if (tree.coordToKeyChecked(cloud[k], key))
        tree.averageNodeColor(key, u8(c.x()), u8(c.y()), u8(c.z()));
    }
  }
  ++scans_;
  return st;
}

void ScanMap::ExtractOccupied(std::vector<Eigen::Vector3f>* points,
                              std::vector<Eigen::Vector3f>* colors) const {
  points->clear();
  colors->clear();
  const octomap::ColorOcTree& tree = impl_->tree;
  std::vector<Eigen::Vector3f> p;
  std::vector<Eigen::Vector3f> c;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const octomap::point3d q = it.getCoordinate();
    p.emplace_back(q.x(), q.y(), q.z());
    const octomap::ColorOcTreeNode::Color col = it->getColor();
    c.emplace_back(col.r / 255.0f, col.g / 255.0f, col.b / 255.0f);
  }
  // Evenly spaced indices: exactly min(n, cap) cells.
  const std::size_t n = p.size();
  const std::size_t cap = std::min(n, static_cast<std::size_t>(config_.max_occupied_cells));
  points->reserve(cap);
  colors->reserve(cap);
  for (std::size_t k = 0; k < cap; ++k) {
    const std::size_t i = k * n / cap;
    points->push_back(p[i]);
    colors->push_back(c[i]);
  }
}

}  // namespace dimr::ros1
