// SPDX-License-Identifier: Apache-2.0
// The pupil ellipse from its edge points: RANSAC over conics through five points with an MSAC cost
// and plausibility checks (Świrski 2012 §3.3; Fischler & Bolles 1981), then a direct least-squares
// refit on the inliers (cv::fitEllipseDirect); and the conversions between conics, ellipses and
// OpenCV's rotated rectangles.
#include "eye/detector_stages.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <numeric>
#include <optional>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye::stages {

namespace {

// A general conic a x^2 + b xy + c y^2 + d x + e y + f = 0 in coordinates relative to `origin`,
// scaled by 1/`scale` (keeps the 5x5 solves well conditioned).
struct Conic {
  double a = 0, b = 0, c = 0, d = 0, e = 0, f = -1;
  cv::Point2d origin;
  double scale = 1;

  double value(const cv::Point2d& p) const {
    const double x = (p.x - origin.x) / scale, y = (p.y - origin.y) / scale;
    return a * x * x + b * x * y + c * y * y + d * x + e * y + f;
  }
  // First-order (Sampson) distance to the curve, in pixels.
  double distance(const cv::Point2d& p) const {
    return distance_at({(p.x - origin.x) / scale, (p.y - origin.y) / scale});
  }
  // The same for a point already in the conic's frame (relative to origin, divided by scale).
  double distance_at(const cv::Point2d& local) const {
    const double x = local.x, y = local.y;
    const double q = a * x * x + b * x * y + c * y * y + d * x + e * y + f;
    const double gx = 2 * a * x + b * y + d, gy = b * x + 2 * c * y + e;
    const double g = std::sqrt(gx * gx + gy * gy);  // not std::hypot: no overflow here, and it is hot (RANSAC)
    if (g < 1e-12) return 1e9;
    return std::abs(q) / g * scale;
  }
};

// Through five points (relative to origin, f = -1: the origin must be off the curve, which holds
// because the origin is the pupil's estimated centre).
std::optional<Conic> conic_through(const std::array<cv::Point2d, 5>& pts, const cv::Point2d& origin, double scale) {
  double m[5][6];
  for (int i = 0; i < 5; ++i) {
    const double x = (pts[static_cast<std::size_t>(i)].x - origin.x) / scale;
    const double y = (pts[static_cast<std::size_t>(i)].y - origin.y) / scale;
    m[i][0] = x * x; m[i][1] = x * y; m[i][2] = y * y; m[i][3] = x; m[i][4] = y; m[i][5] = 1.0;
  }
  for (int col = 0; col < 5; ++col) {  // Gaussian elimination with partial pivoting
    int pivot = col;
    for (int r = col + 1; r < 5; ++r)
      if (std::abs(m[r][col]) > std::abs(m[pivot][col])) pivot = r;
    if (std::abs(m[pivot][col]) < 1e-12) return std::nullopt;
    if (pivot != col)
      for (int k = 0; k < 6; ++k) std::swap(m[col][k], m[pivot][k]);
    for (int r = 0; r < 5; ++r) {
      if (r == col) continue;
      const double factor = m[r][col] / m[col][col];
      for (int k = col; k < 6; ++k) m[r][k] -= factor * m[col][k];
    }
  }
  Conic conic;
  conic.a = m[0][5] / m[0][0];
  conic.b = m[1][5] / m[1][1];
  conic.c = m[2][5] / m[2][2];
  conic.d = m[3][5] / m[3][3];
  conic.e = m[4][5] / m[4][4];
  conic.f = -1;
  conic.origin = origin;
  conic.scale = scale;
  return conic;
}

// Centre, axes and angle of a conic that is a real ellipse; nullopt otherwise.
std::optional<Ellipse> ellipse_of(Conic q) {
  if (q.a + q.c < 0) {  // the same curve with a positive-definite quadratic part
    q.a = -q.a; q.b = -q.b; q.c = -q.c; q.d = -q.d; q.e = -q.e; q.f = -q.f;
  }
  const double det = 4 * q.a * q.c - q.b * q.b;
  if (!(det > 1e-15)) return std::nullopt;
  const double x0 = (q.b * q.e - 2 * q.c * q.d) / det;
  const double y0 = (q.b * q.d - 2 * q.a * q.e) / det;
  const double f0 = q.a * x0 * x0 + q.b * x0 * y0 + q.c * y0 * y0 + q.d * x0 + q.e * y0 + q.f;
  // Eigenvalues of [[a, b/2], [b/2, c]].
  const double mean = (q.a + q.c) / 2, diff = norm2((q.a - q.c) / 2, q.b / 2);
  const double l1 = mean - diff, l2 = mean + diff;  // l1 <= l2: l1 belongs to the major axis
  if (!(l1 > 0) || !(-f0 > 0)) return std::nullopt;
  const double semi_major = std::sqrt(-f0 / l1), semi_minor = std::sqrt(-f0 / l2);
  if (!std::isfinite(semi_major) || !std::isfinite(semi_minor)) return std::nullopt;
  // The major axis is the eigenvector of l1.
  const double angle = 0.5 * std::atan2(q.b, q.a - q.c) + kPi / 2;
  const double angle_deg = std::fmod(angle * 180.0 / kPi + 360.0, 180.0);
  Ellipse e;
  e.centre = {q.origin.x + x0 * q.scale, q.origin.y + y0 * q.scale};
  e.major = 2 * semi_major * q.scale;
  e.minor = 2 * semi_minor * q.scale;
  e.angle_deg = angle_deg;
  if (e.minor > e.major) std::swap(e.minor, e.major);
  return e;
}

}  // namespace

