// Runs the `dimr` command built with the tests (DIMR_CLI, defined by dimr_add_layer_tests) and
// captures stdout + stderr. Shared by the CLI-level tests of every layer.
#pragma once

#include <cstdio>
#include <string>
#include <utility>

namespace dimr::testing {

#ifdef DIMR_CLI
// (exit status as returned by pclose, 0 on success; combined output).
inline std::pair<int, std::string> RunCli(const std::string& args) {
  std::string out;
  FILE* p = ::popen((std::string(DIMR_CLI) + " " + args + " 2>&1").c_str(), "r");
  if (p == nullptr) return {-1, out};
  char buf[4096];
  while (std::fgets(buf, sizeof(buf), p)) out += buf;
  return {::pclose(p), out};
}
#endif

}  // namespace dimr::testing
