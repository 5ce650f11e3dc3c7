#include "tools/reconstruct_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/pipeline/cloud_io.h"
#include "tools/render.h"

namespace dimr::tools {
namespace {

namespace fs = std::filesystem;

bool IsCloudFile(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e == ".ply" || e == ".pcd";
}

fs::path ScanNetCloud(const fs::path& dir) {
  return dir / (dir.filename().string() + "_vh_clean_2.ply");
}

bool IsScanNetScene(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(ScanNetCloud(dir), ec);
}

std::vector<InputScene> ScansFolder(const fs::path& dir) {
  std::vector<InputScene> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_directory(ec) || !IsScanNetScene(e.path())) continue;
    InputScene s;
    s.name = e.path().filename().string();
    s.path = ScanNetCloud(e.path()).string();
    s.kind = "scannet";
    out.push_back(std::move(s));
  }
  std::sort(out.begin(), out.end(),
            [](const InputScene& a, const InputScene& b) { return a.name < b.name; });
  return out;
}

// ScanNet's `<scene>.txt` axisAlignment (row-major 4x4), identity when absent.
Eigen::Matrix4d ReadAxisAlignment(const fs::path& txt) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  std::error_code ec;
  if (!fs::is_regular_file(txt, ec)) return m;
  std::ifstream f(txt);
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("axisAlignment", 0) != 0) continue;
    const auto eq = line.find('=');
    std::istringstream in(line.substr(eq == std::string::npos ? line.size() : eq + 1));
    for (int k = 0; k < 16; ++k) {
      if (!(in >> m(k / 4, k % 4)))
        throw ParseError(txt.string(), "axisAlignment needs 16 numbers");
    }
    if (!m.allFinite()) throw ParseError(txt.string(), "axisAlignment is not finite");
  }
  return m;
}

}  // namespace

std::vector<InputScene> ListInputScenes(const std::string& input) {
  const fs::path p(input);
  std::error_code ec;
  if (fs::is_regular_file(p, ec)) {
    if (!IsCloudFile(p)) {
      throw ParseError(input, "not a point cloud file (.ply or .pcd)");
    }
    InputScene s;
    s.name = p.stem().string();
    s.path = input;
    s.kind = "cloud";
    return {s};
  }
  if (!fs::is_directory(p, ec)) throw ParseError(input, "no such file or folder");
  if (IsScanNetScene(p)) {
    InputScene s;
    s.name = p.filename().string();
    if (s.name.empty()) s.name = p.parent_path().filename().string();
    s.path = ScanNetCloud(p).string();
    s.kind = "scannet";
    return {s};
  }
  if (fs::is_directory(p / "scans", ec)) {
    auto out = ScansFolder(p / "scans");
    if (!out.empty()) return out;
  }
  auto out = ScansFolder(p);
  if (out.empty()) {
    throw ParseError(input,
                     "holds no scene: expected a .ply/.pcd cloud, a ScanNet scene folder "
                     "(<scene>/<scene>_vh_clean_2.ply), a folder of scene folders or a SynthScan "
                     "split (with scans/)");
  }
  return out;
}

void LoadInputScene(InputScene* s) {
  s->cloud = pipeline::ReadPointCloudFile(s->path);
  s->alignment.setIdentity();
  if (s->kind == "scannet") {
    const fs::path dir = fs::path(s->path).parent_path();
    s->alignment = ReadAxisAlignment(dir / (s->name + ".txt"));
    if (!s->alignment.isIdentity(0.0)) {
      s->cloud.Transform(s->alignment.topLeftCorner<3, 3>(), s->alignment.topRightCorner<3, 1>());
    }
  }
  s->cloud.attributes.clear();
}

std::string InstanceMeshName(const std::string& scene, int k, int cad_class, double score) {
  if (cad_class < 0 || cad_class >= data::kNumCadClasses) {
    throw InvalidArgument("InstanceMeshName: class " + std::to_string(cad_class) + " out of range");
  }
  char buf[64];
  std::snprintf(buf, sizeof(buf), "_%d_%s_%.4f.ply", k, data::CadClassNames()[cad_class], score);
  return scene + buf;
}

std::vector<geometry::TriangleMesh> ReadSceneGtMeshes(const std::string& gt_dir,
                                                      const std::string& scene) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(gt_dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(scene + "_", 0) == 0 && n.size() > 6 && n.substr(n.size() - 6) == "_1.ply") {
      files.push_back(e.path().string());
    }
  }
  if (ec) throw ParseError(gt_dir, "cannot list the GT folder");
  std::sort(files.begin(), files.end());
  std::vector<geometry::TriangleMesh> out;
  for (const auto& f : files) out.push_back(geometry::ReadPlyMesh(f));
  return out;
}

