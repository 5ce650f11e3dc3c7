// Scan2CAD full_annotations.json writer / reader (see scan2cad_io.h).
#include "dimr/data/scan2cad_io.h"

#include <fstream>
#include <nlohmann/json.hpp>

#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/error.h"

namespace dimr::data {
namespace {

using geometry::Vec3;
using nlohmann::json;

json Vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

json Trs(const Vec3& t, const Eigen::Quaterniond& q, const Vec3& s) {
  return {{"translation", Vec(t)},
          {"rotation", json::array({q.w(), q.x(), q.y(), q.z()})},
          {"scale", Vec(s)}};
}

Vec3 GetVec(const json& j, const char* key, const std::string& where) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
    throw ParseError(where, std::string("field '") + key + "' must be an array of 3 numbers");
  return Vec3(j[key][0].get<double>(), j[key][1].get<double>(), j[key][2].get<double>());
}

void GetTrs(const json& j, const std::string& where, Vec3* t, Eigen::Quaterniond* q, Vec3* s) {
  if (!j.contains("trs") || !j["trs"].is_object()) throw ParseError(where, "no 'trs' object");
  const json& trs = j["trs"];
  *t = GetVec(trs, "translation", where);
  *s = GetVec(trs, "scale", where);
  if (!trs.contains("rotation") || !trs["rotation"].is_array() || trs["rotation"].size() != 4)
    throw ParseError(where, "trs.rotation must be a quaternion [w, x, y, z]");
  const json& r = trs["rotation"];
  *q = Eigen::Quaterniond(r[0].get<double>(), r[1].get<double>(), r[2].get<double>(),
                          r[3].get<double>());
}

}  // namespace

bool operator==(const Scan2CadModel& a, const Scan2CadModel& b) {
  return a.catid_cad == b.catid_cad && a.id_cad == b.id_cad && a.translation == b.translation &&
         a.rotation.coeffs() == b.rotation.coeffs() && a.scale == b.scale && a.bbox == b.bbox &&
         a.center == b.center && a.sym == b.sym && a.id_instance == b.id_instance;
}

bool operator==(const Scan2CadScene& a, const Scan2CadScene& b) {
  return a.id_scan == b.id_scan && a.translation == b.translation &&
         a.rotation.coeffs() == b.rotation.coeffs() && a.scale == b.scale &&
         a.aligned_models == b.aligned_models;
}

Scan2CadScene ToScan2Cad(const SynthScene& scene) {
  Scan2CadScene s;
  s.id_scan = scene.name;
  const Eigen::Matrix3d a = CanonicalToShapeNetAxes();
  for (const auto& i : scene.instances) {
    if (i.cad_class < 0) continue;
    Scan2CadModel m;
    m.catid_cad = i.synset;
    m.id_cad = i.model_id;
    m.translation = i.translation;
    m.rotation = i.rotation;
    m.scale = i.scale;
    // Half extents of model_normalized: the metric half size (ShapeNet axes) over the scale.
    m.bbox = (0.5 * (a * i.box.size).cwiseAbs()).cwiseQuotient(i.scale);
    m.center = Vec3::Zero();
    m.sym = i.symmetric ? "__SYM_ROTATE_UP_INF" : "__SYM_NONE";
    m.id_instance = i.id;
    s.aligned_models.push_back(m);
  }
  return s;
}

void WriteScan2CadAnnotations(const std::string& path, const std::vector<Scan2CadScene>& scenes) {
  json out = json::array();
  for (const auto& s : scenes) {
    json j;
    j["id_scan"] = s.id_scan;
    j["trs"] = Trs(s.translation, s.rotation, s.scale);
    j["n_aligned_models"] = s.aligned_models.size();
    j["aligned_models"] = json::array();
    for (const auto& m : s.aligned_models) {
      json jm;
      jm["catid_cad"] = m.catid_cad;
      jm["id_cad"] = m.id_cad;
      jm["trs"] = Trs(m.translation, m.rotation, m.scale);
      jm["bbox"] = Vec(m.bbox);
      jm["center"] = Vec(m.center);
      jm["sym"] = m.sym;
      jm["id_instance"] = m.id_instance;
      j["aligned_models"].push_back(jm);
    }
    out.push_back(j);
  }
  std::ofstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open '" + path + "' for writing");
  f << out.dump(1) << "\n";
  if (!f) throw Error("error writing '" + path + "'");
}

std::vector<Scan2CadScene> ReadScan2CadAnnotations(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ParseError(path, "cannot open file");
  json in;
  try {
    in = json::parse(f);
  } catch (const json::exception& e) {
    throw ParseError(path, std::string("malformed JSON: ") + e.what());
  }
  if (!in.is_array()) throw ParseError(path, "expected a JSON list of scans");
  std::vector<Scan2CadScene> out;
  try {
    for (std::size_t k = 0; k < in.size(); ++k) {
      const json& j = in[k];
      const std::string where = path + " [" + std::to_string(k) + "]";
      Scan2CadScene s;
      s.id_scan = j.at("id_scan").get<std::string>();
      GetTrs(j, where, &s.translation, &s.rotation, &s.scale);
      const json& models = j.at("aligned_models");
      for (std::size_t m = 0; m < models.size(); ++m) {
        const json& jm = models[m];
        const std::string w = where + ".aligned_models[" + std::to_string(m) + "]";
        Scan2CadModel a;
        a.catid_cad = jm.at("catid_cad").get<std::string>();
        a.id_cad = jm.at("id_cad").get<std::string>();
        GetTrs(jm, w, &a.translation, &a.rotation, &a.scale);
        a.bbox = GetVec(jm, "bbox", w);
        a.center = GetVec(jm, "center", w);
        if (jm.contains("sym")) a.sym = jm["sym"].get<std::string>();
        if (jm.contains("id_instance")) a.id_instance = jm["id_instance"].get<int>();
        s.aligned_models.push_back(a);
      }
      out.push_back(std::move(s));
    }
  } catch (const json::exception& e) {
    throw ParseError(path, std::string("malformed Scan2CAD annotation: ") + e.what());
  }
  return out;
}

}  // namespace dimr::data
