// Stable instance ids (see instance_tracker.h for the rule).
#include "dimr/ros/instance_tracker.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace dimr::ros1 {
namespace {

// The box or the content moved enough to count as a new revision.
bool Changed(const TrackInput& a, const TrackInput& b) {
  constexpr double kEps = 1e-3;  // 1 mm / 1 mrad
  if (a.content_hash != b.content_hash) return true;
  if ((a.box.center - b.box.center).norm() > kEps) return true;
  if ((a.box.size - b.box.size).norm() > kEps) return true;
  return std::abs(std::remainder(a.box.heading - b.box.heading, 2 * M_PI)) > kEps;
}

}  // namespace

InstanceTracker::InstanceTracker(const AssociationConfig& config) : config_(config) {
  config_.Validate();
}

void InstanceTracker::Reset() { tracks_.clear(); }

TrackResult InstanceTracker::Update(const std::vector<TrackInput>& in) {
  struct Pair {
    double iou, dist;
    std::size_t i, j;
  };
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < in.size(); ++i) {
    for (std::size_t j = 0; j < tracks_.size(); ++j) {
      const TrackInput& t = tracks_[j].last;
      if (t.cad_class != in[i].cad_class) continue;
      const double dist = (t.box.center - in[i].box.center).norm();
      const double iou = geometry::BoxIoU(t.box, in[i].box);
      if (iou >= config_.min_iou || dist <= config_.max_center_distance)
        pairs.push_back({iou, dist, i, j});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
    return std::make_tuple(-a.iou, a.dist, a.i, a.j) < std::make_tuple(-b.iou, b.dist, b.i, b.j);
  });
  std::vector<int> track_of(in.size(), -1);
  std::vector<bool> used(tracks_.size(), false);
  TrackResult r;
  for (const Pair& p : pairs) {
    if (track_of[p.i] >= 0 || used[p.j]) continue;
    track_of[p.i] = static_cast<int>(p.j);
    used[p.j] = true;
    ++r.matched;
  }
  for (std::size_t j = 0; j < tracks_.size(); ++j)
    if (!used[j]) r.removed.push_back(tracks_[j].id);
  std::sort(r.removed.begin(), r.removed.end());

  std::vector<Track> next;
  next.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    Track t;
    if (track_of[i] >= 0) {
      t = tracks_[track_of[i]];
      if (Changed(t.last, in[i])) ++t.revision;
    } else {
      t.id = next_id_++;
    }
    t.last = in[i];
    r.ids.push_back(t.id);
    r.revisions.push_back(t.revision);
    next.push_back(t);
  }
  tracks_ = std::move(next);
  return r;
}

}  // namespace dimr::ros1
