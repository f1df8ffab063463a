// SPDX-License-Identifier: Apache-2.0
// The parts of the LSL outlet that do not need liblsl: channel values and event texts.
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "lsl/lsl_outlet.h"

namespace fovea::trackerd {

std::array<float, kLslGazeChannels.size()> lsl_gaze_values(const protocol::GazeSample& s,
                                                           const protocol::DisplayGeometry& display) {
  constexpr float nan = std::numeric_limits<float>::quiet_NaN();
  const bool valid = (s.flags & protocol::kGazeValid) != 0;
  auto pupil = [&](const protocol::EyeData& e) {
    return (e.flags & protocol::kEyePupilValid) != 0 && e.pupil_diameter_mm > 0 ? e.pupil_diameter_mm : nan;
  };
  const auto w = static_cast<float>(display.width_px);
  const auto h = static_cast<float>(display.height_px);
  return {valid ? s.x * w : nan,
          valid ? s.y * h : nan,
          valid ? s.x : nan,
          valid ? s.y : nan,
          valid ? s.x_deg : nan,
          valid ? s.y_deg : nan,
          valid ? 1.0f : 0.0f,
          s.confidence,
          static_cast<float>(s.state),
          pupil(s.left),
          pupil(s.right)};
}

std::string lsl_event_text(const protocol::GazeEvent& e) {
  const char* phase = e.phase == protocol::EventPhase::Start ? "start" : "end";
  std::string text = fmt::format("{} {}", protocol::to_string(e.kind), phase);
  if (e.phase == protocol::EventPhase::End) {
    text += fmt::format(" duration_ms={:.1f} amplitude_deg={:.2f} peak_velocity_deg_s={:.0f}",
                        static_cast<double>(e.duration_ns) * 1e-6, static_cast<double>(e.amplitude_deg),
                        static_cast<double>(e.peak_velocity_deg_s));
  }
  return text + fmt::format(" x={:.4f} y={:.4f}", static_cast<double>(e.centroid_x), static_cast<double>(e.centroid_y));
}

}  // namespace fovea::trackerd
