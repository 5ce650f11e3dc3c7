// The reconstruction node (see reconstruction_node.h and docs/ros.md).
#include "dimr/ros/reconstruction_node.h"

#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_eigen/tf2_eigen.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "dimr/geometry/error.h"
#include "dimr/ros/density_filter.h"
#include "dimr/ros/scene_conversion.h"
#include "dimr/ros/scene_files.h"

namespace dimr::ros1 {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::size_t RssBytes() {
  std::ifstream f("/proc/self/statm");
  std::size_t pages = 0, rss = 0;
  f >> pages >> rss;
  return rss * static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
}

const char* ModeName(int mode) {
  switch (mode) {
    case SceneMeshes::MODE_GENERATION:
      return "generation";
    case SceneMeshes::MODE_PROJECTION:
      return "projection";
    case SceneMeshes::MODE_RETRIEVAL:
      return "retrieval";
    default:
      return "?";
  }
}

std::string StampText(const ros::Time& t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.3f", t.toSec());
  return buf;
}

}  // namespace

ReconstructionNode::ReconstructionNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                       const NodeConfig& config,
                                       std::unique_ptr<SceneBackend> backend,
                                       ShapeMode initial_mode, int initial_k)
    : nh_(nh),
      pnh_(pnh),
      config_(config),
      input_mode_(config.input()),
      backend_(std::move(backend)),
      queue_(config.input() == InputMode::kScans ? 200 : 1),
      tracker_(config.association),
      markers_(config.visualization),
      diagnostics_(nh, pnh, pnh.getNamespace()) {
  config_.Validate();
  if (!backend_) throw InvalidArgument("ReconstructionNode: no backend");
  model_version_ = backend_->model_version();
  has_pool_ = backend_->has_pool();
  pool_id_ = backend_->pool_id();
  compute_info_ = backend_->compute_info();
  mode_ = static_cast<int>(initial_mode);
  projection_k_ = std::max(1, initial_k);
  mode_text_ = ModeName(mode_);
  if (input_mode_ == InputMode::kScans) scan_map_ = std::make_unique<ScanMap>(config_.scans);

  scene_.header.frame_id = config_.fixed_frame;
  scene_.mode = static_cast<std::uint8_t>(mode_);
  scene_.model_version = model_version_;
  scene_.pool_id = pool_id_;

  scene_pub_ = nh_.advertise<SceneMeshes>("scene_meshes", 1, /*latch=*/true);
  marker_pub_ = nh_.advertise<visualization_msgs::MarkerArray>(
      "instance_markers", 10,
      boost::bind(&ReconstructionNode::OnMarkerSubscriber, this, boost::placeholders::_1));
  segmented_pub_ = nh_.advertise<sensor_msgs::PointCloud2>("segmented_cloud", 1);

  services_.push_back(pnh_.advertiseService("set_mode", &ReconstructionNode::SetModeCb, this));
  services_.push_back(pnh_.advertiseService("reset", &ReconstructionNode::ResetCb, this));
  services_.push_back(pnh_.advertiseService("reprocess", &ReconstructionNode::ReprocessCb, this));
  services_.push_back(pnh_.advertiseService("get_scene", &ReconstructionNode::GetSceneCb, this));
  services_.push_back(
      pnh_.advertiseService("get_instance", &ReconstructionNode::GetInstanceCb, this));
  services_.push_back(
      pnh_.advertiseService("get_pool_model", &ReconstructionNode::GetPoolModelCb, this));
  services_.push_back(pnh_.advertiseService("save_scene", &ReconstructionNode::SaveSceneCb, this));

  diagnostics_.setHardwareID("dimr");
  diagnostics_.add("reconstruction", this, &ReconstructionNode::Diagnose);
  diag_timer_ = nh_.createWallTimer(ros::WallDuration(0.5), [this](const ros::WallTimerEvent&) {
    const CallbackGate::Entry entry(gate_);
    if (entry) diagnostics_.force_update();
  });
  publish_timer_ = nh_.createWallTimer(ros::WallDuration(1.0 / config_.max_publish_rate),
                                       &ReconstructionNode::PublishPending, this);

  tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, nh_);
  tf_filter_ = std::make_unique<tf2_ros::MessageFilter<sensor_msgs::PointCloud2>>(
      *tf_buffer_, config_.fixed_frame, config_.tf_queue_size, nh_);
  tf_filter_->registerCallback(
      boost::bind(&ReconstructionNode::OnCloud, this, boost::placeholders::_1));
  tf_filter_->registerFailureCallback(boost::bind(
      &ReconstructionNode::OnTfFailure, this, boost::placeholders::_1, boost::placeholders::_2));
  tf_timer_ =
      nh_.createWallTimer(ros::WallDuration(0.05), &ReconstructionNode::CheckTfTimeouts, this);

  worker_ = std::thread(&ReconstructionNode::WorkerLoop, this);
  cloud_sub_ = nh_.subscribe("cloud_in", 5, &ReconstructionNode::OnRaw, this,
                             ros::TransportHints().tcpNoDelay());
  ROS_INFO("dimr: ready: %s mode, input_mode %s, fixed_frame '%s', models %s, pool %s",
           ModeName(mode_), config_.input_mode.c_str(), config_.fixed_frame.c_str(),
           model_version_.c_str(), pool_id_.empty() ? "none" : pool_id_.c_str());
  // An empty latched scene, so that a subscriber always gets the current state.
  scene_pub_.publish(scene_);
}

