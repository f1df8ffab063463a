// SPDX-License-Identifier: Apache-2.0
#include "scene/json_path.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <set>

namespace fovea::render::json {

namespace {

bool is_identifier(std::string_view key) {
  if (key.empty()) return false;
  return std::all_of(key.begin(), key.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0u : 1u)});
      diag = up;
    }
  }
  return row[b.size()];
}

// // Parsing: a SAX handler that builds the document while tracking the JSON path, so that duplicate
// keys and numbers that overflow a double (1e999) are reported at their path. nlohmann's DOM
// parser keeps the last of duplicate keys silently and reports overflow without a path.

class DocumentBuilder final : public nlohmann::json_sax<Json> {
 public:
  explicit DocumentBuilder(std::string source) : source_(std::move(source)) {}

  Json& document() { return root_; }
  const std::string& error() const { return error_; }

  bool null() override { return scalar(Json(nullptr)); }
  bool boolean(bool v) override { return scalar(Json(v)); }
  bool number_integer(number_integer_t v) override { return scalar(Json(v)); }
  bool number_unsigned(number_unsigned_t v) override { return scalar(Json(v)); }
  bool number_float(number_float_t v, const string_t& /*text*/) override { return scalar(Json(v)); }
  bool string(string_t& v) override { return scalar(Json(v)); }
  bool binary(binary_t& /*v*/) override { return scalar(Json(nullptr)); }  // not produced by the JSON parser

  bool start_object(std::size_t /*elements*/) override {
    if (too_deep()) return false;
    stack_.push_back(Frame{put(Json::object()), false, 0, {}, {}});
    return true;
  }
  bool key(string_t& k) override {
    Frame& f = stack_.back();
    if (!f.keys.insert(k).second) {
      error_ = source_ + ": " + path(stack_.size() - 1) + key_suffix(k) +
               ": duplicate key (each key may appear once in an object)";
      return false;
    }
    f.key = k;
    return true;
  }
  bool end_object() override { return end(); }
  bool start_array(std::size_t /*elements*/) override {
    if (too_deep()) return false;
    stack_.push_back(Frame{put(Json::array()), true, 0, {}, {}});
    return true;
  }
  bool end_array() override { return end(); }

  bool parse_error(std::size_t position, const std::string& last_token,
                   const nlohmann::detail::exception& ex) override {
    if (ex.id == 406) {  // out_of_range.406: number overflow
      error_ = source_ + ": " + path() + " = " + last_token +
               ": number overflows a double; must be a finite number (JSON has no NaN or Infinity)";
      return false;
    }
    std::string what = ex.what();
    if (const auto close = what.find("] "); what.starts_with("[json.exception") && close != std::string::npos) {
      what = what.substr(close + 2);
    }
    error_ = source_ + ": invalid JSON (byte " + std::to_string(position) + "): " + what;
    return false;
  }

 private:
  struct Frame {
    Json* node;
    bool is_array;
    std::size_t index;
    std::string key;
    std::set<std::string> keys;
  };

  // A scene file nests a handful of levels; a hostile one nested 100,000 deep overflowed the stack
  // (issue 23 item 7). The path in the message stops after a few levels.
  bool too_deep() {
    if (stack_.size() < kMaxJsonDepth) return false;
    error_ = source_ + ": " + path(6) + "...: nested deeper than " + std::to_string(kMaxJsonDepth) +
             " levels (a scene file nests a few)";
    return true;
  }

  // The path of the value being parsed, through the first `depth` open containers (all by default).
  std::string path(std::size_t depth = SIZE_MAX) const {
    std::string p = "$";
    for (std::size_t i = 0; i < std::min(depth, stack_.size()); ++i) {
      const Frame& f = stack_[i];
      p += f.is_array ? index_suffix(f.index) : key_suffix(f.key);
    }
    return p;
  }
  // Places a value at the current position. Pointers into the parent stay valid because the parent
  // is not modified again until this child is complete.
  Json* put(Json&& v) {
    if (stack_.empty()) {
      root_ = std::move(v);
      return &root_;
    }
    Frame& f = stack_.back();
    if (f.is_array) {
      f.node->push_back(std::move(v));
      return &f.node->back();
    }
    Json& slot = (*f.node)[f.key];
    slot = std::move(v);
    return &slot;
  }
  void element_done() {
    if (!stack_.empty() && stack_.back().is_array) ++stack_.back().index;
  }
  bool scalar(Json&& v) {
    put(std::move(v));
    element_done();
    return true;
  }
  bool end() {
    stack_.pop_back();
    element_done();
    return true;
  }

  std::string source_;
  Json root_;
  std::vector<Frame> stack_;
  std::string error_;
};

}  // namespace

std::string format_number(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::array<char, 64> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), res.ptr);
}

std::string format_number(float v) {
  if (!std::isfinite(v)) return format_number(static_cast<double>(v));
  std::array<char, 32> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return std::string(buf.data(), res.ptr);
}

std::string describe(const Json& v) {
  if (v.is_number_float()) return format_number(v.get<double>());
  std::string s = v.dump();
  if (s.size() > 80) s = s.substr(0, 77) + "...";
  return s;
}

std::string key_suffix(std::string_view key) {
  if (is_identifier(key)) return "." + std::string(key);
  return "[" + Json(std::string(key)).dump() + "]";
}

std::string index_suffix(std::size_t i) { return "[" + std::to_string(i) + "]"; }

std::string join(const Keys& keys) {
  std::string out;
  for (const std::string_view k : keys) {
    if (!out.empty()) out += ", ";
    out += k;
  }
  return out;
}

std::string unknown_field_message(std::string_view key, const Keys& allowed) {
  std::string msg = "unknown field; allowed fields here: " + join(allowed);
  std::string_view best;
  std::size_t best_d = 3;  // suggest only close matches
  for (const std::string_view k : allowed) {
    const std::size_t d = edit_distance(key, k);
    if (d < best_d) {
      best_d = d;
      best = k;
    }
  }
  if (!best.empty()) msg += " (did you mean '" + std::string(best) + "'?)";
  return msg;
}


Json parse_document(const std::string& text, const std::string& source) {
  DocumentBuilder builder(source);
  const bool ok = Json::sax_parse(text, &builder);
  if (!ok) {
    throw SceneError(builder.error().empty() ? source + ": invalid JSON" : builder.error());
  }
  Json doc = std::move(builder.document());
  if (!doc.is_object()) throw SceneError(source + ": $ = " + describe(doc) + ": a scene file must hold a JSON object");
  return doc;
}

}  // namespace fovea::render::json
