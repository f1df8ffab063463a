// SPDX-License-Identifier: Apache-2.0
#include "validate_command.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <exception>
#include <filesystem>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <vector>

#include "csv_rows.h"
#include "fovea/calib/display.h"
#include "fovea/calib/model.h"
#include "fovea/calib/validation.h"
#include "validation_report.h"

namespace fovea::calib {

namespace {

namespace fs = std::filesystem;

bool finite(Point p) { return std::isfinite(p.x) && std::isfinite(p.y); }

int validate(const ValidateArgs& args) {
  const Calibration cal = load_calibration(args.calibration);
  Display display;
  if (args.display) {
    try {
      display = parse_display(*args.display);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("--display: ") + e.what());
    }
  } else if (cal.display) {
    display = *cal.display;
  } else {
    throw std::runtime_error("no display geometry: pass --display or calibrate with one");
  }

  // Raw "nan" (a lost sample) is allowed in raw_x, raw_y; targets must be finite.
  const auto rows = csv::read_csv(args.points, {"target_x_px", "target_y_px", "raw_x", "raw_y"}, true, 2);
  if (rows.empty()) throw std::runtime_error(args.points + ": no samples after the header");
  const bool before_is_base = cal.on_top_of != nullptr;
  const bool before_is_raw = !before_is_base && cal.input == kInputScreen;
  const Point lost{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  std::vector<ValidationSample> samples;
  samples.reserve(rows.size());
  for (const auto& r : rows) {
    const Point raw{r.values[2], r.values[3]};
    ValidationSample s{{r.values[0], r.values[1]}, lost, std::nullopt};
    if (finite(raw)) s.measured_px = cal.apply(raw);
    if (before_is_base) s.before_px = finite(raw) ? cal.on_top_of->apply(raw) : lost;
    if (before_is_raw) s.before_px = raw;
    samples.push_back(s);
  }
  ValidationResult result;
  try {
    result = fovea::calib::validate(samples, display);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(args.points + ": " + e.what());
  }

  const std::string model = cal.model->kind() + (cal.on_top_of ? " on top of " + cal.on_top_of->kind() : "");
  const std::string before = before_is_base ? "; before = " + cal.on_top_of->kind() + " alone"
                             : before_is_raw ? "; before = uncorrected screen points"
                                             : "";
  const std::string title = "Validation of " + fs::path(args.calibration).filename().string() + " (" + model + ") on " +
                            fs::path(args.points).filename().string() + before;
  if (!args.report_dir.empty()) write_validation_report(args.report_dir, result, samples, display, title);

  std::cout << title << '\n' << "display: " << to_string(display) << "\n\n" << format_table(result);
  if (!args.report_dir.empty()) {
    std::cout << "wrote " << (fs::path(args.report_dir) / "report.md").string() << ", targets.csv, summary.json, errors.png\n";
  }
  return 0;
}

}  // namespace

CLI::App* add_validate_subcommand(CLI::App& app, ValidateArgs& args) {
  auto* sub = app.add_subcommand(
      "validate",
      "accuracy and precision of CAL.json on validation points, per target and overall (Jensen & Pedersen 2009, "
      "Tables 4.1/4.2); --report also writes report.md, targets.csv, summary.json and errors.png");
  sub->add_option("CAL", args.calibration, "calibration file")->required();
  sub->add_option("--points", args.points,
                  "validation points CSV: target_x_px,target_y_px,raw_x,raw_y, rows in time order; raw 'nan' = lost "
                  "sample")
      ->required();
  sub->add_option("--report", args.report_dir,
                  "directory for the report (created if missing; existing report files there are never replaced)");
  sub->add_option_function<std::string>(
      "--display", [&args](const std::string& text) { args.display = text; },
      "display geometry WxH@WMMxHMMmm,DISTmm, e.g. 1920x1080@531.3x298.9mm,650mm (default: the calibration "
      "file's)");
  return sub;
}

int run_validate(const ValidateArgs& args) {
  try {
    return validate(args);
  } catch (const std::exception& e) {
    std::cerr << "fovea-calibrate: " << e.what() << '\n';
    return 1;
  }
}

}  // namespace fovea::calib
