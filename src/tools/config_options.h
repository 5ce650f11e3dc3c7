// CLI options from config field declarations (dimr/core/config_fields.h): one option per field,
// named --<key with '-' for '_'>, whose help is the field's help and unit. 0/1 fields become
// flags (--mirror, --mirror=false). The values given on the command line are applied on top of
// a config later (after, say, a model card set the defaults), with the field's own parser, so
// the CLI, the model cards and FromString accept exactly the same values.
#pragma once

#include <CLI/CLI.hpp>
#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "dimr/core/config_fields.h"

namespace dimr::tools {

template <class T>
class ConfigOptions {
 public:
  // `only`: the keys to expose (empty = every field); `help_suffix` is appended to each help.
  ConfigOptions(CLI::App& app, const config::Fields<T>& fields, const std::string& help_suffix = "",
                const std::vector<std::string>& only = {})
      : fields_(&fields) {
    for (const auto& f : fields.fields()) {
      if (!only.empty() && std::find(only.begin(), only.end(), f.name) == only.end()) continue;
      auto e = std::make_shared<Entry>();
      e->key = f.name;
      std::string name = "--" + f.name;
      std::replace(name.begin(), name.end(), '_', '-');
      std::string help = f.help + (f.unit.empty() ? "" : " [" + f.unit + "]") + help_suffix;
      if (f.is_flag) {
        e->option = app.add_flag(name, e->flag, help);
      } else {
        e->option = app.add_option(name, e->text, help);
      }
      entries_.push_back(e);
    }
  }

  // The fields given on the command line, applied to `c` in declaration order. Throws
  // dimr::InvalidArgument naming the option's key and value.
  void Apply(T* c) const {
    for (const auto& e : entries_) {
      if (e->option->count() == 0) continue;
      fields_->Set(*c, e->key,
                   e->option->get_expected_max() == 0 ? (e->flag ? "1" : "0") : e->text);
    }
  }
  bool Given(const std::string& key) const {
    for (const auto& e : entries_) {
      if (e->key == key) return e->option->count() > 0;
    }
    return false;
  }

 private:
  struct Entry {
    std::string key, text;
    bool flag = false;
    CLI::Option* option = nullptr;
  };
  const config::Fields<T>* fields_;
  std::vector<std::shared_ptr<Entry>> entries_;
};

}  // namespace dimr::tools
