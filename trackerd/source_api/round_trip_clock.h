// SPDX-License-Identifier: Apache-2.0
#pragma once
// Maps a remote clock that can only be asked ("what time is it?") onto the host's CLOCK_MONOTONIC,
// as NTP and Cristian's algorithm do: each exchange sent at host time s, answered with remote time
// r, received at host time e, says that r was read somewhere in [s, e], so the offset host - remote
// is (s + e) / 2 - r within +-(e - s) / 2. Exchanges whose round trip is short say it best; the
// clock keeps, for each 10 s bucket of the last 2 minutes, the fastest exchange, and fits a line
// (offset and drift) through those nearly as fast as the fastest (round trip at most twice its,
// plus 50 us), so that a remote clock running at a slightly different rate stays mapped within the
// best exchanges' uncertainty. A slope through exchanges close together is mostly their errors
// (buckets are cut at fixed host times: two can be milliseconds apart), so until the slopes the
// exchanges allow lie within 20 ppm of each other the clock takes the allowed slope nearest zero,
// through the fastest exchange: never worse than ignoring the drift. A remote clock that jumps (the
// remote restarted, or its time was set) by more than 100 ms against the prediction starts the
// history afresh, counted in resets().
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <vector>

namespace fovea::trackerd {

class RoundTripClock {
 public:
  // One exchange; ignored when the times are not in order or the answer is not finite.
  void add(std::int64_t host_send_ns, std::int64_t host_receive_ns, double remote_s);
  bool ready() const { return !exchanges_.empty(); }
  // Host time of remote time `remote_s` (requires ready()).
  std::int64_t to_host_ns(double remote_s) const;

  std::int64_t offset_ns() const;                // host - remote, now
  std::optional<double> drift_ppm() const;       // the fitted line's slope, once the exchanges pin it
  std::int64_t uncertainty_ns() const;           // half the fastest kept exchange's round trip
  std::int64_t last_round_trip_ns() const { return last_rtt_ns_; }
  std::uint64_t exchanges() const { return count_; }
  std::uint64_t resets() const { return resets_; }

  // Slopes (drift, ns per ns) a set of exchanges allows; lo > hi when none fits them all.
  struct SlopeRange {
    double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  };

 private:
  struct Exchange {
    std::int64_t host_mid_ns;  // (s + e) / 2
    std::int64_t rtt_ns;       // e - s
    double remote_s;
    std::int64_t offset_ns() const;
  };
  void fit();
  void fit_least_squares(const std::vector<const Exchange*>& used, std::int64_t base, const SlopeRange& allowed);
  std::deque<Exchange> exchanges_;  // the fastest of each bucket, oldest first
  // The fit: offset(host_mid) = a + b * (host_mid - origin).
  std::int64_t origin_ns_ = 0;
  double a_ns_ = 0, b_ = 0;
  bool have_line_ = false;
  std::int64_t last_rtt_ns_ = 0;
  std::uint64_t count_ = 0, resets_ = 0;
};

}  // namespace fovea::trackerd
