// SPDX-License-Identifier: Apache-2.0
#pragma once
// `mouse[:DISPLAY]`: the X11 pointer as gaze, sampled at a fixed rate, for developing experiments
// and gaze-contingent displays without a tracker (PsychoPy's ioHub has the same for the same
// reason). The pointer's position on the X screen, as a fraction of the screen, is the sample's
// normalised gaze; a pointer on another screen of the display is invalid gaze. The display geometry
// is the configured one, else the X screen's size in pixels and millimetres (as the X server states
// them) at the default viewing distance. Samples are stamped when the pointer is read.
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "source_api/gaze_source.h"

namespace fovea::trackerd::mouse {

// "mouse" (the DISPLAY of the environment) or "mouse:DISPLAY" (e.g. "mouse::1"). Throws
// std::invalid_argument naming the spec.
std::optional<std::string> parse_mouse_spec(const std::string& spec);  // the display name, if given
std::string check_mouse_spec(const std::string& spec);

class MouseSource final : public GazeSource {
 public:
  // Opens the X display; throws std::runtime_error naming it and what to do when it cannot.
  MouseSource(const std::optional<std::string>& display_name, std::optional<protocol::DisplayGeometry> configured,
              double rate_hz, std::int64_t start_time_ns);
  ~MouseSource() override;
  MouseSource(const MouseSource&) = delete;
  MouseSource& operator=(const MouseSource&) = delete;

  std::string description() const override { return "mouse:" + display_name_ + " (" + std::to_string(static_cast<long>(rate_hz_)) + " Hz)"; }
  protocol::DisplayGeometry display() const override { return geometry_; }
  double nominal_rate_hz() const override { return rate_hz_; }
  std::optional<GazeItem> next() override;  // the pointer at the next tick
  bool ended() const override { return false; }
  void interrupt() override { interrupted_ = true; }
  std::string status_detail() const override;

 private:
  struct X;  // the Xlib connection
  std::unique_ptr<X> x_;
  std::string display_name_;
  protocol::DisplayGeometry geometry_;
  double rate_hz_;
  std::int64_t next_tick_ns_;
  std::uint64_t samples_ = 0, off_screen_ = 0;
  std::atomic<bool> interrupted_{false};
};

}  // namespace fovea::trackerd::mouse
