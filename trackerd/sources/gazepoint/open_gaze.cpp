// SPDX-License-Identifier: Apache-2.0
#include "sources/gazepoint/open_gaze.h"

#include <charconv>
#include <cmath>
#include <stdexcept>

#include "fovea/protocol/bounded_file.h"
#include "source_api/spec_check.h"
#include "sources/network_common.h"

namespace fovea::trackerd::gazepoint {

namespace {

constexpr std::size_t kMaxAttributes = 64;

bool name_char(char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; }
bool space(char c) { return c == ' ' || c == '\t'; }

std::string_view skip_space(std::string_view s) {
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  return s;
}

// The run of name characters at the start of `s` (empty if none), removed from `s`.
std::string_view take_name(std::string_view& s) {
  std::size_t n = 0;
  while (n < s.size() && name_char(s[n])) ++n;
  const std::string_view name = s.substr(0, n);
  s.remove_prefix(n);
  return name;
}

bool number_text(const std::string& text, double& out) {
  const char* end = text.data() + text.size();
  const auto r = std::from_chars(text.data(), end, out);
  return r.ec == std::errc{} && r.ptr == end && std::isfinite(out);
}

template <typename Int>
bool integer_text(const std::string& text, Int& out) {
  const char* end = text.data() + text.size();
  const auto r = std::from_chars(text.data(), end, out);
  return r.ec == std::errc{} && r.ptr == end;
}

}  // namespace

std::string GazepointSpec::to_string() const { return host + ":" + std::to_string(port); }

GazepointSpec parse_gazepoint_spec(const std::string& spec) {
  const std::string prefix = "gazepoint:";
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("source " + protocol::escape_for_log(spec) + ": " + why +
                                 "; expected gazepoint:HOST[:PORT] (Gazepoint Control's Open Gaze API, port 4242)");
  };
  if (spec.rfind(prefix, 0) != 0) throw bad("not a gazepoint source");
  const net::HostPort hp = net::parse_host_port(spec.substr(prefix.size()), kDefaultPort, bad);
  return GazepointSpec{hp.host, hp.port};
}

std::string check_gazepoint_spec(const std::string& spec) { return spec_problem(parse_gazepoint_spec, spec); }

const std::string* Element::attribute(std::string_view key) const {
  for (const auto& [k, v] : attributes) {
    if (k == key) return &v;
  }
  return nullptr;
}

std::optional<Element> parse_element(std::string_view line, std::string& error) {
  const auto fail = [&](const std::string& why) -> std::optional<Element> {
    error = why;
    return std::nullopt;
  };
  if (line.size() > kMaxLineBytes) return fail("a line of " + std::to_string(line.size()) + " bytes (at most " + std::to_string(kMaxLineBytes) + ")");
  std::string_view s = skip_space(line);
  if (s.empty() || s.front() != '<') return fail("not an XML element");
  s.remove_prefix(1);
  Element e;
  e.name = std::string(take_name(s));
  if (e.name.empty()) return fail("an element without a name");
  while (true) {
    const std::string_view before = s;
    s = skip_space(s);
    if (s.rfind("/>", 0) == 0) {
      if (!skip_space(s.substr(2)).empty()) return fail("text after the element's end");
      return e;
    }
    if (s.empty()) return fail(e.name + ": the element does not end (no \"/>\")");
    if (s.size() == before.size()) return fail(e.name + ": no space before an attribute");
    const std::string_view key = take_name(s);
    if (key.empty()) return fail(e.name + ": \"" + protocol::escape_for_log(std::string(s.substr(0, 16))) + "\" is not an attribute");
    if (s.rfind("=\"", 0) != 0) return fail(e.name + ": attribute " + std::string(key) + " has no quoted value");
    s.remove_prefix(2);
    const std::size_t close = s.find('"');
    if (close == std::string_view::npos) return fail(e.name + ": attribute " + std::string(key) + "'s value does not end");
    const std::string_view value = s.substr(0, close);
    for (const char c : value) {
      if (c == '<' || c == '&' || static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
        return fail(e.name + ": attribute " + std::string(key) + " holds a character that is not allowed");
      }
    }
    if (e.attribute(key) != nullptr) return fail(e.name + ": attribute " + std::string(key) + " given twice");
    if (e.attributes.size() == kMaxAttributes) return fail(e.name + ": more than " + std::to_string(kMaxAttributes) + " attributes");
    e.attributes.emplace_back(std::string(key), std::string(value));
    s.remove_prefix(close + 1);
  }
}

