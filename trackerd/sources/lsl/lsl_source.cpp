// SPDX-License-Identifier: Apache-2.0
// The lsl: source through liblsl (built only when find_package(LSL) found it).
#include <lsl_cpp.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include "fovea/protocol/clock.h"
#include "lsl/lsl_outlet.h"
#include "sources/lsl/lsl_source.h"
#include "sources/network_common.h"

namespace fovea::trackerd::lsl_source {

namespace {

constexpr double kResolveWaitS = 5.0;

std::vector<lsl::stream_info> resolve(const LslSpec& spec, double wait_s) {
  return spec.name.empty() ? lsl::resolve_stream("type", "Gaze", 1, wait_s) : lsl::resolve_stream("name", spec.name, 1, wait_s);
}

bool is_unit(const std::string& unit, std::initializer_list<const char*> names) {
  for (const char* n : names)
    if (unit == n) return true;
  return false;
}

// The channels from desc/channels (XDF gaze meta-data), else from the spec; nullopt with `why`.
std::optional<ChannelMap> map_channels(lsl::stream_info& info, const LslSpec& spec, std::string& why) {
  ChannelMap m;
  int norm_x = -1, norm_y = -1, px_x = -1, px_y = -1, i = 0;
  for (lsl::xml_element ch = info.desc().child("channels").child("channel"); !ch.empty();
       ch = ch.next_sibling("channel"), ++i) {
    const std::string type = ch.child_value("type"), unit = ch.child_value("unit"), eye = ch.child_value("eye");
    const bool normalized = is_unit(unit, {"normalized", "norm", "normalised"});
    const bool pixels = is_unit(unit, {"pixels", "pixel", "px"});
    if (type == "ScreenX" && normalized && norm_x < 0) norm_x = i;
    if (type == "ScreenY" && normalized && norm_y < 0) norm_y = i;
    if (type == "ScreenX" && pixels && px_x < 0) px_x = i;
    if (type == "ScreenY" && pixels && px_y < 0) px_y = i;
    if (type == "Confidence" && m.confidence < 0) m.confidence = i;
    if (type == "Validity" && m.validity < 0) m.validity = i;
    if ((type == "Diameter" || type == "PupilDiameter") && is_unit(unit, {"mm", "millimeters"})) {
      if (eye == "left" && m.pupil_left < 0) m.pupil_left = i;
      if (eye == "right" && m.pupil_right < 0) m.pupil_right = i;
    }
  }
  if (spec.confidence) m.confidence = *spec.confidence;
  if (spec.x) {
    m.x = *spec.x, m.y = *spec.y, m.pixels = spec.units == "pixels", m.origin = "spec";
  } else if (norm_x >= 0 && norm_y >= 0) {
    m.x = norm_x, m.y = norm_y, m.origin = "metadata";
  } else if (px_x >= 0 && px_y >= 0) {
    m.x = px_x, m.y = px_y, m.pixels = true, m.origin = "metadata";
  } else {
    why = "the stream's metadata (desc/channels) names no ScreenX/ScreenY channels with unit normalized or "
          "pixels; give their indices: lsl:" + spec.name + "?x=I&y=J&units=pixels|normalized";
    return std::nullopt;
  }
  const int n = info.channel_count();
  for (const int c : {m.x, m.y, m.confidence, m.validity, m.pupil_left, m.pupil_right}) {
    if (c >= n) {
      why = "channel index " + std::to_string(c) + " is beyond the stream's " + std::to_string(n) + " channels";
      return std::nullopt;
    }
  }
  return m;
}

class LslSource final : public net::ReaderSource {
 public:
  LslSource(LslSpec spec, protocol::DisplayGeometry display, double rate, std::optional<lsl::stream_info> found)
      : ReaderSource(display, rate), spec_(std::move(spec)), found_(std::move(found)) {
    start_reader([this] { run(); });
  }
  ~LslSource() override { stop_reader(); }

