// The `dimr` command: one entry point for every tool of the package.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <exception>
#include <map>
#include <string>

#include "dimr/core/allocator.h"
#include "tools/command_registry.h"

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

}  // namespace

int main(int argc, char** argv) {
  dimr::TuneAllocatorForTensors();  // before LibTorch's first tensor (dimr/core/allocator.h)
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
