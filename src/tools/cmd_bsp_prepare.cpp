// `dimr bsp prepare`: BSP-CVAE training sets from the procedural CAD library.
#include <chrono>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/bsp_dataset.h"
#include "dimr/pipeline/bsp_data.h"
#include "tools/command_registry.h"

namespace dimr::tools {
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
  int per_class = 100;
  std::uint64_t seed = 1;
  std::string classes = "all";
  int resolution = 32;
};

void RunPrepare(const PrepareArgs& a) {
  nn::BspDataset data;
  data.resolution = a.resolution;
  pipeline::BspSampleOptions opt;
  opt.resolution = a.resolution;
  const auto classes = ParseClasses(a.classes);
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t done = 0;
  const std::size_t total = classes.size() * static_cast<std::size_t>(a.per_class);
  for (int c : classes) {
    for (int i = 0; i < a.per_class; ++i) {
      // Model seeds: disjoint streams per (seed, class) so train/val/test never share models.
      const std::uint64_t model_seed =
          a.seed * 1000003ull + static_cast<std::uint64_t>(c) * 7919ull * 1000003ull + i;
      const data::CadModel m = data::GenerateCadModel(c, model_seed);
      data.samples.push_back(
          pipeline::MakeBspSample(m.mesh, c, m.model_id, opt, model_seed ^ 0x9e3779b97f4a7c15ull));
      ++done;
      std::fprintf(stderr, "\rprepare: %zu/%zu shapes", done, total);
    }
  }
  std::fprintf(stderr, "\n");
  data.Save(a.out);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("wrote %zu samples (R=%d) to %s in %.1f s\n", data.samples.size(), a.resolution,
              a.out.c_str(), secs);
}

void SetupPrepare(CLI::App& app) {
  auto a = std::make_shared<PrepareArgs>();
  app.add_option("--out", a->out, "output dataset file")->required();
  app.add_option("--per-class", a->per_class, "procedural CAD models per class")
      ->check(CLI::Range(1, 100000));
  app.add_option("--seed", a->seed,
                 "seed of the model stream (use different seeds for train/val/test)");
  app.add_option("--classes", a->classes, "'all' or a comma list of class names");
  app.add_option("--resolution", a->resolution, "encoder grid resolution")
      ->check(CLI::IsMember({8, 16, 32, 64, 128}));
  app.callback([a]() { RunPrepare(*a); });
}

const Registrar kPrepare("bsp", "prepare",
                         "Build a BSP-CVAE training set from the procedural CAD library",
                         &SetupPrepare);

}  // namespace
}  // namespace dimr::tools