  std::string description() const override { return spec_.to_string(); }
  std::string status_detail() const override {
    // The counts as they are now (the stream's line is refreshed with its clock, every 2 s): the
    // stop line must count the loss that ended the stream.
    std::string out;
    {
      std::lock_guard lock(mutex_);
      out = stream_text_.empty() ? std::string("LSL: no stream read yet") : stream_text_;
    }
    out += fmt::format(", {} samples, {} dropouts, {} losses", samples_.load(), dropouts_.load(), lost_.load());
    if (const double c = min_confidence_.load(); c > 0) {
      out += fmt::format(", {} below confidence {:g} (invalid)", low_confidence_.load(), c);
    }
    if (out_of_order_ > 0) out += fmt::format(", {} out of order (dropped)", out_of_order_.load());
    return out + arrivals_.status();
  }

 private:
  void run() {
    while (!stopping()) {
      std::optional<lsl::stream_info> info = std::move(found_);
      found_.reset();
      if (!info) info = resolve_once();
      if (!info) continue;
      try {
        read(*info);
      } catch (const lsl::lost_error&) {
        ++lost_;
        problem_.set(description() + ": the stream was lost; waiting for it to come back");
      } catch (const std::exception& e) {
        problem_.set(description() + ": " + e.what());
        std::this_thread::sleep_for(std::chrono::seconds(1));
      }
    }
  }

  std::optional<lsl::stream_info> resolve_once() {
    const auto streams = resolve(spec_, 1.0);
    if (streams.empty()) {
      problem_.set(description() + ": no such LSL stream (" +
                   (spec_.name.empty() ? std::string("none of type Gaze") : "none named \"" + spec_.name + "\"") +
                   "); waiting for it");
      return std::nullopt;
    }
    return streams.front();
  }

  void read(const lsl::stream_info& found) {
    // recover = false: a restarted app is a new outlet (new uid); resolving again by name finds it.
    lsl::stream_inlet inlet(found, 360, 0, false);
    inlet.set_postprocessing(lsl::post_clocksync);
    lsl::stream_info info = inlet.info(5.0);
    std::string why = unusable_channel_format(info.channel_format());
    if (!why.empty()) why = "\"" + info.name() + "\": " + why;
    const std::optional<ChannelMap> map = why.empty() ? map_channels(info, spec_, why) : std::nullopt;
    if (!map) {
      problem_.set(description() + ": " + why);
      std::this_thread::sleep_for(std::chrono::seconds(1));
      return;
    }
    min_confidence_ = effective_min_confidence(spec_, map->confidence >= 0);
    inlet.open_stream(5.0);
    last_sample_ns_ = protocol::monotonic_ns();
    lookup_missed_ = false;
    spdlog::info("{}: reading \"{}\" ({}) from {}, {} channels at {} Hz; x/y {} (channels {}, {}) from the {}; {}",
                 description(), info.name(), info.type(), info.hostname(), info.channel_count(), info.nominal_srate(),
                 map->pixels ? "pixels" : "normalized", map->x, map->y, map->origin, confidence_rule(*map));
    problem_.set({});
    pull(inlet, info, *map);
  }

  void pull(lsl::stream_inlet& inlet, const lsl::stream_info& info, const ChannelMap& map) {
    std::vector<float> v;
    double offset = lsl_clock_minus_monotonic_s(), correction = 0;
    std::int64_t next_check_ns = 0;
    while (!stopping()) {
      const double ts = inlet.pull_sample(v, 0.1);
      const std::int64_t now = protocol::monotonic_ns();
      if (now >= next_check_ns) {  // every 2 s: the clocks, and the status line
        offset = lsl_clock_minus_monotonic_s();
        try {
          correction = inlet.time_correction(0.0);
        } catch (const lsl::timeout_error&) {
        }
        next_check_ns = now + 2'000'000'000;
        publish_status(info, correction);
      }
      if (ts == 0.0) {
        if (replaced_after_silence(info, now)) return;
        continue;
      }
      last_sample_ns_ = now;
      lookup_missed_ = false;
      // The arrival rules (arrival_guard.h): the cap on the declared rate, a flood's samples timed
      // by their arrival, no time after it. liblsl's clock correction is not fed by samples: a
      // flood has nothing of it to reset.
      const net::ArrivalGuard::Admission a = arrivals_.admit(now);
      if (!a.keep) continue;
      const auto outlet_ns = static_cast<std::int64_t>(std::llround((ts - offset) * 1e9));
      const std::int64_t t_ns = a.flooding ? now : arrivals_.not_after_arrival(outlet_ns, now);
      // Published times never decrease (a flood's arrival stamps run ahead of the outlet's own, and
      // an inlet that reconnected may deliver a stale stretch): an earlier one is dropped, counted.
      if (t_ns < last_t_ns_) {
        ++out_of_order_;
        continue;
      }
      note_dropout(t_ns, info.nominal_srate());
      queue_.push(to_sample(v, map, t_ns), now);
      ++samples_;
    }
  }

