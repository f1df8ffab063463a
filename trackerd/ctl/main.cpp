// SPDX-License-Identifier: Apache-2.0
// fovea-ctl: the command-line client of fovea-trackerd (status, watch, record, control), recording
// tools (convert, info, classify) and eye-image tools (detect-pupil, synth-eye, synth-calibration).
// The commands live in families (ctl/commands.h); this file builds the app and runs the one chosen.
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>

#include "ctl/commands.h"

namespace fovea::ctl {

std::atomic<bool>& stop_requested() {
  static std::atomic<bool> stop{false};
  return stop;
}

}  // namespace fovea::ctl

namespace {
void on_signal(int) { fovea::ctl::stop_requested().store(true); }
}  // namespace

int main(int argc, char** argv) {
  namespace ctl = fovea::ctl;
  CLI::App app{"fovea-ctl: talk to fovea-trackerd and work with gaze recordings (.fgr, .csv)"};
  app.set_version_flag("--version", "fovea-ctl " FOVEA_VERSION);
  app.require_subcommand(1);
  app.fallthrough();  // --server may also follow the subcommand

  std::vector<ctl::Command> commands;
  for (auto add : {ctl::add_daemon_commands, ctl::add_recording_commands, ctl::add_eye_commands}) {
    for (ctl::Command& command : add(app)) commands.push_back(std::move(command));
  }
  CLI11_PARSE(app, argc, argv);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  for (const ctl::Command& command : commands) {
    if (command.subcommand->parsed()) return command.run();
  }
  return 2;
}
