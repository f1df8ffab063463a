// SPDX-License-Identifier: Apache-2.0
#include "gaze_samples.h"

#include <cmath>

namespace fovea::calib {

RawSample to_raw_sample(const protocol::GazeSample& s, GazeInput input, bool left_eye,
                        const protocol::DisplayGeometry& display) {
  RawSample r;
  r.time_ns = s.tracker_time_ns;
  if (input == GazeInput::PupilGlint) {
    const protocol::EyeData& e = left_eye ? s.left : s.right;
    r.valid = (e.flags & protocol::kEyeFlagMask) == protocol::kEyeFlagMask;
    r.raw = {static_cast<double>(e.pupil_glint_x_px), static_cast<double>(e.pupil_glint_y_px)};
  } else {
    r.valid = (s.flags & protocol::kGazeValid) != 0;
    r.raw = {static_cast<double>(s.x) * display.width_px, static_cast<double>(s.y) * display.height_px};
  }
  r.valid = r.valid && std::isfinite(r.raw.x) && std::isfinite(r.raw.y);
  using State = RawSample::State;
  switch (s.state) {
    case protocol::EyeMovement::Fixation: r.state = State::Fixation; break;
    case protocol::EyeMovement::Saccade: r.state = State::Saccade; break;
    case protocol::EyeMovement::Pursuit: r.state = State::Pursuit; break;
    case protocol::EyeMovement::Blink: r.state = State::Blink; break;
    case protocol::EyeMovement::Unknown: r.state = State::Unknown; break;
  }
  return r;
}

std::vector<RawSample> to_raw_samples(std::span<const protocol::GazeSample> samples, GazeInput input, bool left_eye,
                                      const protocol::DisplayGeometry& display) {
  std::vector<RawSample> out;
  out.reserve(samples.size());
  for (const protocol::GazeSample& s : samples) out.push_back(to_raw_sample(s, input, left_eye, display));
  return out;
}

}  // namespace fovea::calib
