// SPDX-License-Identifier: Apache-2.0
#pragma once
// The bilinear calibration-vector grid of Jensen & Pedersen 2009 ("Gaze-directed photon mapping",
// §4.2.1, eqs. 4.1-4.2). A regular grid of known screen points Q_ij = (x_i, y_j) each carries a
// calibration vector v_ij = (true target - measured point), averaged over that target's samples.
// A measured point p = (x_p, y_p) is corrected to p + v_p, where v_p weights the vectors of the four
// grid points around p:
//
//   alpha = (x_p - x_1) / (x_2 - x_1),   beta = (y_p - y_1) / (y_2 - y_1)                  (4.1)
//   v_p = (1 - alpha) (v_11 (1 - beta) + v_12 beta) + alpha (v_21 (1 - beta) + v_22 beta)  (4.2)
//
// Outside the grid their rules hold: in a corner region (beyond the outermost grid points in both x
// and y) v_p is the single adjacent corner's vector; above or below the grid only alpha is used
// (interpolating along the nearest grid row); left or right of it only beta (along the nearest
// column). So the correction is extrapolated as a constant outward: never beyond the largest
// measured vector.
//
// The measured point is whatever the grid corrects: an uncalibrated screen point when the grid is
// used alone, or another model's output when it corrects that model (J&P's cross-user "general
// calibration map" on top of the tracker's own calibration). Grid and measured points share units
// (screen pixels, say).
#include <cstddef>
#include <span>
#include <vector>

#include "fovea/calib/linear_maps.h"
#include "fovea/calib/point.h"

namespace fovea::calib {

struct BilinearGrid {
  std::vector<double> xs, ys;  // grid coordinates x_i, y_j: strictly increasing, at least 2 each
  std::vector<Point> vectors;  // v_ij at (xs[i], ys[j]), index j * xs.size() + i
  FitStats stats;              // condition is NaN: no linear system is solved

  // Fits from (target, measured) pairs whose targets lie on a full rectangular grid: the distinct x
  // and y values of the targets are found with `tolerance` (target units; <= 0: 1e-3 of the
  // targets' extent in that axis), every (x_i, y_j) must have at least one sample, and v_ij is the
  // mean of (target - raw) over its samples. Throws std::invalid_argument naming the problem: a
  // missing grid target (its coordinates), fewer than 2 distinct x or y values, non-finite input.
  static BilinearGrid fit(std::span<const Correspondence> correspondences, double tolerance = 0);

  // v_p by eqs. 4.1-4.2 and the corner and border rules; NaN when p is not finite.
  Point correction(Point p) const;
  Point apply(Point p) const {
    const Point v = correction(p);
    return {p.x + v.x, p.y + v.y};
  }
  const Point& vector_at(std::size_t i, std::size_t j) const { return vectors[j * xs.size() + i]; }
};

}  // namespace fovea::calib
