#include "dimr/eval/real_import.h"

#include <array>
#include <cmath>
#include <map>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"
#include "dimr/data/scannet_io.h"

namespace dimr::eval {
namespace {

// "7 x 6": an array's shape for messages.
std::string ShapeText(const NpyArray& a) {
  std::string shape;
  for (auto d : a.shape) shape += (shape.empty() ? "" : " x ") + std::to_string(d);
  return shape;
}

// Per-vertex integers of a 1-D (or N x 1) array, each within [lo, hi].
std::vector<int> IntegerColumn(const NpyArray& a, std::int64_t n, int lo, int hi,
                               const std::string& source, const char* what) {
  const bool column = a.shape.size() == 1 || (a.shape.size() == 2 && a.shape[1] == 1);
  if (!column || a.shape[0] != n) {
    throw ParseError(source, std::string("expected ") + std::to_string(n) + " " + what +
                                 " (one per vertex), got shape [" + ShapeText(a) + "]");
  }
  std::vector<int> out(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i) {
    const double v = a.values[static_cast<std::size_t>(i)];
    if (!std::isfinite(v) || v != std::floor(v) || v < lo || v > hi) {
      throw ParseError(source, std::string(what) + " of vertex " + std::to_string(i) + " is " +
                                   std::to_string(v) + ", expected an integer in [" +
                                   std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    out[static_cast<std::size_t>(i)] = static_cast<int>(v);
  }
  return out;
}

}  // namespace

const char* Nyu40ClassName(int nyu40) {
  static const std::array<const char*, 40> kNames = {
      "wall",       "floor",          "cabinet",        "bed",
      "chair",      "sofa",           "table",          "door",
      "window",     "bookshelf",      "picture",        "counter",
      "blinds",     "desk",           "shelves",        "curtain",
      "dresser",    "pillow",         "mirror",         "floor mat",
      "clothes",    "ceiling",        "books",          "refridgerator",
      "television", "paper",          "towel",          "shower curtain",
      "box",        "whiteboard",     "person",         "night stand",
      "toilet",     "sink",           "lamp",           "bathtub",
      "bag",        "otherstructure", "otherfurniture", "otherprop"};
  return nyu40 >= 1 && nyu40 <= 40 ? kNames[nyu40 - 1] : "";
}

data::SynthScene SceneFromLabelledVertices(const std::string& name, const NpyArray& vertices,
                                           const NpyArray& nyu40, const NpyArray& instance,
                                           const LabelledVertexSources& sources) {
  if (vertices.shape.size() != 2 || (vertices.shape[1] != 3 && vertices.shape[1] < 6)) {
    throw ParseError(sources.vertices,
                     "expected N x 3 (x y z) or N x >= 6 (x y z r g b) vertices, got shape [" +
                         ShapeText(vertices) + "]");
  }
  const std::int64_t n = vertices.shape[0];
  const std::int64_t cols = vertices.shape[1];
  if (n == 0) throw ParseError(sources.vertices, "no vertices");
  data::SynthScene s;
  s.name = name;
  s.points.resize(static_cast<std::size_t>(n));
  s.colors.assign(static_cast<std::size_t>(n), geometry::Color(128, 128, 128));
  for (std::int64_t i = 0; i < n; ++i) {
    const double* row = vertices.values.data() + i * cols;
    for (int d = 0; d < 3; ++d) {
      if (!std::isfinite(row[d]) || std::abs(row[d]) > 1e6) {
        throw ParseError(sources.vertices, "vertex " + std::to_string(i) +
                                               " has a non-finite or absurd coordinate " +
                                               std::to_string(row[d]));
      }
    }
    s.points[static_cast<std::size_t>(i)] = geometry::Vec3(row[0], row[1], row[2]);
    if (cols < 6) continue;
    for (int d = 3; d < 6; ++d) {
      if (!std::isfinite(row[d]) || row[d] < 0 || row[d] > 255) {
        throw ParseError(sources.vertices, "vertex " + std::to_string(i) + " has colour " +
                                               std::to_string(row[d]) + " outside [0, 255]");
      }
    }
    s.colors[static_cast<std::size_t>(i)] =
        geometry::Color(static_cast<std::uint8_t>(std::lround(row[3])),
                        static_cast<std::uint8_t>(std::lround(row[4])),
                        static_cast<std::uint8_t>(std::lround(row[5])));
  }
  const std::vector<int> nyu = IntegerColumn(nyu40, n, 0, 40, sources.nyu40, "NYU40 id");
  const std::vector<int> obj = IntegerColumn(instance, n, 0, 65535, sources.instance, "object id");

  // Each object's majority NYU40 id (ties: the smaller id, std::map order).
  std::map<int, std::map<int, int>> votes;
  for (std::int64_t i = 0; i < n; ++i) {
    if (obj[static_cast<std::size_t>(i)] > 0) ++votes[obj[i]][nyu[i]];
  }
  std::map<int, int> rfs_of;
  for (const auto& [id, hist] : votes) {
    int best = 0, count = -1, points = 0;
    for (const auto& [label, c] : hist) {
      points += c;
      if (c > count) best = label, count = c;
    }
    data::SynthInstance inst;
    inst.id = id;
    inst.category = best > 0 ? Nyu40ClassName(best) : "unannotated";
    inst.rfs_class = data::RfsFromCategory(inst.category);
    inst.cad_class = inst.rfs_class >= 0 ? labels::RfsToCad(inst.rfs_class) : -1;
    inst.num_points = points;
    rfs_of[id] = inst.rfs_class;
    s.instances.push_back(inst);
  }
  s.semantic.resize(static_cast<std::size_t>(n));
  s.instance = obj;
  s.segment = obj;
  for (std::int64_t i = 0; i < n; ++i) {
    const int r = obj[i] > 0 ? rfs_of[obj[i]] : data::Nyu40ToRfs(nyu[i]);
    s.semantic[static_cast<std::size_t>(i)] = r < 0 ? data::kSemanticIgnore : r;
  }
  s.room_type = "real (imported vertex arrays)";
  s.Validate();
  return s;
}

}  // namespace dimr::eval
