// SPDX-License-Identifier: Apache-2.0
#pragma once
// Reading a JSON document with errors by path: every message names the source, the JSON path of the
// bad value ($.objects[2].transform.translation[1]), the value, and what is allowed. The scene
// loader (scene_loader.cpp) and the overrides (scene_overrides.h) read scene files through this.
// Errors are SceneError (scene_error.h).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "scene/scene_error.h"

namespace fovea::render::json {

// ordered_json keeps the file's key order, so "the first error" is the first one in the file and
// materials given as an object keep their order.
using Json = nlohmann::ordered_json;
using Keys = std::vector<std::string_view>;

// Doubles as the shortest text that reads back the same ("nan", "inf" for the non-finite).
std::string format_number(double v);
// Floats print as the shortest text that reads back as the same float (0.6, not 0.6000000238...).
std::string format_number(float v);
// The offending value as it appears in messages: JSON text, shortened when long.
std::string describe(const Json& v);
// ".key", or ["key"] when the key is not an identifier; "[i]".
std::string key_suffix(std::string_view key);
std::string index_suffix(std::size_t i);
std::string join(const Keys& keys);  // "a, b, c"
// "unknown field; allowed fields here: a, b, c (did you mean 'b'?)"
std::string unknown_field_message(std::string_view key, const Keys& allowed);

// Parses `text` keeping the file's key order; duplicate keys and numbers that overflow a double
// (1e999) are errors at their path (nlohmann's DOM parser keeps the last duplicate silently and
// reports overflow without a path), and so is nesting deeper than kMaxJsonDepth. Throws SceneError;
// the document must be an object.
inline constexpr std::size_t kMaxJsonDepth = 64;
Json parse_document(const std::string& text, const std::string& source);

// A value in the document and its path.
struct Node {
  const Json& v;
  std::string path;
};

enum class Sign { Any, NonNegative, Positive };

// A closed or open interval of allowed numbers, with its unit for messages.
struct Range {
  double lo, hi;
  bool lo_open, hi_open;
  const char* unit;
  bool contains(double x) const {
    return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
  }
  std::string text() const {
    std::string s = std::string(lo_open ? "(" : "[") + format_number(lo) + ", " + format_number(hi) +
                    (hi_open ? ")" : "]");
    if (unit != nullptr && *unit != '\0') s += std::string(" ") + unit;
    return s;
  }
};

// Typed reads of a document's values, each failing with a SceneError that names the path. Values
// an override set carry a note saying so ("(set by override 'camera.width=320')").
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  const std::string& source() const { return source_; }
  // The value at JSON path `path` was set by the override "path=value" `text`.
  void note_override(std::string path, std::string text) { overridden_.emplace_back(std::move(path), std::move(text)); }

  // ---- errors ----
  [[noreturn]] void fail(const std::string& path, const Json* value, const std::string& what) const {
    std::string msg = source_ + ": " + path;
    if (value != nullptr) msg += " = " + describe(*value);
    msg += ": " + what;
    for (const auto& [p, text] : overridden_) {
      if (path == p || path.starts_with(p + ".") || path.starts_with(p + "[")) {
        msg += " (set by override '" + text + "')";
        break;
      }
    }
    throw SceneError(msg);
  }
  [[noreturn]] void fail(const Node& n, const std::string& what) const { fail(n.path, &n.v, what); }

  // ---- structure ----
  void expect_object(const Node& n, const char* what) const {
    if (!n.v.is_object()) fail(n, std::string("must be an object (") + what + ")");
  }
  void check_keys(const Node& n, const Keys& allowed, const char* what) const {
    expect_object(n, what);
    for (const auto& [k, v] : n.v.items()) {
      if (std::find(allowed.begin(), allowed.end(), k) == allowed.end()) {
        fail(n.path + key_suffix(k), &v, unknown_field_message(k, allowed));
      }
      if (k == "comment" && !v.is_string()) fail(n.path + key_suffix(k), &v, "must be a string (a free-form comment)");
    }
  }
  static std::optional<Node> get(const Node& n, std::string_view key) {
    const auto it = n.v.find(key);
    if (it == n.v.end()) return std::nullopt;
    return Node{*it, n.path + key_suffix(key)};
  }
  Node require(const Node& n, std::string_view key, const std::string& what) const {
    auto c = get(n, key);
    if (!c) fail(n.path + key_suffix(key), nullptr, "missing required field: " + what);
    return *c;
  }
  static Node element(const Node& n, std::size_t i) { return Node{n.v[i], n.path + index_suffix(i)}; }

  // ---- values ----
  double number(const Node& n, const Range& r) const {
    const std::string allowed = "must be a finite number in " + r.text();
    if (n.v.is_string()) fail(n, allowed + " (a number, not a string; JSON has no NaN or Infinity)");
    if (!n.v.is_number()) fail(n, allowed);
    const double x = n.v.get<double>();
    if (!std::isfinite(x) || !r.contains(x)) fail(n, allowed);
    return x;
  }
  float number_f(const Node& n, const Range& r) const { return static_cast<float>(number(n, r)); }
  std::int64_t integer(const Node& n, std::int64_t lo, std::int64_t hi) const {
    const std::string allowed = "must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi);
    std::int64_t x = 0;
    if (n.v.is_number_unsigned()) {
      const auto u = n.v.get<std::uint64_t>();
      if (u > static_cast<std::uint64_t>(hi)) fail(n, allowed);
      x = static_cast<std::int64_t>(u);
    } else if (n.v.is_number_integer()) {
      x = n.v.get<std::int64_t>();
    } else {
      fail(n, allowed);
    }
    if (x < lo || x > hi) fail(n, allowed);
    return x;
  }
  std::string string(const Node& n, const char* what) const {
    if (!n.v.is_string()) fail(n, std::string("must be a string (") + what + ")");
    return n.v.get<std::string>();
  }
  bool boolean(const Node& n) const {
    if (!n.v.is_boolean()) fail(n, "must be true or false");
    return n.v.get<bool>();
  }
  static Range sign_range(Sign s) {
    switch (s) {
      case Sign::NonNegative: return {0, 1e30, false, false, ""};
      case Sign::Positive: return {0, 1e30, true, false, ""};
      case Sign::Any: break;
    }
    return {-1e30, 1e30, false, false, ""};
  }
  template <int N>
  glm::vec<N, float> vec(const Node& n, const Range& r, const char* what) const {
    if (!n.v.is_array() || n.v.size() != static_cast<std::size_t>(N)) {
      fail(n, "must be an array of " + std::to_string(N) + " numbers (" + what + ")");
    }
    glm::vec<N, float> out{};
    for (int i = 0; i < N; ++i) out[i] = number_f(element(n, static_cast<std::size_t>(i)), r);
    return out;
  }
  glm::vec3 vec3(const Node& n, const Range& r, const char* what) const { return vec<3>(n, r, what); }
  glm::vec3 colour(const Node& n, const char* what) const {
    return vec3(n, Range{0, 1e9, false, false, ""}, what);
  }
  glm::vec3 direction(const Node& n, const char* what) const {
    const glm::vec3 d = vec3(n, Range{-1e6, 1e6, false, false, ""}, what);
    if (!(glm::length(d) > 1e-9f)) fail(n, std::string("must be a non-zero vector (") + what + ")");
    return glm::normalize(d);
  }

 protected:
  std::string source_;
  std::vector<std::pair<std::string, std::string>> overridden_;  // JSON path -> "path=value"
};

}  // namespace fovea::render::json
