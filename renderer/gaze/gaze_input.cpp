#include "gaze/gaze_input.h"

#include <algorithm>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/csv.h"
#include "fovea/protocol/recording.h"

namespace fovea::render {

namespace {

class NoGaze final : public GazeInput {
 public:
  std::string description() const override { return "none (screen centre)"; }
  bool available() const override { return false; }
  GazeState at(double) override { return GazeState{}; }
};

class MouseGaze final : public GazeInput {
 public:
  std::string description() const override { return "mouse"; }
  GazeState at(double) override {
    GazeState g;
    g.x = x_;
    g.y = y_;
    g.valid = true;
    g.movement = protocol::EyeMovement::Fixation;
    return g;
  }
  void set_cursor(double x, double y) override {
    x_ = x;
    y_ = y;
  }

 private:
  double x_ = 0.5, y_ = 0.5;
};

class UdpGaze final : public GazeInput {
 public:
  explicit UdpGaze(const std::string& address) : address_(address) {
    protocol::ClientOptions o;
    o.server = protocol::parse_endpoint(address, protocol::kDefaultPort);
    o.streams = protocol::kStreamSamples | protocol::kStreamEvents;
    o.name = "fovea-render";
    client_ = std::make_unique<protocol::GazeClient>(o);
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
      }
      state_.movement = sample->state;
      const auto stats = client_->stats();
      state_.age_ms = static_cast<double>(protocol::monotonic_ns() - (sample->tracker_time_ns - stats.clock_offset_ns)) / 1e6;
      state_.received = stats.samples.received;
      state_.lost = stats.samples.lost;
      state_.latency_p99_ms = static_cast<double>(stats.latency_p99_ns) / 1e6;
    }
    return state_;
  }

 private:
  std::string address_;
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
    for (const auto& r : rec.records) {
      if (const auto* s = std::get_if<protocol::GazeSample>(&r.item)) samples_.push_back(*s);
    }
    if (samples_.empty()) throw std::runtime_error("gaze recording " + path + " holds no samples");
    std::stable_sort(samples_.begin(), samples_.end(), [](const auto& a, const auto& b) {
      return a.tracker_time_ns < b.tracker_time_ns;
    });
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
    for (std::size_t i = index + 1; i-- > 0;) {
      if (samples_[i].flags & protocol::kGazeValid) {
        g.x = samples_[i].x;
        g.y = samples_[i].y;
        break;
      }
    }
    g.age_ms = static_cast<double>(target - it->tracker_time_ns) / 1e6;
    g.received = index + 1;
    return g;
  }

 private:
  std::string path_;
  std::vector<protocol::GazeSample> samples_;
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
