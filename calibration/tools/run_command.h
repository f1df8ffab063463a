// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea-calibrate run: the per-user calibration procedure (calibration/CALIBRATION.md).
//
// Live: opens a window (full screen, or --window WxH), subscribes to fovea-trackerd, shows the
// targets of calib::make_schedule one after another (randomized order, shrinking target, dwell),
// records the raw stream, then collects each target's fixation samples (dropping blinks, saccades
// and off-target samples), fits the model on the calibration targets, validates it on the separate
// validation targets, writes the calibration file (and the report) and tells the daemon to load it
// (CONTROL_REQUEST calibration-load).
// Headless (--headless --from SESSION.fgr): the same analysis on a recorded session (the .fgr and
// its SESSION.targets.csv, as written by run --save-session or fovea-ctl synth-calibration).
#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace fovea::calib {

struct RunArgs {
  std::string server = "127.0.0.1";
  int points = 9, validation_points = 4;
  std::uint64_t seed = 1;
  bool fixed_order = false;
  double lead_in_s = 1.0, shrink_s = 0.8, settle_s = 0.6, duration_s = 1.6;
  std::string model = "auto";  // auto | poly2 | affine | homography | bilinear-grid | poly2+bilinear-grid
  std::string input = "auto";  // auto | pupil-glint | screen
  std::string eye = "auto";    // auto | left | right
  std::string target_space = "auto";  // auto (pupil-glint: fick-deg; screen: px) | px | fick-deg
  std::string out;
  bool force = false;
  std::string report_dir;
  std::string save_session;    // PREFIX: PREFIX.fgr + PREFIX.targets.csv
  std::string window;          // "WxH": a window of that size instead of full screen
  int connect_timeout_ms = 3000;
  bool no_load = false;        // live: do not tell the daemon to load the result
  bool headless = false;
  std::string from, targets;   // headless: the session recording and its targets file
  bool load = false;           // headless: also tell the daemon at --server to load the result
};

CLI::App* add_run_subcommand(CLI::App& app, RunArgs& args);

// 0: calibrated (and loaded, when asked); 1: an error, printed as "fovea-calibrate run: <what>",
// with no calibration file written unless the message says so.
int run_calibration(const RunArgs& args);

}  // namespace fovea::calib
