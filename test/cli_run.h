// Runs the `dimr` command built with the tests (DIMR_CLI, defined by dimr_add_layer_tests) and
// captures stdout + stderr. Shared by the CLI-level tests of every layer.
#pragma once

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>

namespace dimr::testing {

// An empty scratch folder <tmp>/<name>_<pid> (removed first if a crashed run left it).
inline std::filesystem::path FreshTempDir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// The whole file as bytes ("" if it cannot be read).
inline std::string ReadFileText(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

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
