// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea-calibrate validate CAL.json --points POINTS.csv [--report DIR] [--display WxH@WMMxHMMmm,DISTmm]
//
// Accuracy and precision of a calibration on validation points (Jensen & Pedersen 2009, Tables
// 4.1/4.2): POINTS.csv has the header target_x_px,target_y_px,raw_x,raw_y (as `fit`), rows in time
// order, raw "nan" for a lost sample. Each raw point is mapped with the calibration ("after"); the
// "before" figures are the base model's output for a calibration fitted on top of another, the raw
// point itself for a calibration whose input is "screen", and absent otherwise. The display is
// --display, else the calibration file's, else an error. Prints the table; with --report also
// writes the report directory (validation_report.h).
#include <optional>
#include <string>

namespace CLI {
class App;
}

namespace fovea::calib {

struct ValidateArgs {
  std::string calibration, points, report_dir;  // report_dir "" = no report
  std::optional<std::string> display;           // "1920x1080@531.3x298.9mm,650mm"
};

// Registers the "validate" subcommand filling `args` (which must outlive parsing); returns it, so
// that the caller can test `if (*sub)` after parsing.
CLI::App* add_validate_subcommand(CLI::App& app, ValidateArgs& args);

// Runs it: 0 on success; 1 on any error, after printing "fovea-calibrate: <what>" (naming the file,
// line and column at fault) to stderr, with nothing written.
int run_validate(const ValidateArgs& args);

}  // namespace fovea::calib
