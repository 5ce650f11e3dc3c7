// The `dimr` command: one entry point for every tool of the package.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <string>

#include "tools/command_registry.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace dimr::tools {

std::vector<CommandSpec>& Commands() {
  static std::vector<CommandSpec> commands;
  return commands;
}

}  // namespace dimr::tools

namespace {

const std::map<std::string, std::string>& GroupDescriptions() {
  static const std::map<std::string, std::string> kGroups = {
      {"bench", "Benchmarks: print a table and write JSON"},
      {"train", "Train a network"},
      {"mesh", "Mesh and point-cloud utilities"},
      {"bsp", "BSP-CVAE shape autoencoder: data, evaluation, interpolation"},
      {"cad", "Procedural CAD library"},
      {"stage1", "Stage-1 point-wise network: data preparation, inspection, evaluation"},
      {"stage2", "Stage-2 proposal network: proposal caches, evaluation, GT checks"},
  };
  return kGroups;
}

// LibTorch allocates and frees tensors of megabytes on every layer call. glibc's defaults hand
// such blocks back to the kernel (mmap / trim), so every step page-faults them in again. On this
// 2-vCPU virtual machine page faults run at ~220 MB/s: touching a fresh 268 MB block 50 times
// took 59 s, 1.2 s with the heap kept; a BSP fine-tune ran > 4x slower (43 % system time), and
// the stage-1 U-Net forward 10-15 % slower (docs/benchmarks.md). Both settings are needed: fixing
// only the trim threshold also pins the mmap threshold at 128 KB (4x slower). An explicit
// GLIBC_TUNABLES or DIMR_DEFAULT_MALLOC=1 keeps glibc's behaviour.
void TuneAllocator() {
#ifdef __GLIBC__
  if (std::getenv("GLIBC_TUNABLES") != nullptr) return;
  if (const char* v = std::getenv("DIMR_DEFAULT_MALLOC"); v != nullptr && std::string(v) == "1") {
    return;
  }
  // 1 GB: BSP training allocates 268 MB tensors (batch 32 x 2048 points x 1024 planes), which
  // glibc's 32 MB dynamic maximum still maps and unmaps on every step. Older glibc refuses
  // values above 32 MB; fall back to that.
  if (mallopt(M_MMAP_THRESHOLD, 1 << 30) == 0) mallopt(M_MMAP_THRESHOLD, 32 << 20);
  // Never trim: with a 1 GB threshold glibc still shrank the heap by brk when more than that
  // was free at once (a BSP training step frees ~1.5 GB), and re-faulted it on the next step.
  mallopt(M_TRIM_THRESHOLD, -1);
#endif
}

}  // namespace

int main(int argc, char** argv) {
  TuneAllocator();
  CLI::App app{"dimr: complete, labelled instance meshes from indoor point clouds (DIMR)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("dimr 0.1.0"));

  auto specs = dimr::tools::Commands();
  std::sort(specs.begin(), specs.end(), [](const auto& a, const auto& b) {
    return a.parent != b.parent ? a.parent < b.parent : a.name < b.name;
  });
  std::map<std::string, CLI::App*> groups;
  for (const auto& spec : specs) {
    CLI::App* parent = &app;
    if (!spec.parent.empty()) {
      auto it = groups.find(spec.parent);
      if (it == groups.end()) {
        const auto desc = GroupDescriptions().count(spec.parent)
                              ? GroupDescriptions().at(spec.parent)
                              : std::string();
        CLI::App* group = app.add_subcommand(spec.parent, desc);
        group->require_subcommand(1);
        it = groups.emplace(spec.parent, group).first;
      }
      parent = it->second;
    }
    CLI::App* sub = parent->add_subcommand(spec.name, spec.description);
    spec.setup(*sub);
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dimr: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
