// One declaration per configuration field (name, unit, help, check) that drives the
// `key=value` text form of a config struct (FromString / ToString, the lines of model cards and
// model archives), its validation, and the CLI binding (src/tools/config_options.h turns the same
// declarations into command-line options). Values are parsed strictly: the whole token must be
// the value, so `resolution=32x` or `scale=20.5.1` are errors naming the key, never 32 / 20.5.
//
//   struct Cfg { int reps = 1; double scale = 20; bool rgb = false; };
//   const config::Fields<Cfg>& CfgFields() {
//     static const auto f = config::Fields<Cfg>("stage1 config")
//         .Number("reps", [](Cfg& c) -> int& { return c.reps; }, "", "blocks per level", 1, 8)
//         .Number("scale", [](Cfg& c) -> double& { return c.scale; }, "1/m", "voxels per metre",
//                 1.0, 1000.0)
//         .Flag("rgb", [](Cfg& c) -> bool& { return c.rgb; }, "feed colours");
//     return f;
//   }
//   Cfg c = CfgFields().Parse("reps=2 scale=50");   // InvalidArgument "stage1 config: 'reps=2x':
//   ..." std::string s = CfgFields().Format(c);           // "reps=2 scale=50 rgb=0"
//
// Enums get name tables (EnumNames) with Name / Parse helpers whose errors list the valid names.
// Header-only, standard library only.
#pragma once

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "dimr/core/error.h"

