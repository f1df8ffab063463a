// SPDX-License-Identifier: Apache-2.0
#include "gaze/gaze_events.h"

#include <algorithm>
#include <cstdlib>

namespace fovea::render {

using protocol::EventPhase;
using protocol::EyeMovement;

void GazeEventTracker::on_event(const protocol::GazeEvent& e, std::int64_t received_ns) {
  std::lock_guard lock(mu_);
  const bool fixation_start = e.kind == EyeMovement::Fixation && e.phase == EventPhase::Start;
  const bool saccade = e.kind == EyeMovement::Saccade;
  const auto near = [&e](std::int64_t t) { return std::llabs(t - e.start_time_ns) <= kMatchNs; };
  if ((e.flags & protocol::kEventRetracted) != 0) {
    if (fixation_start) {
      const auto it = std::find(counted_.begin(), counted_.end(), e.start_time_ns);
      if (it != counted_.end()) counted_.erase(it);  // already refocused; nothing to undo
    } else if (saccade && e.phase == EventPhase::Start && saccade_open_ && saccade_start_ns_ == e.start_time_ns) {
      saccade_open_ = false;
    }
    return;
  }
  if (e.provisional()) {
    provisional_ = true;
    if (fixation_start) {
      ++fixations_;
      counted_.push_back(e.start_time_ns);
      if (counted_.size() > 64) counted_.pop_front();
    } else if (saccade && e.phase == EventPhase::Start) {
      saccade_open_ = true;
      saccade_start_ns_ = e.start_time_ns;
      saccade_received_ns_ = received_ns;
    } else if (saccade && e.phase == EventPhase::End) {
      saccade_open_ = false;
    }
    return;
  }
  if (e.kind == EyeMovement::Pursuit && e.phase == EventPhase::Start) ++pursuits_;
  if (!fixation_start) return;
  const auto it = std::find_if(counted_.begin(), counted_.end(), near);
  if (it != counted_.end()) {
    counted_.erase(it);  // the final event of a fixation already counted
  } else {
    ++fixations_;
  }
}

std::uint64_t GazeEventTracker::fixations() const {
  std::lock_guard lock(mu_);
  return fixations_;
}

std::uint64_t GazeEventTracker::pursuits() const {
  std::lock_guard lock(mu_);
  return pursuits_;
}

bool GazeEventTracker::provisional() const {
  std::lock_guard lock(mu_);
  return provisional_;
}

bool GazeEventTracker::in_saccade(std::int64_t now_ns) const {
  std::lock_guard lock(mu_);
  return saccade_open_ && now_ns - saccade_received_ns_ < kSaccadeMaxNs;
}

}  // namespace fovea::render
