// SPDX-License-Identifier: Apache-2.0
#include "gaze/gaze_input.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <vector>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/csv.h"
#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/recording.h"
#include "gaze/gaze_events.h"

namespace fovea::render {

namespace {

class NoGaze final : public GazeInput {
 public:
  std::string description() const override { return "none (screen centre)"; }
  bool available() const override { return false; }
  GazeState at(double) override { return GazeState{}; }
};

// The cursor as gaze. A fixation onset is counted when the cursor has stayed within kFixationDeg of
// where it came to rest for kFixationS (a dispersion test, like the daemon's I-DT classifier, on the
// frame clock); the start-up position counts as the first once it has rested that long.
class MouseGaze final : public GazeInput {
 public:
  static constexpr double kFixationDeg = 1.0, kFixationS = 0.1;
  std::string description() const override { return "mouse"; }
  GazeState at(double t) override {
    const protocol::DisplayGeometry display;  // the mouse knows no display: the default one's angles
    const double moved = protocol::angle_between_deg(protocol::normalized_to_degrees(display, {x_, y_}),
                                                     protocol::normalized_to_degrees(display, {rest_x_, rest_y_}));
    if (!std::isfinite(moved) || moved > kFixationDeg || !std::isfinite(rest_since_) || t < rest_since_) {
      rest_x_ = x_;  // moved away (or the clock went back): a new resting place, not yet a fixation
      rest_y_ = y_;
      rest_since_ = t;
      counted_ = false;
    }
    if (!counted_ && t - rest_since_ >= kFixationS - 1e-9) {  // (frame times may fall an ulp short)
      ++fixations_;
      counted_ = true;
    }
    GazeState g;
    g.x = x_;
    g.y = y_;
    g.valid = true;
    g.movement = protocol::EyeMovement::Fixation;
    g.fixations = fixations_;
    return g;
  }
  void set_cursor(double x, double y) override {
    x_ = x;
    y_ = y;
  }

 private:
  double x_ = 0.5, y_ = 0.5;
  double rest_x_ = 0.5, rest_y_ = 0.5, rest_since_ = std::numeric_limits<double>::quiet_NaN();
  bool counted_ = false;
  std::uint64_t fixations_ = 0;
};

std::optional<GazeState::Point> eye_point(const protocol::EyeGaze& e) {
  if (!e.valid()) return std::nullopt;
  return GazeState::Point{e.x, e.y};
}

class UdpGaze final : public GazeInput {
 public:
  explicit UdpGaze(const std::string& address) : address_(address) {
    protocol::ClientOptions o;
    o.server = protocol::parse_endpoint(address, protocol::kDefaultPort);
    // Provisional events too: the focus refocuses at a fixation's landing, not ~110 ms later.
    // Each eye's gaze where the tracker has both: a stereo frame shows each eye its own point.
    o.streams = protocol::kStreamSamples | protocol::kStreamEvents | protocol::kStreamProvisional | protocol::kStreamEyes;
    o.name = "fovea-render";
    client_ = std::make_unique<protocol::GazeClient>(o);
    client_->on_event([this](const protocol::GazeEvent& e, const protocol::Arrival& a) { events_.on_event(e, a.receive_ns); });
    client_->start();
  }
  std::string description() const override { return "udp://" + address_; }
  GazeState at(double) override {
    const auto sample = client_->latest_sample();
    if (sample) {
      state_.valid = (sample->flags & protocol::kGazeValid) != 0;
      if (state_.valid) {
        state_.x = sample->x;
        state_.y = sample->y;
        state_.left_eye = eye_point(sample->left_gaze);
        state_.right_eye = eye_point(sample->right_gaze);
      }
      state_.movement = sample->state;
      state_.in_saccade = sample->state == protocol::EyeMovement::Saccade;
      const auto stats = client_->stats();
      state_.age_ms = static_cast<double>(protocol::monotonic_ns() - (sample->tracker_time_ns - stats.clock_offset_ns)) / 1e6;
      state_.received = stats.samples.received;
      state_.lost = stats.samples.lost;
      state_.latency_p99_ms = static_cast<double>(stats.latency_p99_ns) / 1e6;
    }
    state_.fixations = events_.fixations();
    state_.pursuits = events_.pursuits();
    state_.provisional = events_.provisional();
    if (state_.provisional) state_.in_saccade = events_.in_saccade(protocol::monotonic_ns());
    return state_;
  }

