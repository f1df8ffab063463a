// SPDX-License-Identifier: Apache-2.0
#pragma once
// A source of ready gaze samples and events (synthetic, replayed, HID trackers, the eye pipeline).
// Items carry times on the daemon's CLOCK_MONOTONIC; the daemon publishes each item when its time
// comes.
#include <optional>
#include <string>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/recording.h"

namespace fovea::protocol {
class ViewerFeedServer;
}

namespace fovea::trackerd {

using GazeItem = std::variant<protocol::GazeSample, protocol::GazeEvent>;

// The time at which an item is due: a sample's capture time, an event's start (Start) or end (End).
std::int64_t due_time_ns(const GazeItem& item);

class GazeSource {
 public:
  virtual ~GazeSource() = default;
  virtual std::string description() const = 0;  // e.g. "replay:demo.fgr (x1.0, loop)"
  virtual protocol::DisplayGeometry display() const = 0;
  virtual double nominal_rate_hz() const = 0;
  // The next item in time order. nullopt: the source has ended (ended() true), or it has nothing
  // yet / was interrupted (ended() false) and next() may be called again.
  virtual std::optional<GazeItem> next() = 0;
  // When the item next() returned last reached this host (CLOCK_MONOTONIC), for sources whose items
  // carry a tracker's own timestamp mapped to the host clock (network trackers); nullopt where the
  // item's time is the host's own already (synthetic, HID reads, camera frames). Called on the
  // thread that calls next().
  virtual std::optional<std::int64_t> last_receive_ns() const { return std::nullopt; }
  // Experiment markers (PROTOCOL.md §4.17) the source met on the way to the item next() returned
  // last, times on the daemon's clock (a replayed recording's); the daemon publishes them with it.
  virtual std::vector<protocol::Marker> take_markers() { return {}; }
  // After next() returned nullopt: is the stream over for good? (files: yes; devices: no)
  virtual bool ended() const { return true; }
  // Thread-safe; a source that can block in next() (a device waiting for data) returns nullopt
  // soon after. One-shot: later next() calls work normally.
  virtual void interrupt() {}
  // Empty while the source works; otherwise why not (device missing, busy, lost and being
  // retried), naming the device. The daemon reports it in its status and logs.
  virtual std::string problem() const { return {}; }
  // Counters worth showing beside the description in the daemon's status line and final log
  // (e.g. the eye pipeline's "1200 frames, 1150 pupils, 40 blinks"); empty: none. Called on the
  // thread that calls next().
  virtual std::string status_detail() const { return {}; }
  // Sources that see eye images (the eye pipeline): each frame, and what the detector found in it,
  // is offered to `frames` (PROTOCOL.md §17; it takes one only when a viewer wants it, and never
  // waits), from the thread that calls next(); null stops. Others ignore it.
  virtual bool makes_eye_frames() const { return false; }
  virtual void show_eye_frames(protocol::ViewerFeedServer* /*frames*/) {}
};

}  // namespace fovea::trackerd
