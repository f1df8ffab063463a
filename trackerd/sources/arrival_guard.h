// SPDX-License-Identifier: Apache-2.0
#pragma once
// What a network source (gazepoint:, pupil:, lsl:) checks of each sample as it arrives, before its
// clock sees it: two rules that no peer's word overrides.
//
// A rate cap. A tracker declares its rate ([source] rate); a peer that sends far more (a server
// looping over its buffer, a replay without pacing) must neither flood the daemon's clients nor
// teach the source's clock that the tracker's time runs a thousand times faster than the host's. A
// token bucket on the host's arrival times keeps a sample while a token is left: tokens refill at
// kFloodFactor x the declared rate, and the bucket holds one second of the declared rate (at least
// kMinBurst), so a second's backlog that TCP delivers at once after a stall passes whole, while a
// sustained flood is published at kFloodFactor x the declared rate. The samples kept are the first
// to arrive while under that pace; the others are dropped and counted.
//
// A flood begins at the first sample the cap drops and ends when none was dropped for
// kFloodQuietNs. While it lasts the peer's timestamps are not believed: the samples kept are timed
// by their arrival, and no clock is fed with them. At its start the source resets its clock (the
// burst that emptied the bucket has already taught it the flood's time), which anchors afresh after
// the flood. The flood is logged (a warning with the declared rate, the arrival rate measured and
// the cap; at its end how long it lasted and what it dropped) and shown in status().
//
// Times from the future. A sample cannot have been taken after it reached this host: a mapped time
// after its arrival time is replaced by the arrival time (not_after_arrival), counted, with the
// largest lead seen. A lead means the peer's clock or its mapping is off, and the count says how
// often that happened.
//
// How a source uses it, on its reader thread, for each sample in arrival order:
//   const auto a = arrivals_.admit(receive_ns);
//   if (a.flood_began) clock.reset();          // whether this sample is kept or not
//   if (!a.keep) return;                        // dropped over the cap: counted here, nothing else
//   t = a.flooding ? receive_ns : arrivals_.not_after_arrival(clock.map(device_time, receive_ns), receive_ns);
// and appends status() to its status_detail(). A source whose clock is not fed by samples (Pupil's
// round trips) skips the reset. Thread-safe: admit and not_after_arrival on the reader thread,
// poll and status on any.
#include <cstdint>
#include <mutex>
#include <string>

namespace fovea::trackerd::net {

class ArrivalGuard {
 public:
  static constexpr double kFloodFactor = 4;                // the cap: this many times the declared rate
  static constexpr double kMinBurst = 16;                  // the bucket's least capacity, samples
  static constexpr std::int64_t kFloodQuietNs = 1'000'000'000;  // a flood ends after this long without a drop
  static constexpr std::int64_t kWarnAfterNs = 100'000'000;     // its warning waits this long, to measure its rate

  // `nominal_rate_hz`: the rate the tracker declares; not finite or not positive: no cap (every
  // sample kept, no flood), only the future rule.
  explicit ArrivalGuard(double nominal_rate_hz);

  // What the log lines call the source (its description); set before the reader thread starts.
  void set_name(std::string name);

  struct Admission {
    bool keep = true;         // false: dropped over the cap, and counted; publish it not, map it not
    bool flooding = false;    // a flood is on: time the sample by its arrival, feed no clock with it
    bool flood_began = false; // the flood began with this sample: reset the clock (even if not kept)
    bool within_pace = true;  // nothing lately arrived faster than the cap allows (the bucket was full):
                              // what the clock learnt before this sample is sound
  };
  // Counts the sample that reached this host at `receive_ns` (CLOCK_MONOTONIC, non-decreasing).
  Admission admit(std::int64_t receive_ns);

  // `mapped_ns`, or `receive_ns` when it is later (counted, with its lead).
  std::int64_t not_after_arrival(std::int64_t mapped_ns, std::int64_t receive_ns) {
    if (mapped_ns <= receive_ns) return mapped_ns;
    count_future(mapped_ns, receive_ns);
    return receive_ns;
  }

  // Ends a flood once kFloodQuietNs passed without a drop, and logs its warning when due, also
  // while no sample arrives (ReaderSource calls it from next()).
  void poll(std::int64_t now_ns);

  struct Stats {
    bool flooding = false;
    double arrival_rate_hz = 0;     // while flooding: the flood's rate, measured
    std::uint64_t dropped = 0;      // over the cap, all floods
    std::uint64_t floods = 0;
    std::uint64_t future = 0;       // times replaced by the arrival time
    std::int64_t max_lead_ns = 0;   // the largest lead of those
  };
  Stats stats() const;
  double cap_hz() const { return refill_hz_; }  // 0: no cap

  // For the source's status_detail(): "" while nothing happened, else ", "-led parts, e.g.
  // ", FLOODING: 1000000/s against 150 Hz declared, publishing at most 600/s, 5400000 dropped over
  // the 4x cap in 1 flood, 12 from the future (up to 45.0 ms ahead; stamped on arrival)".
  std::string status() const;

 private:
  void count_future(std::int64_t mapped_ns, std::int64_t receive_ns);
  void begin_flood(std::int64_t now_ns);
  void end_flood(std::int64_t now_ns);
  void warn_if_due(std::int64_t now_ns);
  double flood_rate_hz() const;

  const double nominal_rate_hz_;
  const double capacity_;   // samples
  const double refill_hz_;  // tokens per second; 0: no cap

  mutable std::mutex mutex_;  // guards what follows
  std::string name_ = "a network source";
  double tokens_;
  std::int64_t last_arrival_ns_ = 0;
  bool seen_ = false;
  std::int64_t paced_ns_ = 0;        // the last arrival that found the bucket full
  std::uint64_t since_paced_ = 0;    // arrivals since then, it included
  bool flooding_ = false, warned_ = false;
  std::int64_t flood_start_ns_ = 0, flood_from_ns_ = 0, last_drop_ns_ = 0;
  std::uint64_t flood_arrivals_ = 0, flood_dropped_ = 0;
  Stats stats_;
};

}  // namespace fovea::trackerd::net
