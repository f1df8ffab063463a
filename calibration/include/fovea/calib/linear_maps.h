// SPDX-License-Identifier: Apache-2.0
#pragma once
// Affine and projective (homography) baselines from a raw 2-D measurement to the screen, fitted by
// linear least squares with the Householder-QR solver of least_squares.h.
//
//   affine:      out = (a0 + a1 u + a2 v,  a3 + a4 u + a5 v)                          6 parameters
//   homography:  out = ((h0 u + h1 v + h2) / w, (h3 u + h4 v + h5) / w),
//                w = h6 u + h7 v + h8, h8 = 1                                          8 parameters
//
// The homography is the normalised direct linear transform (Hartley 1997, "In defense of the
// eight-point algorithm"; Hartley & Zisserman, Multiple View Geometry, 2nd ed., Alg. 4.2): raw and
// target points are each moved to centroid 0 and mean distance sqrt(2), the 2n x 8 linear system
// (h8 fixed at 1 in the normalised frame) is solved by least squares, and the result is
// denormalised. This minimises the algebraic, not the geometric, error; the reported residual is the
// geometric one (target units).
//
// Both refuse, with std::invalid_argument saying why: fewer points than the parameters need (3 for
// the affine map, 4 for the homography), a coordinate that is not finite (or beyond +-1e100), and
// point sets that do not determine the map (collinear, too few distinct points, for the homography
// also three of four points on one line): the design matrix is then rank deficient.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <span>
#include <string>

#include "fovea/calib/point.h"

namespace fovea::calib {

// How well a fit went; every model reports the same.
struct FitStats {
  std::size_t points = 0;   // correspondences fitted
  // 2-norm condition number of the (normalised, column-scaled) design matrix; NaN where the model
  // solves no linear system (bilinear-grid).
  double condition = 0;
  double rms_residual = 0;  // sqrt(mean |apply(raw) - target|^2) over the fitted points
  double max_residual = 0;  // largest |apply(raw) - target|
};

struct AffineMap {
  static constexpr std::size_t kParams = 6;
  std::array<double, kParams> a{1, 0, 0, 0, 0, 1};  // raw units in, target units out (see above)
  FitStats stats;

  static AffineMap fit(std::span<const Correspondence> correspondences);
  Point apply(Point raw) const { return {a[0] + a[1] * raw.x + a[2] * raw.y, a[3] + a[4] * raw.x + a[5] * raw.y}; }
};

struct HomographyMap {
  static constexpr std::size_t kParams = 8;
  // Row-major 3x3 matrix on homogeneous raw points, scaled so h[8] == 1.
  std::array<double, 9> h{1, 0, 0, 0, 1, 0, 0, 0, 1};
  FitStats stats;

  static HomographyMap fit(std::span<const Correspondence> correspondences);
  // Not finite when raw is not finite or lies on the line the homography sends to infinity.
  Point apply(Point raw) const;
};

namespace detail {
// Shared by the fits: throws std::invalid_argument("<who>: ...") naming the first correspondence with
// a coordinate that is not finite or beyond +-1e100.
void check_finite(std::span<const Correspondence> correspondences, const std::string& who);
// Number of distinct raw points (exact comparison).
std::size_t distinct_raw_points(std::span<const Correspondence> correspondences);
// "%.6g"
std::string format_number(double v);
// Fills rms_residual and max_residual of `stats` from `apply` over the correspondences.
template <class Map>
void fill_residuals(const Map& map, std::span<const Correspondence> correspondences, FitStats& stats) {
  double sum2 = 0;
  stats.max_residual = 0;
  for (const Correspondence& c : correspondences) {
    const Point p = map.apply(c.raw);
    const double d = std::hypot(p.x - c.target.x, p.y - c.target.y);
    sum2 += d * d;
    stats.max_residual = std::max(stats.max_residual, d);
  }
  stats.rms_residual = correspondences.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(correspondences.size()));
}
}  // namespace detail

}  // namespace fovea::calib
