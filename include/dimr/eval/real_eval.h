// Evaluation of stage 1 on a real ScanNet scene that has only per-vertex NYU40 labels
// (labels.ply; no segments / aggregation) and, optionally, a Scan2CAD alignment (issue 22):
//  - semantic IoU over the RFS 25 classes present in the ground truth (NYU40 -> RFS by
//    data::Nyu40ToRfs), and over DODA's 11 classes (ECCV 2022: wall, floor, cabinet, bed, chair,
//    sofa, table, door, window, bookshelf, desk), with accuracy and the main confusions;
//  - per aligned Scan2CAD model, the scan points inside its aligned CAD box are the ground-truth
//    instance; it is *found* when a predicted instance of the right CAD class has point
//    IoU >= 0.5 with it.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "dimr/data/scan2cad_io.h"
#include "dimr/eval/seg_metrics.h"
#include "dimr/geometry/types.h"

namespace dimr::eval {

constexpr int kNumDodaClasses = 11;
// "wall", "floor", "cabinet", "bed", "chair", "sofa", "table", "door", "window", "bookshelf",
// "desk".
const std::array<const char*, kNumDodaClasses>& DodaClassNames();
// NYU40 id -> DODA class (0..10) or -1: wall 1, floor 2, cabinet 3, bed 4, chair 5, sofa 6,
// table 7, door 8, window 9, bookshelf 10, desk 14.
int Nyu40ToDoda(int nyu40);
// RFS 25 -> DODA class or -1. The RFS classes whose NYU40 id (data::RfsToNyu40) is a DODA
// class: kitchen_cabinet -> cabinet (NYU40 3) and other_table -> table (NYU40 7) besides the
// same-named ones; counter, shelves, toilet, ... -> -1. Out of range -> -1.
int RfsToDoda(int rfs);

struct Confusion {
  int pred = -1;          // predicted class (-1: a class outside the set)
  double fraction = 0.0;  // of the GT class's points
};

struct ClassReport {
  std::string name;
  long long gt_points = 0;
  double iou = 0.0;                  // NaN when the class is neither in GT nor predicted
  std::vector<Confusion> confusion;  // the largest predicted classes for its GT points
};

struct SemanticReport {
  SemanticIouResult raw;
  double miou_present = 0.0;  // mean IoU over classes with GT points
  int classes_present = 0;
  double accuracy = 0.0;  // over points with a valid GT label
  std::vector<ClassReport> classes;
};

// gt / pred per point (labels in [0, names.size()), anything else in gt = ignored, in pred = a
// miss). `top` = confusions kept per class. Throws dimr::InvalidArgument on a size mismatch.
SemanticReport EvaluateSemantic(const std::vector<int>& gt, const std::vector<int>& pred,
                                const std::vector<std::string>& names, int top = 3);

// T(trs) = Translate(t) * R(q) * Scale(s) as a 4x4 matrix.
Eigen::Matrix4d TrsMatrix(const geometry::Vec3& translation, const Eigen::Quaterniond& rotation,
                          const geometry::Vec3& scale);
// Scan2CAD's map of a model's CAD vertices into the scan: inv(T(trs_scan)) * T(trs_cad).
// Throws dimr::InvalidArgument naming the model when it is singular.
Eigen::Matrix4d Scan2CadModelToScan(const data::Scan2CadScene& scene,
                                    const data::Scan2CadModel& model);
// Indices of the points inside the model's aligned CAD box: q = inv(model_to_scan) p within
// |q - center| <= bbox + margin / (per-axis stretch) (margin in metres, may be negative).
std::vector<int> PointsInScan2CadBox(const std::vector<geometry::Vec3>& points,
                                     const data::Scan2CadModel& model,
                                     const Eigen::Matrix4d& model_to_scan, double margin = 0.0);

// The indices of `idx` whose label is not in `drop` (labels indexed by point; a label outside
// `drop`, including -1, is kept). Used to remove the scan's structure points (floor, wall)
// from a box's GT set: an aligned box that reaches the floor holds floor points that no
// instance annotation would count as the object. Throws dimr::InvalidArgument on an index
// outside `label`.
std::vector<int> DropLabelled(const std::vector<int>& idx, const std::vector<int>& label,
                              const std::vector<int>& drop);

// Ground truth of a real scene for the mesh metrics (`dimr eval`, docs/real.md "The product on
// the real room"): a CAD mesh as Scan2CAD aligns it, every vertex q of the model's
// model_normalized.obj mapped to model_to_scan * q (faces, normals dropped - recomputed by the
// consumers - and colours kept). Throws dimr::InvalidArgument for a non-finite matrix.
geometry::TriangleMesh AlignedCadMesh(const geometry::TriangleMesh& cad,
                                      const Eigen::Matrix4d& model_to_scan);

// 1-based instance labels of `num_points` points from per-object index sets (object k -> k + 1;
// a point in several sets belongs to the first; 0 = none). Throws dimr::InvalidArgument for an
// index outside [0, num_points) or more than 65535 objects.
std::vector<int> InstanceLabelsFromSets(std::size_t num_points,
                                        const std::vector<std::vector<int>>& sets);

// |a n b| / |a u b| of two index sets (duplicates ignored); 0 when both are empty.
double PointIoU(const std::vector<int>& a, const std::vector<int>& b);

struct PredictedInstance {
  int cad_class = -1;
  double score = 0.0;
  std::vector<int> points;
};

struct ObjectMatch {
  int cad_class = -1;  // of the GT object
  int gt_points = 0;
  double best_iou = 0.0;      // over predictions of the GT object's class
  int best_index = -1;        // that prediction (index into the predictions), -1 if none
  double best_iou_any = 0.0;  // over all predictions
  int best_any_class = -1;    // the CAD class of that prediction
  // Of that prediction: the share of the GT object's points it holds (recall) and the share of
  // its own points in the GT object (precision) - low recall: the object is split or missed,
  // low precision: it is merged with its surroundings.
  double best_any_recall = 0.0;
  double best_any_precision = 0.0;
  bool found = false;  // best_iou >= threshold
};

// For each GT object (its point set and CAD class), the best-overlapping predictions.
std::vector<ObjectMatch> MatchObjects(const std::vector<std::vector<int>>& gt_points,
                                      const std::vector<int>& gt_class,
                                      const std::vector<PredictedInstance>& preds,
                                      double threshold = 0.5);

}  // namespace dimr::eval
