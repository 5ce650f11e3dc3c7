#include "tools/model_card.h"

#include <filesystem>
#include <fstream>

namespace dimr::tools {

std::string ModelCardPath(const std::string& model_path) {
  return (std::filesystem::path(model_path).parent_path() / "model.yaml").string();
}

std::optional<std::string> ReadModelCardValue(const std::string& model_path,
                                              const std::string& key) {
  std::ifstream in(ModelCardPath(model_path));
  if (!in) return std::nullopt;
  const std::string prefix = key + ":";
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, prefix.size(), prefix) != 0) continue;
    std::string value = line.substr(prefix.size());
    const std::size_t quote = value.find('"');
    if (quote != std::string::npos && value.find_first_not_of(" \t") == quote) {
      const std::size_t end = value.find('"', quote + 1);
      return value.substr(quote + 1,
                          end == std::string::npos ? std::string::npos : end - quote - 1);
    }
    value = value.substr(0, value.find('#'));
    const std::size_t a = value.find_first_not_of(" \t\r");
    if (a == std::string::npos) return std::string();
    const std::size_t b = value.find_last_not_of(" \t\r");
    return value.substr(a, b - a + 1);
  }
  return std::nullopt;
}

}  // namespace dimr::tools
