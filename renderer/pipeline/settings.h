// SPDX-License-Identifier: Apache-2.0
#pragma once
// Render settings: every quality knob and effect switch of fovea-render, with its default, allowed
// values and meaning. `--set key=value` on the command line and the viewer's toggles change them;
// unknown keys and bad values are errors that list what is allowed.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace fovea::render {

struct SettingSpec {
  std::string key;
  std::string default_value;
  std::string allowed;      // "bool", "number in [a, b]", "auto|number in [a, b]", or "a|b|c"
  std::string description;
};

class Settings {
 public:
  Settings();  // every key at its default
  static const std::vector<SettingSpec>& specs();

  // Throws std::invalid_argument naming the key and what is allowed.
  void set(const std::string& key, const std::string& value);
  // "key=value"; throws std::invalid_argument if malformed.
  void set_assignment(const std::string& assignment);

  const std::string& text(const std::string& key) const;
  bool flag(const std::string& key) const;
  double number(const std::string& key) const;
  bool is(const std::string& key, const std::string& value) const { return text(key) == value; }
  // Keys whose value differs from the default, for reports.
  std::map<std::string, std::string> changed() const;
  // Grows with every set() that changes a value: the passes parse their typed settings again only
  // when it moved.
  std::uint64_t version() const { return version_; }

 private:
  std::map<std::string, std::string> values_;
  std::uint64_t version_ = 0;
};

}  // namespace fovea::render
