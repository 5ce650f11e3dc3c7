// `dimr info`: what this build contains.
#include <cstdio>

#include "tools/command_registry.h"

namespace {

void SetupInfo(CLI::App& app) {
  app.callback([]() {
    std::printf("dimr 0.1.0\nlayers:\n  geometry: yes\n");
#ifdef DIMR_HAVE_DATA
    std::printf("  data: yes\n");
#else
    std::printf("  data: no\n");
#endif
#ifdef DIMR_HAVE_EVAL
    std::printf("  eval: yes\n");
#else
    std::printf("  eval: no\n");
#endif
#ifdef DIMR_HAVE_NN
    std::printf("  nn: yes (LibTorch)\n");
#else
    std::printf("  nn: no (built without LibTorch)\n");
#endif
#ifdef DIMR_HAVE_PIPELINE
    std::printf("  pipeline: yes\n");
#else
    std::printf("  pipeline: no\n");
#endif
#ifdef DIMR_HAVE_BENCHMARK
    std::printf("benchmarks: yes\n");
#else
    std::printf("benchmarks: no\n");
#endif
  });
}

const dimr::tools::Registrar kReg("", "info", "Show what this build of dimr contains", &SetupInfo);

}  // namespace
