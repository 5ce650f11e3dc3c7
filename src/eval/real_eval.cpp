#include "dimr/eval/real_eval.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_set>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"
#include "dimr/data/scannet_io.h"

namespace dimr::eval {

const std::array<const char*, kNumDodaClasses>& DodaClassNames() {
  static const std::array<const char*, kNumDodaClasses> kNames = {
      "wall",  "floor", "cabinet", "bed",       "chair", "sofa",
      "table", "door",  "window",  "bookshelf", "desk"};
  return kNames;
}

int Nyu40ToDoda(int nyu40) {
  switch (nyu40) {
    case 1:
    case 2:
    case 3:
    case 4:
    case 5:
    case 6:
    case 7:
    case 8:
    case 9:
    case 10:
      return nyu40 - 1;
    case 14:
      return 10;
    default:
      return -1;
  }
}

int RfsToDoda(int rfs) {
  if (rfs < 0 || rfs >= labels::kNumRfsClasses) return -1;
  return Nyu40ToDoda(data::RfsToNyu40(rfs));
}

SemanticReport EvaluateSemantic(const std::vector<int>& gt, const std::vector<int>& pred,
                                const std::vector<std::string>& names, int top) {
  if (gt.size() != pred.size())
    throw InvalidArgument("EvaluateSemantic: " + std::to_string(gt.size()) + " GT labels, " +
                          std::to_string(pred.size()) + " predictions");
  const int c = static_cast<int>(names.size());
  SemanticReport r;
  r.raw = SemanticIou(gt, pred, c);
  std::vector<std::map<int, long long>> conf(c);
  std::vector<long long> gt_n(c, 0);
  long long valid = 0, correct = 0;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    if (gt[i] < 0 || gt[i] >= c) continue;
    ++valid;
    ++gt_n[gt[i]];
    const int p = pred[i] >= 0 && pred[i] < c ? pred[i] : -1;
    ++conf[gt[i]][p];
    if (p == gt[i]) ++correct;
  }
  r.accuracy = valid ? static_cast<double>(correct) / static_cast<double>(valid) : 0.0;
  double sum = 0;
  for (int k = 0; k < c; ++k) {
    ClassReport cr;
    cr.name = names[k];
    cr.gt_points = gt_n[k];
    cr.iou = r.raw.iou[k];
    std::vector<Confusion> cs;
    for (const auto& [p, n] : conf[k])
      cs.push_back({p, static_cast<double>(n) / static_cast<double>(gt_n[k])});
    std::sort(cs.begin(), cs.end(), [](const Confusion& a, const Confusion& b) {
      return a.fraction != b.fraction ? a.fraction > b.fraction : a.pred < b.pred;
    });
    if (static_cast<int>(cs.size()) > top) cs.resize(std::max(0, top));
    cr.confusion = std::move(cs);
    if (gt_n[k] > 0) {
      sum += r.raw.iou[k];
      ++r.classes_present;
    }
    r.classes.push_back(std::move(cr));
  }
  r.miou_present = r.classes_present ? sum / r.classes_present : 0.0;
  return r;
}

Eigen::Matrix4d TrsMatrix(const geometry::Vec3& translation, const Eigen::Quaterniond& rotation,
                          const geometry::Vec3& scale) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 3>(0, 0) = rotation.normalized().toRotationMatrix() * scale.asDiagonal();
  m.block<3, 1>(0, 3) = translation;
  return m;
}

Eigen::Matrix4d Scan2CadModelToScan(const data::Scan2CadScene& scene,
                                    const data::Scan2CadModel& model) {
  const Eigen::Matrix4d s = TrsMatrix(scene.translation, scene.rotation, scene.scale);
  const Eigen::Matrix4d m = TrsMatrix(model.translation, model.rotation, model.scale);
  const double ds = s.block<3, 3>(0, 0).determinant();
  const double dm = m.block<3, 3>(0, 0).determinant();
  if (!std::isfinite(ds) || std::abs(ds) < 1e-12)
    throw InvalidArgument("Scan2CAD scene '" + scene.id_scan + "': singular scan trs");
  if (!std::isfinite(dm) || std::abs(dm) < 1e-12)
    throw InvalidArgument("Scan2CAD model " + model.id_cad + " of '" + scene.id_scan +
                          "': singular trs");
  return s.inverse() * m;
}

std::vector<int> PointsInScan2CadBox(const std::vector<geometry::Vec3>& points,
                                     const data::Scan2CadModel& model,
                                     const Eigen::Matrix4d& model_to_scan, double margin) {
  const Eigen::Matrix3d lin = model_to_scan.block<3, 3>(0, 0);
  const double det = lin.determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-12)
    throw InvalidArgument("Scan2CAD model " + model.id_cad + ": singular model-to-scan map");
  const Eigen::Matrix3d inv = lin.inverse();
  const Eigen::Vector3d t = model_to_scan.block<3, 1>(0, 3);
  Eigen::Vector3d half;
  for (int k = 0; k < 3; ++k) half(k) = std::abs(model.bbox(k)) + margin / lin.col(k).norm();
  std::vector<int> out;
  if ((half.array() < 0).any()) return out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d q = inv * (points[i] - t) - model.center;
    if ((q.array().abs() <= half.array()).all()) out.push_back(static_cast<int>(i));
  }
  return out;
}

