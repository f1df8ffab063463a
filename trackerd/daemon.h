#pragma once
// The fovea-trackerd main loop: paces a GazeSource in real time, publishes through GazeServer and
// optionally records what it publishes.
#include <atomic>
#include <memory>
#include <optional>
#include <string>

#include "fovea/protocol/server.h"
#include "sources/gaze_source.h"

namespace fovea::trackerd {

struct DaemonOptions {
  std::string source_spec = "synthetic";  // synthetic | replay:FILE
  double synthetic_rate_hz = 250;
  std::uint64_t seed = 1;
  double replay_speed = 1.0;
  bool replay_loop = false;
  std::optional<protocol::DisplayGeometry> display;  // overrides the source's (synthetic default)
  protocol::ServerOptions server;
  std::string record_path;
  bool record_append = false;
  double duration_s = 0;   // 0: until signalled
  bool exit_when_source_ends = false;
};

// Builds the source named by `spec`; throws std::invalid_argument / std::runtime_error with a
// message naming the spec and what is wrong.
std::unique_ptr<GazeSource> make_source(const DaemonOptions& options, std::int64_t start_time_ns);

// Runs until `stop` becomes true, the duration elapses, or (if asked) the source ends.
// Returns the process exit status.
int run_daemon(const DaemonOptions& options, const std::atomic<bool>& stop);

}  // namespace fovea::trackerd