WrittenScene WriteSceneOutputs(const std::string& out_dir, const InputScene& scene,
                               const pipeline::SceneResult& result, bool picture,
                               const std::vector<geometry::TriangleMesh>* gt_meshes) {
  const fs::path out(out_dir);
  std::error_code ec;
  for (const char* sub : {"meshes", "vis", "alternatives"}) {
    fs::create_directories(out / sub, ec);
    if (!fs::is_directory(out / sub, ec)) {
      throw Error("cannot create the output folder '" + (out / sub).string() + "'");
    }
  }
  WrittenScene w;
  using nlohmann::json;
  json j;
  j["scene"] = scene.name;
  j["input"] = scene.path;
  j["input_points"] = result.input_points;
  j["used_points"] = result.used_points;
  j["instances"] = json::array();
  geometry::TriangleMesh combined;
  int k = 0;
  for (const auto& inst : result.instances) {
    if (inst.mesh.empty()) continue;  // nothing to evaluate or show (warned by the pipeline)
    const std::string name = InstanceMeshName(scene.name, k, inst.cad_class, inst.score);
    const fs::path mesh_path = out / "meshes" / name;
    geometry::WritePly(mesh_path.string(), inst.mesh);
    w.meshes.push_back(mesh_path.string());
    json o;
    o["id"] = inst.id;
    o["class"] = data::CadClassNames()[inst.cad_class];
    o["score"] = inst.score;
    o["mesh"] = (fs::path("meshes") / name).string();
    o["points"] = inst.support;
    o["box"] = {{"center", {inst.box.center.x(), inst.box.center.y(), inst.box.center.z()}},
                {"size", {inst.box.size.x(), inst.box.size.y(), inst.box.size.z()}},
                {"heading", inst.box.heading}};
    o["source"] = pipeline::MeshSourceName(inst.source);
    if (!inst.pool_model_id.empty()) o["pool_model_id"] = inst.pool_model_id;
    if (!inst.neighbours.empty()) o["neighbours"] = inst.neighbours;
    o["icp_accepted"] = inst.icp_accepted;
    o["latent"] = std::vector<float>(inst.latent.data(), inst.latent.data() + inst.latent.size());
    json alts = json::array();
    for (std::size_t a = 0; a < inst.alternatives.size(); ++a) {
      const auto& h = inst.alternatives[a];
      if (h.mesh.empty()) continue;
      char suffix[32];
      std::snprintf(suffix, sizeof(suffix), "_alt%zu.ply", a);
      const std::string alt = name.substr(0, name.size() - 4) + suffix;
      geometry::WritePly((out / "alternatives" / alt).string(), h.mesh);
      alts.push_back({{"mesh", (fs::path("alternatives") / alt).string()},
                      {"score", h.score},
                      {"source", pipeline::MeshSourceName(h.source)}});
    }
    if (!alts.empty()) o["alternatives"] = alts;
    j["instances"].push_back(o);
    geometry::TriangleMesh part = inst.mesh;
    part.vertex_normals.clear();
    part.attributes.clear();
    const geometry::Vec3 c = PaletteColour(k) * 255.0;
    part.vertex_colors.assign(
        part.vertices.size(),
        geometry::Color(static_cast<std::uint8_t>(c.x()), static_cast<std::uint8_t>(c.y()),
                        static_cast<std::uint8_t>(c.z())));
    combined.Append(part);
    ++k;
  }
  json t = json::object();
  for (const auto& [stage, ms] : result.timings) t[stage] = ms;
  j["timings_ms"] = t;
  j["warnings"] = result.warnings;
  j["config"] = result.config;
  w.json = (out / (scene.name + ".json")).string();
  {
    std::ofstream f(w.json);
    f << j.dump(1) << "\n";
    if (!f) throw Error("cannot write '" + w.json + "'");
  }
  w.combined_ply = (out / "vis" / (scene.name + ".ply")).string();
  geometry::WritePly(w.combined_ply, combined);
  if (picture && !scene.cloud.points.empty()) {
    ScenePanel input, pred;
    const std::size_t n = scene.cloud.points.size();
    const std::size_t stride = std::max<std::size_t>(1, n / 150000);
    for (std::size_t i = 0; i < n; i += stride) {
      const auto& q = scene.cloud.points[i];
      if (!q.allFinite()) continue;
      input.points.push_back(q);
      pred.points.push_back(q);
      const geometry::Vec3 c = scene.cloud.HasColors()
                                   ? scene.cloud.colors[i].cast<double>() / 255.0
                                   : geometry::Vec3(0.5, 0.5, 0.5);
      input.point_colors.push_back(c);
      pred.point_colors.push_back(0.35 * c + geometry::Vec3::Constant(0.55));
    }
    input.title = scene.name + " input";
    pred.title = "prediction";
    int m = 0;
    for (const auto& inst : result.instances) {
      if (inst.mesh.empty()) continue;
      pred.meshes.push_back({inst.mesh, PaletteColour(m)});
      pred.boxes.push_back({inst.box, 0.6 * PaletteColour(m)});
      ++m;
    }
    std::vector<ScenePanel> panels = {input, pred};
    if (gt_meshes != nullptr) {
      ScenePanel gt;
      gt.title = "ground truth";
      gt.points = pred.points;
      gt.point_colors = pred.point_colors;
      for (std::size_t g = 0; g < gt_meshes->size(); ++g) {
        gt.meshes.push_back({(*gt_meshes)[g], geometry::Vec3(0.55, 0.7, 0.55)});
      }
      panels.push_back(std::move(gt));
    }
    if (!input.points.empty()) {
      w.picture = (out / "vis" / (scene.name + ".png")).string();
      RenderScenePanels(panels, 800, 600, w.picture);
    }
  }
  return w;
}

}  // namespace dimr::tools
