// Declared parameters (see param_table.h).
#include "dimr/ros/param_table.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

std::string Num(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::ostringstream s;
  s << std::setprecision(10) << v;
  return s.str();
}

[[noreturn]] void Fail(const ParamSource& src, const std::string& key, const std::string& what) {
  throw InvalidArgument("parameter '" + key + "' (" + src.Describe() + "): " + what);
}

// Flattened YAML scalars and sequences.
class YamlSource : public ParamSource {
 public:
  YamlSource(const YAML::Node& root, std::string name) : name_(std::move(name)) {
    if (!root.IsMap() && !root.IsNull())
      throw ParseError(name_, "the top level must be a mapping of parameter names");
    Flatten(root, "");
  }
  std::vector<std::string> Keys() const override {
    std::vector<std::string> k;
    for (const auto& [key, node] : leaves_) k.push_back(key);
    return k;
  }
  bool GetBool(const std::string& key, bool* v) const override {
    const YAML::Node* n = Leaf(key);
    if (!n) return false;
    try {
      *v = n->as<bool>();
    } catch (const YAML::Exception&) {
      Fail(*this, key, "expected true or false, got '" + Text(*n) + "'");
    }
    return true;
  }
  bool GetDouble(const std::string& key, double* v) const override {
    const YAML::Node* n = Leaf(key);
    if (!n) return false;
    try {
      if (!n->IsScalar()) throw YAML::Exception(YAML::Mark(), "not a scalar");
      *v = n->as<double>();
    } catch (const YAML::Exception&) {
      Fail(*this, key, "expected a number, got '" + Text(*n) + "'");
    }
    return true;
  }
  bool GetInt(const std::string& key, long long* v) const override {
    const YAML::Node* n = Leaf(key);
    if (!n) return false;
    try {
      if (!n->IsScalar()) throw YAML::Exception(YAML::Mark(), "not a scalar");
      *v = n->as<long long>();
    } catch (const YAML::Exception&) {
      Fail(*this, key, "expected an integer, got '" + Text(*n) + "'");
    }
    return true;
  }
  bool GetString(const std::string& key, std::string* v) const override {
    const YAML::Node* n = Leaf(key);
    if (!n) return false;
    if (n->IsNull()) {
      *v = "";
      return true;
    }
    if (!n->IsScalar()) Fail(*this, key, "expected a string");
    *v = n->Scalar();
    return true;
  }
  bool GetDoubleList(const std::string& key, std::vector<double>* v) const override {
    const YAML::Node* n = Leaf(key);
    if (!n) return false;
    if (!n->IsSequence()) Fail(*this, key, "expected a list of numbers, got '" + Text(*n) + "'");
    v->clear();
    for (const auto& e : *n) {
      try {
        v->push_back(e.as<double>());
      } catch (const YAML::Exception&) {
        Fail(*this, key, "expected a list of numbers, got element '" + Text(e) + "'");
      }
    }
    return true;
  }
  std::string Describe() const override { return name_; }

 private:
  static std::string Text(const YAML::Node& n) {
    YAML::Emitter e;
    e << YAML::Flow << n;
    return e.c_str();
  }
  void Flatten(const YAML::Node& n, const std::string& prefix) {
    if (n.IsMap()) {
      for (const auto& kv : n) {
        const std::string k = kv.first.as<std::string>();
        Flatten(kv.second, prefix.empty() ? k : prefix + "/" + k);
      }
    } else if (!prefix.empty()) {
      leaves_[prefix] = n;
    }
  }
  const YAML::Node* Leaf(const std::string& key) const {
    auto it = leaves_.find(key);
    return it == leaves_.end() ? nullptr : &it->second;
  }
  std::string name_;
  std::map<std::string, YAML::Node> leaves_;
};

}  // namespace

std::unique_ptr<ParamSource> YamlParamSource(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw ParseError(path, std::string("cannot read YAML: ") + e.what());
  }
  return std::make_unique<YamlSource>(root, path);
}

std::unique_ptr<ParamSource> YamlParamSourceFromString(const std::string& text,
                                                       const std::string& name) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ParseError(name, std::string("cannot parse YAML: ") + e.what());
  }
  return std::make_unique<YamlSource>(root, name);
}

void ParamTable::Add(ParamEntry e) {
  if (Find(e.name)) throw InvalidArgument("ParamTable: parameter '" + e.name + "' declared twice");
  entries_.push_back(std::move(e));
}

const ParamEntry* ParamTable::Find(const std::string& name) const {
  for (const ParamEntry& e : entries_)
    if (e.name == name) return &e;
  return nullptr;
}

void ParamTable::AddBool(const std::string& name, bool* field, const std::string& doc) {
  ParamEntry e;
  e.name = name;
  e.type = ParamType::kBool;
  e.doc = doc;
  e.get_text = [field] { return std::string(*field ? "true" : "false"); };
  e.read = [field](const ParamSource& s, const std::string& k) { s.GetBool(k, field); };
  Add(std::move(e));
}