Ellipse from_rotated_rect(const cv::RotatedRect& r) {
  Ellipse e;
  e.centre = {static_cast<double>(r.center.x), static_cast<double>(r.center.y)};
  const double w = static_cast<double>(r.size.width), h = static_cast<double>(r.size.height);
  double angle = static_cast<double>(r.angle);
  if (w >= h) {
    e.major = w; e.minor = h;
  } else {
    e.major = h; e.minor = w; angle += 90.0;
  }
  e.angle_deg = std::fmod(std::fmod(angle, 180.0) + 180.0, 180.0);
  return e;
}

// A point on the ellipse at parameter t (internal pixel convention).
cv::Point2d ellipse_point(const Ellipse& e, double t, double scale) {
  const double th = e.angle_deg * kPi / 180.0;
  const double ca = std::cos(th), sa = std::sin(th);
  const double x = scale * e.major / 2 * std::cos(t), y = scale * e.minor / 2 * std::sin(t);
  return {e.centre.x + x * ca - y * sa, e.centre.y + x * sa + y * ca};
}

namespace {

std::optional<Ellipse> fit_direct(const std::vector<cv::Point2d>& pts) {
  if (pts.size() < 5) return std::nullopt;
  std::vector<cv::Point2f> f;
  f.reserve(pts.size());
  for (const auto& p : pts) f.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  try {
    const cv::RotatedRect r = cv::fitEllipseDirect(f);
    Ellipse e = from_rotated_rect(r);
    if (!finite(e.centre) || !std::isfinite(e.major) || !std::isfinite(e.minor) || e.minor <= 0) return std::nullopt;
    return e;
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
}

// The ellipse's implicit form, to measure point distances.
Conic conic_of(const Ellipse& e) {
  const double th = e.angle_deg * kPi / 180.0;
  const double ca = std::cos(th), sa = std::sin(th);
  const double A = e.major / 2, B = e.minor / 2;
  Conic q;
  q.origin = e.centre;
  q.scale = std::max(1.0, A);
  const double a2 = (A / q.scale) * (A / q.scale), b2 = (B / q.scale) * (B / q.scale);
  q.a = ca * ca / a2 + sa * sa / b2;
  q.b = 2 * ca * sa * (1 / a2 - 1 / b2);
  q.c = sa * sa / a2 + ca * ca / b2;
  q.d = 0; q.e = 0; q.f = -1;
  return q;
}

// The sizes and places a pupil ellipse may have: radius within [rmin, rmax] (with slack for
// foreshortening) and centre near where the search started.
struct PupilBounds {
  cv::Point2d origin;
  double rmin = 0, rmax = 0;

  bool plausible(const Ellipse& e) const {
    return e.major / 2 <= rmax * 1.6 && e.major / 2 >= rmin && e.minor / 2 >= rmin * 0.6 && e.minor / e.major > 0.2 &&
           norm2(e.centre.x - origin.x, e.centre.y - origin.y) < rmax * 1.5;
  }
};

// Świrski 2012 §3.3 (Fischler & Bolles 1981): conics through random five-point samples, scored by
// the MSAC cost; returns the inliers of the cheapest plausible ellipse (empty when none).
std::vector<std::size_t> ransac_inliers(const std::vector<cv::Point2d>& pts, const PupilBounds& bounds,
                                        double tolerance, std::mt19937& rng) {
  const std::size_t n = pts.size();
  const cv::Point2d& origin = bounds.origin;
  std::vector<std::size_t> best_inliers;
  double scale = 0;
  for (const auto& p : pts) scale += norm2(p.x - origin.x, p.y - origin.y);
  scale = std::max(1.0, scale / static_cast<double>(n));
  // The points in the conics' frame once (every conic here shares origin and scale): the cost
  // below reads each of them at every iteration.
  std::vector<cv::Point2d> local(n);
  for (std::size_t i = 0; i < n; ++i) local[i] = {(pts[i].x - origin.x) / scale, (pts[i].y - origin.y) / scale};
  std::vector<std::size_t> inliers;
  inliers.reserve(n);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  double best_cost = 1e300;
  const int iterations = 60;
  for (int it = 0; it < iterations; ++it) {
    std::array<std::size_t, 5> idx{};
    for (std::size_t k = 0; k < 5; ++k) {
      bool fresh = false;
      while (!fresh) {
        idx[k] = pick(rng);
        fresh = std::find(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(k), idx[k]) == idx.begin() + static_cast<std::ptrdiff_t>(k);
      }
    }
    std::array<cv::Point2d, 5> sample;
    for (std::size_t k = 0; k < 5; ++k) sample[k] = pts[idx[k]];
    const auto conic = conic_through(sample, origin, scale);
    if (!conic) continue;
    const auto e = ellipse_of(*conic);
    if (!e || !bounds.plausible(*e)) continue;
    // MSAC cost: inliers cost their squared distance, outliers a constant.
    double cost = 0;
    inliers.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const double d = conic->distance_at(local[i]);
      if (d < tolerance) {
        cost += d * d;
        inliers.push_back(i);
      } else {
        cost += tolerance * tolerance;
      }
    }
    if (cost < best_cost) {
      best_cost = cost;
      best_inliers.swap(inliers);
      if (best_inliers.size() >= n * 95 / 100) break;
    }
  }
  return best_inliers;
}

// Least-squares refit on the inliers, then (after RANSAC) once more with the points it explains;
// `inliers` ends as the points the returned ellipse was fitted to.
std::optional<Ellipse> refit_on_inliers(const std::vector<cv::Point2d>& pts, FitMethod method, double tolerance,
                                        std::vector<std::size_t>& best_inliers) {
  const std::size_t n = pts.size();
  std::optional<Ellipse> e;
  for (int round = 0; round < (method == FitMethod::Ransac ? 2 : 1); ++round) {
    std::vector<cv::Point2d> in;
    in.reserve(best_inliers.size());
    for (std::size_t i : best_inliers) in.push_back(pts[i]);
    e = fit_direct(in);
    if (!e) return std::nullopt;
    if (method != FitMethod::Ransac) break;
    const Conic q = conic_of(*e);
    std::vector<std::size_t> again;
    for (std::size_t i = 0; i < n; ++i)
      if (q.distance(pts[i]) < tolerance) again.push_back(i);
    if (again.size() < 6) break;
    best_inliers.swap(again);
  }
  return e;
}

}  // namespace