ReconstructionNode::~ReconstructionNode() {
  stop_ = true;
  // First: no callback of a spinner thread may still run (or start) while members go away.
  // (roscpp's stop / shutdown below do not wait for a callback already running; see
  // callback_gate.h.) Then nothing new is dispatched, and the worker ends.
  gate_.CloseAndWait();
  cloud_sub_.shutdown();
  tf_timer_.stop();
  publish_timer_.stop();
  diag_timer_.stop();
  services_.clear();
  queue_.Stop();
  if (worker_.joinable()) worker_.join();
  tf_filter_.reset();
  // A callback that roscpp had dispatched just before the stops above meets the closed gate and
  // returns; wait for it too before the members (the gate included) are destroyed.
  gate_.CloseAndWait();
}

// ---------------------------------------------------------------------------------------------
// Input.

void ReconstructionNode::OnRaw(const sensor_msgs::PointCloud2ConstPtr& msg) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return;
  const auto t0 = std::chrono::steady_clock::now();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++received_;
    arrival_times_.push_back(ros::WallTime::now().toSec());
    while (arrival_times_.size() > 20) arrival_times_.pop_front();
  }
  sensor_msgs::PointCloud2ConstPtr in = msg;
  if (!config_.sensor_frame_override.empty()) {
    auto copy = boost::make_shared<sensor_msgs::PointCloud2>(*msg);
    copy->header.frame_id = config_.sensor_frame_override;
    in = copy;
  }
  if (in->header.frame_id.empty()) {
    NoteIssue("empty_frame_id", "cloud on " + cloud_sub_.getTopic() + " stamped " +
                                    StampText(in->header.stamp) +
                                    " has an empty frame_id (set sensor_frame_override?)");
    return;
  }
  if (!in->header.frame_id.empty() && in->header.frame_id[0] == '/') {
    NoteIssue("bad_frame_id", "frame_id '" + in->header.frame_id +
                                  "' starts with '/': tf2 frame ids have no leading slash");
    return;
  }
  {
    std::lock_guard<std::mutex> lock(waiting_mutex_);
    waiting_[in.get()] = ros::WallTime::now();
  }
  tf_filter_->add(in);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::lock_guard<std::mutex> lock(stats_mutex_);
  max_callback_ms_ = std::max(max_callback_ms_, ms);
}

std::string ReconstructionNode::TfProblem(const std_msgs::Header& header,
                                          const std::string& frame) const {
  std::string age = "no transform between them at all";
  try {
    const geometry_msgs::TransformStamped latest =
        tf_buffer_->lookupTransform(config_.fixed_frame, frame, ros::Time(0));
    char buf[160];
    std::snprintf(buf, sizeof(buf), "newest transform at %.3f, %.3f s %s the cloud",
                  latest.header.stamp.toSec(),
                  std::abs((header.stamp - latest.header.stamp).toSec()),
                  latest.header.stamp < header.stamp ? "older than" : "newer than");
    age = buf;
  } catch (const tf2::TransformException&) {
  }
  return "no TF from '" + frame + "' to '" + config_.fixed_frame + "' at stamp " +
         StampText(header.stamp) + " (" + age +
         "); check use_sim_time / rosbag play --clock, a missing static transform, or "
         "tf_timeout";
}

