#include "dimr/eval/inputs.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dimr/eval/classes.h"
#include "dimr/eval/npz.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::eval {

namespace fs = std::filesystem;

namespace {

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur.push_back(c);
    }
  }
  out.push_back(cur);
  return out;
}

bool ParseDouble(const std::string& s, double* v) {
  if (s.empty()) return false;
  try {
    std::size_t pos = 0;
    *v = std::stod(s, &pos);
    return pos == s.size() && std::isfinite(*v);
  } catch (...) {
    return false;
  }
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

void SortRecords(std::vector<MeshRecord>* r) {
  std::stable_sort(r->begin(), r->end(), [](const MeshRecord& a, const MeshRecord& b) {
    return a.scene != b.scene ? a.scene < b.scene : a.name < b.name;
  });
}

}  // namespace

MeshRecord ParseReferenceName(const std::string& path) {
  const std::string base = fs::path(path).filename().string();
  std::string stem = base;
  if (stem.size() > 4 && Lower(stem.substr(stem.size() - 4)) == ".ply") {
    stem = stem.substr(0, stem.size() - 4);
  }
  if (stem.size() < 12) {
    throw ParseError(path, "file name is shorter than the 12-character scene id");
  }
  const std::vector<std::string> tok = Split(stem, '_');
  if (tok.size() < 5) {
    throw ParseError(path, "expected {scene}_{k}_{class}_{score}.ply (at least 5 '_' tokens)");
  }
  MeshRecord r;
  r.scene = stem.substr(0, 12);
  r.name = base;
  r.path = path;
  r.cls = ClassFromName(tok[3]);
  if (r.cls < 0) {
    throw ParseError(path, "unknown class token '" + tok[3] +
                               "' (expected table, chair, bookshelf, sofa, trash, cabinet, "
                               "display or bathtub)");
  }
  if (!ParseDouble(tok.back(), &r.score)) {
    throw ParseError(path, "score token '" + tok.back() + "' is not a number");
  }
  return r;
}

std::vector<MeshRecord> ReadSceneResultJson(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ParseError(path, "cannot open SceneResult JSON");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ParseSceneResultJson(ss.str(), path, fs::path(path).parent_path().string());
}

std::vector<MeshRecord> ParseSceneResultJson(const std::string& text, const std::string& path,
                                             const std::string& folder_name) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    throw ParseError(path, std::string("invalid JSON: ") + e.what());
  }
  if (!j.is_object() || !j.contains("scene") || !j["scene"].is_string()) {
    throw ParseError(path, "missing string field 'scene'");
  }
  if (!j.contains("instances") || !j["instances"].is_array()) {
    throw ParseError(path, "missing array field 'instances'");
  }
  const std::string scene = j["scene"].get<std::string>();
  const fs::path folder(folder_name);
  std::vector<MeshRecord> out;
  int k = 0;
  for (const auto& inst : j["instances"]) {
    const std::string where = "instances[" + std::to_string(k) + "]";
    if (!inst.is_object()) throw ParseError(path, where + " is not an object");
    if (!inst.contains("class") || !inst["class"].is_string()) {
      throw ParseError(path, where + ".class missing or not a string");
    }
    if (!inst.contains("score") || !inst["score"].is_number()) {
      throw ParseError(path, where + ".score missing or not a number");
    }
    if (!inst.contains("mesh") || !inst["mesh"].is_string()) {
      throw ParseError(path, where + ".mesh missing or not a string");
    }
    MeshRecord r;
    r.scene = scene;
    r.cls = ClassFromName(inst["class"].get<std::string>());
    if (r.cls < 0) {
      throw ParseError(path,
                       where + ".class: unknown class '" + inst["class"].get<std::string>() + "'");
    }
    r.score = inst["score"].get<double>();
    if (!std::isfinite(r.score)) throw ParseError(path, where + ".score is not finite");
    r.path = (folder / inst["mesh"].get<std::string>()).string();
    char key[32];
    std::snprintf(key, sizeof key, "#%08d", k);  // keeps array order within the scene
    r.name = fs::path(path).filename().string() + key;
    out.push_back(std::move(r));
    ++k;
  }
  return out;
}

void WriteSceneResultJson(const std::string& path, const std::string& scene,
                          const std::vector<MeshRecord>& instances,
                          const std::vector<std::vector<int>>& points) {
  nlohmann::json j;
  j["scene"] = scene;
  j["instances"] = nlohmann::json::array();
  const fs::path folder = fs::path(path).parent_path();
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const MeshRecord& r = instances[i];
    if (r.cls < 0 || r.cls >= kNumClasses) {
      throw InvalidArgument("WriteSceneResultJson: instance " + std::to_string(i) +
                            " has no valid class");
    }
    nlohmann::json o;
    o["id"] = i;
    o["class"] = ClassNames()[r.cls];
    o["score"] = r.score;
    o["mesh"] = fs::path(r.path).lexically_relative(folder.empty() ? "." : folder).string();
    if (i < points.size()) o["points"] = points[i];
    j["instances"].push_back(o);
  }
  std::ofstream out(path);
  if (!out) throw InvalidArgument("cannot write " + path);
  out << j.dump(1) << "\n";
}

std::vector<MeshRecord> ListMeshFolder(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw ParseError(dir, "not a folder");
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file()) files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  std::vector<MeshRecord> out;
  for (const std::string& f : files) {
    const std::string ext = Lower(fs::path(f).extension().string());
    if (ext == ".ply") {
      out.push_back(ParseReferenceName(f));
    } else if (ext == ".json") {
      auto recs = ReadSceneResultJson(f);
      out.insert(out.end(), recs.begin(), recs.end());
    }
  }
  SortRecords(&out);
  return out;
}

