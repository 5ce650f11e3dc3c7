// rostest with the real default models: a SynthScan room is generated, written to a rosbag
// (dimr synth --bags), and its accumulated /map_cloud messages are replayed into the
// dimr/ReconstructionNodelet loaded in a nodelet manager (reconstruction.test). Asserts, with
// the tolerances stated in docs/ros.md:
//   - scene_meshes is in `map` with the stamp of the last cloud, and its instances match the
//     room's CAD objects (same class, box centre within 0.35 m in xy): recall over the
//     well-observed ones (visible fraction >= 0.3, >= 500 points) >= 0.5, precision (predictions
//     that are one of the room's CAD objects, however little of it was seen) >= 0.5;
//   - the same room sent again with 5 mm noise keeps the ids of the matched instances;
//   - set_mode projection works with the default pool and changes the source;
//   - get_instance / save_scene return real meshes; reset clears.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_srvs/Trigger.h>
#include <unistd.h>

#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <random>

#include "dimr/GetInstance.h"
#include "dimr/SaveScene.h"
#include "dimr/SceneMeshes.h"
#include "dimr/SetMode.h"
#include "dimr/data/synthscan.h"
#include "dimr/ros/bag_writer.h"

namespace dimr::ros1 {
namespace {

namespace fs = std::filesystem;

struct Fixture {
  data::GeneratedScene scene;
  std::vector<sensor_msgs::PointCloud2> map_clouds;
};

Fixture& Room() {
  static Fixture f = [] {
    Fixture x;
    data::SynthConfig c;
    c.scanner.keep_frames = true;
    c.scanner.frames = 40;
    x.scene = data::GenerateScene(c, data::SceneSeed(7, "val", 0), "scene_rostest");
    const fs::path bag =
        fs::temp_directory_path() / ("dimr_rt_" + std::to_string(getpid()) + ".bag");
    BagWriterOptions o;
    o.map_cloud_every = 20;
    WriteScanBag(bag.string(), x.scene.scan, o);
    rosbag::Bag b(bag.string(), rosbag::bagmode::Read);
    for (const rosbag::MessageInstance& m : rosbag::View(b, rosbag::TopicQuery("/map_cloud")))
      if (auto pc = m.instantiate<sensor_msgs::PointCloud2>()) x.map_clouds.push_back(*pc);
    b.close();
    fs::remove(bag);
    return x;
  }();
  return f;
}

class Reconstruction : public ::testing::Test {
 protected:
  void SetUp() override {
    pub_ = nh_.advertise<sensor_msgs::PointCloud2>("/map_cloud", 2);
    sub_ = nh_.subscribe<SceneMeshes>("/scene_meshes", 5, [this](const auto& m) {
      std::lock_guard<std::mutex> l(mu_);
      scenes_.push_back(*m);
      cv_.notify_all();
    });
    ASSERT_TRUE(ros::service::waitForService("/dimr/set_mode", 120000)) << "node did not start";
    for (int i = 0; i < 200 && pub_.getNumSubscribers() == 0; ++i) ros::WallDuration(0.05).sleep();
    ASSERT_GT(pub_.getNumSubscribers(), 0u);
  }
  SceneMeshes Send(const sensor_msgs::PointCloud2& cloud) {
    std::unique_lock<std::mutex> l(mu_);
    const std::size_t n = scenes_.size();
    l.unlock();
    pub_.publish(cloud);
    l.lock();
    cv_.wait_for(l, std::chrono::seconds(400), [&] {
      return scenes_.size() > n && scenes_.back().header.stamp == cloud.header.stamp;
    });
    EXPECT_FALSE(scenes_.empty());
    return scenes_.empty() ? SceneMeshes() : scenes_.back();
  }
  // Matches predictions to GT CAD objects (only well-observed ones unless `all`): same class,
  // centre within 0.35 m (xy), greedy in GT order. Returns (gt index -> prediction index).
  static std::map<int, int> Match(const SceneMeshes& s, int* gt_count, bool all = false) {
    const auto& inst = Room().scene.scene.instances;
    std::map<int, int> m;
    std::set<int> used;
    *gt_count = 0;
    for (std::size_t g = 0; g < inst.size(); ++g) {
      if (inst[g].cad_class < 0) continue;
      if (!all && (inst[g].visible_fraction < 0.3 || inst[g].num_points < 500)) continue;
      ++*gt_count;
      double best = 0.35;
      int who = -1;
      for (std::size_t p = 0; p < s.instances.size(); ++p) {
        if (used.count(static_cast<int>(p)) || s.instances[p].class_id != inst[g].cad_class)
          continue;
        const double d = std::hypot(s.instances[p].pose.position.x - inst[g].box.center.x(),
                                    s.instances[p].pose.position.y - inst[g].box.center.y());
        if (d < best) {
          best = d;
          who = static_cast<int>(p);
        }
      }
      if (who >= 0) {
        m[static_cast<int>(g)] = who;
        used.insert(who);
      }
    }
    return m;
  }

