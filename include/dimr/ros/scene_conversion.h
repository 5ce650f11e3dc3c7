// Backend results -> ROS messages: InstanceMesh (pose = the oriented box, mesh vertices in that
// object frame), the segmented cloud (x, y, z, rgb, instance, label), an instance's support
// points, and the tracker input of an instance.
#pragma once

#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>

#include <vector>

#include "dimr/InstanceMesh.h"
#include "dimr/ros/instance_tracker.h"
#include "dimr/ros/node_config.h"
#include "dimr/ros/scene_backend.h"

namespace dimr::ros1 {

// FNV-1a over the mesh's vertex and face bytes (the revision trigger of the tracker).
std::uint64_t MeshHash(const geometry::TriangleMesh& mesh);
TrackInput TrackOf(const BackendInstance& instance);

InstanceMesh ToInstanceMesh(const BackendInstance& instance, std::uint32_t id,
                            std::uint32_t revision, const NodeConfig& config);

// The input cloud with per-point instance id (0 = none), CAD label (-1 = none) and the colour
// of the point's instance (the input colour, or grey, elsewhere). `ids[i]` is the id of
// result.instances[i].
sensor_msgs::PointCloud2 ToSegmentedCloud(const BackendResult& result,
                                          const std::vector<std::uint32_t>& ids,
                                          const BackendCloud& cloud, const NodeConfig& config,
                                          const std_msgs::Header& header);

// The support points of one instance (x, y, z, rgb) in the fixed frame.
sensor_msgs::PointCloud2 SupportCloud(const BackendInstance& instance, const BackendCloud& cloud,
                                      const std_msgs::Header& header);

// A geometry mesh as shape_msgs/Mesh.
shape_msgs::Mesh ToShapeMesh(const geometry::TriangleMesh& mesh);

}  // namespace dimr::ros1
