#include "tools/model_card.h"

#include "dimr/pipeline/model_card.h"

namespace dimr::tools {

std::string ModelCardPath(const std::string& model_path) {
  return pipeline::ModelCard::CardPath(model_path);
}

std::optional<std::string> ReadModelCardValue(const std::string& model_path,
                                              const std::string& key) {
  const std::optional<pipeline::ModelCard> card = pipeline::ModelCard::LoadIfExists(model_path);
  if (!card || !card->has(key)) return std::nullopt;
  return card->GetString(key);
}

}  // namespace dimr::tools