std::optional<Record> parse_record(const Element& rec, std::string& error) {
  const auto fail = [&](const std::string& why) -> std::optional<Record> {
    error = "REC: " + why;
    return std::nullopt;
  };
  if (rec.name != "REC") return fail("not a data record but " + rec.name);
  Record r;
  // A number, or what is wrong with it; absent: nullopt and no error.
  std::string problem;
  const auto number = [&](const char* key) -> std::optional<double> {
    const std::string* text = rec.attribute(key);
    if (text == nullptr) return std::nullopt;
    double v = 0;
    if (!number_text(*text, v)) {
      problem = std::string(key) + "=\"" + protocol::escape_for_log(*text, 24) + "\" is not a finite number";
      return std::nullopt;
    }
    return v;
  };
  const auto flag = [&](const char* key) -> std::optional<bool> {
    const std::string* text = rec.attribute(key);
    if (text == nullptr) return std::nullopt;
    if (*text != "0" && *text != "1") {
      problem = std::string(key) + "=\"" + protocol::escape_for_log(*text, 24) + "\" is not 0 or 1";
      return std::nullopt;
    }
    return *text == "1";
  };
  const auto x = number("BPOGX");
  const auto y = number("BPOGY");
  const auto valid = flag("BPOGV");
  if (!problem.empty()) return fail(problem);
  if (!x || !y || !valid) return fail("BPOGX, BPOGY and BPOGV are required (ENABLE_SEND_POG_BEST)");
  r.best_x = *x, r.best_y = *y, r.best_valid = *valid;
  if (r.best_x < -1 || r.best_x > 2 || r.best_y < -1 || r.best_y > 2) {
    return fail("point of gaze " + std::to_string(r.best_x) + ", " + std::to_string(r.best_y) + " is beyond -1..2 screens");
  }
  if (const std::string* cnt = rec.attribute("CNT")) {
    std::uint64_t v = 0;
    if (!integer_text(*cnt, v)) return fail("CNT=\"" + protocol::escape_for_log(*cnt, 24) + "\" is not a counter");
    r.counter = v;
  }
  if (const std::string* tick = rec.attribute("TIME_TICK")) {
    std::int64_t v = 0;
    if (!integer_text(*tick, v)) return fail("TIME_TICK=\"" + protocol::escape_for_log(*tick, 24) + "\" is not an integer");
    r.time_tick = v;
  }
  r.time_s = number("TIME");
  if (!problem.empty()) return fail(problem);
  if (r.time_s && (*r.time_s < 0 || *r.time_s > 1e9)) return fail("TIME=" + std::to_string(*r.time_s) + " s is outside 0..1e9");
  const auto pupil = [&](const char* diameter, const char* validity) -> std::optional<double> {
    const auto d = number(diameter);
    const auto v = flag(validity);
    if (!d || !v || !*v || *d <= 0 || *d > 0.02) return std::nullopt;  // a pupil is 1..9 mm; metres on the wire
    return *d * 1000;
  };
  r.left_pupil_mm = pupil("LPUPILD", "LPUPILV");
  r.right_pupil_mm = pupil("RPUPILD", "RPUPILV");
  if (!problem.empty()) return fail(problem);
  // An eye's point of gaze, kept only when valid and within the same -1..2 screens as the best one.
  const auto eye_pog = [&](const char* kx, const char* ky, const char* kv) -> std::optional<Record::Point> {
    const auto ex = number(kx), ey = number(ky);
    const auto ev = flag(kv);
    if (!ex || !ey || !ev || !*ev) return std::nullopt;
    if (*ex < -1 || *ex > 2 || *ey < -1 || *ey > 2) {
      problem = std::string(kx) + ", " + ky + " = " + std::to_string(*ex) + ", " + std::to_string(*ey) +
                " is beyond -1..2 screens";
      return std::nullopt;
    }
    return Record::Point{*ex, *ey};
  };
  r.left_pog = eye_pog("LPOGX", "LPOGY", "LPOGV");
  r.right_pog = eye_pog("RPOGX", "RPOGY", "RPOGV");
  if (!problem.empty()) return fail(problem);
  return r;
}

std::vector<std::string> start_commands() {
  std::vector<std::string> out;
  for (const char* id : {"ENABLE_SEND_COUNTER", "ENABLE_SEND_TIME", "ENABLE_SEND_POG_BEST", "ENABLE_SEND_POG_LEFT",
                         "ENABLE_SEND_POG_RIGHT", "ENABLE_SEND_EYE_LEFT", "ENABLE_SEND_EYE_RIGHT"}) {
    out.push_back(std::string("<SET ID=\"") + id + "\" STATE=\"1\" />\r\n");
  }
  out.push_back("<GET ID=\"SCREEN_SIZE\" />\r\n");
  out.push_back("<SET ID=\"ENABLE_SEND_DATA\" STATE=\"1\" />\r\n");
  return out;
}

std::optional<std::pair<std::uint32_t, std::uint32_t>> screen_size(const Element& ack) {
  const std::string* id = ack.attribute("ID");
  if (ack.name != "ACK" || id == nullptr || *id != "SCREEN_SIZE") return std::nullopt;
  const std::string* w = ack.attribute("WIDTH");
  const std::string* h = ack.attribute("HEIGHT");
  std::uint32_t width = 0, height = 0;
  if (w == nullptr || h == nullptr || !integer_text(*w, width) || !integer_text(*h, height)) return std::nullopt;
  if (width == 0 || height == 0 || width > 65536 || height > 65536) return std::nullopt;
  return std::make_pair(width, height);
}

}  // namespace fovea::trackerd::gazepoint
