// Model-card look-ups of the commands, on top of pipeline::ModelCard (the card read with
// yaml-cpp; dimr/pipeline/model_card.h). Kept for callers that ask for one value as text.
#pragma once

#include <optional>
#include <string>

namespace dimr::tools {

// Path of the card of `model_path`: model.yaml in the same folder.
std::string ModelCardPath(const std::string& model_path);

// The value (as written, quotes removed) of `key` (nested keys dotted: "weights.sha256") in
// the card of `model_path`; nullopt if the card or the key is missing. Throws
// dimr::ParseError naming the card for malformed YAML or a key whose value is a list or a
// mapping.
std::optional<std::string> ReadModelCardValue(const std::string& model_path,
                                              const std::string& key);

}  // namespace dimr::tools
