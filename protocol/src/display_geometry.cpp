// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/display_geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

namespace fovea::protocol {

namespace {
constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr double kDegToRad = std::numbers::pi / 180.0;

bool positive_finite(double v) { return std::isfinite(v) && v > 0; }
}  // namespace

std::string validate(const DisplayGeometry& g) {
  if (g.width_px == 0 || g.width_px > 65536) return "width_px = " + std::to_string(g.width_px) + " (allowed 1..65536)";
  if (g.height_px == 0 || g.height_px > 65536)
    return "height_px = " + std::to_string(g.height_px) + " (allowed 1..65536)";
  if (!positive_finite(g.width_m) || g.width_m > 100)
    return "width_m = " + std::to_string(g.width_m) + " (allowed (0, 100] metres)";
  if (!positive_finite(g.height_m) || g.height_m > 100)
    return "height_m = " + std::to_string(g.height_m) + " (allowed (0, 100] metres)";
  if (!positive_finite(g.viewing_distance_m) || g.viewing_distance_m > 100)
    return "viewing_distance_m = " + std::to_string(g.viewing_distance_m) + " (allowed (0, 100] metres)";
  return {};
}

double pixels_per_mm(const DisplayGeometry& g) {
  // Jensen & Pedersen 2009, eq. 2.2: d_px = sqrt(w_px^2 + h_px^2), ppmm = d_px / d_mm.
  const double d_px = std::hypot(static_cast<double>(g.width_px), static_cast<double>(g.height_px));
  const double d_mm = std::hypot(g.width_m, g.height_m) * 1000.0;
  return d_px / d_mm;
}

double degrees_to_image_pixels(const DisplayGeometry& g, std::uint32_t image_width, double degrees) {
  const double size_m = 2.0 * g.viewing_distance_m * std::tan(degrees * std::numbers::pi / 360.0);
  return size_m / g.width_m * image_width;
}

double visual_angle_deg(double size_m, double distance_m) {
  return 2.0 * std::atan(size_m / (2.0 * distance_m)) * kRadToDeg;  // Jensen & Pedersen 2009, eq. 2.1
}

Degrees normalized_to_degrees(const DisplayGeometry& g, Normalized p) {
  const double dx_m = (p.x - 0.5) * g.width_m;
  const double dy_m = (p.y - 0.5) * g.height_m;
  return {std::atan2(dx_m, g.viewing_distance_m) * kRadToDeg, std::atan2(dy_m, g.viewing_distance_m) * kRadToDeg};
}

Normalized degrees_to_normalized(const DisplayGeometry& g, Degrees d) {
  // Angles beyond +-89 deg have no point on a flat screen; clamp so the result stays finite.
  const double ax = std::clamp(d.x, -89.0, 89.0) * kDegToRad;
  const double ay = std::clamp(d.y, -89.0, 89.0) * kDegToRad;
  return {0.5 + std::tan(ax) * g.viewing_distance_m / g.width_m, 0.5 + std::tan(ay) * g.viewing_distance_m / g.height_m};
}

double angle_between_deg(Degrees a, Degrees b) {
  const double tax = std::tan(a.x * kDegToRad), tay = std::tan(a.y * kDegToRad);
  const double tbx = std::tan(b.x * kDegToRad), tby = std::tan(b.y * kDegToRad);
  // Directions (tax, tay, 1) and (tbx, tby, 1); atan2(|a x b|, a . b) keeps precision for small
  // angles, where acos of the normalised dot product does not.
  const double cx = tay - tby, cy = tbx - tax, cz = tax * tby - tay * tbx;
  return std::atan2(std::sqrt(cx * cx + cy * cy + cz * cz), tax * tbx + tay * tby + 1) * kRadToDeg;
}

std::string to_string(const DisplayGeometry& g) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%ux%u@%.10gx%.10gmm,%.10gmm", g.width_px, g.height_px, g.width_m * 1000.0,
                g.height_m * 1000.0, g.viewing_distance_m * 1000.0);
  return buf;
}

DisplayGeometry parse_display_geometry(const std::string& text) {
  DisplayGeometry g;
  unsigned w = 0, h = 0;
  double wmm = 0, hmm = 0, dmm = 0;
  int consumed = 0;
  if (std::sscanf(text.c_str(), "%ux%u@%lfx%lfmm,%lfmm%n", &w, &h, &wmm, &hmm, &dmm, &consumed) != 5 ||
      static_cast<std::size_t>(consumed) != text.size()) {
    throw std::invalid_argument("display geometry \"" + text +
                                "\" is not of the form WxH@WMMxHMMmm,DISTmm (e.g. 1920x1080@531x299mm,650mm)");
  }
  g.width_px = w;
  g.height_px = h;
  g.width_m = wmm / 1000.0;
  g.height_m = hmm / 1000.0;
  g.viewing_distance_m = dmm / 1000.0;
  if (auto err = validate(g); !err.empty()) {
    throw std::invalid_argument("display geometry \"" + text + "\": " + err);
  }
  return g;
}

}  // namespace fovea::protocol
