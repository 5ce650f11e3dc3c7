#include "dimr/pipeline/model_card.h"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <locale>
#include <sstream>

#include "dimr/core/error.h"

namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

// Cards are a few kB; anything this large is not a card.
constexpr std::uintmax_t kMaxCardBytes = 16u << 20;

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::string ModelCard::CardPath(const std::string& weights_or_card_path) {
  if (EndsWith(weights_or_card_path, ".yaml") || EndsWith(weights_or_card_path, ".yml")) {
    return weights_or_card_path;
  }
  return (fs::path(weights_or_card_path).parent_path() / "model.yaml").string();
}

std::optional<ModelCard> ModelCard::LoadIfExists(const std::string& weights_or_card_path) {
  const std::string card = CardPath(weights_or_card_path);
  std::error_code ec;
  if (!fs::exists(card, ec)) return std::nullopt;
  return Load(weights_or_card_path);
}

ModelCard ModelCard::Load(const std::string& weights_or_card_path) {
  const std::string card = CardPath(weights_or_card_path);
  std::error_code ec;
  if (!fs::is_regular_file(card, ec)) {
    throw ParseError(card, "no model card (model.yaml beside the weights) found");
  }
  const std::uintmax_t size = fs::file_size(card, ec);
  if (ec || size > kMaxCardBytes) {
    throw ParseError(card, "model card unreadable or larger than 16 MiB");
  }
  std::ifstream in(card, std::ios::binary);
  if (!in) throw ParseError(card, "cannot open the model card");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ParseError(card, "read error");
  return Parse(text.str(), card);
}

ModelCard ModelCard::Parse(const std::string& yaml_text, const std::string& source) {
  ModelCard out;
  out.path_ = source;
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ParseError(source, std::string("malformed YAML: ") + e.what());
  }
  if (root.IsNull()) return out;  // an empty card
  if (!root.IsMap()) {
    throw ParseError(source, "the top level of a model card must be a mapping of key: value");
  }
  // Depth-first over the mappings, keys dotted; the first of duplicate keys wins (as YAML
  // readers that stop at the first match, and the line reader this replaces).
  struct Walker {
    ModelCard* card;
    const std::string& source;
    void Walk(const YAML::Node& map, const std::string& prefix, int depth) {
      if (depth > 64) throw ParseError(source, "mappings nested deeper than 64 levels");
      for (const auto& kv : map) {
        if (!kv.first.IsScalar()) {
          throw ParseError(source, "line " + std::to_string(kv.first.Mark().line + 1) +
                                       ": a key must be a plain scalar");
        }
        const std::string key =
            prefix.empty() ? kv.first.Scalar() : prefix + "." + kv.first.Scalar();
        if (card->values_.count(key) != 0) continue;
        Value v;
        const YAML::Node& node = kv.second;
        v.line = (node.Mark().line >= 0 ? node.Mark().line : kv.first.Mark().line) + 1;
        if (node.IsScalar()) {
          v.kind = Kind::kScalar;
          v.scalar = node.Scalar();
        } else if (node.IsSequence()) {
          v.kind = Kind::kSequence;
          for (const auto& item : node) {
            if (item.IsScalar()) {
              v.items.push_back(item.Scalar());
            } else {
              v.items_scalar = false;
              v.items.emplace_back();
            }
          }
        } else if (node.IsMap()) {
          v.kind = Kind::kMap;
        }
        card->values_.emplace(key, v);
        card->order_.push_back(key);
        if (node.IsMap()) Walk(node, key, depth + 1);
      }
    }
  };
  Walker{&out, source}.Walk(root, "", 0);
  return out;
}

bool ModelCard::has(const std::string& key) const { return values_.count(key) != 0; }

std::vector<std::string> ModelCard::Keys() const { return order_; }

const ModelCard::Value* ModelCard::Find(const std::string& key) const {
  const auto it = values_.find(key);
  return it == values_.end() ? nullptr : &it->second;
}

const ModelCard::Value& ModelCard::Require(const std::string& key) const {
  const Value* v = Find(key);
  if (v == nullptr) {
    throw ParseError(Source(), "missing key '" + key + "'");
  }
  return *v;
}

std::string ModelCard::Source() const { return path_.empty() ? "model card" : path_; }

