// The nodelet `dimr/ReconstructionNodelet`: a ReconstructionNode with the pipeline backend in a
// nodelet manager. onInit reads and validates every parameter (ReadNodeParams), warns about
// unknown keys, logs the resolved configuration once and loads the models; any failure is
// logged as FATAL with the reason and rethrown, so that `nodelet load` (and dimr_node) fail
// loudly instead of running half-configured.
#include <nodelet/nodelet.h>
#include <ros/package.h>

#include <memory>
#include <pluginlib/class_list_macros.hpp>

#include "dimr/core/allocator.h"
#include "dimr/ros/node_params.h"
#include "dimr/ros/pipeline_backend.h"
#include "dimr/ros/reconstruction_node.h"
#include "dimr/ros/ros_param_source.h"

namespace dimr::ros1 {

class ReconstructionNodelet : public nodelet::Nodelet {
 public:
  ~ReconstructionNodelet() override { node_.reset(); }

 private:
  void onInit() override {
    try {
      // Multi-threaded handles: services and marker snapshots do not queue behind clouds.
      ros::NodeHandle nh = getMTNodeHandle(), pnh = getMTPrivateNodeHandle();
      const RosParamSource source(pnh);
      const ReadResult r = ReadNodeParams(source, ros::package::getPath("dimr"));
      for (const std::string& k : r.unknown_keys)
        NODELET_WARN("dimr: unknown parameter '%s/%s' ignored (misspelt? docs/ros.md lists them)",
                     pnh.getNamespace().c_str(), k.c_str());
      NODELET_INFO("dimr: resolved configuration of %s:\n%s", pnh.getNamespace().c_str(),
                   r.resolved.c_str());
      // LibTorch frees and re-allocates megabyte tensors on every layer call; keep them in the
      // heap (core/allocator.h) before the models load. Process-wide: in a shared manager the
      // other nodelets' freed memory is kept too (DIMR_DEFAULT_MALLOC=1 keeps glibc's
      // defaults).
      const AllocatorTuning tuning = TuneAllocatorForTensors();
      NODELET_INFO("dimr: allocator %s",
                   tuning == AllocatorTuning::kTuned
                       ? "tuned for tensors (mmap threshold up, no heap trim)"
                       : (tuning == AllocatorTuning::kUserSettings ? "left to GLIBC_TUNABLES / "
                                                                     "DIMR_DEFAULT_MALLOC"
                                                                   : "not glibc: unchanged"));
      auto backend = std::make_unique<PipelineBackend>(r.params.pipeline);
      node_ = std::make_unique<ReconstructionNode>(
          nh, pnh, r.params.node, std::move(backend),
          PipelineBackend::FromPipeline(r.params.pipeline.mode), r.params.pipeline.k);
    } catch (const std::exception& e) {
      NODELET_FATAL("dimr: cannot start: %s", e.what());
      throw;
    }
  }
  std::unique_ptr<ReconstructionNode> node_;
};

}  // namespace dimr::ros1

PLUGINLIB_EXPORT_CLASS(dimr::ros1::ReconstructionNodelet, nodelet::Nodelet)
