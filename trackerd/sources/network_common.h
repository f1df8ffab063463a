#pragma once
// What the sources that read a tracker over its network API share (gazepoint/, pupil/): the
// HOST[:PORT] of their specs, and the hand-over from the reader thread, which owns the connection,
// to the daemon's publishing loop.
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>

#include "source_api/gaze_source.h"

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
  void push(const protocol::GazeSample& s);
  std::optional<GazeItem> next();
  void interrupt();
  std::uint64_t dropped() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<protocol::GazeSample> queue_;
  bool interrupted_ = false;
  std::uint64_t dropped_ = 0;
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

}  // namespace fovea::trackerd::net
