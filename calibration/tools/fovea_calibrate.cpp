// SPDX-License-Identifier: Apache-2.0
// fovea-calibrate: fits calibration files from calibration points and applies them to raw streams.
// calibration/CALIBRATION.md documents the commands and the file format.
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "csv_rows.h"
#include "fovea/calib/model.h"
#include "run_command.h"
#include "validate_command.h"

namespace {

namespace fs = std::filesystem;
using fovea::calib::Calibration;
using fovea::calib::Correspondence;

using fovea::calib::csv::read_csv;

// Writes `text` to `path` via a temporary file; refuses to replace an existing file.
void write_new_file(const std::string& path, const std::string& text) {
  std::error_code ec;
  if (fs::exists(path, ec)) throw std::runtime_error(path + ": exists; refusing to overwrite it");
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << text;
    out.flush();
    if (!out) {
      fs::remove(tmp, ec);
      throw std::runtime_error(tmp + ": cannot write");
    }
  }
  fs::create_hard_link(tmp, path, ec);
  std::error_code ignored;
  fs::remove(tmp, ignored);
  if (ec) throw std::runtime_error(path + ": cannot write: " + ec.message());
}

std::string fmt(double v) {
  if (std::isnan(v)) return "nan";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

struct FitArgs {
  std::string points, kind, base, out, display, input = fovea::calib::kInputScreen, eye, target_space = "px";
  bool force = false;
};

int cmd_fit(const FitArgs& a) {
  const std::string &points = a.points, &kind = a.kind, &base_path = a.base, &out = a.out;
  const bool force = a.force;
  std::optional<fovea::calib::Display> display;
  if (!a.display.empty()) display = fovea::calib::parse_display(a.display);
  const bool fick = a.target_space == fovea::calib::kTargetFickDegrees;
  if (fick && !display) throw std::runtime_error("--target-space fick-deg needs --display (the targets' screen)");
  const auto rows = read_csv(points, {"target_x_px", "target_y_px", "raw_x", "raw_y"}, false, 0);
  std::vector<Correspondence> pts;
  for (const auto& r : rows) pts.push_back({{r.values[2], r.values[3]}, {r.values[0], r.values[1]}});
  Calibration base;
  if (!base_path.empty()) base = fovea::calib::load_calibration(base_path);
  if (!force && fs::exists(out)) throw std::runtime_error(out + ": exists; refusing to overwrite it (use --force)");
  Calibration cal = fovea::calib::fit_calibration(kind, pts, base_path.empty() ? nullptr : &base, {},
                                                  fick ? &*display : nullptr);
  if (display) cal.display = display;
  if (base_path.empty()) {
    cal.input = a.input;
    cal.eye = a.eye;
  }
  fovea::calib::save_calibration(cal, out, force);
  std::cout << "model: " << cal.model->kind() << (cal.on_top_of ? " on top of " + cal.on_top_of->kind() : "") << '\n'
            << "points used: " << cal.points_used << '\n'
            << "rms residual: " << fmt(cal.rms_residual) << " px\n"
            << "max residual: " << fmt(cal.model->stats().max_residual) << " px\n"
            << "condition: " << (std::isfinite(cal.condition) ? fmt(cal.condition) : "n/a (no linear system)") << '\n'
            << "wrote " << out << '\n';
  return 0;
}

int cmd_apply(const std::string& cal_path, const std::string& in, const std::string& out) {
  const Calibration cal = fovea::calib::load_calibration(cal_path);
  if (fs::exists(out)) throw std::runtime_error(out + ": exists; refusing to overwrite it");
  // Invalid samples (blinks: raw "nan") pass through as nan.
  const auto rows = read_csv(in, {"t_ms", "raw_x", "raw_y"}, true, 1);
  std::string text = "t_ms,x_px,y_px\n";
  for (const auto& r : rows) {
    const auto p = cal.apply({r.values[1], r.values[2]});
    const bool ok = std::isfinite(p.x) && std::isfinite(p.y);
    text += r.text[0] + "," + (ok ? fmt(p.x) : "nan") + "," + (ok ? fmt(p.y) : "nan") + "\n";
  }
  write_new_file(out, text);
  std::cout << "mapped " << rows.size() << " row(s) with " << cal.model->kind()
            << (cal.on_top_of ? " on top of " + cal.on_top_of->kind() : "") << " into " << out << '\n';
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "fovea-calibrate: calibrate a viewer on fovea-trackerd (run), fit calibration files from calibration\n"
      "points (fit), check them on validation points (validate) and apply them to raw gaze (apply).\n"
      "See calibration/CALIBRATION.md."};
  app.set_version_flag("--version", "fovea-calibrate " FOVEA_VERSION);
  app.require_subcommand(1);

  FitArgs fa;
  auto* fit = app.add_subcommand("fit", "fit a model to POINTS.csv (target_x_px,target_y_px,raw_x,raw_y) and write CAL.json");
  fit->add_option("--points", fa.points, "calibration points CSV; several rows per target allowed")->required();
  fit->add_option("--model", fa.kind, "bilinear-grid | poly2 | affine | homography")
      ->required()
      ->check(CLI::IsMember(fovea::calib::model_kinds()));
  fit->add_option("--on-top-of", fa.base, "calibration file whose model is applied first; the new model corrects it");
  fit->add_option("--out", fa.out, "calibration file to write")->required();
  fit->add_flag("--force", fa.force, "replace --out if it exists");
  fit->add_option("--display", fa.display,
                  "the targets' screen, WxH@WMMxHMMmm,DISTmm (recorded in the file; needed by validate and fick-deg)");
  fit->add_option("--input", fa.input, "what raw_x,raw_y are: screen (a tracker's gaze, px) | pupil-glint")
      ->check(CLI::IsMember({fovea::calib::kInputScreen, fovea::calib::kInputPupilGlint}))
      ->capture_default_str();
  fit->add_option("--eye", fa.eye, "pupil-glint: left | right (which eye the daemon takes the vector of)")
      ->check(CLI::IsMember({"left", "right"}));
  fit->add_option("--target-space", fa.target_space, "px | fick-deg (fit to the line of sight's angles; needs --display)")
      ->check(CLI::IsMember({fovea::calib::kTargetPixels, fovea::calib::kTargetFickDegrees}))
      ->capture_default_str();

  std::string cal_path, in_csv, out_csv;
  auto* apply = app.add_subcommand("apply", "map IN.csv rows t_ms,raw_x,raw_y to OUT.csv rows t_ms,x_px,y_px");
  apply->add_option("CAL", cal_path, "calibration file")->required();
  apply->add_option("IN", in_csv, "input CSV")->required();
  apply->add_option("OUT", out_csv, "output CSV (must not exist)")->required();

  fovea::calib::ValidateArgs validate_args;
  auto* validate = fovea::calib::add_validate_subcommand(app, validate_args);
  fovea::calib::RunArgs run_args;
  auto* run = fovea::calib::add_run_subcommand(app, run_args);

  CLI11_PARSE(app, argc, argv);
  if (*validate) return fovea::calib::run_validate(validate_args);
  if (*run) return fovea::calib::run_calibration(run_args);
  try {
    if (*fit) return cmd_fit(fa);
    if (*apply) return cmd_apply(cal_path, in_csv, out_csv);
  } catch (const std::exception& e) {
    std::cerr << "fovea-calibrate: " << e.what() << '\n';
    return 1;
  }
  return 2;
}
