// Rosbag writer for SynthScan scans (see bag_writer.h).
#include "dimr/ros/bag_writer.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <rosbag/bag.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstring>
#include <unordered_set>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

using PointVec = std::vector<Eigen::Vector3f>;
using ColorVec = std::vector<geometry::Color>;

sensor_msgs::PointCloud2 MakeCloud(const PointVec& pts, const ColorVec& colors,
                                   const std::string& frame, const ros::Time& stamp) {
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = frame;
  msg.header.stamp = stamp;
  sensor_msgs::PointCloud2Modifier mod(msg);
  mod.setPointCloud2FieldsByString(2, "xyz", "rgb");
  mod.resize(pts.size());
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(pts.size());
  msg.is_dense = true;
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  sensor_msgs::PointCloud2Iterator<std::uint8_t> r(msg, "r"), g(msg, "g"), b(msg, "b");
  for (std::size_t i = 0; i < pts.size(); ++i, ++x, ++y, ++z, ++r, ++g, ++b) {
    *x = pts[i].x();
    *y = pts[i].y();
    *z = pts[i].z();
    *r = colors[i][0];
    *g = colors[i][1];
    *b = colors[i][2];
  }
  return msg;
}

std::uint64_t VoxelKey(const Eigen::Vector3f& p, double inv) {
  auto q = [&](float v) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v * inv)) + (1 << 20)) &
           0x1fffff;
  };
  return q(p.x()) | (q(p.y()) << 21) | (q(p.z()) << 42);
}

}  // namespace

void BagWriterOptions::Validate() const {
  auto fail = [](const std::string& m) { throw InvalidArgument("BagWriterOptions: " + m); };
  if (map_frame.empty() || camera_frame.empty()) fail("frame names must not be empty");
  if (tf_topic.empty() || scan_topic.empty() || map_topic.empty()) fail("topics must not be empty");
  if (!(start_time > 0)) fail("start_time must be > 0 s");
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 1000)) fail("frame_rate_hz must be in (0, 1000]");
  if (map_cloud_every < 1) fail("map_cloud_every must be >= 1");
  if (!(map_voxel_size > 0)) fail("map_voxel_size must be > 0");
}

BagStats WriteScanBag(const std::string& path, const data::ScanResult& scan,
                      const BagWriterOptions& opt) {
  opt.Validate();
  if (scan.frames.empty())
    throw InvalidArgument("WriteScanBag: the scan has no frames (set ScannerConfig::keep_frames)");
  if (!ros::Time::isValid()) ros::Time::init();
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    throw Error("cannot write the bag '" + path + "': " + e.what());
  }
  BagStats stats;
  PointVec map_pts;
  ColorVec map_cols;
  std::unordered_set<std::uint64_t> occupied;
  const double inv = 1.0 / opt.map_voxel_size;
  try {
    for (std::size_t f = 0; f < scan.frames.size(); ++f) {
      const data::ScanFrame& frame = scan.frames[f];
      const ros::Time stamp(opt.start_time + static_cast<double>(f) / opt.frame_rate_hz);
      tf2_msgs::TFMessage tf;
      geometry_msgs::TransformStamped t;
      t.header.stamp = stamp;
      t.header.frame_id = opt.map_frame;
      t.child_frame_id = opt.camera_frame;
      const Eigen::Vector3d p = frame.pose.translation();
      const Eigen::Quaterniond q(frame.pose.linear());
      t.transform.translation.x = p.x();
      t.transform.translation.y = p.y();
      t.transform.translation.z = p.z();
      t.transform.rotation.w = q.w();
      t.transform.rotation.x = q.x();
      t.transform.rotation.y = q.y();
      t.transform.rotation.z = q.z();
      tf.transforms.push_back(t);
      bag.write(opt.tf_topic, stamp, tf);
      ++stats.tf_messages;
      bag.write(opt.scan_topic, stamp,
                MakeCloud(frame.points, frame.colors, opt.camera_frame, stamp));
      ++stats.scan_messages;
      const Eigen::Matrix3f r = frame.pose.linear().cast<float>();
      const Eigen::Vector3f tr = frame.pose.translation().cast<float>();
      for (std::size_t i = 0; i < frame.points.size(); ++i) {
        const Eigen::Vector3f w = r * frame.points[i] + tr;
        if (occupied.insert(VoxelKey(w, inv)).second) {
          map_pts.push_back(w);
          map_cols.push_back(frame.colors[i]);
        }
      }
      if ((f + 1) % opt.map_cloud_every == 0 || f + 1 == scan.frames.size()) {
        bag.write(opt.map_topic, stamp, MakeCloud(map_pts, map_cols, opt.map_frame, stamp));
        ++stats.map_messages;
        stats.map_points = map_pts.size();
      }
    }
    bag.close();
  } catch (const rosbag::BagException& e) {
    throw Error("error writing the bag '" + path + "': " + e.what());
  }
  return stats;
}

}  // namespace dimr::ros1
