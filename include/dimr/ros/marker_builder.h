// rviz markers of a reconstructed scene, sent as deltas: per instance a TRIANGLE_LIST mesh
// (namespace instances/mesh), an oriented-box LINE_LIST (instances/bbox) and a text label
// (instances/label), all with marker id = instance id (stable across updates). An update sends
// ADD only for new instances or a changed revision, DELETE for vanished ids, and a DELETEALL
// first after Reset() or a mode change; Snapshot() is the full state for a late subscriber.
#pragma once

#include <visualization_msgs/MarkerArray.h>

#include <cstdint>
#include <map>
#include <string>

#include "dimr/SceneMeshes.h"
#include "dimr/ros/node_config.h"

namespace dimr::ros1 {

// Deterministic colours: golden-ratio hue per id, a fixed palette per CAD class / source.
std_msgs::ColorRGBA InstanceColor(std::uint32_t id, double alpha);
std_msgs::ColorRGBA ClassColor(int cad_class, double alpha);
std_msgs::ColorRGBA SourceColor(int source, double alpha);

class MarkerBuilder {
 public:
  static constexpr const char* kMeshNs = "instances/mesh";
  static constexpr const char* kBoxNs = "instances/bbox";
  static constexpr const char* kLabelNs = "instances/label";

  explicit MarkerBuilder(const VisualizationConfig& config = {});

  // The delta from the previously published state to `scene`.
  visualization_msgs::MarkerArray Update(const SceneMeshes& scene);
  // DELETEALL followed by the markers of every current instance.
  visualization_msgs::MarkerArray Snapshot() const;
  // Forgets the state; the next Update() starts with DELETEALL.
  void Reset();
  std::size_t size() const { return state_.size(); }

 private:
  struct Published {
    std::uint32_t revision = 0;
    std::vector<visualization_msgs::Marker> markers;  // the ADD markers of this instance
  };
  std::vector<visualization_msgs::Marker> Build(const InstanceMesh& inst,
                                                const std_msgs::Header& header) const;
  VisualizationConfig config_;
  std::map<std::uint32_t, Published> state_;
  std_msgs::Header header_;
  bool delete_all_next_ = true;
};

}  // namespace dimr::ros1