 private:
  std::string address_;
  GazeEventTracker events_;  // written on the client's receive thread; outlives client_
  std::unique_ptr<protocol::GazeClient> client_;
  GazeState state_;
};

// Replays a recording on the frame clock: frame time t shows the last sample at or before
// (first sample time + t). Deterministic: the same frames see the same gaze on every run.
class FileGaze final : public GazeInput {
 public:
  explicit FileGaze(const std::string& path) : path_(path) {
    protocol::Recording rec;
    if (path.size() > 4 && path.compare(path.size() - 4, 4, ".csv") == 0) {
      std::ifstream in(path);
      if (!in) throw std::runtime_error("cannot open gaze recording " + path);
      rec = protocol::read_csv(in, path);
    } else {
      rec = protocol::read_recording(path);
    }
    bool any_event = false;
    for (const auto& r : rec.records) {
      if (const auto* s = std::get_if<protocol::GazeSample>(&r.item)) samples_.push_back(*s);
      if (const auto* e = std::get_if<protocol::GazeEvent>(&r.item)) {
        any_event = true;
        if (e->kind == protocol::EyeMovement::Pursuit && e->phase == protocol::EventPhase::Start &&
            !e->provisional()) {
          pursuit_onsets_ns_.push_back(e->start_time_ns);
        }
        if (e->kind == protocol::EyeMovement::Fixation && e->phase == protocol::EventPhase::Start) {
          fixation_onsets_ns_.push_back(e->start_time_ns);
        }
      }
    }
    if (samples_.empty()) throw std::runtime_error("gaze recording " + path + " holds no samples");
    std::stable_sort(samples_.begin(), samples_.end(), [](const auto& a, const auto& b) {
      return a.tracker_time_ns < b.tracker_time_ns;
    });
    if (!any_event) {
      // No events (CSV keeps none): a fixation (pursuit) starts where a sample's state turns to it.
      for (std::size_t i = 0; i < samples_.size(); ++i) {
        const auto turns_to = [&](protocol::EyeMovement m) {
          return samples_[i].state == m && (i == 0 || samples_[i - 1].state != m);
        };
        if (turns_to(protocol::EyeMovement::Fixation)) fixation_onsets_ns_.push_back(samples_[i].tracker_time_ns);
        if (turns_to(protocol::EyeMovement::Pursuit)) pursuit_onsets_ns_.push_back(samples_[i].tracker_time_ns);
      }
    }
    std::sort(fixation_onsets_ns_.begin(), fixation_onsets_ns_.end());
    std::sort(pursuit_onsets_ns_.begin(), pursuit_onsets_ns_.end());
  }
  std::string description() const override { return "file:" + path_; }
  GazeState at(double t) override {
    const std::int64_t target = samples_.front().tracker_time_ns + static_cast<std::int64_t>(t * 1e9);
    auto it = std::upper_bound(samples_.begin(), samples_.end(), target,
                               [](std::int64_t v, const protocol::GazeSample& s) { return v < s.tracker_time_ns; });
    if (it != samples_.begin()) --it;
    const std::size_t index = static_cast<std::size_t>(it - samples_.begin());
    // Carry the last valid position through blinks, as a live stream would.
    GazeState g;
    g.valid = (it->flags & protocol::kGazeValid) != 0;
    g.movement = it->state;
    g.in_saccade = it->state == protocol::EyeMovement::Saccade;  // the recording's final labels, at their time
    for (std::size_t i = index + 1; i-- > 0;) {
      if (samples_[i].flags & protocol::kGazeValid) {
        g.x = samples_[i].x;
        g.y = samples_[i].y;
        break;
      }
    }
    g.age_ms = static_cast<double>(target - it->tracker_time_ns) / 1e6;
    g.received = index + 1;
    const auto seen = [target](const std::vector<std::int64_t>& onsets) {
      return static_cast<std::uint64_t>(std::upper_bound(onsets.begin(), onsets.end(), target) - onsets.begin());
    };
    g.fixations = seen(fixation_onsets_ns_);
    g.pursuits = seen(pursuit_onsets_ns_);
    return g;
  }

 private:
  std::string path_;
  std::vector<protocol::GazeSample> samples_;
  std::vector<std::int64_t> fixation_onsets_ns_;  // Fixation Start times, sorted
  std::vector<std::int64_t> pursuit_onsets_ns_;   // (final) Pursuit Start times, sorted
};

}  // namespace

std::unique_ptr<GazeInput> make_gaze_input(const std::string& spec) {
  if (spec == "none") return std::make_unique<NoGaze>();
  if (spec == "mouse") return std::make_unique<MouseGaze>();
  if (spec.rfind("udp://", 0) == 0) return std::make_unique<UdpGaze>(spec.substr(6));
  if (spec.rfind("file:", 0) == 0) return std::make_unique<FileGaze>(spec.substr(5));
  throw std::invalid_argument("--gaze \"" + spec + "\": expected udp://HOST:PORT, file:REC.fgr, mouse or none");
}

}  // namespace fovea::render
