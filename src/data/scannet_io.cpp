// ScanNet scene folder writer / reader (see scannet_io.h).
#include "dimr/data/scannet_io.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;
using nlohmann::json;

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open '" + path + "' for writing");
  f << text;
  if (!f) throw Error("error writing '" + path + "'");
}

json ReadJson(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ParseError(path, "cannot open file");
  try {
    return json::parse(f);
  } catch (const json::exception& e) {
    throw ParseError(path, std::string("malformed JSON: ") + e.what());
  }
}

json Vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

Vec3 GetVec(const json& j, const std::string& key, const std::string& source) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
    throw ParseError(source, "field '" + key + "' must be an array of 3 numbers");
  return Vec3(j[key][0].get<double>(), j[key][1].get<double>(), j[key][2].get<double>());
}

}  // namespace

int RfsFromCategory(const std::string& raw) {
  static const std::map<std::string, int> kAlias = {{"wall", kWall},
                                                    {"walls", kWall},
                                                    {"shower wall", kWall},
                                                    {"shower walls", kWall},
                                                    {"closet wall", kWall},
                                                    {"floor", kFloor},
                                                    {"shower floor", kFloor},
                                                    {"cabinet", kCabinet},
                                                    {"cabinets", kCabinet},
                                                    {"kitchen cabinets", kCabinet},
                                                    {"file cabinet", kCabinet},
                                                    {"bathroom vanity", kCabinet},
                                                    {"bathroom cabinet", kCabinet},
                                                    {"bed", kBed},
                                                    {"mattress", kBed},
                                                    {"chair", kChair},
                                                    {"office chair", kChair},
                                                    {"armchair", kChair},
                                                    {"sofa chair", kChair},
                                                    {"couch", kSofa},
                                                    {"sofa", kSofa},
                                                    {"table", kTable},
                                                    {"coffee table", kTable},
                                                    {"end table", kTable},
                                                    {"dining table", kTable},
                                                    {"door", kDoor},
                                                    {"doorframe", kDoor},
                                                    {"window", kWindow},
                                                    {"bookshelf", kBookshelf},
                                                    {"bookshelves", kBookshelf},
                                                    {"picture", kPicture},
                                                    {"poster", kPicture},
                                                    {"counter", kCounter},
                                                    {"kitchen counter", kCounter},
                                                    {"bathroom counter", kCounter},
                                                    {"desk", kDesk},
                                                    {"curtain", kCurtain},
                                                    {"curtains", kCurtain},
                                                    {"shower curtain", kShowerCurtain},
                                                    {"toilet", kToilet},
                                                    {"urinal", kToilet},
                                                    {"sink", kSink},
                                                    {"bathtub", kBathtub},
                                                    {"otherfurniture", kOtherFurniture},
                                                    {"radiator", kOtherFurniture},
                                                    {"ottoman", kOtherFurniture},
                                                    {"bench", kOtherFurniture},
                                                    {"kitchen cabinet", kKitchenCabinet},
                                                    {"kitchen_cabinet", kKitchenCabinet},
                                                    {"open kitchen cabinet", kKitchenCabinet},
                                                    {"monitor", kDisplay},
                                                    {"tv", kDisplay},
                                                    {"display", kDisplay},
                                                    {"trash can", kTrashBin},
                                                    {"trash bin", kTrashBin},
                                                    {"trash_bin", kTrashBin},
                                                    {"recycling bin", kTrashBin},
                                                    {"shelf", kOtherShelf},
                                                    {"shelves", kOtherShelf},
                                                    {"television", kDisplay},
                                                    {"refridgerator", kRefridgerator},
                                                    {"refrigerator", kRefridgerator},
                                                    {"other_shelf", kOtherShelf},
                                                    {"other_table", kOtherTable}};
  const auto it = kAlias.find(Lower(raw));
  if (it != kAlias.end()) return it->second;
  return -1;
}

int RfsToNyu40(int rfs) {
  // wall 1, floor 2, cabinet 3, bed 4, chair 5, sofa 6, table 7, door 8, window 9,
  // bookshelf 10, picture 11, counter 12, desk 14, shelves 15, curtain 16, refridgerator 24,
  // television 25, shower curtain 28, toilet 33, sink 34, bathtub 36, otherfurniture 39,
  // otherprop 40.
  static const int kMap[kNumRfsClasses] = {1,  2,  3,  4,  5,  6,  7,  8, 9,  10, 11, 12, 14,
                                           16, 24, 28, 33, 34, 36, 39, 3, 25, 39, 15, 7};
  if (rfs < 0 || rfs >= kNumRfsClasses) return 0;
  return kMap[rfs];
}

