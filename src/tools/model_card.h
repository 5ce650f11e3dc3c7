// Values of a model card (`model.yaml` beside the weights) that the commands read back, e.g.
// the inference settings a card recommends. Plain `key: value` lines at the top level; the
// value ends at a `#` comment and loses surrounding blanks and double quotes.
#pragma once

#include <optional>
#include <string>

namespace dimr::tools {

// Path of the card of `model_path`: model.yaml in the same folder.
std::string ModelCardPath(const std::string& model_path);

// The value of the first top-level line `key: value` of the card of `model_path`; nullopt if
// the card or the key is missing.
std::optional<std::string> ReadModelCardValue(const std::string& model_path,
                                              const std::string& key);

}  // namespace dimr::tools
