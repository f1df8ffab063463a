// SPDX-License-Identifier: Apache-2.0
// The LSL outlet through liblsl (built only when find_package(LSL) found it).
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <lsl_cpp.h>

#include "fovea/protocol/clock.h"
#include "lsl/lsl_outlet.h"

namespace fovea::trackerd {

namespace {

using protocol::monotonic_ns;

void describe_gaze_channels(lsl::xml_element desc) {
  lsl::xml_element channels = desc.append_child("channels");
  for (const LslChannel& c : kLslGazeChannels) {
    channels.append_child("channel")
        .append_child_value("label", c.label)
        .append_child_value("eye", c.eye)
        .append_child_value("type", c.type)
        .append_child_value("unit", c.unit)
        .append_child_value("coordinate_system", std::string(c.type).starts_with("Screen") ? "screen, origin top-left, y down" : "");
  }
}

void describe_setup(lsl::xml_element desc, const LslOutletOptions& o) {
  desc.append_child("acquisition")
      .append_child_value("manufacturer", "fovea")
      .append_child_value("model", o.device)
      .append_child_value("software", "fovea-trackerd " FOVEA_VERSION);
  desc.append_child("setup")
      .append_child("display")
      .append_child_value("resolution_x", std::to_string(o.display.width_px))
      .append_child_value("resolution_y", std::to_string(o.display.height_px))
      .append_child_value("size_x_mm", fmt::format("{:.1f}", o.display.width_m * 1000))
      .append_child_value("size_y_mm", fmt::format("{:.1f}", o.display.height_m * 1000))
      .append_child_value("viewing_distance_mm", fmt::format("{:.1f}", o.display.viewing_distance_m * 1000));
  desc.append_child_value("class_codes", "0 unknown, 1 fixation, 2 saccade, 3 pursuit, 4 blink");
}

class LiblslOutlet final : public LslOutlet {
 public:
  explicit LiblslOutlet(const LslOutletOptions& o)
      : display_(o.display), gaze_(gaze_info(o)), markers_(markers_info(o)), events_(events_info(o)) {
    offset_s_.store(lsl_clock_minus_monotonic_s());
    next_offset_ns_ = monotonic_ns() + kOffsetRefreshNs;
  }

  void push(const protocol::GazeSample& s) override {
    refresh_offset();
    const auto values = lsl_gaze_values(s, display_);
    gaze_.push_sample(values.data(), lsl_time(s.tracker_time_ns));
  }

  void push(const protocol::GazeEvent& e) override {
    if (e.provisional()) return;
    const std::int64_t t = e.start_time_ns + (e.phase == protocol::EventPhase::End ? e.duration_ns : 0);
    const std::string text = lsl_event_text(e);
    events_.push_sample(&text, lsl_time(t));
  }

  // The label as its sender wrote it: consumers match on their own labels.
  void push(const protocol::Marker& m) override {
    std::lock_guard lock(markers_mutex_);
    markers_.push_sample(&m.label.value, lsl_time(m.time_ns));
  }

  std::string status() const override {
    const auto consumed = [](lsl::stream_outlet& o) { return o.have_consumers() ? "consumed" : "no consumer"; };
    return fmt::format("gaze {}, markers {}, events {}, clock offset {:+.6f} s", consumed(gaze_), consumed(markers_),
                       consumed(events_), offset_s_.load());
  }

 private:
  static constexpr std::int64_t kOffsetRefreshNs = 10'000'000'000;

  static lsl::stream_info gaze_info(const LslOutletOptions& o) {
    lsl::stream_info info(o.name + " gaze", "Gaze", static_cast<std::int32_t>(kLslGazeChannels.size()),
                          o.nominal_rate_hz > 0 ? o.nominal_rate_hz : lsl::IRREGULAR_RATE, lsl::cf_float32,
                          o.source_id + "-gaze");
    describe_gaze_channels(info.desc());
    describe_setup(info.desc(), o);
    return info;
  }

  static lsl::stream_info markers_info(const LslOutletOptions& o) {
    lsl::stream_info info(o.name + " markers", "Markers", 1, lsl::IRREGULAR_RATE, lsl::cf_string,
                          o.source_id + "-markers");
    info.desc().append_child("channels").append_child("channel").append_child_value("label", "marker").append_child_value("type", "Marker");
    return info;
  }

  static lsl::stream_info events_info(const LslOutletOptions& o) {
    lsl::stream_info info(o.name + " events", "GazeEvents", 1, lsl::IRREGULAR_RATE, lsl::cf_string,
                          o.source_id + "-events");
    info.desc().append_child("channels").append_child("channel").append_child_value("label", "event").append_child_value("type", "EyeMovementEvent");
    info.desc().append_child_value("format", kLslEventFormat);
    return info;
  }

  void refresh_offset() {
    const std::int64_t now = monotonic_ns();
    if (now < next_offset_ns_) return;
    offset_s_.store(lsl_clock_minus_monotonic_s());
    next_offset_ns_ = now + kOffsetRefreshNs;
  }

  double lsl_time(std::int64_t monotonic) const { return static_cast<double>(monotonic) * 1e-9 + offset_s_.load(); }

  protocol::DisplayGeometry display_;
  // mutable: liblsl's C++ wrapper has no const have_consumers(), which status() asks.
  mutable lsl::stream_outlet gaze_;
  std::mutex markers_mutex_;  // MARKERs come from the server's thread and the loop's
  mutable lsl::stream_outlet markers_;
  mutable lsl::stream_outlet events_;  // the loop's thread only
  std::atomic<double> offset_s_{0};
  std::int64_t next_offset_ns_ = 0;
};

}  // namespace

// The read of LSL's clock bracketed by the two monotonic reads closest together (liblsl uses
// std::chrono::steady_clock, the same clock on Linux, so this is ~0; measured rather than assumed,
// so another standard library or platform stays correct).
double lsl_clock_minus_monotonic_s() {
  double best_gap = 1e9, offset = 0;
  for (int i = 0; i < 8; ++i) {
    const std::int64_t a = monotonic_ns();
    const double l = lsl::local_clock();
    const std::int64_t b = monotonic_ns();
    const double gap = static_cast<double>(b - a);
    if (gap < best_gap) {
      best_gap = gap;
      offset = l - static_cast<double>(a + (b - a) / 2) * 1e-9;
    }
  }
  return offset;
}

bool lsl_available() { return true; }

std::string lsl_library_info() {
  return fmt::format("liblsl {}.{} ({})", lsl::library_version() / 100, lsl::library_version() % 100,
                     lsl::library_info());
}

std::unique_ptr<LslOutlet> open_lsl_outlet(const LslOutletOptions& options) {
  try {
    return std::make_unique<LiblslOutlet>(options);
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("LSL outlet \"{} gaze\": {}", options.name, e.what()));
  }
}

}  // namespace fovea::trackerd