  // What the start's log line says of confidence: which channel, and the threshold with its origin.
  std::string confidence_rule(const ChannelMap& map) const {
    if (map.confidence < 0) {
      return spec_.min_confidence && *spec_.min_confidence > 0
                 ? fmt::format("no confidence channel: min_confidence={:g} has nothing to gate", *spec_.min_confidence)
                 : std::string("no confidence channel");
    }
    if (!spec_.min_confidence) {
      return fmt::format("confidence in channel {}: gaze below {:g} is invalid (the default for a stream with "
                         "confidence; min_confidence=C sets another, min_confidence=0 turns it off)",
                         map.confidence, min_confidence_.load());
    }
    if (min_confidence_ > 0) {
      return fmt::format("confidence in channel {}: gaze below {:g} is invalid (min_confidence)", map.confidence,
                         min_confidence_.load());
    }
    return fmt::format("confidence in channel {}, not gated (min_confidence=0)", map.confidence);
  }

  protocol::GazeSample to_sample(const std::vector<float>& v, const ChannelMap& map, std::int64_t t_ns) {
    protocol::GazeSample s;
    s.tracker_time_ns = t_ns;
    double x = v[static_cast<std::size_t>(map.x)], y = v[static_cast<std::size_t>(map.y)];
    if (map.pixels) {
      x /= static_cast<double>(display_.width_px);
      y /= static_cast<double>(display_.height_px);
    }
    const float confidence = map.confidence >= 0 ? v[static_cast<std::size_t>(map.confidence)] : 1.0f;
    s.confidence = std::isfinite(confidence) ? std::clamp(confidence, 0.0f, 1.0f) : 0.0f;
    bool valid = std::isfinite(x) && std::isfinite(y) && std::abs(x) < 1e3 && std::abs(y) < 1e3;
    if (map.validity >= 0 && !(v[static_cast<std::size_t>(map.validity)] > 0.5f)) valid = false;
    if (static_cast<double>(s.confidence) < min_confidence_.load()) {
      valid = false;
      ++low_confidence_;
    }
    if (valid) {
      s.flags = protocol::kGazeValid;
      s.x = static_cast<float>(x), s.y = static_cast<float>(y);
      const protocol::Degrees d = protocol::normalized_to_degrees(display_, {x, y});
      s.x_deg = static_cast<float>(d.x), s.y_deg = static_cast<float>(d.y);
    }
    const auto pupil = [&](int c, protocol::EyeData& e) {
      if (c < 0) return;
      const float mm = v[static_cast<std::size_t>(c)];
      if (std::isfinite(mm) && mm > 0 && mm < 20) {
        e.flags |= protocol::kEyePupilValid;
        e.pupil_diameter_mm = mm;
      }
    };
    pupil(map.pupil_left, s.left);
    pupil(map.pupil_right, s.right);
    return s;
  }