int Nyu40ToRfs(int nyu40) {
  switch (nyu40) {
    case 1:
      return kWall;
    case 2:
      return kFloor;
    case 3:
      return kCabinet;
    case 4:
      return kBed;
    case 5:
      return kChair;
    case 6:
      return kSofa;
    case 7:
      return kTable;
    case 8:
      return kDoor;
    case 9:
      return kWindow;
    case 10:
      return kBookshelf;
    case 11:
      return kPicture;
    case 12:
      return kCounter;
    case 14:
      return kDesk;
    case 15:
      return kOtherShelf;
    case 16:
      return kCurtain;
    case 24:
      return kRefridgerator;
    case 25:
      return kDisplay;
    case 28:
      return kShowerCurtain;
    case 33:
      return kToilet;
    case 34:
      return kSink;
    case 36:
      return kBathtub;
    case 39:
      return kOtherFurniture;
    default:
      return -1;
  }
}

void WriteScanNetScene(const std::string& scans_dir, const SynthScene& scene) {
  scene.Validate();
  if (scene.name.empty() || scene.name.find('/') != std::string::npos)
    throw InvalidArgument("WriteScanNetScene: bad scene name '" + scene.name + "'");
  const fs::path dir = fs::path(scans_dir) / scene.name;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw Error("cannot create the scene folder '" + dir.string() + "': " + ec.message());
  const std::string base = (dir / scene.name).string();
  const std::size_t n = scene.points.size();

  geometry::PointCloud cloud;
  cloud.points = scene.points;
  cloud.colors = scene.colors;
  cloud.SetAttribute("alpha", geometry::ScalarType::kUInt8, std::vector<double>(n, 255.0));
  geometry::WritePly(base + "_vh_clean_2.ply", cloud);
  std::vector<double> labels(n);
  for (std::size_t k = 0; k < n; ++k)
    labels[k] = scene.semantic[k] == kSemanticIgnore
                    ? (scene.instance[k] > 0 ? 40.0 : 0.0)
                    : static_cast<double>(RfsToNyu40(scene.semantic[k]));
  cloud.SetAttribute("label", geometry::ScalarType::kUInt16, std::move(labels));
  geometry::WritePly(base + "_vh_clean_2.labels.ply", cloud);

  json segs;
  segs["params"] = {{"kThresh", "0.0001"}, {"segMinVerts", "20"},  {"minPoints", "750"},
                    {"maxPoints", "5000"}, {"thinThresh", "0.05"}, {"flatThresh", "0.001"},
                    {"minLength", "0.02"}, {"maxLength", "1"}};
  segs["sceneId"] = scene.name;
  segs["segIndices"] = scene.segment;
  WriteText(base + "_vh_clean_2.0.010000.segs.json", segs.dump());

  // Segments of each instance, in order of first appearance.
  std::map<int, std::vector<int>> segments_of;
  std::map<int, int> owner;
  for (std::size_t k = 0; k < n; ++k) {
    const int seg = scene.segment[k], inst = scene.instance[k];
    auto it = owner.find(seg);
    if (it == owner.end()) {
      owner[seg] = inst;
      if (inst > 0) segments_of[inst].push_back(seg);
    } else if (it->second != inst) {
      throw InvalidArgument("scene " + scene.name + ": segment " + std::to_string(seg) +
                            " spans instances " + std::to_string(it->second) + " and " +
                            std::to_string(inst));
    }
  }
  json agg;
  agg["sceneId"] = "scannet." + scene.name;
  agg["appId"] = "SynthScan.v1";
  agg["segGroups"] = json::array();
  for (const auto& inst : scene.instances) {
    json g;
    g["id"] = inst.id - 1;
    g["objectId"] = inst.id - 1;
    g["segments"] = segments_of[inst.id];
    g["label"] = inst.category;
    agg["segGroups"].push_back(g);
  }
  agg["segmentsFile"] = "scannet." + scene.name + "_vh_clean_2.0.010000.segs.json";
  WriteText(base + ".aggregation.json", agg.dump());

  std::ostringstream txt;
  txt.precision(17);
  txt << "axisAlignment =";
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) txt << ' ' << scene.axis_alignment(r, c);
  }
  txt << "\nnumDepthFrames = 0\nsceneType = "
      << (scene.room_type.empty() ? "Unknown" : scene.room_type) << "\n";
  WriteText(base + ".txt", txt.str());

  json meta;
  meta["scene"] = scene.name;
  meta["room_shape"] = scene.room_shape;
  meta["room_type"] = scene.room_type;
  meta["floor_area"] = scene.floor_area;
  meta["room_height"] = scene.room_height;
  meta["instances"] = json::array();
  for (const auto& i : scene.instances) {
    json j;
    j["id"] = i.id;
    j["category"] = i.category;
    j["rfs_class"] = i.rfs_class;
    j["cad_class"] = i.cad_class;
    j["synset"] = i.synset;
    j["model_id"] = i.model_id;
    j["family"] = i.family;
    j["symmetric"] = i.symmetric;
    j["trs"] = {{"translation", Vec(i.translation)},
                {"rotation", {i.rotation.w(), i.rotation.x(), i.rotation.y(), i.rotation.z()}},
                {"scale", Vec(i.scale)}};
    j["box"] = {
        {"center", Vec(i.box.center)}, {"size", Vec(i.box.size)}, {"heading", i.box.heading}};
    j["num_points"] = i.num_points;
    j["visible_fraction"] = i.visible_fraction;
    meta["instances"].push_back(j);
  }
  WriteText(base + ".synthscan.json", meta.dump(1));
}

