// Self-registering subcommands of the `dimr` tool. Each src/tools/cmd_*.cpp defines
//   static const dimr::tools::Registrar kReg("", "synth", &SetupSynth);       // dimr synth
//   static const dimr::tools::Registrar kReg("bench", "sparse", &SetupBench);  // dimr bench sparse
// where Setup(CLI::App& sub) adds options and a callback to the created subcommand.
#pragma once

#include <CLI/CLI.hpp>
#include <algorithm>
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

// The command line that ran `app` ("dimr train bsp --train x ..."), for model cards.
inline std::string CommandLine(const CLI::App& app) {
  std::string out = "dimr";
  std::vector<const CLI::App*> chain;
  for (const CLI::App* a = &app; a && a->get_parent(); a = a->get_parent()) chain.push_back(a);
  std::reverse(chain.begin(), chain.end());
  for (const CLI::App* a : chain) out += " " + a->get_name();
  for (const CLI::Option* o : app.get_options()) {
    if (o->count() == 0 || o->get_name() == "--help") continue;
    if (o->get_expected_max() == 0) {  // a flag: no separate value ("--flag", or "--flag=false")
      const std::string v = o->results().empty() ? "true" : o->results().back();
      out += " " + o->get_name() + (v == "true" || v == "1" ? "" : "=" + v);
      continue;
    }
    out += " " + o->get_name();
    for (const auto& r : o->results()) {
      // Quote values a shell would split or expand, so the line can be pasted back.
      if (r.empty() || r.find_first_of(" \t'\"$`\\*?;&|<>()") != std::string::npos) {
        std::string q = "'";
        for (char c : r) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
        out += " " + q + "'";
      } else {
        out += " " + r;
      }
    }
  }
  return out;
}

struct Registrar {
  Registrar(std::string parent, std::string name, std::string description,
            std::function<void(CLI::App&)> setup) {
    Commands().push_back(
        CommandSpec{std::move(parent), std::move(name), std::move(description), std::move(setup)});
  }
};

}  // namespace dimr::tools
