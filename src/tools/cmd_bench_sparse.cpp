// `dimr bench sparse`: sparse convolution (fused vs torch-ops) and stage-1 U-Net timings on
// a procedural 2 cm scanned room. Torch-free: calls dimr::nn::RunSparseBench.
#ifdef DIMR_HAVE_NN
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "dimr/nn/sparse_bench.h"
#include "tools/command_registry.h"

namespace {

struct Args {
  dimr::nn::SparseBenchOptions opt;
  std::string json;
  bool no_torch_ops = false;
  bool no_unet = false;
  bool no_sgemm = false;
};

void PrintReport(const dimr::nn::SparseBenchReport& r) {
  std::printf("CPU: %s; ISA: %s; default kernel path: %s\n", r.cpu_model.c_str(), r.cpu_isa.c_str(),
              r.default_kernels.c_str());
  if (r.sgemm_gflops > 0) {
    std::printf("sgemm 2048^3, one thread: %.1f GFLOP/s (%.1f over CPU time)\n", r.sgemm_gflops,
                r.sgemm_cpu_gflops);
  }
  std::printf("room: %lld points -> %lld voxels at 2 cm; SubM3 rulebook %.1f ms\n",
              static_cast<long long>(r.room_points), static_cast<long long>(r.room_voxels),
              r.rulebook_ms);
  std::printf("threads (at::get_num_threads): %d\n", r.threads);
  std::printf("%-54s %-9s %-7s %8s %10s %10s %10s %8s %10s\n", "layer", "backend", "kernels",
              "pairs", "fwd ms", "bwd ms", "total ms", "GFLOP/s", "CPU ms");
  for (const auto& row : r.rows) {
    std::printf("%-54s %-9s %-7s %8lld %10.1f %10.1f %10.1f %8.1f %10.1f\n", row.layer.c_str(),
                row.backend.c_str(), row.kernels.c_str(), static_cast<long long>(row.pairs),
                row.forward_ms, row.backward_ms, row.total_ms, row.gflops, row.cpu_ms);
  }
  // Fused / torch-ops ratios of the conv rows, and fused against one-thread sgemm.
  for (const auto& a : r.rows) {
    if (a.backend != "fused") continue;
    for (const auto& b : r.rows) {
      if (b.backend == "torch-ops" && b.layer == a.layer && a.total_ms > 0 && a.cpu_ms > 0) {
        std::printf("%s, %s kernels: fused %.1fx torch-ops wall (%.1fx CPU time)", a.layer.c_str(),
                    a.kernels.c_str(), b.total_ms / a.total_ms, b.cpu_ms / a.cpu_ms);
        if (r.sgemm_gflops > 0 && r.sgemm_cpu_gflops > 0 && a.cpu_ms > 0) {
          // Same FLOPs over CPU time: gflops * total_ms / cpu_ms.
          std::printf(", %.0f%% of one-thread sgemm (%.0f%% in CPU time)",
                      100.0 * a.gflops / r.sgemm_gflops,
                      100.0 * a.gflops * a.total_ms / a.cpu_ms / r.sgemm_cpu_gflops);
        }
        std::printf("\n");
      }
    }
  }
  std::printf("peak RSS after U-Net forward+backward: %.0f MB; at the end: %.0f MB\n",
              r.peak_rss_mb, r.final_peak_rss_mb);
}

void WriteJson(const dimr::nn::SparseBenchReport& r, const std::string& path) {
  nlohmann::json j;
  j["cpu_model"] = r.cpu_model;
  j["cpu_isa"] = r.cpu_isa;
  j["default_kernels"] = r.default_kernels;
  j["sgemm_gflops_one_thread"] = r.sgemm_gflops;
  j["sgemm_cpu_gflops_one_thread"] = r.sgemm_cpu_gflops;
  j["room_points"] = r.room_points;
  j["room_voxels"] = r.room_voxels;
  j["rulebook_ms"] = r.rulebook_ms;
  j["threads"] = r.threads;
  j["parallel_info"] = r.parallel_info;
  j["peak_rss_mb_unet_train"] = r.peak_rss_mb;
  j["peak_rss_mb_end"] = r.final_peak_rss_mb;
  j["rows"] = nlohmann::json::array();
  for (const auto& row : r.rows) {
    j["rows"].push_back({{"layer", row.layer},
                         {"backend", row.backend},
                         {"kernels", row.kernels},
                         {"width", row.width},
                         {"sites", row.sites},
                         {"pairs", row.pairs},
                         {"forward_ms", row.forward_ms},
                         {"backward_ms", row.backward_ms},
                         {"total_ms", row.total_ms},
                         {"gflops", row.gflops},
                         {"cpu_ms", row.cpu_ms}});
  }
  std::ofstream f(path);
  if (!f) throw std::runtime_error("bench sparse: cannot write " + path);
  f << j.dump(2) << "\n";
}

void Setup(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.add_option("--sites", args->opt.sites, "Target active voxels of the room")
      ->check(CLI::Range(int64_t{1000}, int64_t{5000000}));
  app.add_option("--widths", args->opt.widths, "SubM3 C->C widths to time")->delimiter(',');
  app.add_option("--threads", args->opt.threads,
                 "Intra-op threads (at::set_num_threads; 0 = default). BLAS threads follow "
                 "OMP_NUM_THREADS / OPENBLAS_NUM_THREADS")
      ->check(CLI::Range(0, 256));
  app.add_option("--repeats", args->opt.repeats, "Timed runs per row (median)")
      ->check(CLI::Range(1, 100));
  app.add_option("--seed", args->opt.seed, "Room generator seed");
  app.add_option("--kernels", args->opt.kernels,
                 "Kernel paths of the fused rows: auto (the path in force: DIMR_SPARSE_KERNELS or "
                 "the best this CPU has), avx512, avx2, gemm, or all (every supported path)")
      ->delimiter(',');
  app.add_flag("--no-sgemm", args->no_sgemm, "Skip the one-thread sgemm reference");
  app.add_flag("--no-torch-ops", args->no_torch_ops, "Skip the torch-ops rows");
  app.add_flag("--no-unet", args->no_unet, "Skip the stage-1 U-Net rows");
  app.add_flag("--unet-torch-ops", args->opt.unet_torch_ops,
               "Also time the U-Net forward on the torch-ops path (slow)");
  app.add_option("--json", args->json, "Also write the results as JSON to this file");
  app.callback([args]() {
    args->opt.torch_ops = !args->no_torch_ops;
    args->opt.unet = !args->no_unet;
    args->opt.sgemm = !args->no_sgemm;
    const auto report = dimr::nn::RunSparseBench(args->opt);
    PrintReport(report);
    if (!args->json.empty()) WriteJson(report, args->json);
  });
}

const dimr::tools::Registrar kReg(
    "bench", "sparse",
    "Sparse conv (fused vs torch-ops) and stage-1 U-Net timings on a 2 cm procedural room", &Setup);

}  // namespace
#endif  // DIMR_HAVE_NN
