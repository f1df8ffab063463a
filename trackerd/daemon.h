// SPDX-License-Identifier: Apache-2.0
#pragma once
// The fovea-trackerd main loop: paces a GazeSource in real time, passes each item through the
// calibration stage (and, with step 3's classifier, the online classifier), publishes it through
// GazeServer and optionally records it. Between two items it attends to SIGHUP reloads and control
// commands, and reports to systemd (READY, STATUS, WATCHDOG).
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fovea/protocol/server.h"
#include "service/config.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd {

// Settings of one run that are not configuration (tests and demos use them).
struct RunOptions {
  double duration_s = 0;  // 0: until signalled
  bool exit_when_source_ends = false;
  std::size_t wait_subscribers = 0;  // hold the source until this many clients have subscribed
};

// Produces the configuration to adopt on a reload (SIGHUP or the control command): the file read
// again with the same command-line overrides applied. Throws service::ConfigError.
using ConfigLoader = std::function<service::DaemonConfig()>;

// Flags set by signal handlers (never any work there); the loop polls them.
struct DaemonSignals {
  const std::atomic<bool>* stop = nullptr;  // SIGINT / SIGTERM
  std::atomic<bool>* reload = nullptr;      // SIGHUP; the loop clears it when it starts the reload
};

// Runs until `signals.stop` becomes true, the duration elapses, or (if asked) the source ends.
// Returns the process exit status (0 clean, 1 recording failed on the way, 2 could not start).
int run_daemon(const service::DaemonConfig& config, const RunOptions& run, const DaemonSignals& signals,
               ConfigLoader reload_config = {});

class LslOutlet;
// The daemon's LSL outlet once it has stopped: left open for the process's end, never destroyed
// (liblsl 1.16's outlet destructor can crash while consumers are connected; daemon.cpp, shut_down).
extern LslOutlet* lsl_outlet_left_to_exit;

}  // namespace fovea::trackerd
