// Rosbag writer: a small SynthScan bag read back with rosbag::View and `rosbag info`.
#include "dimr/ros/bag_writer.h"

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

#include "dimr/data/room.h"
#include "dimr/data/scanner.h"
#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

namespace fs = std::filesystem;

data::ScanResult SmallScan(int frames) {
  const data::Room room = data::ComposeRoom(data::RoomConfig(), 21);
  data::ScannerConfig c;
  c.width = 96;
  c.height = 72;
  c.frames = frames;
  c.keep_frames = true;
  return data::ScanRoom(room, c, 3);
}

std::string RunCommand(const std::string& cmd) {
  std::string out;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return out;
  char buf[512];
  while (fgets(buf, sizeof(buf), p)) out += buf;
  pclose(p);
  return out;
}

TEST(BagWriterTest, TopicsCountsAndRosbagInfo) {
  const data::ScanResult scan = SmallScan(12);
  const int n = static_cast<int>(scan.frames.size());
  ASSERT_GE(n, 8);
  const fs::path path =
      fs::temp_directory_path() / ("synth_" + std::to_string(::getpid()) + ".bag");
  BagWriterOptions opt;
  opt.map_cloud_every = 5;
  const BagStats stats = WriteScanBag(path.string(), scan, opt);
  const int expect_map = (n + 4) / 5;
  EXPECT_EQ(stats.tf_messages, n);
  EXPECT_EQ(stats.scan_messages, n);
  EXPECT_EQ(stats.map_messages, expect_map);

  rosbag::Bag bag(path.string(), rosbag::bagmode::Read);
  std::map<std::string, int> counts;
  std::size_t last_map = 0;
  double last_stamp = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    ++counts[m.getTopic()];
    if (m.getTopic() == "/tf") {
      auto tf = m.instantiate<tf2_msgs::TFMessage>();
      ASSERT_TRUE(tf);
      ASSERT_EQ(tf->transforms.size(), 1u);
      EXPECT_EQ(tf->transforms[0].header.frame_id, "map");
      EXPECT_EQ(tf->transforms[0].child_frame_id, "camera");
      EXPECT_GE(m.getTime().toSec(), last_stamp);
      last_stamp = m.getTime().toSec();
    } else {
      auto pc = m.instantiate<sensor_msgs::PointCloud2>();
      ASSERT_TRUE(pc);
      EXPECT_EQ(pc->header.frame_id, m.getTopic() == "/map_cloud" ? "map" : "camera");
      EXPECT_EQ(pc->fields.size(), 4u);
      EXPECT_GT(pc->width, 10u);
      if (m.getTopic() == "/map_cloud") {
        EXPECT_GE(pc->width, last_map);  // the map only grows
        last_map = pc->width;
      }
    }
  }
  bag.close();
  EXPECT_EQ(counts["/tf"], n);
  EXPECT_EQ(counts["/camera/points"], n);
  EXPECT_EQ(counts["/map_cloud"], expect_map);
  EXPECT_EQ(last_map, stats.map_points);

  const std::string info = RunCommand("rosbag info --yaml " + path.string() + " 2>&1");
  EXPECT_NE(info.find("messages: " + std::to_string(2 * n + expect_map)), std::string::npos)
      << info;
  EXPECT_NE(info.find("topic: /camera/points"), std::string::npos) << info;
  EXPECT_NE(info.find("type: sensor_msgs/PointCloud2"), std::string::npos) << info;
  EXPECT_NE(info.find("type: tf2_msgs/TFMessage"), std::string::npos) << info;
  EXPECT_NE(info.find("topic: /map_cloud"), std::string::npos) << info;
  fs::remove(path);
}

TEST(BagWriterTest, Errors) {
  data::ScanResult empty;
  EXPECT_THROW(WriteScanBag("/tmp/x.bag", empty), InvalidArgument);
  const data::ScanResult scan = SmallScan(2);
  try {
    WriteScanBag("/proc/no/such/dir/x.bag", scan);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/no/such/dir/x.bag"), std::string::npos);
  }
  BagWriterOptions opt;
  opt.map_cloud_every = 0;
  EXPECT_THROW(WriteScanBag("/tmp/x.bag", scan, opt), InvalidArgument);
}

}  // namespace
}  // namespace dimr::ros1
