// ShapeNet-style tree writer / reader (see include/dimr/data/shapenet_io.h).
#include "dimr/data/shapenet_io.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;
using nlohmann::json;

constexpr const char* kIndexName = "index.json";
constexpr const char* kIndexFormat = "dimr-shapenet-index";

bool IsModelId(const std::string& id) {
  if (id.size() != 32) return false;
  return std::all_of(id.begin(), id.end(),
                     [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

// Per-axis re-normalisation to [-0.5, 0.5]^3 (exact at the bounds).
void NormaliseUnitBox(geometry::TriangleMesh* mesh) {
  const geometry::AABB box = mesh->Bounds();
  const Vec3 lo = box.min, ext = box.Extent();
  for (auto& v : mesh->vertices) {
    for (int a = 0; a < 3; ++a) v[a] = (v[a] - lo[a]) / ext[a] - 0.5;
  }
}

json ReadIndex(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ParseError(path, "cannot open index");
  std::stringstream ss;
  ss << in.rdbuf();
  json j;
  try {
    j = json::parse(ss.str());
  } catch (const json::exception& e) {
    throw ParseError(path, std::string("malformed JSON: ") + e.what());
  }
  if (!j.is_object() || !j.contains("models") || !j["models"].is_array()) {
    throw ParseError(path, "expected an object with a \"models\" array");
  }
  if (j.contains("format") && j["format"] != kIndexFormat) {
    throw ParseError(path, "unknown index format " + j["format"].dump());
  }
  for (std::size_t i = 0; i < j["models"].size(); ++i) {
    const json& e = j["models"][i];
    if (!e.is_object() || !e.contains("model_id") || !e["model_id"].is_string() ||
        !e.contains("synset") || !e["synset"].is_string()) {
      throw ParseError(path, "models[" + std::to_string(i) +
                                 "]: expected an object with string \"model_id\" and \"synset\"");
    }
  }
  return j;
}

json EntryOf(const CadModel& m) {
  json e;
  e["model_id"] = m.model_id;
  e["synset"] = m.synset;
  e["class"] = m.cad_class;
  e["rfs_class"] = m.rfs_class;
  e["class_name"] =
      (m.cad_class >= 0 && m.cad_class < kNumCadClasses) ? CadClassNames()[m.cad_class] : "";
  e["family"] = m.family;
  e["nominal_size"] = {m.nominal_size.x(), m.nominal_size.y(), m.nominal_size.z()};
  e["seed"] = m.seed;
  e["symmetric_about_z"] = m.symmetric_about_z;
  e["triangles"] = m.mesh.faces.size();
  e["path"] = ShapeNetRelativePath(m.synset, m.model_id);
  e["part_face_begin"] = m.part_face_begin;
  e["part_names"] = m.part_names;
  return e;
}

template <typename T>
T Field(const json& e, const char* key, const std::string& where) {
  if (!e.contains(key)) throw ParseError(where, std::string("missing field \"") + key + "\"");
  try {
    return e.at(key).get<T>();
  } catch (const json::exception& ex) {
    throw ParseError(where, std::string("field \"") + key + "\": " + ex.what());
  }
}

}  // namespace

Eigen::Matrix3d CanonicalToShapeNetAxes() {
  Eigen::Matrix3d A;
  A << 0, -1, 0,  //
      0, 0, 1,    //
      -1, 0, 0;
  return A;
}

Eigen::Matrix3d CanonicalToShapeNet(const Vec3& nominal_size) {
  if (!(nominal_size.array() > 0).all() || !nominal_size.allFinite()) {
    throw InvalidArgument("CanonicalToShapeNet: nominal size must be positive and finite");
  }
  return CanonicalToShapeNetAxes() * nominal_size.asDiagonal() * (1.0 / nominal_size.norm());
}

std::string ShapeNetRelativePath(const std::string& synset, const std::string& model_id) {
  return synset + "/" + model_id + "/models/model_normalized.obj";
}

void WriteShapeNetTree(const std::string& dir, const std::vector<CadModel>& models, int precision) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    throw InvalidArgument("cannot create output directory '" + dir +
                          "': " + (ec ? ec.message() : std::string("not a directory")));
  }
  const std::string index_path = (fs::path(dir) / kIndexName).string();
  json index;
  if (fs::exists(index_path)) {
    index = ReadIndex(index_path);
  } else {
    index["models"] = json::array();
  }
  index["format"] = kIndexFormat;
  index["version"] = 1;
  index["convention"] =
      "model_normalized: y up, -z forward, centred, bbox diagonal 1; q = A diag(s) p / |s|, "
      "A = [[0,-1,0],[0,0,1],[-1,0,0]], p canonical (x forward, y left, z up, unit box), "
      "s = nominal_size (metres)";
  std::map<std::string, std::size_t> position;
  for (std::size_t i = 0; i < index["models"].size(); ++i) {
    const json& e = index["models"][i];
    if (e.is_object() && e.contains("model_id") && e["model_id"].is_string()) {
      position[e["model_id"].get<std::string>()] = i;
    }
  }
  for (const CadModel& m : models) {
    if (m.synset.empty()) {
      throw InvalidArgument("WriteShapeNetTree " + dir + ": model '" + m.model_id + "' (" +
                            m.family + ") has no synset (only CAD models go into the tree)");
    }
    if (!IsModelId(m.model_id)) {
      throw InvalidArgument("WriteShapeNetTree " + dir + ": model id '" + m.model_id +
                            "' is not 32 lower-case hex characters");
    }
    const fs::path obj = fs::path(dir) / ShapeNetRelativePath(m.synset, m.model_id);
    fs::create_directories(obj.parent_path(), ec);
    if (ec) {
      throw InvalidArgument("cannot create directory '" + obj.parent_path().string() +
                            "': " + ec.message());
    }
    geometry::TriangleMesh mesh;
    mesh.vertices = m.mesh.vertices;
    mesh.faces = m.mesh.faces;
    mesh.Transform(CanonicalToShapeNet(m.nominal_size), Vec3::Zero());
    geometry::WriteObj(obj.string(), mesh, precision);
    const json e = EntryOf(m);
    const auto it = position.find(m.model_id);
    if (it != position.end()) {
      index["models"][it->second] = e;
    } else {
      position[m.model_id] = index["models"].size();
      index["models"].push_back(e);
    }
  }
  const std::string tmp = index_path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InvalidArgument("cannot write index '" + tmp + "'");
    out << index.dump(1) << "\n";
    if (!out) throw InvalidArgument("cannot write index '" + tmp + "'");
  }
  fs::rename(tmp, index_path, ec);
  if (ec) throw InvalidArgument("cannot write index '" + index_path + "': " + ec.message());
}

