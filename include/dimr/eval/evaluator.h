// `dimr eval`: the DIMR evaluation protocol over a prediction set (spec
// ../shared/reference/dimr-metrics.md): mesh AP at IoU@0.25/0.5, CD@0.1/0.047, LFD@5000/2500
// and PCR@0.5, per class and as means over the 8 CAD classes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/eval/ap.h"
#include "dimr/eval/inputs.h"
#include "dimr/eval/mesh_metrics.h"

namespace dimr::eval {

struct EvalOptions {
  Protocol protocol = Protocol::kReference;
  bool iou = true;
  bool cd = true;
  bool lfd = true;
  bool pcr = false;
  int threads = 0;            // <= 0: all cores
  std::string lfd_cache_dir;  // optional on-disk descriptor cache (content-hash keyed)
  std::uint64_t seed = 0;     // CD sampling seed
  bool progress = false;      // progress bars on stderr
  // Parses "iou,cd,lfd,pcr" (any subset); throws dimr::InvalidArgument on unknown names.
  void SetMetrics(const std::string& list);
};

struct EvalInputs {
  std::vector<MeshRecord> gt;           // GT meshes (IoU, CD, LFD)
  std::vector<MeshRecord> preds;        // predictions
  std::vector<std::string> pcr_scenes;  // PCR scene list (every scene contributes its GT)
  std::vector<PointsGt> pcr_gt;
};

struct StageTiming {
  std::string stage;
  double seconds = 0.0;
};

// Per GT mesh: the best value of each mesh metric over the predictions of its scene and class
// (NaN when the metric was not asked or no such prediction exists) - what keeps an object from
// counting, independent of AP ranking. CD is the first Chamfer pass (the reference protocol
// re-samples per threshold).
struct GtObjectResult {
  std::string scene;
  std::string name;  // the GT mesh's file basename
  int cls = -1;
  double best_iou = 0.0;
  int best_iou_pred = -1;     // index into EvalInputs::preds, -1 if none
  std::string best_iou_name;  // that prediction's file basename
  double best_cd = 0.0;
  double best_lfd = 0.0;
};

struct EvalReport {
  Protocol protocol = Protocol::kReference;
  // In order: iou@0.25, iou@0.5, cd@0.1, cd@0.047, lfd@5000, lfd@2500, pcr@0.5 (those asked).
  std::vector<ApTable> tables;
  std::vector<GtObjectResult> objects;  // one per GT mesh, in EvalInputs::gt order
  int num_scenes = 0;
  int num_gt = 0;
  int num_preds = 0;      // predictions evaluated by the mesh metrics
  int dropped_preds = 0;  // predictions of scenes without GT meshes (reference: KeyError)
  int num_pcr_scenes = 0;
  int num_pcr_gt = 0;
  int num_pcr_preds = 0;
  int dropped_pcr_preds = 0;           // predictions of scenes outside the PCR scene list
  std::size_t lfd_descriptors = 0;     // descriptors computed (not cache hits)
  double lfd_ms_per_descriptor = 0.0;  // wall time of the descriptor stage / descriptors * threads
  std::vector<std::string> warnings;
  std::vector<StageTiming> timings;
  double total_seconds = 0.0;
  int threads = 1;

  // The table of `metric` at `threshold`, or nullptr.
  const ApTable* Find(const std::string& metric, double threshold) const;
};

// Loads everything, computes all pairwise metrics on a thread pool and the AP tables. Throws
// dimr::ParseError for unreadable meshes (naming the file) and dimr::InvalidArgument when PCR
// is requested without PCR GT or when there is no GT at all.
EvalReport Evaluate(const EvalInputs& inputs, const EvalOptions& options);

}  // namespace dimr::eval