void ReconstructionNode::OnTfFailure(const sensor_msgs::PointCloud2ConstPtr& msg,
                                     tf2_ros::filter_failure_reasons::FilterFailureReason reason) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return;
  {
    std::lock_guard<std::mutex> lock(waiting_mutex_);
    if (waiting_.erase(msg.get()) == 0) return;  // already reported as timed out
  }
  std::string why = reason == tf2_ros::filter_failure_reasons::OutTheBack
                        ? "older than the TF buffer"
                        : (reason == tf2_ros::filter_failure_reasons::EmptyFrameID
                               ? "empty frame id"
                               : "pushed out of the TF queue");
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++tf_failures_;
  }
  NoteIssue("tf_failure", why + ": " + TfProblem(msg->header, msg->header.frame_id));
}

void ReconstructionNode::CheckTfTimeouts(const ros::WallTimerEvent&) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return;
  std::vector<const sensor_msgs::PointCloud2*> expired;
  const ros::WallTime now = ros::WallTime::now();
  {
    std::lock_guard<std::mutex> lock(waiting_mutex_);
    for (auto it = waiting_.begin(); it != waiting_.end();) {
      if ((now - it->second).toSec() > config_.tf_timeout) {
        expired.push_back(it->first);
        it = waiting_.erase(it);
      } else {
        ++it;
      }
    }
  }
  // The expired clouds stay in the filter until its queue pushes them out; OnCloud ignores
  // them (they are no longer in waiting_). With use_latest_tf_on_failure they are processed
  // here with the newest transform instead.
  for (const sensor_msgs::PointCloud2* raw : expired) {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++tf_timeouts_;
    }
    NoteIssue("tf_timeout", "waited " + std::to_string(config_.tf_timeout) +
                                " s: " + TfProblem(raw->header, raw->header.frame_id));
    if (config_.use_latest_tf_on_failure) {
      try {
        const auto tf =
            tf_buffer_->lookupTransform(config_.fixed_frame, raw->header.frame_id, ros::Time(0));
        auto copy = boost::make_shared<sensor_msgs::PointCloud2>(*raw);
        ROS_WARN_THROTTLE(5.0,
                          "dimr: using the newest transform (stamp %.3f) for a cloud "
                          "stamped %.3f (use_latest_tf_on_failure)",
                          tf.header.stamp.toSec(), raw->header.stamp.toSec());
        Enqueue(copy, tf2::transformToEigen(tf), false);
      } catch (const tf2::TransformException&) {
      }
    }
  }
}

void ReconstructionNode::OnCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return;
  {
    std::lock_guard<std::mutex> lock(waiting_mutex_);
    if (waiting_.erase(msg.get()) == 0) return;  // timed out earlier: reported, not processed
  }
  geometry_msgs::TransformStamped tf;
  try {
    tf = tf_buffer_->lookupTransform(config_.fixed_frame, msg->header.frame_id, msg->header.stamp);
  } catch (const tf2::TransformException& e) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++tf_failures_;
    last_issue_ = std::string("tf_failure: ") + e.what();
    return;
  }
  if (input_mode_ == InputMode::kAccumulated && config_.min_process_interval > 0) {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (msg->header.stamp.toSec() - last_processed_stamp_ < config_.min_process_interval) return;
    last_processed_stamp_ = msg->header.stamp.toSec();
  }
  Enqueue(msg, tf2::transformToEigen(tf), false);
}

void ReconstructionNode::Enqueue(const sensor_msgs::PointCloud2ConstPtr& msg,
                                 const Eigen::Isometry3d& to_fixed, bool reprocess) {
  Job job;
  job.msg = msg;
  job.to_fixed = to_fixed;
  job.received = ros::WallTime::now();
  job.reprocess = reprocess;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    job.epoch = epoch_;
  }
  queue_.Push(std::move(job));
}