CadModel ReadShapeNetModel(const std::string& path, const std::string& synset) {
  geometry::TriangleMesh file = geometry::ReadObj(path);
  if (file.faces.empty()) throw ParseError(path, "model has no faces");
  CadModel m;
  m.synset = synset;
  m.cad_class = CadClassFromSynset(synset);
  m.rfs_class = m.cad_class >= 0 ? CadToRfs(m.cad_class) : -1;
  m.family = "shapenet";
  const fs::path p(path);
  if (p.parent_path().filename() == "models") {
    m.model_id = p.parent_path().parent_path().filename().string();
  } else {
    m.model_id = p.stem().string();
  }
  m.mesh.vertices = std::move(file.vertices);
  m.mesh.faces = std::move(file.faces);
  m.mesh.Transform(CanonicalToShapeNetAxes().transpose(), Vec3::Zero());
  const Vec3 ext = m.mesh.Bounds().Extent();
  if (!(ext.array() > 0).all()) {
    throw ParseError(path, "model is flat along an axis (bounding box extent " +
                               std::to_string(ext.minCoeff()) + ")");
  }
  m.nominal_size = ext;
  NormaliseUnitBox(&m.mesh);
  m.part_face_begin = {0};
  m.part_names = {"mesh"};
  return m;
}

std::vector<CadModel> ReadShapeNetTree(const std::string& dir) {
  if (!fs::is_directory(dir)) throw ParseError(dir, "no such directory");
  const std::string index_path = (fs::path(dir) / kIndexName).string();
  std::vector<CadModel> models;
  if (fs::exists(index_path)) {
    const json index = ReadIndex(index_path);
    for (std::size_t i = 0; i < index["models"].size(); ++i) {
      const json& e = index["models"][i];
      const std::string where = index_path + ": models[" + std::to_string(i) + "]";
      if (!e.is_object()) throw ParseError(where, "entry is not an object");
      const auto id = Field<std::string>(e, "model_id", where);
      const auto synset = Field<std::string>(e, "synset", where);
      if (!IsModelId(id)) throw ParseError(where, "bad model id '" + id + "'");
      if (synset.empty() || synset.find('/') != std::string::npos || synset == "..") {
        throw ParseError(where, "bad synset '" + synset + "'");
      }
      CadModel m =
          ReadShapeNetModel((fs::path(dir) / ShapeNetRelativePath(synset, id)).string(), synset);
      m.family = Field<std::string>(e, "family", where);
      const auto size = Field<std::vector<double>>(e, "nominal_size", where);
      if (size.size() != 3 || !(size[0] > 0 && size[1] > 0 && size[2] > 0)) {
        throw ParseError(where, "nominal_size must be 3 positive numbers");
      }
      m.nominal_size = Vec3(size[0], size[1], size[2]);
      m.seed = Field<std::uint64_t>(e, "seed", where);
      m.symmetric_about_z = Field<bool>(e, "symmetric_about_z", where);
      const int cls = Field<int>(e, "class", where);
      if (cls != m.cad_class) {
        throw ParseError(where,
                         "class " + std::to_string(cls) + " does not match synset " + synset);
      }
      if (e.contains("rfs_class")) {
        const int rfs = Field<int>(e, "rfs_class", where);
        if (rfs < -1 || rfs >= kNumRfsClasses) {
          throw ParseError(where, "rfs_class " + std::to_string(rfs) + " out of range");
        }
        m.rfs_class = rfs;
      }
      if (e.contains("part_face_begin")) {
        auto begins = Field<std::vector<int>>(e, "part_face_begin", where);
        auto names = Field<std::vector<std::string>>(e, "part_names", where);
        const int nf = static_cast<int>(m.mesh.faces.size());
        bool ok = !begins.empty() && begins.size() == names.size() && begins[0] == 0;
        for (std::size_t k = 1; ok && k < begins.size(); ++k) {
          ok = begins[k] > begins[k - 1] && begins[k] < nf;
        }
        if (!ok) throw ParseError(where, "part_face_begin inconsistent with the mesh");
        m.part_face_begin = std::move(begins);
        m.part_names = std::move(names);
      }
      models.push_back(std::move(m));
    }
    return models;
  }
  // No index: a plain ShapeNet tree.
  std::vector<std::pair<std::string, std::string>> found;  // (synset, path)
  for (const char* synset : CadSynsets()) {
    const fs::path sdir = fs::path(dir) / synset;
    if (!fs::is_directory(sdir)) continue;
    for (const auto& entry : fs::directory_iterator(sdir)) {
      const fs::path obj = entry.path() / "models" / "model_normalized.obj";
      if (entry.is_directory() && fs::exists(obj)) found.emplace_back(synset, obj.string());
    }
  }
  std::sort(found.begin(), found.end());
  for (const auto& [synset, path] : found) models.push_back(ReadShapeNetModel(path, synset));
  return models;
}

}  // namespace dimr::data
