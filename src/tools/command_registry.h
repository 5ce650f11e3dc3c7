// Self-registering subcommands of the `dimr` tool. Each src/tools/cmd_*.cpp defines
//   static const dimr::tools::Registrar kReg("", "synth", &SetupSynth);       // dimr synth
//   static const dimr::tools::Registrar kReg("bench", "sparse", &SetupBench);  // dimr bench sparse
// where Setup(CLI::App& sub) adds options and a callback to the created subcommand.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace dimr::tools {

struct CommandSpec {
  std::string parent;  // "" for a top-level command, else a group such as "bench" or "train"
  std::string name;
  std::string description;
  std::function<void(CLI::App&)> setup;
};

std::vector<CommandSpec>& Commands();

struct Registrar {
  Registrar(std::string parent, std::string name, std::string description,
            std::function<void(CLI::App&)> setup) {
    Commands().push_back(
        CommandSpec{std::move(parent), std::move(name), std::move(description), std::move(setup)});
  }
};

}  // namespace dimr::tools