// ---------------------------------------------------------------------------------------------
// Worker.

void ReconstructionNode::WorkerLoop() {
  Job job;
  while (!stop_) {
    if (!queue_.Pop(&job, 200ms)) continue;
    try {
      Process(job);
    } catch (const std::exception& e) {
      // Nothing a message does may end the worker.
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++failed_;
      last_issue_ = std::string("pipeline_error: ") + e.what();
      ROS_ERROR_THROTTLE(5.0, "dimr: %s", last_issue_.c_str());
    }
  }
}

void ReconstructionNode::Process(const Job& job) {
  // A mode change requested by set_mode is applied here, on the thread that owns the
  // Reconstructor.
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (pending_mode_ >= 0) {
      const int mode = pending_mode_, k = pending_k_;
      pending_mode_ = -1;  // applied once, also when the backend refuses it
      try {
        backend_->SetMode(static_cast<ShapeMode>(mode), k);
        mode_ = mode;
        projection_k_ = k;
      } catch (const Error& e) {
        NoteIssue("set_mode_failed", e.what());
      }
    }
  }
  const sensor_msgs::PointCloud2& msg = *job.msg;
  DecodeOptions opt;
  opt.crop_min = config_.crop_min;
  opt.crop_max = config_.crop_max;
  opt.max_points = static_cast<std::size_t>(config_.max_input_points);
  if (input_mode_ == InputMode::kScans) opt.max_points = 100000000;  // a scan is not capped
  DecodedCloud decoded;
  try {
    decoded = DecodeCloud(msg, job.to_fixed, opt);
  } catch (const CloudError& e) {
    NoteIssue(CloudIssueName(e.issue()), e.what());
    return;
  }
  for (const std::string& w : decoded.warnings) NoteIssue("cloud_warning", w);
  if (decoded.stride > 1)
    ROS_WARN_THROTTLE(10.0, "dimr: cloud of %zu points subsampled by %zu (max_input_points %d)",
                      decoded.message_points, decoded.stride, config_.max_input_points);

  std_msgs::Header header = msg.header;
  header.frame_id = config_.fixed_frame;
  BackendCloud input;
  if (input_mode_ == InputMode::kScans) {
    {
      std::lock_guard<std::mutex> lock(map_mutex_);
      if (!job.reprocess)
        scan_map_->Insert(decoded.points, decoded.colors, job.to_fixed.translation().cast<float>());
      std::lock_guard<std::mutex> slock(stats_mutex_);
      map_scans_ = scan_map_->scans();
      map_leaves_ = scan_map_->leaf_count();
      map_bytes_ = scan_map_->memory_bytes();
    }
    {
      std::lock_guard<std::mutex> lock(state_mutex_);
      if (job.epoch != epoch_) return;
      if (!job.reprocess && msg.header.stamp.toSec() - last_scan_reconstruct_stamp_ <
                                config_.scans.reconstruct_interval) {
        last_msg_ = job.msg;
        last_to_fixed_ = job.to_fixed;
        return;
      }
      last_scan_reconstruct_stamp_ = msg.header.stamp.toSec();
    }
    std::lock_guard<std::mutex> lock(map_mutex_);
    scan_map_->ExtractOccupied(&input.points, &input.colors);
    input.name = "OctoMap of " + std::to_string(scan_map_->scans()) + " scans";
    if (input.points.empty()) return;
  } else {
    input.points = std::move(decoded.points);
    input.colors = std::move(decoded.colors);
    input.normals = std::move(decoded.normals);
    input.name = "cloud '" + msg.header.frame_id + "' @ " + StampText(msg.header.stamp);
  }
  // No ceiling (stage 1 never saw one), then the density stage 1 was trained on
  // (density_filter.h).
  const CeilingFilterStats cf =
      config_.remove_ceiling ? CeilingFilter(&input) : CeilingFilterStats();
  const VoxelFilterStats vf = VoxelMeanFilter(&input, config_.input_voxel_size);
  if (config_.input_voxel_size > 0 && !vf.applied)
    NoteIssue("cloud_warning", "input_voxel_size " + std::to_string(config_.input_voxel_size) +
                                   " m not applied: the cloud spans more than 2^21 cells");
  {
    std::lock_guard<std::mutex> slock(stats_mutex_);
    last_voxel_in_ = vf.input_points;
    last_voxel_out_ = vf.output_points;
    last_ceiling_removed_ = cf.removed;
  }
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (job.epoch != epoch_) return;  // reset since it was queued
    last_msg_ = job.msg;
    last_to_fixed_ = job.to_fixed;
  }
  Reconstruct(input, header, job.received, job.epoch);
}

