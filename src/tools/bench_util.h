// Runs the Google Benchmark cases registered in the `dimr` binary (BENCHMARK macros in
// src/tools/bench_*.cpp) whose names match `filter`; prints the console table and writes
// JSON to `json_out` (if not empty).
#pragma once

#include <string>

namespace dimr::tools {

// Returns the number of failed/errored benchmarks (0 on success). `min_time` in seconds
// per case (Google Benchmark's --benchmark_min_time); `repetitions` > 1 reports medians.
int RunBenchmarks(const std::string& filter, const std::string& json_out, double min_time = 0.5,
                  int repetitions = 1);

}  // namespace dimr::tools
