// `dimr bsp prepare`: BSP-CVAE training sets from the procedural CAD library or a
// ShapeNet-format tree; `dimr bsp render|eval-cad` on procedural models.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/core/hash.h"
#include "dimr/core/timing.h"
#include "dimr/data/cad_library.h"
#include "dimr/data/labels.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/eval/mesh_metrics.h"
#include "dimr/eval/parallel.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/bsp_dataset.h"
#include "dimr/pipeline/bsp_data.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/bsp_mesher.h"
#include "dimr/pipeline/shape_pool.h"
#include "tools/bsp_options.h"
#include "tools/command_registry.h"
#include "tools/render.h"

namespace dimr::tools {

std::string ShapeNetSplitOf(const std::string& model_id) {
  const std::uint64_t bucket = Fnv1a(model_id) % 100;
  return bucket < 80 ? "train" : (bucket < 90 ? "val" : "test");
}

nn::BspDataset ShapeNetBspDataset(const std::string& dir, const ShapeNetSelection& sel) {
  namespace fs = std::filesystem;
  if (sel.split != "all" && sel.split != "train" && sel.split != "val" && sel.split != "test") {
    throw InvalidArgument("ShapeNet split '" + sel.split + "': use all, train, val or test");
  }
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw ParseError(dir, "no such ShapeNet tree (directory)");
  struct Item {
    std::string path, synset, model_id;
    int cad_class;
  };
  std::vector<Item> items;
  std::vector<int> taken(data::kNumCadClasses, 0);
  for (int c : sel.classes) {
    const std::string synset = data::CadSynsets()[c];
    const fs::path synset_dir = fs::path(dir) / synset;
    if (!fs::is_directory(synset_dir, ec)) continue;
    std::vector<std::string> ids;
    for (const auto& entry : fs::directory_iterator(synset_dir)) {
      if (entry.is_directory()) ids.push_back(entry.path().filename().string());
    }
    std::sort(ids.begin(), ids.end());
    for (const std::string& id : ids) {
      const fs::path obj = fs::path(dir) / data::ShapeNetRelativePath(synset, id);
      if (!fs::is_regular_file(obj, ec)) continue;  // e.g. a model without model_normalized.obj
      if (sel.split != "all" && ShapeNetSplitOf(id) != sel.split) continue;
      if (sel.per_class > 0 && taken[c] >= sel.per_class) break;
      ++taken[c];
      items.push_back({obj.string(), synset, id, c});
    }
  }
  if (items.empty()) {
    throw InvalidArgument("ShapeNet tree '" + dir + "': no model_normalized.obj of the selected " +
                          "classes in split '" + sel.split + "'");
  }
  nn::BspDataset data;
  data.resolution = sel.resolution;
  const std::size_t copies = sel.mirror ? 2 : 1;
  data.samples.resize(items.size() * copies);
  pipeline::BspSampleOptions opt;
  opt.resolution = sel.resolution;
  eval::Progress progress("bsp prepare (shapenet)", items.size(), true);
  eval::ParallelFor(
      items.size(), sel.jobs,
      [&](std::size_t k) {
        const Item& it = items[k];
        const data::CadModel m = data::ReadShapeNetModel(it.path, it.synset);
        try {
          data.samples[k * copies] = pipeline::MakeBspSample(
              m.mesh, it.cad_class, it.model_id, opt, Fnv1a(it.model_id) ^ 0x9e3779b97f4a7c15ull);
          if (sel.mirror) {
            const std::string id = it.model_id + "~mirror";
            data.samples[k * copies + 1] =
                pipeline::MakeBspSample(pipeline::MirrorLeftRight(m.mesh), it.cad_class, id, opt,
                                        Fnv1a(id) ^ 0x9e3779b97f4a7c15ull);
          }
        } catch (const std::exception& e) {
          throw ParseError(it.path, e.what());
        }
      },
      &progress);
  progress.Finish();
  return data;
}

namespace {

std::vector<int> ParseClasses(const std::string& text) {
  std::vector<int> out;
  if (text == "all") {
    for (int c = 0; c < 8; ++c) out.push_back(c);
    return out;
  }
  std::istringstream in(text);
  std::string name;
  while (std::getline(in, name, ',')) {
    int found = -1;
    for (int c = 0; c < 8; ++c) {
      if (name == data::CadClassNames()[c]) found = c;
    }
    if (found < 0) throw InvalidArgument("unknown class '" + name + "'");
    out.push_back(found);
  }
  return out;
}

// ---------------------------------------------------------------- prepare
struct PrepareArgs {
  std::string out;
  std::string shapenet;  // a ShapeNet-format tree instead of the procedural library
  std::string split = "all";
  int per_class = 0;  // 0: 100 procedural models per class, every model of a tree
  std::uint64_t seed = 1;
  std::string classes = "all";
  int resolution = 32;
  int jobs = 1;
  bool mirror = false;
};

// Model seeds: disjoint streams per (seed, class) so train/val/test never share models.
std::uint64_t ModelSeed(std::uint64_t seed, int cad_class, int i) {
  return seed * 1000003ull + static_cast<std::uint64_t>(cad_class) * 7919ull * 1000003ull +
         static_cast<std::uint64_t>(i);
}

void RunPrepareShapeNet(const PrepareArgs& a) {
  const Stopwatch elapsed;
  ShapeNetSelection sel;
  sel.split = a.split;
  sel.classes = ParseClasses(a.classes);
  sel.per_class = a.per_class;
  sel.resolution = a.resolution;
  sel.jobs = a.jobs;
  sel.mirror = a.mirror;
  const nn::BspDataset data = ShapeNetBspDataset(a.shapenet, sel);
  data.Save(a.out);
  std::vector<int> count(data::kNumCadClasses, 0);
  for (const auto& s : data.samples) ++count[s.cad_class];
  std::string counts;
  for (int c = 0; c < data::kNumCadClasses; ++c) {
    if (count[c] == 0) continue;
    counts += (counts.empty() ? "" : ", ") + std::string(data::CadClassNames()[c]) + " " +
              std::to_string(count[c]);
  }
  const double secs = elapsed.ElapsedSeconds();
  std::printf("wrote %zu samples (R=%d, split %s: %s) from %s to %s in %.1f s\n",
              data.samples.size(), a.resolution, a.split.c_str(), counts.c_str(),
              a.shapenet.c_str(), a.out.c_str(), secs);
}

void RunPrepare(const PrepareArgs& a) {
  if (!a.shapenet.empty()) return RunPrepareShapeNet(a);
  if (a.split != "all") throw InvalidArgument("--split applies to --shapenet trees only");
  if (a.mirror) throw InvalidArgument("--mirror applies to --shapenet trees only");
  const int per_class = a.per_class > 0 ? a.per_class : 100;
  nn::BspDataset data;
  data.resolution = a.resolution;
  pipeline::BspSampleOptions opt;
  opt.resolution = a.resolution;
  const auto classes = ParseClasses(a.classes);
  const Stopwatch elapsed;
  const std::size_t total = classes.size() * static_cast<std::size_t>(per_class);
  // Each shape depends only on its (seed, class, index), so the output is the same for any
  // number of jobs: every item writes its own slot.
  data.samples.resize(total);
  eval::Progress progress("bsp prepare", total, true);
  eval::ParallelFor(
      total, a.jobs,
      [&](std::size_t k) {
        const int c = classes[k / static_cast<std::size_t>(per_class)];
        const int i = static_cast<int>(k % static_cast<std::size_t>(per_class));
        try {
          const std::uint64_t model_seed = ModelSeed(a.seed, c, i);
          const data::CadModel m = data::GenerateCadModel(c, model_seed);
          data.samples[k] = pipeline::MakeBspSample(m.mesh, c, m.model_id, opt,
                                                    model_seed ^ 0x9e3779b97f4a7c15ull);
        } catch (const std::exception& e) {
          throw InvalidArgument("bsp prepare: shape " + std::to_string(i) + " of class " +
                                data::CadClassNames()[c] + ": " + e.what());
        }
      },
      &progress);
  progress.Finish();
  data.Save(a.out);
  const double secs = elapsed.ElapsedSeconds();
  std::printf("wrote %zu samples (R=%d) to %s in %.1f s\n", data.samples.size(), a.resolution,
              a.out.c_str(), secs);
}

void SetupPrepare(CLI::App& app) {
  auto a = std::make_shared<PrepareArgs>();
  app.add_option("--out", a->out, "output dataset file")->required();
  app.add_option("--shapenet", a->shapenet,
                 "read the CAD models from this ShapeNet-format tree (<synset>/<id>/models/"
                 "model_normalized.obj: `dimr cad generate` or ShapeNetCore v2) instead of "
                 "generating them");
  app.add_option("--split", a->split,
                 "with --shapenet: all | train | val | test (80/10/10 by a hash of the model id)")
      ->check(CLI::IsMember({"all", "train", "val", "test"}));
  app.add_option("--per-class", a->per_class,
                 "procedural CAD models per class (default 100); with --shapenet the most per "
                 "class (balancing; default all)")
      ->check(CLI::Range(0, 100000));
  app.add_option("--seed", a->seed,
                 "seed of the model stream (use different seeds for train/val/test)");
  app.add_option("--classes", a->classes, "'all' or a comma list of class names");
  app.add_option("--resolution", a->resolution, "encoder grid resolution")
      ->check(CLI::IsMember({8, 16, 32, 64, 128}));
  app.add_option("--jobs", a->jobs,
                 "worker threads (0 = all cores); the output does not depend on it")
      ->check(CLI::Range(0, 1024));
  app.add_flag("--mirror", a->mirror,
               "with --shapenet: also a left-right mirrored copy of every model (id "
               "'<id>~mirror'; augmentation for small real sets)");
  app.callback([a]() { RunPrepare(*a); });
}

// ---------------------------------------------------------------- render
struct RenderArgs {
  BspDilation dilation;
  std::string model, out, interp_out;
  int per_class = 3;
  std::uint64_t seed = 3;
  int tile = 150;
  std::string interp_class = "chair";
  int steps = 6;
};

// Decoded mesh of a CAD model through the autoencoder, with its grid IoU (percent).
tools::RenderTile Reconstruct(const pipeline::BspDecoder& decoder, const Eigen::VectorXf& mu, int c,
                              const geometry::Vec3& scale, const nn::BspSample* sample) {
  const Eigen::MatrixXf planes = decoder.Planes(mu, c);
  const pipeline::BspMeshResult r = decoder.MeshFromPlanes(planes);
  tools::RenderTile t;
  t.mesh = r.mesh;
  t.scale = scale;
  for (int k : r.face_convex)
    t.face_colors.push_back(tools::NameColour("convex" + std::to_string(k)));
  if (sample) {
    const auto occ =
        decoder.OccupancyFromPlanes(planes, pipeline::BspGridCenters(decoder.resolution()));
    const double iou = pipeline::OccupancyIoU(occ, sample->iou_grid);
    t.label = "bsp iou " + std::to_string(static_cast<int>(100 * iou));
  }
  return t;
}

void RunRender(const RenderArgs& a) {
  const pipeline::BspDecoder decoder =
      pipeline::BspDecoder::Load(a.model, {a.dilation.plane, a.dilation.distance});
  const int L = decoder.latent_dim();
  pipeline::BspSampleOptions opt;
  opt.resolution = decoder.resolution();
  auto original = [&](int c, int i, nn::BspSample* sample) {
    const std::uint64_t seed = ModelSeed(a.seed, c, i);
    const data::CadModel m = data::GenerateCadModel(c, seed);
    *sample = pipeline::MakeBspSample(m.mesh, c, m.model_id, opt, seed ^ 0x9e3779b97f4a7c15ull);
    tools::RenderTile t;
    t.mesh = pipeline::NormalizeForBsp(m.mesh, opt.resolution);
    t.scale = m.nominal_size;
    t.color = tools::NameColour(data::CadClassNames()[c]);
    t.label = data::CadClassNames()[c];
    return t;
  };
  std::vector<tools::RenderTile> tiles;
  for (int c = 0; c < decoder.num_classes() && c < data::kNumCadClasses; ++c) {
    for (int i = 0; i < a.per_class; ++i) {
      nn::BspSample sample;
      tools::RenderTile orig = original(c, i, &sample);
      const Eigen::VectorXf mu = decoder.Encode(sample.grid, c).head(L);
      tiles.push_back(Reconstruct(decoder, mu, c, orig.scale, &sample));
      tiles.insert(tiles.end() - 1, std::move(orig));
    }
  }
  tools::RenderSheet(tiles, 2 * a.per_class, a.tile, a.out);
  std::printf("rendered %zu originals and reconstructions -> %s\n", tiles.size() / 2,
              a.out.c_str());
  if (a.interp_out.empty()) return;
  const int c = data::CadClassFromName(a.interp_class);
  if (c < 0) throw InvalidArgument("--interp-class: unknown class '" + a.interp_class + "'");
  nn::BspSample sa, sb;
  tools::RenderTile ta = original(c, 0, &sa), tb = original(c, 1, &sb);
  const Eigen::VectorXf za = decoder.Encode(sa.grid, c).head(L);
  const Eigen::VectorXf zb = decoder.Encode(sb.grid, c).head(L);
  std::vector<tools::RenderTile> strip;
  strip.push_back(ta);
  for (int s = 0; s < a.steps; ++s) {
    const double t = a.steps == 1 ? 0.0 : static_cast<double>(s) / (a.steps - 1);
    const geometry::Vec3 scale = (1 - t) * ta.scale + t * tb.scale;
    tools::RenderTile tile =
        Reconstruct(decoder, pipeline::InterpolateCodes(za, zb, t), c, scale, nullptr);
    tile.label = "t " + std::to_string(static_cast<int>(std::lround(100 * t)));
    strip.push_back(std::move(tile));
  }
  strip.push_back(tb);
  tools::RenderSheet(strip, static_cast<int>(strip.size()), a.tile, a.interp_out);
  std::printf("rendered the interpolation strip -> %s\n", a.interp_out.c_str());
}

void SetupRender(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  app.add_option("--model", a->model, "BSP-CVAE weights")->required();
  app.add_option("--out", a->out, "PNG of originals next to reconstructions")->required();
  app.add_option("--interp-out", a->interp_out, "PNG of a latent interpolation strip");
  app.add_option("--per-class", a->per_class)->check(CLI::Range(1, 20));
  app.add_option("--seed", a->seed, "model stream (as `bsp prepare --seed`; 3 = the test split)");
  app.add_option("--tile", a->tile, "pixels per tile")->check(CLI::Range(32, 1024));
  app.add_option("--interp-class", a->interp_class);
  app.add_option("--steps", a->steps)->check(CLI::Range(1, 20));
  tools::AddBspDilationOption(app, &a->dilation);
  app.callback([a]() { RunRender(*a); });
}

const Registrar kRender("bsp", "render",
                        "Pictures: CAD originals next to their BSP reconstructions, interpolation",
                        &SetupRender);

// ---------------------------------------------------------------- eval-cad
struct EvalCadArgs {
  BspDilation dilation;
  std::string model;
  int per_class = 25;
  std::uint64_t seed = 3;
};

// IoU on the 32^3 grid and Chamfer distance (reference definition, 4096 seeded samples per
// mesh, in units of the normalised cube [-1, 1]^3) between held-out CAD models and their
// decoded BSP meshes.
void RunEvalCad(const EvalCadArgs& a) {
  const pipeline::BspDecoder decoder =
      pipeline::BspDecoder::Load(a.model, {a.dilation.plane, a.dilation.distance});
  pipeline::BspSampleOptions opt;
  opt.resolution = decoder.resolution();
  const int R = opt.resolution;
  const int L = decoder.latent_dim();
  const Eigen::MatrixX3f centers = pipeline::BspGridCenters(R);
  std::printf("dilation %.3g, distance dilation %.3g\n\n", decoder.mesh_options().dilation,
              decoder.mesh_options().distance_dilation);
  std::printf(
      "| class | shapes | IoU@32^3 | Chamfer (x 1e-2) | empty meshes |\n|---|---|---|---|---|\n");
  double all_iou = 0, all_cd = 0;
  int all_n = 0, all_cd_n = 0;
  for (int c = 0; c < data::kNumCadClasses && c < decoder.num_classes(); ++c) {
    double iou_sum = 0, cd_sum = 0;
    int n = 0, cd_n = 0, empty = 0;
    for (int i = 0; i < a.per_class; ++i) {
      const std::uint64_t seed = ModelSeed(a.seed, c, i);
      const data::CadModel m = data::GenerateCadModel(c, seed);
      const nn::BspSample sample =
          pipeline::MakeBspSample(m.mesh, c, m.model_id, opt, seed ^ 0x9e3779b97f4a7c15ull);
      const Eigen::VectorXf mu = decoder.Encode(sample.grid, c).head(L);
      const Eigen::MatrixXf planes = decoder.Planes(mu, c);
      const auto occ = decoder.OccupancyFromPlanes(planes, centers);
      iou_sum += pipeline::OccupancyIoU(occ, sample.iou_grid);
      ++n;
      const geometry::TriangleMesh decoded = decoder.MeshFromPlanes(planes).mesh;
      if (decoded.faces.empty()) {
        ++empty;
        continue;
      }
      const geometry::TriangleMesh original = pipeline::NormalizeForBsp(m.mesh, R);
      cd_sum += eval::ChamferDistance(eval::ChamferSamples(original, seed),
                                      eval::ChamferSamples(decoded, seed + 1));
      ++cd_n;
    }
    std::printf("| %s | %d | %.4f | %.2f | %d |\n", data::CadClassNames()[c], n, iou_sum / n,
                cd_n ? 100.0 * cd_sum / cd_n : 0.0, empty);
    all_iou += iou_sum;
    all_cd += cd_sum;
    all_n += n;
    all_cd_n += cd_n;
  }
  std::printf("| **all** | %d | **%.4f** | **%.2f** | |\n", all_n, all_iou / std::max(1, all_n),
              all_cd_n ? 100.0 * all_cd / all_cd_n : 0.0);
}

void SetupEvalCad(CLI::App& app) {
  auto a = std::make_shared<EvalCadArgs>();
  app.add_option("--model", a->model, "BSP-CVAE weights")->required();
  app.add_option("--per-class", a->per_class)->check(CLI::Range(1, 10000));
  app.add_option("--seed", a->seed, "model stream (as `bsp prepare --seed`; 3 = the test split)");
  tools::AddBspDilationOption(app, &a->dilation);
  app.callback([a]() { RunEvalCad(*a); });
}

const Registrar kEvalCad("bsp", "eval-cad",
                         "IoU and Chamfer distance of decoded vs. original procedural CAD models",
                         &SetupEvalCad);
const Registrar kPrepare("bsp", "prepare",
                         "Build a BSP-CVAE training set from the procedural CAD library",
                         &SetupPrepare);

}  // namespace
}  // namespace dimr::tools
