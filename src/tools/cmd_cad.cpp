// `dimr cad generate | stats | render`: the procedural CAD library from the command line.
//   dimr cad generate --class chair --count 100 --seed 0 --out data/cad
//   dimr cad stats --dir data/cad
//   dimr cad render --out docs/img/cad_contact_sheet.png --per-class 6
// `render` draws a labelled contact sheet with a small z-buffer software rasteriser and writes a
// PNG (own encoder: zlib stream with fixed-Huffman deflate blocks, CRC-32 and Adler-32).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/labels.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/error.h"
#include "tools/command_registry.h"
#include "tools/render.h"

namespace {

using dimr::data::CadModel;
using dimr::geometry::Vec3;

// ---------------------------------------------------------------------------------------
// Commands.
// ---------------------------------------------------------------------------------------
std::vector<int> ParseClasses(const std::string& name) {
  if (name == "all") {
    std::vector<int> all(dimr::data::kNumCadClasses);
    for (int c = 0; c < dimr::data::kNumCadClasses; ++c) all[c] = c;
    return all;
  }
  const int c = dimr::data::CadClassFromName(name);
  if (c < 0) {
    throw dimr::InvalidArgument("--class: unknown CAD class '" + name +
                                "' (table, chair, bookshelf, sofa, trash_bin, cabinet, display, "
                                "bathtub or all)");
  }
  return {c};
}

struct GenerateArgs {
  std::string cls = "all";
  int count = 10;
  std::uint64_t seed = 0;
  std::string out;
  int precision = 8;
};

void SetupGenerate(CLI::App& app) {
  auto a = std::make_shared<GenerateArgs>();
  app.add_option("--class", a->cls, "CAD class name or 'all'")->capture_default_str();
  app.add_option("--count", a->count, "models per class")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  app.add_option("--seed", a->seed, "first seed (models use seed, seed+1, ...)")
      ->capture_default_str();
  app.add_option("--out", a->out, "output ShapeNet-style tree")->required();
  app.add_option("--precision", a->precision, "OBJ digits after the decimal point")
      ->capture_default_str()
      ->check(CLI::Range(1, 17));
  app.callback([a]() {
    const std::vector<int> classes = ParseClasses(a->cls);
    std::size_t faces = 0, total = 0;
    for (int c : classes) {
      std::vector<CadModel> models;
      models.reserve(a->count);
      for (int i = 0; i < a->count; ++i) {
        models.push_back(dimr::data::GenerateCadModel(c, a->seed + static_cast<std::uint64_t>(i)));
        faces += models.back().mesh.faces.size();
      }
      dimr::data::WriteShapeNetTree(a->out, models, a->precision);
      total += models.size();
      std::printf("%-10s %d models -> %s/%s\n", dimr::data::CadClassNames()[c], a->count,
                  a->out.c_str(), dimr::data::CadSynsets()[c]);
    }
    std::printf("wrote %zu models (mean %.0f triangles), index %s/index.json\n", total,
                total ? static_cast<double>(faces) / total : 0.0, a->out.c_str());
  });
}

void SetupStats(CLI::App& app) {
  auto dir = std::make_shared<std::string>();
  app.add_option("--dir,--out", *dir, "ShapeNet-style tree written by `dimr cad generate`")
      ->required();
  app.callback([dir]() {
    const auto models = dimr::data::ReadShapeNetTree(*dir);
    struct Row {
      int n = 0;
      std::map<std::string, int> families;
      double faces = 0, parts = 0;
      Vec3 size_min = Vec3::Constant(1e9), size_max = Vec3::Zero();
    };
    std::map<std::string, Row> rows;
    for (const auto& m : models) {
      const std::string name =
          m.cad_class >= 0 ? dimr::data::CadClassNames()[m.cad_class] : std::string("other");
      Row& r = rows[name];
      ++r.n;
      ++r.families[m.family];
      r.faces += static_cast<double>(m.mesh.faces.size());
      r.parts += m.NumParts();
      r.size_min = r.size_min.cwiseMin(m.nominal_size);
      r.size_max = r.size_max.cwiseMax(m.nominal_size);
    }
    std::printf("%-10s %7s %9s %9s %7s  %-31s %s\n", "class", "models", "families", "mean_tris",
                "parts", "size min..max (x y z, m)", "family counts");
    for (const auto& [name, r] : rows) {
      std::string fams;
      for (const auto& [f, n] : r.families) fams += f + ":" + std::to_string(n) + " ";
      std::printf("%-10s %7d %9zu %9.0f %7.1f  %4.2f..%4.2f %4.2f..%4.2f %4.2f..%4.2f  %s\n",
                  name.c_str(), r.n, r.families.size(), r.faces / r.n, r.parts / r.n,
                  r.size_min.x(), r.size_max.x(), r.size_min.y(), r.size_max.y(), r.size_min.z(),
                  r.size_max.z(), fams.c_str());
    }
    std::printf("total: %zu models\n", models.size());
  });
}

struct RenderArgs {
  std::string out;
  std::string cls = "all";
  int per_class = 6;
  std::uint64_t seed = 0;
  int tile = 160;
  bool distractors = false;
  bool families = false;
  int cols = 0;
};

void SetupRender(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  app.add_option("--out", a->out, "PNG file")->required();
  app.add_option("--class", a->cls, "CAD class name or 'all'")->capture_default_str();
  app.add_option("--per-class", a->per_class, "models per row")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--seed", a->seed, "first seed")->capture_default_str();
  app.add_option("--tile", a->tile, "tile size in pixels")
      ->capture_default_str()
      ->check(CLI::Range(32, 1024));
  app.add_option("--cols", a->cols, "tiles per row (default: --per-class, 6 with --families)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--distractors", a->distractors, "render the distractor kinds instead");
  app.add_flag("--families", a->families,
               "one model of each family per class (first seed with that family)");
  app.callback([a]() {
    std::vector<CadModel> models;
    int cols = a->per_class;
    if (a->distractors) {
      for (int k = 0; k < dimr::data::NumDistractorKinds(); ++k) {
        for (int i = 0; i < a->per_class; ++i) {
          models.push_back(dimr::data::GenerateDistractor(k, a->seed + i));
        }
      }
    } else {
      for (int c : ParseClasses(a->cls)) {
        if (a->families) {
          const auto fams = dimr::data::CadFamilies(c);
          cols = 6;
          std::set<std::string> seen;
          std::vector<CadModel> row;
          for (std::uint64_t s = a->seed; seen.size() < fams.size() && s < a->seed + 10000; ++s) {
            CadModel m = dimr::data::GenerateCadModel(c, s);
            if (seen.insert(m.family).second) row.push_back(std::move(m));
          }
          std::sort(row.begin(), row.end(), [&](const CadModel& x, const CadModel& y) {
            return std::find(fams.begin(), fams.end(), x.family) <
                   std::find(fams.begin(), fams.end(), y.family);
          });
          for (auto& m : row) models.push_back(std::move(m));
          // Pad the row so that each class starts a new row.
          while (models.size() % cols != 0) {
            models.push_back(models.back());
            models.back().mesh.faces.clear();
            models.back().part_face_begin.clear();
            models.back().part_names.clear();
            models.back().family.clear();
          }
          continue;
        }
        for (int i = 0; i < a->per_class; ++i) {
          models.push_back(dimr::data::GenerateCadModel(c, a->seed + i));
        }
      }
    }
    if (a->cols > 0 && !a->families) cols = a->cols;
    std::vector<dimr::tools::RenderTile> tiles;
    for (const CadModel& m : models) {
      dimr::tools::RenderTile t;
      t.mesh = m.mesh;
      t.scale = m.nominal_size;
      t.label = m.family;
      t.face_colors.resize(m.mesh.faces.size());
      for (int part = 0; part < m.NumParts(); ++part) {
        const Vec3 c = dimr::tools::NameColour(m.part_names[part]);
        for (int f = m.PartBegin(part); f < m.PartEnd(part); ++f) t.face_colors[f] = c;
      }
      tiles.push_back(std::move(t));
    }
    dimr::tools::RenderSheet(tiles, cols, a->tile, a->out);
    std::printf("rendered %zu models -> %s\n", models.size(), a->out.c_str());
  });
}

const dimr::tools::Registrar kRegGenerate("cad", "generate",
                                          "Generate procedural CAD models as a ShapeNet tree",
                                          &SetupGenerate);
const dimr::tools::Registrar kRegStats("cad", "stats", "Summarise a ShapeNet-style CAD tree",
                                       &SetupStats);
const dimr::tools::Registrar kRegRender("cad", "render",
                                        "Render a contact sheet of CAD models to PNG",
                                        &SetupRender);

}  // namespace
