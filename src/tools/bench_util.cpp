#include "tools/bench_util.h"

#include <cstdio>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"

#ifdef DIMR_HAVE_BENCHMARK
#include <benchmark/benchmark.h>
#endif

namespace dimr::tools {

int RunBenchmarks(const std::string& filter, const std::string& json_out, double min_time,
                  int repetitions) {
#ifdef DIMR_HAVE_BENCHMARK
  std::vector<std::string> args = {"dimr-bench", "--benchmark_filter=" + filter,
                                   "--benchmark_min_time=" + std::to_string(min_time),
                                   "--benchmark_counters_tabular=true"};
  if (repetitions > 1) {
    args.push_back("--benchmark_repetitions=" + std::to_string(repetitions));
    args.push_back("--benchmark_report_aggregates_only=true");
  }
  if (!json_out.empty()) {
    args.push_back("--benchmark_out=" + json_out);
    args.push_back("--benchmark_out_format=json");
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  int argc = static_cast<int>(argv.size());
  benchmark::Initialize(&argc, argv.data());
  const std::size_t ran = benchmark::RunSpecifiedBenchmarks();
  if (ran == 0) {
    throw Error("no benchmark matched '" + filter + "'");
  }
  if (!json_out.empty()) std::printf("JSON written to %s\n", json_out.c_str());
  return 0;
#else
  (void)filter;
  (void)json_out;
  (void)min_time;
  (void)repetitions;
  throw Error("this dimr was built without Google Benchmark (install libbenchmark-dev)");
#endif
}

}  // namespace dimr::tools
