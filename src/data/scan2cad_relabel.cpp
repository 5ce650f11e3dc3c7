#include "dimr/data/scan2cad_relabel.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/types.h"

namespace dimr::data {
namespace {

using geometry::AABB;
using geometry::OrientedBox;
using geometry::Vec3;

constexpr double kRebuildMargin = 0.05;  // metres per side (get_points_inside_bbox expansion)

Eigen::Matrix4d Trs(const Vec3& t, const Eigen::Quaterniond& q, const Vec3& s) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = q.normalized().toRotationMatrix() * s.asDiagonal();
  m.topRightCorner<3, 1>() = t;
  return m;
}

Vec3 Apply(const Eigen::Matrix4d& m, const Vec3& p) {
  return m.topLeftCorner<3, 3>() * p + m.topRightCorner<3, 1>();
}

// Closest rotation Q and uniform scale rho with l ~ rho Q.
void Similarity(const Eigen::Matrix3d& l, Eigen::Matrix3d* q, double* rho) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(l, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) *= -1;
  *q = u * svd.matrixV().transpose();
  *rho = std::cbrt(std::abs(l.determinant()));
}

bool IsRebuiltClass(int cad) {
  return cad == kCadBookshelf || cad == kCadCabinet || cad == kCadBathtub;
}

// CAD fields of a linked / rebuilt instance from its model.
void AssignModel(const Scan2CadModel& m, int cad, const OrientedBox& box,
                 const Eigen::Matrix4d& to_scene, SynthInstance* inst) {
  inst->cad_class = cad;
  inst->box = box;
  inst->synset = m.catid_cad;
  inst->model_id = m.id_cad;
  inst->symmetric = m.sym != "__SYM_NONE";
  Eigen::Matrix3d q;
  double rho = 1.0;
  Similarity(to_scene.topLeftCorner<3, 3>(), &q, &rho);
  inst->translation = Apply(to_scene, m.translation);
  inst->rotation = Eigen::Quaterniond(q * m.rotation.normalized().toRotationMatrix()).normalized();
  inst->scale = rho * m.scale;
}

}  // namespace

Eigen::Matrix4d Scan2CadToAlignedScene(const Eigen::Matrix4d& axis_alignment,
                                       const Scan2CadScene& annotation) {
  const Eigen::Matrix4d m_scan = Trs(annotation.translation, annotation.rotation, annotation.scale);
  const double det = m_scan.topLeftCorner<3, 3>().determinant();
  if (!std::isfinite(det) || std::abs(det) < 1e-12) {
    throw InvalidArgument(
        "Scan2CAD scan '" + annotation.id_scan + "': the scene trs is singular (scale " +
        std::to_string(annotation.scale.x()) + " " + std::to_string(annotation.scale.y()) + " " +
        std::to_string(annotation.scale.z()) + ")");
  }
  return axis_alignment * m_scan.inverse();
}

OrientedBox Scan2CadModelBox(const Scan2CadModel& model, const Eigen::Matrix4d& to_scene) {
  const Eigen::Matrix4d t = to_scene * Trs(model.translation, model.rotation, model.scale);
  const Eigen::Matrix3d l = t.topLeftCorner<3, 3>();
  // ShapeNet forward (-z), left (-x), up (+y) and the half extents along them.
  const Vec3 axes[3] = {-Vec3::UnitZ(), -Vec3::UnitX(), Vec3::UnitY()};
  const double half[3] = {std::abs(model.bbox.z()), std::abs(model.bbox.x()),
                          std::abs(model.bbox.y())};
  Vec3 dir[3];
  double size[3];
  for (int i = 0; i < 3; ++i) {
    const Vec3 v = l * axes[i];
    const double len = v.norm();
    if (!std::isfinite(len) || len < 1e-12) {
      throw InvalidArgument("Scan2CAD model '" + model.id_cad + "' (" + model.catid_cad +
                            "): degenerate transform (zero scale along a model axis)");
    }
    dir[i] = v / len;
    size[i] = 2.0 * half[i] * len;
  }
  int up = 0;
  for (int i = 1; i < 3; ++i) {
    if (dir[i].z() > dir[up].z()) up = i;
  }
  const int fwd = up != 0 ? 0 : 1;
  const int left = 3 - up - fwd;
  const Eigen::Vector2d f(dir[fwd].x(), dir[fwd].y());
  if (f.norm() < 1e-9) {
    throw InvalidArgument("Scan2CAD model '" + model.id_cad + "' (" + model.catid_cad +
                          "): its forward axis is vertical, no heading");
  }
  OrientedBox box;
  box.center = Apply(t, model.center);
  box.size = Vec3(size[fwd], size[left], size[up]);
  box.heading = std::atan2(f.y(), f.x());
  return box;
}

void AxisAlignScene(SynthScene* scene) {
  const Eigen::Matrix4d& a = scene->axis_alignment;
  if (a.isIdentity(0.0)) return;
  const Eigen::Matrix3d r = a.topLeftCorner<3, 3>();
  const bool rigid =
      (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-3 &&
      r.determinant() > 0 && std::abs(r(2, 2) - 1.0) < 1e-3 &&
      a.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-9) && a.allFinite();
  if (!rigid) {
    throw InvalidArgument("scene '" + scene->name +
                          "': axisAlignment is not a rotation about z plus a translation");
  }
  const double yaw = std::atan2(r(1, 0), r(0, 0));
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  const Vec3 t = a.topRightCorner<3, 1>();
  for (Vec3& p : scene->points) p = (r * p + t).cast<float>().cast<double>();
  for (SynthInstance& in : scene->instances) {
    in.box.center = r * in.box.center + t;
    in.box.heading += yaw;
    in.translation = r * in.translation + t;
    in.rotation = (Eigen::Quaterniond(rz) * in.rotation).normalized();
  }
  scene->axis_alignment.setIdentity();
}

