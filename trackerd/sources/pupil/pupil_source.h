// SPDX-License-Identifier: Apache-2.0
#pragma once
// `pupil:HOST[:PORT][?surface=NAME|gaze=scene&min_confidence=C]`: Pupil Core through Pupil Capture's (or Pupil
// Service's) network API (pupil_messages.h). A reader thread owns the ZeroMQ sockets:
//  - Pupil Remote (REQ, port 50020): "SUB_PORT" finds the publisher; "t" asks Pupil time, once a
//    second (16 times in a row at the start and after Pupil time jumps), and a RoundTripClock maps
//    Pupil time onto CLOCK_MONOTONIC from those exchanges (the midpoints of the fastest, with drift);
//  - the publisher (SUB) on "surfaces.NAME" and "gaze.".
// Screen gaze comes from the surface (Surface Tracker, a surface fitted to the screen, named
// "screen" unless ?surface= says otherwise): norm_pos with y flipped (Pupil's origin is
// bottom-left), valid when its confidence reaches min_confidence (0.6, as Pupil's own tools).
// Gaze off the surface stays valid, outside 0..1. Without the surface only scene-camera gaze exists:
// the source then publishes its samples invalid (their times, no screen point) and says so as its
// problem. With ?gaze=scene the scene camera's gaze is published instead, valid (its image
// coordinates, y flipped), for a fovea calibration of input "screen" to map onto the screen: the
// way to use Pupil Core without a surface. When Pupil Capture stops answering, or restarts (its clock jumps, its publisher moves),
// the source reconnects.
// Every gaze passes the arrival rules (arrival_guard.h): at most 4x the declared rate is published,
// samples are stamped on arrival while the publisher floods, and a time after the gaze's arrival is
// replaced by the arrival time and counted.
#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "source_api/gaze_source.h"
#include "source_api/round_trip_clock.h"
#include "sources/network_common.h"
#include "sources/pupil/pupil_messages.h"

namespace fovea::trackerd::pupil {

struct PupilStats {
  bool connected = false;
  std::uint64_t samples = 0;          // published from surface gaze (or scene gaze with gaze=scene)
  std::uint64_t valid = 0;
  std::uint64_t low_confidence = 0;   // below min_confidence: invalid
  std::uint64_t off_surface = 0;      // on_surf false (valid, outside the screen)
  std::uint64_t scene_only = 0;       // scene-camera gaze published invalid (no surface)
  std::uint64_t malformed = 0;        // messages refused
  std::uint64_t out_of_order = 0;     // gaze not after the last one published (dropped)
  std::uint64_t gaps = 0;             // dropouts: more than 2.5 sample periods between two gaze points
  std::uint64_t stamped_unsynced = 0; // mapped in the past, yet stamped on arrival: the clock was re-syncing
  std::uint64_t connects = 0;
  std::uint64_t clock_exchanges = 0, clock_resets = 0;
  std::int64_t clock_offset_ns = 0, clock_uncertainty_ns = 0, clock_last_rtt_ns = 0;
  std::optional<double> clock_drift_ppm;
  std::int64_t delay_p50_ns = 0, delay_p99_ns = 0;  // receive time - mapped time, last 1024 gaze points
  std::string last_malformed;
};

class PupilSource final : public net::ReaderSource {
 public:
  PupilSource(PupilSpec spec, protocol::DisplayGeometry display, double nominal_rate_hz);
  ~PupilSource() override { stop_reader(); }

  std::string description() const override {
    return "pupil:" + spec_.to_string() + (spec_.scene_gaze ? " (scene camera)" : " (surface " + spec_.surface + ")");
  }
  std::string status_detail() const override;
  PupilStats stats() const;

 private:
  struct Connection;  // the ZeroMQ sockets of one connection to Pupil Capture
  void run();
  void serve(Connection& c);
  bool sync_clock(Connection& c);
  bool handle_message(Connection& c, std::int64_t receive_ns);  // false: no message waiting
  void publish(const PupilGaze& g, bool screen, std::int64_t receive_ns);
  void count_malformed(const std::string& why);
  // What the problem is, so that gaze arriving clears the ones it answers (reader thread only).
  enum class Problem { None, Waiting, SceneOnly, Silent, Lost };
  void set_problem(Problem kind, std::string text);
  Problem problem_kind_ = Problem::None;

  PupilSpec spec_;
  RoundTripClock clock_;
  double last_timestamp_ = -1e300;        // the last Pupil time published
  bool clock_suspect_ = false;            // a gaze's time made no sense: ask Pupil time now
  bool clock_suspect() const {
    std::lock_guard lock(mutex_);
    return clock_suspect_;
  }
  std::int64_t last_surface_ns_ = 0;      // host time of the last surface message

  mutable std::mutex mutex_;  // guards stats_ and the members the loop's threads read
  PupilStats stats_;
  net::DelayWindow delays_;  // receive - mapped (guarded by mutex_)
  std::uint64_t delay_samples_ = 0;  // gaze points added to delays_ (guarded by mutex_)
};

}  // namespace fovea::trackerd::pupil