bool one_ellipse_explains(const std::vector<EdgePoint>& edges, const std::vector<std::size_t>& run, double tolerance) {
  std::vector<char> in_run(edges.size(), 0);
  for (std::size_t i : run) in_run[i] = 1;
  std::vector<cv::Point2d> rest;
  for (std::size_t i = 0; i < edges.size(); ++i)
    if (!in_run[i]) rest.push_back(edges[i].p);
  if (rest.size() < 6) return false;
  // Fitted without the run: a lid's chord lies inside the pupil's own outline (up to the cut cap's
  // height away), where a least-squares ellipse through every point could bend to follow it.
  const std::optional<Ellipse> e = fit_direct(rest);
  if (!e || e->minor / e->major < 0.2) return false;
  const Conic q = conic_of(*e);
  std::size_t near_rest = 0, near_run = 0;
  for (const cv::Point2d& p : rest) near_rest += q.distance(p) < tolerance ? 1U : 0U;
  for (std::size_t i : run) near_run += q.distance(edges[i].p) < tolerance ? 1U : 0U;
  return 10 * near_rest >= 9 * rest.size() && 10 * near_run >= 9 * run.size();
}

std::optional<FitResult> fit_pupil(const std::vector<EdgePoint>& edges, FitMethod method, const cv::Point2d& origin,
                                   double rmin, double rmax, std::mt19937& rng) {
  const std::size_t n = edges.size();
  if (n < 6) return std::nullopt;
  std::vector<cv::Point2d> pts(n);
  for (std::size_t i = 0; i < n; ++i) pts[i] = edges[i].p;
  const PupilBounds bounds{origin, rmin, rmax};
  const double tolerance = std::max(0.8, 0.03 * rmin * 2);
  std::vector<std::size_t> best_inliers;
  if (method == FitMethod::Ransac) {
    best_inliers = ransac_inliers(pts, bounds, tolerance, rng);
    if (best_inliers.size() < 6) return std::nullopt;
  } else {
    best_inliers.resize(n);
    std::iota(best_inliers.begin(), best_inliers.end(), std::size_t{0});
  }
  const std::optional<Ellipse> e = refit_on_inliers(pts, method, tolerance, best_inliers);
  if (!e || !bounds.plausible(*e)) return std::nullopt;
  FitResult result;
  result.ellipse = *e;
  result.inliers = best_inliers;
  const Conic q = conic_of(*e);
  double ss = 0;
  for (std::size_t i : best_inliers) ss += std::pow(q.distance(pts[i]), 2);
  result.rms = std::sqrt(ss / static_cast<double>(std::max<std::size_t>(1, best_inliers.size())));
  return result;
}

}  // namespace fovea::trackerd::eye::stages
