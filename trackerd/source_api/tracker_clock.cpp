// SPDX-License-Identifier: Apache-2.0
#include "source_api/tracker_clock.h"

#include <algorithm>
#include <cmath>

namespace fovea::trackerd {

TrackerClock::TrackerClock(double tick_s, std::uint32_t counter_bits, double window_s, double max_gap_s)
    : tick_ns_(std::isfinite(tick_s) && tick_s > 0 ? tick_s * 1e9 : 1e3),
      mask_(counter_bits == 0 || counter_bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << counter_bits) - 1u),
      window_ns_(static_cast<std::int64_t>(window_s * 1e9)),
      max_gap_ns_(static_cast<std::int64_t>(max_gap_s * 1e9)) {}

void TrackerClock::anchor(std::uint64_t ticks, std::int64_t receive_ns) {
  if (anchored_) ++resets_;
  anchored_ = true;
  last_ticks_ = ticks & mask_;
  tracker_ns_ = 0;
  fraction_ns_ = 0;
  offset_ns_ = receive_ns;
  window_.clear();
  window_.push_back({0, receive_ns});
  first_full_window_.reset();
}

std::optional<double> TrackerClock::drift_ppm() const {
  if (!first_full_window_) return std::nullopt;
  const std::int64_t span = tracker_ns_ - first_full_window_->tracker_ns;
  if (span < window_ns_ || span <= 0) return std::nullopt;
  return static_cast<double>(offset_ns_ - first_full_window_->offset_ns) / static_cast<double>(span) * 1e6;
}

std::int64_t TrackerClock::map(std::uint64_t ticks, std::int64_t receive_ns) {
  ticks &= mask_;
  bool fresh = !anchored_;
  if (anchored_) {
    const std::uint64_t delta = (ticks - last_ticks_) & mask_;
    // Deltas in the upper half of the counter's range are steps backwards (reset, reordering).
    const bool backwards = delta > mask_ / 2;
    const double step_ns = static_cast<double>(delta) * tick_ns_ + fraction_ns_;
    if (backwards || !(step_ns <= static_cast<double>(max_gap_ns_))) {
      fresh = true;
    } else {
      const auto whole = static_cast<std::int64_t>(std::floor(step_ns));
      fraction_ns_ = step_ns - static_cast<double>(whole);
      tracker_ns_ += whole;
      last_ticks_ = ticks;
      const std::int64_t candidate = receive_ns - tracker_ns_;
      if (candidate < offset_ns_ - max_gap_ns_ || candidate > offset_ns_ + max_gap_ns_) {
        fresh = true;  // the clocks disagree by more than any latency: the tracker restarted
      } else {
        // Sliding-window minimum (monotonic deque): O(1) amortized per report.
        while (!window_.empty() && window_.back().offset_ns >= candidate) window_.pop_back();
        window_.push_back({tracker_ns_, candidate});
        while (window_.front().tracker_ns < tracker_ns_ - window_ns_) window_.pop_front();
        offset_ns_ = window_.front().offset_ns;
        if (!first_full_window_ && tracker_ns_ >= window_ns_) first_full_window_ = Candidate{tracker_ns_, offset_ns_};
      }
    }
  }
  if (fresh) {
    const bool had = anchored_;
    anchor(ticks, receive_ns);
    if (!had) {
      last_mapped_ns_ = receive_ns;
      return receive_ns;
    }
  }
  const std::int64_t mapped = std::max(tracker_ns_ + offset_ns_, last_mapped_ns_);
  last_mapped_ns_ = mapped;
  return mapped;
}

}  // namespace fovea::trackerd
