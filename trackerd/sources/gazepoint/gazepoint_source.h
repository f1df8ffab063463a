// SPDX-License-Identifier: Apache-2.0
#pragma once
// `gazepoint:HOST[:PORT]`: a Gazepoint tracker (GP3, GP3 HD) through Gazepoint Control's Open Gaze
// API (open_gaze.h). A reader thread connects, enables the counter, the tracker's time, the best
// point of gaze (BPOGX/BPOGY: both eyes' average; FPOG is fixation-filtered and lags) and the eye
// data (pupil diameters), asks the screen size and starts the data; each record becomes a sample:
//  - gaze: BPOGX/BPOGY are fractions of the screen, origin top-left, y down: fovea's normalised
//    coordinates as they are; valid when BPOGV is 1;
//  - time: the tracker's TIME mapped onto CLOCK_MONOTONIC by a TrackerClock (the least receive
//    delay over a sliding second, following drift), so a sample's time is when the tracker took it,
//    not when the network delivered it; a record without TIME gets its receive time.
// Every record passes the arrival rules first (arrival_guard.h): at most 4x the declared rate is
// published; while the server floods, records are stamped on arrival and the clock is not fed (it
// is reset when the flood begins and anchors afresh after it).
// A lost connection (Gazepoint Control closed or restarted) is retried every second, reported as
// the source's problem meanwhile; a line that does not parse is counted and dropped, never used.
#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "source_api/gaze_source.h"
#include "source_api/tracker_clock.h"
#include "sources/gazepoint/open_gaze.h"
#include "sources/network_common.h"

namespace fovea::trackerd::gazepoint {

struct GazepointStats {
  bool connected = false;
  std::uint64_t records = 0;      // data records read (those dropped over the rate cap among them)
  std::uint64_t valid = 0;        // of which with a valid point of gaze
  std::uint64_t malformed = 0;    // lines refused (not an element, a bad record, too long)
  std::uint64_t refused = 0;      // NACKs: commands the server did not take
  std::uint64_t counter_gaps = 0; // records missing by CNT (the tracker's or the network's loss)
  std::uint64_t connects = 0;     // successful connections (1 + reconnections)
  std::uint64_t clock_resets = 0;
  std::optional<std::pair<std::uint32_t, std::uint32_t>> screen;  // what SCREEN_SIZE said
  std::optional<std::int64_t> clock_offset_ns;  // host - tracker; none until a record's TIME anchors the clock
  std::optional<double> clock_drift_ppm;
  std::int64_t delay_p50_ns = 0, delay_p99_ns = 0;  // receive time - mapped time, last 1024 records
  std::string last_malformed;                  // why the last refused line was refused
};

class GazepointSource final : public net::ReaderSource {
 public:
  GazepointSource(GazepointSpec spec, protocol::DisplayGeometry display, double nominal_rate_hz);
  ~GazepointSource() override { stop_reader(); }

  std::string description() const override { return "gazepoint:" + spec_.to_string(); }
  std::string status_detail() const override;
  GazepointStats stats() const;

 private:
  void run();
  int connect_to_server();  // a connected socket, or -1 with problem_ set
  void serve(int fd);       // until the connection ends or the source stops
  bool handle_line(std::string_view line, std::int64_t receive_ns);  // true: a record
  void handle_record(const Record& r, std::int64_t receive_ns);

  GazepointSpec spec_;
  TrackerClock clock_{1e-6, 64};  // TIME in microseconds
  std::optional<std::uint64_t> last_counter_;
  net::DelayWindow delays_;  // receive - mapped
  std::uint64_t delay_samples_ = 0;  // records added to delays_
  // The clock's offset and drift before the last record that arrived within the declared pace:
  // what STATUS shows from a flood's start until the clock anchors afresh.
  std::pair<std::optional<std::int64_t>, std::optional<double>> paced_clock_;
  bool silence_reported_ = false;  // "no gaze records" is the problem now

  mutable std::mutex mutex_;  // guards stats_
  GazepointStats stats_;
};

}  // namespace fovea::trackerd::gazepoint
