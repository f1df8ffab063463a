// SPDX-License-Identifier: Apache-2.0
#pragma once
// Second-order polynomial calibration map: each output coordinate is a full quadratic in the raw
// 2-D measurement (u, v),
//
//   out_x = a0 + a1 u + a2 v + a3 u v + a4 u^2 + a5 v^2,   out_y = b0 + b1 u + ... + b5 v^2,
//
// the classic mapping from the pupil–glint vector to screen position of video eye trackers
// (Morimoto & Mimica 2005, §3; Cerrolaza, Villanueva & Cabeza 2008 compare it with other
// polynomials). Fitted by linear least squares (Householder QR with column pivoting, see
// least_squares.h). For conditioning, u and v are first centred and scaled to unit RMS spread, and
// the design matrix's columns are scaled to unit norm; the coefficients are kept in those
// normalised coordinates (apply() normalises the same way), which is also the stable form to store.
//
// Needs at least 6 correspondences that do not all lie on one line or one conic (a 3x3 grid of
// targets is the usual minimum; 9 points give 3 degrees of freedom per axis to check residuals).
#include <array>
#include <cstddef>
#include <span>
#include <string>

#include "fovea/calib/point.h"

namespace fovea::calib {

struct Poly2Map {
  static constexpr std::size_t kTerms = 6;  // 1, u, v, u v, u^2, v^2

  // Normalisation of the raw input: un = (u - centre.x) / scale.x, vn = (v - centre.y) / scale.y.
  Point centre{0, 0};
  Point scale{1, 1};
  std::array<double, kTerms> coeff_x{}, coeff_y{};  // on terms(un, vn)

  std::size_t points = 0;     // correspondences fitted
  // 2-norm condition number (sigma_max / sigma_min) of the normalised, column-scaled design
  // matrix: how much the fit amplifies noise in the targets. Well spread grids give ~10.
  double condition = 0;
  double rms_residual = 0;    // sqrt(mean |apply(raw) - target|^2) over the fitted points, target units
  double max_residual = 0;    // largest |apply(raw) - target|, target units

  // Fits the map. Throws std::invalid_argument with a message saying what is wrong when there are
  // fewer than 6 correspondences, a coordinate is not finite (or beyond +-1e100), or the points do
  // not determine the polynomial (collinear, all on one conic, or too few distinct points).
  static Poly2Map fit(std::span<const Correspondence> correspondences);

  // The mapped point. Not finite when `raw` is not finite; callers that must not pass NaN on check.
  Point apply(Point raw) const;

  // The six terms at a normalised point, in coefficient order.
  static std::array<double, kTerms> terms(double un, double vn) { return {1.0, un, vn, un * vn, un * un, vn * vn}; }

  // "poly2, 81 points, rms 0.0012, max 0.0031, condition 12.3"
  std::string describe() const;
};

}  // namespace fovea::calib
