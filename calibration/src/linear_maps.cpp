// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/linear_maps.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "fovea/calib/least_squares.h"

namespace fovea::calib {

namespace {

constexpr double kMaxMagnitude = 1e100;
// As for Poly2Map: pivots below this fraction of the largest one of the normalised, unit-column
// design matrix mean the points do not determine the map.
constexpr double kRankTolerance = 1e-10;

// Scales every column of `a` to unit 2-norm; returns the scales (a zero column keeps scale 1 and
// shows up as rank deficiency).
std::vector<double> equilibrate(Matrix& a) {
  std::vector<double> scale(a.cols(), 1.0);
  for (std::size_t j = 0; j < a.cols(); ++j) {
    double s = 0;
    for (std::size_t i = 0; i < a.rows(); ++i) s += a(i, j) * a(i, j);
    scale[j] = s > 0 ? std::sqrt(s) : 1.0;
    for (std::size_t i = 0; i < a.rows(); ++i) a(i, j) /= scale[j];
  }
  return scale;
}

std::string too_few(const std::string& who, std::size_t n, std::size_t params, std::size_t min_points,
                    const std::string& shape) {
  return who + ": " + std::to_string(n) + " correspondence(s); the model has " + std::to_string(params) +
         " parameters (2 equations per point) and needs at least " + std::to_string(min_points) + " points " + shape;
}

std::string degenerate(const std::string& who, std::span<const Correspondence> pts, const LeastSquaresSolution& sol,
                       std::size_t params, const std::string& shape) {
  return who + ": the " + std::to_string(pts.size()) + " points (" +
         std::to_string(detail::distinct_raw_points(pts)) + " distinct) do not determine the map (rank " +
         std::to_string(sol.rank) + " of " + std::to_string(params) + ", condition " +
         detail::format_number(sol.condition) + "): they are " + shape +
         " or too few are distinct; spread the calibration points over the area to be mapped";
}

}  // namespace

namespace detail {

std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

void check_finite(std::span<const Correspondence> pts, const std::string& who) {
  auto usable = [](double v) { return std::isfinite(v) && std::abs(v) <= kMaxMagnitude; };
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Correspondence& c = pts[i];
    if (!usable(c.raw.x) || !usable(c.raw.y) || !usable(c.target.x) || !usable(c.target.y)) {
      throw std::invalid_argument(who + ": correspondence " + std::to_string(i) + " raw (" + format_number(c.raw.x) +
                                  ", " + format_number(c.raw.y) + ") -> target (" + format_number(c.target.x) + ", " +
                                  format_number(c.target.y) +
                                  ") is not finite (or beyond +-1e100); drop invalid samples (blinks, lost "
                                  "tracking) before fitting");
    }
  }
}

std::size_t distinct_raw_points(std::span<const Correspondence> pts) {
  std::vector<Point> raw;
  raw.reserve(pts.size());
  for (const auto& c : pts) raw.push_back(c.raw);
  std::sort(raw.begin(), raw.end(), [](Point a, Point b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  return static_cast<std::size_t>(std::unique(raw.begin(), raw.end()) - raw.begin());
}

}  // namespace detail

AffineMap AffineMap::fit(std::span<const Correspondence> pts) {
  const std::string who = "AffineMap::fit";
  const std::size_t n = pts.size();
  if (n < 3) throw std::invalid_argument(too_few(who, n, kParams, 3, "not all on one line"));
  detail::check_finite(pts, who);

  // Centre and scale the raw points to unit RMS spread per axis, then fit out = c0 + c1 un + c2 vn.
  const double nd = static_cast<double>(n);
  Point centre, scale;
  for (const auto& c : pts) {
    centre.x += c.raw.x / nd;
    centre.y += c.raw.y / nd;
  }
  for (const auto& c : pts) {
    scale.x += (c.raw.x - centre.x) * (c.raw.x - centre.x) / nd;
    scale.y += (c.raw.y - centre.y) * (c.raw.y - centre.y) / nd;
  }
  scale = {scale.x > 0 ? std::sqrt(scale.x) : 1.0, scale.y > 0 ? std::sqrt(scale.y) : 1.0};

  Matrix a(n, 3), b(n, 2);
  for (std::size_t i = 0; i < n; ++i) {
    a(i, 0) = 1;
    a(i, 1) = (pts[i].raw.x - centre.x) / scale.x;
    a(i, 2) = (pts[i].raw.y - centre.y) / scale.y;
    b(i, 0) = pts[i].target.x;
    b(i, 1) = pts[i].target.y;
  }
  const std::vector<double> cs = equilibrate(a);
  const LeastSquaresSolution sol = solve_least_squares(a, b, kRankTolerance);
  if (!sol.full_rank) throw std::invalid_argument(degenerate(who, pts, sol, 3, "collinear"));

  AffineMap map;
  for (std::size_t k = 0; k < 2; ++k) {
    const double c0 = sol.x(0, k) / cs[0], c1 = sol.x(1, k) / cs[1], c2 = sol.x(2, k) / cs[2];
    const double a1 = c1 / scale.x, a2 = c2 / scale.y;
    map.a[3 * k + 0] = c0 - a1 * centre.x - a2 * centre.y;
    map.a[3 * k + 1] = a1;
    map.a[3 * k + 2] = a2;
  }
  map.stats.points = n;
  map.stats.condition = sol.condition;
  detail::fill_residuals(map, pts, map.stats);
  return map;
}

namespace {

// Hartley's isotropic normalisation: centroid to the origin, mean distance from it sqrt(2).
struct Similarity {
  double s = 1, cx = 0, cy = 0;  // p' = s (p - c)
  Point apply(Point p) const { return {s * (p.x - cx), s * (p.y - cy)}; }
};

template <class Get>
Similarity normaliser(std::span<const Correspondence> pts, Get get) {
  Similarity t;
  const double nd = static_cast<double>(pts.size());
  for (const auto& c : pts) {
    t.cx += get(c).x / nd;
    t.cy += get(c).y / nd;
  }
  double mean_dist = 0;
  for (const auto& c : pts) mean_dist += std::hypot(get(c).x - t.cx, get(c).y - t.cy) / nd;
  t.s = mean_dist > 0 ? std::sqrt(2.0) / mean_dist : 1.0;
  return t;
}

using Mat3 = std::array<double, 9>;
Mat3 mul(const Mat3& l, const Mat3& r) {
  Mat3 o{};
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = 0; j < 3; ++j)
      for (std::size_t k = 0; k < 3; ++k) o[3 * i + j] += l[3 * i + k] * r[3 * k + j];
  return o;
}

}  // namespace

HomographyMap HomographyMap::fit(std::span<const Correspondence> pts) {
  const std::string who = "HomographyMap::fit";
  const std::size_t n = pts.size();
  if (n < 4) throw std::invalid_argument(too_few(who, n, kParams, 4, "no three of them on one line"));
  detail::check_finite(pts, who);

  const Similarity tr = normaliser(pts, [](const Correspondence& c) { return c.raw; });
  const Similarity tt = normaliser(pts, [](const Correspondence& c) { return c.target; });

  // DLT with h8 = 1 (Hartley & Zisserman eq. 4.3 in inhomogeneous form): for each normalised
  // (x, y) -> (x', y'),
  //   h0 x + h1 y + h2 - h6 x x' - h7 y x' = x',   h3 x + h4 y + h5 - h6 x y' - h7 y y' = y'.
  // Fixing h8 is safe after normalisation: the raw centroid (now the origin) does not map to infinity
  // for any calibration worth having.
  Matrix a(2 * n, kParams), b(2 * n, 1);
  for (std::size_t i = 0; i < n; ++i) {
    const Point p = tr.apply(pts[i].raw), q = tt.apply(pts[i].target);
    const std::size_t r0 = 2 * i, r1 = 2 * i + 1;
    a(r0, 0) = p.x;
    a(r0, 1) = p.y;
    a(r0, 2) = 1;
    a(r0, 6) = -p.x * q.x;
    a(r0, 7) = -p.y * q.x;
    b(r0, 0) = q.x;
    a(r1, 3) = p.x;
    a(r1, 4) = p.y;
    a(r1, 5) = 1;
    a(r1, 6) = -p.x * q.y;
    a(r1, 7) = -p.y * q.y;
    b(r1, 0) = q.y;
  }
  const std::vector<double> cs = equilibrate(a);
  const LeastSquaresSolution sol = solve_least_squares(a, b, kRankTolerance);
  if (!sol.full_rank) {
    throw std::invalid_argument(degenerate(who, pts, sol, kParams, "collinear (or three of four on one line)"));
  }
  Mat3 hn{};
  for (std::size_t k = 0; k < kParams; ++k) hn[k] = sol.x(k, 0) / cs[k];
  hn[8] = 1;
  // H = T_target^-1 Hn T_raw.
  const Mat3 t_raw{tr.s, 0, -tr.s * tr.cx, 0, tr.s, -tr.s * tr.cy, 0, 0, 1};
  const Mat3 t_target_inv{1 / tt.s, 0, tt.cx, 0, 1 / tt.s, tt.cy, 0, 0, 1};
  Mat3 h = mul(t_target_inv, mul(hn, t_raw));
  if (!(std::abs(h[8]) > 0) || !std::isfinite(h[8])) {
    throw std::invalid_argument(who + ": the fitted homography sends the raw origin to infinity; the points are degenerate");
  }
  for (double& v : h) v /= h[8];

  HomographyMap map;
  map.h = h;
  // The line the map sends to infinity must not cut through the calibration points: w of one sign.
  int sign = 0;
  for (const auto& c : pts) {
    const double w = h[6] * c.raw.x + h[7] * c.raw.y + h[8];
    const int s = w > 0 ? 1 : (w < 0 ? -1 : 0);
    if (s == 0 || (sign != 0 && s != sign)) {
      throw std::invalid_argument(who + ": the best-fitting homography folds the plane between the calibration points "
                                        "(its line at infinity crosses them); the points are inconsistent with a "
                                        "projective map, use poly2 or bilinear-grid");
    }
    sign = s;
  }
  map.stats.points = n;
  map.stats.condition = sol.condition;
  detail::fill_residuals(map, pts, map.stats);
  return map;
}

Point HomographyMap::apply(Point raw) const {
  const double w = h[6] * raw.x + h[7] * raw.y + h[8];
  return {(h[0] * raw.x + h[1] * raw.y + h[2]) / w, (h[3] * raw.x + h[4] * raw.y + h[5]) / w};
}

}  // namespace fovea::calib
