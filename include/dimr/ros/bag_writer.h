// Rosbag writer for SynthScan scans: what the dimr node consumes, without a ROS master.
// Per scene one bag with
//   /tf             tf2_msgs/TFMessage, map -> camera (optical frame: x right, y down, z forward)
//                   per frame, from the scanner's estimated (possibly drifted) poses;
//   /camera/points  sensor_msgs/PointCloud2 per frame in the camera frame (x, y, z, rgb);
//   /map_cloud      sensor_msgs/PointCloud2 in map: the accumulated frames, voxel-filtered,
//                   published every `map_cloud_every` frames and after the last frame.
// This header is ROS-free; the implementation uses rosbag / roscpp serialisation.
#pragma once

#include <string>

#include "dimr/data/scanner.h"

// Namespace `ros1`, not `ros`: a dimr::ros would shadow ::ros inside dimr (ros::Time,
// ros::NodeHandle).
namespace dimr::ros1 {

struct BagWriterOptions {
  std::string map_frame = "map";
  std::string camera_frame = "camera";
  std::string tf_topic = "/tf";
  std::string scan_topic = "/camera/points";
  std::string map_topic = "/map_cloud";
  double start_time = 1000.0;    // stamp of the first frame (seconds)
  double frame_rate_hz = 5.0;    // frame spacing of the stamps
  int map_cloud_every = 10;      // frames between accumulated-cloud messages
  double map_voxel_size = 0.02;  // voxel filter of the accumulated cloud (metres)
  void Validate() const;         // throws dimr::InvalidArgument naming the field
};

struct BagStats {
  int tf_messages = 0;
  int scan_messages = 0;
  int map_messages = 0;
  std::size_t map_points = 0;  // points of the last accumulated cloud
};

// Writes `scan.frames` (ScannerConfig::keep_frames must have been set) to a new bag at
// `path`. Throws dimr::InvalidArgument when the scan has no frames and dimr::Error naming the
// path when the bag cannot be written.
BagStats WriteScanBag(const std::string& path, const data::ScanResult& scan,
                      const BagWriterOptions& options = {});

}  // namespace dimr::ros1
