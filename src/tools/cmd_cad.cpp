// `dimr cad generate | stats | render | import`: the procedural CAD library and the imported
// real furniture from the command line.
//   dimr cad generate --class chair --count 100 --seed 0 --out data/cad
//   dimr cad import --out data/sh3d       (Sweet Home 3D catalogues -> train / test trees)
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
#include "dimr/data/real_furniture.h"
#include "dimr/data/sh3d_catalog.h"
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
  bool sh3d = false;  // real furniture from the Sweet Home 3D catalogues
  std::string sh3d_dir = dimr::data::DefaultSh3dFurnitureDir();
  std::string split = "all";
};

// Contact sheet of imported real furniture: one row per class (CAD classes, then with
// --distractors the non-CAD rules), models in id order, coloured by their texture / MTL colours.
void RenderSh3d(const RenderArgs& a) {
  dimr::data::ImportOptions opt;
  opt.watertight_res = 0;
  opt.include_distractors = a.distractors;
  const auto models =
      dimr::data::ImportSh3dCatalogs(dimr::data::ListSh3dCatalogs(a.sh3d_dir), opt, nullptr);
  std::map<std::string, std::vector<const dimr::data::ImportedModel*>> rows;
  std::vector<std::string> order;
  for (int c : ParseClasses(a.cls)) order.push_back(dimr::data::CadClassNames()[c]);
  for (const auto& im : models) {
    if (a.split != "all" && (a.split == "test") != im.held_out) continue;
    const std::string key = im.model.cad_class >= 0
                                ? std::string(dimr::data::CadClassNames()[im.model.cad_class])
                                : im.cls.label;
    if (im.model.cad_class < 0 && std::find(order.begin(), order.end(), key) == order.end())
      order.push_back(key);
    rows[key].push_back(&im);
  }
  const int cols = a.cols > 0 ? a.cols : a.per_class;
  std::vector<dimr::tools::RenderTile> tiles;
  for (const std::string& key : order) {
    auto& list = rows[key];
    if (list.empty()) continue;
    std::sort(list.begin(), list.end(),
              [](const auto* x, const auto* y) { return x->model.model_id < y->model.model_id; });
    int n = 0;
    for (const auto* im : list) {
      if (n == a.per_class) break;
      dimr::tools::RenderTile t;
      const CadModel& m = im->model;
      t.mesh = m.mesh;
      t.scale = m.nominal_size;
      std::string name = im->entry.name;
      std::replace(name.begin(), name.end(), ' ', '-');
      t.label = (im->held_out ? "test_" : "") + name;
      for (const auto& f : m.mesh.faces) {
        Vec3 c = Vec3::Zero();
        for (int k = 0; k < 3; ++k)
          for (int ch = 0; ch < 3; ++ch)
            c[ch] += std::pow(m.mesh.vertex_colors[f[k]][ch] / 255.0, 2.2) / 3;
        t.face_colors.push_back(c);
      }
      tiles.push_back(std::move(t));
      ++n;
    }
    while (n++ % cols != 0) {  // each class starts a new row
      dimr::tools::RenderTile t;
      tiles.push_back(std::move(t));
    }
  }
  dimr::tools::RenderSheet(tiles, cols, a.tile, a.out);
  std::printf("rendered %zu real models -> %s\n", tiles.size(), a.out.c_str());
}

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
  app.add_flag("--sh3d", a->sh3d,
               "real furniture imported from the Sweet Home 3D catalogues (one row per class)");
  app.add_option("--sh3d-dir", a->sh3d_dir, "folder of .sh3f catalogues")->capture_default_str();
  app.add_option("--split", a->split, "with --sh3d: all | train | test")
      ->check(CLI::IsMember({"all", "train", "test"}));
  app.callback([a]() {
    if (a->sh3d) {
      RenderSh3d(*a);
      return;
    }
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

struct ImportArgs {
  std::vector<std::string> catalogs;
  std::string dir = dimr::data::DefaultSh3dFurnitureDir();
  std::string out;
  bool no_distractors = false;
  bool solid = false;
  int watertight_res = 64;
  int close_cells = 1;
};

void SetupImport(CLI::App& app) {
  auto a = std::make_shared<ImportArgs>();
  app.add_option("--out", a->out, "output folder (gitignored, e.g. data/sh3d)")->required();
  app.add_option("--dir", a->dir, "folder of .sh3f catalogues")->capture_default_str();
  app.add_option("--catalog", a->catalogs, "catalogue file(s) instead of every .sh3f in --dir");
  app.add_flag("--no-distractors", a->no_distractors, "only the 8 CAD classes");
  app.add_flag("--solid", a->solid,
               "also write train_solid/ and test_solid/ (closed voxel meshes for BSP training)");
  app.add_option("--watertight-res", a->watertight_res,
                 "grid of the inside/outside check (0 = skip)")
      ->capture_default_str()
      ->check(CLI::Range(0, 256));
  app.add_option("--close-cells", a->close_cells, "closing radius of the hole repair (cells)")
      ->capture_default_str()
      ->check(CLI::Range(0, 8));
  app.callback([a]() {
    const std::vector<std::string> files =
        a->catalogs.empty() ? dimr::data::ListSh3dCatalogs(a->dir) : a->catalogs;
    dimr::data::ImportOptions opt;
    opt.include_distractors = !a->no_distractors;
    opt.watertight_res = a->watertight_res;
    opt.close_cells = a->close_cells;
    std::vector<std::string> errors;
    const auto models = dimr::data::ImportSh3dCatalogs(files, opt, &errors);
    for (const auto& e : errors) std::fprintf(stderr, "skipped: %s\n", e.c_str());
    dimr::data::RealFurnitureWriteOptions wopt;
    wopt.solid = a->solid;
    wopt.solid_res = a->watertight_res > 0 ? a->watertight_res : 64;
    wopt.close_cells = a->close_cells;
    dimr::data::WriteRealFurniture(a->out, models, wopt);
    struct Row {
      int train = 0, test = 0;
      double tris = 0, open = 0, closed = 0, textured = 0;
    };
    std::map<std::string, Row> rows;
    for (const auto& im : models) {
      const std::string key = im.model.cad_class >= 0
                                  ? std::string(dimr::data::CadClassNames()[im.model.cad_class])
                                  : "~" + im.cls.label;
      Row& r = rows[key];
      (im.held_out ? r.test : r.train) += 1;
      r.tris += static_cast<double>(im.model.mesh.faces.size());
      r.open += im.solid_fraction_open;
      r.closed += im.solid_fraction_closed;
      r.textured += im.stats.textures_sampled > 0;
    }
    std::printf("%-18s %6s %5s %9s %9s %11s %13s\n", "class", "train", "test", "mean_tris",
                "textured", "solid_open", "solid_closed");
    int ntrain = 0, ntest = 0;
    for (const auto& [k, r] : rows) {
      const double n = r.train + r.test;
      std::printf("%-18s %6d %5d %9.0f %8.0f%% %11.3f %13.3f\n", k.c_str(), r.train, r.test,
                  r.tris / n, 100 * r.textured / n, r.open / n, r.closed / n);
      ntrain += r.train;
      ntest += r.test;
    }
    std::printf(
        "imported %zu models (%d train, %d held-out test) from %zu catalogues, %zu "
        "skipped -> %s (catalog.json, ATTRIBUTION.md)\n",
        models.size(), ntrain, ntest, files.size(), errors.size(), a->out.c_str());
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
const dimr::tools::Registrar kRegImport(
    "cad", "import", "Import Sweet Home 3D furniture (.sh3f) into train / held-out ShapeNet trees",
    &SetupImport);

}  // namespace
