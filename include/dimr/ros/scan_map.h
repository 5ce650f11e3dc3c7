// OctoMap integration of per-frame sensor scans (`input_mode: scans`): each scan is inserted
// with its sensor origin (ray casting clears free space, marks end points occupied, colours
// averaged per leaf), and the occupied leaves become the cloud that the pipeline reconstructs.
// Memory is bounded: the map lives inside a cube of side `max_extent` around the first sensor
// origin (end points and ray segments outside are ignored), and at most `max_occupied_cells`
// leaves are extracted. ROS-free (OctoMap behind a pimpl).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "dimr/ros/node_config.h"

namespace dimr::ros1 {

struct ScanInsertStats {
  std::size_t inserted = 0;       // end points handed to OctoMap
  std::size_t out_of_bounds = 0;  // end points outside the map cube (dropped)
};

class ScanMap {
 public:
  explicit ScanMap(const ScanMapConfig& config);
  ~ScanMap();
  ScanMap(const ScanMap&) = delete;
  ScanMap& operator=(const ScanMap&) = delete;

  // `points` (and optional `colors` in [0, 1], same length or empty) in the map frame,
  // `origin` the sensor position in the map frame. Throws dimr::InvalidArgument on a
  // non-finite origin or mismatched colours.
  ScanInsertStats Insert(const std::vector<Eigen::Vector3f>& points,
                         const std::vector<Eigen::Vector3f>& colors, const Eigen::Vector3f& origin);
  // Centres of the occupied leaves and their colours (uniformly subsampled to at most
  // max_occupied_cells), in a deterministic order.
  void ExtractOccupied(std::vector<Eigen::Vector3f>* points,
                       std::vector<Eigen::Vector3f>* colors) const;
  void Clear();

  std::size_t scans() const { return scans_; }
  std::size_t leaf_count() const;
  std::size_t memory_bytes() const;
  bool has_bounds() const { return has_bounds_; }
  Eigen::Vector3f bounds_min() const { return bmin_; }
  Eigen::Vector3f bounds_max() const { return bmax_; }

 private:
  struct Impl;
  ScanMapConfig config_;
  std::unique_ptr<Impl> impl_;
  std::size_t scans_ = 0;
  bool has_bounds_ = false;
  Eigen::Vector3f bmin_ = Eigen::Vector3f::Zero(), bmax_ = Eigen::Vector3f::Zero();
};

}  // namespace dimr::ros1
