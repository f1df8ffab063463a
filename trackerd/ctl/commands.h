// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea-ctl's command families. Each adds its subcommands to the app and returns, per subcommand,
// the action that runs it with the options it parsed; main() runs the one the user chose.
//   daemon_commands.cpp    talk to a running fovea-trackerd: status, watch, record, reload,
//                          record-start, record-stop, calibration-load
//   recording_commands.cpp work with recordings: convert, info, classify
//   eye_commands.cpp       eye images and simulated sessions: detect-pupil, synth-eye, synth-calibration
#include <CLI/CLI.hpp>
#include <atomic>
#include <functional>
#include <string>
#include <vector>

namespace fovea::ctl {

struct Command {
  CLI::App* subcommand;      // owned by the app
  std::function<int()> run;  // the exit status
};

std::vector<Command> add_daemon_commands(CLI::App& app);
std::vector<Command> add_recording_commands(CLI::App& app);
std::vector<Command> add_eye_commands(CLI::App& app);

// Writes `text` to `path` through a temporary file beside it, renamed into place (never a
// half-written file); refuses to replace an existing file unless `force`. Throws std::runtime_error.
void write_new_file(const std::string& path, const std::string& text, bool force);

// Set by SIGINT/SIGTERM (main installs the handlers); long-running commands poll it.
std::atomic<bool>& stop_requested();

inline bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace fovea::ctl
