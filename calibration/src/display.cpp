// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/display.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <system_error>

namespace fovea::calib {

namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string check_field(const char* name, double v, double max, const char* unit) {
  if (std::isfinite(v) && v > 0 && v <= max) return {};
  return std::string(name) + " = " + num(v) + " (allowed (0, " + num(max) + "] " + unit + ")";
}

constexpr const char* kFields[] = {"width_px", "height_px", "width_mm", "height_mm", "distance_mm"};

double& field(Display& d, int i) {
  switch (i) {
    case 0: return d.width_px;
    case 1: return d.height_px;
    case 2: return d.width_mm;
    case 3: return d.height_mm;
    default: return d.distance_mm;
  }
}

bool finite(Point p) { return std::isfinite(p.x) && std::isfinite(p.y); }

}  // namespace

std::string check(const Display& d) {
  for (const auto& err : {check_field("width_px", d.width_px, 65536, "px"),
                          check_field("height_px", d.height_px, 65536, "px"),
                          check_field("width_mm", d.width_mm, 100000, "mm"),
                          check_field("height_mm", d.height_mm, 100000, "mm"),
                          check_field("distance_mm", d.distance_mm, 100000, "mm")}) {
    if (!err.empty()) return err;
  }
  return {};
}

nlohmann::json to_json(const Display& d) {
  return {{"width_px", d.width_px},
          {"height_px", d.height_px},
          {"width_mm", d.width_mm},
          {"height_mm", d.height_mm},
          {"distance_mm", d.distance_mm}};
}

Display display_from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw std::invalid_argument(where + ": must be a JSON object");
  Display d;
  for (int i = 0; i < 5; ++i) {
    const auto it = j.find(kFields[i]);
    if (it == j.end()) throw std::invalid_argument(where + ": field '" + kFields[i] + "' is missing");
    if (!it->is_number()) throw std::invalid_argument(where + ": field '" + kFields[i] + "' must be a number");
    field(d, i) = it->get<double>();
  }
  if (const std::string err = check(d); !err.empty()) throw std::invalid_argument(where + ": " + err);
  return d;
}

std::string to_string(const Display& d) {
  return num(d.width_px) + "x" + num(d.height_px) + "@" + num(d.width_mm) + "x" + num(d.height_mm) + "mm," +
         num(d.distance_mm) + "mm";
}

Display parse_display(std::string_view text) {
  const std::string s(text);
  const auto bad = [&s](const std::string& why) {
    return std::invalid_argument("display geometry '" + s + "' " + why);
  };
  // WxH@WMMxHMMmm,DISTmm with plain decimal numbers (std::from_chars: no blanks, signs other than
  // '-', or hexadecimal).
  Display d;
  double* const fields[] = {&d.width_px, &d.height_px, &d.width_mm, &d.height_mm, &d.distance_mm};
  const char* const after[] = {"x", "@", "x", "mm,", "mm"};
  const char* p = s.data();
  const char* const end = s.data() + s.size();
  for (int i = 0; i < 5; ++i) {
    const auto [next, ec] = std::from_chars(p, end, *fields[i]);
    const std::string_view lit(after[i]);
    if (ec != std::errc() || static_cast<std::size_t>(end - next) < lit.size() ||
        std::string_view(next, lit.size()) != lit) {
      throw bad("is not of the form WxH@WMMxHMMmm,DISTmm (e.g. 1920x1080@531.3x298.9mm,650mm)");
    }
    p = next + lit.size();
  }
  if (p != end) throw bad("is not of the form WxH@WMMxHMMmm,DISTmm (e.g. 1920x1080@531.3x298.9mm,650mm)");
  if (const std::string err = check(d); !err.empty()) throw bad("has " + err);
  return d;
}

Point px_to_mm(const Display& d, Point px) {
  return {(px.x - d.width_px / 2) * (d.width_mm / d.width_px), (px.y - d.height_px / 2) * (d.height_mm / d.height_px)};
}

Point px_to_fick_deg(const Display& d, Point px) {
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  const Point mm = px_to_mm(d, px);
  return {std::atan2(mm.x, d.distance_mm) * kDeg, std::atan2(mm.y, std::hypot(mm.x, d.distance_mm)) * kDeg};
}

Point fick_deg_to_px(const Display& d, Point a) {
  constexpr double kRad = 3.14159265358979323846 / 180.0;
  if (!(std::abs(a.x) < 89.9) || !(std::abs(a.y) < 89.9)) {
    return {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  }
  const double x_mm = d.distance_mm * std::tan(a.x * kRad);
  const double y_mm = std::tan(a.y * kRad) * std::hypot(x_mm, d.distance_mm);
  return {x_mm * (d.width_px / d.width_mm) + d.width_px / 2, y_mm * (d.height_px / d.height_mm) + d.height_px / 2};
}

double px_per_mm(const Display& d) { return d.width_px / d.width_mm; }

double angle_between_deg(const Display& d, Point a, Point b) {
  if (!finite(a) || !finite(b)) return std::numeric_limits<double>::quiet_NaN();
  const double kx = d.width_mm / d.width_px, ky = d.height_mm / d.height_px;
  // Offsets from the centre in pixels: finite for finite points (the centre is at most 32768).
  const double ax = a.x - d.width_px / 2, ay = a.y - d.height_px / 2;
  const double bx = b.x - d.width_px / 2, by = b.y - d.height_px / 2;
  // Everything is divided by m >= 1 so that no product below can overflow; the angle between two
  // vectors does not change when both are scaled alike.
  const double m = std::max({std::abs(ax), std::abs(ay), std::abs(bx), std::abs(by), 1.0});
  const double sax = ax / m * kx, say = ay / m * ky, sz = d.distance_mm / m;
  // b - a from the pixel difference (exact for nearby points), unless that overflows.
  double sdx = (b.x - a.x) / m * kx, sdy = (b.y - a.y) / m * ky;
  if (!std::isfinite(sdx) || !std::isfinite(sdy)) {
    sdx = (bx / m - ax / m) * kx;
    sdy = (by / m - ay / m) * ky;
  }
  // a = (sax, say, sz), b = a + (sdx, sdy, 0): a x b = a x (sdx, sdy, 0).
  const double cx = -sz * sdy, cy = sz * sdx, cz = sax * sdy - say * sdx;
  const double dot = sax * (sax + sdx) + say * (say + sdy) + sz * sz;
  return std::atan2(std::hypot(cx, cy, cz), dot) * kRadToDeg;
}

}  // namespace fovea::calib