namespace dimr::config {

// ---------------------------------------------------------------- strict scalars
// The whole text is an integer (optional sign, decimal digits): no blanks, no trailing text.
inline bool ParseInt(const std::string& text, long long* out) {
  if (text.empty() || text.find_first_of(" \t\r\n") != std::string::npos) return false;
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (errno != 0 || end != text.c_str() + text.size()) return false;
  *out = v;
  return true;
}

// The whole text is a finite decimal number ("0.05", "-1e-3"): no trailing text, no nan/inf.
inline bool ParseDouble(const std::string& text, double* out) {
  if (text.empty() || text.find_first_of(" \t\r\n") != std::string::npos) return false;
  if (text.find_first_of("xXpP") != std::string::npos) return false;  // no hex floats
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (errno != 0 || end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

// 1/0, true/false.
inline bool ParseBool(const std::string& text, bool* out) {
  if (text == "1" || text == "true") {
    *out = true;
  } else if (text == "0" || text == "false") {
    *out = false;
  } else {
    return false;
  }
  return true;
}

// Shortest round-trip-free default text of a double, as std::ostream prints it ("20", "0.08").
inline std::string FormatDouble(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The comma-separated items of a value; "" has none (and so has "none" when none_is_empty).
inline std::vector<std::string> SplitList(const std::string& text, bool none_is_empty = false) {
  std::vector<std::string> items;
  if (text.empty() || (none_is_empty && text == "none")) return items;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) items.push_back(item);
  if (!text.empty() && text.back() == ',') items.emplace_back();  // "a," has an empty item
  return items;
}

// ---------------------------------------------------------------- enums
// A table of an enum's values and their names, in order.
template <class E>
class EnumNames {
 public:
  EnumNames(std::string what, std::vector<std::pair<E, std::string>> names)
      : what_(std::move(what)), names_(std::move(names)) {}

  const std::string& Name(E value) const {
    for (const auto& [v, n] : names_) {
      if (v == value) return n;
    }
    throw InvalidArgument(what_ + ": value " + std::to_string(static_cast<long long>(value)) +
                          " has no name");
  }
  // Throws dimr::InvalidArgument "<what>: 'x' is not one of a, b, c".
  E Parse(const std::string& text) const {
    for (const auto& [v, n] : names_) {
      if (n == text) return v;
    }
    throw InvalidArgument(what_ + ": '" + text + "' is not one of " + List());
  }
  bool TryParse(const std::string& text, E* out) const {
    for (const auto& [v, n] : names_) {
      if (n == text) {
        *out = v;
        return true;
      }
    }
    return false;
  }
  // "a, b, c"
  std::string List() const {
    std::string r;
    for (const auto& [v, n] : names_) r += (r.empty() ? "" : ", ") + n;
    return r;
  }
  const std::vector<std::pair<E, std::string>>& names() const { return names_; }
  const std::string& what() const { return what_; }

 private:
  std::string what_;
  std::vector<std::pair<E, std::string>> names_;
};

// ---------------------------------------------------------------- fields
template <class X>
struct NonDeduced {
  using type = X;
};

template <class T>
class Fields {
 public:
  struct Field {
    std::string name;  // the key ("vote_radius"); the CLI option is --vote-radius
    std::string unit;  // "m", "1/m", "" ...
    std::string help;
    bool is_flag = false;  // a 0/1 value (a CLI flag without argument)
    // The value's text; parse returns "" or the problem ("expected an integer").
    std::function<std::string(const T&)> format;
    std::function<std::string(T&, const std::string&)> parse;
    // "" or the problem of the current value (range, consistency); null = always fine.
    std::function<std::string(const T&)> check;
    // Whether Format writes the field; null = always.
    std::function<bool(const T&)> written;
  };

  explicit Fields(std::string owner) : owner_(std::move(owner)) {}

  const std::string& owner() const { return owner_; }
  const std::vector<Field>& fields() const { return fields_; }
  const Field* Find(const std::string& key) const {
    for (const auto& f : fields_) {
      if (f.name == key) return &f;
    }
    return nullptr;
  }

  Fields& Add(Field f) {
    fields_.push_back(std::move(f));
    return *this;
  }

  // A number (integral or floating) in [lo, hi], reached through `ref(T&) -> V&`.
  template <class Ref, class V = std::decay_t<std::invoke_result_t<Ref, T&>>>
  Fields& Number(const std::string& name, Ref ref, const std::string& unit, const std::string& help,
                 typename NonDeduced<V>::type lo, typename NonDeduced<V>::type hi) {
    static_assert(std::is_arithmetic_v<V> && !std::is_same_v<V, bool>, "Number: arithmetic");
    Field f;
    f.name = name;
    f.unit = unit;
    f.help = help;
    f.format = [ref](const T& c) { return FormatNumber(ref(const_cast<T&>(c))); };
    f.check = [ref, lo, hi](const T& c) { return RangeProblem(ref(const_cast<T&>(c)), lo, hi); };
    f.parse = [ref, lo, hi](T& c, const std::string& text) -> std::string {
      V v{};
      if (const std::string p = ParseNumber(text, &v); !p.empty()) return p;
      if (const std::string p = RangeProblem(v, lo, hi); !p.empty()) return p;
      ref(c) = v;
      return "";
    };
    return Add(std::move(f));
  }

  // A comma-separated list of numbers, each in [lo, hi], with at least `min_count` items.
  template <class Ref, class V = typename std::decay_t<std::invoke_result_t<Ref, T&>>::value_type>
  Fields& NumberList(const std::string& name, Ref ref, const std::string& unit,
                     const std::string& help, typename NonDeduced<V>::type lo,
                     typename NonDeduced<V>::type hi, std::size_t min_count = 1) {
    Field f;
    f.name = name;
    f.unit = unit;
    f.help = help;
    f.format = [ref](const T& c) {
      std::string r;
      for (const V& v : ref(const_cast<T&>(c))) r += (r.empty() ? "" : ",") + FormatNumber(v);
      return r;
    };
    auto check_list = [name, lo, hi, min_count](const std::vector<V>& list) -> std::string {
      if (list.size() < min_count) {
        return "needs at least " + std::to_string(min_count) + " value(s), got " +
               std::to_string(list.size());
      }
      for (std::size_t i = 0; i < list.size(); ++i) {
        if (const std::string p = RangeProblem(list[i], lo, hi); !p.empty()) {
          return name + "[" + std::to_string(i) + "] = " + FormatNumber(list[i]) + " " + p;
        }
      }
      return "";
    };
    f.check = [ref, check_list](const T& c) { return check_list(ref(const_cast<T&>(c))); };
    f.parse = [ref, check_list](T& c, const std::string& text) -> std::string {
      std::vector<V> list;
      const std::vector<std::string> items = SplitList(text);
      for (std::size_t i = 0; i < items.size(); ++i) {
        V v{};
        if (const std::string p = ParseNumber(items[i], &v); !p.empty()) {
          return "item " + std::to_string(i) + " '" + items[i] + "': " + p;
        }
        list.push_back(v);
      }
      if (const std::string p = check_list(list); !p.empty()) return p;
      ref(c) = std::move(list);
      return "";
    };
    return Add(std::move(f));
  }

  // A 0/1 value.
  template <class Ref>
  Fields& Flag(const std::string& name, Ref ref, const std::string& help) {
    Field f;
    f.name = name;
    f.help = help;
    f.is_flag = true;
    f.format = [ref](const T& c) { return std::string(ref(const_cast<T&>(c)) ? "1" : "0"); };
    f.parse = [ref](T& c, const std::string& text) -> std::string {
      bool v = false;
      if (!ParseBool(text, &v)) return "expected 0 or 1";
      ref(c) = v;
      return "";
    };
    return Add(std::move(f));
  }

  // An enum by name.
  template <class Ref, class E = std::decay_t<std::invoke_result_t<Ref, T&>>>
  Fields& Enum(const std::string& name, Ref ref, const EnumNames<E>& names,
               const std::string& help) {
    Field f;
    f.name = name;
    f.help = help + " (" + names.List() + ")";
    f.format = [ref, names](const T& c) { return names.Name(ref(const_cast<T&>(c))); };
    f.parse = [ref, names](T& c, const std::string& text) -> std::string {
      E v{};
      if (!names.TryParse(text, &v)) return "expected one of " + names.List();
      ref(c) = v;
      return "";
    };
    return Add(std::move(f));
  }

  // Writes only fields whose `written` holds: e.g. "only when not the default".
  Fields& WrittenIf(std::function<bool(const T&)> written) {
    fields_.back().written = std::move(written);
    return *this;
  }
  // An extra check of the last field (after its own).
  Fields& Check(std::function<std::string(const T&)> check) {
    auto own = fields_.back().check;
    fields_.back().check = [own, check](const T& c) {
      if (own) {
        if (std::string p = own(c); !p.empty()) return p;
      }
      return check(c);
    };
    return *this;
  }

  // Sets one field from text and runs that field's check. Throws dimr::InvalidArgument
  // "<owner>: 'key=value': <problem>" (also "unknown key (keys: a, b, ...)"); `c` is unchanged
  // when the value does not parse.
  void Set(T& c, const std::string& key, const std::string& value) const {
    const std::string where = owner_ + ": '" + key + "=" + value + "': ";
    const Field* f = Find(key);
    if (f == nullptr) throw InvalidArgument(where + "unknown key (keys: " + Keys() + ")");
    if (const std::string p = f->parse(c, value); !p.empty()) throw InvalidArgument(where + p);
    if (f->check) {
      if (const std::string p = f->check(c); !p.empty()) throw InvalidArgument(where + p);
    }
  }

  // Whitespace-separated key=value tokens applied in order on top of `base`; no Check.
  T Parse(const std::string& text, T base = T()) const {
    std::istringstream in(text);
    std::string token;
    while (in >> token) {
      const std::size_t eq = token.find('=');
      if (eq == std::string::npos || eq == 0) {
        throw InvalidArgument(owner_ + ": '" + token + "' is not key=value");
      }
      Set(base, token.substr(0, eq), token.substr(eq + 1));
    }
    return base;
  }

  // "key=value ..." in declaration order (fields whose `written` is false are left out).
  std::string Format(const T& c) const {
    std::string r;
    for (const auto& f : fields_) {
      if (f.written && !f.written(c)) continue;
      r += (r.empty() ? "" : " ") + f.name + "=" + f.format(c);
    }
    return r;
  }

  // Throws dimr::InvalidArgument "<owner>: key = value: <problem>" for the first bad field.
  void Validate(const T& c) const {
    for (const auto& f : fields_) {
      if (!f.check) continue;
      if (const std::string p = f.check(c); !p.empty()) {
        throw InvalidArgument(owner_ + ": " + f.name + " = " + f.format(c) + ": " + p);
      }
    }
  }

  // "a, b, c"
  std::string Keys() const {
    std::string r;
    for (const auto& f : fields_) r += (r.empty() ? "" : ", ") + f.name;
    return r;
  }

 private:
  template <class V>
  static std::string FormatNumber(V v) {
    if constexpr (std::is_floating_point_v<V>) {
      return FormatDouble(static_cast<double>(v));
    } else {
      return std::to_string(v);
    }
  }
  template <class V>
  static std::string ParseNumber(const std::string& text, V* out) {
    if constexpr (std::is_floating_point_v<V>) {
      double v = 0;
      if (!ParseDouble(text, &v)) return "expected a finite number";
      *out = static_cast<V>(v);
    } else {
      long long v = 0;
      if (!ParseInt(text, &v)) return "expected an integer";
      if (v < static_cast<long long>(std::numeric_limits<V>::min()) ||
          v > static_cast<long long>(std::numeric_limits<V>::max())) {
        return "out of range";
      }
      *out = static_cast<V>(v);
    }
    return "";
  }
  template <class V>
  static std::string RangeProblem(V v, V lo, V hi) {
    if constexpr (std::is_floating_point_v<V>) {
      if (!std::isfinite(v)) return "not finite";
    }
    if (v < lo || v > hi) return "must be in [" + FormatNumber(lo) + ", " + FormatNumber(hi) + "]";
    return "";
  }

  std::string owner_;
  std::vector<Field> fields_;
};

}  // namespace dimr::config
