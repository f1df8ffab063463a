// SPDX-License-Identifier: Apache-2.0
#pragma once
// Fixation onsets and saccades in flight, from a live stream of final and provisional GAZE_EVENTs
// (PROTOCOL.md §4.9). The final events trail the eye by the classifier's window (the default gbt:
// ~112 ms, up to 351 ms; ivvt up to 385 ms); provisional ones come at once: a fixation onset is counted when
// its provisional Fixation Start arrives, and its final Fixation Start (within 50 ms of it) is not
// counted again; a final onset nobody said provisionally (after a blink, out of pursuit) is counted
// when it arrives. A saccade is in flight from a provisional Saccade Start to its End, its
// retraction, or 200 ms (the detector gives up on a saccade after 150 ms).
// Thread-safe: the client's receive thread writes, the render thread reads.
#include <cstdint>
#include <deque>
#include <mutex>

#include "fovea/protocol/messages.h"

namespace fovea::render {

class GazeEventTracker {
 public:
  void on_event(const protocol::GazeEvent& e, std::int64_t received_ns);
  std::uint64_t fixations() const;
  std::uint64_t pursuits() const;  // final Pursuit Start events (pursuit has no provisional events)
  bool provisional() const;  // provisional events have arrived (the daemon sends them)
  bool in_saccade(std::int64_t now_ns) const;

  static constexpr std::int64_t kMatchNs = 50'000'000;      // as the daemon's check (ProvisionalCheck)
  static constexpr std::int64_t kSaccadeMaxNs = 200'000'000;

 private:
  mutable std::mutex mu_;
  std::uint64_t fixations_ = 0, pursuits_ = 0;
  std::deque<std::int64_t> counted_;  // onsets of provisional fixations counted (the last 64)
  bool provisional_ = false;
  bool saccade_open_ = false;
  std::int64_t saccade_start_ns_ = 0, saccade_received_ns_ = 0;
};

}  // namespace fovea::render
