// Configuration of the reconstruction node (everything that is not the Reconstructor's own
// config): frames, TF, input handling, OctoMap scan integration, instance association,
// publication and visualisation. In-class defaults are the documented defaults
// (config/default.yaml, docs/ros.md); DeclareNodeParams binds every field to its parameter
// name. ROS-free.
#pragma once

#include <array>
#include <string>

#include "dimr/pipeline/voxel_downsample.h"
#include "dimr/ros/param_table.h"

namespace dimr::ros1 {

enum class InputMode { kAccumulated, kScans };
enum class ColorBy { kInstance, kClass, kSource };

// Instance association between consecutive reconstructions (instance_tracker.h).
struct AssociationConfig {
  double min_iou = 0.2;              // oriented-box IoU for a match
  double max_center_distance = 0.3;  // m; a same-class pair this close also matches
  void Validate() const;
};

// OctoMap integration of per-frame scans (`input_mode: scans`).
struct ScanMapConfig {
  double resolution = 0.03;           // m, leaf size
  double max_range = 6.0;             // m, beams longer than this are truncated (-1 would be off)
  double max_extent = 16.0;           // m, the map is kept inside a cube of this side around the
                                      // first sensor origin (memory bound)
  int max_occupied_cells = 1500000;   // hard bound of the occupied leaves handed to the pipeline
  double reconstruct_interval = 2.0;  // s (message time) between reconstructions of the map
  double occupancy_threshold = 0.5;   // probability above which a leaf is occupied
  bool ray_casting = true;            // clear free space along beams (false: only mark hits)
  void Validate() const;
};

struct VisualizationConfig {
  std::string color_by = "class";  // instance | class | source
  double alpha = 1.0;
  bool show_bbox = true;
  bool show_labels = true;
  void Validate() const;
  ColorBy color_mode() const;
};

struct NodeConfig {
  std::string fixed_frame = "map";
  std::string sensor_frame_override;  // replaces the cloud's header.frame_id when non-empty
  double tf_timeout = 0.2;            // s, how long the MessageFilter waits for TF
  int tf_queue_size = 5;
  bool use_latest_tf_on_failure = false;
  std::string input_mode = "accumulated";  // accumulated | scans
  double min_process_interval = 0.0;       // s between processed clouds (message time)
  int max_input_points = 2000000;          // larger clouds are subsampled (uniform stride)
  double input_voxel_size = pipeline::kTrainingVoxelSize;  // m, voxel-mean filter (0 = off)
  bool remove_ceiling = true;  // drop a detected ceiling before stage 1 (pipeline/ceiling.h)
  std::array<double, 3> crop_min = {-1000, -1000, -1000};  // m in fixed_frame
  std::array<double, 3> crop_max = {1000, 1000, 1000};
  double max_publish_rate = 2.0;  // Hz, markers / scene publication cap
  bool publish_latent_codes = false;
  AssociationConfig association;
  ScanMapConfig scans;
  VisualizationConfig visualization;

  InputMode input() const;
  // Throws dimr::InvalidArgument naming the field on an inconsistent combination (the
  // per-field ranges are checked by the ParamTable).
  void Validate() const;
};

// Binds every NodeConfig field to its parameter name, unit, range and documentation.
void DeclareNodeParams(NodeConfig* config, ParamTable* table);

}  // namespace dimr::ros1
