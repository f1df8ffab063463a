// SPDX-License-Identifier: Apache-2.0
#pragma once
// Maps a tracker's sensor timestamps onto the host's CLOCK_MONOTONIC.
//
// The first report anchors the mapping: host time = tracker time + offset, with offset = receive
// time - tracker time. Transport latency only ever delays a report, so the least (receive -
// tracker) is the best offset; it is taken over a sliding window of `window_s` of tracker time,
// which removes USB and scheduling jitter (to within the best report of the window) while following
// a tracker clock that drifts against the host (lag at most drift x window: 0.1 ms at 100 ppm).
// Because the window includes the current report, a mapped time is never after its report's
// receive time (a sample is never due in the future). Counter wrap is unwrapped modulo the
// counter's width; a step backwards, a jump of more than `max_gap_s`, or an offset off by more
// than that re-anchors (tracker reset), counted in resets(). Mapped times never decrease.
#include <cstdint>
#include <deque>
#include <optional>

namespace fovea::trackerd {

class TrackerClock {
 public:
  TrackerClock(double tick_s, std::uint32_t counter_bits, double window_s = 1.0, double max_gap_s = 5);

  // Host time of a report with raw counter `ticks` received at `receive_ns`.
  std::int64_t map(std::uint64_t ticks, std::int64_t receive_ns);
  // Forgets the mapping (a new connection, a flood's false times): the next report anchors afresh;
  // drift is unknown until then. Mapped times still never decrease.
  void reset() {
    anchored_ = false;
    window_.clear();
    first_full_window_.reset();
  }
  std::uint64_t resets() const { return resets_; }
  // Whether a report anchored the mapping since construction or the last reset().
  bool anchored() const { return anchored_; }
  std::int64_t offset_ns() const { return offset_ns_; }
  // How fast the tracker's clock runs against the host's, in parts per million (positive: the
  // offset host - tracker grows, the tracker is slow): the change of the best offset since the
  // first full window, over the tracker time between. nullopt until two windows have passed since
  // the last anchor.
  std::optional<double> drift_ppm() const;

 private:
  void anchor(std::uint64_t ticks, std::int64_t receive_ns);

  double tick_ns_;
  std::uint64_t mask_;
  std::int64_t window_ns_;
  std::int64_t max_gap_ns_;
  bool anchored_ = false;
  std::uint64_t last_ticks_ = 0;
  std::int64_t tracker_ns_ = 0;      // tracker time since the anchor, unwrapped
  double fraction_ns_ = 0;           // sub-ns remainder of tick conversions
  std::int64_t offset_ns_ = 0;       // host - tracker
  struct Candidate {
    std::int64_t tracker_ns, offset_ns;
  };
  std::deque<Candidate> window_;     // increasing offsets: the front is the window's least
  std::int64_t last_mapped_ns_ = 0;
  std::uint64_t resets_ = 0;
  std::optional<Candidate> first_full_window_;  // the best offset when the first window had passed
};

}  // namespace fovea::trackerd
