// A model card: the `model.yaml` beside a model's weights (architecture, label set, training
// record, metrics, sha256 of the weights, recommended inference settings; docs/models.md).
// Read with yaml-cpp once, at Load; every mapping level is flattened into dotted keys
// ("weights.sha256", "metrics.test_iou_per_class.chair"), so getters are plain look-ups.
//
//   const auto card = pipeline::ModelCard::Load("models/bsp/bsp.pt");   // reads
//   models/bsp/model.yaml double d = card.GetDouble("recommended_distance_dilation", 0.0);  //
//   default when absent std::string sha = card.GetString("weights.sha256");               //
//   required: throws if absent
//
// Every error is a dimr::ParseError whose source is the card's path and whose message names the
// key (and the card's line), e.g. "models/bsp/model.yaml: recommended_dilation (line 52) must be
// a number, got 'wide'". A ModelCard is immutable after Load: safe to share between threads.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace dimr::pipeline {

class ModelCard {
 public:
  // An empty card (no keys, path ""): every getter returns its default.
  ModelCard() = default;

  // The card of a model: `weights_or_card_path` itself when it ends in .yaml / .yml, else
  // model.yaml in the same folder as the weights. Throws dimr::ParseError naming the card for a
  // missing or unreadable file, malformed YAML or a top level that is not a mapping.
  static ModelCard Load(const std::string& weights_or_card_path);
  // As Load, but std::nullopt when the card file does not exist (a model without a card);
  // a card that exists and is malformed still throws.
  static std::optional<ModelCard> LoadIfExists(const std::string& weights_or_card_path);
  // A card from YAML text; `source` names it in errors (and is its path()).
  static ModelCard Parse(const std::string& yaml_text, const std::string& source);
  // The path Load reads for `weights_or_card_path`.
  static std::string CardPath(const std::string& weights_or_card_path);

  const std::string& path() const { return path_; }

  // True when the (dotted) key exists, whatever its value (scalar, list, mapping or empty).
  bool has(const std::string& key) const;
  // Every key in card order, nested ones dotted (a mapping's own key comes before its members).
  std::vector<std::string> Keys() const;

  // Typed getters. Without a default: throws dimr::ParseError when the key is missing. With a
  // default: returns it when the key is missing. Either way a value that is present but not of
  // the asked type throws (a card never silently falls back on a typo).
  //  - string: any scalar as written (quotes removed; an empty value `key:` is "").
  //  - double: a finite decimal number ("0.0145", "1e-3"); int: an integer in int range;
  //  - bool: true/false, yes/no, on/off, 1/0 (any case).
  //  - lists: a YAML sequence of scalars ([a, b] or one "- a" per line).
  std::string GetString(const std::string& key) const;
  std::string GetString(const std::string& key, const std::string& fallback) const;
  double GetDouble(const std::string& key) const;
  double GetDouble(const std::string& key, double fallback) const;
  int GetInt(const std::string& key) const;
  int GetInt(const std::string& key, int fallback) const;
  bool GetBool(const std::string& key) const;
  bool GetBool(const std::string& key, bool fallback) const;
  std::vector<std::string> GetStringList(const std::string& key) const;
  std::vector<double> GetDoubleList(const std::string& key) const;

 private:
  enum class Kind { kNull, kScalar, kSequence, kMap };
  struct Value {
    Kind kind = Kind::kNull;
    std::string scalar;
    std::vector<std::string> items;  // kSequence: its scalars
    bool items_scalar = true;        // false when some item is not a scalar
    int line = 0;                    // 1-based line of the value in the card
  };

  const Value& Require(const std::string& key) const;
  const Value* Find(const std::string& key) const;
  std::string Source() const;
  std::string Where(const std::string& key, const Value& v) const;
  std::string ScalarOf(const std::string& key, const Value& v) const;
  double DoubleOf(const std::string& key, const Value& v) const;
  int IntOf(const std::string& key, const Value& v) const;
  bool BoolOf(const std::string& key, const Value& v) const;

  std::string path_;
  std::map<std::string, Value> values_;
  std::vector<std::string> order_;
};

}  // namespace dimr::pipeline