std::string ModelCard::Where(const std::string& key, const Value& v) const {
  return key + " (line " + std::to_string(v.line) + ")";
}

std::string ModelCard::ScalarOf(const std::string& key, const Value& v) const {
  if (v.kind == Kind::kNull) return std::string();
  if (v.kind != Kind::kScalar) {
    throw ParseError(Source(), Where(key, v) + " must be a single value, got a " +
                                   (v.kind == Kind::kMap ? "mapping" : "list"));
  }
  return v.scalar;
}

namespace {

bool ParseFiniteDouble(const std::string& text, double* out) {
  std::istringstream in(text);
  in.imbue(std::locale::classic());
  double d = 0.0;
  in >> d;
  if (in.fail()) return false;
  in >> std::ws;
  if (!in.eof()) return false;
  if (!std::isfinite(d)) return false;
  *out = d;
  return true;
}

bool ParseInt(const std::string& text, int* out) {
  const std::size_t a = text.find_first_not_of(" \t");
  if (a == std::string::npos) return false;
  const char* begin = text.c_str() + a;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(begin, &end, 10);
  if (end == begin || errno == ERANGE || v < INT_MIN || v > INT_MAX) return false;
  while (*end == ' ' || *end == '\t') ++end;
  if (*end != '\0') return false;
  *out = static_cast<int>(v);
  return true;
}

}  // namespace

double ModelCard::DoubleOf(const std::string& key, const Value& v) const {
  const std::string s = ScalarOf(key, v);
  double d = 0.0;
  if (v.kind != Kind::kScalar || !ParseFiniteDouble(s, &d)) {
    throw ParseError(Source(), Where(key, v) + " must be a finite number, got '" + s + "'");
  }
  return d;
}

int ModelCard::IntOf(const std::string& key, const Value& v) const {
  const std::string s = ScalarOf(key, v);
  int i = 0;
  if (v.kind != Kind::kScalar || !ParseInt(s, &i)) {
    throw ParseError(Source(), Where(key, v) + " must be an integer, got '" + s + "'");
  }
  return i;
}

bool ModelCard::BoolOf(const std::string& key, const Value& v) const {
  const std::string s = Lower(ScalarOf(key, v));
  if (s == "true" || s == "yes" || s == "on" || s == "1") return true;
  if (s == "false" || s == "no" || s == "off" || s == "0") return false;
  throw ParseError(Source(), Where(key, v) + " must be true or false, got '" + s + "'");
}

std::string ModelCard::GetString(const std::string& key) const {
  return ScalarOf(key, Require(key));
}
std::string ModelCard::GetString(const std::string& key, const std::string& fallback) const {
  const Value* v = Find(key);
  return v == nullptr ? fallback : ScalarOf(key, *v);
}
double ModelCard::GetDouble(const std::string& key) const { return DoubleOf(key, Require(key)); }
double ModelCard::GetDouble(const std::string& key, double fallback) const {
  const Value* v = Find(key);
  return v == nullptr ? fallback : DoubleOf(key, *v);
}
int ModelCard::GetInt(const std::string& key) const { return IntOf(key, Require(key)); }
int ModelCard::GetInt(const std::string& key, int fallback) const {
  const Value* v = Find(key);
  return v == nullptr ? fallback : IntOf(key, *v);
}
bool ModelCard::GetBool(const std::string& key) const { return BoolOf(key, Require(key)); }
bool ModelCard::GetBool(const std::string& key, bool fallback) const {
  const Value* v = Find(key);
  return v == nullptr ? fallback : BoolOf(key, *v);
}

std::vector<std::string> ModelCard::GetStringList(const std::string& key) const {
  const Value& v = Require(key);
  if (v.kind == Kind::kNull) return {};
  if (v.kind != Kind::kSequence || !v.items_scalar) {
    throw ParseError(Source(), Where(key, v) + " must be a list of values ([a, b, ...])");
  }
  return v.items;
}

std::vector<double> ModelCard::GetDoubleList(const std::string& key) const {
  const std::vector<std::string> items = GetStringList(key);
  std::vector<double> out(items.size());
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (!ParseFiniteDouble(items[i], &out[i])) {
      throw ParseError(Source(), Where(key, *Find(key)) + " item " + std::to_string(i) +
                                     " must be a finite number, got '" + items[i] + "'");
    }
  }
  return out;
}

}  // namespace dimr::pipeline
