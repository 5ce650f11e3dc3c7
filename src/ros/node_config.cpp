// Node configuration and its parameter declarations (see node_config.h).
#include "dimr/ros/node_config.h"

#include <limits>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {

void AssociationConfig::Validate() const {
  if (!(min_iou > 0 && min_iou <= 1))
    throw InvalidArgument("association/min_iou must be in (0, 1]");
  if (!(max_center_distance >= 0))
    throw InvalidArgument("association/max_center_distance must be >= 0");
}

void ScanMapConfig::Validate() const {
  if (!(resolution > 0)) throw InvalidArgument("scans/resolution must be > 0");
  if (!(max_range > 0)) throw InvalidArgument("scans/max_range must be > 0");
  if (!(max_extent > 4 * resolution))
    throw InvalidArgument("scans/max_extent must exceed 4 x scans/resolution");
  if (max_occupied_cells < 1) throw InvalidArgument("scans/max_occupied_cells must be >= 1");
  if (!(occupancy_threshold > 0 && occupancy_threshold < 1))
    throw InvalidArgument("scans/occupancy_threshold must be in (0, 1)");
  if (!(reconstruct_interval >= 0))
    throw InvalidArgument("scans/reconstruct_interval must be >= 0");
}

void VisualizationConfig::Validate() const { (void)color_mode(); }

ColorBy VisualizationConfig::color_mode() const {
  if (color_by == "instance") return ColorBy::kInstance;
  if (color_by == "class") return ColorBy::kClass;
  if (color_by == "source") return ColorBy::kSource;
  throw InvalidArgument("visualization/color_by: '" + color_by +
                        "' is not one of instance, class, source");
}

InputMode NodeConfig::input() const {
  if (input_mode == "accumulated") return InputMode::kAccumulated;
  if (input_mode == "scans") return InputMode::kScans;
  throw InvalidArgument("input_mode: '" + input_mode + "' is not one of accumulated, scans");
}

void NodeConfig::Validate() const {
  if (fixed_frame.empty()) throw InvalidArgument("fixed_frame must not be empty");
  if (fixed_frame[0] == '/')
    throw InvalidArgument("fixed_frame '" + fixed_frame +
                          "' starts with '/': tf2 frame ids have no leading slash");
  if (!sensor_frame_override.empty() && sensor_frame_override[0] == '/')
    throw InvalidArgument("sensor_frame_override '" + sensor_frame_override +
                          "' starts with '/': tf2 frame ids have no leading slash");
  (void)input();
  for (int i = 0; i < 3; ++i)
    if (!(crop_min[i] < crop_max[i]))
      throw InvalidArgument("crop_box/min must be below crop_box/max on every axis (axis " +
                            std::to_string(i) + ")");
  if (!(max_publish_rate > 0)) throw InvalidArgument("max_publish_rate must be > 0");
  if (max_input_points < 1) throw InvalidArgument("max_input_points must be >= 1");
  association.Validate();
  scans.Validate();
  visualization.Validate();
}

void DeclareNodeParams(NodeConfig* c, ParamTable* t) {
  const double kInf = std::numeric_limits<double>::infinity();
  t->AddString("fixed_frame", &c->fixed_frame, {},
               "world-fixed output frame; every input cloud is transformed into it", false);
  t->AddString("sensor_frame_override", &c->sensor_frame_override, {},
               "replaces header.frame_id of every input cloud when non-empty");
  t->AddDouble("tf_timeout", &c->tf_timeout, 0, 30, "s",
               "how long a cloud waits in the tf2 MessageFilter for its transform");
  t->AddInt("tf_queue_size", &c->tf_queue_size, 1, 1000, "",
            "clouds the tf2 MessageFilter holds while waiting for TF");
  t->AddBool("use_latest_tf_on_failure", &c->use_latest_tf_on_failure,
             "use the newest transform when the stamped one is unavailable (explicit opt-in)");
  t->AddString("input_mode", &c->input_mode, {"accumulated", "scans"},
               "accumulated: each message is the whole map cloud; scans: one sensor scan each, "
               "integrated into an OctoMap");
  t->AddDouble("min_process_interval", &c->min_process_interval, 0, 3600, "s",
               "minimum message-time spacing of processed clouds (accumulated mode)");
  t->AddInt("max_input_points", &c->max_input_points, 1000, 100000000, "",
            "larger input clouds are subsampled with a uniform stride before reconstruction");
  t->AddDouble("input_voxel_size", &c->input_voxel_size, 0, 1, "m",
               "each occupied cell of this size becomes the mean of its points before "
               "reconstruction (stage 1's training density: 0.045); 0 = off");
  t->AddBool("remove_ceiling", &c->remove_ceiling,
             "drop a detected ceiling (topmost large horizontal layer) before stage 1, which "
             "never saw one in training");
  t->AddVector3("crop_box/min", &c->crop_min, -kInf, kInf, "m",
                "lower corner of the crop box in fixed_frame");
  t->AddVector3("crop_box/max", &c->crop_max, -kInf, kInf, "m",
                "upper corner of the crop box in fixed_frame");
  t->AddDouble("max_publish_rate", &c->max_publish_rate, 0.01, 100, "Hz",
               "cap on scene_meshes / instance_markers publications");
  t->AddBool("publish_latent_codes", &c->publish_latent_codes,
             "fill InstanceMesh.latent_code with the [mu, logvar] code");
  t->AddDouble("association/min_iou", &c->association.min_iou, 0.01, 1, "",
               "oriented-box IoU at which a new instance keeps an old instance's id");
  t->AddDouble("association/max_center_distance", &c->association.max_center_distance, 0, 10, "m",
               "a same-class pair whose box centres are this close also keeps the id");
  t->AddDouble("scans/resolution", &c->scans.resolution, 0.005, 1, "m", "OctoMap leaf size");
  t->AddDouble("scans/max_range", &c->scans.max_range, 0.1, 100, "m",
               "beams are truncated at this range");
  t->AddDouble("scans/max_extent", &c->scans.max_extent, 0.5, 1000, "m",
               "side of the cube around the first sensor origin that bounds the map (memory)");
  t->AddInt("scans/max_occupied_cells", &c->scans.max_occupied_cells, 1, 100000000, "",
            "occupied leaves handed to the pipeline at most (uniformly subsampled beyond)");
  t->AddDouble("scans/reconstruct_interval", &c->scans.reconstruct_interval, 0, 3600, "s",
               "message time between reconstructions of the map");
  t->AddDouble("scans/occupancy_threshold", &c->scans.occupancy_threshold, 0.01, 0.99, "",
               "occupancy probability of an occupied leaf");
  t->AddBool("scans/ray_casting", &c->scans.ray_casting,
             "clear free space along each beam (false: only mark end points)");
  t->AddString("visualization/color_by", &c->visualization.color_by,
               {"instance", "class", "source"}, "marker colour: per instance id, class or source");
  t->AddDouble("visualization/alpha", &c->visualization.alpha, 0, 1, "", "marker opacity");
  t->AddBool("visualization/show_bbox", &c->visualization.show_bbox,
             "publish oriented-box line markers");
  t->AddBool("visualization/show_labels", &c->visualization.show_labels,
             "publish text labels (class, id, score)");
}

}  // namespace dimr::ros1