  // liblsl notices a closed outlet only through its watchdog (many seconds), so after 1 s without a
  // sample the stream is looked up again: there under a new uid (the app restarted), it is lost and
  // the reader resolves it anew; the same stream, merely paused, is read on. Not found at all, it is
  // lost only when a second lookup a second later agrees: on a loaded host a lookup can miss a
  // stream that is there, and a false loss drops the connection to a live outlet.
  bool replaced_after_silence(const lsl::stream_info& info, std::int64_t now) {
    if (now - last_sample_ns_ < 1'000'000'000 || now - last_lookup_ns_ < 1'000'000'000) return false;
    last_lookup_ns_ = now;
    const auto streams = resolve(spec_, 0.5);
    const bool same = std::any_of(streams.begin(), streams.end(), [&](const lsl::stream_info& s) { return s.uid() == info.uid(); });
    const bool missed_before = lookup_missed_;
    lookup_missed_ = streams.empty();
    if (same || (streams.empty() && !missed_before)) return false;
    lookup_missed_ = false;
    ++lost_;
    problem_.set(description() + ": the stream was lost; waiting for it to come back");
    spdlog::warn("{}: \"{}\" was lost (no sample for 1 s and {}); resolving it again", description(), info.name(),
                 streams.empty() ? "not found twice in a row" : "another outlet now has its name");
    if (!streams.empty()) found_ = streams.front();
    return true;
  }

  // A gap over 2.5 sample periods in the outlet's timestamps is a dropout.
  void note_dropout(std::int64_t t_ns, double rate) {
    if (last_t_ns_ != 0 && rate > 0 && static_cast<double>(t_ns - last_t_ns_) > 2.5e9 / rate) ++dropouts_;
    last_t_ns_ = t_ns;
  }

  void publish_status(const lsl::stream_info& info, double correction_s) {
    std::lock_guard lock(mutex_);
    stream_text_ = fmt::format("LSL \"{}\" from {}, {} Hz, clock offset {:+.3f} ms", info.name(), info.hostname(),
                               info.nominal_srate(), correction_s * 1e3);
  }

  const LslSpec spec_;
  std::optional<lsl::stream_info> found_;  // resolved by make_lsl_source, read first
  std::atomic<double> min_confidence_{0};   // the stream's (effective_min_confidence); set by the reader
  std::int64_t last_t_ns_ = 0;
  std::int64_t last_sample_ns_ = 0, last_lookup_ns_ = 0;  // CLOCK_MONOTONIC
  bool lookup_missed_ = false;  // the last lookup after a silence found no stream of the name
  // Counted by the reader thread, read by status_detail() on the loop's.
  std::atomic<std::uint64_t> samples_{0}, dropouts_{0}, lost_{0}, low_confidence_{0}, out_of_order_{0};
  mutable std::mutex mutex_;  // guards stream_text_
  std::string stream_text_;   // the stream, its host, rate and clock offset
};

}  // namespace

std::unique_ptr<GazeSource> make_lsl_source(const LslSpec& spec, protocol::DisplayGeometry display, double rate_hz) {
  std::optional<lsl::stream_info> found;
  const auto streams = resolve(spec, rate_hz > 0 ? 1.0 : kResolveWaitS);
  if (!streams.empty()) found = streams.front();
  if (found) {
    if (const std::string why = unusable_channel_format(found->channel_format()); !why.empty()) {
      throw std::runtime_error("source \"" + spec.to_string() + "\": the LSL stream \"" + found->name() + "\" from " +
                               found->hostname() + ": " + why);
    }
  }
  if (rate_hz <= 0) {
    if (!found) {
      throw std::runtime_error("source \"" + spec.to_string() + "\": no LSL stream " +
                               (spec.name.empty() ? std::string("of type Gaze") : "named \"" + spec.name + "\"") +
                               " found within 5 s; start the tracker's LSL app first, or give [source] rate (--rate) "
                               "to start without it");
    }
    rate_hz = found->nominal_srate();
    if (!(rate_hz > 0)) {
      throw std::runtime_error("source \"" + spec.to_string() + "\": the stream has an irregular rate; give --rate");
    }
  }
  return std::make_unique<LslSource>(spec, display, rate_hz, std::move(found));
}

}  // namespace fovea::trackerd::lsl_source
