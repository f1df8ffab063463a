// SPDX-License-Identifier: Apache-2.0
#include "sources/replay_source.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "fovea/protocol/bounded_file.h"

namespace fovea::trackerd {

using protocol::GazeEvent;
using protocol::GazeSample;

ReplaySource::ReplaySource(ReplayOptions options)
    : ReplaySource(options, protocol::read_recording(options.path)) {}

ReplaySource::ReplaySource(ReplayOptions options, protocol::Recording recording)
    : options_(std::move(options)), recording_(std::move(recording)) {
  if (!(options_.speed > 0) || !std::isfinite(options_.speed) || options_.speed > 1000) {
    throw std::runtime_error("replay speed " + std::to_string(options_.speed) + " is outside (0, 1000]");
  }
  const bool has_sample = std::any_of(recording_.records.begin(), recording_.records.end(), [](const auto& r) {
    return std::holds_alternative<GazeSample>(r.item);
  });
  if (!has_sample) throw std::runtime_error("recording " + options_.path + " holds no intact gaze samples");
  refuse_absurd_times();
  std::int64_t first = INT64_MAX, last = INT64_MIN;
  for (const auto& r : recording_.records) {
    first = std::min(first, r.time_ns());
    last = std::max(last, r.time_ns());
  }
  recorded_origin_ns_ = first;
  const double rate = recording_.header.nominal_rate_hz > 0 ? recording_.header.nominal_rate_hz : 1000.0;
  loop_span_ns_ = (last - first) + static_cast<std::int64_t>(1e9 / rate);
  live_origin_ns_ = options_.start_time_ns;
}

// Times near +-2^63 would wrap in the span, the rebasing and the loop arithmetic (issue 23 item 12).
// Every time must lie within +-2^61 ns (73 years) and every event last at most that long, so that
// no sum or difference below can overflow.
void ReplaySource::refuse_absurd_times() const {
  constexpr std::int64_t kMax = std::int64_t{1} << 61;
  for (std::size_t i = 0; i < recording_.records.size(); ++i) {
    const auto& item = recording_.records[i].item;
    std::int64_t t = 0, d = 0;
    if (const auto* s = std::get_if<GazeSample>(&item)) {
      t = s->tracker_time_ns;
    } else if (const auto* e = std::get_if<GazeEvent>(&item)) {
      t = e->start_time_ns;
      d = e->duration_ns;
    } else {
      const auto& m = std::get<protocol::Marker>(item);
      t = m.time_ns;
      d = m.received_ns - m.time_ns;  // the rebasing shifts both: their distance must stay in range too
      if (d < 0) d = -d;
    }
    if (t < -kMax || t > kMax || d < 0 || d > kMax) {
      throw std::runtime_error("recording " + protocol::escape_for_log(options_.path) + ": record " +
                               std::to_string(i) + " has the time " + std::to_string(t) + " ns" +
                               (d != 0 ? " (duration " + std::to_string(d) + " ns)" : std::string()) +
                               ", beyond +-2^61 ns: not a recording this replays");
    }
  }
}

std::string ReplaySource::status_detail() const {
  return markers_replayed_ == 0 ? std::string() : std::to_string(markers_replayed_) + " markers replayed";
}

std::string ReplaySource::description() const {
  char buf[64];
  std::snprintf(buf, sizeof buf, " (x%.3g%s)", options_.speed, options_.loop ? ", loop" : "");
  // The file name without its directory: status and recording headers have little room.
  const auto slash = options_.path.find_last_of('/');
  return "replay:" + (slash == std::string::npos ? options_.path : options_.path.substr(slash + 1)) + buf;
}

std::int64_t ReplaySource::to_live(std::int64_t recorded_ns) const {
  return live_origin_ns_ +
         static_cast<std::int64_t>(std::llround(static_cast<double>(recorded_ns - recorded_origin_ns_) / options_.speed));
}

std::vector<protocol::Marker> ReplaySource::take_markers() {
  std::vector<protocol::Marker> out;
  out.swap(markers_);
  return out;
}

// The next sample or event; the markers passed on the way are kept for take_markers(), rebased.
std::optional<GazeItem> ReplaySource::next() {
  while (true) {
    if (index_ >= recording_.records.size()) {
      if (!options_.loop) return std::nullopt;
      index_ = 0;
      ++loops_;
      live_origin_ns_ += static_cast<std::int64_t>(std::llround(static_cast<double>(loop_span_ns_) / options_.speed));
    }
    const protocol::Record& r = recording_.records[index_++];
    if (const auto* m = std::get_if<protocol::Marker>(&r.item)) {
      protocol::Marker live = *m;
      live.time_ns = to_live(m->time_ns);
      live.received_ns = to_live(m->received_ns);
      markers_.push_back(live);
      ++markers_replayed_;
      continue;
    }
    return live_item(r);
  }
}

GazeItem ReplaySource::live_item(const protocol::Record& r) {
  GazeItem item;
  last_receive_ns_.reset();
  if (const auto* s = std::get_if<GazeSample>(&r.item)) {
    GazeSample live = *s;
    live.tracker_time_ns = to_live(s->tracker_time_ns);
    if (r.host_receive_ns) last_receive_ns_ = to_live(*r.host_receive_ns);
    item = live;
  } else {
    GazeEvent live = std::get<GazeEvent>(r.item);
    live.start_time_ns = to_live(live.start_time_ns);
    live.duration_ns = static_cast<std::int64_t>(std::llround(static_cast<double>(live.duration_ns) / options_.speed));
    item = live;
  }
  // Damaged or hand-edited files may step back in time; never let published time run backwards.
  const std::int64_t due = due_time_ns(item);
  if (due < last_due_ns_) {
    if (auto* s = std::get_if<GazeSample>(&item)) s->tracker_time_ns = last_due_ns_;
  }
  last_due_ns_ = std::max(last_due_ns_, due_time_ns(item));
  return item;
}

}  // namespace fovea::trackerd
