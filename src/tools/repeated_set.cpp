#include "tools/repeated_set.h"

#include <algorithm>
#include <filesystem>

#include "dimr/core/error.h"

namespace dimr::tools {

RepeatedSet ParseRepeatedSet(const std::string& spec, const std::string& what) {
  const std::size_t at = spec.rfind('@');
  if (at == std::string::npos || std::filesystem::exists(spec)) return {spec, 1};
  const std::string count = spec.substr(at + 1);
  const bool digits =
      !count.empty() && count.size() <= 3 &&
      std::all_of(count.begin(), count.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (!digits || std::stoi(count) < 1 || std::stoi(count) > 100) {
    throw InvalidArgument(what + " '" + spec +
                          "': the repeat count after '@' must be an integer in 1..100");
  }
  return {spec.substr(0, at), std::stoi(count)};
}

}  // namespace dimr::tools
