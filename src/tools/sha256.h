// SHA-256 (FIPS 180-4) of a file, for model cards.
#pragma once

#include <string>

namespace dimr::tools {

// Lower-case hex digest; throws dimr::Error if the file cannot be read.
std::string Sha256File(const std::string& path);
std::string Sha256(const std::string& bytes);

}  // namespace dimr::tools