void ParamTable::AddInt(const std::string& name, int* field, int min, int max,
                        const std::string& unit, const std::string& doc) {
  ParamEntry e;
  e.name = name;
  e.type = ParamType::kInt;
  e.unit = unit;
  e.doc = doc;
  e.min = min;
  e.max = max;
  e.get_text = [field] { return std::to_string(*field); };
  e.read = [field, min, max](const ParamSource& s, const std::string& k) {
    long long v = 0;
    if (!s.GetInt(k, &v)) return;
    if (v < min || v > max)
      Fail(s, k,
           std::to_string(v) + " is outside [" + std::to_string(min) + ", " + std::to_string(max) +
               "]");
    *field = static_cast<int>(v);
  };
  Add(std::move(e));
}

void ParamTable::AddDouble(const std::string& name, double* field, double min, double max,
                           const std::string& unit, const std::string& doc) {
  ParamEntry e;
  e.name = name;
  e.type = ParamType::kDouble;
  e.unit = unit;
  e.doc = doc;
  e.min = min;
  e.max = max;
  e.get_text = [field] { return Num(*field); };
  e.read = [field, min, max](const ParamSource& s, const std::string& k) {
    double v = 0;
    if (!s.GetDouble(k, &v)) return;
    if (!std::isfinite(v) || v < min || v > max)
      Fail(s, k, Num(v) + " is outside [" + Num(min) + ", " + Num(max) + "]");
    *field = v;
  };
  Add(std::move(e));
}

void ParamTable::AddString(const std::string& name, std::string* field,
                           std::vector<std::string> choices, const std::string& doc,
                           bool allow_empty) {
  ParamEntry e;
  e.name = name;
  e.type = ParamType::kString;
  e.doc = doc;
  e.choices = choices;
  e.allow_empty = allow_empty;
  e.get_text = [field] { return "\"" + *field + "\""; };
  e.read = [field, choices, allow_empty](const ParamSource& s, const std::string& k) {
    std::string v;
    if (!s.GetString(k, &v)) return;
    if (!choices.empty()) {
      bool ok = false;
      std::string list;
      for (const std::string& c : choices) {
        ok = ok || c == v;
        list += (list.empty() ? "" : " | ") + c;
      }
      if (!ok) Fail(s, k, "'" + v + "' is not one of " + list);
    } else if (!allow_empty && v.empty()) {
      Fail(s, k, "must not be empty");
    }
    *field = v;
  };
  Add(std::move(e));
}

void ParamTable::AddVector3(const std::string& name, std::array<double, 3>* field, double min,
                            double max, const std::string& unit, const std::string& doc) {
  ParamEntry e;
  e.name = name;
  e.type = ParamType::kVector3;
  e.unit = unit;
  e.doc = doc;
  e.min = min;
  e.max = max;
  e.get_text = [field] {
    return "[" + Num((*field)[0]) + ", " + Num((*field)[1]) + ", " + Num((*field)[2]) + "]";
  };
  e.read = [field, min, max](const ParamSource& s, const std::string& k) {
    std::vector<double> v;
    if (!s.GetDoubleList(k, &v)) return;
    if (v.size() != 3) Fail(s, k, "expected 3 numbers, got " + std::to_string(v.size()));
    for (double x : v)
      if (!std::isfinite(x) || x < min || x > max)
        Fail(s, k, Num(x) + " is outside [" + Num(min) + ", " + Num(max) + "]");
    *field = {v[0], v[1], v[2]};
  };
  Add(std::move(e));
}

std::vector<std::string> ParamTable::Read(const ParamSource& source,
                                          const std::vector<std::string>& ignore_prefixes) const {
  for (const ParamEntry& e : entries_) e.read(source, e.name);
  std::vector<std::string> unknown;
  for (const std::string& k : source.Keys()) {
    bool skip = Find(k) != nullptr;
    for (const std::string& p : ignore_prefixes) skip = skip || k.rfind(p, 0) == 0;
    if (!skip) unknown.push_back(k);
  }
  return unknown;
}

std::string ParamTable::Dump() const {
  std::string out;
  for (const ParamEntry& e : entries_) {
    out += e.name + ": " + e.get_text();
    if (!e.unit.empty()) out += "  # " + e.unit;
    out += "\n";
  }
  return out;
}

std::string ParamTable::RangeText(const ParamEntry& e) {
  switch (e.type) {
    case ParamType::kBool:
      return "true, false";
    case ParamType::kInt:
    case ParamType::kDouble:
    case ParamType::kVector3:
      return "[" + Num(e.min) + ", " + Num(e.max) + "]";
    case ParamType::kString: {
      if (e.choices.empty()) return e.allow_empty ? "any" : "non-empty";
      std::string s;
      for (const std::string& c : e.choices) s += (s.empty() ? "" : ", ") + c;
      return s;
    }
  }
  return "";
}

}  // namespace dimr::ros1