void ReconstructionNode::Reconstruct(const BackendCloud& cloud, const std_msgs::Header& header,
                                     const ros::WallTime& received, std::uint64_t epoch) {
  const ros::WallTime t0 = ros::WallTime::now();
  BackendResult result = backend_->Reconstruct(cloud);
  const double processing = (ros::WallTime::now() - t0).toSec();
  for (const std::string& w : result.warnings) NoteIssue("scene_warning", w);

  std::lock_guard<std::mutex> lock(state_mutex_);
  if (epoch != epoch_) return;  // reset while it ran: discard
  std::vector<TrackInput> tracks;
  for (const auto& inst : result.instances) tracks.push_back(TrackOf(inst));
  const TrackResult ids = tracker_.Update(tracks);
  SceneMeshes scene;
  scene.header = header;
  for (std::size_t i = 0; i < result.instances.size(); ++i)
    scene.instances.push_back(
        ToInstanceMesh(result.instances[i], ids.ids[i], ids.revisions[i], config_));
  scene.removed_ids = ids.removed;
  scene.mode = static_cast<std::uint8_t>(mode_);
  scene.scene_revision = ++scene_revision_;
  scene.model_version = model_version_;
  scene.pool_id = pool_id_;
  scene.input_points = static_cast<std::uint32_t>(cloud.points.size());
  scene.processing_time = static_cast<float>(processing);
  scene.latency = static_cast<float>((ros::WallTime::now() - received).toSec());
  scene_ = std::move(scene);
  last_result_ = std::move(result);
  last_ids_ = ids.ids;
  auto input = std::make_shared<LastInput>();
  input->cloud = cloud;
  input->header = header;
  last_input_ = input;
  pending_publish_ = true;
  {
    std::lock_guard<std::mutex> slock(stats_mutex_);
    ++processed_;
    last_latency_ = scene_.latency;
    last_processing_ = processing;
    instances_ = scene_.instances.size();
    mode_text_ = ModeName(mode_);
  }
  if ((ros::WallTime::now() - last_publish_).toSec() >= 1.0 / config_.max_publish_rate)
    PublishLocked();
  if (segmented_pub_.getNumSubscribers() > 0) PublishSegmentedCloud();
}

void ReconstructionNode::PublishPending(const ros::WallTimerEvent&) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return;
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (pending_publish_) PublishLocked();
}

void ReconstructionNode::PublishLocked() {
  pending_publish_ = false;
  last_publish_ = ros::WallTime::now();
  scene_pub_.publish(scene_);
  const visualization_msgs::MarkerArray delta = markers_.Update(scene_);
  if (!delta.markers.empty()) marker_pub_.publish(delta);
}

void ReconstructionNode::OnMarkerSubscriber(const ros::SingleSubscriberPublisher& pub) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return;
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (markers_.size() > 0) pub.publish(markers_.Snapshot());
}

void ReconstructionNode::PublishSegmentedCloud() {
  // Called with state_mutex_ held, only when someone subscribed (lazy).
  if (!last_input_) return;
  segmented_pub_.publish(
      ToSegmentedCloud(last_result_, last_ids_, last_input_->cloud, config_, last_input_->header));
}

// ---------------------------------------------------------------------------------------------
// Services (none of them waits for inference).

