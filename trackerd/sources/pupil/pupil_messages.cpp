// SPDX-License-Identifier: Apache-2.0
#include "sources/pupil/pupil_messages.h"

#include <msgpack.hpp>

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string_view>

#include "fovea/protocol/bounded_file.h"
#include "source_api/spec_check.h"
#include "sources/network_common.h"

namespace fovea::trackerd::pupil {

namespace {

// Generous for a gaze datum or a surface event (a surface holds the gaze of one world frame: a few
// dozen entries), small enough that no payload can make us allocate much.
const msgpack::unpack_limit kLimits(/*array=*/4096, /*map=*/256, /*str=*/4096, /*bin=*/4096, /*ext=*/0, /*depth=*/16);
constexpr double kMaxTimestampS = 1e10;  // Pupil time is seconds since some start: far below
constexpr double kMaxCoordinate = 1e3;   // normalised units; beyond is not a gaze point

class Refused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

msgpack::object_handle unpack_payload(std::span<const std::uint8_t> payload) {
  if (payload.size() > kMaxPayloadBytes) {
    throw Refused("a payload of " + std::to_string(payload.size()) + " bytes (at most " +
                  std::to_string(kMaxPayloadBytes) + ")");
  }
  std::size_t offset = 0;
  msgpack::object_handle oh;
  try {
    oh = msgpack::unpack(reinterpret_cast<const char*>(payload.data()), payload.size(), offset, nullptr, nullptr,
                         kLimits);
  } catch (const std::exception& e) {
    throw Refused(std::string("not msgpack (") + e.what() + ")");
  }
  if (offset != payload.size()) throw Refused("bytes after the msgpack object");
  if (oh.get().type != msgpack::type::MAP) throw Refused("the payload is not a map");
  return oh;
}

const msgpack::object* find(const msgpack::object& map, std::string_view key) {
  if (map.type != msgpack::type::MAP) return nullptr;
  for (std::uint32_t i = 0; i < map.via.map.size; ++i) {
    const msgpack::object_kv& kv = map.via.map.ptr[i];
    if (kv.key.type == msgpack::type::STR && std::string_view(kv.key.via.str.ptr, kv.key.via.str.size) == key) {
      return &kv.val;
    }
  }
  return nullptr;
}

std::optional<double> as_number(const msgpack::object& o) {
  switch (o.type) {
    case msgpack::type::FLOAT32:
    case msgpack::type::FLOAT64:
      return std::isfinite(o.via.f64) ? std::optional<double>(o.via.f64) : std::nullopt;
    case msgpack::type::POSITIVE_INTEGER:
      return static_cast<double>(o.via.u64);
    case msgpack::type::NEGATIVE_INTEGER:
      return static_cast<double>(o.via.i64);
    default:
      return std::nullopt;
  }
}

double number(const msgpack::object& map, std::string_view key, double limit) {
  const msgpack::object* o = find(map, key);
  if (o == nullptr) throw Refused(std::string(key) + " is missing");
  const auto v = as_number(*o);
  if (!v || std::abs(*v) > limit) throw Refused(std::string(key) + " is not a finite number within +-" + std::to_string(limit));
  return *v;
}

// Fields every gaze point has: norm_pos [x, y], confidence, timestamp (or base_data's time).
PupilGaze gaze_point(const msgpack::object& datum) {
  if (datum.type != msgpack::type::MAP) throw Refused("a gaze entry is not a map");
  PupilGaze g;
  const msgpack::object* pos = find(datum, "norm_pos");
  if (pos == nullptr) throw Refused("norm_pos is missing");
  if (pos->type != msgpack::type::ARRAY || pos->via.array.size != 2) throw Refused("norm_pos is not [x, y]");
  const auto x = as_number(pos->via.array.ptr[0]);
  const auto y = as_number(pos->via.array.ptr[1]);
  if (!x || !y || std::abs(*x) > kMaxCoordinate || std::abs(*y) > kMaxCoordinate) {
    throw Refused("norm_pos does not hold two finite numbers");
  }
  g.x = *x, g.y_up = *y;
  g.confidence = number(datum, "confidence", 1.0);
  if (g.confidence < 0) throw Refused("confidence is negative");
  g.timestamp = number(datum, "timestamp", kMaxTimestampS);
  return g;
}

template <typename F>
auto refusing(std::string& error, F&& parse) -> decltype(std::optional(parse())) {
  try {
    return parse();
  } catch (const Refused& e) {
    error = e.what();
    return std::nullopt;
  }
}

}  // namespace

std::string PupilSpec::to_string() const { return host + ":" + std::to_string(port); }

PupilSpec parse_pupil_spec(const std::string& spec) {
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("source " + protocol::escape_for_log(spec) + ": " + why +
                                 "; expected pupil:HOST[:PORT][?surface=NAME|gaze=scene&min_confidence=C] (Pupil Capture's "
                                 "Pupil Remote, port 50020)");
  };
  const std::string prefix = "pupil:";
  if (spec.rfind(prefix, 0) != 0) throw bad("not a pupil source");
  std::string rest = spec.substr(prefix.size());
  PupilSpec out;
  if (const std::size_t q = rest.find('?'); q != std::string::npos) {
    std::string_view options(rest.data() + q + 1, rest.size() - q - 1);
    while (!options.empty()) {
      const std::size_t amp = options.find('&');
      const std::string_view kv = options.substr(0, amp);
      options = amp == std::string_view::npos ? std::string_view() : options.substr(amp + 1);
      const std::size_t eq = kv.find('=');
      const std::string key(kv.substr(0, eq));
      const std::string value(eq == std::string_view::npos ? std::string_view() : kv.substr(eq + 1));
      if (key == "surface" && !value.empty() && value.size() <= 64 && value.find_first_of(" \t\r\n") == std::string::npos) {
        out.surface = value;
      } else if (key == "gaze" && (value == "scene" || value == "surface")) {
        out.scene_gaze = value == "scene";
      } else if (key == "min_confidence") {
        double c = -1;
        const auto r = std::from_chars(value.data(), value.data() + value.size(), c);
        if (r.ec != std::errc{} || r.ptr != value.data() + value.size() || !(c >= 0 && c <= 1)) {
          throw bad("min_confidence \"" + protocol::escape_for_log(value) + "\" is not a number in 0..1");
        }
        out.min_confidence = c;
      } else {
        throw bad("\"" + protocol::escape_for_log(std::string(kv)) +
                  "\" is not surface=NAME, gaze=scene|surface or min_confidence=C");
      }
    }
    if (out.scene_gaze && out.surface != "screen") throw bad("gaze=scene uses no surface: drop surface=");
    rest.resize(q);
  }
  const net::HostPort hp = net::parse_host_port(rest, kDefaultPort, bad);
  out.host = hp.host;
  out.port = hp.port;
  return out;
}

