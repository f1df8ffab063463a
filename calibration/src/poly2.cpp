// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/poly2.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "fovea/calib/least_squares.h"

namespace fovea::calib {

namespace {

constexpr double kMaxMagnitude = 1e100;  // beyond this, squares and products lose all meaning
// Pivots below this fraction of the largest one mean the normalised, unit-column design matrix is
// singular to working precision (condition ~1e10 and more): the points do not determine the map.
constexpr double kRankTolerance = 1e-10;

bool usable(double v) { return std::isfinite(v) && std::abs(v) <= kMaxMagnitude; }

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

Poly2Map Poly2Map::fit(std::span<const Correspondence> pts) {
  const std::size_t n = pts.size();
  if (n < kTerms) {
    throw std::invalid_argument("Poly2Map::fit: " + std::to_string(n) +
                                " correspondence(s); a second-order polynomial has 6 coefficients per axis and "
                                "needs at least 6 points, not all on one line or conic");
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Correspondence& c = pts[i];
    if (!usable(c.raw.x) || !usable(c.raw.y) || !usable(c.target.x) || !usable(c.target.y)) {
      throw std::invalid_argument("Poly2Map::fit: correspondence " + std::to_string(i) + " raw (" + fmt(c.raw.x) +
                                  ", " + fmt(c.raw.y) + ") -> target (" + fmt(c.target.x) + ", " +
                                  fmt(c.target.y) + ") is not finite (or beyond +-1e100)");
    }
  }

  Poly2Map map;
  map.points = n;
  // Centre and scale u, v to unit RMS spread: the terms are then O(1) and the normal equations'
  // (never formed here) conditioning does not depend on the units of the raw measurement.
  const double nd = static_cast<double>(n);
  for (const auto& c : pts) {
    map.centre.x += c.raw.x / nd;
    map.centre.y += c.raw.y / nd;
  }
  double su = 0, sv = 0;
  for (const auto& c : pts) {
    su += (c.raw.x - map.centre.x) * (c.raw.x - map.centre.x) / nd;
    sv += (c.raw.y - map.centre.y) * (c.raw.y - map.centre.y) / nd;
  }
  map.scale = {su > 0 ? std::sqrt(su) : 1.0, sv > 0 ? std::sqrt(sv) : 1.0};

  Matrix a(n, kTerms), b(n, 2);
  for (std::size_t i = 0; i < n; ++i) {
    const auto t = terms((pts[i].raw.x - map.centre.x) / map.scale.x, (pts[i].raw.y - map.centre.y) / map.scale.y);
    for (std::size_t j = 0; j < kTerms; ++j) a(i, j) = t[j];
    b(i, 0) = pts[i].target.x;
    b(i, 1) = pts[i].target.y;
  }
  // Column equilibration: every column to unit 2-norm (a zero column is left alone and shows up as
  // rank deficiency).
  std::array<double, kTerms> col_scale{};
  for (std::size_t j = 0; j < kTerms; ++j) {
    double s = 0;
    for (std::size_t i = 0; i < n; ++i) s += a(i, j) * a(i, j);
    col_scale[j] = s > 0 ? std::sqrt(s) : 1.0;
    for (std::size_t i = 0; i < n; ++i) a(i, j) /= col_scale[j];
  }

  const LeastSquaresSolution sol = solve_least_squares(a, b, kRankTolerance);
  map.condition = sol.condition;
  if (!sol.full_rank) {
    throw std::invalid_argument("Poly2Map::fit: the " + std::to_string(n) +
                                " points do not determine a second-order polynomial (rank " + std::to_string(sol.rank) +
                                " of 6, condition " + fmt(sol.condition) +
                                "): they are collinear, all on one conic, or too few are distinct; spread the "
                                "calibration points over the whole area to be mapped (e.g. a 3x3 grid)");
  }
  for (std::size_t j = 0; j < kTerms; ++j) {
    map.coeff_x[j] = sol.x(j, 0) / col_scale[j];
    map.coeff_y[j] = sol.x(j, 1) / col_scale[j];
  }

  double sum2 = 0;
  for (const auto& c : pts) {
    const Point p = map.apply(c.raw);
    const double d = std::hypot(p.x - c.target.x, p.y - c.target.y);
    sum2 += d * d;
    map.max_residual = std::max(map.max_residual, d);
  }
  map.rms_residual = std::sqrt(sum2 / nd);
  return map;
}

Point Poly2Map::apply(Point raw) const {
  const auto t = terms((raw.x - centre.x) / scale.x, (raw.y - centre.y) / scale.y);
  Point out;
  for (std::size_t j = 0; j < kTerms; ++j) {
    out.x += coeff_x[j] * t[j];
    out.y += coeff_y[j] * t[j];
  }
  return out;
}

std::string Poly2Map::describe() const {
  char buf[160];
  std::snprintf(buf, sizeof buf, "poly2, %zu points, rms %.3g, max %.3g, condition %.3g", points, rms_residual,
                max_residual, condition);
  return buf;
}

}  // namespace fovea::calib