bool ReconstructionNode::SetModeCb(SetMode::Request& req, SetMode::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  std::unique_lock<std::mutex> lock(state_mutex_);
  res.previous_mode = static_cast<std::uint8_t>(pending_mode_ >= 0 ? pending_mode_ : mode_);
  res.active_mode = res.previous_mode;
  res.max_publish_rate = config_.max_publish_rate;
  if (req.max_publish_rate != 0 && !(req.max_publish_rate >= 0.01 && req.max_publish_rate <= 100)) {
    res.success = false;
    res.message = "max_publish_rate " + std::to_string(req.max_publish_rate) +
                  " Hz is outside [0.01, 100] (0 = keep)";
    return true;
  }
  if (req.mode > SetMode::Request::RETRIEVAL) {
    res.success = false;
    res.message =
        "unknown mode " + std::to_string(req.mode) + " (0 generation, 1 projection, 2 retrieval)";
    return true;
  }
  std::string why;
  if (!backend_->SupportsMode(static_cast<ShapeMode>(req.mode), &why)) {
    res.success = false;
    res.message = std::string(ModeName(req.mode)) + " is not available: " + why;
    return true;
  }
  const int k = req.projection_k == 0 ? projection_k_ : req.projection_k;
  const bool changed = req.mode != res.previous_mode;
  pending_mode_ = req.mode;
  pending_k_ = k;
  if (changed) markers_.Reset();  // the next publication starts with DELETEALL
  res.success = true;
  res.active_mode = req.mode;
  const bool new_rate = req.max_publish_rate != 0;
  if (new_rate) config_.max_publish_rate = req.max_publish_rate;
  res.max_publish_rate = config_.max_publish_rate;
  res.message = std::string("mode ") + ModeName(req.mode) + ", k " + std::to_string(k) +
                ", max_publish_rate " + std::to_string(config_.max_publish_rate) + " Hz" +
                (req.reprocess_last ? ", reprocessing the last cloud" : "");
  if (req.reprocess_last && last_msg_) {
    Job job;
    job.msg = last_msg_;
    job.to_fixed = last_to_fixed_;
    job.received = ros::WallTime::now();
    job.reprocess = true;
    job.epoch = epoch_;
    queue_.Push(std::move(job));
  }
  const double period = 1.0 / config_.max_publish_rate;
  lock.unlock();  // the timer's callback takes state_mutex_
  if (new_rate) publish_timer_.setPeriod(ros::WallDuration(period));
  return true;
}

bool ReconstructionNode::ResetCb(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  std::lock_guard<std::mutex> lock(state_mutex_);
  ++epoch_;
  queue_.Clear();
  tracker_.Reset();
  if (scan_map_) {
    std::lock_guard<std::mutex> mlock(map_mutex_);
    scan_map_->Clear();
  }
  last_result_ = BackendResult();
  last_ids_.clear();
  last_input_.reset();
  last_msg_.reset();
  last_processed_stamp_ = last_scan_reconstruct_stamp_ = -1e300;
  SceneMeshes empty;
  empty.header.frame_id = config_.fixed_frame;
  empty.header.stamp = scene_.header.stamp;
  empty.mode = static_cast<std::uint8_t>(mode_);
  empty.scene_revision = ++scene_revision_;
  empty.model_version = model_version_;
  empty.pool_id = pool_id_;
  for (const InstanceMesh& i : scene_.instances) empty.removed_ids.push_back(i.id);
  scene_ = empty;
  markers_.Reset();
  PublishLocked();  // DELETEALL + the empty latched scene
  {
    std::lock_guard<std::mutex> slock(stats_mutex_);
    instances_ = 0;
  }
  res.success = true;
  res.message = "cleared " + std::to_string(empty.removed_ids.size()) + " instances";
  return true;
}

bool ReconstructionNode::ReprocessCb(std_srvs::Trigger::Request&,
                                     std_srvs::Trigger::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (!last_msg_) {
    res.success = false;
    res.message = "no cloud processed yet";
    return true;
  }
  Job job;
  job.msg = last_msg_;
  job.to_fixed = last_to_fixed_;
  job.received = ros::WallTime::now();
  job.reprocess = true;
  job.epoch = epoch_;
  queue_.Push(std::move(job));
  res.success = true;
  res.message = "queued the last cloud (stamp " + StampText(last_msg_->header.stamp) + ")";
  return true;
}

