// The `PATH@N` form of repeatable dataset options (`dimr train stage1 --train`, `stage1 eval
// --scans`, `dimr train bsp --train`): a set included N times, to oversample a small set among
// a large one.
#pragma once

#include <string>

namespace dimr::tools {

struct RepeatedSet {
  std::string path;
  int repeat = 1;
};

// "PATH" -> {PATH, 1}; "PATH@N" -> {PATH, N}, N an integer in 1..100. A spec that names an
// existing file or folder is taken as a path even if it contains '@'. Throws
// dimr::InvalidArgument "<what> '<spec>': the repeat count after '@' must be an integer in
// 1..100" for a bad count.
RepeatedSet ParseRepeatedSet(const std::string& spec, const std::string& what);

}  // namespace dimr::tools
