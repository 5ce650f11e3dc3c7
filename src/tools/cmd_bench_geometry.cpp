// `dimr bench geometry`: the Google Benchmark cases named BM_Geometry* (sampling, boxes,
// voxelisation in bench_geometry_vox.cpp; kd-tree, mesh distance, polytopes in
// bench_geometry_query.cpp).
#include <memory>
#include <string>

#include "tools/bench_util.h"
#include "tools/command_registry.h"

namespace {

struct Args {
  std::string json;
  double min_time = 0.5;
  int repetitions = 1;
  std::string filter = "BM_Geometry";
};

void Setup(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.add_option("--json", args->json, "Also write Google Benchmark JSON to this file");
  app.add_option("--min-time", args->min_time, "Minimum seconds per benchmark case")
      ->check(CLI::Range(0.0, 600.0));
  app.add_option("--repetitions", args->repetitions, "Repetitions per case (>1 reports medians)")
      ->check(CLI::Range(1, 100));
  app.add_option("--filter", args->filter,
                 "Regular expression of the cases to run (default: all BM_Geometry cases)");
  app.callback([args]() {
    const int failed =
        dimr::tools::RunBenchmarks(args->filter, args->json, args->min_time, args->repetitions);
    if (failed != 0) throw CLI::RuntimeError(failed);
  });
}

const dimr::tools::Registrar kReg("bench", "geometry",
                                  "Geometry benchmarks: sampling, box IoU, voxelisation, kd-tree, "
                                  "mesh distance, polytopes",
                                  &Setup);

}  // namespace
