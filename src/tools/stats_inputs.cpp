#include "tools/stats_inputs.h"

#include <algorithm>
#include <filesystem>

#include "dimr/core/error.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/synthscan.h"
#include "dimr/geometry/ply_io.h"

namespace dimr::tools {
namespace {

namespace fs = std::filesystem;

bool IsSceneFolder(const fs::path& dir) {
  const std::string name = dir.filename().string();
  return fs::is_regular_file(dir / (name + "_vh_clean_2.ply"));
}

fs::path Normalised(const std::string& p) {
  fs::path path(p);
  if (path.filename().empty()) path = path.parent_path();
  return path;
}

}  // namespace

std::vector<std::string> ListStatsInputs(const std::string& input) {
  const fs::path path = Normalised(input);
  if (fs::is_regular_file(path)) return {path.string()};
  if (!fs::is_directory(path))
    throw ParseError(input,
                     "no such file or folder (want a PLY, a ScanNet scene folder, a "
                     "folder of scene folders or a SynthScan split)");
  if (IsSceneFolder(path)) return {path.string()};
  const fs::path scans = fs::is_directory(path / "scans") ? path / "scans" : path;
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(scans))
    if (e.is_directory() && IsSceneFolder(e.path())) out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  if (out.empty())
    throw ParseError(input, "holds no ScanNet scene folder (<scene>/<scene>_vh_clean_2.ply)");
  return out;
}

StatsCloud ReadStatsCloud(const std::string& p) {
  const fs::path path = Normalised(p);
  StatsCloud c;
  if (fs::is_regular_file(path)) {
    geometry::PointCloud cloud = geometry::ReadPlyCloud(path.string());
    c.name = path.stem().string();
    c.points = std::move(cloud.points);
    c.colors = std::move(cloud.colors);
    if (const auto* lab = cloud.FindAttribute("label")) {
      c.nyu40.resize(lab->values.size());
      c.semantic.resize(lab->values.size());
      for (std::size_t i = 0; i < lab->values.size(); ++i) {
        c.nyu40[i] = static_cast<int>(lab->values[i]);
        const int r = data::Nyu40ToRfs(c.nyu40[i]);
        c.semantic[i] = r < 0 ? data::kSemanticIgnore : r;
      }
    }
    return c;
  }
  const std::string name = path.filename().string();
  const fs::path base = path / name;
  c.name = name;
  const bool have_segs = fs::exists(base.string() + "_vh_clean_2.0.010000.segs.json");
  const bool have_agg = fs::exists(base.string() + ".aggregation.json");
  if (have_segs && have_agg) {
    data::SynthScene s = data::ReadScanNetScene(path.string());
    c.points = std::move(s.points);
    c.colors = std::move(s.colors);
    c.semantic = std::move(s.semantic);
    c.instance = std::move(s.instance);
    c.nyu40.resize(c.semantic.size());
    for (std::size_t i = 0; i < c.semantic.size(); ++i)
      c.nyu40[i] = c.semantic[i] == data::kSemanticIgnore ? 0 : data::RfsToNyu40(c.semantic[i]);
    return c;
  }
  const std::string ply = base.string() + "_vh_clean_2.ply";
  geometry::PointCloud cloud = geometry::ReadPlyCloud(ply);
  c.points = std::move(cloud.points);
  c.colors = std::move(cloud.colors);
  const std::string labels = base.string() + "_vh_clean_2.labels.ply";
  if (fs::exists(labels)) {
    const geometry::PointCloud lab = geometry::ReadPlyCloud(labels);
    const auto* attr = lab.FindAttribute("label");
    if (!attr) throw ParseError(labels, "no vertex property 'label'");
    if (lab.size() != c.points.size())
      throw ParseError(labels, "has " + std::to_string(lab.size()) + " vertices, " + ply + " has " +
                                   std::to_string(c.points.size()));
    c.nyu40.resize(lab.size());
    c.semantic.resize(lab.size());
    for (std::size_t i = 0; i < lab.size(); ++i) {
      c.nyu40[i] = static_cast<int>(attr->values[i]);
      const int r = data::Nyu40ToRfs(c.nyu40[i]);
      c.semantic[i] = r < 0 ? data::kSemanticIgnore : r;
    }
  }
  return c;
}

}  // namespace dimr::tools