std::vector<PointsGt> PcrGtFromArrays(const std::string& scene,
                                      const std::vector<geometry::Vec3>& points,
                                      const std::vector<int>& semantic_rfs,
                                      const std::vector<int>& instance_1based) {
  if (semantic_rfs.size() != points.size() || instance_1based.size() != points.size()) {
    throw InvalidArgument("PCR GT of " + scene + ": label arrays do not match the point count");
  }
  int max_id = -1;
  for (int v : instance_1based) max_id = std::max(max_id, v - 1);
  std::vector<std::vector<int>> members(static_cast<std::size_t>(max_id + 1));
  for (std::size_t i = 0; i < points.size(); ++i) {
    const int id = instance_1based[i] - 1;
    if (id >= 0) members[id].push_back(static_cast<int>(i));
  }
  std::vector<PointsGt> out;
  for (int id = 0; id <= max_id; ++id) {
    const auto& m = members[id];
    if (m.empty()) continue;
    const int sem = semantic_rfs[m.front()];  // the first (lowest-index) vertex decides
    if (sem == 255) continue;
    const int cls = RfsToCad(sem);
    if (cls < 0) continue;
    PointsGt g;
    g.scene = scene;
    g.cls = cls;
    g.points.reserve(m.size());
    for (int i : m) g.points.push_back(points[i]);
    out.push_back(std::move(g));
  }
  return out;
}

std::vector<PointsGt> ReadPcrGtScene(const std::string& path, const std::string& scene) {
  const geometry::PointCloud cloud = geometry::ReadPlyCloud(path);
  auto find = [&](std::initializer_list<const char*> names) -> const geometry::VertexAttribute* {
    for (const char* n : names) {
      if (const auto* a = cloud.FindAttribute(n)) return a;
    }
    return nullptr;
  };
  const auto* sem = find({"semantic_label", "semantic_labels", "label"});
  const auto* ins = find({"instance_label", "instance_labels", "instance"});
  if (!sem) throw ParseError(path, "no semantic label vertex property (semantic_label/label)");
  if (!ins) throw ParseError(path, "no instance label vertex property (instance_label/instance)");
  std::vector<int> s(sem->values.begin(), sem->values.end());
  std::vector<int> i(ins->values.begin(), ins->values.end());
  return PcrGtFromArrays(scene, cloud.points, s, i);
}

std::vector<PointsGt> ReadPcrGtNpz(const std::string& path, const std::string& scene) {
  const auto arrays = ReadNpz(path);
  auto get = [&](const char* name) -> const NpyArray& {
    const auto it = arrays.find(name);
    if (it == arrays.end()) throw ParseError(path, std::string("missing array '") + name + "'");
    return it->second;
  };
  const NpyArray& v = get("mesh_vertices");
  const NpyArray& sem = get("semantic_labels");
  const NpyArray& inst = get("instance_labels");
  if (v.shape.size() != 2 || v.shape[1] < 3) {
    throw ParseError(path, "mesh_vertices must be N x 3 or N x 6");
  }
  const std::int64_t n = v.shape[0], cols = v.shape[1];
  if (sem.size() != n || inst.size() != n) {
    throw ParseError(path, "semantic_labels / instance_labels do not have one value per vertex");
  }
  std::vector<geometry::Vec3> pts(static_cast<std::size_t>(n));
  std::vector<int> s(static_cast<std::size_t>(n)), in(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i) {
    pts[i] = geometry::Vec3(v.values[i * cols], v.values[i * cols + 1], v.values[i * cols + 2]);
    s[i] = static_cast<int>(sem.values[i]);
    in[i] = static_cast<int>(inst.values[i]);
  }
  return PcrGtFromArrays(scene, pts, s, in);
}

std::vector<PointsGt> LoadPcrGtFolder(const std::string& dir, std::vector<std::string>* scenes,
                                      const std::string& scene_list) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw ParseError(dir, "not a folder");
  // scene -> file (PLY per scene, or <scene>/data.npz as the reference's processed data).
  std::map<std::string, std::string> files;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file() && Lower(e.path().extension().string()) == ".ply") {
      files[e.path().stem().string()] = e.path().string();
    } else if (e.is_directory() && fs::is_regular_file(e.path() / "data.npz", ec)) {
      files[e.path().filename().string()] = (e.path() / "data.npz").string();
    }
  }
  std::vector<std::string> wanted;
  if (!scene_list.empty()) {
    std::ifstream in(scene_list);
    if (!in) throw ParseError(scene_list, "cannot open the scene list");
    std::string line;
    while (std::getline(in, line)) {
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
      if (line.empty()) continue;
      if (!files.count(line)) {
        throw ParseError(scene_list, "scene '" + line + "' has no GT points in " + dir);
      }
      wanted.push_back(line);
    }
  } else {
    for (const auto& [scene, file] : files) wanted.push_back(scene);
  }
  std::sort(wanted.begin(), wanted.end());
  std::vector<PointsGt> out;
  if (scenes) scenes->clear();
  for (const std::string& scene : wanted) {
    if (scenes) scenes->push_back(scene);
    const std::string& f = files.at(scene);
    auto g = Lower(fs::path(f).extension().string()) == ".npz" ? ReadPcrGtNpz(f, scene)
                                                               : ReadPcrGtScene(f, scene);
    out.insert(out.end(), std::make_move_iterator(g.begin()), std::make_move_iterator(g.end()));
  }
  return out;
}

}  // namespace dimr::eval
