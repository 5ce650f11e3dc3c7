// Declared parameters: one table binds each parameter name (slash-separated, relative to the
// node's private namespace, e.g. "association/min_iou") to a field of a config struct, with its
// unit, documentation and valid range. The node reads ROS parameters through it, tests read
// config/default.yaml through it, and docs/ros.md is checked against it - so a parameter
// cannot exist in one place and not in the others. ROS-free.
#pragma once

#include <array>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace dimr::ros1 {

// A typed key -> value store (the ROS parameter server, a YAML file). Keys are relative,
// slash-separated. Getters return false when the key is absent and throw
// dimr::InvalidArgument naming the key when it is present with the wrong type.
class ParamSource {
 public:
  virtual ~ParamSource() = default;
  virtual std::vector<std::string> Keys() const = 0;  // every leaf key present
  virtual bool GetBool(const std::string& key, bool* v) const = 0;
  virtual bool GetDouble(const std::string& key, double* v) const = 0;  // ints accepted
  virtual bool GetInt(const std::string& key, long long* v) const = 0;
  virtual bool GetString(const std::string& key, std::string* v) const = 0;
  virtual bool GetDoubleList(const std::string& key, std::vector<double>* v) const = 0;
  // Where the values come from, for messages ("ROS parameters of /dimr", "config/default.yaml").
  virtual std::string Describe() const = 0;
};

// A YAML mapping (nested maps become slash-separated keys). Throws dimr::ParseError naming the
// file when it cannot be read or is not a mapping.
std::unique_ptr<ParamSource> YamlParamSource(const std::string& path);
std::unique_ptr<ParamSource> YamlParamSourceFromString(const std::string& text,
                                                       const std::string& name);

enum class ParamType { kBool, kInt, kDouble, kString, kVector3 };

struct ParamEntry {
  std::string name;
  ParamType type = ParamType::kDouble;
  std::string unit;                  // "m", "s", "Hz", "" for none
  std::string doc;                   // one line
  double min = 0, max = 0;           // inclusive numeric range (kInt, kDouble, each kVector3 value)
  std::vector<std::string> choices;  // kString: allowed values, empty = any
  bool allow_empty = true;           // kString without choices
  // Bound field accessors.
  std::function<std::string()> get_text;                             // current value as YAML text
  std::function<void(const ParamSource&, const std::string&)> read;  // reads + range-checks
};

class ParamTable {
 public:
  void AddBool(const std::string& name, bool* field, const std::string& doc);
  void AddInt(const std::string& name, int* field, int min, int max, const std::string& unit,
              const std::string& doc);
  void AddDouble(const std::string& name, double* field, double min, double max,
                 const std::string& unit, const std::string& doc);
  void AddString(const std::string& name, std::string* field, std::vector<std::string> choices,
                 const std::string& doc, bool allow_empty = true);
  void AddVector3(const std::string& name, std::array<double, 3>* field, double min, double max,
                  const std::string& unit, const std::string& doc);

  const std::vector<ParamEntry>& entries() const { return entries_; }
  const ParamEntry* Find(const std::string& name) const;

  // Reads every declared key that `source` has into its field (absent keys keep the field's
  // value). Throws dimr::InvalidArgument naming the key, the source, the value and the valid
  // range on a wrong type or an out-of-range value. Returns the keys of `source` that are not
  // declared (the caller warns about them; `ignore_prefixes` are skipped, e.g. "bond/").
  std::vector<std::string> Read(const ParamSource& source,
                                const std::vector<std::string>& ignore_prefixes = {}) const;
  // "name: value  # unit" per line, in declaration order (the resolved config, logged once).
  std::string Dump() const;
  // A "range" column for documentation: "[0, 1]", "generation, projection", "any".
  static std::string RangeText(const ParamEntry& e);

 private:
  void Add(ParamEntry e);
  std::vector<ParamEntry> entries_;
};

}  // namespace dimr::ros1
