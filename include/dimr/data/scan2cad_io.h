// Scan2CAD-style `full_annotations.json`: a JSON list with one entry per scan,
//   {"id_scan", "trs": {"translation": [x,y,z], "rotation": [w,x,y,z], "scale": [sx,sy,sz]},
//    "n_aligned_models", "aligned_models": [{"catid_cad", "id_cad", "trs", "bbox", "center",
//    "sym", "id_instance"}]}
// trs of a model maps the ShapeNet model_normalized.obj vertex q to the scan:
// p = t + R(q_wxyz) * diag(scale) * q (Scan2CAD's M = T * R * S). bbox = half extents and
// center = bounding-box centre of the model in its own (ShapeNet) frame. `id_instance` is a
// SynthScan extension linking the model to the ScanNet instance (objectId + 1); real Scan2CAD
// files lack it (read as 0).
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "dimr/data/synthscan.h"
#include "dimr/geometry/types.h"

namespace dimr::data {

struct Scan2CadModel {
  std::string catid_cad, id_cad;
  geometry::Vec3 translation = geometry::Vec3::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  geometry::Vec3 scale = geometry::Vec3::Ones();
  geometry::Vec3 bbox = geometry::Vec3::Constant(0.5);
  geometry::Vec3 center = geometry::Vec3::Zero();
  std::string sym = "__SYM_NONE";
  int id_instance = 0;
};

struct Scan2CadScene {
  std::string id_scan;
  geometry::Vec3 translation = geometry::Vec3::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  geometry::Vec3 scale = geometry::Vec3::Ones();
  std::vector<Scan2CadModel> aligned_models;
};

bool operator==(const Scan2CadModel& a, const Scan2CadModel& b);
bool operator==(const Scan2CadScene& a, const Scan2CadScene& b);

// The Scan2CAD entry of a scene: every CAD instance (cad_class >= 0). `nominal_sizes` are not
// needed: bbox is derived from the instance's ShapeNet-frame scale convention (half extents of
// the model_normalized box: the alignment scale folds the metric size in).
Scan2CadScene ToScan2Cad(const SynthScene& scene);

// Writes the list (pretty JSON, doubles with round-trip precision). Throws dimr::Error naming
// the path when it cannot be written.
void WriteScan2CadAnnotations(const std::string& path, const std::vector<Scan2CadScene>& scenes);
// Throws dimr::ParseError naming the path and entry for malformed files.
std::vector<Scan2CadScene> ReadScan2CadAnnotations(const std::string& path);

}  // namespace dimr::data