bool ReconstructionNode::GetSceneCb(GetScene::Request&, GetScene::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  std::lock_guard<std::mutex> lock(state_mutex_);
  res.scene = scene_;
  return true;
}

bool ReconstructionNode::GetInstanceCb(GetInstance::Request& req, GetInstance::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  std::lock_guard<std::mutex> lock(state_mutex_);
  res.found = false;
  for (std::size_t i = 0; i < scene_.instances.size(); ++i) {
    if (scene_.instances[i].id != req.id) continue;
    res.found = true;
    res.instance = scene_.instances[i];
    if (last_input_ && i < last_result_.instances.size())
      res.points = SupportCloud(last_result_.instances[i], last_input_->cloud, last_input_->header);
    break;
  }
  return true;
}

bool ReconstructionNode::GetPoolModelCb(GetPoolModel::Request& req, GetPoolModel::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  res.found = false;
  try {
    geometry::TriangleMesh mesh;
    res.found = backend_->PoolModel(req.model_id, &mesh, &res.mesh_resource);
    if (res.found) res.mesh = ToShapeMesh(mesh);
  } catch (const Error& e) {
    ROS_WARN("dimr: get_pool_model '%s': %s", req.model_id.c_str(), e.what());
  }
  return true;
}

bool ReconstructionNode::SaveSceneCb(SaveScene::Request& req, SaveScene::Response& res) {
  const CallbackGate::Entry entry(gate_);
  if (!entry) return false;
  SceneMeshes scene;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    scene = scene_;
  }
  try {
    res.files = SaveSceneFiles(scene, req.directory, req.format.empty() ? "ply" : req.format);
    res.success = true;
    res.message = "wrote " + std::to_string(res.files.size()) + " files to " + req.directory;
  } catch (const Error& e) {
    res.success = false;
    res.message = e.what();
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Diagnostics.

void ReconstructionNode::NoteIssue(const std::string& code, const std::string& message) {
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++issues_[code];
    last_issue_ = code + ": " + message;
  }
  ROS_WARN_THROTTLE(2.0, "dimr: %s: %s", code.c_str(), message.c_str());
}

void ReconstructionNode::Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  double rate = 0;
  if (arrival_times_.size() >= 2)
    rate = (arrival_times_.size() - 1) /
           std::max(1e-9, arrival_times_.back() - arrival_times_.front());
  std::size_t bad = 0;
  for (const auto& [code, n] : issues_) bad += n;
  if (failed_ > 0 || (received_ > 0 && processed_ == 0 && bad > 0))
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, last_issue_);
  else if (bad > 0 || tf_failures_ + tf_timeouts_ > 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, last_issue_);
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK,
                 processed_ ? "reconstructing" : "waiting for clouds");
  stat.add("mode", mode_text_);
  stat.add("input_mode", config_.input_mode);
  stat.add("model_version", model_version_);
  stat.add("pool_id", pool_id_.empty() ? "none" : pool_id_);
  stat.add("clouds_received", received_);
  stat.add("clouds_processed", processed_);
  stat.add("input_rate_hz", rate);
  stat.add("queue_drops", queue_.dropped());
  stat.add("tf_failures", tf_failures_);
  stat.add("tf_timeouts", tf_timeouts_);
  stat.add("tf_problems", tf_failures_ + tf_timeouts_);
  stat.add("pipeline_errors", failed_);
  for (const auto& [code, n] : issues_) stat.add("issue/" + code, n);
  stat.add("last_issue", last_issue_);
  stat.add("latency_s", last_latency_);
  stat.add("processing_s", last_processing_);
  stat.add("voxel_input_points", last_voxel_in_);
  stat.add("voxel_output_points", last_voxel_out_);
  stat.add("ceiling_removed_points", last_ceiling_removed_);
  stat.add("max_callback_ms", max_callback_ms_);
  stat.add("instances", instances_);
  stat.add("rss_mb", RssBytes() / 1048576.0);
  stat.add("compute", compute_info_);
  if (input_mode_ == InputMode::kScans) {
    stat.add("octomap_scans", map_scans_);
    stat.add("octomap_leaves", map_leaves_);
    stat.add("octomap_mb", map_bytes_ / 1048576.0);
  }
}

}  // namespace dimr::ros1