SynthScene ReadScanNetScene(const std::string& scene_dir) {
  fs::path dir(scene_dir);
  if (dir.filename().empty()) dir = dir.parent_path();
  SynthScene s;
  s.name = dir.filename().string();
  const std::string base = (dir / s.name).string();
  const std::string ply_path = base + "_vh_clean_2.ply";
  const geometry::PointCloud cloud = geometry::ReadPlyCloud(ply_path);
  const std::size_t n = cloud.size();
  if (cloud.colors.size() != n) throw ParseError(ply_path, "vertices have no red/green/blue");
  s.points = cloud.points;
  s.colors = cloud.colors;

  std::vector<int> nyu(n, 0);
  const std::string labels_path = base + "_vh_clean_2.labels.ply";
  if (fs::exists(labels_path)) {
    const geometry::PointCloud lab = geometry::ReadPlyCloud(labels_path);
    const auto* attr = lab.FindAttribute("label");
    if (!attr) throw ParseError(labels_path, "no vertex property 'label'");
    if (lab.size() != n)
      throw ParseError(labels_path, "has " + std::to_string(lab.size()) + " vertices, " + ply_path +
                                        " has " + std::to_string(n));
    for (std::size_t k = 0; k < n; ++k) nyu[k] = static_cast<int>(attr->values[k]);
  }

  const std::string segs_path = base + "_vh_clean_2.0.010000.segs.json";
  const json segs = ReadJson(segs_path);
  if (!segs.contains("segIndices") || !segs["segIndices"].is_array())
    throw ParseError(segs_path, "no 'segIndices' array");
  if (segs["segIndices"].size() != n)
    throw ParseError(segs_path, "segIndices has " + std::to_string(segs["segIndices"].size()) +
                                    " entries for " + std::to_string(n) + " vertices");
  s.segment.resize(n);
  for (std::size_t k = 0; k < n; ++k) s.segment[k] = segs["segIndices"][k].get<int>();

  s.instance.assign(n, 0);
  s.semantic.assign(n, kSemanticIgnore);
  const std::string agg_path = base + ".aggregation.json";
  const bool have_agg = fs::exists(agg_path);
  std::map<int, int> seg_to_instance;
  if (have_agg) {
    const json agg = ReadJson(agg_path);
    if (!agg.contains("segGroups") || !agg["segGroups"].is_array())
      throw ParseError(agg_path, "no 'segGroups' array");
    for (std::size_t gi = 0; gi < agg["segGroups"].size(); ++gi) {
      const json& g = agg["segGroups"][gi];
      const std::string where = agg_path + " segGroups[" + std::to_string(gi) + "]";
      if (!g.contains("objectId") || !g.contains("segments") || !g.contains("label"))
        throw ParseError(where, "needs objectId, segments and label");
      SynthInstance inst;
      inst.id = g["objectId"].get<int>() + 1;
      inst.category = g["label"].get<std::string>();
      inst.rfs_class = RfsFromCategory(inst.category);
      inst.cad_class = inst.rfs_class >= 0 ? RfsToCad(inst.rfs_class) : -1;
      for (const auto& seg : g["segments"]) seg_to_instance[seg.get<int>()] = inst.id;
      s.instances.push_back(inst);
    }
    for (std::size_t k = 0; k < n; ++k) {
      auto it = seg_to_instance.find(s.segment[k]);
      if (it != seg_to_instance.end()) s.instance[k] = it->second;
    }
  }
  std::map<int, int> rfs_of;
  for (const auto& i : s.instances) rfs_of[i.id] = i.rfs_class;
  for (std::size_t k = 0; k < n; ++k) {
    if (have_agg) {
      const int r = s.instance[k] > 0 ? rfs_of[s.instance[k]] : -1;
      s.semantic[k] = r < 0 ? kSemanticIgnore : r;
    } else {
      const int r = Nyu40ToRfs(nyu[k]);
      s.semantic[k] = r < 0 ? kSemanticIgnore : r;
    }
  }

  const std::string txt_path = base + ".txt";
  if (fs::exists(txt_path)) {
    std::ifstream f(txt_path);
    std::string line;
    while (std::getline(f, line)) {
      if (line.rfind("axisAlignment", 0) == 0) {
        const auto eq = line.find('=');
        std::istringstream in(line.substr(eq == std::string::npos ? line.size() : eq + 1));
        for (int k = 0; k < 16; ++k) {
          if (!(in >> s.axis_alignment(k / 4, k % 4)))
            throw ParseError(txt_path, "axisAlignment needs 16 numbers");
        }
      } else if (line.rfind("sceneType", 0) == 0) {
        const auto eq = line.find("= ");
        if (eq != std::string::npos) s.room_type = line.substr(eq + 2);
      }
    }
  }

  const std::string meta_path = base + ".synthscan.json";
  if (fs::exists(meta_path)) {
    const json meta = ReadJson(meta_path);
    try {
      s.room_shape = meta.at("room_shape").get<std::string>();
      s.room_type = meta.at("room_type").get<std::string>();
      s.floor_area = meta.at("floor_area").get<double>();
      s.room_height = meta.at("room_height").get<double>();
      std::map<int, const json*> by_id;
      for (const auto& j : meta.at("instances")) by_id[j.at("id").get<int>()] = &j;
      for (auto& inst : s.instances) {
        auto it = by_id.find(inst.id);
        if (it == by_id.end())
          throw ParseError(meta_path, "no entry for instance " + std::to_string(inst.id));
        const json& j = *it->second;
        inst.category = j.at("category").get<std::string>();
        inst.rfs_class = j.at("rfs_class").get<int>();
        inst.cad_class = j.at("cad_class").get<int>();
        inst.synset = j.at("synset").get<std::string>();
        inst.model_id = j.at("model_id").get<std::string>();
        inst.family = j.at("family").get<std::string>();
        inst.symmetric = j.at("symmetric").get<bool>();
        const json& trs = j.at("trs");
        inst.translation = GetVec(trs, "translation", meta_path);
        inst.scale = GetVec(trs, "scale", meta_path);
        const json& q = trs.at("rotation");
        inst.rotation = Eigen::Quaterniond(q.at(0).get<double>(), q.at(1).get<double>(),
                                           q.at(2).get<double>(), q.at(3).get<double>());
        const json& b = j.at("box");
        inst.box.center = GetVec(b, "center", meta_path);
        inst.box.size = GetVec(b, "size", meta_path);
        inst.box.heading = b.at("heading").get<double>();
        inst.num_points = j.at("num_points").get<int>();
        inst.visible_fraction = j.at("visible_fraction").get<double>();
      }
    } catch (const json::exception& e) {
      throw ParseError(meta_path, std::string("malformed SynthScan metadata: ") + e.what());
    }
  } else {
    // Real ScanNet: boxes from the points (axis-aligned), counts from the labels.
    std::map<int, geometry::AABB> bounds;
    std::map<int, int> counts;
    for (std::size_t k = 0; k < n; ++k) {
      if (s.instance[k] > 0) {
        bounds[s.instance[k]].Extend(s.points[k]);
        ++counts[s.instance[k]];
      }
    }
    for (auto& inst : s.instances) {
      inst.num_points = counts[inst.id];
      if (counts[inst.id] > 0) {
        inst.box.center = bounds[inst.id].Center();
        inst.box.size = bounds[inst.id].Extent();
      }
    }
  }
  return s;
}

}  // namespace dimr::data
