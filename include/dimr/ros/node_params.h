// Every parameter of the reconstruction node: the node's own (node_config.h) plus the
// pipeline's (`pipeline/...` keys bound to pipeline::ReconstructorConfig fields). Read from any
// ParamSource (the ROS parameter server in the node, config/default.yaml in tests), validated
// as a whole. ROS-free.
#pragma once

#include <string>
#include <vector>

#include "dimr/pipeline/reconstructor_config.h"
#include "dimr/ros/node_config.h"
#include "dimr/ros/param_table.h"

namespace dimr::ros1 {

struct NodeParams {
  NodeConfig node;
  pipeline::ReconstructorConfig pipeline;
};

// Binds the pipeline fields to `pipeline/<name>` parameters. Enum fields go through the
// string holders in `text` (converted by ReadNodeParams).
struct PipelineParamText {
  std::string preset = "accurate";  // fast | accurate
  std::string mode = "generation";  // generation | projection | retrieval
  int seed = 0;
  std::string score = "combined";             // combined | stage2
  std::string icp_backend = "own";            // own | pcl
  std::string icp_metric = "point_to_point";  // point_to_point | point_to_plane
};
void DeclarePipelineParams(pipeline::ReconstructorConfig* config, PipelineParamText* text,
                           ParamTable* table);

struct ReadResult {
  NodeParams params;
  std::vector<std::string> unknown_keys;  // present in the source, not declared
  std::string resolved;                   // every parameter with its value (YAML)
};

// Reads every declared parameter of `source` over the defaults, resolves relative model paths
// against `package_dir` (when non-empty), and validates the whole. Throws
// dimr::InvalidArgument naming the key and the source on a bad value.
ReadResult ReadNodeParams(const ParamSource& source, const std::string& package_dir);

// Every declared parameter name, in order (for documentation checks).
std::vector<std::string> DeclaredParamNames();

}  // namespace dimr::ros1
