// fovea-calibrate: fits calibration files from calibration points and applies them to raw streams.
// calibration/CALIBRATION.md documents the commands and the file format.
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "fovea/calib/model.h"

namespace {

namespace fs = std::filesystem;
using fovea::calib::Calibration;
using fovea::calib::Correspondence;

struct Row {
  std::size_t line = 0;
  std::vector<std::string> text;
  std::vector<double> values;
};

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && (s[b] == ' ' || s[b] == '\t')) ++b;
  return s.substr(b);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

// Reads a CSV with exactly `header`; every field a number (finite unless allow_nan; "nan" then
// allowed in the columns from `nan_from` on). Errors name the file, line and column.
std::vector<Row> read_csv(const std::string& path, const std::vector<std::string>& header, bool allow_nan,
                          std::size_t nan_from) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::string line;
  std::size_t no = 0;
  std::vector<Row> rows;
  bool have_header = false;
  std::string want;
  for (const auto& h : header) want += (want.empty() ? "" : ",") + h;
  while (std::getline(in, line)) {
    ++no;
    line = trim(line);
    if (line.empty() || line[0] == '#') continue;
    const auto fields = split(line);
    if (!have_header) {
      if (fields != header) {
        throw std::runtime_error(path + ":" + std::to_string(no) + ": header must be '" + want + "', not '" + line + "'");
      }
      have_header = true;
      continue;
    }
    if (fields.size() != header.size()) {
      throw std::runtime_error(path + ":" + std::to_string(no) + ": " + std::to_string(fields.size()) +
                               " field(s); expected " + std::to_string(header.size()) + " (" + want + ")");
    }
    Row r{no, fields, {}};
    for (std::size_t c = 0; c < fields.size(); ++c) {
      const std::string& f = fields[c];
      double v = 0;
      const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
      const bool parsed = !f.empty() && ec == std::errc() && end == f.data() + f.size();
      const bool nan_ok = allow_nan && c >= nan_from && std::isnan(v);
      if (!parsed || (!std::isfinite(v) && !nan_ok)) {
        throw std::runtime_error(path + ":" + std::to_string(no) + ": column " + std::to_string(c + 1) + " (" +
                                 header[c] + "): '" + f + "' is not a " + (parsed ? "finite " : "") + "number");
      }
      r.values.push_back(v);
    }
    rows.push_back(std::move(r));
  }
  if (!have_header) throw std::runtime_error(path + ": empty; expected the header '" + want + "'");
  return rows;
}

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

int cmd_fit(const std::string& points, const std::string& kind, const std::string& base_path, const std::string& out,
            bool force) {
  const auto rows = read_csv(points, {"target_x_px", "target_y_px", "raw_x", "raw_y"}, false, 0);
  std::vector<Correspondence> pts;
  for (const auto& r : rows) pts.push_back({{r.values[2], r.values[3]}, {r.values[0], r.values[1]}});
  Calibration base;
  if (!base_path.empty()) base = fovea::calib::load_calibration(base_path);
  if (!force && fs::exists(out)) throw std::runtime_error(out + ": exists; refusing to overwrite it (use --force)");
  const Calibration cal = fovea::calib::fit_calibration(kind, pts, base_path.empty() ? nullptr : &base);
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
      "fovea-calibrate: fit calibration files from calibration points and apply them to raw gaze streams.\n"
      "Implemented: fit, apply. Not implemented yet: 'run' (interactive calibration with targets on screen)\n"
      "and 'validate' (accuracy/precision report); see calibration/CALIBRATION.md."};
  app.require_subcommand(1);

  std::string points, kind, base, out;
  bool force = false;
  auto* fit = app.add_subcommand("fit", "fit a model to POINTS.csv (target_x_px,target_y_px,raw_x,raw_y) and write CAL.json");
  fit->add_option("--points", points, "calibration points CSV; several rows per target allowed")->required();
  fit->add_option("--model", kind, "bilinear-grid | poly2 | affine | homography")
      ->required()
      ->check(CLI::IsMember(fovea::calib::model_kinds()));
  fit->add_option("--on-top-of", base, "calibration file whose model is applied first; the new model corrects it");
  fit->add_option("--out", out, "calibration file to write")->required();
  fit->add_flag("--force", force, "replace --out if it exists");

  std::string cal_path, in_csv, out_csv;
  auto* apply = app.add_subcommand("apply", "map IN.csv rows t_ms,raw_x,raw_y to OUT.csv rows t_ms,x_px,y_px");
  apply->add_option("CAL", cal_path, "calibration file")->required();
  apply->add_option("IN", in_csv, "input CSV")->required();
  apply->add_option("OUT", out_csv, "output CSV (must not exist)")->required();

  CLI11_PARSE(app, argc, argv);
  try {
    if (*fit) return cmd_fit(points, kind, base, out, force);
    if (*apply) return cmd_apply(cal_path, in_csv, out_csv);
  } catch (const std::exception& e) {
    std::cerr << "fovea-calibrate: " << e.what() << '\n';
    return 1;
  }
  return 2;
}