std::string check_pupil_spec(const std::string& spec) { return spec_problem(parse_pupil_spec, spec); }

std::optional<std::vector<PupilGaze>> parse_surface_payload(std::span<const std::uint8_t> payload,
                                                            const std::string& surface, std::string& error) {
  return refusing(error, [&] {
    const msgpack::object_handle oh = unpack_payload(payload);
    const msgpack::object& m = oh.get();
    const msgpack::object* name = find(m, "name");
    if (name == nullptr || name->type != msgpack::type::STR ||
        std::string_view(name->via.str.ptr, name->via.str.size) != surface) {
      throw Refused("not the surface \"" + surface + "\"");
    }
    const msgpack::object* entries = find(m, "gaze_on_surfaces");
    if (entries == nullptr || entries->type != msgpack::type::ARRAY) throw Refused("gaze_on_surfaces is not a list");
    std::vector<PupilGaze> out;
    for (std::uint32_t i = 0; i < entries->via.array.size; ++i) {
      const msgpack::object& e = entries->via.array.ptr[i];
      PupilGaze g = gaze_point(e);
      const msgpack::object* on = find(e, "on_surf");
      if (on == nullptr) throw Refused("on_surf is missing");
      if (on->type == msgpack::type::BOOLEAN) {
        g.on_surface = on->via.boolean;
      } else if (on->type == msgpack::type::POSITIVE_INTEGER && on->via.u64 <= 1) {
        g.on_surface = on->via.u64 == 1;
      } else {
        throw Refused("on_surf is not a boolean");
      }
      out.push_back(g);
    }
    return out;
  });
}

std::optional<PupilGaze> parse_gaze_payload(std::span<const std::uint8_t> payload, std::string& error) {
  return refusing(error, [&] {
    const msgpack::object_handle oh = unpack_payload(payload);
    return gaze_point(oh.get());
  });
}

std::optional<std::uint16_t> parse_port_reply(const std::string& reply) {
  unsigned port = 0;
  const auto r = std::from_chars(reply.data(), reply.data() + reply.size(), port);
  if (reply.empty() || r.ec != std::errc{} || r.ptr != reply.data() + reply.size() || port < 1 || port > 65535) {
    return std::nullopt;
  }
  return static_cast<std::uint16_t>(port);
}

std::optional<double> parse_time_reply(const std::string& reply) {
  double t = 0;
  const auto r = std::from_chars(reply.data(), reply.data() + reply.size(), t);
  if (reply.empty() || r.ec != std::errc{} || r.ptr != reply.data() + reply.size() || !std::isfinite(t) ||
      std::abs(t) > kMaxTimestampS) {
    return std::nullopt;
  }
  return t;
}

}  // namespace fovea::trackerd::pupil
