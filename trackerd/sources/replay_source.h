// SPDX-License-Identifier: Apache-2.0
#pragma once
// Replays a .fgr recording as if it were a live tracker: original timing (scaled by a speed
// factor), times rebased onto the daemon's clock, optional looping.
#include <memory>

#include "fovea/protocol/recording.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd {

struct ReplayOptions {
  std::string path;
  double speed = 1.0;  // 2.0 plays twice as fast
  bool loop = false;
  std::int64_t start_time_ns = 0;  // daemon time at which the first record is due
};

class ReplaySource final : public GazeSource {
 public:
  // Reads the whole recording; throws std::runtime_error naming the file when it is unreadable,
  // not a recording, or holds no gaze samples.
  explicit ReplaySource(ReplayOptions options);
  ReplaySource(ReplayOptions options, protocol::Recording recording);

  std::string description() const override;
  protocol::DisplayGeometry display() const override { return recording_.header.display; }
  double nominal_rate_hz() const override { return recording_.header.nominal_rate_hz * options_.speed; }
  std::optional<GazeItem> next() override;
  std::string status_detail() const override;
  // The recorded receive time, rebased as the sample's time is (a recording of a network tracker).
  std::optional<std::int64_t> last_receive_ns() const override { return last_receive_ns_; }
  // The recording's markers met on the way to the last item, rebased like it.
  std::vector<protocol::Marker> take_markers() override;
  const protocol::RecoveryReport& recovery() const { return recording_.report; }
  std::uint64_t loops_completed() const { return loops_; }

 private:
  void refuse_absurd_times() const;
  std::int64_t to_live(std::int64_t recorded_ns) const;
  GazeItem live_item(const protocol::Record& r);
  ReplayOptions options_;
  protocol::Recording recording_;
  std::size_t index_ = 0;
  std::uint64_t loops_ = 0;
  std::int64_t recorded_origin_ns_ = 0;  // time of the first record
  std::int64_t live_origin_ns_ = 0;      // daemon time that maps to recorded_origin_ns_ this loop
  std::int64_t loop_span_ns_ = 0;        // recorded duration of one pass plus one sample period
  std::int64_t last_due_ns_ = 0;
  std::vector<protocol::Marker> markers_;  // met, not yet taken
  std::uint64_t markers_replayed_ = 0;
  std::optional<std::int64_t> last_receive_ns_;
};

}  // namespace fovea::trackerd
