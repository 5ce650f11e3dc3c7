// Stable instance ids across reconstructions. Every reconstruction of a growing or re-sent
// map produces a fresh list of instances; the tracker gives each the id of the instance it
// continues, so that rviz markers, InstanceMesh.id and the get_instance service refer to the
// same object from one update to the next. ROS-free.
//
// Association rule (docs/ros.md): a new instance i and a tracked instance j are a candidate
// pair when they have the same CAD class and either their oriented boxes overlap with
// IoU >= min_iou, or their box centres are at most max_center_distance apart. Candidate pairs
// are taken greedily by decreasing IoU (ties: increasing centre distance, then lower indices),
// each instance and each track at most once. Unmatched new instances get fresh ids (1, 2, ...,
// never reused, also not after Reset()); tracks without a match are removed and reported.
#pragma once

#include <cstdint>
#include <vector>

#include "dimr/geometry/oriented_box.h"
#include "dimr/ros/node_config.h"

namespace dimr::ros1 {

struct TrackInput {
  int cad_class = 0;
  geometry::OrientedBox box;
  std::uint64_t content_hash = 0;  // e.g. of the mesh; a change bumps the revision
};

struct TrackResult {
  std::vector<std::uint32_t> ids;        // per input, in input order
  std::vector<std::uint32_t> revisions;  // per input: 0 for a new id, +1 on every change
  std::vector<std::uint32_t> removed;    // ids tracked before and not matched now (ascending)
  int matched = 0;
};

class InstanceTracker {
 public:
  explicit InstanceTracker(const AssociationConfig& config = {});
  TrackResult Update(const std::vector<TrackInput>& instances);
  // Forgets every track (the next update assigns only fresh ids).
  void Reset();
  std::size_t size() const { return tracks_.size(); }
  std::uint32_t next_id() const { return next_id_; }

 private:
  struct Track {
    std::uint32_t id = 0;
    std::uint32_t revision = 0;
    TrackInput last;
  };
  AssociationConfig config_;
  std::vector<Track> tracks_;
  std::uint32_t next_id_ = 1;
};

}  // namespace dimr::ros1