RelabelStats RelabelWithScan2Cad(SynthScene* scene, const Scan2CadScene& annotation) {
  if (annotation.id_scan != scene->name) {
    throw InvalidArgument("scene '" + scene->name + "': Scan2CAD annotation is for '" +
                          annotation.id_scan + "'");
  }
  const std::size_t n = scene->points.size();
  if (scene->semantic.size() != n || scene->instance.size() != n) {
    throw InvalidArgument("scene '" + scene->name + "': per-point arrays disagree in length");
  }
  const Eigen::Matrix4d to_scene = Scan2CadToAlignedScene(scene->axis_alignment, annotation);
  AxisAlignScene(scene);

  RelabelStats stats;
  // 1-2: keep / drop ScanNet instances.
  std::map<int, int> kept_index;  // id -> index into `kept`
  std::vector<SynthInstance> kept;
  int max_id = 0;
  for (const SynthInstance& in : scene->instances) {
    max_id = std::max(max_id, in.id);
    const bool ignored = in.rfs_class < 0 || in.rfs_class >= kNumRfsClasses;
    if (ignored) {
      ++stats.dropped_ignored;
    } else if (IsRebuiltClass(RfsToCad(in.rfs_class))) {
      ++stats.dropped_rebuilt;
    } else {
      kept_index[in.id] = static_cast<int>(kept.size());
      kept.push_back(in);
    }
  }
  std::vector<AABB> bounds(kept.size());
  std::vector<int> counts(kept.size(), 0);
  std::vector<bool> was_dropped(n, false);
  for (std::size_t k = 0; k < n; ++k) {
    const int id = scene->instance[k];
    if (id == 0) continue;
    auto it = kept_index.find(id);
    if (it == kept_index.end()) {
      scene->instance[k] = 0;  // dropped (or unknown) instance
      was_dropped[k] = true;
      continue;
    }
    bounds[it->second].Extend(scene->points[k]);
    ++counts[it->second];
  }
  std::vector<OrientedBox> kept_boxes(kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) {
    SynthInstance& in = kept[i];
    in.cad_class = kNonCad;
    in.synset.clear();
    in.model_id.clear();
    in.symmetric = false;
    in.num_points = counts[i];
    in.box = OrientedBox();
    if (counts[i] > 0) {
      in.box.center = bounds[i].Center();
      in.box.size = bounds[i].Extent();
    }
    kept_boxes[i] = in.box;
  }
  const std::size_t num_kept = kept.size();

  // 3: models in annotation order.
  std::vector<SynthInstance> rebuilt;
  for (const Scan2CadModel& m : annotation.aligned_models) {
    const int cad = CadClassFromSynset(m.catid_cad);
    if (cad < 0) {
      ++stats.non_cad_models;
      continue;
    }
    const OrientedBox box = Scan2CadModelBox(m, to_scene);
    if (IsRebuiltClass(cad)) {
      const int id = max_id + 1;
      std::map<int, int> label_votes;
      int count = 0;
      for (std::size_t k = 0; k < n; ++k) {
        if (scene->instance[k] != 0 || !box.Contains(scene->points[k], kRebuildMargin)) continue;
        scene->instance[k] = id;
        ++label_votes[scene->semantic[k]];
        ++count;
      }
      if (count == 0) {
        ++stats.rebuilt_empty;
        continue;
      }
      max_id = id;
      ++stats.rebuilt;
      int majority = -1, best = 0;
      for (const auto& [label, votes] : label_votes) {
        if (votes > best) {
          best = votes;
          majority = label;
        }
      }
      SynthInstance in;
      in.id = id;
      in.category = CadClassNames()[cad];
      in.rfs_class = majority >= 0 && majority < kNumRfsClasses && RfsToCad(majority) == cad
                         ? majority
                         : CadToRfs(cad);
      in.family = in.category;
      in.num_points = count;
      AssignModel(m, cad, box, to_scene, &in);
      rebuilt.push_back(in);
    } else {
      double best_iou = 0.0;
      int best = -1;
      for (std::size_t i = 0; i < num_kept; ++i) {
        if (counts[i] == 0) continue;
        const double iou = geometry::BoxIoU(box, kept_boxes[i]);
        if (iou > best_iou) {
          best_iou = iou;
          best = static_cast<int>(i);
        }
      }
      if (best < 0) {
        ++stats.unmatched;
        continue;
      }
      ++stats.linked;
      AssignModel(m, cad, box, to_scene, &kept[best]);
    }
  }
  for (std::size_t k = 0; k < n; ++k)
    stats.points_lost += was_dropped[k] && scene->instance[k] == 0;
  stats.kept = static_cast<int>(num_kept);
  for (const SynthInstance& in : kept) stats.kept_with_box += in.cad_class >= 0;
  scene->instances = std::move(kept);
  scene->instances.insert(scene->instances.end(), rebuilt.begin(), rebuilt.end());
  return stats;
}

std::string ToString(const RelabelStats& s) {
  std::ostringstream o;
  o << "kept " << s.kept << " (" << s.kept_with_box << " with a CAD box), dropped "
    << s.dropped_ignored << " ignored + " << s.dropped_rebuilt << " to rebuild, rebuilt "
    << s.rebuilt << " (" << s.rebuilt_empty << " empty boxes), linked " << s.linked
    << ", unmatched " << s.unmatched << ", non-CAD models " << s.non_cad_models << ", points lost "
    << s.points_lost;
  return o.str();
}

}  // namespace dimr::data
