// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the sources that read a tracker over its network API share (gazepoint/, pupil/): the
// HOST[:PORT] of their specs, the hand-over from the reader thread, which owns the connection, to
// the daemon's publishing loop, and the rules every sample passes as it arrives (arrival_guard.h).
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/clock.h"
#include "source_api/gaze_source.h"
#include "sources/arrival_guard.h"

namespace fovea::trackerd::net {

struct HostPort {
  std::string host;
  std::uint16_t port = 0;
};
// "HOST[:PORT]": HOST an IPv4 address or a host name, PORT 1..65535 (else `default_port`). Throws
// what `bad(why)` makes of what is wrong.
HostPort parse_host_port(std::string text, std::uint16_t default_port,
                         const std::function<std::invalid_argument(const std::string&)>& bad);

// Samples from the reader thread to the loop: bounded (beyond 4096 the oldest is dropped, counted),
// next() waits up to 50 ms, interrupt() wakes it without a sample.
class SampleQueue {
 public:
  // `receive_ns`: when the sample's bytes reached this host (CLOCK_MONOTONIC).
  void push(const protocol::GazeSample& s, std::int64_t receive_ns);
  std::optional<GazeItem> next();
  std::int64_t last_receive_ns() const { return last_receive_ns_; }  // of what next() returned; its thread only
  void interrupt();
  std::uint64_t dropped() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  struct Entry {
    protocol::GazeSample sample;
    std::int64_t receive_ns;
  };
  std::deque<Entry> queue_;
  std::int64_t last_receive_ns_ = 0;
  bool interrupted_ = false;
  std::uint64_t dropped_ = 0;
};

// The delay a bridge adds (host receive time minus the tracker's own time, mapped) over the last
// 1024 samples: its median and 99th percentile are the STATUS line's delay and jitter.
class DelayWindow {
 public:
  void add(std::int64_t delay_ns);
  std::int64_t percentile(double q) const;  // 0 while empty

 private:
  std::vector<std::int64_t> ring_;
  std::size_t next_ = 0;
};

// The source's problem (GazeSource::problem), written by the reader thread, read by the loop.
class ProblemText {
 public:
  std::string get() const {
    std::lock_guard lock(mutex_);
    return text_;
  }
  void set(std::string text) {
    std::lock_guard lock(mutex_);
    text_ = std::move(text);
  }

 private:
  mutable std::mutex mutex_;
  std::string text_;
};

// A source whose tracker is read by a thread of its own: the samples that thread hands over, its
// problem, the display and rate, and the arrival rules (arrivals_: the cap on its declared rate, the
// flood rule, no times from the future), which the reader thread applies to every sample before its
// clock sees it (the call order is in arrival_guard.h) and the source's status_detail() reports
// (arrivals_.status()). The derived class starts the thread at the end of its constructor
// (start_reader) and stops it first thing in its destructor (stop_reader), while its members live.
class ReaderSource : public GazeSource {
 public:
  protocol::DisplayGeometry display() const override { return display_; }
  double nominal_rate_hz() const override { return nominal_rate_hz_; }
  std::optional<GazeItem> next() override {  // waits up to 50 ms for a sample
    arrivals_.poll(protocol::monotonic_ns());  // a flood ends also when the peer falls silent
    return queue_.next();
  }
  std::optional<std::int64_t> last_receive_ns() const override { return queue_.last_receive_ns(); }
  bool ended() const override { return false; }  // a tracker never ends; it may be away a while
  void interrupt() override { queue_.interrupt(); }
  std::string problem() const override { return problem_.get(); }

 protected:
  ReaderSource(protocol::DisplayGeometry display, double nominal_rate_hz)
      : display_(display), nominal_rate_hz_(nominal_rate_hz), arrivals_(nominal_rate_hz) {}
  ~ReaderSource() override { stop_reader(); }
  ReaderSource(const ReaderSource&) = delete;
  ReaderSource& operator=(const ReaderSource&) = delete;

  void start_reader(std::function<void()> run) {
    problem_.set(description() + ": connecting");
    arrivals_.set_name(description());
    reader_ = std::thread(std::move(run));
  }
  void stop_reader() {
    stop_ = true;
    if (reader_.joinable()) reader_.join();
  }
  bool stopping() const { return stop_.load(); }

  const protocol::DisplayGeometry display_;
  const double nominal_rate_hz_;
  SampleQueue queue_;
  ProblemText problem_;
  ArrivalGuard arrivals_;

 private:
  std::atomic<bool> stop_{false};
  std::thread reader_;
};

}  // namespace fovea::trackerd::net