std::vector<int> DropLabelled(const std::vector<int>& idx, const std::vector<int>& label,
                              const std::vector<int>& drop) {
  std::vector<int> out;
  out.reserve(idx.size());
  for (int i : idx) {
    if (i < 0 || static_cast<std::size_t>(i) >= label.size()) {
      throw InvalidArgument("DropLabelled: point index " + std::to_string(i) + " outside the " +
                            std::to_string(label.size()) + " labels");
    }
    if (std::find(drop.begin(), drop.end(), label[i]) == drop.end()) out.push_back(i);
  }
  return out;
}

namespace {
// |a n b| of two sets of point indices.
std::size_t Intersection(const std::unordered_set<int>& a, const std::unordered_set<int>& b) {
  std::size_t inter = 0;
  for (int x : b) inter += a.count(x);
  return inter;
}
double SetIoU(std::size_t a, std::size_t b, std::size_t inter) {
  if (a == 0 && b == 0) return 0.0;
  return static_cast<double>(inter) / static_cast<double>(a + b - inter);
}
}  // namespace

double PointIoU(const std::vector<int>& a, const std::vector<int>& b) {
  const std::unordered_set<int> sa(a.begin(), a.end());
  const std::unordered_set<int> sb(b.begin(), b.end());
  return SetIoU(sa.size(), sb.size(), Intersection(sa, sb));
}

std::vector<ObjectMatch> MatchObjects(const std::vector<std::vector<int>>& gt_points,
                                      const std::vector<int>& gt_class,
                                      const std::vector<PredictedInstance>& preds,
                                      double threshold) {
  if (gt_points.size() != gt_class.size())
    throw InvalidArgument("MatchObjects: " + std::to_string(gt_points.size()) + " GT point sets, " +
                          std::to_string(gt_class.size()) + " classes");
  std::vector<ObjectMatch> out(gt_points.size());
  for (std::size_t g = 0; g < gt_points.size(); ++g) {
    ObjectMatch& m = out[g];
    m.cad_class = gt_class[g];
    const std::unordered_set<int> gt_set(gt_points[g].begin(), gt_points[g].end());
    m.gt_points = static_cast<int>(gt_set.size());
    for (std::size_t p = 0; p < preds.size(); ++p) {
      const std::unordered_set<int> pred_set(preds[p].points.begin(), preds[p].points.end());
      const std::size_t inter = Intersection(gt_set, pred_set);
      const double iou = SetIoU(gt_set.size(), pred_set.size(), inter);
      if (iou > m.best_iou_any) {
        m.best_iou_any = iou;
        m.best_any_class = preds[p].cad_class;
        m.best_any_recall = gt_set.empty() ? 0.0 : static_cast<double>(inter) / gt_set.size();
        m.best_any_precision =
            pred_set.empty() ? 0.0 : static_cast<double>(inter) / pred_set.size();
      }
      if (preds[p].cad_class == m.cad_class && iou > m.best_iou) {
        m.best_iou = iou;
        m.best_index = static_cast<int>(p);
      }
    }
    m.found = m.best_index >= 0 && m.best_iou >= threshold;
  }
  return out;
}

geometry::TriangleMesh AlignedCadMesh(const geometry::TriangleMesh& cad,
                                      const Eigen::Matrix4d& model_to_scan) {
  if (!model_to_scan.allFinite()) {
    throw InvalidArgument("AlignedCadMesh: the model-to-scan matrix is not finite");
  }
  geometry::TriangleMesh out;
  out.faces = cad.faces;
  out.vertex_colors = cad.vertex_colors;
  out.vertices.reserve(cad.vertices.size());
  const Eigen::Matrix3d m = model_to_scan.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = model_to_scan.topRightCorner<3, 1>();
  for (const auto& q : cad.vertices) out.vertices.push_back(m * q + t);
  return out;
}

std::vector<int> InstanceLabelsFromSets(std::size_t num_points,
                                        const std::vector<std::vector<int>>& sets) {
  if (sets.size() > 65535) {
    throw InvalidArgument("InstanceLabelsFromSets: " + std::to_string(sets.size()) +
                          " objects, at most 65535 fit a 16-bit instance label");
  }
  std::vector<int> label(num_points, 0);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    for (int i : sets[k]) {
      if (i < 0 || static_cast<std::size_t>(i) >= num_points) {
        throw InvalidArgument("InstanceLabelsFromSets: object " + std::to_string(k) +
                              " has point " + std::to_string(i) + ", outside [0, " +
                              std::to_string(num_points) + ")");
      }
      if (label[i] == 0) label[i] = static_cast<int>(k) + 1;
    }
  }
  return label;
}

}  // namespace dimr::eval
