// SPDX-License-Identifier: Apache-2.0
// The lsl: spec, which needs no liblsl (so --check-config can judge it in any build).
#include <charconv>
#include <cstdio>
#include <stdexcept>

#include "lsl/lsl_outlet.h"
#include "sources/lsl/lsl_source.h"

namespace fovea::trackerd::lsl_source {

namespace {

std::invalid_argument bad(const std::string& spec, const std::string& why) {
  return std::invalid_argument("source \"" + spec + "\": " + why +
                               " (lsl[:NAME][?x=I&y=J&units=pixels|normalized&confidence=K&min_confidence=C])");
}

int index_of(const std::string& spec, const std::string& key, const std::string& value) {
  int v = -1;
  const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), v);
  if (ec != std::errc{} || end != value.data() + value.size() || v < 0 || v > 4095) {
    throw bad(spec, key + "=" + value + " is not a channel index 0..4095");
  }
  return v;
}

void parse_query(const std::string& spec, const std::string& query, LslSpec& s) {
  std::size_t at = 0;
  while (at <= query.size()) {
    const std::size_t amp = std::min(query.find('&', at), query.size());
    const std::string pair = query.substr(at, amp - at);
    const std::size_t eq = pair.find('=');
    if (eq == std::string::npos) throw bad(spec, "\"" + pair + "\" is not KEY=VALUE");
    const std::string key = pair.substr(0, eq), value = pair.substr(eq + 1);
    if (key == "x") s.x = index_of(spec, key, value);
    else if (key == "y") s.y = index_of(spec, key, value);
    else if (key == "confidence") s.confidence = index_of(spec, key, value);
    else if (key == "units") {
      if (value != "pixels" && value != "normalized") throw bad(spec, "units=" + value + "; allowed: pixels, normalized");
      s.units = value;
    } else if (key == "min_confidence") {
      double c = -1;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), c);
      if (ec != std::errc{} || end != value.data() + value.size() || !(c >= 0 && c <= 1)) {
        throw bad(spec, "min_confidence=" + value + " is not a number in 0..1");
      }
      s.min_confidence = c;
    } else {
      throw bad(spec, "unknown key \"" + key + "\"; allowed: x, y, units, confidence, min_confidence");
    }
    at = amp + 1;
  }
  if (s.x.has_value() != s.y.has_value()) throw bad(spec, "x= and y= go together");
}

}  // namespace

LslSpec parse_lsl_spec(const std::string& spec) {
  if (spec != "lsl" && !spec.starts_with("lsl:") && !spec.starts_with("lsl?")) throw bad(spec, "not an lsl source");
  LslSpec s;
  std::string rest = spec.substr(3);
  if (rest.starts_with(":")) rest = rest.substr(1);
  const std::size_t q = rest.find('?');
  s.name = rest.substr(0, q);
  if (q != std::string::npos) parse_query(spec, rest.substr(q + 1), s);
  if (s.name.size() > 255) throw bad(spec, "the stream name is longer than 255 bytes");
  return s;
}

std::string check_lsl_spec(const std::string& spec) {
  try {
    parse_lsl_spec(spec);
  } catch (const std::exception& e) {
    return e.what();
  }
  if (!lsl_available()) return "source \"" + spec + "\": " + lsl_library_info();
  return {};
}

double effective_min_confidence(const LslSpec& spec, bool has_confidence_channel) {
  if (spec.min_confidence) return *spec.min_confidence;
  return has_confidence_channel ? kDefaultMinConfidence : 0.0;
}

std::string unusable_channel_format(int format) {
  switch (format) {
    case 1: case 2: case 4: case 5: case 6: case 7: return {};
    case 3:
      return "its channels are strings (channel format string), which cannot carry gaze coordinates; fovea reads "
             "numeric streams (float32, double64, int8..int64)";
    case 0:
      return "its channel format is undefined, which cannot carry gaze coordinates; fovea reads numeric streams "
             "(float32, double64, int8..int64)";
    default:
      return "its channel format " + std::to_string(format) + " is not one liblsl defines";
  }
}

std::string LslSpec::to_string() const {
  std::string out = "lsl" + (name.empty() ? std::string() : ":" + name);
  std::string q;
  const auto add = [&q](const std::string& kv) { q += (q.empty() ? "?" : "&") + kv; };
  if (x) add("x=" + std::to_string(*x));
  if (y) add("y=" + std::to_string(*y));
  if (!units.empty()) add("units=" + units);
  if (confidence) add("confidence=" + std::to_string(*confidence));
  if (min_confidence) {
    char c[32];
    std::snprintf(c, sizeof c, "%g", *min_confidence);
    add(std::string("min_confidence=") + c);
  }
  return out + q;
}

}  // namespace fovea::trackerd::lsl_source