  ros::NodeHandle nh_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<SceneMeshes> scenes_;
};

TEST_F(Reconstruction, RealModelsOnASynthScanBag) {
  Fixture& room = Room();
  ASSERT_FALSE(room.map_clouds.empty());
  const sensor_msgs::PointCloud2& last = room.map_clouds.back();
  const SceneMeshes s = Send(last);
  EXPECT_EQ(s.header.frame_id, "map");
  EXPECT_EQ(s.header.stamp, last.header.stamp);
  EXPECT_EQ(s.mode, SceneMeshes::MODE_GENERATION);
  ASSERT_FALSE(s.instances.empty());
  int gt = 0;
  const auto match = Match(s, &gt);
  ASSERT_GT(gt, 0);
  const double recall = double(match.size()) / gt;
  int gt_all = 0;
  const double precision = double(Match(s, &gt_all, true).size()) / s.instances.size();
  std::printf(
      "real models: %u input points -> %zu instances; %d well-observed of %d GT CAD objects;"
      " recall %.2f, precision %.2f; processing %.1f s\n",
      s.input_points, s.instances.size(), gt, gt_all, recall, precision, s.processing_time);
  RecordProperty("recall", std::to_string(recall));
  RecordProperty("precision", std::to_string(precision));
  EXPECT_GE(recall, 0.5);
  EXPECT_GE(precision, 0.5);
  for (const InstanceMesh& m : s.instances) {
    EXPECT_GT(m.mesh.triangles.size(), 10u) << m.id;
    EXPECT_EQ(m.source, InstanceMesh::SOURCE_GENERATED);
  }

  // Ids survive the same room with 5 mm noise.
  sensor_msgs::PointCloud2 noisy = last;
  noisy.header.stamp += ros::Duration(1.0);
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0.0f, 0.005f);
  for (sensor_msgs::PointCloud2Iterator<float> x(noisy, "x"); x != x.end(); ++x) {
    x[0] += n(rng);
    x[1] += n(rng);
    x[2] += n(rng);
  }
  const SceneMeshes s2 = Send(noisy);
  int gt2 = 0;
  const auto match2 = Match(s2, &gt2);
  int kept = 0, both = 0;
  for (const auto& [g, p] : match) {
    auto it = match2.find(g);
    if (it == match2.end()) continue;
    ++both;
    kept += s.instances[p].id == s2.instances[it->second].id;
  }
  ASSERT_GT(both, 0);
  EXPECT_GE(double(kept) / both, 0.8) << kept << " of " << both << " ids kept";

  // get_instance and save_scene: real meshes.
  GetInstance gi;
  gi.request.id = s2.instances[0].id;
  ASSERT_TRUE(ros::service::call("/dimr/get_instance", gi));
  EXPECT_TRUE(gi.response.found);
  EXPECT_GT(gi.response.instance.mesh.triangles.size(), 10u);
  EXPECT_GT(gi.response.points.width, 50u);
  const fs::path dir = fs::temp_directory_path() / ("dimr_rt_save_" + std::to_string(getpid()));
  SaveScene sv;
  sv.request.directory = dir.string();
  ASSERT_TRUE(ros::service::call("/dimr/save_scene", sv));
  EXPECT_TRUE(sv.response.success) << sv.response.message;
  EXPECT_EQ(sv.response.files.size(), s2.instances.size() + 1);
  fs::remove_all(dir);

  // Projection with the default pool.
  SetMode sm;
  sm.request.mode = SetMode::Request::PROJECTION;
  sm.request.projection_k = 3;
  sm.request.reprocess_last = true;
  std::unique_lock<std::mutex> l(mu_);
  const std::size_t before = scenes_.size();
  l.unlock();
  ASSERT_TRUE(ros::service::call("/dimr/set_mode", sm));
  ASSERT_TRUE(sm.response.success) << sm.response.message;
  l.lock();
  cv_.wait_for(l, std::chrono::seconds(400), [&] {
    return scenes_.size() > before && scenes_.back().mode == SceneMeshes::MODE_PROJECTION;
  });
  ASSERT_GT(scenes_.size(), before);
  const SceneMeshes p = scenes_.back();
  l.unlock();
  EXPECT_EQ(p.mode, SceneMeshes::MODE_PROJECTION);
  EXPECT_FALSE(p.pool_id.empty());
  for (const InstanceMesh& m : p.instances) {
    EXPECT_EQ(m.source, InstanceMesh::SOURCE_PROJECTED);
    EXPECT_FALSE(m.neighbor_ids.empty());
  }

  std_srvs::Trigger t;
  ASSERT_TRUE(ros::service::call("/dimr/reset", t));
  EXPECT_TRUE(t.response.success);
}

}  // namespace
}  // namespace dimr::ros1

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "dimr_reconstruction_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int rc = RUN_ALL_TESTS();
  ros::shutdown();
  return rc;
}
