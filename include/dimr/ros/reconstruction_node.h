// The reconstruction node: PointCloud2 in (through a tf2 MessageFilter into fixed_frame), the
// scene backend (pipeline::Reconstructor) on a worker thread, SceneMeshes / MarkerArray /
// segmented cloud / diagnostics out, mode and query services. The ROS-facing class of the
// voxblox pattern: the constructor takes the core config and a backend; the nodelet reads the
// parameters into them (ReadNodeParams) and fails loudly on a bad value. Used by the nodelet
// `dimr/ReconstructionNodelet` and the standalone `dimr_node` (docs/ros.md).
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/message_filter.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "dimr/GetInstance.h"
#include "dimr/GetPoolModel.h"
#include "dimr/GetScene.h"
#include "dimr/SaveScene.h"
#include "dimr/SceneMeshes.h"
#include "dimr/SetMode.h"
#include "dimr/ros/callback_gate.h"
#include "dimr/ros/cloud_conversion.h"
#include "dimr/ros/instance_tracker.h"
#include "dimr/ros/job_queue.h"
#include "dimr/ros/marker_builder.h"
#include "dimr/ros/node_config.h"
#include "dimr/ros/scan_map.h"
#include "dimr/ros/scene_backend.h"

namespace dimr::ros1 {

class ReconstructionNode {
 public:
  // Validates `config` (throws dimr::InvalidArgument naming the field), advertises topics and
  // services on `nh` (topics) / `pnh` (services), starts the worker. `initial_mode` and
  // `initial_k` are the backend's current mode and projection k.
  ReconstructionNode(ros::NodeHandle nh, ros::NodeHandle pnh, const NodeConfig& config,
                     std::unique_ptr<SceneBackend> backend, ShapeMode initial_mode, int initial_k);
  // Shutdown order: in-flight callbacks (gate_), the worker, timers, the MessageFilter, the
  // subscriber.
  ~ReconstructionNode();

  ReconstructionNode(const ReconstructionNode&) = delete;
  ReconstructionNode& operator=(const ReconstructionNode&) = delete;

 private:
  struct Job {
    sensor_msgs::PointCloud2ConstPtr msg;
    Eigen::Isometry3d to_fixed = Eigen::Isometry3d::Identity();
    ros::WallTime received;
    bool reprocess = false;
    std::uint64_t epoch = 0;
  };
  // What the worker keeps of the last processed cloud (get_instance points, reprocess,
  // segmented_cloud).
  struct LastInput {
    BackendCloud cloud;
    std_msgs::Header header;
  };

  void OnCloud(const sensor_msgs::PointCloud2ConstPtr& msg);
  void OnTfFailure(const sensor_msgs::PointCloud2ConstPtr& msg,
                   tf2_ros::filter_failure_reasons::FilterFailureReason reason);
  void OnRaw(const sensor_msgs::PointCloud2ConstPtr& msg);  // subscriber callback
  void CheckTfTimeouts(const ros::WallTimerEvent&);
  void Enqueue(const sensor_msgs::PointCloud2ConstPtr& msg, const Eigen::Isometry3d& to_fixed,
               bool reprocess);
  std::string TfProblem(const std_msgs::Header& header, const std::string& frame) const;
  void WorkerLoop();
  void Process(const Job& job);
  void Reconstruct(const BackendCloud& cloud, const std_msgs::Header& header,
                   const ros::WallTime& received, std::uint64_t epoch);
  void PublishPending(const ros::WallTimerEvent&);
  void PublishLocked();
  void PublishSegmentedCloud();
  void OnMarkerSubscriber(const ros::SingleSubscriberPublisher& pub);
  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);
  void NoteIssue(const std::string& code, const std::string& message);

  bool SetModeCb(SetMode::Request& req, SetMode::Response& res);
  bool ResetCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool ReprocessCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool GetSceneCb(GetScene::Request& req, GetScene::Response& res);
  bool GetInstanceCb(GetInstance::Request& req, GetInstance::Response& res);
  bool GetPoolModelCb(GetPoolModel::Request& req, GetPoolModel::Response& res);
  bool SaveSceneCb(SaveScene::Request& req, SaveScene::Response& res);

  ros::NodeHandle nh_, pnh_;
  NodeConfig config_;
  InputMode input_mode_;

  // Used by the worker thread only, except the const queries (PoolModel for services).
  std::unique_ptr<SceneBackend> backend_;
  std::string model_version_, pool_id_;
  bool has_pool_ = false;

  // TF + input.
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Subscriber cloud_sub_;  // -> (frame override) -> tf_filter_
  std::unique_ptr<tf2_ros::MessageFilter<sensor_msgs::PointCloud2>> tf_filter_;
  ros::WallTimer tf_timer_;
  // Clouds waiting in the MessageFilter (arrival wall time) and those that timed out.
  std::map<const sensor_msgs::PointCloud2*, ros::WallTime> waiting_;
  std::mutex waiting_mutex_;

  // Worker.
  JobQueue<Job> queue_;
  std::thread worker_;
  std::atomic<bool> stop_{false};

  // Scene state (guarded by state_mutex_).
  std::mutex state_mutex_;
  std::uint64_t epoch_ = 0;                  // bumped by reset: in-flight results are discarded
  int mode_ = SceneMeshes::MODE_GENERATION;  // active mode
  int pending_mode_ = -1, pending_k_ = 0;    // applied by the worker before its next run
  int projection_k_ = 1;
  InstanceTracker tracker_;
  MarkerBuilder markers_;
  std::unique_ptr<ScanMap> scan_map_;  // guarded by map_mutex_
  std::mutex map_mutex_;
  SceneMeshes scene_;  // last published (or pending) scene
  BackendResult last_result_;
  std::vector<std::uint32_t> last_ids_;
  std::shared_ptr<LastInput> last_input_;
  sensor_msgs::PointCloud2ConstPtr last_msg_;
  Eigen::Isometry3d last_to_fixed_ = Eigen::Isometry3d::Identity();
  bool pending_publish_ = false;
  ros::WallTime last_publish_;
  double last_processed_stamp_ = -1e300, last_scan_reconstruct_stamp_ = -1e300;
  std::uint32_t scene_revision_ = 0;

  // Outputs.
  ros::Publisher scene_pub_, marker_pub_, segmented_pub_;
  ros::WallTimer publish_timer_, diag_timer_;
  std::vector<ros::ServiceServer> services_;
  diagnostic_updater::Updater diagnostics_;

  // Statistics (guarded by stats_mutex_).
  std::mutex stats_mutex_;
  std::size_t received_ = 0, processed_ = 0, tf_failures_ = 0, tf_timeouts_ = 0, failed_ = 0;
  std::map<std::string, std::size_t> issues_;  // cloud issue code -> count
  std::string last_issue_;
  double last_latency_ = 0, last_processing_ = 0, max_callback_ms_ = 0;
  std::size_t last_voxel_in_ = 0, last_voxel_out_ = 0;  // input_voxel_size filter
  std::size_t last_ceiling_removed_ = 0;                // remove_ceiling: points dropped
  std::deque<double> arrival_times_;  // wall seconds of the last clouds (input rate)
  std::size_t instances_ = 0, map_scans_ = 0, map_leaves_ = 0, map_bytes_ = 0;
  std::string mode_text_;
  std::string compute_info_;  // backend's compute path (diagnostics `compute`)

  // Every ROS callback entry point holds an entry; the destructor closes it first. Declared last:
  // destroyed first, after the destructor body has waited on it.
  CallbackGate gate_;
};

}  // namespace dimr::ros1
